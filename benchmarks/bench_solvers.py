"""The package's Levenberg-Marquardt against optimistix's solvers, on the same residuals.

Run with ``python benchmarks/bench_solvers.py [--repeats 3] [--default-loops] [--out DIR]``
(needs ``pip install -e '.[bench]'`` for optimistix). Each solver minimises the same
$\\|r\\|^2$, the package's multi-step residuals of the Cascaded Tanks (eq. 21, ``k4``
fixed; the measured estimation record, repeated for 10 000 samples) from the same start,
with $\\gamma = 0$ so that every solver minimises the same smooth function:

* physics only (5 free variables) at 1000 and 10 000 samples;
* with a degree-2 polynomial dictionary on both states (25 free variables), 1000 samples.

For each: the first call (compilation included), the fastest of ``--repeats`` further
calls, the iterations, the cost reached and whether the solution is finite and within the
box bounds of the physics (the package's solver projects on them; optimistix's do not know
them). The package's solver runs with the estimator's defaults (``max_iter=200``,
``tol=1e-10``); optimistix's with ``rtol = atol = 1e-8`` and 200 steps at most. Writes
``bench_solvers.md`` in ``--out`` (default ``reports/benchmarks``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import jax
import numpy as np
from bench_speed import _lm_problem  # same folder: run as a script

MAX_STEPS = 200


def _solvers(model, layout, problem, free0) -> dict:
    """Zero-argument calls returning ``(free, iterations)`` for each solver."""
    import optimistix as optx

    from sk_offwhite.solvers._core import free_residuals
    from sk_offwhite.solvers._device import levenberg_marquardt_on_device as levenberg_marquardt

    def ours():
        result = levenberg_marquardt(free0, problem, model, layout, max_iter=MAX_STEPS, tol=1e-10)
        return result.free, result.n_iter

    def residuals(free, data):
        return free_residuals(free, data, model, layout)

    def theirs(solver):
        @jax.jit
        def solve(start, data):
            solution = optx.least_squares(
                residuals, solver, start, args=data, max_steps=MAX_STEPS, throw=False
            )
            return solution.value, solution.stats["num_steps"]

        return lambda: solve(free0, problem)

    return {
        "sk_offwhite LM": ours,
        "optimistix LevenbergMarquardt": theirs(optx.LevenbergMarquardt(rtol=1e-8, atol=1e-8)),
        "optimistix GaussNewton": theirs(optx.GaussNewton(rtol=1e-8, atol=1e-8)),
    }


def _timed(call) -> tuple[float, tuple]:
    start = time.perf_counter()
    free, n_iter = call()
    free = np.asarray(jax.block_until_ready(free))
    return time.perf_counter() - start, (free, int(n_iter))


def compare(repeats: int) -> list[dict]:
    """One row per case and solver."""
    import pysindy as ps

    from sk_offwhite.solvers._core import free_residuals

    rows = []
    with jax.enable_x64(True):
        cases = ((1000, None), (10000, None), (1000, ps.PolynomialLibrary(degree=2)))
        for n_samples, library in cases:
            model, layout, problem, free0 = _lm_problem(n_samples, library, gamma=0.0)
            for name, call in _solvers(model, layout, problem, free0).items():
                first, (free, n_iter) = _timed(call)
                warm = min(_timed(call)[0] for _ in range(repeats))
                r = np.asarray(free_residuals(free, problem, model, layout))
                lower, upper = np.asarray(problem.lower), np.asarray(problem.upper)
                rows.append(
                    {
                        "samples": n_samples,
                        "free": int(free0.shape[0]),
                        "solver": name,
                        "first_call_s": first,
                        "warm_s": warm,
                        "iterations": n_iter,
                        "cost": float(r @ r),
                        "bounds": _bounds(free, lower, upper),
                    }
                )
    return rows


def _bounds(free: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> str:
    if not np.all(np.isfinite(free)):
        return "not finite"
    return "held" if np.all((free >= lower) & (free <= upper)) else "violated"


def _markdown(rows: list[dict], loops: str) -> str:
    from importlib.metadata import version

    versions = f"jax {jax.__version__}, optimistix {version('optimistix')}"
    lines = [
        f"{versions}; loops on CPU: {loops}; γ = 0, at most {MAX_STEPS} iterations.",
        "",
        "| samples | free | solver | first call (s) | warm (s) | iterations | cost | bounds |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [
        f"| {r['samples']} | {r['free']} | {r['solver']} | {r['first_call_s']:.2f} | "
        f"{r['warm_s']:.4f} | {r['iterations']} | {r['cost']:.6g} | "
        f"{r['bounds']} |"
        for r in rows
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--default-loops", action="store_true", help="XLA's default loops")
    parser.add_argument("--out", default="reports/benchmarks")
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    if not args.default_loops:
        from sk_offwhite import enable_fused_loops

        enable_fused_loops()
    loops = "XLA's default" if args.default_loops else "fused"
    rows = compare(args.repeats)
    text = _markdown(rows, loops)
    print(text)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_solvers.md").write_text(text, encoding="utf-8")
    from _results import records_table, write_results  # same folder: run as a script

    title = f"Same residuals, same start, γ = 0, at most {MAX_STEPS} iterations; loops: {loops}"
    write_results("bench_solvers", [records_table(title, rows)], path=args.json, argv=argv)


if __name__ == "__main__":
    main()
