"""Measured EMPS benchmark (Electro-Mechanical Positioning System) and its physical models.

The records are the estimation (`DATA_EMPS`) and validation (`DATA_EMPS_PULSES`) records of
the EMPS benchmark (Janot, Gautier, Brunot 2019), shipped in `data/emps.npz`; see
`data/EMPS.md` for provenance, attribution and checksums.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite import Parameter, PhysicsModel
from sk_offwhite.datasets._packed import read_packed

__all__ = [
    "emps_physics",
    "emps_reference_physics",
    "load_emps",
]

RAW_SAMPLING_TIME = 1e-3
"""Sampling time of the recorded signals, in seconds (1 kHz)."""

DEFAULT_DECIMATION = 10
"""Decimation of [load_emps][sk_offwhite.datasets.load_emps]: 100 Hz records."""

SAMPLING_TIME = DEFAULT_DECIMATION * RAW_SAMPLING_TIME
"""Sampling time of the records at the default decimation, in seconds (0.01 s: 100 Hz)."""

INIT_DURATION = 0.02
"""The protocol's initialisation window, in seconds (20 samples at 1 kHz)."""

REFERENCE_PARAMETERS = {"M": 95.1089, "Fv": 203.5034, "Fc": 20.3935, "offset": -3.1648}
"""The benchmark's reference (IDIM-LS) estimates: kg, N s/m, N, N."""

VELOCITY_SCALE = 1e-3
"""Width $v_s$ (m/s) of the smooth sign $\\tanh(v / v_s)$ of the reference Coulomb friction."""

_FILE = "emps.npz"
_POSITIVE = (1e-6, None)
_KINDS = {"state_kinds": ("position", "velocity"), "input_kinds": ("force",)}
_NAMES = {"state_names": ("q", "v"), "input_names": ("tau",), "output_names": ("q",)}

_PUBLISHED_RESULTS = (
    ("CT-SUBNET, continuous-time subspace encoder (Beintema, Schoukens, Toth, ICLR 2023)", 4.61,
     "the benchmark's data notes", "after about 10 h of training, at 1 kHz"),
    ("Reference physics M q'' = tau - Fv q' - Fc sign(q') - offset at the IDIM-LS estimates, "
     "simulated", None, "the benchmark's data notes", "about 6-9 mm"),
)  # fmt: skip

_DESCR = """\
EMPS benchmark (measured data)
==============================

Electro-Mechanical Positioning System (Janot, Gautier, Brunot 2019, Workshop on Nonlinear
System Identification Benchmarks): a prismatic joint driven by a DC motor through a ball
screw, under closed-loop position control. Input `u`: motor force on the load side,
`tau = gtau * vir` (N), with `vir` the controller output sent to the drive (V) and
`gtau = 35.15 N/V` the drive gain. Output `z`: measured position `qm` of the load (m).

Records: estimation DATA_EMPS (u_est, z_est) and validation DATA_EMPS_PULSES (u_val,
z_val, with extra force pulses), 24 841 samples each at 1 kHz (about 25 s), here decimated
(`decimation`, default 10: 100 Hz, 2484 samples). Decimation averages the force over each
block of samples and keeps the position at the block's first sample. The experiment runs in
closed loop: the force depends on the measured position.

Reference physics (benchmark): M q'' = tau - Fv q' - Fc sign(q') - offset, IDIM-LS
estimates M = 95.1089 kg, Fv = 203.5034 N s/m, Fc = 20.3935 N, offset = -3.1648 N. The
position is an integral of the force: any force error drifts the simulated position.

Scoring protocol (`protocols["nonlinear_benchmarks"]`): estimate on the estimation
record; simulate the validation record from u_val, its initial state estimated from its
first 20 ms (20 samples at 1 kHz, 2 at 100 Hz), which are not scored; report the RMS error
of the position in mm.

Data: the benchmark's EMPS.zip (public copy: GitHub forgi86/sysid-neural-continuous); see
data/EMPS.md in this package.
"""


def _checked_decimation(decimation) -> int:
    """`decimation` as an int in `[1, 100]`, or a clear error naming it."""
    if isinstance(decimation, bool) or not isinstance(decimation, int | np.integer):
        raise TypeError(f"decimation must be an int, got {decimation!r}.")
    if not 1 <= decimation <= 100:
        raise ValueError(f"decimation must be an integer in [1, 100], got {decimation}.")
    return int(decimation)


def decimate_record(force: np.ndarray, position: np.ndarray, decimation: int):
    """Force averaged over each block of `decimation` samples; position at each block's start.

    Returns `(u, z)` of shape `(n // decimation, 1)`; trailing samples that fill no block
    are dropped. With `decimation=1` the records are returned unchanged.
    """
    n_blocks = len(force) // decimation
    blocks = force[: n_blocks * decimation].reshape(n_blocks, decimation)
    u = blocks.mean(axis=1)
    z = position[: n_blocks * decimation : decimation]
    return u[:, None].copy(), z[:, None].copy()


def _raw_records() -> dict[str, np.ndarray]:
    """Force (N) and position (m) of both records at 1 kHz, from the package data."""
    packed = read_packed(_FILE)
    gain = float(packed["gtau"])
    return {
        "force_est": gain * packed["vir_est"],
        "position_est": packed["qm_est_codes"] * packed["qm_est_step"],
        "force_val": gain * packed["vir_val"],
        "position_val": packed["qm_val"],
    }


def _protocols(decimation: int, n_val: int) -> dict:
    init_window = math.ceil(round(INIT_DURATION / RAW_SAMPLING_TIME) / decimation)
    return {
        "nonlinear_benchmarks": {
            "description": (
                "Estimate on (u_est, z_est) only; simulate the validation record from u_val, "
                "its initial state estimated from the first init_window outputs z_val "
                "(the first 20 ms: 20 samples at 1 kHz), and report the RMS error of the "
                "position over the remaining samples, in mm."
            ),
            "init_window": init_window,
            "scored_samples": (init_window, n_val),
            "rmse_unit": "mm",
            "rmse_scale": 1e3,
        }
    }


def _published_results() -> list[dict]:
    keys = ("method", "test_rms", "source", "note")
    return [dict(zip(keys, row, strict=True)) for row in _PUBLISHED_RESULTS]


def load_emps(decimation: int = DEFAULT_DECIMATION) -> Bunch:
    """Load the measured EMPS benchmark records, decimated to `1 kHz / decimation`.

    Decimation averages the force over each block of `decimation` samples and keeps the
    position at the block's first sample: the recorded force is held over each 1 ms
    sample, so the block mean is exactly the constant force that transfers the same impulse
    over the block, which is what a zero-order-hold model at the lower rate sees between
    two position samples.

    Parameters
    ----------
    decimation : int, default=10
        Samples of the 1 kHz records per sample returned, in `[1, 100]`; 1 returns the
        recorded signals unchanged.

    Returns
    -------
    data : sklearn.utils.Bunch
        `u_est`, `z_est`, `u_val`, `z_val` : ndarray of shape (24841 // decimation, 1)
            Motor force $\\tau = g_\\tau v_{ir}$ (N) and measured position $q_m$ (m) of the
            estimation (`DATA_EMPS`) and validation (`DATA_EMPS_PULSES`) records (fresh
            copies on every call).
        `time` : ndarray of shape (24841 // decimation,)
            Sample times `k * sampling_time` in seconds (both records).
        `sampling_time` : float
            `decimation * 1e-3` s.
        `decimation` : int
            The decimation applied.
        `input_names`, `output_names` : list of str
            `["tau"]` and `["q"]`.
        `units` : dict
            `{"tau": "N", "q": "m"}`.
        `reference_parameters` : dict
            The benchmark's reference estimates `M`, `Fv`, `Fc`, `offset` (kg, N s/m, N, N).
        `protocols` : dict
            `"nonlinear_benchmarks"`: `description`, `init_window` (samples at this rate,
            the first 20 ms: 2 at 100 Hz), `scored_samples`, `rmse_unit` (`"mm"`) and
            `rmse_scale` (1000, metres to millimetres).
        `published_results` : list of dict
            Published validation simulation RMS errors (mm): `method`, `test_rms` (`None`
            where only a range is quoted), `source`, `note`.
        `DESCR` : str
            Description of the benchmark.

    Examples
    --------
    >>> from sk_offwhite.datasets import load_emps
    >>> data = load_emps()
    >>> data.u_est.shape, data.sampling_time
    ((2484, 1), 0.01)
    """
    decimation = _checked_decimation(decimation)
    raw = _raw_records()
    u_est, z_est = decimate_record(raw["force_est"], raw["position_est"], decimation)
    u_val, z_val = decimate_record(raw["force_val"], raw["position_val"], decimation)
    sampling_time = decimation * RAW_SAMPLING_TIME
    return Bunch(
        u_est=u_est,
        z_est=z_est,
        u_val=u_val,
        z_val=z_val,
        time=sampling_time * np.arange(len(u_est), dtype=np.float64),
        sampling_time=sampling_time,
        decimation=decimation,
        input_names=["tau"],
        output_names=["q"],
        units={"tau": "N", "q": "m"},
        reference_parameters=dict(REFERENCE_PARAMETERS),
        protocols=_protocols(decimation, len(u_val)),
        published_results=_published_results(),
        DESCR=_DESCR,
    )


def emps_rhs(x, u, theta):
    """Rate of the declared physics $M \\dot v = \\tau - F_v v$, $\\dot q = v$ (`jax.numpy`)."""
    acceleration = (u[0] - theta["Fv"] * x[1]) / theta["M"]
    return jnp.stack([x[1], acceleration])


def emps_reference_rhs(x, u, theta):
    """Rate of the reference law, with the smooth sign $\\tanh(v / v_s)$ (`jax.numpy`):

    $$ M \\dot v = \\tau - F_v v - F_c \\tanh(v / v_s) - \\mathrm{offset}, \\qquad \\dot q = v. $$
    """
    friction = theta["Fv"] * x[1] + theta["Fc"] * jnp.tanh(x[1] / theta["v_s"])
    acceleration = (u[0] - friction - theta["offset"]) / theta["M"]
    return jnp.stack([x[1], acceleration])


def _checked_positive(argument: str, value) -> float:
    value = float(value)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{argument} must be a positive finite number, got {value!r}.")
    return value


def _mechanical_physics(rhs, parameters: dict, sampling_time: float, x0) -> PhysicsModel:
    """Two states `(q, v)` measuring `q`, force input, RK4 over each sampling interval."""
    return PhysicsModel.from_ode(
        rhs,
        _checked_positive("sampling_time", sampling_time),
        output=0,
        parameters=parameters,
        n_states=2,
        n_inputs=1,
        method="rk4",
        x0=x0,
        **_NAMES,
        **_KINDS,
    )


def emps_physics(
    mass: float = 50.0,
    viscous_friction: float = 100.0,
    *,
    sampling_time: float = SAMPLING_TIME,
    x0: Sequence[float] | None = None,
) -> PhysicsModel:
    """The textbook model of the EMPS a user would declare: a mass with viscous friction.

    $$ \\dot q = v, \\qquad M \\dot v = \\tau - F_v v, \\qquad z = q, $$

    integrated with RK4 over each sampling interval, the force held (zero-order hold). It
    lacks what the benchmark's reference law has (Coulomb friction and a force offset):
    that is for the closed loop ([close_the_loop][sk_offwhite.loop.close_the_loop]) to find.

    Parameters
    ----------
    mass : float, default=50.0
        Starting value of `M` (kg): the moving mass and the motor's inertia seen at the
        load, a guess of the order of the carriage's weight.
    viscous_friction : float, default=100.0
        Starting value of `Fv` (N s/m).
    sampling_time : float, default=0.01
        Seconds per sample: `data.sampling_time` of [load_emps][sk_offwhite.datasets.load_emps]
        (0.01 s at its default decimation).
    x0 : sequence of 2 floats, default=None
        Initial-state guess `(q, v)` in m and m/s; `None`: at rest at 0.

    Returns
    -------
    PhysicsModel
        States `("q", "v")` of kinds `("position", "velocity")`, input `"tau"` of kind
        `"force"`, output `"q"`, parameters `M` and `Fv` bounded below by `1e-6`.
    """
    parameters = {
        "M": Parameter(_checked_positive("mass", mass), _POSITIVE),
        "Fv": Parameter(_checked_positive("viscous_friction", viscous_friction), _POSITIVE),
    }
    return _mechanical_physics(emps_rhs, parameters, sampling_time, x0)


def _reference_parameters(values: Mapping[str, float] | None, velocity_scale) -> dict:
    values = dict(REFERENCE_PARAMETERS if values is None else values)
    if set(values) != set(REFERENCE_PARAMETERS):
        raise KeyError(f"parameters must name exactly {sorted(REFERENCE_PARAMETERS)}.")
    parameters = {
        name: Parameter(_checked_positive(f"parameters[{name!r}]", values[name]), _POSITIVE)
        for name in ("M", "Fv", "Fc")
    }
    parameters["offset"] = Parameter(float(values["offset"]))
    scale = _checked_positive("velocity_scale", velocity_scale)
    parameters["v_s"] = Parameter(scale, (scale, scale), fixed=True)
    return parameters


def emps_reference_physics(
    parameters: Mapping[str, float] | None = None,
    *,
    velocity_scale: float = VELOCITY_SCALE,
    sampling_time: float = SAMPLING_TIME,
    x0: Sequence[float] | None = None,
) -> PhysicsModel:
    """The benchmark's reference model of the EMPS, with a smooth sign.

    $$ \\dot q = v, \\qquad
    M \\dot v = \\tau - F_v v - F_c \\tanh(v / v_s) - \\mathrm{offset}, \\qquad z = q, $$

    integrated with RK4 over each sampling interval, the force held. The sign of the
    Coulomb friction is smoothed over $v_s$ = 1 mm/s (`velocity_scale`), under 1 % of the
    records' peak speed of 0.125 m/s; at 100 Hz the friction's slope at rest,
    $F_c / (M v_s) \\approx 214$ s⁻¹, keeps RK4 stable ($214 \\times 0.01 < 2.78$).

    Parameters
    ----------
    parameters : dict, default=None
        Starting values of `M` (kg), `Fv` (N s/m), `Fc` (N) and `offset` (N); `None`:
        the benchmark's IDIM-LS estimates (`reference_parameters` of
        [load_emps][sk_offwhite.datasets.load_emps]).
    velocity_scale : float, default=1e-3
        $v_s$ in m/s, kept fixed (the parameter `v_s`).
    sampling_time : float, default=0.01
        Seconds per sample: `data.sampling_time` of [load_emps][sk_offwhite.datasets.load_emps].
    x0 : sequence of 2 floats, default=None
        Initial-state guess `(q, v)`; `None`: at rest at 0.

    Returns
    -------
    PhysicsModel
        States `("q", "v")` of kinds `("position", "velocity")`, input `"tau"` of kind
        `"force"`, output `"q"`; `M`, `Fv`, `Fc` bounded below by `1e-6`, `offset` free,
        `v_s` fixed.
    """
    values = _reference_parameters(parameters, velocity_scale)
    return _mechanical_physics(emps_reference_rhs, values, sampling_time, x0)
