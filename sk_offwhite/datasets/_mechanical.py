"""Synthetic mechanical and electromechanical systems whose declared physics misses one effect.

Same conventions as `sk_offwhite.datasets._synthetic`: each generator simulates a true
system, one explicit-Euler step of the declared physics per sample
(``PhysicsModel.from_ode(..., method="euler")``) plus an additive hidden effect on one state
equation, so that with no process noise

``physics.step(x[k], u[k], true_parameters) + hidden_effect["state_function"](x[k], u[k])``

reproduces ``x[k+1]`` to rounding error. The hidden effect's discrete contribution is
``dt`` times a continuous-time rate; ``hidden_effect["rates"]`` gives the rate's
coefficients in units of the affected state's time derivative, so that a fitted
continuous-time effect can be compared with them directly. ``hidden_effect["kinds"]`` (also
``kinds`` in the returned Bunch) names the physical kind of each state and input. The
measured output is the first state plus Gaussian noise. All quantities are in SI units
(seconds, metres, newtons, radians); ``sampling_time`` is in seconds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._common import (
    _check_n_samples,
    _check_number,
    _check_random_state,
    _multisine,
    _noise_stds,
    _simple_dataset,
    _SimpleSystem,
    _tanh,
    _TermName,
)
from sk_offwhite.datasets._synthetic import (
    POSITIVE,
    _first_order_physics,
    _friction_effect,
    _signed_square,
    motor_rhs,
    oscillator_rhs,
)
from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = [
    "make_coulomb_drive",
    "make_dead_zone_motor",
    "make_duffing_oscillator",
    "make_pendulum_drag",
]


@dataclass(frozen=True)
class _Generator:
    """A `_SimpleSystem` with its multisine input, default noise, rates and kinds;
    the input is ``input_mean + input_std`` times a unit multisine, floored at
    ``input_floor`` (a heater's power cannot go below zero)."""

    system: _SimpleSystem
    input_std: float
    band: float
    noise_std: float
    rates: dict
    kinds: dict
    input_mean: float = 0.0
    input_floor: float = -np.inf


def _generate(spec: _Generator, n_samples, noise_std, random_state, process_noise_std) -> Bunch:
    """Validate the arguments, draw the two multisine inputs and simulate."""
    n = _check_n_samples(n_samples)
    stds = _noise_stds(spec.noise_std if noise_std is None else noise_std, process_noise_std)
    rng = _check_random_state(random_state)
    inputs = [
        np.maximum(
            spec.input_mean + spec.input_std * _multisine(rng, n, spec.band), spec.input_floor
        )[:, None]
        for _ in range(2)
    ]
    data = _simple_dataset(spec.system, rng, n, inputs, stds)
    kinds = {key: tuple(value) for key, value in spec.kinds.items()}
    data.hidden_effect["rates"] = dict(spec.rates)
    data.hidden_effect["kinds"] = kinds
    data.kinds = dict(kinds)
    return data


def _second_order_physics(rhs, values, x0, dt, names, kinds=None) -> PhysicsModel:
    """Euler-discretised two-state physics measuring its first state (``names``: x, v, u;
    ``kinds``: ``{"states": ..., "inputs": ...}``, declared when given)."""
    kinds = kinds or {}
    return PhysicsModel.from_ode(
        rhs,
        dt,
        output=0,
        parameters={name: Parameter(v, POSITIVE) for name, v in values.items()},
        n_states=2,
        n_inputs=1,
        method="euler",
        x0=x0,
        state_names=names[:2],
        input_names=names[2:],
        output_names=names[:1],
        state_kinds=kinds.get("states"),
        input_kinds=kinds.get("inputs"),
    )


_MECHANICAL_KINDS = {"states": ("position", "velocity"), "inputs": ("force",)}

# --------------------------------------------------------------------------------------
# a. Positioning drive with Coulomb friction and a force offset
# --------------------------------------------------------------------------------------

DRIVE_THETA = {"m": 1.0, "k": 2500.0, "c": 20.0}
DRIVE_M = DRIVE_THETA["m"]
DRIVE_FC, DRIVE_EPS, DRIVE_F0, DRIVE_DT = 3.0, 0.005, 1.5, 1e-3


def _coulomb_drive_effect(x, u, fc, eps, f0, m, dt):
    """``[0, dt (-Fc tanh(v / eps) + F0) / m]`` (numpy)."""
    return _friction_effect(x, u, fc, eps, m, dt) + np.array([0.0, dt * f0 / m])


def _tanh_width(a):
    """``tanh(a / 0.005)``: a Coulomb-like step of width 0.005 (m/s for a velocity)."""
    return _tanh(a / DRIVE_EPS)


def _drive_physics(values: dict, x0) -> PhysicsModel:
    return _second_order_physics(oscillator_rhs, values, x0, DRIVE_DT, ("q", "v", "u"))


def _drive_library():
    import pysindy as ps  # imported when a dictionary is asked for

    steps = ps.CustomLibrary([_tanh_width], [_TermName(f"tanh({{0}}/{DRIVE_EPS:g})")])
    return ps.PolynomialLibrary(degree=3) + steps


_DRIVE = _Generator(
    system=_SimpleSystem(
        physics=_drive_physics,
        theta=DRIVE_THETA,
        guess={"m": 1.25, "k": 2000.0, "c": 15.0},
        x0=(0.0, 0.0),
        contribution=_coulomb_drive_effect,
        params={"fc": DRIVE_FC, "eps": DRIVE_EPS, "f0": DRIVE_F0, "m": DRIVE_M, "dt": DRIVE_DT},
        equation=1,
        variables=("v",),
        effect_description="Coulomb friction -Fc tanh(v / 0.005) opposing the velocity plus a "
        "constant force offset F0 (velocity equation), Fc = 3 N, F0 = 1.5 N.",
        library=_drive_library,
        process_target="velocity equation",
        descr="Positioning drive m q'' + c q' + k q = u - Fc tanh(q'/eps) + F0 [SI units], "
        "m=1 kg, k=2500 N/m, c=20 N s/m, Fc=3 N, eps=0.005 m/s, F0=1.5 N, Euler dt=1 ms, "
        "position measured; the physics omits the friction and the offset.\n",
        dt=DRIVE_DT,
    ),
    input_std=15.0,
    band=0.01,
    noise_std=1e-4,
    rates={"coulomb": DRIVE_FC / DRIVE_M, "offset": DRIVE_F0 / DRIVE_M, "width": DRIVE_EPS},
    kinds=_MECHANICAL_KINDS,
)


def make_coulomb_drive(
    n_samples: int = 4000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """Positioning drive whose physics misses Coulomb friction and a force offset.

    True system, one explicit-Euler step of $\\Delta t = 10^{-3}$ s per sample:

    $$
    \\dot q = v, \\qquad
    m \\dot v = u - k q - c v - F_c \\tanh(v / \\varepsilon) + F_0, \\qquad z = q + \\eta,
    $$

    with $m = 1$ kg, $k = 2500$ N/m, $c = 20$ N s/m, $F_c = 3$ N,
    $\\varepsilon = 0.005$ m/s and $F_0 = 1.5$ N (position ``q`` in m, velocity
    ``v`` in m/s, force ``u`` in N). The hidden effect
    $\\Delta t (-F_c \\tanh(v/\\varepsilon) + F_0) / m$ enters the velocity equation
    (index 1); ``hidden_effect["rates"]`` is ``{"coulomb": Fc/m, "offset": F0/m, "width":
    eps}`` (m/s², m/s², m/s).

    Euler is stable for the linear part when $c > \\Delta t\\, k$ (then
    $|1 + \\Delta t \\lambda|^2 = 1 - \\Delta t\\, c / m + \\Delta t^2 k / m < 1$); the
    nominal $c = 5$ N s/m would be stable (modulus 0.99875) but leaves the 8 Hz
    resonance so lightly damped (damping ratio 0.025 after Euler's own negative damping of
    $\\Delta t\\, k$) that no input level gives both a moderate velocity and a
    sizeable friction, so $c$ was raised to 20 N s/m (damping ratio 0.2, modulus
    0.9912). Near $v = 0$ the friction's slope $F_c / \\varepsilon$ adds damping
    and keeps the step stable (factor 0.4 on the velocity). Input: force multisine 0-10 Hz
    (0.01 cycles/sample), std 15 N: the velocity's std is about 0.38 m/s and the
    friction's RMS is about 22 % of that of $u / m$. The drive starts at rest.

    Suggested library: polynomials of degree 3 on ``[q, v, u]`` (bias included) plus
    ``tanh(a / 0.005)`` of each variable (23 features); it contains the effect exactly.

    Parameters
    ----------
    n_samples : int, default=4000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (m) of the Gaussian position-sensor noise; ``None`` means
        ``1e-4`` m, about 1 % of the position's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (m/s) of a Gaussian disturbance added to the velocity update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_DRIVE, n_samples, noise_std, random_state, process_noise_std)


# --------------------------------------------------------------------------------------
# b. Oscillator with a hardening (Duffing) spring
# --------------------------------------------------------------------------------------

DUFFING_THETA = {"m": 1.0, "k": 1.0, "c": 0.2}
DUFFING_K3, DUFFING_DT = 1.5, 0.02


def _cubic_spring_effect(x, u, k3, m, dt, exponent=3.0):
    """``[0, -dt k3 y |y|^(exponent - 1) / m]`` (numpy; ``y^3`` for 3)."""
    y = x[..., 0]
    spring = y**3 if exponent == 3.0 else np.sign(y) * np.abs(y) ** exponent
    force = -dt * k3 * spring / m
    return np.stack([np.zeros_like(force), force], axis=-1)


def _duffing_physics(values: dict, x0) -> PhysicsModel:
    return _second_order_physics(oscillator_rhs, values, x0, DUFFING_DT, ("y", "v", "u"))


def _polynomial_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=3)


_DUFFING = _Generator(
    system=_SimpleSystem(
        physics=_duffing_physics,
        theta=DUFFING_THETA,
        guess={"m": 1.25, "k": 0.8, "c": 0.25},
        x0=(0.0, 0.0),
        contribution=_cubic_spring_effect,
        params={"k3": DUFFING_K3, "m": DUFFING_THETA["m"], "dt": DUFFING_DT},
        equation=1,
        variables=("y",),
        effect_description="Hardening spring -k3 y^3 (k3 = 1.5 N/m^3) in the velocity "
        "equation, stiffer than linear at large |y|.",
        library=_polynomial_library,
        process_target="velocity equation",
        descr="Duffing oscillator m y'' + c y' + k y + k3 y^3 = u [SI units], m=1 kg, "
        "k=1 N/m, c=0.2 N s/m, k3=1.5 N/m^3, Euler dt=0.02 s, position measured; the "
        "physics is the linear mass-spring-damper.\n",
        dt=DUFFING_DT,
    ),
    input_std=0.3,
    band=0.01,
    noise_std=4e-3,
    rates={"cubic": DUFFING_K3 / DUFFING_THETA["m"]},
    kinds=_MECHANICAL_KINDS,
)


def make_duffing_oscillator(
    n_samples: int = 3000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    exponent: float = 3.0,
) -> Bunch:
    """Oscillator whose physics is linear but whose spring hardens (Duffing oscillator).

    True system, one explicit-Euler step of $\\Delta t = 0.02$ s per sample:

    $$
    \\dot y = v, \\qquad
    m \\dot v = u - k y - c v - k_3 y^3, \\qquad z = y + \\eta,
    $$

    with $m = 1$ kg, $k = 1$ N/m, $c = 0.2$ N s/m and
    $k_3 = 1.5$ N/m³; the physics is the linear mass-spring-damper
    ($k_3 = 0$). The hidden effect $-\\Delta t\\, k_3 y^3 / m$ enters the
    velocity equation (index 1; it pulls ``y`` back towards 0, but its ``sign``, taken
    against the velocity, is set by end and discretisation terms and says little);
    ``hidden_effect["rates"]`` is ``{"cubic": k3/m}`` (1/(m² s²)). At the largest
    $|y|$ (about 1 m) the cubic force is about 1.5 times the linear one. Euler is
    stable while $c > \\Delta t (k + 3 k_3 y^2)$ (the tangent stiffness): the
    eigenvalues' modulus is 0.9982 at $y = 0$, 0.9993 at $|y| = 1.1$ and
    reaches 1 only at $|y| = \\sqrt 2$. Input: force multisine 0-0.5 Hz
    (0.01 cycles/sample), std 0.3 N; the system starts at rest.

    Suggested library: polynomials of degree 3 on ``[y, v, u]`` (20 features); it contains
    the effect exactly.

    Parameters
    ----------
    n_samples : int, default=3000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (m) of the Gaussian position-sensor noise; ``None`` means
        ``4e-3`` m, about 1 % of the position's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (m/s) of a Gaussian disturbance added to the velocity update.
    exponent : float, default=3.0
        $a$ of a spring force $k_3\\, y |y|^{a - 1}$ ($k_3 = 1.5$ in
        N/m<sup>a</sup>): 3 is the cubic spring; another power is one the cubic law only
        approximates (the loop must refine its cubic stiffness into
        [`PowerStiffness`][sk_offwhite.PowerStiffness]). ``hidden_effect["rates"]`` then also holds
        ``"exponent"``.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_duffing(exponent), n_samples, noise_std, random_state, process_noise_std)


def _duffing(exponent: float) -> _Generator:
    """The Duffing generator with a spring of power ``exponent`` (3: `_DUFFING`)."""
    exponent = _check_number("exponent", exponent, "a number in [1, 5]")
    law = f"k3 y|y|^{float(exponent) - 1:g}"
    return _of_power(
        _DUFFING, exponent, (1.0, 3.0, 5.0),
        effect_description=f"Spring -{law} (k3 = {DUFFING_K3} N/m^{float(exponent):g}) in "
        "the velocity equation, its power not cubic.",
        descr=_DUFFING.system.descr.replace("k3 y^3", law).replace(
            "N/m^3", f"N/m^{float(exponent):g}"
        ),
    )  # fmt: skip


def _of_power(spec: _Generator, exponent, bounds: tuple, **described) -> _Generator:
    """``spec`` whose hidden effect takes the power ``exponent`` (its contribution's
    argument of that name), described anew (``described``: the system's
    ``effect_description`` and ``descr``); ``spec`` itself at the default power.
    ``bounds``: ``(lowest, default, highest)``."""
    exponent = float(exponent)
    lowest, default, highest = bounds
    if not lowest <= exponent <= highest:
        raise ValueError(f"exponent must lie in [{lowest:g}, {highest:g}], got {exponent!r}.")
    if exponent == default:
        return spec
    params = {**spec.system.params, "exponent": exponent}
    system = replace(spec.system, params=params, **described)
    return replace(spec, system=system, rates={**spec.rates, "exponent": exponent})


# --------------------------------------------------------------------------------------
# c. Driven pendulum with aerodynamic drag
# --------------------------------------------------------------------------------------

PENDULUM_L, PENDULUM_M, PENDULUM_G = 0.5, 1.0, 9.81
PENDULUM_THETA = {
    "g_over_l": PENDULUM_G / PENDULUM_L,
    "b": 0.3,
    "gain": 1.0 / (PENDULUM_M * PENDULUM_L**2),
}
PENDULUM_CD, PENDULUM_DT = 0.3, 0.005


def pendulum_rhs(x, u, theta):
    """``[omega, -(g/l) sin(theta) - b omega + gain u]``: pendulum driven by the torque ``u``."""
    accel = -theta["g_over_l"] * jnp.sin(x[0]) - theta["b"] * x[1] + theta["gain"] * u[0]
    return jnp.stack([x[1], accel])


def _quadratic_drag_effect(x, u, cd, dt, exponent=2.0):
    """``[0, -dt cd omega |omega|^(exponent - 1)]`` (numpy)."""
    omega = x[..., 1]
    power = _signed_square(omega) if exponent == 2.0 else np.sign(omega) * np.abs(omega) ** exponent
    drag = -dt * cd * power
    return np.stack([np.zeros_like(drag), drag], axis=-1)


def _pendulum_physics(values: dict, x0) -> PhysicsModel:
    return _second_order_physics(pendulum_rhs, values, x0, PENDULUM_DT, ("theta", "omega", "u"))


def _pendulum_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=3) + ps.CustomLibrary(
        [_signed_square], [_TermName("{0}|{0}|")]
    )


_PENDULUM = _Generator(
    system=_SimpleSystem(
        physics=_pendulum_physics,
        theta=PENDULUM_THETA,
        guess={"g_over_l": 15.0, "b": 0.4, "gain": 3.0},
        x0=(0.0, 0.0),
        contribution=_quadratic_drag_effect,
        params={"cd": PENDULUM_CD, "dt": PENDULUM_DT},
        equation=1,
        variables=("omega",),
        effect_description="Aerodynamic drag -cd omega |omega| (cd = 0.3 1/rad) opposing "
        "the angular rate (rate equation).",
        library=_pendulum_library,
        process_target="rate equation",
        descr="Driven pendulum theta'' = -(g/l) sin(theta) - b theta' + u/(m l^2) "
        "- cd theta'|theta'| [SI units], l=0.5 m, m=1 kg, g=9.81 m/s^2, b=0.3 1/s, "
        "cd=0.3 1/rad, Euler dt=5 ms, angle measured; the physics omits the quadratic "
        "drag.\n",
        dt=PENDULUM_DT,
    ),
    input_std=1.0,
    band=0.0075,
    noise_std=4e-3,
    rates={"quadratic_drag": PENDULUM_CD},
    kinds={"states": ("angle", "rate"), "inputs": ("torque",)},
)


def make_pendulum_drag(
    n_samples: int = 3000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    exponent: float = 2.0,
) -> Bunch:
    """Driven pendulum whose physics misses quadratic (aerodynamic) drag.

    True system, one explicit-Euler step of $\\Delta t = 0.005$ s per sample:

    $$
    \\dot\\theta = \\omega, \\qquad
    \\dot\\omega = -\\frac{g}{l} \\sin\\theta - b\\, \\omega + \\frac{u}{m l^2}
    - c_d\\, \\omega |\\omega|, \\qquad z = \\theta + \\eta,
    $$

    with $l = 0.5$ m, $m = 1$ kg, $g = 9.81$ m/s², $b = 0.3$ 1/s
    and $c_d = 0.3$ 1/rad (angle in rad, rate in rad/s, torque ``u`` in N m). The
    physics' parameters are ``g_over_l`` $= g/l = 19.62$ 1/s², ``b`` and ``gain``
    $= 1/(m l^2) = 4$ 1/(kg m²). The hidden effect
    $-\\Delta t\\, c_d\\, \\omega |\\omega|$ enters the rate equation (index 1, sign
    -1); ``hidden_effect["rates"]`` is ``{"quadratic_drag": cd}`` (1/rad). Euler is stable
    for the linearised pendulum when $b > \\Delta t\\, g / l = 0.098$ 1/s (eigenvalues'
    modulus 0.9995 with $b = 0.3$); the drag only adds damping. Input: torque
    multisine 0-1.5 Hz (0.0075 cycles/sample) around the 0.7 Hz natural frequency, std
    1 N m; $|\\theta|$ stays below about 1 rad and $|\\omega|$ below about
    5 rad/s (no full rotations). The pendulum starts hanging at rest.

    Suggested library: polynomials of degree 3 plus the signed square ``a |a|`` on
    ``[theta, omega, u]`` (23 features); it contains the effect exactly.

    Parameters
    ----------
    n_samples : int, default=3000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (rad) of the Gaussian angle-sensor noise; ``None`` means
        ``4e-3`` rad, about 1 % of the angle's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (rad/s) of a Gaussian disturbance added to the rate update.
    exponent : float, default=2.0
        $a$ of a drag $-c_d\\, \\omega |\\omega|^{a - 1}$ ($c_d = 0.3$
        in rad<sup>1-a</sup> s<sup>a-2</sup>): 2 is the quadratic drag; between 1 and 2 a drag
        the quadratic law only approximates (the loop must refine its quadratic drag into
        [`PowerDrag`][sk_offwhite.PowerDrag]). ``hidden_effect["rates"]`` then also holds
        ``"exponent"``.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_pendulum(exponent), n_samples, noise_std, random_state, process_noise_std)


def _pendulum(exponent: float) -> _Generator:
    """The pendulum's generator with a drag of power ``exponent`` (2: `_PENDULUM`)."""
    exponent = _check_number("exponent", exponent, "a number in [1, 3]")
    power = f"{float(exponent) - 1:g}"
    descr = (
        _PENDULUM.system.descr.replace("cd theta'|theta'|", f"cd theta'|theta'|^{power}")
        .replace("quadratic drag", f"drag of power {float(exponent):g}")
        .replace(f"cd={PENDULUM_CD} 1/rad", f"cd={PENDULUM_CD}")
    )
    return _of_power(
        _PENDULUM, exponent, (1.0, 2.0, 3.0),
        effect_description=f"Drag -cd omega |omega|^{power} (cd = {PENDULUM_CD}) opposing "
        "the angular rate (rate equation).",
        descr=descr,
    )  # fmt: skip


# --------------------------------------------------------------------------------------
# d. First-order motor with a dead zone in its drive
# --------------------------------------------------------------------------------------

DEAD_ZONE_THETA = {"a": 2.0, "b": 4.0}
DEAD_ZONE_W, DEAD_ZONE_DT = 0.3, 0.05


def _dead_zone_effect(x, u, b, w, dt):
    """``dt b (dz(u) - u) = -dt b clip(u, -w, w)`` on the speed equation (numpy)."""
    return (-dt * b * np.clip(u[..., 0], -w, w))[..., None]


def _dead_zone_physics(values: dict, x0) -> PhysicsModel:
    return _first_order_physics(motor_rhs, values, x0, DEAD_ZONE_DT, ("omega", "u"))


_DEAD_ZONE = _Generator(
    system=_SimpleSystem(
        physics=_dead_zone_physics,
        theta=DEAD_ZONE_THETA,
        guess={"a": 1.5, "b": 3.0},
        x0=(0.0,),
        contribution=_dead_zone_effect,
        params={"b": DEAD_ZONE_THETA["b"], "w": DEAD_ZONE_W, "dt": DEAD_ZONE_DT},
        equation=0,
        variables=("u",),
        effect_description="Dead zone of half-width w = 0.3 V in the drive: b dz(u) with "
        "dz(u) = sign(u) max(|u| - w, 0) instead of b u.",
        library=_polynomial_library,
        process_target="speed equation",
        descr="First-order motor omega' = -a omega + b dz(u), dz(u) = sign(u) max(|u| - w, 0) "
        "[SI units], a=2 1/s, b=4 rad/(V s^2), w=0.3 V, Euler dt=0.05 s, speed measured; the "
        "physics assumes the linear drive b u.\n",
        dt=DEAD_ZONE_DT,
    ),
    input_std=0.8,
    band=0.03,
    noise_std=1e-2,
    rates={"dead_zone": DEAD_ZONE_W, "gain": DEAD_ZONE_THETA["b"]},
    kinds={"states": ("rate",), "inputs": ("voltage",)},
)


def make_dead_zone_motor(
    n_samples: int = 2000,
    noise_std: float | None = None,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """First-order motor whose physics assumes a linear drive that has a dead zone.

    True system, one explicit-Euler step of $\\Delta t = 0.05$ s per sample:

    $$
    \\dot\\omega = -a \\omega + b\\, \\mathrm{dz}(u), \\qquad
    \\mathrm{dz}(u) = \\mathrm{sign}(u) \\max(|u| - w, 0), \\qquad z = \\omega + \\eta,
    $$

    with $a = 2$ 1/s, $b = 4$ rad/(V s²) and $w = 0.3$ V (speed in rad/s,
    voltage ``u`` in V); the physics uses $b u$. The hidden effect
    $\\Delta t\\, b (\\mathrm{dz}(u) - u) = -\\Delta t\\, b\\, \\mathrm{clip}(u, -w, w)$
    depends on ``u`` only (sign -1: the drive is weaker than linear);
    ``hidden_effect["rates"]`` is ``{"dead_zone": w, "gain": b}``, so that the rate is
    ``-gain * clip(u, -dead_zone, dead_zone)`` (rad/s²). Euler is stable:
    $|1 - a \\Delta t| = 0.9$. Input: zero-mean multisine 0-0.6 Hz
    (0.03 cycles/sample) with std 0.8 V, so that $|u|$ is inside the dead zone about
    30 % of the time.

    Suggested library: polynomials of degree 3 on ``[omega, u]`` (10 features); it only
    approximates the clipped input (least squares explains about 89 % of the effect's
    variance).

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float or None, default=None
        Standard deviation (rad/s) of the Gaussian speed-sensor noise; ``None`` means
        ``1e-2`` rad/s, about 1 % of the speed's standard deviation.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (rad/s) of a Gaussian disturbance added to the speed update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    return _generate(_DEAD_ZONE, n_samples, noise_std, random_state, process_noise_std)
