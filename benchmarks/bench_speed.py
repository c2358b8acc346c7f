"""Speed of sk_offwhite, measured the way a user meets it: cold, warm, per step, per grid.

Run with ``python benchmarks/bench_speed.py [--rounds 3] [--main-job] [--fused-loops]
[--jax-sysid-python PATH] [--only-fit] [--out DIR]``. One run
prints (and writes ``bench_speed.md`` / ``.json`` in ``--out``, default
``reports/benchmarks``):

* **fit, cold and warm** — the physics-only Cascaded Tanks fit (eq. 21 with ``k4`` fixed,
  every other parameter and both initial levels free, the measured estimation record):
  sk_offwhite; scipy ``least_squares`` on a numpy Euler loop of the same model (finite
  differences); jax-sysid, from the environment given by ``--jax-sysid-python`` (its
  version 1.1 requires ``jax<=0.4.31``, so it needs an environment of its own) or from
  this one when it is installed here, skipped otherwise. Each contender runs in a fresh
  process, contenders alternating, ``--rounds`` times: its import, its *first fit*
  (+ predict, compilation included), *cold* (the two together) and *warm* (the same fit
  again in that process), min and median, with its JAX version and simulation MSE.
* **per step** — microseconds per simulated step of what the solver runs: one
  Levenberg-Marquardt iteration (one program: the damped step, the candidate's simulation
  and, when it is accepted, the Jacobian there), accepted and rejected, called from
  Python; per pass of a whole run on the device (what a fit runs: the same iterations in
  one program); and the plain forward rollout, physics only and with a 10-term
  dictionary, at 10³ and 10⁴ samples; min and median of interleaved repeats.
* **grid against one fit** — ``fit_gamma_path`` over 8 values of γ with 3 contiguous
  folds, and ``GridSearchCV`` over the same γ and folds, against one fit at the γ the path
  chose, all after a warm-up (and the first path cold); and the work each does, whatever
  the compilation: the Levenberg-Marquardt runs and iterations of the path and of the one
  fit (in one process), and how many runs ended at ``max_iter``.
* **batched against sequential** — the path's 8 γ as one ``vmap``-ped solver run against
  the same 8 runs in turn, from one start (compilation excluded): whether batching what
  has the same shape pays on this machine.
* **creeping runs** — the path's first unpenalised runs that ended at ``max_iter``, run
  again with 2000 iterations and by scipy's ``least_squares`` from the same start.
* **memory** — resident set size over 100 fits in one process (growth per fit).
* **main job** (``--main-job``) — the README's closed loop on the Cascaded Tanks in a
  fresh process, split into XLA compilation, tracing, lowering and the rest
  (``jax.monitoring``), and its peak RSS, without the on-disk compilation cache; and the
  README's command as a user runs it (two workers, the cache on), with a cache of its own
  empty and then filled: wall time, the report's time and the peak RSS.

Everything runs with XLA's default for loops on CPU unless ``--fused-loops`` is given, which
calls [`sk_offwhite.enable_fused_loops`][sk_offwhite.enable_fused_loops] first (inherited by every
process the script starts, the main job included).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
import warnings
from functools import partial
from pathlib import Path

HERE = Path(__file__).resolve().parent
K4 = 0.05


def _tanks_record():
    """The estimation record ``(u, z)``, read from the package's data file with numpy only
    (so that no contender's import time includes sk_offwhite, and jax-sysid can run in an
    environment without it)."""
    import numpy as np

    path = HERE.parent / "sk_offwhite" / "datasets" / "data" / "cascaded_tanks_estimation.csv"
    table = np.genfromtxt(path, delimiter=",", names=True)
    return table["u_pump_V"][:, None], table["y_lower_tank_V"][:, None]


def _fit_sk(u, z):
    import numpy as np

    from sk_offwhite import GreyBoxSparseRegressor
    from sk_offwhite.datasets import cascaded_tanks_physics

    est = GreyBoxSparseRegressor(cascaded_tanks_physics(fixed={"k4": K4}))
    est.fit(u, z)
    return float(np.mean((est.predict(u).ravel() - z[:, 0]) ** 2))


def _euler_outputs(params, u):
    import numpy as np

    k1, k2, k3, x1, x2 = params
    outputs = np.empty(len(u))
    for i, u_k in enumerate(u[:, 0]):
        outputs[i] = x2
        r1, r2 = np.sqrt(max(x1, 1e-6)), np.sqrt(max(x2, 1e-6))
        x1, x2 = x1 + 4.0 * (-k1 * r1 + K4 * u_k), x2 + 4.0 * (k2 * r1 - k3 * r2)
    return outputs


def _fit_scipy(u, z):
    import numpy as np
    from scipy.optimize import least_squares

    start = np.array([0.05, 0.05, 0.05, z[0, 0], z[0, 0]])
    fit = least_squares(
        lambda p: _euler_outputs(p, u) - z[:, 0],
        start,
        bounds=([1e-6] * 3 + [0.0] * 2, [np.inf] * 5),
    )
    return float(np.mean(fit.fun**2))


def _fit_jax_sysid(u, z):
    import jax
    import jax.numpy as jnp

    jax.config.update("jax_enable_x64", True)  # its own process; float64 as sk_offwhite's fit
    from jax_sysid.models import Model

    def state_fcn(x, u_k, params):
        k1, k2, k3 = params[0]
        r1, r2 = jnp.sqrt(jnp.maximum(x[0], 1e-6)), jnp.sqrt(jnp.maximum(x[1], 1e-6))
        return jnp.stack([x[0] + 4.0 * (-k1 * r1 + K4 * u_k[0]), x[1] + 4.0 * (k2 * r1 - k3 * r2)])

    model = Model(2, 1, 1, state_fcn=state_fcn, output_fcn=lambda x, u_k, params: x[1:2])
    model.init(params=[jnp.array([0.05, 0.05, 0.05])], x0=jnp.array([z[0, 0], z[0, 0]]))
    # L-BFGS from the start stops after one iteration on this record (its first line search
    # fails); Adam first, as jax-sysid's examples do. 500 epochs is the fewest of 50, 100,
    # 200 and 500 that reach the same optimum as scipy and sk_offwhite (MSE 0.3616).
    model.loss(rho_x0=0.0, rho_th=0.0)
    model.optimization(adam_epochs=500, lbfgs_epochs=200, params_min=[jnp.full(3, 1e-6)])
    model.fit(z, u)
    return float(jnp.mean((model.predict(model.x0, u)[0] - z) ** 2))


CONTENDERS = {"sk_offwhite": _fit_sk, "scipy": _fit_scipy, "jax-sysid": _fit_jax_sysid}


IMPORTS = {
    "sk_offwhite": "sk_offwhite.datasets",
    "scipy": "scipy.optimize",
    "jax-sysid": "jax_sysid.models",
}


def one_process(name: str) -> dict:
    """In this (fresh) process: the contender's import, its first fit + predict (compilation
    included), their sum (*cold*), and the same fit again (*warm*)."""
    import importlib

    start = time.perf_counter()
    importlib.import_module(IMPORTS[name])
    imported = time.perf_counter() - start
    u, z = _tanks_record()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = time.perf_counter()
        CONTENDERS[name](u, z)
        done = time.perf_counter()
        mse = CONTENDERS[name](u, z)
    warm = time.perf_counter() - done
    return {"import": imported, "first_fit": done - first, "cold": imported + done - first,
            "warm": warm, "mse": mse}  # fmt: skip


def _interpreter(name: str, jax_sysid_python: str | None) -> str | None:
    """The Python that runs ``name``: jax-sysid's own environment when given, else this one
    if it can import the contender; ``None`` when none can."""
    if name == "jax-sysid" and jax_sysid_python:
        return jax_sysid_python
    try:
        __import__(IMPORTS[name])
    except ImportError:
        return None
    return sys.executable


def cold_and_warm(rounds: int, jax_sysid_python: str | None = None) -> dict:
    """Fresh-process timings of every available contender, alternated ``rounds`` times."""
    pythons = {n: _interpreter(n, jax_sysid_python) for n in CONTENDERS}
    names = [n for n, python in pythons.items() if python]
    runs = {n: [] for n in names}
    for _ in range(rounds):
        for name in names:
            out = subprocess.run(
                [pythons[name], __file__, "--one", name],
                capture_output=True,
                text=True,
                check=True,
            )
            runs[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
    keys = ("import", "first_fit", "cold", "warm")
    summaries = {n: _summary(r, keys) | {"mse": r[-1]["mse"]} for n, r in runs.items()}
    return summaries | {
        "skipped": [n for n in CONTENDERS if n not in names],
        "versions": {n: "-" if n == "scipy" else _versions(pythons[n]) for n in names},
    }


def _versions(python: str) -> str:
    """``jax x.y.z`` of the interpreter ``python`` (the contenders may run on different JAX)."""
    code = "import importlib.metadata as m; print(m.version('jax'))"
    out = subprocess.run([python, "-c", code], capture_output=True, text=True)
    return f"jax {out.stdout.strip() or 'absent'}"


def _summary(runs: list[dict], keys) -> dict:
    return {
        k: {"min": min(r[k] for r in runs), "median": statistics.median(r[k] for r in runs)}
        for k in keys
    }


def _lm_problem(n_samples: int, library, gamma: float = 1e-3):
    """The solver's data for the tanks cost at ``n_samples`` samples (the measured record
    repeated) and penalty ``gamma``: ``(model, layout, problem, free0)``."""
    import numpy as np
    from bench_scaling import cost_problem  # same folder: run as a script

    from sk_offwhite.datasets import cascaded_tanks_physics

    u, z = _tanks_record()
    repeats = -(-n_samples // len(u))
    u, z = np.tile(u, (repeats, 1))[:n_samples], np.tile(z, (repeats, 1))[:n_samples]
    physics = cascaded_tanks_physics(fixed={"k4": K4})
    return cost_problem(u, z, physics, library, weights=(gamma, 0.0, 0.0, 1.0, 1.0))


def _timed(function, repeats: int) -> list[float]:
    import jax

    jax.block_until_ready(function())
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(function())
        times.append(time.perf_counter() - start)
    return times


def _solver_programs(model, layout, problem, free0) -> dict:
    """Zero-argument calls of the solver's programs with the passes each makes: one
    iteration (a damped step, the candidate's simulation and, when it is accepted, the
    state there, Jacobian included; the current cost is set to ``inf`` or ``-inf`` so that
    the candidate is accepted or rejected), a whole run on the device (``RUN_PASSES`` - 1
    trial steps after the start's evaluation, fewer only if the cost stops decreasing:
    ``tol=0``), and the forward rollout."""
    import jax
    import numpy as np

    from sk_offwhite.solvers._core import free_residuals
    from sk_offwhite.solvers._dense import _lm_advance, _origin, first_state
    from sk_offwhite.solvers._device import levenberg_marquardt_on_device

    static = dict(model=model, layout=layout, forward=True)
    state = first_state(free0, problem, scaling="per-variable", **static)
    forward = jax.jit(free_residuals, static_argnames=("model", "layout"))

    def iteration(current_cost: float):
        origin = (*_origin(state)[:-1], np.array(current_cost))
        return lambda: _lm_advance(origin, 1e-3, state.diag, True, problem, **static)

    def run():
        options = dict(max_iter=RUN_PASSES - 1, tol=0.0)
        return levenberg_marquardt_on_device(free0, problem, model, layout, **options)

    return {
        "LM iteration, accepted": (iteration(np.inf), 1),
        "LM iteration, rejected": (iteration(-np.inf), 1),
        "LM run on the device, per pass": (lambda: run().free, run().n_iter + 1),
        "forward": (lambda: forward(free0, problem, model=model, layout=layout), 1),
    }


RUN_PASSES = 40
"""Passes of the timed device run (its first evaluates the start)."""


def per_step(repeats: int) -> list[dict]:
    """µs per step of a Levenberg-Marquardt iteration, of a pass of a whole run and of a
    forward rollout."""
    import jax
    import pysindy as ps

    rows = []
    with jax.enable_x64(True):
        for n_samples in (1000, 10000):
            for label, library in (("physics", None), ("+ 10 terms", ps.PolynomialLibrary())):
                model, layout, problem, free0 = _lm_problem(n_samples, library)
                programs = _solver_programs(model, layout, problem, free0)
                times = {k: [] for k in programs}
                for _ in range(3):  # interleaved
                    for key, (program, _) in programs.items():
                        times[key] += _timed(program, repeats)
                for key, values in times.items():
                    steps = n_samples * programs[key][1]
                    rows.append(
                        {
                            "samples": n_samples,
                            "model": label,
                            "free": int(free0.shape[0]),
                            "program": key,
                            "us_per_step_min": 1e6 * min(values) / steps,
                            "us_per_step_median": 1e6 * statistics.median(values) / steps,
                        }
                    )
    return rows


WARM_PATHS = 3
"""Paths after the first, the fastest of which is the warm one: the workers are reused, but
which worker gets which fold's layout varies between calls, so the second path with two
jobs may still compile (measured: 14.7, 7.95, 2.61 and 2.07 s in four calls)."""


WARM_FITS = 5
"""Fits at the path's γ after it, the fastest of which is the one fit the path and the grid
are compared with (a single one measured 0.22 and 0.34 s in two runs)."""


def grid_against_one() -> tuple[dict, tuple]:
    """``fit_gamma_path`` over 8 γ (3 folds) against one fit at the γ it chose (the
    estimator is left there; the fastest of `WARM_FITS`), in one process and with the
    folds in two worker processes (``n_jobs=2``; "cold" is their first path, "warm" the
    fastest of the next `WARM_PATHS`); and
    ``GridSearchCV`` over the path's 8 γ (3 folds, one process), warm, with the traces and
    compilations it makes (``jax.monitoring``). Also returns the path counted for its
    solver runs and those runs, ``(path, calls)`` as `_captured_solver_calls` lists
    them, for `batched_against_sequential` and `creeping_runs`."""
    from sklearn.model_selection import KFold

    from sk_offwhite import fit_gamma_path

    est, u, z = _path_estimator()
    out = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for jobs, suffix in ((None, ""), (2, "_2jobs")):
            seconds = []
            for _ in range(1 + WARM_PATHS):
                start = time.perf_counter()
                path = fit_gamma_path(est, u, z, n_gammas=8, cv=KFold(3), n_jobs=jobs)
                seconds.append(time.perf_counter() - start)
            out[f"path{suffix}_cold"], out[f"path{suffix}_warm"] = seconds[0], min(seconds[1:])
        out |= _grid_search(est, path.gammas, u, z)
        out["one_fit_warm"] = min(_timed(lambda: est.fit(u, z), WARM_FITS))
        with _captured_solver_calls() as counted_calls:
            counted = fit_gamma_path(est, u, z, n_gammas=8, cv=KFold(3))
        out |= _iteration_counts("path", counted_calls)
        with _captured_solver_calls() as calls:
            est.fit(u, z)
        out |= _iteration_counts("one_fit", calls)
    for key in ("path_warm", "path_2jobs_warm", "grid_search_warm"):
        out[key.replace("_warm", "_ratio")] = out[key] / out["one_fit_warm"]
    return out, (counted, counted_calls)


def batched_against_sequential(path_calls, repeats: int = 3) -> dict:
    """The support path's 8 γ as one ``vmap``-ped Levenberg-Marquardt run (one program, the
    runs stepping together until the last stops) against the same 8 runs one after the
    other, each from the same start: that of the path's longest penalised run (most
    passes; a run started where every term is zero barely moves them, whatever its γ),
    its γ replaced by each of the path's. Seconds are the fastest of ``repeats`` after a
    first call (compilation excluded); ``max_free_difference`` is the largest difference
    between the two ways' solutions. ``path_calls``: the second value of
    `grid_against_one`."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    path, calls = path_calls
    penalised = [c for c in calls if float(c[0][1].weights.gamma) > 0]
    args, options, _ = max(penalised, key=lambda call: call[2].n_iter)
    with jax.enable_x64(True):
        run_at, start = _device_run(*args, **options)
        gammas = jnp.asarray(path.gammas)
        batched = jax.jit(jax.vmap(run_at, in_axes=(0, None)))

        def in_turn():
            return [jax.device_get(run_at(gamma, start)) for gamma in gammas]

        sequential = _timed(in_turn, repeats)
        together = _timed(lambda: batched(gammas, start), repeats)
        one_by_one, all_at_once = in_turn(), jax.device_get(batched(gammas, start))
    difference = max(
        float(np.max(np.abs(np.asarray(all_at_once.state.free[k]) - run.state.free)))
        for k, run in enumerate(one_by_one)
    )
    return {
        "sequential_s": min(sequential),
        "batched_s": min(together),
        "batched_ratio": min(together) / min(sequential),
        "passes_sequential": [int(run.passes) for run in one_by_one],
        "passes_batched": [int(p) for p in all_at_once.passes],
        "max_free_difference": difference,
    }


CREEP_RUNS, CREEP_MAX_ITER = 3, 2000
"""How many of the path's unpenalised runs that ended at ``max_iter`` are run again, and
how far (`creeping_runs`)."""


def creeping_runs(path_calls) -> dict:
    """The first `CREEP_RUNS` runs of the support path that ended at ``max_iter``
    without a penalty (the refits on a support), run again from their start with
    `CREEP_MAX_ITER` iterations, and by scipy's ``least_squares`` (trust region,
    ``x_scale='jac'``, the package's residuals and forward-mode Jacobian, every tolerance
    1e-15): whether their length belongs to the problem or to this solver.
    ``path_calls``: the second value of `grid_against_one`."""
    import jax

    from sk_offwhite.solvers._device import levenberg_marquardt_on_device

    _, calls = path_calls
    unfinished = [
        c for c in calls
        if float(c[0][1].weights.gamma) == 0 and c[2].message.startswith("max_iter")
    ][:CREEP_RUNS]  # fmt: skip
    rows = []
    with jax.enable_x64(True):
        for (free0, problem, model, layout), options, result in unfinished:
            longer = levenberg_marquardt_on_device(
                free0, problem, model, layout, **(options | {"max_iter": CREEP_MAX_ITER})
            )
            trust = _trust_region(free0, problem, model, layout)
            rows.append({
                "iterations": result.n_iter, "cost": result.cost,
                "longer_iterations": longer.n_iter, "longer_cost": longer.cost,
                "longer_message": longer.message.split(" (")[0],
                "scipy_evaluations": int(trust.nfev), "scipy_cost": 2.0 * float(trust.cost),
            })  # fmt: skip
    return {"runs": rows}


def _trust_region(free0, problem, model, layout):
    """scipy's ``least_squares`` on the package's residuals from ``free0`` (forward-mode
    Jacobian, ``x_scale='jac'``, every tolerance 1e-15, `CREEP_MAX_ITER`
    evaluations at most)."""
    import jax
    import numpy as np
    from scipy.optimize import least_squares

    from sk_offwhite.solvers._core import free_residuals

    residual = jax.jit(partial(free_residuals, problem=problem, model=model, layout=layout))
    jacobian = jax.jit(jax.jacfwd(residual))
    return least_squares(
        lambda free: np.asarray(residual(free)), np.asarray(free0),
        jac=lambda free: np.asarray(jacobian(free)),
        bounds=(np.asarray(problem.lower), np.asarray(problem.upper)),
        x_scale="jac", ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=CREEP_MAX_ITER,
    )  # fmt: skip


def _path_estimator():
    """The Cascaded Tanks' estimator of `grid_against_one` (physics, ``k4`` fixed, and
    the polynomial library) and its estimation record ``(est, u, z)``."""
    import pysindy as ps

    from sk_offwhite import GreyBoxSparseRegressor
    from sk_offwhite.datasets import cascaded_tanks_physics

    u, z = _tanks_record()
    est = GreyBoxSparseRegressor(
        cascaded_tanks_physics(fixed={"k4": K4}), library=ps.PolynomialLibrary(), gamma=1e-2
    )
    return est, u, z


def _device_run(free0, problem, model, layout, *, max_iter, tol, scaling, **_):
    """``(run_at, start)``: the whole device run of
    `levenberg_marquardt_on_device`'s arguments as a function
    of γ and its start carry (`device_run`)."""
    from sk_offwhite.solvers import _device as device

    start, problem, static = device.device_run(free0, problem, model, layout, max_iter, scaling)

    def run_at(gamma, start):
        weighted = problem._replace(weights=problem.weights._replace(gamma=gamma))
        return device._run_on_device(start, weighted, tol, **static)

    return run_at, start


@contextlib.contextmanager
def _captured_solver_calls():
    """The Levenberg-Marquardt runs made in this process inside the block: a list of their
    ``(args, kwargs, SolverResult)``."""
    from sk_offwhite.fitting import _problem

    solver, calls = _problem.levenberg_marquardt_on_device, []

    def captured(*args, **kwargs):
        calls.append((args, kwargs, solver(*args, **kwargs)))
        return calls[-1][2]

    _problem.levenberg_marquardt_on_device = captured
    try:
        yield calls
    finally:
        _problem.levenberg_marquardt_on_device = solver


def _iteration_counts(name: str, calls: list) -> dict:
    """How many solver runs, how many iterations in all, and how many runs ended at
    ``max_iter`` (``calls`` as `_captured_solver_calls` lists them): the work a path
    does against one fit, whatever the compilation."""
    runs = [result for _, _, result in calls]
    return {
        f"{name}_solver_runs": len(runs),
        f"{name}_iterations": sum(run.n_iter for run in runs),
        f"{name}_runs_at_max_iter": sum(run.message.startswith("max_iter") for run in runs),
    }


def _grid_search(est, gammas, u, z) -> dict:
    """``GridSearchCV`` over ``gammas`` (3 contiguous folds), a first time and again (warm),
    the second with its counts of traces, XLA compilations and solver iterations."""
    import collections

    import jax
    from sklearn.model_selection import GridSearchCV, KFold

    search = GridSearchCV(est, {"gamma": list(gammas)}, cv=KFold(3))
    search.fit(u, z)
    events = collections.Counter()

    def count(event, duration, **kwargs):
        events.update({event: 1})

    jax.monitoring.register_event_duration_secs_listener(count)
    with _captured_solver_calls() as calls:
        start = time.perf_counter()
        search.fit(u, z)
        elapsed = time.perf_counter() - start
    jax.monitoring.unregister_event_duration_listener(count)
    return {
        "grid_search_warm": elapsed,
        "grid_search_traces": events["/jax/core/compile/jaxpr_trace_duration"],
        "grid_search_compiles": events["/jax/core/compile/backend_compile_duration"],
        **_iteration_counts("grid_search", calls),
    }


def _rss_mib() -> float:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def memory(n_fits: int = 100) -> dict:
    """RSS after 10 fits and after ``n_fits`` (the growth per fit in between)."""
    u, z = _tanks_record()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(10):
            _fit_sk(u, z)
        early = _rss_mib()
        for _ in range(n_fits - 10):
            _fit_sk(u, z)
    late = _rss_mib()
    return {"rss_after_10_mib": early, "rss_after_100_mib": late,
            "growth_per_fit_mib": (late - early) / (n_fits - 10)}  # fmt: skip


MAIN_JOB = """
import collections, json, resource, sys, time
from jax import monitoring
seconds = collections.Counter()
monitoring.register_event_duration_secs_listener(
    lambda event, duration, **kw: seconds.update({{event: duration}}))
sys.path.insert(0, {examples!r})
import cascaded_tanks_loop
start = time.perf_counter()
cascaded_tanks_loop.main(["--out", {out!r}, "--quiet", "--no-cache", "--n-jobs", "1"]
                         + ([] if {fused!r} else ["--no-fused-loops"]))
print(json.dumps({{"total": time.perf_counter() - start,
       "compile": seconds["/jax/core/compile/backend_compile_duration"],
       "trace": seconds["/jax/core/compile/jaxpr_trace_duration"],
       "lower": seconds["/jax/core/compile/jaxpr_to_mlir_module_duration"],
       "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}))
"""


def main_job(out: Path, fused_loops: bool) -> dict:
    """The README's main job in a fresh process, split by ``jax.monitoring``: in one process
    (``--n-jobs 1``), since the monitoring events of worker processes are not seen here."""
    code = MAIN_JOB.format(
        examples=str(HERE.parent / "examples"), out=str(out / "main_job"), fused=fused_loops
    )
    result = subprocess.run(
        [sys.executable, "-W", "ignore", "-c", code], capture_output=True, text=True, check=True
    )
    timings = json.loads(result.stdout.strip().splitlines()[-1])
    timings["execute_and_python"] = (
        timings["total"] - timings["compile"] - timings["trace"] - timings["lower"]
    )
    return timings


README_COMMAND = """
import json, resource, runpy, sys
from joblib.externals.loky import get_reusable_executor
sys.argv = {argv!r}
runpy.run_path(sys.argv[0], run_name="__main__")
get_reusable_executor().shutdown(wait=True)  # the workers reaped: their RSS counts below
print(json.dumps([resource.getrusage(who).ru_maxrss / 1024
                  for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)]))
"""


def readme_command(out: Path, fused_loops: bool) -> dict:
    """The README's command as a user runs it (two worker processes, the compilation cache
    on), twice in fresh processes with a cache of its own: empty, then filled. Wall time of
    each command, the report's time of the loop and scoring, and the peak RSS of the
    largest process (the command's own or a worker's)."""
    import tempfile

    script = str(HERE.parent / "examples" / "cascaded_tanks_loop.py")
    flags = [] if fused_loops else ["--no-fused-loops"]
    code = README_COMMAND.format(argv=[script, "--out", str(out / "readme_command"), *flags])
    runs = {}
    with tempfile.TemporaryDirectory() as cache:
        environment = os.environ | {"SK_OFFWHITE_CACHE": cache}
        for name in ("cache_empty", "cache_filled"):
            start = time.perf_counter()
            result = subprocess.run(
                [sys.executable, "-W", "ignore", "-c", code],
                capture_output=True, text=True, check=True, env=environment,
            )  # fmt: skip
            lines = result.stdout.strip().splitlines()
            runs[name] = {
                "wall_s": time.perf_counter() - start,
                "loop_and_scoring_s": _report_seconds(lines),
                "peak_rss_mib": max(json.loads(lines[-1])),
            }
    return runs


def _report_seconds(lines: list[str]) -> float:
    """The loop's and scoring's seconds the example prints after its report's path."""
    line = next(text for text in lines if text.startswith("report:"))
    return float(line.rsplit("(", 1)[1].split()[0])


def _markdown(results: dict) -> str:
    loops = "fused (enable_fused_loops)" if results["fused_loops"] else "XLA's default"
    lines = [f"Machine: {results['machine']}; loops on CPU: {loops}", ""]
    lines += ["## Fit, fresh process (s)", ""]
    lines += [
        "| contender | JAX | import | first fit (min / median) | cold (min / median) "
        "| warm (min / median) | simulation MSE |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, row in results["fit"].items():
        if name in ("skipped", "versions"):
            continue
        lines.append(
            f"| {name} | {results['fit']['versions'][name]} | {row['import']['median']:.2f} | "
            f"{row['first_fit']['min']:.3f} / {row['first_fit']['median']:.3f} | "
            f"{row['cold']['min']:.2f} / {row['cold']['median']:.2f} | "
            f"{row['warm']['min']:.3f} / {row['warm']['median']:.3f} | {row['mse']:.6f} |"
        )
    if results["fit"]["skipped"]:
        lines += ["", "Skipped (not installed): " + ", ".join(results["fit"]["skipped"])]
    lines += ["", "## Per simulated step (µs)", ""]
    lines += ["| samples | model | free | program | min | median |", "|---|---|---|---|---|---|"]
    lines += [
        f"| {r['samples']} | {r['model']} | {r['free']} | {r['program']} | "
        f"{r['us_per_step_min']:.3f} | {r['us_per_step_median']:.3f} |"
        for r in results.get("per_step", [])
    ]
    other = ("grid", "batched", "creeping", "memory", "main_job", "readme_command")
    lines += ["", "## Other", "", "```", json.dumps(
        {k: results[k] for k in other if k in results}, indent=2
    ), "```"]  # fmt: skip
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--main-job", action="store_true")
    parser.add_argument("--out", default="reports/benchmarks")
    parser.add_argument(
        "--fused-loops", action="store_true", help="sk_offwhite.enable_fused_loops() first"
    )
    parser.add_argument(
        "--jax-sysid-python",
        help="Python of an environment with jax-sysid installed (it requires jax<=0.4.31, so it "
        "cannot share this package's environment); runs that contender there",
    )
    parser.add_argument("--only-fit", action="store_true", help="only the fresh-process fits")
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    parser.add_argument("--one", choices=sorted(CONTENDERS), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.fused_loops:
        from sk_offwhite import enable_fused_loops

        enable_fused_loops()
    if args.one:
        print(json.dumps(one_process(args.one)))
        return
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {
        "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}",
        "fused_loops": args.fused_loops,
        "fit": cold_and_warm(args.rounds, args.jax_sysid_python),
    }
    if not args.only_fit:
        steps = per_step(args.repeats)
        grid, path_calls = grid_against_one()
        results |= {"per_step": steps, "grid": grid,
                    "batched": batched_against_sequential(path_calls),
                    "creeping": creeping_runs(path_calls), "memory": memory()}  # fmt: skip
    if args.main_job:
        results["main_job"] = main_job(out, args.fused_loops)
        results["readme_command"] = readme_command(out, args.fused_loops)
    results["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    text = _markdown(results)
    print(text)
    (out / "bench_speed.md").write_text(text, encoding="utf-8")
    (out / "bench_speed.json").write_text(json.dumps(results, indent=2), encoding="utf-8")
    from _results import markdown_tables, records_table, write_results  # run as a script

    tables = markdown_tables("Speed", text.split("## Other")[0])
    for key, title in (
        ("grid", "γ path and grid search against one fit"),
        ("batched", "The path's γ batched against the same runs in turn"),
        ("memory", "Memory over repeated fits"),
        ("main_job", "The main job in a fresh process, without the cache"),
        ("readme_command", "The README's command, its cache empty then filled"),
    ):
        if isinstance(results.get(key), dict):
            flat = {k: v for k, v in results[key].items() if not isinstance(v, dict | list)}
            if flat:
                tables.append(records_table(title, [flat]))
    write_results("bench_speed", tables, path=args.json, argv=argv, data=results)


if __name__ == "__main__":
    main()
