"""What the loop knows of an effect beyond its law: its mechanism and its richer variant.

`mechanism` names what an effect models: variants of one mechanism (an overflow into one
tank or another, a soft or a hard actuator limit) share it, and an effect set holds at most
one of them. `richer` is the next variant of the same mechanism with one more degree of
freedom, which holds the effect as a special case (a calibration of one degree more, a
drag of fitted exponent): once an effect is chosen the loop tries its richer variant in
its place, started from `richer_start`, where the variant reproduces the effect.
"""

from __future__ import annotations

import re
from functools import singledispatch

from ..effects import (
    DifferenceDeadZone,
    Effect,
    Friction,
    InputDelay,
    InputLag,
    InputSaturation,
    Overflow,
    PowerDrag,
    PowerStiffness,
    QuadraticDrag,
    SensorCalibration,
    SensorLag,
    SensorStep,
    Stiffness,
    VaryingParameter,
)
from ._fits import size

__all__ = ["mechanism", "representatives", "richer", "richer_start"]


@singledispatch
def mechanism(effect: Effect) -> str:
    """What ``effect`` models (default: its name, a mechanism of its own)."""
    return effect.name


@mechanism.register
def _(effect: Overflow) -> str:
    return f"overflow of state {effect.state}"


@mechanism.register
def _(effect: InputSaturation) -> str:
    return f"saturation of input {effect.input}"


@mechanism.register
def _(effect: DifferenceDeadZone) -> str:
    return f"threshold on input {effect.input} minus state {effect.state}"


@mechanism.register
def _(effect: SensorCalibration) -> str:
    return f"sensor calibration of output {effect.output}"


@mechanism.register
def _(effect: SensorStep) -> str:
    return f"step in output {effect.output}"


@mechanism.register
def _(effect: Friction) -> str:
    return f"friction of state {effect.velocity} in state {effect.state}"


@mechanism.register
def _(effect: Stiffness) -> str:
    return f"stiffness of state {effect.position} in state {effect.state}"


@mechanism.register
def _(effect: QuadraticDrag) -> str:
    return f"drag of state {effect.state}"


@mechanism.register
def _(effect: VaryingParameter) -> str:
    return f"variation of {effect.parameter}"


@mechanism.register(InputLag)
@mechanism.register(InputDelay)
def _(effect) -> str:
    """A lag and a dead time are variants of how a command reaches the plant."""
    return f"dynamics of input {effect.input}"


@mechanism.register
def _(effect: SensorLag) -> str:
    return f"dynamics of the sensor of output {effect.output}"


@singledispatch
def richer(effect: Effect) -> Effect | None:
    """The richer variant of ``effect``, or ``None`` (the default: no such variant)."""
    return None


@richer.register
def _(effect: SensorCalibration) -> SensorCalibration:
    """The calibration of degree $d + 1$ (named ``{base}_degree{d+1}``, ``base`` the name
    without an earlier ``_degree`` suffix), on the same centre and scale."""
    base = re.sub(r"_degree\d+$", "", effect.name)
    return effect.replace(degree=effect.degree + 1, name=f"{base}_degree{effect.degree + 1}")


@richer.register
def _(effect: Friction) -> Friction | None:
    """The Stribeck friction of fitted level and velocity (named ``{name}_stribeck``) of a
    Coulomb friction, its velocity started at `Friction.STRIBECK_START` times the width;
    ``None`` for a friction that has a Stribeck term."""
    if effect.stribeck_velocity is not None:
        return None
    return effect.replace(
        stribeck_velocity=effect.STRIBECK_START * effect.width, fit_stribeck_velocity=True,
        name=f"{effect.name}_stribeck",
    )  # fmt: skip


@richer.register
def _(effect: Stiffness) -> PowerStiffness:
    """The spring of fitted exponent (named ``{name}_power``), started at its power, on the
    same reference position."""
    return PowerStiffness(
        effect.state, effect.position, power=effect.power, reference=effect.reference,
        name=f"{effect.name}_power",
    )  # fmt: skip


@richer.register
def _(effect: QuadraticDrag) -> PowerDrag:
    """The drag of fitted exponent (named ``{name}_power``) on the same reference velocity."""
    return PowerDrag(effect.state, reference=effect.reference, name=f"{effect.name}_power")


@richer.register(PowerStiffness)
@richer.register(PowerDrag)
def _(effect) -> None:
    """None: the exponent is already free."""
    return None


@richer.register
def _(effect: InputDelay) -> InputDelay:
    """The same dead time with twice the reach ($2D$ past commands): a delay the fit left
    at its bound may be longer."""
    reach = 2 * effect.n_taps * effect.sampling_time
    return effect.replace(max_delay=reach, name=f"{effect.name}_longer")


@singledispatch
def richer_start(effect: Effect, values: dict) -> dict:
    """The start of `richer`'s parameters from ``effect``'s fitted ``values`` (by parameter
    name; any type): each of the effect's parameters carried into the richer one's of the
    same field (``{name}_c0`` into ``{richer name}_c0``), the extra ones at their declared
    starts; empty when there is no richer variant."""
    variant = richer(effect)
    if variant is None:
        return {}
    start = variant.parameters()
    for name in effect.parameters():
        carried = variant.name + name[len(effect.name) :]
        if carried in start:
            start[carried] = values[name]
    return start


@richer_start.register
def _(effect: Friction, values: dict) -> dict:
    """The Coulomb level carried over and the Stribeck level at 0; the width carried over
    unless the fit made it sharper than it started, where it restarts (a sign far sharper
    than every speed on the record is flat in the width: from there the Stribeck fit could
    not smooth it again)."""
    start = richer_start.dispatch(Effect)(effect, values)
    width = values[f"{effect.name}_width"]
    if start and getattr(width, "value", width) < effect.width:
        variant = richer(effect)
        start[f"{variant.name}_width"] = variant.parameters()[f"{variant.name}_width"]
    return start


def representatives(ranked, tolerance: float) -> list:
    """``ranked`` (``(RMSE, candidate, parameters)``, best first) with one variant per
    mechanism, in the place of the mechanism's best: the variant with the fewest parameters
    among those within ``tolerance`` of that best (an overflow whose excess leaves the
    system rather than one with a fitted fraction, unless the fraction is worth it)."""
    groups: dict[str, list] = {}
    for item in ranked:
        groups.setdefault(mechanism(item[1].effect), []).append(item)
    return [min(within(group, tolerance), key=n_parameters) for group in groups.values()]


def within(group, tolerance: float) -> list:
    """The items of ``group`` (best first) whose RMSE is within ``tolerance`` of the first."""
    return [item for item in group if item[0] <= group[0][0] * (1.0 + tolerance)]


def n_parameters(item) -> int:
    return size((item[1].effect,))
