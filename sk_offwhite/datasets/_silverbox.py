"""Measured Silverbox benchmark (an electronic Duffing oscillator) and its linear model.

The record is `SNLS80mV` of the Silverbox benchmark (Wigren and Schoukens 2013), shipped in
`data/silverbox_snls80mv.npz`; see `data/SILVERBOX.md` for provenance, attribution and
checksums.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np
from sklearn.utils import Bunch

from sk_offwhite import Parameter, PhysicsModel
from sk_offwhite.datasets._packed import read_packed

__all__ = ["load_silverbox", "silverbox_physics"]

SAMPLING_TIME = 1.0 / 610.3515625
"""Sampling time of the record, in seconds: $2^{14} / 10^7$ = 1.6384 ms."""

INIT_WINDOW = 50
"""Samples at the start of each test from which its initial state is estimated (not scored)."""

N_NO_EXTRAPOLATION = 32_000
"""Samples at the start of the arrow test in its "no extrapolation" part: up to there its
amplitude stays close to the estimation record's (a peak output of 0.233 V against 0.216 V);
beyond, it reaches 0.301 V."""

ARROW = (100, 40_575)
"""0-based `[start, stop)` of the arrow test in `SNLS80mV`."""

MULTISINE = (40_650, 127_400)
"""0-based `[start, stop)` of the multisine part: the first 75 % for estimation, the rest a
multisine test."""

ESTIMATION_FRACTION = 0.75
"""Fraction of the multisine part used for estimation (rounded down to whole samples)."""

_FILE = "silverbox_snls80mv.npz"

_DESCR = """\
Silverbox benchmark (measured data)
===================================

An electronic circuit implementing a mass-spring-damper with a hardening cubic spring,
m y'' + d y' + k(y) y = u with k(y) = k1 + k3 y^2 (Duffing), Wigren and Schoukens, "Three
free data sets for development and benchmarking in nonlinear system identification", ECC
2013. Input `u`: voltage V1 (V); output `y`: voltage V2 (V). Record SNLS80mV, 131 072
samples at 1e7 / 2^14 = 610.3515625 Hz (Ts = 1.6384 ms). The means of V1 and V2 over the
whole record are removed (`input_mean`, `output_mean`), as the benchmark's notes advise.

Parts (0-based slices of SNLS80mV, `slices`): the arrow test [100:40575], whose amplitude
grows along the record; its first 32 000 samples stay close to the estimation record's
range (the "no extrapolation" test), the rest go beyond it. The multisine part
[40650:127400]: its first 75 % (65 062 samples, [40650:105712]) is the estimation record,
the rest ([105712:127400]) a multisine test.

Scoring protocol (`protocols["nonlinear_benchmarks"]`): each test's initial state is
estimated from its first 50 samples, which are not scored; RMS error in mV.

Data: the benchmark's SilverboxFiles.zip (public copy: GitHub antonior92/sysid-neuralnet);
see data/SILVERBOX.md in this package.
"""


def _raw_voltages() -> tuple[np.ndarray, np.ndarray]:
    """V1 and V2 of the whole record (V): the shipped integer codes times their step."""
    packed = read_packed(_FILE)
    step = packed["volts_per_code"]
    return packed["V1_codes"] * step, packed["V2_codes"] * step


def _slices() -> dict[str, tuple[int, int]]:
    start, stop = MULTISINE
    split = start + math.floor(ESTIMATION_FRACTION * (stop - start))
    return {
        "estimation": (start, split),
        "arrow": ARROW,
        "arrow_no_extrapolation": (ARROW[0], ARROW[0] + N_NO_EXTRAPOLATION),
        "multisine_test": (split, stop),
    }


def _protocols() -> dict:
    return {
        "nonlinear_benchmarks": {
            "description": (
                "Estimate on (u_est, z_est) only; simulate each test record from its input, "
                "its initial state estimated from its first 50 outputs, and report the RMS "
                "error of the output over the remaining samples, in mV."
            ),
            "init_window": INIT_WINDOW,
            "tests": ("arrow", "arrow_no_extrapolation", "multisine_test"),
            "rmse_unit": "mV",
            "rmse_scale": 1e3,
        }
    }


def _records(u: np.ndarray, y: np.ndarray, slices: dict) -> dict[str, np.ndarray]:
    """`u_<part>`, `z_<part>` columns of every part (`est` for the estimation record)."""
    records = {}
    for part, (start, stop) in slices.items():
        key = "est" if part == "estimation" else part
        records[f"u_{key}"] = u[start:stop, None].copy()
        records[f"z_{key}"] = y[start:stop, None].copy()
    return records


def load_silverbox() -> Bunch:
    """Load the measured Silverbox benchmark record `SNLS80mV`, means removed.

    Returns
    -------
    data : sklearn.utils.Bunch
        `u_est`, `z_est` : ndarray of shape (65062, 1)
            Input V1 and output V2 (V) of the estimation record, the first 75 % of the
            multisine part (fresh copies on every call, as are all arrays).
        `u_arrow`, `z_arrow` : ndarray of shape (40475, 1)
            The arrow test.
        `u_arrow_no_extrapolation`, `z_arrow_no_extrapolation` : ndarray of shape (32000, 1)
            The arrow test's first 32 000 samples.
        `u_multisine_test`, `z_multisine_test` : ndarray of shape (21688, 1)
            The last 25 % of the multisine part.
        `sampling_time` : float
            $T_s = 2^{14} / 10^7$ s = 1.6384 ms.
        `input_mean`, `output_mean` : float
            The means of V1 and V2 over the whole record (V), removed from every array.
        `slices` : dict
            Each part's 0-based `(start, stop)` in the record (`"estimation"`, `"arrow"`,
            `"arrow_no_extrapolation"`, `"multisine_test"`).
        `input_names`, `output_names` : list of str
            `["u"]` and `["y"]`.
        `units` : dict
            `{"u": "V", "y": "V"}`.
        `protocols` : dict
            `"nonlinear_benchmarks"`: `description`, `init_window` (50), `tests`,
            `rmse_unit` (`"mV"`) and `rmse_scale` (1000, volts to millivolts).
        `published_results` : list of dict
            Published test RMS errors (mV), `method`, `test_rms`, `source`, `note`; none
            are listed yet.
        `DESCR` : str
            Description of the benchmark.

    Examples
    --------
    >>> from sk_offwhite.datasets import load_silverbox
    >>> data = load_silverbox()
    >>> data.u_est.shape, data.z_arrow.shape
    ((65062, 1), (40475, 1))
    """
    v1, v2 = _raw_voltages()
    input_mean, output_mean = float(np.mean(v1)), float(np.mean(v2))
    slices = _slices()
    return Bunch(
        **_records(v1 - input_mean, v2 - output_mean, slices),
        sampling_time=SAMPLING_TIME,
        input_mean=input_mean,
        output_mean=output_mean,
        slices=slices,
        input_names=["u"],
        output_names=["y"],
        units={"u": "V", "y": "V"},
        protocols=_protocols(),
        published_results=[],
        DESCR=_DESCR,
    )


def silverbox_rhs(x, u, theta):
    """Rate of the linear oscillator $m \\ddot y + d \\dot y + k_1 y = u$ (`jax.numpy`)."""
    acceleration = (u[0] - theta["d"] * x[1] - theta["k1"] * x[0]) / theta["m"]
    return jnp.stack([x[1], acceleration])


def _positive(argument: str, value, lower: float) -> Parameter:
    value = float(value)
    if not (math.isfinite(value) and value > lower):
        raise ValueError(f"{argument} must be a finite number above {lower:g}, got {value!r}.")
    return Parameter(value, (lower, None))


def silverbox_physics(
    m: float = 7e-6,
    d: float = 5e-4,
    k1: float = 1.0,
    *,
    sampling_time: float = SAMPLING_TIME,
    x0: Sequence[float] | None = None,
) -> PhysicsModel:
    """The linear part of the Silverbox: a mass-spring-damper driven by the input voltage.

    $$ \\dot y = v, \\qquad m \\dot v = u - d v - k_1 y, \\qquad z = y, $$

    integrated with RK4 over each sampling interval, the input held (zero-order hold). With
    input and output in volts, $k_1$ is the inverse of the static gain, $m$ is in s² and
    $d$ in s. The defaults are what a look at the record suggests: a resonance near 60 Hz,
    $m = k_1 / (2\\pi \\cdot 60)^2 \\approx 7 \\times 10^{-6}$, a static gain of 1
    ($k_1 = 1$) and a damping ratio of 0.1, $d = 2 \\cdot 0.1 \\sqrt{k_1 m} \\approx
    5 \\times 10^{-4}$. The circuit's cubic stiffness $k_3 y^3$ is deliberately left out:
    that is for the closed loop ([close_the_loop][sk_offwhite.loop.close_the_loop]) to
    find.

    Parameters
    ----------
    m, d, k1 : float, default=7e-6, 5e-4, 1.0
        Starting values; each is bounded below (`m` by `1e-9`, `d` by 0, `k1` by `1e-6`).
    sampling_time : float, default=1/610.3515625
        Seconds per sample.
    x0 : sequence of 2 floats, default=None
        Initial-state guess `(y, v)` in V and V/s; `None`: at rest at 0.

    Returns
    -------
    PhysicsModel
        States `("y", "v")` of kinds `("position", "velocity")` (the circuit's analogue of a
        displacement and its rate), input `"u"` of kind `"voltage"`, output `"y"`,
        parameters `m`, `d`, `k1`.
    """
    if not (math.isfinite(float(sampling_time)) and sampling_time > 0):
        raise ValueError(f"sampling_time must be a positive number, got {sampling_time!r}.")
    parameters = {
        "m": _positive("m", m, 1e-9),
        "d": _positive("d", d, 0.0),
        "k1": _positive("k1", k1, 1e-6),
    }
    return PhysicsModel.from_ode(
        silverbox_rhs,
        float(sampling_time),
        output=0,
        parameters=parameters,
        n_states=2,
        n_inputs=1,
        method="rk4",
        x0=x0,
        state_names=("y", "v"),
        input_names=("u",),
        output_names=("y",),
        state_kinds=("position", "velocity"),
        input_kinds=("voltage",),
    )
