"""Accuracy benchmark: every system, sk_offwhite against pysindy baselines, in free run.

Run with ``python benchmarks/run_all.py [--quick] [--out reports/benchmarks]``. For each
system (the measured Cascaded Tanks, the vehicle of Section 5.1, and the synthetic systems
with an undeclared effect) it fits, on the estimation record only:

* sk_offwhite, physics only; physics + sparse δ; after the closed loop
  ([`sk_offwhite.loop.close_the_loop`][sk_offwhite.loop.close_the_loop]), with and without δ. Every
  fit with δ runs the support path ([`sk_offwhite.fit_gamma_path`][sk_offwhite.fit_gamma_path]) over
  the default grid of the dimensionless γ relative to γ_max of the record (5 values, 3 with
  ``--quick``, down to 1e-4 γ_max) and chooses γ by 3-fold CV on the estimation record: no γ is set
  by hand;
* pysindy ``DiscreteSINDy`` on a delay embedding (STLSQ and SR3; for the tanks also the
  physics-informed square-root library), lags and threshold by the same CV;

and scores every model on the validation record by free-run simulation, the first 50
samples used to estimate the initial state (history) and excluded from the score. It
writes ``run_all[_quick].md`` (a Markdown table) and ``.json`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import jax
import numpy as np
import pysindy as ps
import sklearn
from sklearn.base import clone

from sk_offwhite import GreyBoxSparseRegressor, fit_gamma_path
from sk_offwhite.baselines import tune_delay_sindy
from sk_offwhite.datasets import (
    cascaded_tanks_physics,
    load_cascaded_tanks,
    make_cascaded_tanks,
    make_friction_oscillator,
    make_leaky_tank,
    make_saturating_actuator,
    make_vehicle_lateral,
)
from sk_offwhite.diagnose import simulation_metrics
from sk_offwhite.loop import LoopSettings, close_the_loop, fit_continued

INIT_WINDOW = 50
LOOP_MODELS = (
    ("physics only", "baseline"),
    ("physics + δ", "with_delta"),
    ("after loop", "final"),
    ("after loop + δ", "final_with_delta"),
)


@dataclass(frozen=True)
class Case:
    """One system: records, declared physics, dictionary, truth and baselines."""

    name: str
    u: np.ndarray
    z: np.ndarray
    u_val: np.ndarray
    z_val: np.ndarray
    physics: object
    library: object
    truth: dict | None
    baselines: dict = field(default_factory=dict)
    delta_states: tuple[int, ...] | None = None


# ----------------------------------------------------------------------------- systems
def _grid(quick: bool, degree: int = 2, input_lags=(1, 2, 3)) -> dict:
    lags = [1, 2] if quick else [1, 2, 3]
    inputs = list(input_lags[:2]) if quick else list(input_lags)
    return {"n_output_lags": lags, "n_input_lags": inputs, "threshold": [1e-3, 1e-2, 1e-1]}


def _baselines(quick: bool, sqrt: bool, degree: int = 2, input_lags=(1, 2, 3)) -> dict:
    grid = _grid(quick, degree, input_lags)
    specs = {
        "pysindy STLSQ": ("stlsq", False, degree, grid),
        "pysindy SR3": ("sr3", False, degree, grid),
    }
    if sqrt:  # square roots already give the Torricelli terms: let CV try degree 1 too
        specs["pysindy STLSQ + sqrt"] = ("stlsq", True, degree, {**grid, "degree": [1, 2]})
    return specs


def measured_tanks(quick: bool) -> Case:
    """The measured Cascaded Tanks benchmark; eq. (21) with k4 fixed (scale of x1)."""
    d = load_cascaded_tanks()
    physics = cascaded_tanks_physics(fixed={"k4": 0.05})
    return Case("Cascaded Tanks (measured)", d.u_est, d.z_est, d.u_val, d.z_val, physics,
                ps.PolynomialLibrary(degree=2), None, _baselines(quick, True))  # fmt: skip


def synthetic_tanks(quick: bool) -> Case:
    """Synthetic tanks with overflow and saturation; k4 fixed at its true value."""
    d = make_cascaded_tanks(n_samples=600 if quick else 1024, random_state=0)
    physics = cascaded_tanks_physics(fixed={"k4": d.true_parameters["k4"]}, x0=[d.z[0, 0]] * 2)
    return Case("Tanks, overflow + saturation (synthetic)", d.u, d.z, d.u_val, d.z_val,
                physics, d.suggested_library, d.true_parameters,
                _baselines(quick, True))  # fmt: skip


def vehicle(quick: bool) -> Case:
    """Vehicle lateral dynamics of Section 5.1 with the unmodelled Delta."""
    d = make_vehicle_lateral(n_samples=1000 if quick else 2000, random_state=0)
    specs = _baselines(quick, False, degree=3, input_lags=(2, 3))
    return Case("Vehicle lateral (synthetic, §5.1)", d.u, d.z, d.u_val, d.z_val, d.physics,
                d.suggested_library, d.true_parameters, specs, (0,))  # fmt: skip


def synthetic(name: str, maker, quick: bool, n_samples: int) -> Case:
    """A ``make_*`` generator's records, declared physics and suggested library."""
    d = maker(n_samples=n_samples // 2 if quick else n_samples, random_state=0)
    return Case(name, d.u, d.z, d.u_val, d.z_val, d.physics, d.suggested_library,
                d.true_parameters, _baselines(quick, False))  # fmt: skip


def all_cases(quick: bool) -> list:
    """Builders of every benchmarked system (called lazily, one at a time)."""
    return [
        lambda: measured_tanks(quick),
        lambda: vehicle(quick),
        lambda: synthetic_tanks(quick),
        lambda: synthetic("Friction oscillator (synthetic)", make_friction_oscillator, quick, 2000),
        lambda: synthetic("Saturating actuator (synthetic)", make_saturating_actuator, quick, 1000),
        lambda: synthetic("Leaky tank (synthetic)", make_leaky_tank, quick, 1000),
    ]


# ----------------------------------------------------------------------------- scoring
def validation_metrics(est, case: Case) -> dict:
    """Free-run RMSE and fit % on validation after an initial window of 50 samples."""
    run = est.simulate(case.u_val, z_init=case.z_val[:INIT_WINDOW])
    overall = simulation_metrics(case.z_val, run.outputs, skip=INIT_WINDOW)["overall"]
    diverged = bool(getattr(run, "diverged", False)) or not np.all(np.isfinite(run.outputs))
    return {"rmse": overall["rmse"], "fit_percent": overall["fit_percent"], "diverged": diverged}


def parameter_error(est, truth: dict | None) -> float | None:
    """Relative error of the free physical parameters the truth names (None if unknown)."""
    if truth is None or not hasattr(est, "parameters_"):
        return None
    free = [n for n in truth if n in est.parameters_ and not est.physics_.parameters[n].fixed]
    if not free:
        return None
    fitted = np.array([est.parameters_[n] for n in free])
    true = np.array([truth[n] for n in free])
    return float(np.linalg.norm(fitted - true) / np.linalg.norm(true))


def _row(case, model, est, fit_s, select_s, note="") -> dict:
    coef = np.asarray(getattr(est, "coef_", np.zeros(0)))
    return dict(
        system=case.name,
        model=model,
        **validation_metrics(est, case),
        parameter_error=parameter_error(est, case.truth),
        support=int(getattr(est, "n_nonzero_", np.count_nonzero(coef))),
        n_terms=int(coef.size),
        fit_s=fit_s,
        select_s=select_s,
        note=note,
    )


def _timed_refit(est, case: Case) -> float:
    """Seconds for one refit of ``est`` at its chosen hyperparameters (compile cached)."""
    start = time.perf_counter()
    fit_continued(clone(est), case.u, case.z, est.horizon if est.horizon else None)
    return time.perf_counter() - start


def gamma_note(path) -> str:
    """The chosen γ, relative to γ_max, and how it was chosen."""
    if path is None:
        return ""
    relative = path.best_gamma / path.gamma_max
    return f"γ = {relative:.2g} γ_max (γ_max {path.gamma_max:.2g}; {len(path.gammas)}-value CV)"


def run_direct(case: Case, settings: LoopSettings) -> list[dict]:
    """Physics only and physics + δ (support path, γ by CV) without the loop."""
    rows = []
    plain = GreyBoxSparseRegressor(case.physics, max_iter=settings.max_iter)
    start = time.perf_counter()
    plain.fit(case.u, case.z)
    rows.append(_row(case, "sk_offwhite physics only", plain, time.perf_counter() - start, None))
    est = GreyBoxSparseRegressor(
        case.physics, case.library, delta_states=case.delta_states, max_iter=5 * settings.max_iter
    )
    start = time.perf_counter()
    path = fit_gamma_path(
        est,
        case.u,
        case.z,
        n_gammas=settings.n_gammas,
        eps=settings.gamma_eps,
        cv=settings.n_folds,
        init_window=settings.init_window,
    )
    select_s = time.perf_counter() - start
    row = _row(case, "sk_offwhite physics + δ", est, _timed_refit(est, case), select_s)
    rows.append({**row, "note": gamma_note(path)})
    return rows


def run_sk_offwhite(case: Case, settings: LoopSettings) -> list[dict]:
    """The four models of the closed loop, each scored on validation.

    If the loop fails (e.g. a physics that diverges in free run from its guess, as the
    vehicle's), the failure is a row and the plain fits of `run_direct` are reported.
    """
    try:
        return run_loop(case, settings)
    except Exception as error:  # noqa: BLE001 - a benchmark reports failures as rows
        message = f"{type(error).__name__}: {error}"
        failed = dict(system=case.name, model="sk_offwhite closed loop", error=message)
        return [failed, *run_direct(case, settings)]


def run_loop(case: Case, settings: LoopSettings) -> list[dict]:
    """The four models of [`close_the_loop`][sk_offwhite.loop.close_the_loop], each scored on
    validation."""
    settings = replace(settings, delta_states=case.delta_states)
    start = time.perf_counter()
    result = close_the_loop(case.physics, case.library, case.u, case.z, settings=settings)
    loop_s = time.perf_counter() - start
    effects = ", ".join(e.name for e in result.effects) or "none added"
    paths = {"with_delta": result.gamma_path, "final_with_delta": result.final_gamma_path}
    rows = []
    for label, key in LOOP_MODELS:
        est = getattr(result, key)
        notes = [gamma_note(paths[key])] if key in paths else []
        notes += [f"effects: {effects}"] if key.startswith("final") else []
        note = "; ".join(notes)
        rows.append(_row(case, f"sk_offwhite {label}", est, _timed_refit(est, case), loop_s, note))
    return rows


def run_baseline(case: Case, label: str, spec) -> dict:
    """One pysindy baseline tuned by CV on the estimation record, scored on validation."""
    optimizer, sqrt, degree, grid = spec
    start = time.perf_counter()
    search = tune_delay_sindy(
        case.u, case.z, optimizer=optimizer, sqrt_outputs=sqrt, degree=degree, param_grid=grid
    )
    select_s = time.perf_counter() - start
    best = search.best_estimator_
    start = time.perf_counter()
    clone(best).fit(case.u, case.z)
    fit_s = time.perf_counter() - start
    params = search.best_params_
    note = f"lags z {params['n_output_lags']}, u {params['n_input_lags']}, "
    note += f"threshold {params['threshold']:g}, degree {params.get('degree', degree)}"
    return _row(case, label, best, fit_s, select_s, note)


def run_case(case: Case, settings: LoopSettings) -> list[dict]:
    """sk_offwhite and every baseline on one system; a failing model becomes a row."""
    rows = []
    jobs = [("sk_offwhite", lambda: run_sk_offwhite(case, settings))]
    jobs += [(k, lambda k=k, s=s: [run_baseline(case, k, s)]) for k, s in case.baselines.items()]
    for label, job in jobs:
        try:
            rows += job()
        except Exception as error:  # noqa: BLE001 - a benchmark reports failures as rows
            message = f"{type(error).__name__}: {error}"
            rows.append(dict(system=case.name, model=label, error=message))
    return rows


# ----------------------------------------------------------------------------- output
def machine() -> dict:
    """What the numbers were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
        cpu = next(line.split(":", 1)[1].strip() for line in lines if "model name" in line)
    except (OSError, StopIteration):
        pass
    return dict(
        cpu=cpu,
        cores=os.cpu_count(),
        load_average=os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        python=platform.python_version(),
        jax=jax.__version__,
        jax_backend=jax.default_backend(),
        pysindy=ps.__version__,
        sklearn=sklearn.__version__,
    )


def _fmt(value, spec: str) -> str:
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "—"
    return format(value, spec)


def markdown_table(rows: list[dict]) -> str:
    """One line per (system, model)."""
    lines = [
        "| system | model | val RMSE | val fit % | param. error | support | fit (s) "
        "| with selection (s) | notes |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['system']} | {r['model']} | failed | | | | | | {r['error']} |")
            continue
        rmse = _fmt(r["rmse"], ".4f") + (" (diverged)" if r["diverged"] else "")
        support = f"{r['support']}/{r['n_terms']}" if r["n_terms"] else "0"
        lines.append(
            f"| {r['system']} | {r['model']} | {rmse} | {_fmt(r['fit_percent'], '.1f')} "
            f"| {_fmt(r['parameter_error'], '.3f')} | {support} | {_fmt(r['fit_s'], '.1f')} "
            f"| {_fmt(r['select_s'], '.0f')} | {r['note']} |"
        )
    return "\n".join(lines)


def merge_previous(rows: list[dict], path: Path) -> list[dict]:
    """Earlier rows of ``path`` (JSON) for the systems not in ``rows``, then ``rows``."""
    if not path.exists():
        return rows
    done = {r["system"] for r in rows}
    kept = [r for r in json.loads(path.read_text())["rows"] if r["system"] not in done]
    return kept + rows


def write(rows: list[dict], info: dict, out: Path, quick: bool) -> Path:
    """``run_all[_quick].json`` and ``.md`` in ``out``; returns the Markdown path."""
    out.mkdir(parents=True, exist_ok=True)
    stem = out / ("run_all_quick" if quick else "run_all")
    payload = {"machine": info, "mode": "quick" if quick else "full", "rows": rows}
    stem.with_suffix(".json").write_text(json.dumps(payload, indent=2, default=float))
    header = (
        f"Mode: {payload['mode']}. Machine: {info['cpu']}, {info['cores']} cores, "
        f"{info['jax_backend']} (jax {info['jax']}, pysindy {info['pysindy']}); load average "
        f"{info['load_average']:.1f} at start. Validation free run, first {INIT_WINDOW} samples "
        "estimate the initial state and are not scored."
    )
    stem.with_suffix(".md").write_text(header + "\n\n" + markdown_table(rows) + "\n")
    return stem.with_suffix(".md")


def results_tables(rows: list[dict]) -> list:
    """The rows as the documentation's table (``benchmarks/_results.py``)."""
    from _results import table  # same folder: run as a script

    columns = ["system", "model", "val RMSE", "val fit %", "param. error", "support"]
    columns += ["fit (s)", "with selection (s)", "notes"]
    cells = []
    for r in rows:
        if "error" in r:
            cells.append([r["system"], r["model"], "failed", None, None, None, None, None])
            cells[-1].append(r["error"])
            continue
        rmse = r["rmse"] if not r["diverged"] else f"{r['rmse']:.4g} (diverged)"
        support = f"{r['support']}/{r['n_terms']}" if r["n_terms"] else "0"
        cells.append([r["system"], r["model"], rmse, r["fit_percent"], r["parameter_error"]])
        cells[-1] += [support, r["fit_s"], r["select_s"], r["note"]]
    title = f"Validation free run, the first {INIT_WINDOW} samples estimate the initial state"
    return [table(title, columns, cells)]


def loop_settings(quick: bool) -> LoopSettings:
    """Loop settings of the benchmark: the default relative γ grid, chosen by 3-fold CV."""
    if quick:
        return LoopSettings(max_iter=100, max_effects=1, n_gammas=3)
    return LoopSettings(n_folds=3)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter records, smaller grids")
    parser.add_argument("--out", default="reports/benchmarks")
    parser.add_argument("--only", default=None, help="run the systems whose name contains this")
    parser.add_argument("--json", default=None, help="results file (default benchmarks/results)")
    args = parser.parse_args(argv)
    from _results import default_path, write_results  # same folder: run as a script

    name = "run_all_quick" if args.quick else "run_all"
    results_path = Path(args.json) if args.json else default_path(name)
    info, rows = machine(), []
    settings = loop_settings(args.quick)
    for build in all_cases(args.quick):
        case = build()
        if args.only and args.only.lower() not in case.name.lower():
            continue
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rows += run_case(case, settings)
        print(f"{case.name}: {time.perf_counter() - start:.0f} s", flush=True)
        json_path = Path(args.out) / ("run_all_quick.json" if args.quick else "run_all.json")
        merged = merge_previous(rows, json_path) if args.only else rows
        path = write(merged, info, Path(args.out), args.quick)
        if args.only and results_path.exists():
            earlier = json.loads(results_path.read_text())["data"]["rows"]
            done = {r["system"] for r in rows}
            merged = [r for r in earlier if r["system"] not in done] + rows
        tables = results_tables(merged)
        data = {"mode": "quick" if args.quick else "full", "rows": merged}
        write_results(name, tables, path=results_path, argv=argv, data=data)
    print(path.read_text())


if __name__ == "__main__":
    main()
