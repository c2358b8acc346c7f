"""How sk_offwhite's cost grows: record length, dictionary size and a γ grid search.

Run with ``python benchmarks/bench_scaling.py [--quick] [--out reports/benchmarks]``.
On noise-free Cascaded Tanks data (eq. 21, k4 fixed) it measures

* microseconds per simulated step of one value-and-gradient of the multi-step cost,
  against the record length (10³ to 10⁵ samples);
* the wall time of a physics-only fit against the record length;
* the wall time of a fit with a correction against the dictionary size (polynomial
  degree 1 to 4 on ``(x1, x2, u)``), at a fixed number of iterations;
* the wall time of ``GridSearchCV`` over 5 values of γ (3 contiguous folds).

Writes ``bench_scaling[_quick].md`` and ``.json`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import jax
import numpy as np
import pysindy as ps
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV, KFold

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.datasets import cascaded_tanks_physics
from sk_offwhite.fitting._problem import bound_blocks, free_blocks, initial_blocks, make_problem
from sk_offwhite.simulation._layout import Layout
from sk_offwhite.simulation._segments import make_segments
from sk_offwhite.solvers._core import free_residuals

GAMMAS = (1e-5, 1e-4, 1e-3, 1e-2, 1e-1)


TRUE_K = {"k1": 0.1, "k2": 0.075, "k3": 0.07, "k4": 0.088}


def multisine(n_samples: int, rng) -> np.ndarray:
    """Pump voltage: random-phase multisine below 0.0576 cycles/sample, mean 2.8, std 1."""
    freqs = np.fft.rfftfreq(n_samples)
    spectrum = np.where((freqs > 0) & (freqs < 0.0576), 1.0, 0.0).astype(complex)
    spectrum *= np.exp(2j * np.pi * rng.uniform(size=freqs.shape))
    signal = np.fft.irfft(spectrum, n_samples)
    return np.clip(2.8 + signal / signal.std(), 0.0, None)[:, None]


def tanks_data(n_samples: int):
    """Noise-free eq. (21) record (numpy Euler loop) and the physics with k4 fixed."""
    u, x = multisine(n_samples, np.random.default_rng(0)), np.array([5.0, 6.0])
    z, k = np.empty((n_samples, 1)), TRUE_K
    for i in range(n_samples):
        z[i] = x[1]
        r1, r2 = np.sqrt(max(x[0], 1e-6)), np.sqrt(max(x[1], 1e-6))
        x = x + 4.0 * np.array([-k["k1"] * r1 + k["k4"] * u[i, 0], k["k2"] * r1 - k["k3"] * r2])
    physics = cascaded_tanks_physics(fixed={"k4": k["k4"]}, x0=[z[0, 0]] * 2)
    return u, z, physics


def cost_problem(u, z, physics, library=None, horizon=None, weights=(0.1, 0.0, 0.0, 10.0, 1000.0)):
    """The fit cost's static structure and data: ``(model, layout, problem, free0)``."""
    est = GreyBoxSparseRegressor(physics, library=library, horizon=horizon)
    basis, model = est._compile(physics)
    records = [(u, z)]
    segments = make_segments(records, horizon)
    blocks = initial_blocks(physics, basis, model, records, segments, horizon)
    free = free_blocks(physics, basis, model, segments)
    layout = Layout.from_arrays(blocks)
    problem, free0 = make_problem(
        layout, blocks, free, bound_blocks(physics, blocks, records, segments), segments, weights
    )
    return model, layout, problem, free0


def value_and_grad_problem(u, z, physics, library=None, horizon=None):
    """Jitted value-and-gradient of the fit cost and its starting point."""
    model, layout, problem, free0 = cost_problem(u, z, physics, library, horizon)

    def cost(f):
        residuals = free_residuals(f, problem, model, layout)
        return residuals @ residuals

    return jax.jit(jax.value_and_grad(cost)), free0


def time_value_and_grad(n_samples: int, repeats: int) -> dict:
    """Microseconds per step of one value-and-gradient (physics only, whole record)."""
    u, z, physics = tanks_data(n_samples)
    with jax.enable_x64(True):
        value_and_grad, free0 = value_and_grad_problem(u, z, physics)
        jax.block_until_ready(value_and_grad(free0))
        start = time.perf_counter()
        for i in range(repeats):
            jax.block_until_ready(value_and_grad(free0 + 1e-9 * (i + 1)))
        seconds = (time.perf_counter() - start) / repeats
    return {"n_samples": n_samples, "us_per_step": 1e6 * seconds / n_samples}


def _timed_fit(est, u, z) -> tuple[float, GreyBoxSparseRegressor]:
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est.fit(u, z)
    return time.perf_counter() - start, est


def time_fit_length(n_samples: int) -> dict:
    """Physics-only fit (horizon 256, LM): first fit (compiles) and a second one."""
    u, z, physics = tanks_data(n_samples)
    first, _ = _timed_fit(GreyBoxSparseRegressor(physics, horizon=256), u, z)
    second, est = _timed_fit(GreyBoxSparseRegressor(physics, horizon=256), u, z)
    return {"n_samples": n_samples, "first_fit_s": first, "fit_s": second,
            "iterations": est.n_iter_}  # fmt: skip


def time_fit_dictionary(degree: int, n_samples: int, max_iter: int) -> dict:
    """Fit with a polynomial dictionary of ``degree`` on (x1, x2, u), fixed iterations."""
    u, z, physics = tanks_data(n_samples)
    library = ps.PolynomialLibrary(degree=degree)
    est = GreyBoxSparseRegressor(
        physics, library=library, gamma=1e-3, horizon=256, max_iter=max_iter, tol=0.0
    )
    first, _ = _timed_fit(clone(est), u, z)
    seconds, est = _timed_fit(est, u, z)
    return {
        "degree": degree,
        "n_features": len(est.feature_names_),
        "first_fit_s": first,
        "fit_s": seconds,
        "iterations": est.n_iter_,
        "ms_per_iteration": 1e3 * seconds / max(est.n_iter_, 1),
    }


def time_grid_search(n_samples: int, n_jobs: int) -> dict:
    """``GridSearchCV`` over 5 γ (3 contiguous folds) of physics + degree-2 dictionary."""
    u, z, physics = tanks_data(n_samples)
    est = GreyBoxSparseRegressor(
        physics, library=ps.PolynomialLibrary(degree=2), horizon=128, max_iter=100
    )
    search = GridSearchCV(est, {"gamma": list(GAMMAS)}, cv=KFold(3), n_jobs=n_jobs)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search.fit(u, z, sample_index=np.arange(n_samples))
    seconds = time.perf_counter() - start
    return {"n_samples": n_samples, "n_jobs": n_jobs, "fits": 16, "total_s": seconds,
            "best_gamma": search.best_params_["gamma"]}  # fmt: skip


def _table(rows: list[dict]) -> str:
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    for row in rows:
        cells = [f"{v:.3g}" if isinstance(v, float) else str(v) for v in row.values()]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def run(quick: bool) -> dict:
    """Every measurement; ``quick`` uses fewer repeats and a shorter grid-search record."""
    lengths = (1_000, 10_000, 100_000)
    return {
        "value_and_grad": [time_value_and_grad(n, 10 if quick else 50) for n in lengths],
        "fit_vs_length": [time_fit_length(n) for n in lengths],
        "fit_vs_dictionary": [
            time_fit_dictionary(d, 1024, 20 if quick else 50) for d in (1, 2, 3, 4)
        ],
        "grid_search": [time_grid_search(512 if quick else 1024, 1)],
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--out", default="reports/benchmarks")
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    from run_all import machine  # the benchmarks folder is on sys.path when run as a script

    results = {"machine": machine(), "mode": "quick" if args.quick else "full"}
    results.update(run(args.quick))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stem = out / ("bench_scaling_quick" if args.quick else "bench_scaling")
    stem.with_suffix(".json").write_text(json.dumps(results, indent=2, default=float))
    titles = {
        "value_and_grad": "Value-and-gradient of the cost (physics only, whole record)",
        "fit_vs_length": "Physics-only fit against record length (horizon 256; first fit compiles)",
        "fit_vs_dictionary": "Fit with a dictionary against its size (1024 samples, horizon 256)",
        "grid_search": "GridSearchCV over 5 values of γ (3 folds, n_jobs=1)",
    }
    text = "\n\n".join(f"**{t}**\n\n{_table(results[k])}" for k, t in titles.items())
    stem.with_suffix(".md").write_text(text + "\n")
    print(text)
    from _results import records_table, write_results  # same folder: run as a script

    tables = [records_table(t, results[k]) for k, t in titles.items()]
    name = "bench_scaling_quick" if args.quick else "bench_scaling"
    write_results(name, tables, path=args.json, argv=argv, data=results)


if __name__ == "__main__":
    main()
