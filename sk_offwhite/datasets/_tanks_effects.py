"""Cascaded Tanks physics of eq. (21) augmented with the effects it leaves out.

The benchmark note (Schoukens et al. 2016) names the hard nonlinearities that the suggested
model omits: the upper tank overflows (partly into the lower tank, partly back to the
reservoir) and the lower tank / its sensor saturates at 10 V. The lower-tank sensor is
uncalibrated, so its zero need not be the outlet level, and its reading need not be
proportional to the level. `tanks_effects_physics` builds a
[`PhysicsModel`][sk_offwhite.PhysicsModel] with any subset of these effects, each with named
physical parameters, written with ``jax.numpy`` and smooth (softplus hinges) so that the simulation
error stays differentiable.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import jax
import jax.numpy as jnp

from sk_offwhite.datasets._cascaded_tanks import SAMPLING_TIME, SATURATION_LEVEL, safe_sqrt
from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = [
    "EFFECTS",
    "TanksEffectsOutput",
    "TanksEffectsStep",
    "hinge",
    "soft_min",
    "tanks_effects_physics",
]

EFFECTS = (
    "overflow",
    "tank_limit",
    "sensor_limit",
    "offset",
    "outlet_exponent",
    "pump_threshold",
    "upper_exponent",
)
"""Effects that `tanks_effects_physics` can add to eq. (21):

* ``"overflow"``: the upper-tank level cannot exceed ``h_max``; the excess leaves the upper
  tank and a part of it, ``k_overflow`` (in lower-tank sensor volts per unit of ``x1``),
  reaches the lower tank (the rest returns to the reservoir);
* ``"tank_limit"``: the lower-tank level cannot exceed ``x2_max`` (its own overflow);
* ``"sensor_limit"``: the sensor reads ``min(x2, 10)`` (smooth), the clip seen in the data;
* ``"offset"``: the lower tank drains through ``x2 - z_out`` instead of ``x2``, ``z_out``
  being the sensor reading at the outlet level (the sensor is uncalibrated);
* ``"outlet_exponent"``: the lower-tank outflow is ``k3 (x2 - z_out)^a2`` instead of
  Torricelli's square root (``a2 = 1/2``); it absorbs a nonlinear sensor characteristic;
* ``"pump_threshold"``: the pump delivers ``k4 max(u - u_dead, 0)`` (smooth) instead of
  ``k4 u``;
* ``"upper_exponent"``: the upper-tank outflow is ``k1 x1^a1``, ``a1`` between 1/2
  (turbulent orifice) and 1 (laminar outlet), and the lower tank receives ``k2 x1^a1``.
"""

DEFAULT_SHARPNESS = 20.0
"""Default ``beta`` of the smooth hinges ``softplus(beta a) / beta`` (1/V)."""

_PARAMETERS = {
    "k1": Parameter(0.05, (1e-6, None)),
    "k2": Parameter(0.05, (1e-6, None)),
    "k3": Parameter(0.05, (1e-6, None)),
    "k4": Parameter(0.05, (1e-6, None)),
    "h_max": Parameter(12.0, (1.0, 100.0)),
    "k_overflow": Parameter(0.5, (0.0, 10.0)),
    "x2_max": Parameter(10.5, (5.0, 20.0)),
    "z_out": Parameter(0.0, (-10.0, 2.9)),
    "a2": Parameter(0.5, (0.05, 1.5)),
    "u_dead": Parameter(0.0, (-5.0, 0.4)),
    "a1": Parameter(0.5, (0.5, 1.0)),
}
_EFFECT_PARAMETERS = {
    "overflow": ("h_max", "k_overflow"),
    "tank_limit": ("x2_max",),
    "sensor_limit": (),
    "offset": ("z_out",),
    "outlet_exponent": ("a2",),
    "pump_threshold": ("u_dead",),
    "upper_exponent": ("a1",),
}


def hinge(a, sharpness):
    """Smooth ``max(a, 0)``: ``softplus(sharpness * a) / sharpness`` (``jax.numpy``)."""
    return jax.nn.softplus(sharpness * a) / sharpness


def soft_min(a, limit, sharpness):
    """Smooth ``min(a, limit)``: ``limit - hinge(limit - a)``; exact far from ``limit``."""
    return limit - hinge(limit - a, sharpness)


def _flags(effects: Sequence[str]) -> frozenset[str]:
    """The effects as a frozenset, after checking their names."""
    if isinstance(effects, str):
        effects = (effects,)
    unknown = set(effects) - set(EFFECTS)
    if unknown:
        raise ValueError(f"unknown effects {sorted(unknown)}; known: {EFFECTS}.")
    return frozenset(effects)


class TanksEffectsStep:
    r"""One sample of the augmented tanks model (picklable, compared by value).

    ``n_substeps`` explicit-Euler sub-steps of eq. (21), each followed by the limits; with
    $r(a) = \max(a, 10^{-6})^{a_1}$ ($a_1 = 1/2$: Torricelli),
    $g(a) = \max(a, 10^{-6})^{a_2}$ and the pump flow $p(u)$:

    $$
    \tilde x_1 &= x_1 + \Delta t(-k_1 r(x_1) + k_4 p(u)), \qquad
    o = \mathrm{hinge}(\tilde x_1 - h_{max}), \qquad x_1^+ = \tilde x_1 - o, \\
    \tilde x_2 &= x_2 + \Delta t(k_2 r(x_1) - k_3 g(x_2 - z_{out}))
    + k_{overflow}\, o, \qquad x_2^+ = \mathrm{softmin}(\tilde x_2, x_{2,max}).
    $$

    Effects that are not selected drop out (``o = 0``, ``z_out = 0``, ``a1 = a2 = 1/2``,
    ``p(u) = u``, no cap).
    """

    def __init__(
        self, effects: Sequence[str], sampling_time: float, sharpness: float, n_substeps: int = 1
    ):
        self.effects = _flags(effects)
        self.sampling_time = float(sampling_time)
        self.sharpness = float(sharpness)
        self.n_substeps = int(n_substeps)
        self.__name__ = "tanks_effects_step"

    def _key(self):
        return (
            TanksEffectsStep,
            self.effects,
            self.sampling_time,
            self.sharpness,
            self.n_substeps,
        )

    def __eq__(self, other) -> bool:
        return isinstance(other, TanksEffectsStep) and other._key() == self._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def _upper_outflow_law(self, x1, theta):
        """``r(x1)``: ``sqrt(x1)``, or ``x1^a1`` with ``"upper_exponent"``."""
        if "upper_exponent" in self.effects:
            return jnp.maximum(x1, 1e-6) ** theta["a1"]
        return safe_sqrt(x1)

    def _lower_outflow(self, x2, theta):
        """Lower-tank outflow ``k3 g(x2 - z_out)`` (Torricelli without the effects)."""
        head = x2 - theta["z_out"] if "offset" in self.effects else x2
        if "outlet_exponent" in self.effects:
            return theta["k3"] * jnp.maximum(head, 1e-6) ** theta["a2"]
        return theta["k3"] * safe_sqrt(head)

    def _pump(self, u, theta):
        """Pump flow per unit ``k4``: ``u``, or ``hinge(u - u_dead)``."""
        if "pump_threshold" in self.effects:
            return hinge(u - theta["u_dead"], self.sharpness)
        return u

    def _substep(self, x, u, theta):
        """One explicit-Euler sub-step of ``Ts / n_substeps`` followed by the limits."""
        dt, beta = self.sampling_time / self.n_substeps, self.sharpness
        flow1 = self._upper_outflow_law(x[0], theta)
        x1 = x[0] + dt * (-theta["k1"] * flow1 + theta["k4"] * self._pump(u[0], theta))
        x2 = x[1] + dt * (theta["k2"] * flow1 - self._lower_outflow(x[1], theta))
        if "overflow" in self.effects:
            spill = hinge(x1 - theta["h_max"], beta)
            x1 = x1 - spill
            x2 = x2 + theta["k_overflow"] * spill
        if "tank_limit" in self.effects:
            x2 = soft_min(x2, theta["x2_max"], beta)
        return jnp.stack([x1, x2])

    def __call__(self, x, u, theta):
        for _ in range(self.n_substeps):
            x = self._substep(x, u, theta)
        return x


class TanksEffectsOutput:
    """Output map ``z = x2`` or, with ``"sensor_limit"``, ``softmin(x2, level)``."""

    def __init__(self, effects: Sequence[str], sharpness: float, level: float):
        self.effects = _flags(effects)
        self.sharpness, self.level = float(sharpness), float(level)
        self.__name__ = "tanks_effects_output"

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


def _parameters(effects, init: Mapping[str, float], fixed: Mapping[str, float]) -> dict:
    """Parameters of eq. (21) and of the selected effects, with initial / fixed values."""
    names = ["k1", "k2", "k3", "k4"]
    for effect in EFFECTS:
        if effect in effects:
            names.extend(_EFFECT_PARAMETERS[effect])
    unknown = (set(init) | set(fixed)) - set(names)
    if unknown:
        raise KeyError(f"unknown parameters {sorted(unknown)} for effects {sorted(effects)}.")
    params = {}
    for name in names:
        default = _PARAMETERS[name]
        value = float(fixed.get(name, init.get(name, default.value)))
        params[name] = Parameter(value, default.bounds, fixed=name in fixed)
    return params


def tanks_effects_physics(
    effects: Sequence[str] = ("overflow", "tank_limit", "sensor_limit", "offset"),
    init: Mapping[str, float] | None = None,
    fixed: Mapping[str, float] | None = None,
    x0: Sequence[float] = (5.205, 5.205),
    *,
    sharpness: float = DEFAULT_SHARPNESS,
    n_substeps: int = 1,
    sampling_time: float = SAMPLING_TIME,
    level: float = SATURATION_LEVEL,
) -> PhysicsModel:
    """Cascaded Tanks model of eq. (21) with the selected effects of `EFFECTS`.

    Parameters
    ----------
    effects : sequence of str, default=("overflow", "tank_limit", "sensor_limit", "offset")
        Effects to add; ``()`` gives eq. (21) itself (one explicit-Euler step per sample).
    init : dict, default=None
        Initial values ``name -> value``. Defaults: ``k1..k4 = 0.05``, ``h_max = 12``,
        ``k_overflow = 0.5``, ``x2_max = 10.5``, ``z_out = 0``, ``a1 = a2 = 0.5``,
        ``u_dead = 0``.
    fixed : dict, default=None
        Parameters kept fixed, ``name -> value``. Fix one of ``k1, k2, k4`` (e.g. ``k4``):
        with only ``x2`` measured the scale of ``x1`` is not identifiable.
    x0 : sequence of 2 floats, default=(5.205, 5.205)
        Initial-state guess (the first estimation output for both levels).
    sharpness : float, default=20.0
        ``beta`` of the smooth hinges, in 1/(level unit).
    n_substeps : int, default=1
        Explicit-Euler sub-steps per sample (the limits act after each sub-step); ``1`` is
        the discrete-time model of eq. (21).
    sampling_time : float, default=4.0
        ``Ts`` in seconds.
    level : float, default=10.0
        Sensor saturation level of ``"sensor_limit"`` (V).

    Returns
    -------
    PhysicsModel
        States ``("x1", "x2")``, input ``"u"``, output ``"x2"``, parameters ``k1..k4`` then
        those of the effects in the order of `EFFECTS`.

    Examples
    --------
    >>> from sk_offwhite.datasets._tanks_effects import tanks_effects_physics
    >>> model = tanks_effects_physics(("overflow", "sensor_limit"), fixed={"k4": 0.04})
    >>> model.parameter_names
    ('k1', 'k2', 'k3', 'k4', 'h_max', 'k_overflow')
    """
    flags = _flags(effects)
    params = _parameters(flags, dict(init or {}), dict(fixed or {}))
    return PhysicsModel(
        TanksEffectsStep(flags, sampling_time, sharpness, n_substeps),
        TanksEffectsOutput(flags, sharpness, level),
        params,
        n_states=2,
        n_inputs=1,
        x0=x0,
        x0_bounds=(0.0, None),
        state_names=("x1", "x2"),
        input_names=("u",),
        output_names=("x2",),
        state_kinds=("level", "level"),
        input_kinds=("voltage",),
    )
