"""The closed loop on the measured EMPS benchmark, from the textbook model of a positioning drive.

Declares what a physicist would write first for the Electro-Mechanical Positioning System,
a mass with viscous friction driven by the motor force (`emps_physics`), fits it to the
estimation record at 100 Hz, lets the closed loop find and add what it lacks, and writes a
report. Everything is chosen on the estimation record; the validation record (with extra
force pulses) is only scored, with the benchmark's protocol: its initial state estimated from
its first 20 ms (2 samples at 100 Hz), which are not scored, and the RMS error of the position
in mm. For comparison the benchmark's reference law (`emps_reference_physics`: viscous and
Coulomb friction and a force offset) is fitted with all four parameters free and scored the
same way.

Run: ``python examples/emps_loop.py [--out DIR] [--quick] [--quiet] [--no-cache]
[--n-jobs N]`` (``DIR`` defaults to ``reports/emps``); ``--quick`` only checks that the
script runs.
"""

from __future__ import annotations

import argparse
import time

import jax.numpy as jnp
import numpy as np
import pysindy as ps
from _study import configure_runtime, print_outcome, print_rows, write_study_report

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.datasets import emps_physics, emps_reference_physics, load_emps
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models

COULOMB_WIDTH = 0.01
"""Velocity (m/s) over which the library's smooth sign rises: under a tenth of the peak speed."""


REFERENCE_LABEL = "reference law, fitted"
"""The label of the benchmark's reference law in the report's rows."""

QUICK_SAMPLES = 600
"""Estimation samples the `--quick` run fits (6 s of the record)."""


def smooth_sign(v):
    """`tanh(v / 0.01)`, a Coulomb friction's sign (numpy in pysindy, jax.numpy in the fit)."""
    xp = np if isinstance(v, np.ndarray) else jnp
    return xp.tanh(v / COULOMB_WIDTH)


def smooth_sign_name(v: str) -> str:
    return f"tanh({v}/{COULOMB_WIDTH:g})"


def drive_library():
    """Terms a physicist expects in a drive: polynomials of degree 2 in `(q, v, tau)` (bias,
    drag `v^2`, position-dependent forces `q`, `q^2`, ...) and a smooth sign of the velocity."""
    return ps.GeneralizedLibrary(
        [
            ps.PolynomialLibrary(degree=2, include_bias=True),
            ps.CustomLibrary([smooth_sign], [smooth_sign_name]),
        ],
        inputs_per_library=[[0, 1, 2], [1]],
    )


def fitted_reference(data, max_iter: int) -> GreyBoxSparseRegressor:
    """The benchmark's reference law, all four parameters free, started at the data notes'."""
    physics = emps_reference_physics(sampling_time=data.sampling_time)
    estimator = GreyBoxSparseRegressor(physics=physics, library=None, max_iter=max_iter)
    return estimator.fit(data.u_est, data.z_est)


def loop_settings(args, init_window: int) -> LoopSettings:
    return LoopSettings(
        gammas=(0.01,) if args.quick else None,
        n_folds=2 if args.quick else 3,
        max_iter=20 if args.quick else 300,
        max_effects=1 if args.quick else 3,
        max_candidates=1 if args.quick else None,
        init_window=init_window,
        n_jobs=args.n_jobs,
        fit_delta=not args.quick,
    )


def parse(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="reports/emps")
    parser.add_argument(
        "--quick", action="store_true", help="short fits, few candidates: checks the script runs"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress messages")
    parser.add_argument(
        "--no-cache", action="store_true", help="do not keep compiled programs on disk"
    )
    parser.add_argument(
        "--n-jobs", type=int, default=2, help="processes for the cross-validation (default 2)"
    )
    return parser.parse_args(argv)


def print_summary(result, rows, reference, elapsed) -> None:
    print_rows(rows, "mm", 1e3, 2, 10)
    values = ", ".join(f"{k} = {v:.4g}" for k, v in reference.parameters_.items())
    print(f"{REFERENCE_LABEL} parameters: {values}")
    print_outcome(result, "mm", 1e3, elapsed)


def main(argv=None):
    args = parse(argv)
    configure_runtime(cache=not args.no_cache, log=not args.quiet)
    data = load_emps()
    init_window = data.protocols["nonlinear_benchmarks"]["init_window"]
    start = time.perf_counter()
    physics = emps_physics(sampling_time=data.sampling_time)
    settings = loop_settings(args, init_window)
    n_fit = QUICK_SAMPLES if args.quick else len(data.u_est)
    u_fit, z_fit = data.u_est[:n_fit], data.z_est[:n_fit]
    result = close_the_loop(physics, drive_library(), u_fit, z_fit, settings=settings)
    records = {"estimation": (u_fit, z_fit), "validation": (data.u_val, data.z_val)}
    reference = fitted_reference(data, 40 if args.quick else 1000)
    others = {REFERENCE_LABEL: reference}
    rows = score_models(result, records, init_window=init_window, others=others)
    elapsed = time.perf_counter() - start
    notes = [
        "Data: measured EMPS benchmark (Janot, Gautier, Brunot 2019), decimated to 100 Hz.",
        "Everything is chosen on the estimation record (3-fold CV inside it, each held-out",
        f"block started from its first {init_window} samples); the validation record is only",
        f"scored. `init_window`: the state estimated from the first {init_window} samples",
        "(20 ms, the benchmark's protocol), which are not scored. RMSE in m (x1000: mm).",
        f"`{REFERENCE_LABEL}`: the benchmark's reference law (viscous and Coulomb friction,",
        "a force offset), its four parameters fitted on the estimation record.",
        f"Wall time of the loop, scoring and reference fit: {elapsed:.0f} s.",
    ]
    path = write_study_report(result, rows, records, args.out, data, title="EMPS", notes=notes)
    print_summary(result, rows, reference, elapsed)
    print(f"report: {path}")


if __name__ == "__main__":
    main()
