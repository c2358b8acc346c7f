"""Vehicle lateral dynamics with an unmodelled term (Donati et al., Section 5.1)."""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

if TYPE_CHECKING:
    import pysindy as ps

from sk_offwhite.datasets._common import (
    _bunch,
    _check_n_samples,
    _check_random_state,
    _check_scale,
    _effect_sign,
    _hidden_effect,
    _HiddenEffect,
    _multisine,
    _ones_like,
    _record_noise,
    _rollout,
    _TermName,
    _uniform,
    printable,
)
from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = ["make_vehicle_lateral", "vehicle_dictionary_library"]

VEHICLE_THETA = {"theta1": 2.0, "theta2": -1.087, "theta3": -1.070, "theta4": 3.715}
VEHICLE_DELTA = (-9.625, 10.69, -11.52)
_VEHICLE_BURN_IN = 200
_STEERING_BAND = 0.02  # cycles/sample
_SPEED_BAND = 0.1  # cycles/sample: p_k and p_(k-1) must differ (see make_vehicle_lateral)


def vehicle_step(x, u, theta):
    """Known part of the vehicle lateral dynamics (``jax.numpy``).

    ``f(x, u) = [th1 x1 + th2 x2 + th3 x1 x5 + th4 x4 x6, x1, u1, x3, u2, x5]``.
    """
    yaw = (
        theta["theta1"] * x[0]
        + theta["theta2"] * x[1]
        + theta["theta3"] * x[0] * x[4]
        + theta["theta4"] * x[3] * x[5]
    )
    return jnp.stack([yaw, x[0], u[0], x[2], u[1], x[4]])


def _vehicle_delta(x, u, a, b, c):
    """``[a x1 x6 + b x2 x6 + c x2 x6^2, 0, 0, 0, 0, 0]`` (numpy)."""
    x1, x2, x6 = x[..., 0], x[..., 1], x[..., 5]
    delta = a * x1 * x6 + b * x2 * x6 + c * x2 * x6**2
    zeros = np.zeros_like(delta)
    return np.stack([delta, zeros, zeros, zeros, zeros, zeros], axis=-1)


def _vehicle_signals(rng, length: int, steering_std: float, speed_range) -> np.ndarray:
    """Steering ``s`` (band-limited, rad) and inverse speed ``p = 1/v`` (s/m), ``(length, 2)``."""
    steering = steering_std * _multisine(rng, length, _STEERING_BAND)
    varying = _multisine(rng, length, _SPEED_BAND)
    low, high = speed_range
    speed = 0.5 * (low + high) + 0.5 * (high - low) * varying / np.max(np.abs(varying))
    return np.column_stack([steering, 1.0 / speed])


# Dictionary phi of Section 5.1, each term a function of the full vector [x1..x6, u1, u2].
def _phi_one(x1, x2, x3, x4, x5, x6, u1, u2):
    return _ones_like(x1)


def _phi_x3(x1, x2, x3, x4, x5, x6, u1, u2):
    return x3


def _phi_x4(x1, x2, x3, x4, x5, x6, u1, u2):
    return x4


def _phi_x5(x1, x2, x3, x4, x5, x6, u1, u2):
    return x5


def _phi_x6(x1, x2, x3, x4, x5, x6, u1, u2):
    return x6


def _phi_x3_sq(x1, x2, x3, x4, x5, x6, u1, u2):
    return x3 * x3


def _phi_x4_sq(x1, x2, x3, x4, x5, x6, u1, u2):
    return x4 * x4


def _phi_x5_sq(x1, x2, x3, x4, x5, x6, u1, u2):
    return x5 * x5


def _phi_x4_x6(x1, x2, x3, x4, x5, x6, u1, u2):
    return x4 * x6


def _phi_x1_x6(x1, x2, x3, x4, x5, x6, u1, u2):
    return x1 * x6


def _phi_x2_x6(x1, x2, x3, x4, x5, x6, u1, u2):
    return x2 * x6


def _phi_x2_x6_sq(x1, x2, x3, x4, x5, x6, u1, u2):
    return x2 * x6 * x6


_VEHICLE_TERMS = (
    ("1", _phi_one, "1"),
    ("x3", _phi_x3, "{2}"),
    ("x4", _phi_x4, "{3}"),
    ("x5", _phi_x5, "{4}"),
    ("x6", _phi_x6, "{5}"),
    ("x3^2", _phi_x3_sq, "{2}^2"),
    ("x4^2", _phi_x4_sq, "{3}^2"),
    ("x5^2", _phi_x5_sq, "{4}^2"),
    ("x4 x6", _phi_x4_x6, "{3} {5}"),
    ("x1 x6", _phi_x1_x6, "{0} {5}"),
    ("x2 x6", _phi_x2_x6, "{1} {5}"),
    ("x2 x6^2", _phi_x2_x6_sq, "{1} {5}^2"),
)

# Shared name functions: libraries from separate calls then describe the same dictionary
# (same functions, same names), so the package compiles it once for all of them.
_VEHICLE_TERM_NAMES = tuple(_TermName(name) for _, _, name in _VEHICLE_TERMS)


class DictionaryTerm:
    """One dictionary function of the full vector ``v = [x; u]`` (last axis), picklable.

    Works on numpy and JAX arrays: ``term(v) = phi(v[..., 0], ..., v[..., n-1])``.
    """

    def __init__(self, phi: Callable, n_variables: int = 8):
        self.phi, self.n_variables = phi, int(n_variables)

    def __call__(self, v):
        return self.phi(*[v[..., j] for j in range(self.n_variables)])

    def __eq__(self, other) -> bool:
        return isinstance(other, DictionaryTerm) and (other.phi, other.n_variables) == (
            self.phi,
            self.n_variables,
        )

    def __hash__(self) -> int:
        return hash((DictionaryTerm, self.phi, self.n_variables))

    def __repr__(self) -> str:
        return f"DictionaryTerm({self.phi.__name__})"


def vehicle_dictionary_library() -> ps.CustomLibrary:
    """The 12-function dictionary of Section 5.1 as a pysindy ``CustomLibrary``.

    Each library function takes all eight variables ``(x1, .., x6, u1, u2)``, so pysindy
    applies it to the single combination of the eight inputs: fitted on ``[x; u]`` the
    library yields exactly the 12 features
    ``[1, x3, x4, x5, x6, x3^2, x4^2, x5^2, x4 x6, x1 x6, x2 x6, x2 x6^2]`` in this order.
    """
    import pysindy as ps  # imported when a dictionary is asked for

    library = ps.CustomLibrary(
        library_functions=[phi for _, phi, _ in _VEHICLE_TERMS],
        function_names=list(_VEHICLE_TERM_NAMES),
    )
    return printable(library)


def _vehicle_physics(x0) -> PhysicsModel:
    guess = {name: round(0.9 * value, 2) for name, value in VEHICLE_THETA.items()}
    return PhysicsModel(
        vehicle_step,
        output=0,
        parameters={name: Parameter(value) for name, value in guess.items()},
        n_states=6,
        n_inputs=2,
        x0=x0,
        state_names=("x1", "x2", "x3", "x4", "x5", "x6"),
        input_names=("u1", "u2"),
        output_names=("y",),
    )


def _vehicle_record(rng, n, effect, bounds, steering_std, speed_range, physics):
    """One record: signals with burn-in, simulation, bounded noise."""
    length = _VEHICLE_BURN_IN + n + 1
    signals = _vehicle_signals(rng, length, steering_std, speed_range)
    u_all = signals[1:]  # u_k = [s_{k+1}, p_{k+1}]
    s0, p0 = signals[0]
    x_start = np.array([0.0, 0.0, s0, s0, p0, p0])
    w = np.zeros((length - 1, 6))
    w[:, 0] = _uniform(rng, length - 1, bounds[1])
    x_all = _rollout(physics, VEHICLE_THETA, x_start, u_all, effect, w)
    x, u, w = x_all[_VEHICLE_BURN_IN:], u_all[_VEHICLE_BURN_IN:], w[_VEHICLE_BURN_IN:-1]
    e = _uniform(rng, (n, 1), bounds[0])
    return (u, x, x[:, :1] + e), (e, w)


_VEHICLE_DESCR = """\
Vehicle lateral dynamics with an unmodelled term (Donati et al., Section 5.1; Novara 2011)
=========================================================================================

y[k+1] = th1 y_k + th2 y_(k-1) + th3 y_k p_k + th4 s_(k-1) p_(k-1) + Delta_k (+ eta^v_k)
Delta_k = -9.625 y_k p_(k-1) + 10.69 y_(k-1) p_(k-1) - 11.52 y_(k-1) p_(k-1)^2
y: yaw rate, s: steering angle (rad), p = 1/v: inverse longitudinal speed (s/m),
true theta = [2, -1.087, -1.070, 3.715].

State x_k = [y_k, y_(k-1), s_k, s_(k-1), p_k, p_(k-1)], input row u_k = [s_(k+1), p_(k+1)]
(the steering / inverse speed that enters the state at k+1), output z_k = y_k (+ noise).
The declared physics omits Delta, which enters equation 0 (x1 = y). Without Delta the
recursion is unstable for the true theta (th2 = -1.087: the two poles have product 1.087),
so a physics-only simulation diverges; Delta moves the y_(k-1) coefficient to
-1.087 + 10.69 p - 11.52 p^2 and makes the system stable for the speeds used (12-28 m/s).
Inputs: s = band-limited random-phase multisine (0-0.02 cycles/sample), p = 1/v with v a
multisine (0-0.1 cycles/sample) spanning the speed range. The speed varies faster than a
real car's would, on purpose: p_k and p_(k-1) must differ, otherwise th3 y_k p_k and the
Delta term y_k p_(k-1) are collinear and th3 absorbs -9.625. Noise: eta^z uniform in
[-noise_bound, noise_bound] on the measured output; eta^v uniform in
[-process_noise_bound, process_noise_bound] added to the y recursion (default 0).
"""


def make_vehicle_lateral(
    n_samples: int = 2000,
    noise_bound: float = 0.002,
    random_state=None,
    include_delta: bool = True,
    *,
    process_noise_bound: float = 0.0,
    steering_std: float = 0.05,
    speed_range: tuple[float, float] = (12.0, 28.0),
) -> Bunch:
    """Vehicle lateral dynamics of Donati et al. (Section 5.1) with the unmodelled ``Delta``.

    True system (paper's notation, ``y`` yaw rate, ``s`` steering angle, ``p = 1/v``):

    $$
    y_{k+1} &= \\bar\\theta^\\top [y_k,\\ y_{k-1},\\ y_k p_k,\\ s_{k-1} p_{k-1}]
              + \\Delta_k + \\eta^v_k, \\\\
    \\Delta_k &= -9.625\\, y_k p_{k-1} + 10.69\\, y_{k-1} p_{k-1}
                - 11.52\\, y_{k-1} p_{k-1}^2,
    $$

    with $\\bar\\theta = [2, -1.087, -1.070, 3.715]$. State-space recast of the paper:
    $x_k = [y_k, y_{k-1}, s_k, s_{k-1}, p_k, p_{k-1}]$ and
    $f(x, u, \\theta) = [\\theta_1 x_1 + \\theta_2 x_2 + \\theta_3 x_1 x_5 +
    \\theta_4 x_4 x_6,\\ x_1,\\ u_1,\\ x_3,\\ u_2,\\ x_5]$, $z_k = x_{1,k}$, so that
    $\\Delta_k = -9.625 x_1 x_6 + 10.69 x_2 x_6 - 11.52 x_2 x_6^2$ (equation 0).

    **Index convention.** The paper writes $u_k = [s_k, p_k]$, but then
    $x_{3,k+1} = u_{1,k}$ would hold $s_k$ instead of $s_{k+1}$. To keep the
    paper's state and ``f`` exactly, the input row ``u[k]`` here is
    $[s_{k+1}, p_{k+1}]$: the steering and inverse speed delivered at step ``k`` and
    held in the state from ``k+1`` on (``x[k+1, 2] == u[k, 0]``, ``x[k+1, 4] == u[k, 1]``).

    **Stability.** Without ``Delta`` the recursion is unstable for $\\bar\\theta$
    ($\\theta_2 = -1.087$, the product of the two poles, exceeds 1 in magnitude for
    every ``p``): a physics-only simulation with the true parameters diverges (about
    $10^{38}$ after 2000 steps). ``Delta`` changes the $y_{k-1}$ coefficient to
    $-1.087 + 10.69 p - 11.52 p^2$ and the $y_k$ coefficient to
    $2 - 10.695 p$, which is stable (frozen-``p`` Jury test) for speeds of about
    4.6-120 m/s; the default speeds are 12-28 m/s. The frozen-``p`` test does not cover a
    fast-varying speed, but the simulated records stay bounded (checked on 40 seeds with the
    default arguments: peak yaw rate at most about 4 standard deviations).

    **Inputs** (Novara 2011 is not available; generated here): steering
    ``s = steering_std * multisine`` with random phases on the band 0-0.02 cycles/sample;
    ``p = 1/v`` with ``v`` a multisine on the band 0-0.1 cycles/sample scaled to
    ``speed_range``. A burn-in of 200 samples is simulated from rest and discarded.
    The speed varies much faster than a real vehicle's (it can swing across the whole
    range within about ten samples); this is an excitation choice for identifiability, not
    a drive cycle. With a slowly varying speed, $p_k \\approx p_{k-1}$: the physical
    term $\\theta_3 y_k p_k$ and the ``Delta`` term $-9.625\\, y_k p_{k-1}$ are
    then collinear (correlation above 0.999999 for a 0-0.002 cycles/sample speed), so
    $\\theta_3$ and $\\bar\\omega_{10}$ cannot be told apart and a sparse fit
    moves the ``Delta`` term into $\\theta_3$.

    **Dictionary.** ``suggested_library`` is the paper's 12-function dictionary
    $\\varphi = [1, x_3, x_4, x_5, x_6, x_3^2, x_4^2, x_5^2, x_4 x_6, x_1 x_6, x_2 x_6,
    x_2 x_6^2]$ as a pysindy ``CustomLibrary`` on ``[x; u]`` (exactly these 12 features);
    ``dictionary_functions`` lists the same terms as ``(name, callable(v))`` on
    ``v = [x; u]``. ``true_omega`` has -9.625, 10.69, -11.52 on the last three entries: the
    paper lists $\\bar\\omega_{12} = +11.52$ but writes ``Delta`` with -11.52; the
    ``Delta`` equation is used as the truth here.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_bound : float, default=0.002
        Bound of the uniform output noise $\\eta^z$ (the yaw rate has a standard
        deviation of about 0.08).
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    include_delta : bool, default=True
        Include ``Delta`` in the true system. ``False`` simulates the physics alone, which
        diverges (a ``RuntimeWarning`` is issued).
    process_noise_bound : float, default=0.0
        Bound of the uniform noise $\\eta^v$ added to the ``y`` recursion.
    steering_std : float, default=0.05
        Standard deviation of the steering angle (rad).
    speed_range : (float, float), default=(12.0, 28.0)
        Range of the longitudinal speed ``v`` (m/s).

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, dictionary_functions, true_omega, noise, DESCR``.
    """
    n = _check_n_samples(n_samples)
    bounds = (_check_scale("noise_bound", noise_bound),)
    bounds += (_check_scale("process_noise_bound", process_noise_bound),)
    rng = _check_random_state(random_state)
    params = dict(zip("abc", VEHICLE_DELTA, strict=True))
    effect = _HiddenEffect(_vehicle_delta, params) if include_delta else None
    plain = _vehicle_physics(np.zeros(6))
    args = (effect, bounds, steering_std, speed_range, plain)
    est, noise_est = _vehicle_record(rng, n, *args)
    val, noise_val = _vehicle_record(rng, n, *args)
    _warn_if_diverged(est[1], val[1])
    u, x, z = est
    physics = _vehicle_physics([z[0, 0], z[0, 0], u[0, 0], u[0, 0], u[0, 1], u[0, 1]])
    sign = _effect_sign(_HiddenEffect(_vehicle_delta, params, 0), x, u, 0)
    hidden = _hidden_effect(
        _vehicle_delta,
        params,
        0,
        ("x1", "x2", "x6"),
        sign,
        "Unmodelled yaw term -9.625 y_k p_(k-1) + 10.69 y_(k-1) p_(k-1) - 11.52 y_(k-1) "
        "p_(k-1)^2 (x1 x6, x2 x6, x2 x6^2) that stabilises the yaw recursion.",
    )
    uniform = {"distribution": "uniform"}
    noise = _record_noise(
        {**uniform, "bound": bounds[0], "applied_to": "z (eta^z)"},
        {**uniform, "bound": bounds[1], "applied_to": "equation 0, y recursion (eta^v)"},
        noise_est,
        noise_val,
    )
    return _bunch(
        physics,
        (est, val),
        VEHICLE_THETA,
        (x[0], val[1][0]),
        hidden if include_delta else None,
        vehicle_dictionary_library(),
        noise,
        _VEHICLE_DESCR,
        dictionary_functions=[(name, DictionaryTerm(phi)) for name, phi, _ in _VEHICLE_TERMS],
        true_omega=np.array([0.0] * 9 + list(VEHICLE_DELTA)) * float(include_delta),
        sampling_time=None,
    )


def _warn_if_diverged(*trajectories) -> None:
    if any(np.max(np.abs(x[:, 0])) > 1e3 for x in trajectories):
        warnings.warn(
            "The vehicle yaw recursion without Delta is unstable for the true theta "
            "(theta2 = -1.087); the simulated records diverge.",
            RuntimeWarning,
            stacklevel=3,
        )


def vehicle_physics_known_registers(data) -> PhysicsModel:
    """The generator's physics with the measured-input registers ``x3..x6`` of ``x0`` known.

    ``x3..x6`` hold the measured steering and inverse speed, so their initial values are
    measurements, not unknowns (fitted, they are nearly unidentifiable: they act on one or
    two samples only). ``x1, x2`` start from the first measured output and are estimated.

    Parameters
    ----------
    data : sklearn.utils.Bunch
        Output of [`make_vehicle_lateral`][sk_offwhite.datasets.make_vehicle_lateral].

    Returns
    -------
    PhysicsModel
    """
    physics = data.physics
    return PhysicsModel(
        physics.step,
        physics.output,
        physics.parameters,
        n_states=6,
        n_inputs=2,
        x0=np.r_[data.z[0, 0], data.z[0, 0], data.true_x0[2:]],
        x0_fixed=[False, False, True, True, True, True],
        state_names=physics.state_names,
        input_names=physics.input_names,
    )
