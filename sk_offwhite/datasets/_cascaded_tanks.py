"""Measured Cascaded Tanks benchmark data and the physical model of its eq. (21).

The data are the estimation and validation records of the Cascaded Tanks benchmark
(Schoukens, Mattsson, Wigren, Noël 2016); see ``data/CASCADED_TANKS.md`` for provenance,
licence and checksums.
"""

from __future__ import annotations

import csv
from collections.abc import Mapping, Sequence
from importlib import resources

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite.model._physics import Parameter, PhysicsModel

__all__ = ["cascaded_tanks_physics", "load_cascaded_tanks", "safe_sqrt"]

SAMPLING_TIME = 4.0
"""Sampling time of the benchmark records, in seconds."""

SATURATION_LEVEL = 10.0
"""Level (V) at which the lower-tank sensor saturates in the measured records."""

SQRT_EPS = 1e-6
"""Floor used by [`safe_sqrt`][sk_offwhite.datasets.safe_sqrt]."""

_PARAMETER_NAMES = ("k1", "k2", "k3", "k4")
_FILES = {"est": "cascaded_tanks_estimation.csv", "val": "cascaded_tanks_validation.csv"}

_PROTOCOLS = {
    "original": {
        "description": (
            "Benchmark note (Schoukens et al. 2016): estimate on (u_est, z_est) only; simulate "
            "all 1024 validation samples from u_val alone, starting from the initial state "
            "shared with the estimation record, and report the RMS error over all of them."
        ),
        "init_window": 0,
        "scored_samples": (0, 1024),
        "shared_initial_state": True,
    },
    "nonlinear_benchmarks": {
        "description": (
            "PyPI package nonlinear-benchmarks (Cascaded_Tanks()): the model may use u_val and "
            "the first 50 validation outputs z_val[:50] (e.g. to estimate the initial state); "
            "the RMS error is computed on z_val[50:] only."
        ),
        "init_window": 50,
        "scored_samples": (50, 1024),
        "shared_initial_state": False,
    },
}

_PUBLISHED_RESULTS = (
    ("Grey-box model with explicit overflow (Rogers, Holmes, Cross, Worden 2017)", 0.18,
     "quoted in Forgione & Piga, Eur. J. Control 59:69-81 (2021)", ""),
    ("Physics eq. (21) + sparse black-box correction, multi-step (Donati, Mammarella, "
     "Dabbene, Novara, Lagoa)", 0.26,
     "Donati et al., 'Combining off-white and sparse black models in multi-step "
     "physics-based systems identification', Section 5.2 and Table 1",
     "the physics-only model eq. (21) gives 0.670 (fit 68.16 % vs 87.64 %)"),
    ("CT-SUBNET, continuous-time subspace encoder (Beintema, Schoukens, Toth, ICLR 2023)", 0.30,
     "repository GerbenBeintema/CT-subnet, notebook encoder-CT-analysis.ipynb",
     "median over about 17 runs (best single run 0.217); the first half of the test record "
     "was used for early stopping"),
    ("Neural continuous-time state-space model, truncated simulation error "
     "(Forgione & Piga 2021)", 0.33, "Forgione & Piga, Eur. J. Control 59:69-81 (2021)",
     "training RMS 0.08"),
    ("NLSS2, unstructured nonlinear state space (Relan, Tiels, Marconato, Schoukens 2017)",
     0.34, "Forgione & Piga (2021); Hindawi Math. Probl. Eng. 2021, art. 6613425, Table 2",
     "0.3433 in the Hindawi table (labelled MSE there, values are RMS in V)"),
    ("Flexible GP-prior state-space model (Svensson & Schon, Automatica 80, 2017)", 0.45,
     "Forgione & Piga (2021)", ""),
    ("PNLSS-I, polynomial nonlinear state space", 0.4498,
     "Hindawi Math. Probl. Eng. 2021, art. 6613425, Table 2", ""),
    ("Volterra, 3rd degree, with transient removal (Birpoutsoukis et al. 2018)", 0.54,
     "Hindawi Math. Probl. Eng. 2021, art. 6613425, Table 2", ""),
    ("BLA, best linear approximation", 0.7574,
     "Hindawi Math. Probl. Eng. 2021, art. 6613425, Table 2", ""),
    ("Volterra, 3rd degree, no transient estimation", 2.08,
     "Hindawi Math. Probl. Eng. 2021, art. 6613425, Table 2", ""),
)  # fmt: skip

_DESCR = """\
Cascaded Tanks benchmark (measured data)
=======================================

Two cascaded water tanks with free outlets fed by a pump (Schoukens, Mattsson, Wigren,
Noel 2016, Workshop on Nonlinear System Identification Benchmarks). Input ``u``: pump
voltage (V). Output ``x2``: water level of the lower tank measured by an uncalibrated
capacitive sensor (raw V, 16-bit quantisation, saturating at exactly 10 V).

Records: estimation (u_est, z_est) and validation (u_val, z_val), 1024 samples each,
multisine inputs exciting 0-0.0144 Hz (mean 2.8 V, std 1 V), zero-order hold, Ts = 4 s,
SNR about 40 dB. The system was not in steady state; the unknown initial state is the same
for both records. Hard nonlinearities not in the suggested physical model: overflow of the
upper tank (partly into the lower tank) and saturation of the lower tank / sensor at 10 V.

Suggested physics (benchmark note; eq. (21) of Donati et al.):
    x1[k+1] = x1 + Ts (-k1 sqrt(x1) + k4 u)
    x2[k+1] = x2 + Ts ( k2 sqrt(x1) - k3 sqrt(x2)),    z = x2.
With only x2 measured, (k1, k2, k4, x1(0)) are not jointly identifiable.

Scoring protocols (``protocols``): "original" = simulate all 1024 validation samples from
the shared initial state, RMS over all samples; "nonlinear_benchmarks" = the first 50
validation samples may be used to estimate the initial state and are excluded from the RMS.

Data: nonlinearbenchmark.org / 4TU.ResearchData (DOI 10.4121/12960104, licence CC BY-SA 4.0
according to a third-party manifest, not verified). Converted from dataBenchmark.mat with
12 significant digits; see data/CASCADED_TANKS.md in this package.
"""


def safe_sqrt(x, eps: float = SQRT_EPS):
    """Square root that stays finite, with a finite gradient, for ``x <= 0``.

    Computes $\\sqrt{\\max(x, \\varepsilon)}$: equal to $\\sqrt{x}$ for
    $x \\ge \\varepsilon$, constant $\\sqrt{\\varepsilon}$ (gradient 0) below.
    The largest gradient is $1 / (2\\sqrt{\\varepsilon}) = 500$ for the default
    $\\varepsilon = 10^{-6}$. Written with ``jax.numpy``.
    """
    return jnp.sqrt(jnp.maximum(x, eps))


def cascaded_tanks_rhs(x, u, theta):
    """Rate of change of the two levels, eq. (21) without noise (``jax.numpy``).

    $$
    \\dot x_1 = -k_1 \\sqrt{x_1} + k_4 u, \\qquad
    \\dot x_2 = k_2 \\sqrt{x_1} - k_3 \\sqrt{x_2}.
    $$

    """
    root1, root2 = safe_sqrt(x[0]), safe_sqrt(x[1])
    inflow = theta["k4"] * u[0]
    return jnp.stack([-theta["k1"] * root1 + inflow, theta["k2"] * root1 - theta["k3"] * root2])


def cascaded_tanks_rhs_exponents(x, u, theta):
    r"""`cascaded_tanks_rhs` with the outflow laws' exponents as parameters:

    $$
    \dot x_1 = -k_1 x_1^{a_1} + k_4 u, \qquad
    \dot x_2 = k_2 x_1^{a_1} - k_3 x_2^{a_2},
    $$

    levels floored at $10^{-6}$ as in [`safe_sqrt`][sk_offwhite.datasets.safe_sqrt] (``jax.numpy``).
    """
    flow1 = jnp.maximum(x[0], SQRT_EPS) ** theta["a1"]
    flow2 = jnp.maximum(x[1], SQRT_EPS) ** theta["a2"]
    inflow = theta["k4"] * u[0]
    return jnp.stack([-theta["k1"] * flow1 + inflow, theta["k2"] * flow1 - theta["k3"] * flow2])


EXPONENT_BOUNDS = (0.05, 1.5)
"""Range of a relaxed outflow exponent (1/2: turbulent orifice, Torricelli; 1: laminar)."""


def _k_values(k_init) -> dict[str, float]:
    values = np.asarray(k_init, dtype=float)
    if values.size not in (1, 4) or values.ndim > 1 or not np.all(np.isfinite(values)):
        raise ValueError(f"k_init must be one finite number or four (k1..k4), got {k_init!r}.")
    values = np.broadcast_to(values.reshape(-1), (4,))
    return dict(zip(_PARAMETER_NAMES, values.tolist(), strict=True))


def _tank_parameters(k_init, fixed: Mapping[str, float] | None) -> dict[str, Parameter]:
    fixed = dict(fixed or {})
    unknown = set(fixed) - set(_PARAMETER_NAMES)
    if unknown:
        raise KeyError(f"unknown parameters in fixed: {sorted(unknown)}; known: k1..k4.")
    values = _k_values(k_init)
    return {
        name: Parameter(float(fixed.get(name, value)), (1e-6, None), fixed=name in fixed)
        for name, value in values.items()
    }


def cascaded_tanks_physics(
    fixed: Mapping[str, float] | None = None,
    k_init: float | Sequence[float] = 0.05,
    x0: Sequence[float] | None = None,
    sampling_time: float = SAMPLING_TIME,
    relaxable_exponents: bool = False,
) -> PhysicsModel:
    """Physical model of the Cascaded Tanks, eq. (21) of Donati et al. without noise.

    $$
    x_{1,k+1} &= x_{1,k} + T_s(-k_1 \\sqrt{x_{1,k}} + k_4 u_k), \\\\
    x_{2,k+1} &= x_{2,k} + T_s(k_2 \\sqrt{x_{1,k}} - k_3 \\sqrt{x_{2,k}}), \\qquad
    z_k = x_{2,k},
    $$

    i.e. one explicit-Euler step of `cascaded_tanks_rhs` per sample
    ([`PhysicsModel.from_ode`][sk_offwhite.PhysicsModel.from_ode] with ``method="euler"``). Square
    roots use [`safe_sqrt`][sk_offwhite.datasets.safe_sqrt] (``sqrt(max(x, 1e-6))``) so that levels
    at or below zero give finite values and gradients. Overflow and saturation are deliberately not
    modelled.

    Parameters
    ----------
    fixed : dict, default=None
        Parameters to keep fixed, ``name -> value``. With only ``x2`` measured,
        ``(k1, k2, k4, x1(0))`` are not jointly identifiable (scaling ``x1`` by ``a`` and
        ``(k1, k2, k4)`` by ``(sqrt(a), 1/sqrt(a), a)`` leaves the output unchanged);
        fixing one of them, e.g. ``{"k4": 0.05}``, removes that direction.
    k_init : float or sequence of 4 floats, default=0.05
        Initial guess of ``(k1, k2, k3, k4)`` (the paper's choice is 0.05 for all).
    x0 : sequence of 2 floats, default=None
        Initial-state guess. ``None`` uses ``[z0, z0]`` with ``z0`` the first output of the
        measured estimation record (5.205 V), as in the paper.
    sampling_time : float, default=4.0
        ``Ts`` in seconds.
    relaxable_exponents : bool, default=False
        Write the square roots as powers $x_i^{a_i}$ with exponents ``a1``, ``a2``
        fixed at 1/2 and relaxable ([`Parameter`][sk_offwhite.Parameter], bounds
        `EXPONENT_BOUNDS`): the closed loop may then free them
        ([`RelaxedLaw`][sk_offwhite.RelaxedLaw]) if that lowers the cross-validated error
        (`cascaded_tanks_rhs_exponents`).

    Returns
    -------
    PhysicsModel
        Two states ``("x1", "x2")``, input ``"u"``, output ``"x2"``, parameters ``k1..k4``
        bounded below by ``1e-6``, initial levels bounded below by 0.
    """
    if x0 is None:
        z0 = float(_read_record("est")[0, 1])
        x0 = (z0, z0)
    parameters = _tank_parameters(k_init, fixed)
    if relaxable_exponents:
        law = Parameter(0.5, EXPONENT_BOUNDS, fixed=True, relaxable=True)
        parameters.update(a1=law, a2=law)
    return PhysicsModel.from_ode(
        cascaded_tanks_rhs_exponents if relaxable_exponents else cascaded_tanks_rhs,
        sampling_time,
        output=1,
        parameters=parameters,
        n_states=2,
        n_inputs=1,
        method="euler",
        x0=x0,
        x0_bounds=(0.0, None),
        state_names=("x1", "x2"),
        input_names=("u",),
        output_names=("x2",),
        state_kinds=("level", "level"),
        input_kinds=("voltage",),
    )


def _read_record(part: str) -> np.ndarray:
    """Return the ``(1024, 2)`` array ``[u, y]`` of one record from the package data."""
    text = resources.files(__package__).joinpath("data", _FILES[part]).read_text("utf-8")
    rows = list(csv.reader(text.splitlines()))
    header, body = rows[0], rows[1:]
    columns = [header.index("u_pump_V"), header.index("y_lower_tank_V")]
    return np.array([[float(row[c]) for c in columns] for row in body], dtype=np.float64)


def _published_results() -> list[dict]:
    keys = ("method", "test_rms", "source", "note")
    return [dict(zip(keys, row, strict=True)) for row in _PUBLISHED_RESULTS]


def load_cascaded_tanks() -> Bunch:
    """Load the measured Cascaded Tanks benchmark records.

    Returns
    -------
    data : sklearn.utils.Bunch
        ``u_est``, ``z_est``, ``u_val``, ``z_val`` : ndarray of shape (1024, 1), float64
            Pump voltage (V) and lower-tank level sensor output (V) of the estimation and
            validation records (fresh copies on every call).
        ``time`` : ndarray of shape (1024,)
            Sample times ``k * Ts`` in seconds (both records).
        ``sampling_time`` : float
            ``Ts = 4.0`` s.
        ``input_names``, ``output_names`` : list of str
            ``["u"]`` and ``["x2"]``.
        ``units`` : dict
            ``{"u": "V", "x2": "V"}``: the pump voltage and the raw level-sensor voltage,
            by the names of [`cascaded_tanks_physics`][sk_offwhite.datasets.cascaded_tanks_physics]
            (its states are in the sensor's volts, since ``z = x2``).
        ``saturation_level`` : float
            10.0 V, where the lower-tank sensor saturates.
        ``protocols`` : dict
            The two scoring protocols, ``"original"`` (init window 0) and
            ``"nonlinear_benchmarks"`` (init window 50), each with ``description``,
            ``init_window`` and ``scored_samples``.
        ``published_results`` : list of dict
            Published validation simulation RMS errors (V): ``method``, ``test_rms``,
            ``source``, ``note``.
        ``DESCR`` : str
            Description of the benchmark.

    Examples
    --------
    >>> from sk_offwhite.datasets import load_cascaded_tanks
    >>> data = load_cascaded_tanks()
    >>> data.u_est.shape, data.sampling_time
    ((1024, 1), 4.0)
    """
    est, val = _read_record("est"), _read_record("val")
    return Bunch(
        u_est=est[:, :1].copy(),
        z_est=est[:, 1:].copy(),
        u_val=val[:, :1].copy(),
        z_val=val[:, 1:].copy(),
        time=SAMPLING_TIME * np.arange(est.shape[0], dtype=np.float64),
        sampling_time=SAMPLING_TIME,
        input_names=["u"],
        output_names=["x2"],
        units={"u": "V", "x2": "V"},
        saturation_level=SATURATION_LEVEL,
        protocols={name: dict(spec) for name, spec in _PROTOCOLS.items()},
        published_results=_published_results(),
        DESCR=_DESCR,
    )
