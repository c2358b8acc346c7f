r"""A declared constant that is not constant: $\theta_j \to \theta_j\,g(v)$.

When a law's coefficient depends on a state or an input (a spring that hardens with its
deflection, a valve coefficient that depends on its opening, an inductance that falls with
its current), the declared constant is replaced, inside the declared step (inside the
integrated right-hand side of a physics built with
[`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode]), by the constant times a factor
of one closed form:

$$
\text{polynomial } 1 \pm (v/v_s)^2, \qquad \text{rational } \frac{1}{1 + (v/v_s)^2}, \qquad
\text{power } |v/v_s|^p, \qquad \text{exponential } e^{v/v_s},
$$

with the scale $v_s > 0$ (in the variable's units) and the exponent $p$ fitted. The
declared parameter keeps its meaning: the polynomial, rational and exponential forms equal
it at $v = 0$.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model._physics import Parameter
from ._base import Effect, _positive

__all__ = ["VaryingParameter"]

FAMILIES = ("polynomial", "rational", "power", "exponential")
"""The closed forms of the factor."""

EXPONENT_BOUNDS = (0.05, 6.0)
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
        The polynomial's sign: $1 + (v/v_s)^2$ (a hardening spring) or $1 - (v/v_s)^2$.
    source : {'state', 'input'}, default='state'
    name : str, default=None
        ``vary_{parameter}`` when ``None``.
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
        self.source, self.name = source, name or f"vary_{parameter}"

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
        return xp.exp(scaled)

    def apply_parameters(self, x, u, theta):
        v = (x if self.source == "state" else u)[self.variable]
        return {**theta, self.parameter: theta[self.parameter] * self.factor(v, theta)}

    def sign(self, values=None) -> str:
        """Whether the coefficient rises or falls as $|v|$ grows (with $v$ for the
        exponential form), at the fitted ``values`` where they matter."""
        if self.family == "polynomial":
            return "rising" if self.rising else "falling"
        if self.family == "rational":
            return "falling"
        if self.family == "power":
            exponent = (values or {}).get(f"{self.name}_exponent", self.exponent)
            return "rising" if float(getattr(exponent, "value", exponent)) > 0 else "falling"
        return "rising"

    def formula(self, variable_name: str, values=None) -> str:
        """The law with its numbers, e.g. ``k(q) = k·(1 + (q/0.04)²)``."""
        values = values or {}
        scale = values.get(f"{self.name}_scale", self.scale)
        scale = float(getattr(scale, "value", scale))
        v, p = variable_name, f"{self.parameter}({variable_name})"
        ratio = f"({v}/{scale:.4g})"
        if self.family == "polynomial":
            return f"{p} = {self.parameter}·(1 {'+' if self.rising else '-'} {ratio}²)"
        if self.family == "rational":
            return f"{p} = {self.parameter}/(1 + {ratio}²)"
        if self.family == "power":
            exponent = values.get(f"{self.name}_exponent", self.exponent)
            exponent = float(getattr(exponent, "value", exponent))
            return f"{p} = {self.parameter}·|{ratio}|^{exponent:.3g}"
        return f"{p} = {self.parameter}·exp{ratio}"

    def describe(self, state_names, output_names, values=None) -> str:
        names = state_names if self.source == "state" else ("input",) * (self.variable + 1)
        variable = names[self.variable] if self.variable < len(names) else f"v{self.variable}"
        return (
            f"the declared constant {self.parameter} depends on {variable}: "
            f"{self.formula(variable, values)} ({self.sign(values)})"
        )
