r"""Limits: a capped level, a saturated reading or actuator, dead zones.

Each hard limit has smooth corners (`SHARPNESS`, relative to the effect's own level or
width), so that the simulation error stays differentiable.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..model._physics import Parameter
from ._base import (
    SHARPNESS,
    InputEffect,
    OutputEffect,
    StateEffect,
    _beyond,
    _checked_corner,
    _corner_parameters,
    _hinge_corner,
    _positive,
    hinge,
)

__all__ = ["DeadZone", "DifferenceDeadZone", "InputSaturation", "OutputSaturation", "Overflow"]


class Overflow(StateEffect):
    r"""State ``state`` cannot exceed a level; a fraction of the excess reaches ``sink``.

    $$
    o = \mathrm{hinge}_\beta(x^+_s - h), \quad x^+_s \leftarrow x^+_s - o, \quad
    x^+_{d} \leftarrow x^+_{d} + \rho\, o,
    $$

    with parameters ``{name}_level`` ($h$) and, with a sink, ``{name}_fraction``
    ($\rho \in [0, 1]$; the rest leaves the system). The hinge is rounded over
    ``corner`` ($c$, in the state's units):
    $\mathrm{hinge}(a) = c\,\mathrm{softplus}(a / c)$, so $\beta = 1/c$. The
    loop sets $c$ to 2.5 % of the state's standard deviation on the record, so the
    rounding follows the data's units. With ``fit_corner=True`` the corner is a parameter,
    ``{name}_corner``, started at ``corner`` and kept above `RELATIVE_FLOOR` of it:
    the data decide how sharp the overflow is (a weir spills gradually, a rim at once).
    A corner driven to its floor leaves the cost kinked there and the Hessian singular in
    it (infinite standard errors): start it from a fitted model, and read it as "sharp".
    """

    def __init__(
        self,
        state: int,
        level: float,
        sink: int | None = None,
        *,
        fraction: float = 0.5,
        corner: float = 0.05,
        fit_corner: bool = False,
        name: str = "overflow",
    ):
        self.state, self.level, self.sink = int(state), float(level), sink
        self.fraction, self.corner, self.name = float(fraction), _checked_corner(corner), name
        self.fit_corner = bool(fit_corner)

    def parameters(self) -> dict[str, Parameter]:
        params = {f"{self.name}_level": Parameter(self.level)}
        if self.sink is not None:
            params[f"{self.name}_fraction"] = Parameter(self.fraction, (0.0, 1.0))
        return {**params, **_corner_parameters(self)}

    def apply_state(self, x, u, x_next, theta):
        corner = _hinge_corner(self, theta)
        excess = hinge(x_next[self.state] - theta[f"{self.name}_level"], 1.0 / corner)
        x_next = x_next.at[self.state].add(-excess)
        if self.sink is None:
            return x_next
        return x_next.at[self.sink].add(theta[f"{self.name}_fraction"] * excess)

    def describe(self, state_names, output_names, values=None) -> str:
        fraction = (values or {}).get(f"{self.name}_fraction", self.fraction)
        where = ""
        if self.sink is not None and fraction >= 0.01:
            where = f", a fraction {fraction:.2g} of the excess flowing into "
            where += state_names[self.sink]
        elif self.sink is not None:
            where = ", the excess leaving the system"
        return f"{state_names[self.state]} overflows above a level{where}"


class OutputSaturation(OutputEffect):
    r"""Output ``output`` saturates at an upper level.

    $z \leftarrow z - \mathrm{hinge}_\beta(z - z_{max})$;
    parameter ``{name}_level`` ($z_{max}$). The hinge is rounded over ``corner``
    (in the output's units, $\beta = 1/c$; fitted as ``{name}_corner`` with
    ``fit_corner=True``; see [`Overflow`][sk_offwhite.Overflow]); the loop sets it to 2.5 % of the
    simulated output's standard deviation.
    """

    def __init__(
        self,
        output: int,
        level: float,
        *,
        corner: float = 0.05,
        fit_corner: bool = False,
        name: str = "saturation",
    ):
        self.output, self.level, self.name = int(output), float(level), name
        self.corner, self.fit_corner = _checked_corner(corner), bool(fit_corner)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_level": Parameter(self.level), **_corner_parameters(self)}

    def apply_output(self, x, u, z, theta):
        corner = _hinge_corner(self, theta)
        excess = hinge(z[self.output] - theta[f"{self.name}_level"], 1.0 / corner)
        return z.at[self.output].add(-excess)

    def describe(self, state_names, output_names, values=None) -> str:
        return f"the measured {output_names[self.output]} saturates at an upper level"


class InputSaturation(InputEffect):
    r"""Input ``input`` reaches the physics through a saturating actuator.

    Two shapes, applied before the declared step, with parameter ``{name}_level``
    ($u_{max} > 0$, kept above `RELATIVE_FLOOR` of its start):

    * ``shape="tanh"``: $u_j \leftarrow u_{max} \tanh(u_j / u_{max})$, a soft
      saturation (already 8 % below $u_j$ at half the level);
    * ``shape="clip"``: a hard limit at $\pm u_{max}$ with rounded corners (below): the
      input passes unchanged below the level (a heater, a valve, a drive at its current
      limit).

    The hard limit is

    $$
    u_j \leftarrow u_j - \frac{u_{max}}{s}\left[\mathrm{sp}\big(s(u_j/u_{max} - 1)\big) -
    \mathrm{sp}\big(s(-u_j/u_{max} - 1)\big)\right],
    $$

    with $\mathrm{sp}$ the softplus and $s$ = ``sharpness``, relative to $u_{max}$ so
    that the rounding follows the input's units.

    Both shapes are one mechanism (`mechanism`): a set holds at most one of them.
    """

    SHAPES = ("tanh", "clip")

    def __init__(
        self,
        input: int,
        level: float,
        *,
        shape: str = "tanh",
        sharpness: float = SHARPNESS,
        name: str = "actuator",
    ):
        if shape not in self.SHAPES:
            raise ValueError(f"shape must be one of {self.SHAPES}, got {shape!r}.")
        if not level > 0:
            raise ValueError(f"level must be positive, got {level!r}.")
        self.input, self.level, self.name = int(input), float(level), name
        self.shape, self.sharpness = shape, float(sharpness)

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_level": _positive(self.level)}

    def apply_input(self, x, u, theta):
        level, value = theta[f"{self.name}_level"], u[self.input]
        if self.shape == "tanh":
            return u.at[self.input].set(level * jnp.tanh(value / level))
        s = self.sharpness
        return u.at[self.input].set(value - level * _beyond(value / level, s) / s)

    def describe(self, state_names, output_names, values=None) -> str:
        if self.shape == "clip":
            return "the actuator saturates: the input is clipped at ±u_max"
        return "the actuator saturates: the input acts as u_max tanh(u / u_max)"


class DeadZone(InputEffect):
    r"""Input ``input`` acts only beyond a dead zone of half-width $w$.

    $u_j \leftarrow w\,[\mathrm{sp}(s(u_j/w - 1)) - \mathrm{sp}(s(-u_j/w - 1))]/s$,
    a smooth $\mathrm{sign}(u)\max(|u| - w, 0)$ ($\mathrm{sp}$ the softplus,
    $s$ = ``sharpness``, relative to $w$, so the smoothing follows the input's
    units). Parameter ``{name}_width`` ($w > 0$, kept above `RELATIVE_FLOOR`
    of its start, as every positive width of this module).
    """

    def __init__(self, input: int, width: float, *, sharpness: float = SHARPNESS, name="dead_zone"):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.input, self.width, self.sharpness, self.name = (
            int(input),
            float(width),
            sharpness,
            name,
        )

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_width": _positive(self.width)}

    def apply_input(self, x, u, theta):
        width, s = theta[f"{self.name}_width"], self.sharpness
        return u.at[self.input].set(width * _beyond(u[self.input] / width, s) / s)

    def describe(self, state_names, output_names, values=None) -> str:
        return "the actuator has a dead zone: inputs smaller than a width do nothing"


class DifferenceDeadZone(InputEffect):
    r"""Input ``input`` drives the physics through its difference with state ``state``,
    and that difference acts only beyond a threshold $w$.

    With the drive $d = u_j - x_i$ (both in the same units: a source and a capacitor
    voltage, a commanded and a measured position, a supply and a tank level), the declared
    step sees $u_j \leftarrow x_i + g(d)$ in place of $u_j$, so every term in
    $u_j - x_i$ becomes $g(d)$:

    * ``one_sided=False``: $g(d) = \mathrm{sign}(d)\max(|d| - w, 0)$, a dead zone
      (a clearance in a spring, two anti-parallel diodes);
    * ``one_sided=True``: $g(d) = \max(d - w, 0)$, conduction in one direction only
      past a forward drop (a diode, a check valve's cracking pressure).

    Both are smoothed as [`DeadZone`][sk_offwhite.DeadZone] (softplus, $s$ = ``sharpness``, relative
    to $w$, so the rounding follows the variables' units). Parameter
    ``{name}_width`` ($w > 0$, in the state's units). Both shapes are one mechanism:
    a set holds at most one of them.
    """

    def __init__(
        self,
        input: int,
        state: int,
        width: float,
        *,
        one_sided: bool = False,
        sharpness: float = SHARPNESS,
        name: str = "drop",
    ):
        if not width > 0:
            raise ValueError(f"width must be positive, got {width!r}.")
        self.input, self.state, self.width = int(input), int(state), float(width)
        self.one_sided, self.sharpness, self.name = bool(one_sided), float(sharpness), name

    def parameters(self) -> dict[str, Parameter]:
        return {f"{self.name}_width": _positive(self.width)}

    def apply_input(self, x, u, theta):
        width, s, level = theta[f"{self.name}_width"], self.sharpness, x[self.state]
        passed = _beyond((u[self.input] - level) / width, s, self.one_sided)
        return u.at[self.input].set(level + width * passed / s)

    def describe(self, state_names, output_names, values=None) -> str:
        drive = f"the difference between its input and {state_names[self.state]}"
        if self.one_sided:
            return f"{drive} drives it in one direction only, past a forward drop (a diode)"
        return f"{drive} acts only beyond a dead zone (a clearance)"
