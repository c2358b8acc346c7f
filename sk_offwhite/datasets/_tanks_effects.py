"""Cascaded Tanks physics of eq. (21) augmented with the effects it leaves out.

The benchmark note (Schoukens et al. 2016) names the hard nonlinearities that the suggested
model omits: the upper tank overflows (partly into the lower tank, partly back to the
reservoir) and the lower tank / its sensor saturates at 10 V. The lower-tank sensor is
uncalibrated, so its zero need not coincide with the outlet level. :func:`tanks_effects_physics`
builds a :class:`~sk_offwhite.PhysicsModel` with any subset of these effects, each with named
physical parameters, written with ``jax.numpy`` and smooth (softplus hinges) so that the
simulation error stays differentiable.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp

from sk_offwhite._physics import Parameter, PhysicsModel
from sk_offwhite.datasets._cascaded_tanks import SAMPLING_TIME, SATURATION_LEVEL, safe_sqrt

__all__ = ["EFFECTS", "TanksEffectsOutput", "TanksEffectsStep", "tanks_effects_physics"]

EFFECTS = ("offset", "overflow", "tank_limit", "sensor_limit")
"""Effects that :func:`tanks_effects_physics` can add to eq. (21):

* ``"offset"``: the lower tank drains through ``sqrt(x2 - z_out)``, ``z_out`` the sensor
  reading at the outlet level (parameter ``z_out``);
* ``"overflow"``: the upper-tank level cannot exceed ``h_max``; the excess leaves the tank,
  a part ``k_overflow`` of it (in lower-tank sensor units) reaching the lower tank;
* ``"tank_limit"``: the lower-tank level cannot exceed ``x2_max`` (its own overflow);
* ``"sensor_limit"``: the sensor output is ``min(x2, 10)`` (smooth), the measured clip.
"""

DEFAULT_SHARPNESS = 20.0
"""Default ``beta`` of the smooth hinges ``softplus(beta a) / beta`` (1/V)."""


def hinge(a, sharpness):
    """Smooth ``max(a, 0)``: ``softplus(sharpness * a) / sharpness`` (``jax.numpy``)."""
    return jax.nn.softplus(sharpness * a) / sharpness


def soft_min(a, limit, sharpness):
    """Smooth ``min(a, limit)``: ``limit - hinge(limit - a)``; exact far from ``limit``."""
    return limit - hinge(limit - a, sharpness)


def _flags(effects: Sequence[str]) -> frozenset[str]:
    unknown = set(effects) - set(EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)}; known: {EFFECTS}.")
    return frozenset(effects)


class TanksEffectsStep:
    r"""One sample of the augmented tanks model (picklable, compared by value).

    With :math:`s(a) = \sqrt{\max(a, 10^{-6})}` and an explicit-Euler step of eq. (21),

    .. math::

        \tilde x_1 &= x_1 + T_s(-k_1 s(x_1) + k_4 u), \qquad
        o = \mathrm{hinge}(\tilde x_1 - h_{max}), \qquad x_1^+ = \tilde x_1 - o, \\
        \tilde x_2 &= x_2 + T_s(k_2 s(x_1) - k_3 s(x_2 - z_{out})) + k_{overflow}\, o,
        \qquad x_2^+ = \min(\tilde x_2, x_{2,max}),

    where each effect that is not selected drops out (``o = 0``, ``z_out = 0``, no cap).
    """

    def __init__(self, effects: Sequence[str], sampling_time: float, sharpness: float):
        self.effects = _flags(effects)
        self.sampling_time = float(sampling_time)
        self.sharpness = float(sharpness)
        self.__name__ = "tanks_effects_step"

    def _key(self):
        return (TanksEffectsStep, self.effects, self.sampling_time, self.sharpness)

    def __eq__(self, other) -> bool:
        return isinstance(other, TanksEffectsStep) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __call__(self, x, u, theta):
        ts, beta = self.sampling_time, self.sharpness
        root1 = safe_sqrt(x[0])
        outlet = theta["z_out"] if "offset" in self.effects else 0.0
        x1 = x[0] + ts * (-theta["k1"] * root1 + theta["k4"] * u[0])
        x2 = x[1] + ts * (theta["k2"] * root1 - theta["k3"] * safe_sqrt(x[1] - outlet))
        if "overflow" in self.effects:
            spill = hinge(x1 - theta["h_max"], beta)
            x1 = x1 - spill
            x2 = x2 + theta["k_overflow"] * spill
        if "tank_limit" in self.effects:
            x2 = soft_min(x2, theta["x2_max"], beta)
        return jnp.stack([x1, x2])


class TanksEffectsOutput:
    """Output map ``z = x2`` or, with ``"sensor_limit"``, ``soft_min(x2, 10)``."""

    def __init__(self, effects: Sequence[str], sharpness: float, level: float):
        self.effects = _flags(effects)
        self.sharpness, self.level = float(sharpness), float(level)

    def _key(self):
        return (TanksEffectsOutput, self.effects, self.sharpness, self.level)

    def __eq__(self, other) -> bool:
        return isinstance(other, TanksEffectsOutput) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __call__(self, x, u, theta):
        if "sensor_limit" in self.effects:
            return soft_min(x[1:2], self.level, self.sharpness)
        return x[1:2]


_DEFAULTS = {
    "k1": Parameter(0.05, (1e-6, None)),
    "k2": Parameter(0.05, (1e-6, None)),
    "k3": Parameter(0.05, (1e-6, None)),
    "k4": Parameter(0.05, (1e-6, None)),
    "z_out": Parameter(0.0, (-10.0, 2.0)),
    "h_max": Parameter(10.0, (1.0, 100.0)),
    "k_overflow": Parameter(0.5, (0.0, 10.0)),
    "x2_max": Parameter(10.5, (5.0, 20.0)),
}
_EFFECT_PARAMETERS = {
    "offset": ("z_out",),
    "overflow": ("h_max", "k_overflow"),
    "tank_limit": ("x2_max",),
    "sensor_limit": (),
}


def _parameters(effects, init: Mapping[str, float], fixed: Mapping[str, float]):
    names = ["k1", "k2", "k3", "k4"]
    for effect in EFFECTS:
        if effect in effects:
            names.extend(_EFFECT_PARAMETERS[effect])
    unknown = (set(init) | set(fixed)) - set(names)
    if unknown:
        raise KeyError(f"unknown parameters {sorted(unknown)} for effects {sorted(effects)}.")
    params = {}
    for name in names:
        default = _DEFAULTS[name]
        value = float(fixed.get(name, init.get(name, default.value)))
        params[name] = Parameter(value, default.bounds, fixed=name in fixed)
    return params


def tanks_effects_physics(
    effects: Sequence[str] = ("offset", "overflow", "sensor_limit"),
    init: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    x0: Sequence[float] = (5.205, 5.205),
    *,
    sharpness: float = DEFAULT_SHARPNESS,
    sampling_time: float = SAMPLING_TIME,
    level: float = SATURATION_LEVEL,
) -> PhysicsModel:
    """Cascaded Tanks model of eq. (21) with the selected effects of :data:`EFFECTS`.

    Parameters
    ----------
    effects : sequence of str, default=("offset", "overflow", "sensor_limit")
        Effects to add; ``()`` gives eq. (21) itself (as a discrete step).
    init : dict, default=None
        Initial values ``name -> value`` (defaults: ``k1..k4 = 0.05``, ``z_out = 0``,
        ``h_max = 10``, ``k_overflow = 0.5``, ``x2_max = 10.5``).
    fixed : dict, default=None
        Parameters kept fixed, ``name -> value``. Fix one of ``k1, k2, k4`` (e.g. ``k4``):
        with only ``x2`` measured the scale of ``x1`` is not identifiable.
    x0 : sequence of 2 floats, default=(5.205, 5.205)
        Initial-state guess (the first estimation output for both levels).
    sharpness : float, default=20.0
        ``beta`` of the smooth hinges, in 1/(level unit).
    sampling_time : float, default=4.0
        ``Ts`` in seconds.
    level : float, default=10.0
        Sensor saturation level of ``"sensor_limit"`` (V).

    Returns
    -------
    PhysicsModel
        States ``("x1", "x2")``, input ``"u"``, output ``"x2"``.
    """
    flags = _flags(effects)
    params = _parameters(flags, dict(init or {}), dict(fixed or {}))
    return PhysicsModel(
        TanksEffectsStep(flags, sampling_time, sharpness),
        TanksEffectsOutput(flags, sharpness, level),
        params,
        n_states=2,
        n_inputs=1,
        x0=x0,
        x0_bounds=(0.0, None),
        state_names=("x1", "x2"),
        input_names=("u",),
        output_names=("x2",),
    )
