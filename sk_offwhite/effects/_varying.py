r"""A declared constant that is not constant: $\theta_j \to \theta_j\,g(v)$.

When a law's coefficient depends on a state or an input (a spring that hardens with its
deflection, a valve coefficient that depends on its opening, an inductance that falls with
its current), the declared constant is replaced, inside the declared step (inside the
integrated right-hand side of a physics built with
[`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode]), by the constant times a factor
of one closed form:

$$
\text{polynomial } 1 \pm (v/v_s)^2, \qquad \text{rational } \frac{1}{1 + (v/v_s)^2}, \qquad
\text{power } |v/v_s|^p, \qquad \text{exponential } e^{\pm v/v_s},
$$

with the scale $v_s > 0$ (in the variable's units) and the exponent $p$ fitted. The
declared parameter keeps its meaning: the polynomial, rational and exponential forms equal
it at $v = 0$.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model._physics import Parameter, value_of
from ._base import Effect, _positive

__all__ = ["VaryingParameter"]

FAMILIES = ("polynomial", "rational", "power", "exponential")
"""The closed forms of the factor."""

EXPONENT_BOUNDS = (-6.0, 6.0)
"""Where the power law's exponent is fitted."""


class VaryingParameter(Effect):
    r"""The declared constant ``parameter`` made a law of one variable (module docstring).

    Parameters
    ----------
    parameter : str
        The declared parameter $\theta_j$ (free or fixed).
    variable : int
        Index of the state (``source="state"``) or input (``source="input"``) $v$.
    family : {'polynomial', 'rational', 'power', 'exponential'}
    scale : float
        Start of $v_s$ (``{name}_scale``, kept above a small fraction of it).
    exponent : float, default=1.0
        Start of $p$ (``{name}_exponent``, power law only).
    rising : bool, default=True
        The sign of the polynomial and exponential forms: $1 + (v/v_s)^2$ (a hardening
        spring) or $1 - (v/v_s)^2$, $e^{v/v_s}$ or $e^{-v/v_s}$.
    source : {'state', 'input'}, default='state'
    stiffness : bool, default=False
        The parameter is a stiffness and the variable its deflection: the sign reads
        ``"hardening"`` or ``"softening"``.
    variable_name : str, default=None
        The variable's name in the descriptions (``None``: the state's name, or ``u{k}``).
    name : str, default=None
        ``vary_{parameter}_{variable_name}`` when ``None`` (``x{k}`` or ``u{k}`` without a
        ``variable_name``).
    """

    target = "parameter"

    def __init__(
        self,
        parameter: str,
        variable: int,
        family: str,
        scale: float,
        *,
        exponent: float = 1.0,
        rising: bool = True,
        source: str = "state",
        stiffness: bool = False,
        variable_name: str | None = None,
        name: str | None = None,
    ):
        if family not in FAMILIES:
            raise ValueError(f"family must be one of {FAMILIES}, got {family!r}.")
        if source not in ("state", "input"):
            raise ValueError(f"source must be 'state' or 'input', got {source!r}.")
        if not (np.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be finite and positive, got {scale!r}.")
        self.parameter, self.variable, self.family = str(parameter), int(variable), family
        self.scale, self.exponent, self.rising = float(scale), float(exponent), bool(rising)
        self.source, self.stiffness = source, bool(stiffness)
        self.variable_name = variable_name
        where = variable_name or f"{'x' if source == 'state' else 'u'}{self.variable}"
        self.name = name or f"vary_{parameter}_{where}"

    def parameters(self) -> dict[str, Parameter]:
        params = {f"{self.name}_scale": _positive(self.scale)}
        if self.family == "power":
            params[f"{self.name}_exponent"] = Parameter(self.exponent, EXPONENT_BOUNDS)
        return params

    def factor(self, v, theta, xp=jnp):
        """$g(v)$ at the parameters ``theta`` (``xp``: ``jax.numpy`` or ``numpy``)."""
        scaled = v / theta[f"{self.name}_scale"]
        if self.family == "polynomial":
            return 1.0 + (1.0 if self.rising else -1.0) * scaled**2
        if self.family == "rational":
            return 1.0 / (1.0 + scaled**2)
        if self.family == "power":
            safe = xp.maximum(xp.abs(scaled), 1e-12)
            return safe ** theta[f"{self.name}_exponent"]
        return xp.exp(scaled if self.rising else -scaled)

    def apply_parameters(self, x, u, theta):
        v = (x if self.source == "state" else u)[self.variable]
        return {**theta, self.parameter: theta[self.parameter] * self.factor(v, theta)}

    def sign(self, values=None) -> str:
        """Whether the coefficient rises or falls as $|v|$ grows (with $v$ for the
        exponential form), at the fitted ``values`` where they matter; ``"hardening"`` or
        ``"softening"`` for a stiffness."""
        rising = self._rising(values)
        if self.stiffness:
            return "hardening" if rising else "softening"
        return "rising" if rising else "falling"

    def _rising(self, values=None) -> bool:
        if self.family == "rational":
            return False
        if self.family == "power":
            return value_of((values or {}).get(f"{self.name}_exponent", self.exponent)) > 0
        return self.rising

    def formula(self, variable_name: str, values=None) -> str:
        """The law with its numbers, e.g. ``k(q) = k·(1 + (q/0.04)²)``."""
        values = values or {}
        scale = value_of(values.get(f"{self.name}_scale", self.scale))
        v, p = variable_name, f"{self.parameter}({variable_name})"
        value = values.get(self.parameter)
        theta = self.parameter if value is None else f"{value_of(value):.4g}"
        ratio = f"({v}/{scale:.4g})"
        if self.family == "polynomial":
            return f"{p} = {theta}·(1 {'+' if self.rising else '-'} {ratio}²)"
        if self.family == "rational":
            return f"{p} = {theta}/(1 + {ratio}²)"
        if self.family == "power":
            exponent = value_of(values.get(f"{self.name}_exponent", self.exponent))
            return f"{p} = {theta}·|{ratio}|^{exponent:.3g}"
        return f"{p} = {theta}·exp({'' if self.rising else '-'}{v}/{scale:.4g})"

    def describe(self, state_names, output_names, values=None) -> str:
        if self.variable_name is not None:
            variable = self.variable_name
        elif self.source == "state" and self.variable < len(state_names):
            variable = state_names[self.variable]
        else:
            variable = f"{'x' if self.source == 'state' else 'u'}{self.variable}"
        return (
            f"the declared constant {self.parameter} depends on {variable}: "
            f"{self.formula(variable, values)} ({self.sign(values)})"
        )
