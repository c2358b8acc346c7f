r"""Terms added to one state equation: a constant, a linear loss, a loss in a power."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._physics import Parameter
from ._base import AdditiveEffect

__all__ = ["Bias", "Leak", "PowerLoss", "signed_power"]


class Leak(AdditiveEffect):
    r"""A loss proportional to the state: $g = -c\, x_s$.

    Parameter ``{name}_rate`` ($c \ge 0$).
    """

    def __init__(self, state: int, *, rate: float = 0.01, name: str = "leak"):
        self.state, self.rate, self.name = int(state), float(rate), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_rate": Parameter(self.rate, (0.0, None))}

    def term(self, x, u, theta):
        return -theta[f"{self.name}_rate"] * x[self.state]

    def basis(self, x, u):
        return -x[:, self.state]

    def describe(self, state_names, output_names, values=None) -> str:
        return f"{state_names[self.state]} leaks in proportion to its value"


class PowerLoss(AdditiveEffect):
    r"""A loss growing with a fitted power of a state's excess over a level:

    $$
    g = -c\,\Delta \left(\frac{|\Delta|}{\Delta_r}\right)^{a - 1},
    \qquad \Delta = x_s - \ell,
    $$

    on top of the declared loss: a heat loss by convection ($a$ = 5/4 or 4/3), or
    the curvature of a radiative one, where the physics declares Newton's law of cooling,
    whose linear part the declared conductance keeps. Parameters ``{name}_rate``
    ($c \ge 0$: the loss is $c\,\Delta_r$ at $|\Delta| = \Delta_r$
    whatever $a$),
    ``{name}_level`` ($\ell$, in the state's units) and ``{name}_exponent``
    ($a$, in `EXPONENT_BOUNDS`, started at 2: at $a = 1$ the loss is
    linear, which the declared one already is).
    ``reference`` ($\Delta_r > 0$, the loop takes the state's RMS deviation on the
    record) makes the rate convert with the state's units alone.
    """

    EXPONENT_BOUNDS = (1.0, 3.0)

    def __init__(
        self,
        state: int,
        *,
        rate: float = 0.0,
        level: float = 0.0,
        exponent: float = 2.0,
        reference: float = 1.0,
        name: str = "loss",
    ):
        self.state, self.rate, self.level, self.name = int(state), float(rate), float(level), name
        self.exponent = _check_exponent(exponent, self.EXPONENT_BOUNDS)
        self.reference = _check_reference(reference)

    def parameters(self) -> dict[str, Parameter]:
        return {
            f"{self.name}_rate": Parameter(self.rate, (0.0, None)),
            f"{self.name}_level": Parameter(self.level),
            f"{self.name}_exponent": Parameter(self.exponent, self.EXPONENT_BOUNDS),
        }

    def term(self, x, u, theta):
        excess = x[self.state] - theta[f"{self.name}_level"]
        power = signed_power(excess, self.reference, 1, theta[f"{self.name}_exponent"])
        return -theta[f"{self.name}_rate"] * power

    def describe(self, state_names, output_names, values=None) -> str:
        exponent = (values or {}).get(f"{self.name}_exponent", self.exponent)
        return (
            f"{state_names[self.state]} loses in the power {float(exponent):.3g} of its excess "
            "over a level, beyond the declared loss"
        )


class Bias(AdditiveEffect):
    r"""A constant in the equation of state ``state``: $g = b$ (a force offset, a
    constant inflow, a heat source). Parameter ``{name}_value``."""

    def __init__(self, state: int, *, value: float = 0.0, name: str = "bias"):
        self.state, self.value, self.name = int(state), float(value), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_value": Parameter(self.value)}

    def term(self, x, u, theta):
        return theta[f"{self.name}_value"]

    def basis(self, x, u):
        return np.ones(len(x))

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the {state_names[self.state]} equation has a constant term (an offset)"


def signed_power(v, reference: float, base: int, exponent, xp=jnp):
    r"""$v|v|^{b-1} (|v|/v_r)^{a-b}$, $b$ = ``base``, $a$ = ``exponent``,
    $v_r$ = ``reference``: the signed power $a$ of $v$ whose size at
    $|v| = v_r$ does not depend on $a$, and which is $v|v|^{b-1}$ at
    $a = b$. Zero at $v = 0$, where the power of the zero ratio is left out,
    so that no $\log 0$ reaches the derivative in $a$ (``xp``: ``jax.numpy``,
    or ``numpy`` for the basis)."""
    ratio = xp.abs(v) / reference
    moving = ratio > 0
    safe_ratio = xp.where(moving, ratio, 1.0)
    scale = xp.where(moving, safe_ratio ** (exponent - base), 0.0)
    return v * xp.abs(v) ** (base - 1) * scale


def _check_reference(reference: float) -> float:
    if not (np.isfinite(reference) and reference > 0):
        raise ValueError(f"reference must be finite and positive, got {reference!r}.")
    return float(reference)


def _check_exponent(exponent: float, bounds: tuple[float, float]) -> float:
    lower, upper = bounds
    if not lower <= exponent <= upper:
        raise ValueError(f"exponent must lie in [{lower}, {upper}], got {exponent!r}.")
    return float(exponent)
