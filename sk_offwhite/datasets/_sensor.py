"""Tanks whose level sensor is not what the physics says: the missing effect is in the
output map (a curved characteristic, a step in the reading) or in the sensor's own
dynamics (a reading that lags the level)."""

from __future__ import annotations

from functools import partial

import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.datasets._common import (
    _bunch,
    _check_n_samples,
    _check_number,
    _check_random_state,
    _gaussian,
    _gaussian_noise,
    _multisine,
    _noise_stds,
    _rollout,
)
from sk_offwhite.datasets._synthetic import POSITIVE, tank_rhs
from sk_offwhite.effects._base import checked_positive
from sk_offwhite.effects._lags import sensor_lag_law
from sk_offwhite.model._physics import Parameter, PhysicsModel

SENSOR_THETA = {"k": 0.5, "b": 0.5}
SENSOR_CURVATURE, SENSOR_DT, SENSOR_X0 = 0.04, 1.0, 4.0
STEP_LEVEL, STEP_HEIGHT = 5.0, 0.4
SENSOR_LAG = 4.0


def sensor_reading(level, curvature: float = SENSOR_CURVATURE, cubic: float = 0.0):
    """What the sensor reads at ``level``: $x + q x^2 + r x^3$ (``cubic``: $r$)."""
    return level + curvature * level**2 + cubic * level**3


def stepped_reading(level, step_level: float = STEP_LEVEL, step_height: float = STEP_HEIGHT):
    r"""What a sensor with a seam reads at ``level``: $x + H\,[x > L]$."""
    return level + step_height * (np.asarray(level) > step_level)


def lagged_reading(level, time_constant: float = SENSOR_LAG, sampling_time: float = SENSOR_DT):
    r"""What a sensor with a first-order lag of time constant $\tau$ reads of the
    sampled ``level`` (1-D, or one column), the level linear over each sample and the
    sensor settled at the first level:
    $s_{k+1} = s_k + \alpha (x_k - s_k) + \beta (x_{k+1} - x_k)$ with
    $\alpha = 1 - e^{-T_s/\tau}$ and $\beta = 1 - \alpha\tau/T_s$
    ([`SensorLag`][sk_offwhite.SensorLag]'s law)."""
    level = np.asarray(level, dtype=np.float64)
    samples = level.reshape(len(level))
    reading = np.empty_like(samples)
    reading[0] = samples[0]
    ratio = time_constant / sampling_time
    for k in range(samples.size - 1):
        reading[k + 1] = sensor_lag_law(reading[k], samples[k], samples[k + 1], ratio, np)
    return reading.reshape(level.shape)


def _sensor_tank_physics(k: float, x0: float) -> PhysicsModel:
    """The declared tank: Torricelli outlet, the pump gain ``b`` known, the level read as is."""
    return PhysicsModel.from_ode(
        tank_rhs,
        SENSOR_DT,
        output=0,
        parameters={
            "k": Parameter(k, POSITIVE),
            "b": Parameter(SENSOR_THETA["b"], fixed=True),
        },
        n_states=1,
        n_inputs=1,
        method="euler",
        x0=(x0,),
        state_names=("x",),
        input_names=("u",),
        output_names=("x",),
        state_kinds=("level",),
        input_kinds=("flow",),
    )


def _sensor_record(rng, n: int, physics: PhysicsModel, stds, reading=sensor_reading) -> tuple:
    u = np.clip(2.0 + 0.6 * _multisine(rng, n, 0.02), 0.0, None)[:, None]
    w = _gaussian(rng, (n - 1, 1), stds[1])
    x = _rollout(physics, SENSOR_THETA, np.array([SENSOR_X0]), u, None, w)
    e = _gaussian(rng, (n, 1), stds[0])
    return (u, x, reading(x) + e), (e, w)


def make_nonlinear_sensor_tank(
    n_samples: int = 1000,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    cubic: float = 0.0,
) -> Bunch:
    """Single tank read by a level sensor whose characteristic is not linear.

    True system, one explicit-Euler step of $\\Delta t = 1$ s per sample:

    $$
    \\dot x = -k \\sqrt{x} + b u, \\qquad z = x + q x^2 + r x^3 + \\eta,
    $$

    with $k = 0.5$, $b = 0.5$ (the pump gain, known: fixed in the declared
    physics), $q = 0.04$, $r$ = ``cubic`` (0 by default: a quadratic
    characteristic, which the loop's calibration of degree 2 holds) and $x(0) = 4$.
    The physics reads the level as it is ($z = x$); the missing effect is static and
    in the output map, so no term of the state equations can stand for it exactly.
    ``hidden_effect["rates"]`` is ``{"curvature": q, "cubic": r}``;
    [`sensor_reading`][sk_offwhite.datasets.sensor_reading] is the true characteristic. Input: pump
    flow, multisine 0-0.02 cycles/sample, mean 2, std 0.6, clipped at 0 (levels about 0-12).
    Suggested library: polynomials of degree 2 on ``[x, u]``.

    Parameters
    ----------
    n_samples : int, default=1000
        Length of each record.
    noise_std : float, default=0.02
        Standard deviation of the Gaussian sensor noise.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of a Gaussian disturbance added to the level update.
    cubic : float, default=0.0
        $r$, the characteristic's cubic coefficient (per level unit squared):
        with 0.004 the reading at the top level (12) is 6.9 above the level, and a
        calibration of degree 2 leaves a curve the noise does not hide.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u, z, u_val, z_val, x, x_val, physics, true_parameters, true_x0, true_x0_val,
        hidden_effect, suggested_library, noise, sampling_time, DESCR``.
    """
    cubic = _check_number("cubic", cubic, "a finite number")
    if not np.isfinite(cubic):
        raise ValueError(f"cubic must be finite, got {cubic!r}.")
    cubic_term = f" + {cubic:g} x^3" if cubic else ""
    hidden = {
        "description": "The level sensor reads x + q x^2 + r x^3 instead of x.",
        "rates": {"curvature": SENSOR_CURVATURE, "cubic": cubic},
    }
    return _sensor_tank_data(
        (n_samples, noise_std, process_noise_std, random_state),
        partial(sensor_reading, cubic=cubic),
        hidden,
        f"reads z = x + 0.04 x^2{cubic_term}; the physics reads z = x.\n",
    )


def make_stepped_sensor_tank(
    n_samples: int = 1000,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
) -> Bunch:
    """Single tank read by a level sensor whose reading steps where the level passes a value.

    True system, one explicit-Euler step of $\\Delta t = 1$ s per sample:

    $$
    \\dot x = -k \\sqrt{x} + b u, \\qquad z = x + H\\,[x > L] + \\eta,
    $$

    with $k = 0.5$, $b = 0.5$ (the pump gain, known: fixed in the declared
    physics), $L = 5$, $H = 0.4$ and $x(0) = 4$: a seam in the sensor
    (a capacitive strip in two pieces) makes the reading jump by $H$ each time the
    level passes $L$, up as it rises and down as it falls. The physics reads the level
    as it is ($z = x$); the missing effect is static, discontinuous and in the output
    map. ``hidden_effect["rates"]`` is ``{"step_level": L, "step_height": H}``;
    [`stepped_reading`][sk_offwhite.datasets.stepped_reading] is the true characteristic. Input:
    pump flow, multisine 0-0.02 cycles/sample, mean 2, std 0.6, clipped at 0 (levels about 0-12).
    Suggested library: polynomials of degree 2 on ``[x, u]``.

    Parameters
    ----------
    n_samples : int, default=1000
        Length of each record.
    noise_std : float, default=0.02
        Standard deviation of the Gaussian sensor noise.
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
    hidden = {
        "description": "The level sensor reads x + H [x > L] instead of x.",
        "rates": {"step_level": STEP_LEVEL, "step_height": STEP_HEIGHT},
    }
    return _sensor_tank_data(
        (n_samples, noise_std, process_noise_std, random_state), stepped_reading, hidden,
        "reads z = x + 0.4 [x > 5]; the physics reads z = x.\n",
    )  # fmt: skip


def make_slow_sensor_tank(
    n_samples: int = 1000,
    noise_std: float = 0.02,
    random_state=None,
    *,
    process_noise_std: float = 0.0,
    time_constant: float = SENSOR_LAG,
) -> Bunch:
    """Single tank read by a level sensor that lags the level (sensor dynamics).

    True system, one explicit-Euler step of $\\Delta t = 1$ s per sample:

    $$
    \\dot x = -k \\sqrt{x} + b u, \\qquad \\tau \\dot s = x - s, \\qquad z = s + \\eta,
    $$

    with $k = 0.5$, $b = 0.5$ (the pump gain, known: fixed in the declared
    physics), $x(0) = 4$ and $\\tau$ = ``time_constant`` (4 s by default,
    four samples: a damped pressure transducer, a float in a stilling well), the level
    taken linear over each sample ([`lagged_reading`][sk_offwhite.datasets.lagged_reading]) and the
    sensor settled at the first level. The physics reads the level as it is ($z = x$); the missing
    effect has memory and sits in the measurement, not in the tank. The outlet's square root
    tells it apart from a lag of the pump, which a linear tank would not (a lag commutes
    with a linear plant). ``hidden_effect["rates"]`` is ``{"time_constant": τ}``. Input:
    pump flow, multisine 0-0.02 cycles/sample, mean 2, std 0.6, clipped at 0 (levels
    about 0-12). Suggested library: polynomials of degree 2 on ``[x, u]``.

    Parameters
    ----------
    n_samples : int, default=1000
        Length of each record.
    noise_std : float, default=0.02
        Standard deviation of the Gaussian sensor noise.
    random_state : int, RandomState instance or None, default=None
        Seed of the input and noise realisations.
    process_noise_std : float, default=0.0
        Standard deviation of a Gaussian disturbance added to the level update.
    time_constant : float, default=4.0
        The sensor's time constant $\\tau$ in seconds.

    Returns
    -------
    data : sklearn.utils.Bunch
        As [`make_nonlinear_sensor_tank`][sk_offwhite.datasets.make_nonlinear_sensor_tank].
    """
    time_constant = checked_positive(time_constant, "time_constant")
    hidden = {
        "description": f"The level sensor follows the level through a lag of {time_constant:g} s.",
        "rates": {"time_constant": time_constant},
    }
    return _sensor_tank_data(
        (n_samples, noise_std, process_noise_std, random_state),
        partial(lagged_reading, time_constant=time_constant),
        hidden,
        f"follows the level through a first-order lag, tau={time_constant:g} s; the physics "
        "reads z = x.\n",
    )


def _sensor_tank_data(sampling, reading, hidden: dict, read_as: str) -> Bunch:
    """The records and Bunch of a sensor tank whose sensor reads ``reading(x)``;
    ``sampling`` is the generator's ``(n_samples, noise_std, process_noise_std,
    random_state)``, ``hidden`` holds the description and rates of the hidden effect,
    ``read_as`` ends the DESCR."""
    import pysindy as ps

    n_samples, noise_std, process_noise_std, random_state = sampling
    n, stds = _check_n_samples(n_samples), _noise_stds(noise_std, process_noise_std)
    rng = _check_random_state(random_state)
    truth = _sensor_tank_physics(SENSOR_THETA["k"], SENSOR_X0)
    records = [_sensor_record(rng, n, truth, stds, reading) for _ in range(2)]
    (est, est_noise), (val, val_noise) = records
    hidden = {"target": "output", "equation": None, "variables": ["x"], "sign": 1, **hidden}
    noise = _gaussian_noise(stds, (est_noise, val_noise), "level equation")
    x0 = np.array([SENSOR_X0])
    return _bunch(
        _sensor_tank_physics(0.4, float(est[2][0, 0])),
        (est, val),
        SENSOR_THETA,
        (x0, x0),
        hidden,
        ps.PolynomialLibrary(degree=2),
        noise,
        "Tank x' = -k sqrt(x) + b u, k=0.5, b=0.5 (known), Euler dt=1 s; the level sensor "
        + read_as,
        sampling_time=SENSOR_DT,
    )
