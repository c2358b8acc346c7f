"""Synthetic systems whose declared physics misses one effect.

Every generator returns an estimation record and an independent validation record of a
*true* discrete-time system

$$
x_{k+1} = f(x_k, u_k; \\bar\\theta) + \\Delta(x_k, u_k) + w_k, \\qquad
z_k = h(x_k) + e_k,
$$

together with the incomplete `PhysicsModel` a user would
write (``f`` and ``h`` only, parameters at a plausible guess), the true parameters, a
description of the hidden effect $\\Delta$ and a small pysindy library able to
represent (or approximate) it. The records are simulated in float64 with the physics' own
``step`` (jitted under a local ``jax.enable_x64``), so that with ``w = 0``

``physics.step(x[k], u[k], true_parameters) + hidden_effect["state_function"](x[k], u[k])``

reproduces ``x[k+1]`` to rounding error.

Conventions shared by all generators: ``x[k+1]`` is produced from ``x[k]`` and ``u[k]``
(``k = 0 .. n-2``; the last input row drives the first state after the record);
``hidden_effect["function"]`` is the contribution to state equation
``hidden_effect["equation"]`` and ``hidden_effect["state_function"]`` the full
``(n_states,)`` contribution; ``hidden_effect["sign"]`` is the sign of
``sum_k Delta_k * x_{equation,k}`` (``-1``: the effect drains, damps or opposes that state).
"""

from __future__ import annotations

from dataclasses import replace

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._cascaded_tanks import (
    SATURATION_LEVEL,
    SQRT_EPS,
    cascaded_tanks_physics,
    safe_sqrt,
)
from sk_offwhite.datasets._common import (
    _bunch,
    _check_fraction,
    _check_n_samples,
    _check_number,
    _check_random_state,
    _check_scale,
    _effect_sign,
    _gaussian,
    _hidden_effect,
    _HiddenEffect,
    _multisine,
    _noise_stds,
    _record_noise,
    _rollout,
    _simple_dataset,
    _SimpleSystem,
    _softplus,
    _tanh,
    _TermName,
    _xp,
)
from sk_offwhite.datasets._vehicle import make_vehicle_lateral, vehicle_dictionary_library
from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = [
    "make_cascaded_tanks",
    "make_friction_oscillator",
    "make_leaky_tank",
    "make_saturating_actuator",
    "make_vehicle_lateral",
    "vehicle_dictionary_library",
]

POSITIVE = (1e-6, None)

# --------------------------------------------------------------------------------------
# b. Cascaded tanks with overflow and saturation
# --------------------------------------------------------------------------------------

TANKS_K = {"k1": 0.1, "k2": 0.075, "k3": 0.07, "k4": 0.088}
TANKS_X0 = (5.0, 6.0)
_TANKS_TS = 4.0


def _tanks_candidate(x, u, k1, k2, k3, k4, ts):
    """Eq. (21) step in numpy (same operations as the physics), shape ``(..., 2)``."""
    root1 = np.sqrt(np.maximum(x[..., 0], SQRT_EPS))
    root2 = np.sqrt(np.maximum(x[..., 1], SQRT_EPS))
    rate1 = -k1 * root1 + k4 * u[..., 0]
    rate2 = k2 * root1 - k3 * root2
    return np.stack([x[..., 0] + ts * rate1, x[..., 1] + ts * rate2], axis=-1)


def _tanks_limit(candidate, level, fraction, overflow, saturation):
    """Overflow of the upper tank (``fraction`` of the excess to the lower tank), then the
    lower tank capped at ``level``."""
    excess = np.maximum(candidate[..., 0] - level, 0.0) if overflow else 0.0 * candidate[..., 0]
    lower = candidate[..., 1] + fraction * excess
    lower = np.minimum(lower, level) if saturation else lower
    return np.stack([candidate[..., 0] - excess, lower], axis=-1)


def _tanks_effect(x, u, k1, k2, k3, k4, ts, level, fraction, overflow, saturation):
    """Additive contribution ``limit(f(x, u)) - f(x, u)`` of overflow and saturation."""
    candidate = _tanks_candidate(x, u, k1, k2, k3, k4, ts)
    return _tanks_limit(candidate, level, fraction, overflow, saturation) - candidate


class _TanksLimit:
    def __init__(self, **params):
        self.params = params

    def __call__(self, candidate):
        return _tanks_limit(candidate, **self.params)


def _tanks_input(rng, n: int) -> np.ndarray:
    """Benchmark-like pump voltage: multisine 0-0.0144 Hz at Ts = 4 s, mean 2.8, std 1."""
    return np.clip(2.8 + _multisine(rng, n, 0.0144 * _TANKS_TS), 0.0, None)[:, None]


def _tanks_record(rng, n, physics, limit, stds, saturation):
    u = _tanks_input(rng, n)
    w = _gaussian(rng, (n - 1, 2), stds[1])
    x = _rollout(physics, TANKS_K, np.array(TANKS_X0), u, None, w, limit)
    e = _gaussian(rng, (n, 1), stds[0])
    z = x[:, 1:] + e
    return (u, x, np.minimum(z, SATURATION_LEVEL) if saturation else z), (e, w)


def _tanks_hidden(params, overflow, saturation, sign) -> dict | None:
    if not (overflow or saturation):
        return None
    if overflow:
        equation, variables = 0, ("x1", "u")
        text = (
            "Upper-tank overflow: the level x1 is capped at 10 and a fraction "
            f"{params['fraction']:g} of the excess spills into the lower tank (equation 1)"
        )
        text += ", whose level and sensor saturate at 10." if saturation else "."
    else:
        equation, variables = 1, ("x1", "x2")
        text = "Saturation of the lower-tank level (and sensor) at 10."
    return _hidden_effect(_tanks_effect, params, equation, variables, sign, text)


_TANKS_DESCR = """\
Synthetic cascaded tanks with overflow and saturation
=====================================================

True system: eq. (21) of Donati et al. (Euler step, Ts = 4 s) with
k = [k1, k2, k3, k4] = [0.1, 0.075, 0.07, 0.088] and x0 = [5, 6] (shared by the estimation
and validation records, as in the benchmark), followed by the hard limits the physics
omits: upper-tank overflow at x1 = 10 (half of the excess spills into the lower tank, the
rest is lost) and the lower tank capped at 10; the sensor reading z = x2 + e is clipped at
10 as well. Input: multisine 0-0.0144 Hz, mean 2.8, std 1, clipped at 0 (as the measured
benchmark). With only x2 measured, (k1, k2, k4, x1(0)) are identifiable only up to the
scaling of x1; fix e.g. k4 to make the true values recoverable.
"""


def make_cascaded_tanks(
    n_samples: int = 1024,
    overflow: bool = True,
    saturation: bool = True,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    overflow_fraction: float = 0.5,
) -> Bunch:
    """Cascaded tanks of eq. (21) with the overflow and saturation the physics omits.

    True system (Euler step of
    [`cascaded_tanks_physics`][sk_offwhite.datasets.cascaded_tanks_physics], $T_s = 4$ s, $k = [0.1,
    0.075, 0.07, 0.088]$):

    $$
    \\tilde x_{k+1} &= f(x_k, u_k; k) + w_k, \\qquad
    o_k = \\max(\\tilde x_{1,k+1} - 10,\\ 0), \\\\
    x_{1,k+1} &= \\tilde x_{1,k+1} - o_k, \\qquad
    x_{2,k+1} = \\min(\\tilde x_{2,k+1} + \\rho o_k,\\ 10), \\\\
    z_k &= \\min(x_{2,k} + \\eta_k,\\ 10),
    $$

    with spill fraction $\\rho$ = ``overflow_fraction``. The levels were chosen (the
    paper's identified ``k = [0.076, 0.027, 0.042, 0.039]`` never reach 10 with the benchmark
    input) so that both limits act, on a few percent of the samples each.

    The hidden effect is ``limit(f) - f``; it enters equation 0 (overflow, the dominant
    part, depends on ``x1`` and ``u`` through the candidate level) and equation 1 (spill
    and saturation); ``hidden_effect["state_function"]`` returns both. With process noise
    the limits act on ``f + w``.

    Parameters
    ----------
    n_samples : int, default=1024
        Length of each record.
    overflow, saturation : bool, default=True
        Include the upper-tank overflow / the lower-tank and sensor saturation. With both
        ``False`` the physics is exact and ``hidden_effect`` is ``None``.
    noise_std : float, default=0.02
        Standard deviation of the Gaussian output noise (about 40 dB SNR, as the benchmark).
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of the Gaussian process noise ``w`` on both levels.
    overflow_fraction : float, default=0.5
        Fraction of the upper-tank overflow that reaches the lower tank, in $[0, 1]$ (0: all
        of it leaves the system, 1: all of it reaches the lower tank).

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, saturation_level, DESCR``.
        ``physics`` is [`cascaded_tanks_physics`][sk_offwhite.datasets.cascaded_tanks_physics] with
        ``k_init = 0.05`` and ``x0 = [z0, z0]`` (the paper's initialisation).
    """
    n = _check_n_samples(n_samples)
    stds = (
        _check_scale("noise_std", noise_std),
        _check_scale("process_noise_std", process_noise_std),
    )
    rng = _check_random_state(random_state)
    flags = {"overflow": bool(overflow), "saturation": bool(saturation)}
    fraction = _check_fraction("overflow_fraction", overflow_fraction)
    limits = {"level": SATURATION_LEVEL, "fraction": fraction, **flags}
    plain = cascaded_tanks_physics(x0=TANKS_X0, sampling_time=_TANKS_TS)
    est, noise_est = _tanks_record(rng, n, plain, _TanksLimit(**limits), stds, saturation)
    val, noise_val = _tanks_record(rng, n, plain, _TanksLimit(**limits), stds, saturation)
    u, x, z = est
    params = {**TANKS_K, "ts": _TANKS_TS, **limits}
    equation = 0 if overflow else 1
    sign = _effect_sign(_HiddenEffect(_tanks_effect, params, equation), x, u, equation)
    gaussian = {"distribution": "gaussian"}
    noise = _record_noise(
        {**gaussian, "std": stds[0], "applied_to": "z = min(x2 + e, 10)"},
        {**gaussian, "std": stds[1], "applied_to": "both levels, before the limits"},
        noise_est,
        noise_val,
    )
    physics = cascaded_tanks_physics(x0=(z[0, 0], z[0, 0]), sampling_time=_TANKS_TS)
    return _bunch(
        physics,
        (est, val),
        TANKS_K,
        (TANKS_X0, TANKS_X0),
        _tanks_hidden(params, overflow, saturation, sign),
        _tanks_library(),
        noise,
        _TANKS_DESCR,
        sampling_time=_TANKS_TS,
        saturation_level=SATURATION_LEVEL,
    )


def _hinge(a):
    """Smooth hinge ``softplus(8 (a - 9.75)) / 8``, about ``max(a - 9.75, 0)`` near a tank top."""
    return _softplus(8.0 * (a - 9.75)) / 8.0


def _hinge_times(a, b):
    return _hinge(a) * b


def _hinge_times_square(a, b):
    return _hinge(a) * b * b


def _tanks_library():
    """Degree-2 polynomials plus smooth hinges at the tank top times ``1, b, b^2`` on
    ``[x1, x2, u]`` (19 features); least squares on them explains about 97-99 % of the
    variance of the overflow contribution to equation 0."""
    import pysindy as ps  # imported when a dictionary is asked for

    functions = [_hinge, _hinge_times, _hinge_times_square]
    names = [_TermName("hinge({0})"), _TermName("hinge({0}) {1}"), _TermName("hinge({0}) {1}^2")]
    return ps.PolynomialLibrary(degree=2) + ps.CustomLibrary(functions, names)


# --------------------------------------------------------------------------------------
# c. Mass-spring-damper with Coulomb friction
# --------------------------------------------------------------------------------------

FRICTION_THETA = {"m": 1.0, "k": 4.0, "c": 0.4}
FRICTION_FC, FRICTION_EPS, FRICTION_DT = 0.5, 0.1, 0.05
FRICTION_VS = 0.3
"""The Stribeck velocity of
[`make_friction_oscillator`][sk_offwhite.datasets.make_friction_oscillator] (about 20 % of the
velocity's RMS)."""


def oscillator_rhs(x, u, theta):
    """``[v, (u - k x - c v) / m]``: mass-spring-damper driven by the force ``u``."""
    accel = (u[0] - theta["k"] * x[0] - theta["c"] * x[1]) / theta["m"]
    return jnp.stack([x[1], accel])


def _friction_effect(x, u, fc, eps, m, dt, stribeck=0.0):
    """``[0, -dt (Fc + Fs exp(-(v / vs)^2)) tanh(v / eps) / m]`` (numpy; Fs = ``stribeck``,
    vs = `FRICTION_VS`)."""
    v = x[..., 1]
    level = fc if stribeck == 0.0 else fc + stribeck * np.exp(-((v / FRICTION_VS) ** 2))
    drag = -dt * level * np.tanh(v / eps) / m
    return np.stack([np.zeros_like(drag), drag], axis=-1)


def _signed_square(a):
    return a * _xp(a).abs(a)


def _tanh_10(a):
    return _tanh(10.0 * a)


def make_friction_oscillator(
    n_samples: int = 2000,
    noise_std: float = 0.005,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    stribeck: float = 0.0,
) -> Bunch:
    """Mass-spring-damper whose physics misses Coulomb friction.

    True system, one explicit-Euler step of $\\Delta t = 0.05$ s per sample
    (``PhysicsModel.from_ode(..., method="euler")``):

    $$
    \\dot x = v, \\qquad
    m \\dot v = u - k x - c v - F_c \\tanh(v / \\varepsilon), \\qquad z = x + \\eta,
    $$

    with $m = 1, k = 4, c = 0.4, F_c = 0.5, \\varepsilon = 0.1$. The physics omits the
    friction; in discrete time the hidden effect is exactly
    $-\\Delta t F_c \\tanh(v/\\varepsilon) / m$ in the velocity equation (index 1).
    Euler is used so that the effect stays additive and inside ``suggested_library``
    (polynomials of degree 2 plus ``tanh(10 .)`` on ``[x, v, u]``, 13 features). Input: force
    multisine 0-0.05 cycles/sample, std 2 N; the system starts at rest.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float, default=0.005
        Standard deviation of the Gaussian position-sensor noise (about 1 % of the
        position's standard deviation).
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of a Gaussian disturbance added to the velocity update.
    stribeck : float, default=0.0
        $F_s \\ge 0$: the friction level rises to $F_c + F_s$ near rest,
        $(F_c + F_s e^{-(v/v_s)^2}) \\tanh(v/\\varepsilon)$ with $v_s = 0.3$
        (`FRICTION_VS`), a Stribeck friction (the loop must refine its Coulomb
        friction into the Stribeck one). ``hidden_effect["rates"]`` then holds
        ``{"coulomb": 0.5, "stribeck": Fs, "stribeck_velocity": 0.3}``.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, DESCR``.
    """
    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    system, rates = _friction_system(stribeck)
    rng = _check_random_state(random_state)
    inputs = [2.0 * _multisine(rng, n, 0.05)[:, None] for _ in range(2)]
    data = _simple_dataset(system, rng, n, inputs, stds)
    if rates:
        data.hidden_effect["rates"] = rates
    return data


def _friction_system(stribeck: float) -> tuple:
    """The friction oscillator's system with a Stribeck level ``stribeck`` (0: the
    Coulomb friction, `_FRICTION_SYSTEM`) and the rates to report (none for 0)."""
    stribeck = _check_number("stribeck", stribeck, "a finite number >= 0")
    if not (np.isfinite(stribeck) and stribeck >= 0):
        raise ValueError(f"stribeck must be finite and >= 0, got {stribeck!r}.")
    if stribeck == 0.0:
        return _FRICTION_SYSTEM, None
    law = f"(Fc + {stribeck:g} exp(-(v/{FRICTION_VS:g})^2)) tanh(v/eps)"
    system = replace(
        _FRICTION_SYSTEM,
        params={**_FRICTION_SYSTEM.params, "stribeck": stribeck},
        effect_description=f"Stribeck friction -{law} opposing the velocity (velocity equation).",
        descr=_FRICTION_SYSTEM.descr.replace("Fc tanh(x'/eps)", law).replace(
            "Coulomb friction", "Stribeck friction"
        ),
    )
    return system, {"coulomb": FRICTION_FC, "stribeck": stribeck, "stribeck_velocity": FRICTION_VS}


def _oscillator_physics(values: dict, x0) -> PhysicsModel:
    return PhysicsModel.from_ode(
        oscillator_rhs,
        FRICTION_DT,
        output=0,
        parameters={name: Parameter(v, POSITIVE) for name, v in values.items()},
        n_states=2,
        n_inputs=1,
        method="euler",
        x0=x0,
        state_names=("x", "v"),
        input_names=("u",),
        output_names=("x",),
    )


def _friction_library():
    import pysindy as ps  # imported when a dictionary is asked for

    tanh_terms = ps.CustomLibrary([_tanh_10], [_TermName("tanh(10 {0})")])
    return ps.PolynomialLibrary(degree=2) + tanh_terms


_FRICTION_SYSTEM = _SimpleSystem(
    physics=_oscillator_physics,
    theta=FRICTION_THETA,
    guess={"m": 1.2, "k": 3.0, "c": 0.6},
    x0=(0.0, 0.0),
    contribution=_friction_effect,
    params={"fc": FRICTION_FC, "eps": FRICTION_EPS, "m": FRICTION_THETA["m"], "dt": FRICTION_DT},
    equation=1,
    variables=("v",),
    effect_description="Coulomb friction -Fc tanh(v / 0.1) opposing the velocity "
    "(velocity equation).",
    library=_friction_library,
    process_target="velocity equation",
    descr="Mass-spring-damper m x'' + c x' + k x = u - Fc tanh(x'/eps), m=1, k=4, c=0.4, "
    "Fc=0.5, eps=0.1, Euler dt=0.05 s, position measured; the physics omits the "
    "Coulomb friction.\n",
    dt=FRICTION_DT,
)


# --------------------------------------------------------------------------------------
# d. First-order motor with a saturating actuator
# --------------------------------------------------------------------------------------

ACTUATOR_THETA = {"a": 2.0, "b": 4.0}
ACTUATOR_UMAX, ACTUATOR_DT = 1.0, 0.05


def motor_rhs(x, u, theta):
    """``[-a omega + b u]``: first-order motor speed with a linear actuator."""
    return jnp.stack([-theta["a"] * x[0] + theta["b"] * u[0]])


def _actuator_effect(x, u, b, umax, dt):
    """``dt b (umax tanh(u / umax) - u)`` on the speed equation (numpy)."""
    return (dt * b * (umax * np.tanh(u[..., 0] / umax) - u[..., 0]))[..., None]


def _first_order_physics(rhs, values, x0, dt, names, kinds=None) -> PhysicsModel:
    return PhysicsModel.from_ode(
        rhs,
        dt,
        output=0,
        parameters={name: Parameter(v, POSITIVE) for name, v in values.items()},
        n_states=1,
        n_inputs=1,
        method="euler",
        x0=x0,
        state_names=names[:1],
        input_names=names[1:],
        output_names=names[:1],
        state_kinds=None if kinds is None else kinds[:1],
        input_kinds=None if kinds is None else kinds[1:],
    )


def _motor_physics(values: dict, x0) -> PhysicsModel:
    return _first_order_physics(
        motor_rhs, values, x0, ACTUATOR_DT, ("omega", "u"), ("rate", "voltage")
    )


def _actuator_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=3) + ps.CustomLibrary(
        [_signed_square], [_TermName("{0}|{0}|")]
    )


_ACTUATOR_SYSTEM = _SimpleSystem(
    physics=_motor_physics,
    theta=ACTUATOR_THETA,
    guess={"a": 1.5, "b": 3.0},
    x0=(0.0,),
    contribution=_actuator_effect,
    params={"b": ACTUATOR_THETA["b"], "umax": ACTUATOR_UMAX, "dt": ACTUATOR_DT},
    equation=0,
    variables=("u",),
    effect_description="Actuator saturation: the drive is b umax tanh(u / umax) instead of "
    "b u, less than linear at large |u|.",
    library=_actuator_library,
    process_target="speed equation",
    descr="First-order motor omega' = -a omega + b umax tanh(u/umax), a=2, b=4, umax=1, "
    "Euler dt=0.05 s, speed measured; the physics assumes the linear drive b u.\n",
    dt=ACTUATOR_DT,
)


def make_saturating_actuator(
    n_samples: int = 1000,
    noise_std: float = 0.01,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """First-order motor whose physics assumes a linear actuator that actually saturates.

    True system, one explicit-Euler step of $\\Delta t = 0.05$ s per sample:

    $$
    \\dot\\omega = -a \\omega + b\\, u_{\\max} \\tanh(u / u_{\\max}), \\qquad
    z = \\omega + \\eta,
    $$

    with $a = 2, b = 4, u_{\\max} = 1$; the physics uses $b u$. The hidden
    effect $\\Delta t\\, b (u_{\\max} \\tanh(u/u_{\\max}) - u)$ depends on ``u`` only and
    is smaller than linear at large $|u|$ (sign -1). Input: multisine 0-0.03
    cycles/sample with std 0.8 ($|u|$ reaches about $2 u_{\\max}$).

    Suggested library: polynomials of degree 3 plus the signed square ``a |a|`` on
    ``[omega, u]`` (12 features); it approximates the effect (least squares explains about
    99.9 % of its variance) but deliberately contains no ``tanh``: with ``tanh(u)`` in the
    library the sparsest exact model would be ``b = 0`` and ``delta = dt b tanh(u)``, i.e.
    the correction would absorb the physical actuator gain.

    Parameters
    ----------
    n_samples : int, default=1000
        Length of each record.
    noise_std : float, default=0.01
        Standard deviation of the Gaussian speed-sensor noise (about 1 % of the speed's
        standard deviation).
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of a Gaussian disturbance added to the speed update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, DESCR``.
    """
    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    rng = _check_random_state(random_state)
    inputs = [0.8 * _multisine(rng, n, 0.03)[:, None] for _ in range(2)]
    return _simple_dataset(_ACTUATOR_SYSTEM, rng, n, inputs, stds)


# --------------------------------------------------------------------------------------
# e. Tank with an unmodelled leak
# --------------------------------------------------------------------------------------

LEAKY_THETA = {"k": 0.5, "b": 0.5}
LEAKY_C, LEAKY_DT, LEAKY_X0 = 0.05, 1.0, 4.0


def tank_rhs(x, u, theta):
    """``[-k sqrt(x) + b u]``: single tank with a free outlet (Torricelli), safe square root."""
    return jnp.stack([-theta["k"] * safe_sqrt(x[0]) + theta["b"] * u[0]])


def _leak_effect(x, u, c, dt):
    """``-dt c x`` on the level equation (numpy)."""
    return -dt * c * x[..., :1]


def _tank_physics(values: dict, x0) -> PhysicsModel:
    return _first_order_physics(tank_rhs, values, x0, LEAKY_DT, ("x", "u"), ("level", "flow"))


def _leaky_library():
    import pysindy as ps  # imported when a dictionary is asked for

    return ps.PolynomialLibrary(degree=2)


_LEAKY_SYSTEM = _SimpleSystem(
    physics=_tank_physics,
    theta=LEAKY_THETA,
    guess={"k": 0.4, "b": 0.6},
    x0=(LEAKY_X0,),
    contribution=_leak_effect,
    params={"c": LEAKY_C, "dt": LEAKY_DT},
    equation=0,
    variables=("x",),
    effect_description="Unmodelled leak -c x draining the tank in proportion to its level.",
    library=_leaky_library,
    process_target="level equation",
    descr="Tank x' = -k sqrt(x) + b u - c x, k=0.5, b=0.5, c=0.05, Euler dt=1 s, level "
    "measured; the physics omits the leak -c x.\n",
    dt=LEAKY_DT,
    guess_x0_measured=True,
)


def make_leaky_tank(
    n_samples: int = 1000,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """Single tank whose physics misses a leak.

    True system, one explicit-Euler step of $\\Delta t = 1$ s per sample:

    $$
    \\dot x = -k \\sqrt{x} + b u - c x, \\qquad z = x + \\eta,
    $$

    with $k = 0.5, b = 0.5, c = 0.05$ and $x(0) = 4$. The physics omits the
    leak $-c x$ (a seepage proportional to the level, which a re-fitted outlet
    coefficient ``k`` cannot mimic); in discrete time the hidden effect is exactly
    $-\\Delta t\\, c\\, x$ (sign -1). Input: pump flow, multisine 0-0.02 cycles/sample,
    mean 2, std 0.6, clipped at 0. Suggested library: polynomials of degree 2 on ``[x, u]``
    (6 features). Square roots use [`safe_sqrt`][sk_offwhite.datasets.safe_sqrt].

    Parameters
    ----------
    n_samples : int, default=1000
        Length of each record.
    noise_std : float, default=0.02
        Standard deviation of the Gaussian level-sensor noise (about 1 % of the level's
        standard deviation).
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of a Gaussian disturbance added to the level update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, DESCR``.
    """
    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    rng = _check_random_state(random_state)
    inputs = [np.clip(2.0 + 0.6 * _multisine(rng, n, 0.02), 0.0, None)[:, None] for _ in range(2)]
    return _simple_dataset(_LEAKY_SYSTEM, rng, n, inputs, stds)
