"""Sparsity targets: exact supports on the vehicle of Section 5.1, supports in other units.

Sections (all by default, or name some):

* ``vehicle``: ``make_vehicle_lateral`` (T = 2000) for seeds 0-9 without noise and with
  output noise bound 2e-4; physics + the paper's 12-term dictionary on the yaw equation,
  gamma from the default grid (8 values from gamma_max down to 1e-6 gamma_max) chosen by
  3-fold CV on the record (``fit_gamma_path``). Counts the runs whose support is exactly
  Delta's 3 terms.
* ``units``: the Cascaded Tanks estimation record with the README's physics (k4 fixed) and
  a degree-2 polynomial dictionary, in volts and with u, z, the states and the physics
  rescaled by 1e-3 and 1e3 (the same physics in other units): the support path (default
  grid, gamma chosen by 3-fold CV on the record) in each unit, under both of
  Levenberg-Marquardt's scalings (``lm_scaling``); chosen gamma, support and R^2 on the
  estimation record.

Run: ``python benchmarks/bench_sparsity.py [vehicle] [units] [--seeds N]
[--one-standard-error]`` (the last chooses gamma by the one-standard-error rule instead of
the lowest CV error; both before the first diverged fold, ``fit_gamma_path``'s default).
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np
import pysindy as ps

from sk_offwhite import GreyBoxSparseRegressor, PhysicsModel, fit_gamma_path
from sk_offwhite.datasets import cascaded_tanks_physics, load_cascaded_tanks, make_vehicle_lateral

NOISE_BOUNDS = (0.0, 2e-4)


def vehicle_run(seed: int, noise: float, one_se: bool = False) -> dict:
    """One vehicle record: the CV-chosen support against Delta's."""
    data = make_vehicle_lateral(n_samples=2000, noise_bound=noise, random_state=seed)
    est = GreyBoxSparseRegressor(
        data.physics, data.suggested_library, delta_states=[0], max_iter=1000
    )
    start = time.perf_counter()
    path = fit_gamma_path(est, data.u, data.z, cv=3, one_standard_error=one_se)
    truth = data.true_omega != 0
    return {
        "exact": bool(np.array_equal(est.support_[0], truth)),
        "n_terms": est.n_nonzero_,
        "gamma_ratio": path.best_gamma / path.gamma_max,
        "seconds": time.perf_counter() - start,
    }


def vehicle(seeds: int, one_se: bool = False) -> list:
    """Print and return one row per noise bound."""
    rows = []
    for noise in NOISE_BOUNDS:
        runs = [vehicle_run(seed, noise, one_se) for seed in range(seeds)]
        exact = sum(r["exact"] for r in runs)
        terms = [r["n_terms"] for r in runs]
        ratios = ", ".join(f"{r['gamma_ratio']:.1e}" for r in runs)
        seconds = np.median([r["seconds"] for r in runs])
        print(
            f"vehicle, noise bound {noise:g}: exact Delta support in {exact}/{seeds} seeds; "
            f"terms kept {terms}; chosen gamma/gamma_max [{ratios}]; {seconds:.0f} s per path "
            "(median)"
        )
        rows.append([noise, f"{exact}/{seeds}", str(terms), f"[{ratios}]", seconds])
    return rows


def in_units(physics: PhysicsModel, scale: float) -> PhysicsModel:
    """The same physics for states, inputs and outputs all multiplied by ``scale``."""
    step = physics.step

    def scaled_step(x, u, theta):
        return scale * step(x / scale, u / scale, theta)

    lower, upper = physics.x0_bounds
    return PhysicsModel(
        scaled_step,
        list(physics.output.indices),
        physics.parameters,
        physics.n_states,
        physics.n_inputs,
        x0=scale * np.asarray(physics.x0),
        x0_bounds=tuple(
            None if b is None or not np.isfinite(b) else scale * b for b in (lower, upper)
        ),
        state_names=physics.state_names,
        input_names=physics.input_names,
    )


def units(one_se: bool = False, rules=("global", "per-variable")) -> list:
    """Print and return one row per rule and unit."""
    rows = []
    data = load_cascaded_tanks()
    physics = cascaded_tanks_physics(fixed={"k4": 0.05})
    library = ps.PolynomialLibrary(degree=2)
    for rule in rules:
        print(f"lm_scaling={rule!r}: the support path (default grid, 3-fold CV) in each unit")
        for scale in (1.0, 1e-3, 1e3):
            start = time.perf_counter()
            est = GreyBoxSparseRegressor(
                in_units(physics, scale), library, max_iter=300, lm_scaling=rule
            )
            path = fit_gamma_path(
                est, data.u_est * scale, data.z_est * scale, cv=3, one_standard_error=one_se
            )
            terms = np.flatnonzero(est.support_.ravel()).tolist()
            r2 = est.score(data.u_est * scale, data.z_est * scale)
            seconds = time.perf_counter() - start
            print(
                f"scale {scale:g}: gamma {path.best_gamma:.3g}, {est.n_nonzero_} of "
                f"{est.coef_.size} terms {terms}, R^2 {r2:.6f} ({seconds:.0f} s)\n"
                f"{path.summary()}",
                flush=True,
            )
            rows.append([rule, scale, path.best_gamma, est.n_nonzero_, str(terms), r2, seconds])
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sections", nargs="*", default=["vehicle", "units"])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument(
        "--one-standard-error",
        action="store_true",
        help="choose gamma as the largest within one standard error of the lowest CV error",
    )
    parser.add_argument(
        "--lm-scaling", nargs="+", default=["global", "per-variable"], help=argparse.SUPPRESS
    )
    parser.add_argument(
        "--results", default=None, help="folder of the results files (default benchmarks/results)"
    )
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    from _results import RESULTS, table, write_results  # same folder: run as a script

    folder = Path(args.results) if args.results else RESULTS
    rule = "one standard error" if args.one_standard_error else "lowest CV error"
    if "units" in args.sections:
        rows = units(args.one_standard_error, args.lm_scaling)
        columns = ["lm_scaling", "scale", "chosen γ", "terms kept", "support", "R²", "path (s)"]
        title = f"Cascaded Tanks estimation record in three units, γ by 3-fold CV ({rule})"
        tables = [table(title, columns, rows)]
        write_results("bench_sparsity_units", tables, path=folder / "bench_sparsity_units.json")
    if "vehicle" in args.sections:
        rows = vehicle(args.seeds, args.one_standard_error)
        columns = ["noise bound", "exact Δ support", "terms kept", "γ / γ_max", "path (s, median)"]
        title = f"Vehicle of Section 5.1, T = 2000, γ by 3-fold CV ({rule})"
        tables = [table(title, columns, rows)]
        path = folder / "bench_sparsity_vehicle.json"
        write_results("bench_sparsity_vehicle", tables, path=path)


if __name__ == "__main__":
    main()
