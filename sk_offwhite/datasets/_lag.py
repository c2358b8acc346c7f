"""A motor driven through an amplifier that lags its command: actuator dynamics left out."""

from __future__ import annotations

import numpy as np
from sklearn.utils import Bunch, check_random_state

from sk_offwhite.datasets._common import (
    _bunch,
    _check_n_samples,
    _gaussian,
    _gaussian_noise,
    _memory_effect,
    _multisine,
    _noise_stds,
    _rollout,
)
from sk_offwhite.datasets._synthetic import _first_order_physics, motor_rhs

__all__ = ["lagged_command", "make_lagged_drive"]

DRIVE_THETA = {"a": 2.0, "b": 4.0}
DRIVE_GUESS = {"a": 1.5, "b": 3.0}
DRIVE_LAG, DRIVE_DT, DRIVE_INPUT_STD, DRIVE_BAND = 0.15, 0.05, 0.8, 0.03
DRIVE_KINDS = {"states": ("rate",), "inputs": ("voltage",)}


def lagged_command(u, time_constant: float, sampling_time: float, start=None) -> np.ndarray:
    r"""What a first-order lag of time constant :math:`\tau` delivers over each held sample
    of the command sequence ``u`` (1-D), its mean over the sample:

    .. math::

        \tilde u_k = p_k + \beta (u_k - p_k), \qquad p_{k+1} = p_k + \alpha (u_k - p_k),
        \qquad \alpha = 1 - e^{-T_s/\tau}, \quad \beta = 1 - \frac{\tau}{T_s}\,\alpha,

    the exact solution of :math:`\tau \dot p = u - p` under a zero-order hold
    (:math:`p_0` = ``start``, ``u[0]`` when ``None``: settled at the first command).
    """
    u = np.asarray(u, dtype=np.float64)
    alpha = -np.expm1(-sampling_time / time_constant)
    beta = 1.0 - time_constant / sampling_time * alpha
    output = float(u[0]) if start is None else float(start)
    seen = np.empty_like(u)
    for k, command in enumerate(u):
        seen[k] = output + beta * (command - output)
        output += alpha * (command - output)
    return seen


def _drive_physics(values: dict):
    return _first_order_physics(
        motor_rhs, values, (0.0,), DRIVE_DT, ("omega", "u"), ("rate", "voltage")
    )


def _drive_record(rng, n: int, stds) -> tuple:
    """One record: the command, the motor speed (driven by the lagged command), the
    measured speed, and the realised noises and lagged commands."""
    u = DRIVE_INPUT_STD * _multisine(rng, n, DRIVE_BAND)[:, None]
    seen = lagged_command(u[:, 0], DRIVE_LAG, DRIVE_DT)
    w = _gaussian(rng, (n - 1, 1), stds[1])
    x = _rollout(_drive_physics(DRIVE_THETA), DRIVE_THETA, np.zeros(1), seen[:, None], None, w)
    e = _gaussian(rng, (n, 1), stds[0])
    return (u, x, x + e), (e, w), seen


def make_lagged_drive(
    n_samples: int = 2000,
    noise_std: float = 1e-2,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """First-order motor whose physics assumes the drive applies its command at once.

    True system, one explicit-Euler step of :math:`\\Delta t = 0.05` s per sample, the
    motor driven by its amplifier's output :math:`p`, a first-order lag of the command
    ``u`` (V) with time constant :math:`\\tau = 0.15` s (three samples), integrated exactly
    over each held sample (:func:`lagged_command`, the mean over the sample
    :math:`\\tilde u`):

    .. math::

        \\tau \\dot p = u - p, \\qquad \\dot\\omega = -a \\omega + b\\, \\tilde u, \\qquad
        z = \\omega + \\eta,

    with :math:`a = 2` 1/s and :math:`b = 4` rad/(V s²) (speed in rad/s); the amplifier
    starts settled at the first command and the motor at rest. The physics has
    :math:`\\tilde u = u`. The effect has memory, so it is no function of
    :math:`(\\omega, u)`: ``hidden_effect`` gives the realised contribution
    :math:`\\Delta t\\, b (\\tilde u_k - u_k)` to the speed equation on the estimation
    record (``"contribution"``) and the lagged commands (``"seen"``, ``"seen_val"``)
    instead of a function; ``hidden_effect["rates"]`` is ``{"time_constant": τ}``. Input:
    zero-mean multisine 0-0.6 Hz (0.03 cycles/sample), std 0.8 V, where the lag shifts the
    phase by up to 30°. Suggested library: polynomials of degree 2 on ``[omega, u]``.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float, default=1e-2
        Standard deviation (rad/s) of the Gaussian speed-sensor noise, about 1 % of the
        speed's standard deviation.
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
    import pysindy as ps

    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    rng = check_random_state(random_state)
    (est, est_noise, seen), (val, val_noise, seen_val) = (
        _drive_record(rng, n, stds) for _ in range(2)
    )
    contribution = DRIVE_DT * DRIVE_THETA["b"] * (seen[:-1] - est[0][:-1, 0])
    hidden = _memory_effect(
        0,
        contribution,
        est[1][:-1, 0],
        "The amplifier delivers the command through a lag of 0.15 s.",
        {"time_constant": DRIVE_LAG},
        {"seen": seen, "seen_val": seen_val},
        DRIVE_KINDS,
    )
    return _bunch(
        _drive_physics(DRIVE_GUESS),
        (est, val),
        DRIVE_THETA,
        (np.zeros(1), np.zeros(1)),
        hidden,
        ps.PolynomialLibrary(degree=2),
        _gaussian_noise(stds, (est_noise, val_noise), "speed equation"),
        "Motor omega' = -a omega + b p, p the amplifier's output, a first-order lag of "
        "the command u with tau=0.15 s, a=2 1/s, b=4 rad/(V s^2), Euler dt=0.05 s, speed "
        "measured; the physics has p = u.\n",
        sampling_time=DRIVE_DT,
        kinds=dict(hidden["kinds"]),
    )
