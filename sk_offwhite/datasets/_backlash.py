"""A position servo driven through a gear with play: the missing effect has memory."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._common import (
    _bunch,
    _check_n_samples,
    _check_random_state,
    _gaussian,
    _gaussian_noise,
    _memory_effect,
    _multisine,
    _noise_stds,
    _rollout,
)
from sk_offwhite.datasets._mechanical import _second_order_physics
from sk_offwhite.model._physics import PhysicsModel

__all__ = ["make_backlash_servo", "play"]

SERVO_THETA = {"k": 400.0, "c": 8.0}
SERVO_WIDTH, SERVO_DT, SERVO_INPUT_STD, SERVO_BAND = 0.05, 0.005, 0.5, 0.01


def servo_rhs(x, u, theta):
    """``[omega, k (u - theta) - c omega]``: a load angle pulled towards the input angle."""
    return jnp.stack([x[1], theta["k"] * (u[0] - x[0]) - theta["c"] * x[1]])


def play(u, width: float, start: float | None = None) -> np.ndarray:
    """The exact backlash of a command sequence ``u`` (1-D): the driven side's position
    $p_{k+1} = \\mathrm{clip}(p_k, u_k - w, u_k + w)$, $p_0$ = ``start``
    (``u[0]`` when ``None``); returns $p_1, \\dots, p_n$."""
    u = np.asarray(u, dtype=np.float64)
    position = float(u[0]) if start is None else float(start)
    out = np.empty_like(u)
    for k, command in enumerate(u):
        position = min(max(position, command - width), command + width)
        out[k] = position
    return out


SERVO_KINDS = {"states": ("angle", "rate"), "inputs": ("angle",)}


def _servo_physics(values: dict) -> PhysicsModel:
    names = ("theta", "omega", "u")
    return _second_order_physics(servo_rhs, values, (0.0, 0.0), SERVO_DT, names, SERVO_KINDS)


def _servo_record(rng, n: int, stds) -> tuple:
    """One record: the motor angle, the load's states (driven by the play's output), the
    measured load angle, and the realised noises and played positions."""
    u = SERVO_INPUT_STD * _multisine(rng, n, SERVO_BAND)[:, None]
    played = play(u[:, 0], SERVO_WIDTH)
    w = np.zeros((n - 1, 2))
    w[:, 1] = _gaussian(rng, n - 1, stds[1])
    x = _rollout(_servo_physics(SERVO_THETA), SERVO_THETA, np.zeros(2), played[:, None], None, w)
    e = _gaussian(rng, (n, 1), stds[0])
    return (u, x, x[:, :1] + e), (e, w), played


def make_backlash_servo(
    n_samples: int = 2000,
    noise_std: float = 1e-3,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """Position servo whose physics assumes a stiff transmission that has play (backlash).

    True system, one explicit-Euler step of $\\Delta t = 5$ ms per sample:

    $$
    p_{k+1} = \\mathrm{clip}(p_k, u_k - w, u_k + w), \\qquad
    \\dot\\vartheta = \\omega, \\quad \\dot\\omega = k (p - \\vartheta) - c\\,\\omega,
    \\qquad z = \\vartheta + \\eta,
    $$

    with the motor angle ``u`` (rad) as input, the play's half-width $w = 0.05$ rad,
    $k = 400$ s⁻² (a 3.2 Hz resonance) and $c = 8$ s⁻¹ (damping ratio 0.2);
    the load starts at rest at 0 and the play at $p_0 = u_0$. The physics has
    $p = u$. The effect has memory ($p$ depends on the input's past), so it is
    no function of $(\\vartheta, \\omega, u)$: ``hidden_effect`` gives the realised
    contribution $\\Delta t\\, k (p_{k+1} - u_k)$ to the rate equation on the
    estimation record (``"contribution"``) and the played positions (``"played"``,
    ``"played_val"``) instead of a function; ``hidden_effect["rates"]`` is
    ``{"backlash": w}``. Input: zero-mean multisine 0-2 Hz (0.01 cycles/sample), std 0.5
    rad, reversing many times per record. Suggested library: polynomials of degree 3 on
    ``[theta, omega, u]``.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float, default=1e-3
        Standard deviation (rad) of the Gaussian angle-sensor noise.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (rad/s) of a Gaussian disturbance added to the rate update.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, kinds, DESCR``.
    """
    import pysindy as ps

    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    rng = _check_random_state(random_state)
    (est, est_noise, played), (val, val_noise, played_val) = (
        _servo_record(rng, n, stds) for _ in range(2)
    )
    contribution = SERVO_DT * SERVO_THETA["k"] * (played[:-1] - est[0][:-1, 0])
    hidden = _memory_effect(
        1,
        contribution,
        est[1][:-1, 1],
        "The motor drives the load through a play of half-width 0.05 rad.",
        {"backlash": SERVO_WIDTH},
        {"played": played, "played_val": played_val},
        SERVO_KINDS,
    )
    return _bunch(
        _servo_physics({"k": 300.0, "c": 6.0}),
        (est, val),
        SERVO_THETA,
        (np.zeros(2), np.zeros(2)),
        hidden,
        ps.PolynomialLibrary(degree=3),
        _gaussian_noise(stds, (est_noise, val_noise), "rate equation"),
        "Servo theta'' = k (p - theta) - c theta', p the motor angle u after a play of "
        "half-width 0.05 rad, k=400 1/s^2, c=8 1/s, Euler dt=5 ms, load angle measured; "
        "the physics has p = u.\n",
        sampling_time=SERVO_DT,
        kinds=dict(hidden["kinds"]),
    )
