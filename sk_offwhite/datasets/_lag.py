"""Plants whose command reaches them late: an actuator that lags its command (a drive's
amplifier, a heating element) or a dead time (heat carried along a pipe, a command sent
over a network), which the declared physics leaves out."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

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
from sk_offwhite.datasets._synthetic import _first_order_physics, motor_rhs
from sk_offwhite.datasets._thermal import (
    HEATER_DT,
    HEATER_MEAN,
    HEATER_STD,
    HEATER_THETA,
    _heated_block_physics,
)
from sk_offwhite.effects._base import checked_positive
from sk_offwhite.effects._lags import delayed_command, lag_coefficients

__all__ = [
    "lagged_command",
    "make_delayed_drive",
    "make_delayed_heater",
    "make_lagged_drive",
    "make_lagged_heater",
]

DRIVE_THETA = {"a": 2.0, "b": 4.0}
DRIVE_GUESS = {"a": 1.5, "b": 3.0}
DRIVE_LAG, DRIVE_DT, DRIVE_INPUT_STD, DRIVE_BAND = 0.15, 0.05, 0.8, 0.03
DRIVE_KINDS = {"states": ("rate",), "inputs": ("voltage",)}
HEATER_LAG, HEATER_BAND = 30.0, 0.01
HEATER_GUESS = {"capacity": 600.0, "conductance": 2.0, "ambient": 290.0}
HEATER_X0 = HEATER_THETA["ambient"] + HEATER_MEAN / HEATER_THETA["conductance"]
DRIVE_DELAY, HEATER_DELAY = 0.12, 9.0


def lagged_command(u, time_constant: float, sampling_time: float, start=None) -> np.ndarray:
    r"""What a first-order lag of time constant $\tau$ delivers over each held sample
    of the command sequence ``u`` (1-D), its mean over the sample:

    $$
    \begin{gathered}
    \tilde u_k = p_k + \beta (u_k - p_k), \qquad p_{k+1} = p_k + \alpha (u_k - p_k), \\
    \alpha = 1 - e^{-T_s/\tau}, \quad \beta = 1 - \frac{\tau}{T_s}\,\alpha,
    \end{gathered}
    $$

    the exact solution of $\tau \dot p = u - p$ under a zero-order hold
    ($p_0$ = ``start``, ``u[0]`` when ``None``: settled at the first command).
    """
    u = np.asarray(u, dtype=np.float64)
    alpha, beta = lag_coefficients(time_constant / sampling_time, np)
    output = float(u[0]) if start is None else float(start)
    seen = np.empty_like(u)
    for k, command in enumerate(u):
        seen[k] = output + beta * (command - output)
        output += alpha * (command - output)
    return seen


@dataclass(frozen=True)
class _LaggedPlant:
    r"""A first-order plant driven through a lag or a dead time of its command:
    ``physics(values)`` the declared model (started at ``x0``), ``gain`` the factor that
    turns the error $\tilde u - u$ into the state's rate, ``memory`` the lag's
    ``{"time_constant": τ}`` or the dead time's ``{"delay": d}``, the command
    ``input_mean + input_std`` times a unit multisine of ``band`` cycles/sample, floored at
    ``input_floor``."""

    physics: Callable
    theta: dict
    guess: dict
    x0: float
    gain: Callable
    memory: dict
    dt: float
    input_mean: float
    input_std: float
    input_floor: float
    band: float
    kinds: dict
    description: str
    process_target: str
    descr: str


def _delivered(plant: _LaggedPlant, command: np.ndarray) -> np.ndarray:
    """What ``plant``'s lag or dead time delivers of ``command`` over each held sample."""
    if "delay" in plant.memory:
        return delayed_command(command, plant.memory["delay"], plant.dt)
    return lagged_command(command, plant.memory["time_constant"], plant.dt)


def _lagged_record(plant: _LaggedPlant, rng, n: int, stds) -> tuple:
    """One record: the command, the state (driven by the lagged command), the measured
    state, and the realised noises and lagged commands."""
    command = plant.input_mean + plant.input_std * _multisine(rng, n, plant.band)
    u = np.maximum(command, plant.input_floor)[:, None]
    seen = _delivered(plant, u[:, 0])
    w = _gaussian(rng, (n - 1, 1), stds[1])
    x0 = np.array([plant.x0])
    x = _rollout(plant.physics(plant.theta), plant.theta, x0, seen[:, None], None, w)
    e = _gaussian(rng, (n, 1), stds[0])
    return (u, x, x + e), (e, w), seen


def _lagged_dataset(plant: _LaggedPlant, n_samples, noise_std, random_state, process_noise_std):
    """Estimation and validation records of ``plant``, as the generators return them."""
    import pysindy as ps

    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    rng = _check_random_state(random_state)
    (est, est_noise, seen), (val, val_noise, seen_val) = (
        _lagged_record(plant, rng, n, stds) for _ in range(2)
    )
    contribution = plant.dt * plant.gain(plant.theta) * (seen[:-1] - est[0][:-1, 0])
    physics = plant.physics(plant.guess)
    hidden = _memory_effect(
        0,
        contribution,
        est[1][:-1, 0],
        plant.description,
        dict(plant.memory),
        {"seen": seen, "seen_val": seen_val},
        plant.kinds,
        physics.input_names,
    )
    return _bunch(
        physics,
        (est, val),
        plant.theta,
        (np.array([plant.x0]), np.array([plant.x0])),
        hidden,
        ps.PolynomialLibrary(degree=2),
        _gaussian_noise(stds, (est_noise, val_noise), plant.process_target),
        plant.descr,
        sampling_time=plant.dt,
        kinds=dict(hidden["kinds"]),
    )


def _drive_physics(values: dict):
    return _first_order_physics(
        motor_rhs, values, (0.0,), DRIVE_DT, ("omega", "u"), ("rate", "voltage")
    )


_DRIVE = _LaggedPlant(
    physics=_drive_physics,
    theta=DRIVE_THETA,
    guess=DRIVE_GUESS,
    x0=0.0,
    gain=lambda theta: theta["b"],
    memory={"time_constant": DRIVE_LAG},
    dt=DRIVE_DT,
    input_mean=0.0,
    input_std=DRIVE_INPUT_STD,
    input_floor=-np.inf,
    band=DRIVE_BAND,
    kinds=DRIVE_KINDS,
    description="The amplifier delivers the command through a lag of 0.15 s.",
    process_target="speed equation",
    descr="Motor omega' = -a omega + b p, p the amplifier's output, a first-order lag of "
    "the command u with tau=0.15 s, a=2 1/s, b=4 rad/(V s^2), Euler dt=0.05 s, speed "
    "measured; the physics has p = u.\n",
)


_HEATER = _LaggedPlant(
    physics=lambda values: _heated_block_physics(values, (HEATER_X0,)),
    theta=HEATER_THETA,
    guess=HEATER_GUESS,
    x0=HEATER_X0,
    gain=lambda theta: 1.0 / theta["capacity"],
    memory={"time_constant": HEATER_LAG},
    dt=HEATER_DT,
    input_mean=HEATER_MEAN,
    input_std=HEATER_STD,
    input_floor=0.0,
    band=HEATER_BAND,
    kinds={"states": ("temperature",), "inputs": ("generic",)},
    description="The heating element delivers the commanded power through a lag of 30 s.",
    process_target="temperature equation",
    descr="Heated block C T' = p - G (T - T_a) [SI units: K, W, J/K, s], p the heating "
    "element's output, a first-order lag of the commanded power P with tau=30 s, C=800 "
    "J/K, G=2.5 W/K, T_a=295 K, Euler dt=2 s, temperature measured; the physics has "
    "p = P.\n",
)


def make_lagged_drive(
    n_samples: int = 2000,
    noise_std: float = 1e-2,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """First-order motor whose physics assumes the drive applies its command at once.

    True system, one explicit-Euler step of $\\Delta t = 0.05$ s per sample, the
    motor driven by its amplifier's output $p$, a first-order lag of the command
    ``u`` (V) with time constant $\\tau = 0.15$ s (three samples), integrated exactly
    over each held sample ([`lagged_command`][sk_offwhite.datasets.lagged_command], the mean over
    the sample $\\tilde u$):

    $$
    \\tau \\dot p = u - p, \\qquad \\dot\\omega = -a \\omega + b\\, \\tilde u, \\qquad
    z = \\omega + \\eta,
    $$

    with $a = 2$ 1/s and $b = 4$ rad/(V s²) (speed in rad/s); the amplifier
    starts settled at the first command and the motor at rest. The physics has
    $\\tilde u = u$. The effect has memory, so it is no function of
    $(\\omega, u)$: ``hidden_effect`` gives the realised contribution
    $\\Delta t\\, b (\\tilde u_k - u_k)$ to the speed equation on the estimation
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
    return _lagged_dataset(_DRIVE, n_samples, noise_std, random_state, process_noise_std)


def make_lagged_heater(
    n_samples: int = 2000,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """Heated block whose physics assumes the heating element delivers its command at once.

    The block of [`make_heated_block`][sk_offwhite.datasets.make_heated_block] ($C \\dot T = p - G
    (T - T_a)$, SI units, $C$ = 800 J/K, $G$ = 2.5 W/K, $T_a$ = 295 K, one explicit-Euler step of
    $\\Delta t$ = 2 s per sample), heated by an element whose output $p$ is a
    first-order lag of the commanded power ``P`` with time constant $\\tau$ = 30 s
    (its own heat capacity), integrated exactly over each held sample
    ([`lagged_command`][sk_offwhite.datasets.lagged_command]); no power limit. The block starts at
    its steady state for the mean power (313 K) and the element settled at the first command. The
    physics has $p = P$. ``hidden_effect`` gives the realised contribution
    $\\Delta t (\\tilde p_k - P_k) / C$ and the lagged powers (``"seen"``,
    ``"seen_val"``); ``hidden_effect["rates"]`` is ``{"time_constant": τ}``. Input: 45 W
    plus a multisine of std 25 W over 0-0.0025 Hz (0.01 cycles/sample), floored at 0.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float, default=0.02
        Standard deviation (K) of the Gaussian temperature-sensor noise.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (K) of a Gaussian disturbance added to the temperature update.

    Returns
    -------
    data : sklearn.utils.Bunch
        As [`make_lagged_drive`][sk_offwhite.datasets.make_lagged_drive].
    """
    return _lagged_dataset(_HEATER, n_samples, noise_std, random_state, process_noise_std)


def _delayed_drive(delay: float) -> _LaggedPlant:
    """The lagged drive's motor, its command applied ``delay`` seconds late instead."""
    return replace(
        _DRIVE,
        memory={"delay": delay},
        description=f"The command reaches the amplifier {delay:g} s late.",
        descr=f"Motor omega' = -a omega + b u(t - d), the command u applied after a dead time "
        f"d={delay:g} s ({delay / DRIVE_DT:g} samples; a command sent over a network), a=2 "
        "1/s, b=4 rad/(V s^2), Euler dt=0.05 s, speed measured; the physics has d = 0.\n",
    )


def _delayed_heater(delay: float) -> _LaggedPlant:
    """The lagged heater's block, its heat arriving ``delay`` seconds late instead."""
    return replace(
        _HEATER,
        memory={"delay": delay},
        description=f"The heat reaches the block {delay:g} s after the heater delivers it.",
        descr="Heated block C T' = P(t - d) - G (T - T_a) [SI units: K, W, J/K, s], the heat "
        f"carried from the heater by a fluid that takes d={delay:g} s ({delay / HEATER_DT:g} "
        "samples) to reach the block, C=800 J/K, G=2.5 W/K, T_a=295 K, Euler dt=2 s, "
        "temperature measured; the physics has d = 0.\n",
    )


def make_delayed_drive(
    n_samples: int = 2000,
    noise_std: float = 1e-2,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    delay: float = DRIVE_DELAY,
) -> Bunch:
    """First-order motor whose physics assumes the command acts at once; it acts late.

    The motor of [`make_lagged_drive`][sk_offwhite.datasets.make_lagged_drive] ($\\dot\\omega =
    -a\\omega + b\\tilde u$, $a$ = 2 1/s, $b$ = 4 rad/(V s²), one explicit-Euler step of
    $\\Delta t$ = 0.05 s per sample), driven by the command ``u`` (V) after a dead
    time $d$ (``delay``, 0.12 s by default, 2.4 samples: a command sent over a
    network), the held command
    delayed and averaged over each sample
    ([`delayed_command`][sk_offwhite.datasets.delayed_command], $\\tilde u_k = 0.6\\,u_{k-2} +
    0.4\\,u_{k-3}$); the commands before the record equal the first. The physics has $\\tilde u =
    u$. ``hidden_effect`` gives the realised contribution $\\Delta t\\, b (\\tilde u_k - u_k)$
    (``"contribution"``), the delayed commands (``"seen"``, ``"seen_val"``) and ``"rates"``
    ``{"delay": d}``. Input: zero-mean multisine 0-0.6 Hz (0.03 cycles/sample), std
    0.8 V, where the dead time shifts the phase by up to 26°. Suggested library:
    polynomials of degree 2 on ``[omega, u]``.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float, default=1e-2
        Standard deviation (rad/s) of the Gaussian speed-sensor noise.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (rad/s) of a Gaussian disturbance added to the speed update.
    delay : float, default=0.12
        The dead time in seconds.

    Returns
    -------
    data : sklearn.utils.Bunch
        As [`make_lagged_drive`][sk_offwhite.datasets.make_lagged_drive].
    """
    plant = _delayed_drive(checked_positive(delay, "delay"))
    return _lagged_dataset(plant, n_samples, noise_std, random_state, process_noise_std)


def make_delayed_heater(
    n_samples: int = 2000,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    delay: float = HEATER_DELAY,
) -> Bunch:
    """Heated block whose physics assumes the heat arrives at once; it arrives late.

    The block of [`make_heated_block`][sk_offwhite.datasets.make_heated_block] ($C \\dot T = \\tilde
    p - G (T - T_a)$, SI units, $C$ = 800 J/K, $G$ = 2.5 W/K, $T_a$ = 295 K, one
    explicit-Euler step of $\\Delta t$ = 2 s per sample), heated by a fluid that
    carries the heater's power ``P`` to the block in $d$ (``delay``, 9 s by default,
    4.5 samples: a transport delay), the held power delayed and averaged over each sample
    ([`delayed_command`][sk_offwhite.datasets.delayed_command]); the powers before the record equal
    the first. No power limit. The block starts at its steady state for the mean power (313 K). The
    physics has $\\tilde p = P$. ``hidden_effect`` gives the realised contribution
    $\\Delta t (\\tilde p_k - P_k) / C$, the delayed powers (``"seen"``,
    ``"seen_val"``) and ``"rates"`` ``{"delay": d}``. Input: 45 W plus a multisine of
    std 25 W over 0-0.0025 Hz (0.01 cycles/sample), floored at 0.

    Parameters
    ----------
    n_samples : int, default=2000
        Length of each record.
    noise_std : float, default=0.02
        Standard deviation (K) of the Gaussian temperature-sensor noise.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation (K) of a Gaussian disturbance added to the temperature update.
    delay : float, default=9.0
        The dead time in seconds.

    Returns
    -------
    data : sklearn.utils.Bunch
        As [`make_lagged_drive`][sk_offwhite.datasets.make_lagged_drive].
    """
    plant = _delayed_heater(checked_positive(delay, "delay"))
    return _lagged_dataset(plant, n_samples, noise_std, random_state, process_noise_std)
