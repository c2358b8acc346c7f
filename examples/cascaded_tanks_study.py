"""Cascaded Tanks benchmark: physics, sparse corrections and explicit effects, measured.

Fits four kinds of model on the estimation record of the measured Cascaded Tanks benchmark
(Schoukens, Mattsson, Wigren, Noel 2016) and scores them on the validation record:

1. the physics of eq. (21) of Donati et al. alone;
2. eq. (21) plus a sparse black-box correction ``delta`` (two pysindy libraries), with the
   L1 weight ``gamma`` chosen by cross-validation on the estimation record;
3. eq. (21) augmented with explicit physical effects (upper-tank overflow, lower-tank and
   sensor limits, sensor offset, outlet law), the set of effects chosen by cross-validation
   on the estimation record;
4. the chosen augmented physics plus ``delta``, ``gamma`` again chosen by cross-validation.

Every choice (effects, library, ``gamma``) uses the estimation record only: ``KFold`` blocks
of it are held out, each held-out block has its initial state estimated from its first 50
samples and is scored by its simulation RMSE on the rest. The validation record is only
scored, under both protocols of ``load_cascaded_tanks().protocols``: "original" (simulate
all 1024 samples from the initial state fitted on the estimation record, which the benchmark
states is the same for both records) and "nonlinear_benchmarks" (the first 50 validation
samples estimate the state; RMSE over samples 50..1023).

Run ``python examples/cascaded_tanks_study.py`` (a few minutes on two CPU cores); the
options (``--folds``, ``--max-iter``, ``--gammas``) are listed by ``--help``.
"""

from __future__ import annotations

import argparse
import time
import warnings
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import GridSearchCV, KFold, cross_val_score

from sk_offwhite import GreyBoxSparseRegressor, compile_basis
from sk_offwhite.datasets import cascaded_tanks_physics, load_cascaded_tanks
from sk_offwhite.datasets._tanks_effects import tanks_effects_physics

K4 = 0.04
"""Fixed pump gain: with only ``x2`` measured it sets the (otherwise free) scale of ``x1``."""

INIT_WINDOW = 50
"""Samples used to estimate the initial state of a held-out block / the validation record."""

GAMMAS = (1e-2, 1e-1, 1.0)
"""Default grid of the L1 weight ``gamma`` of the correction."""

DIVERGED_RMSE = 10.0
"""RMSE (V, the sensor range) charged to a held-out block whose simulation is not finite."""

STRUCTURES = {
    "eq21": (),
    "overflow+sensor": ("overflow", "sensor_limit"),
    "+tank_limit": ("overflow", "sensor_limit", "tank_limit"),
    "+offset": ("overflow", "sensor_limit", "tank_limit", "offset"),
    "+outlet_exponent": ("overflow", "sensor_limit", "tank_limit", "offset", "outlet_exponent"),
}
"""Nested candidate sets of effects for the augmented physics, from eq. (21) upwards."""


# --------------------------------------------------------------------------------------
# Correction libraries
# --------------------------------------------------------------------------------------


def hinge(a):
    """Smooth ``max(a - 9.75, 0)`` near the tank top: ``softplus(8 (a - 9.75)) / 8``."""
    return jax.nn.softplus(8.0 * (a - 9.75)) / 8.0


def hinge_times(a, b):
    """``hinge(a) * b``."""
    return hinge(a) * b


def hinge_times_square(a, b):
    """``hinge(a) * b^2``."""
    return hinge(a) * b * b


def _name_hinge(a):
    return f"hinge({a})"


def _name_hinge_times(a, b):
    return f"hinge({a}) {b}"


def _name_hinge_times_square(a, b):
    return f"hinge({a}) {b}^2"


def tank_hinge_library():
    """Degree-2 polynomials plus smooth hinges at the tank top times ``1, b, b^2`` on
    ``[x1, x2, u]`` (19 features), the features of ``_tanks_library`` of the synthetic
    tanks data set.

    Written with plain module-level functions (also for the names) so that the clones
    made by the cross-validation describe the same library and share one compiled model.
    """
    functions = [hinge, hinge_times, hinge_times_square]
    names = [_name_hinge, _name_hinge_times, _name_hinge_times_square]
    return ps.PolynomialLibrary(degree=2) + ps.CustomLibrary(functions, names)


LIBRARIES = {
    "poly2": lambda: ps.PolynomialLibrary(degree=2),
    "tank_hinge": tank_hinge_library,
}
"""Correction libraries compared (factories, evaluated on ``[x1, x2, u]``)."""

AUGMENTED_LIBRARIES = ("poly2",)
"""Libraries tried on top of the augmented physics (``--all-libraries``: all of them)."""

DELTA_OPTIONS = (None, (1,))
"""Corrected equations searched on top of the augmented physics: both, or ``x2`` only."""


# --------------------------------------------------------------------------------------
# Scores
# --------------------------------------------------------------------------------------


def rmse(simulated, measured) -> float:
    """Root mean square of ``simulated - measured`` (V)."""
    error = np.ravel(simulated) - np.ravel(measured)
    with np.errstate(over="ignore", invalid="ignore"):
        return float(np.sqrt(np.mean(error**2)))


def fit_percent(simulated, measured) -> float:
    """``100 (1 - ||e|| / ||z - mean z||)`` over the given samples."""
    measured = np.ravel(measured)
    error = np.ravel(simulated) - measured
    return float(100.0 * (1.0 - np.linalg.norm(error) / np.linalg.norm(measured - measured.mean())))


def held_out_score(estimator, u, z) -> float:
    """CV scorer: minus the simulation RMSE of a held-out block after its first
    ``INIT_WINDOW`` samples, which estimate its initial state (``DIVERGED_RMSE`` when the
    simulation is not finite)."""
    z_sim = estimator.predict(u, z_init=z[:INIT_WINDOW])
    error = rmse(np.asarray(z_sim)[INIT_WINDOW:], np.asarray(z)[INIT_WINDOW:])
    return -error if np.isfinite(error) else -DIVERGED_RMSE


def benchmark_scores(estimator, data) -> dict:
    """Estimation RMSE and validation RMSE / fit % under both protocols."""
    z_est = estimator.predict(data.u_est)
    z_orig = estimator.predict(data.u_val)
    z_nb = estimator.predict(data.u_val, z_init=data.z_val[:INIT_WINDOW])
    tail = slice(INIT_WINDOW, None)
    return {
        "est_rmse": rmse(z_est, data.z_est),
        "orig_rmse": rmse(z_orig, data.z_val),
        "orig_fit": fit_percent(z_orig, data.z_val),
        "nb_rmse": rmse(z_nb[tail], data.z_val[tail]),
        "nb_fit": fit_percent(z_nb[tail], data.z_val[tail]),
    }


# --------------------------------------------------------------------------------------
# Fitting
# --------------------------------------------------------------------------------------


@dataclass
class Result:
    """One row of the study: a fitted estimator, its scores and how it was chosen."""

    name: str
    estimator: GreyBoxSparseRegressor
    fit_seconds: float
    cv_rmse: float = float("nan")
    cv_seconds: float = 0.0
    gamma: float | None = None
    cv_table: dict = field(default_factory=dict)
    scores: dict = field(default_factory=dict)


def base_estimator(physics, max_iter, library=None, gamma=0.1) -> GreyBoxSparseRegressor:
    """The estimator used throughout (simulation error, Levenberg-Marquardt)."""
    return GreyBoxSparseRegressor(physics, library=library, gamma=gamma, max_iter=max_iter)


def timed_fit(estimator, data):
    """Fit on the whole estimation record; return the estimator and the seconds taken."""
    start = time.perf_counter()
    estimator.fit(data.u_est, data.z_est)
    return estimator, time.perf_counter() - start


def cv_splitter(folds: int) -> KFold:
    """Contiguous blocks of the estimation record (no shuffling: rows are time samples)."""
    return KFold(n_splits=folds, shuffle=False)


def cross_validated_rmse(estimator, data, folds: int) -> tuple[float, float]:
    """Mean held-out RMSE over the folds of the estimation record, and the seconds taken."""
    start = time.perf_counter()
    scores = cross_val_score(
        estimator,
        data.u_est,
        data.z_est,
        cv=cv_splitter(folds),
        scoring=held_out_score,
        params={"sample_index": np.arange(len(data.u_est))},
    )
    return float(-np.mean(scores)), time.perf_counter() - start


def gamma_search(estimator, data, args, delta_options=(None,)):
    """``GridSearchCV`` over ``gamma`` (and the corrected equations ``delta_states``) on
    the estimation record, refitted on all of it; returns the search, its seconds and the
    mean held-out RMSE of every candidate."""
    grid = {"gamma": list(args.gammas), "delta_states": list(delta_options)}
    search = GridSearchCV(estimator, grid, cv=cv_splitter(args.folds), scoring=held_out_score)
    start = time.perf_counter()
    search.fit(data.u_est, data.z_est, sample_index=np.arange(len(data.u_est)))
    seconds = time.perf_counter() - start
    table = {
        _candidate_label(params): -score
        for params, score in zip(
            search.cv_results_["params"], search.cv_results_["mean_test_score"], strict=True
        )
    }
    return search, seconds, table


def _candidate_label(params) -> str:
    """``gamma=..`` plus the corrected equations when they are not all of them."""
    label = f"gamma={params['gamma']:g}"
    states = params.get("delta_states")
    return label if states is None else label + " on " + "+".join(f"x{i + 1}" for i in states)


def physics_only(data, args) -> Result:
    """Eq. (21) alone (``k4`` fixed), initial values of the paper (0.05, ``[z0, z0]``)."""
    estimator = base_estimator(cascaded_tanks_physics(fixed={"k4": K4}), args.max_iter)
    cv_rmse, cv_seconds = cross_validated_rmse(estimator, data, args.folds)
    estimator, seconds = timed_fit(estimator, data)
    return Result("physics eq. (21)", estimator, seconds, cv_rmse, cv_seconds)


def with_correction(name, physics, library_name, data, args, delta_options=(None,)):
    """``physics`` plus a ``delta`` from ``LIBRARIES[library_name]``; ``gamma`` (and the
    corrected equations, among ``delta_options``) by CV on the estimation record."""
    estimator = base_estimator(physics, args.max_iter, LIBRARIES[library_name]())
    search, cv_seconds, table = gamma_search(estimator, data, args, delta_options)
    return Result(
        f"{name} + delta[{library_name}]",
        search.best_estimator_,
        search.refit_time_,
        cv_rmse=-search.best_score_,
        cv_seconds=cv_seconds,
        gamma=search.best_params_["gamma"],
        cv_table=table,
    )


def augmented_physics(effects, init=None):
    """Eq. (21) with the given effects (``k4`` fixed), default initial values."""
    return tanks_effects_physics(effects, init=init, fixed={"k4": K4})


def select_structure(data, args) -> tuple[str, dict, float]:
    """Cross-validated RMSE of every candidate set of effects; the best name."""
    table, seconds = {}, 0.0
    for name, effects in STRUCTURES.items():
        estimator = base_estimator(augmented_physics(effects), args.max_iter)
        table[name], spent = cross_validated_rmse(estimator, data, args.folds)
        seconds += spent
    return min(table, key=table.get), table, seconds


def augmented(data, args) -> Result:
    """The augmented physics whose effects have the smallest CV RMSE, fitted on all data."""
    best, table, cv_seconds = select_structure(data, args)
    estimator, seconds = timed_fit(
        base_estimator(augmented_physics(STRUCTURES[best]), args.max_iter), data
    )
    return Result(
        f"augmented physics [{best}]",
        estimator,
        seconds,
        cv_rmse=table[best],
        cv_seconds=cv_seconds,
        cv_table=table,
    )


# --------------------------------------------------------------------------------------
# Reading the correction
# --------------------------------------------------------------------------------------


def simulated_states(estimator, u, x0) -> np.ndarray:
    """States ``x_k`` of the fitted model (physics + correction) simulated from ``x0``."""
    physics = estimator.physics_
    theta = {k: jnp.asarray(v) for k, v in estimator.parameters_.items()}
    basis, omega, rows = None, None, None
    if estimator.coef_.size:
        features = list(physics.state_names) + list(physics.input_names)
        basis = compile_basis(estimator.library, features, len(estimator.delta_states_))
        omega, rows = jnp.asarray(estimator.coef_), jnp.asarray(estimator.delta_states_)
    inner = {k: jnp.asarray(v) for k, v in estimator.inner_params_.items()}

    def advance(x, u_k):
        x_next = physics.step(x, u_k, theta)
        if basis is not None:
            phi = basis.evaluate(inner, jnp.concatenate([x, u_k]))
            x_next = x_next.at[rows].add(jnp.sum(omega * phi, axis=1))
        return x_next, x

    with jax.enable_x64(True):
        _, states = jax.lax.scan(advance, jnp.asarray(x0, float), jnp.asarray(u, float))
        return np.asarray(states)


def term_contributions(estimator, data, top: int = 5) -> list[tuple[str, str, float, float]]:
    """Largest correction terms ``(equation, term, rms, mean)`` along the estimation
    simulation, the equation's whole correction first (term ``"delta (all terms)"``).

    ``rms`` and ``mean`` are the root mean square and the mean over the record of
    ``Omega_ij phi_j(x_k, u_k)``, the change the term makes to the next state per sample
    (V per sample for ``x2``).
    """
    if not estimator.coef_.size:
        return []
    physics = estimator.physics_
    states = simulated_states(estimator, data.u_est, estimator.x0_)
    features = list(physics.state_names) + list(physics.input_names)
    basis = compile_basis(estimator.library, features, len(estimator.delta_states_))
    inner = {k: jnp.asarray(v) for k, v in estimator.inner_params_.items()}
    with jax.enable_x64(True):
        rows = jnp.concatenate([jnp.asarray(states), jnp.asarray(data.u_est, float)], axis=1)
        phi = np.asarray(jax.vmap(lambda v: basis.evaluate(inner, v))(rows))
    parts = phi * estimator.coef_[None]
    terms, means = np.sqrt(np.mean(parts**2, axis=0)), np.mean(parts, axis=0)
    ranked = []
    for i, state in enumerate(estimator.delta_states_):
        name, total = physics.state_names[state], parts[:, i].sum(axis=1)
        ranked.append((name, "delta (all terms)", _rms(total), float(total.mean())))
        for j in np.argsort(terms[i])[::-1][:top]:
            if estimator.support_[i, j]:
                ranked.append((name, basis.names[j], float(terms[i, j]), float(means[i, j])))
    return ranked


def _rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def overflow_share(parameters) -> float | None:
    """Share of the upper-tank overflow that reaches the lower tank.

    The upper outlet moves ``k2 / k1`` lower-tank volts per unit of ``x1``; the overflow
    moves ``k_overflow`` of them, so the share is ``k_overflow k1 / k2``.
    """
    if "k_overflow" not in parameters:
        return None
    return parameters["k_overflow"] * parameters["k1"] / parameters["k2"]


# --------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------


def print_table(results) -> None:
    """The table of results (RMSE in V, fit in %)."""
    header = (
        f"{'model':44s} {'gamma':>6s} {'CV':>6s} {'est':>6s} | {'orig':>6s} {'fit%':>6s} | "
        f"{'nb50':>6s} {'fit%':>6s} | {'fit s':>6s} {'CV s':>6s}"
    )
    print(header)
    print("-" * len(header))
    for r in results:
        s = r.scores
        gamma = "-" if r.gamma is None else f"{r.gamma:g}"
        print(
            f"{r.name:44s} {gamma:>6s} {r.cv_rmse:6.3f} {s['est_rmse']:6.3f} | "
            f"{s['orig_rmse']:6.3f} {s['orig_fit']:6.2f} | {s['nb_rmse']:6.3f} {s['nb_fit']:6.2f}"
            f" | {r.fit_seconds:6.1f} {r.cv_seconds:6.1f}"
        )


def print_details(result, data) -> None:
    """Parameters, initial state, CV table and the largest correction terms of a row."""
    est = result.estimator
    print(f"\n== {result.name}")
    params = ", ".join(f"{k}={v:.4g}" for k, v in est.parameters_.items())
    print(f"   parameters: {params}")
    print(f"   x0 = [{est.x0_[0]:.4g}, {est.x0_[1]:.4g}]   LM iterations: {est.n_iter_}")
    share = overflow_share(est.parameters_)
    if share is not None:
        print(f"   share of the upper-tank overflow reaching the lower tank: {share:.2f}")
    if result.cv_table:
        cells = ", ".join(f"{k}: {v:.3f}" for k, v in result.cv_table.items())
        print(f"   CV RMSE (V): {cells}")
    if est.coef_.size:
        names = [est.physics_.state_names[i] for i in est.delta_states_]
        active = ", ".join(
            f"{name}: {int(n)}" for name, n in zip(names, est.support_.sum(axis=1), strict=True)
        )
        print(f"   active terms (|Omega| > threshold) of {est.coef_.shape[1]}: {active}")
        for state, term, size, mean in term_contributions(est, data):
            print(f"   {state}: {term:18s} rms {size:.4f}  mean {mean:+.4f}  (per sample)")


def parse_arguments(argv=None):
    """Command-line options."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folds", type=int, default=4, help="KFold blocks (default 4)")
    parser.add_argument("--max-iter", type=int, default=150, help="LM iterations per fit")
    parser.add_argument(
        "--gammas", type=float, nargs="+", default=list(GAMMAS), help="grid of gamma"
    )
    parser.add_argument(
        "--all-libraries",
        action="store_true",
        help="also try every library on top of the augmented physics (slower)",
    )
    return parser.parse_args(argv)


def run_study(args) -> tuple[list[Result], object]:
    """Fit every model of the study and score it; return the results and the data."""
    data = load_cascaded_tanks()
    results = [physics_only(data, args)]
    for library in LIBRARIES:
        physics = cascaded_tanks_physics(fixed={"k4": K4})
        results.append(with_correction("physics eq. (21)", physics, library, data, args))
    chosen = augmented(data, args)
    results.append(chosen)
    effects = tuple(chosen.estimator.physics_.step.effects)
    libraries = LIBRARIES if args.all_libraries else AUGMENTED_LIBRARIES
    for library in libraries:
        physics = augmented_physics(effects)
        results.append(with_correction("augmented", physics, library, data, args, DELTA_OPTIONS))
    for result in results:
        result.scores = benchmark_scores(result.estimator, data)
    return results, data


def main(argv=None) -> None:
    """Run the study and print the table and the details."""
    args = parse_arguments(argv)
    warnings.filterwarnings("ignore", category=ConvergenceWarning)
    start = time.perf_counter()
    results, data = run_study(args)
    print("Cascaded Tanks: RMSE (V) on the estimation record (est), held-out blocks of it (CV),")
    print("and the validation record: 'orig' = simulated from the fitted x0 over all 1024")
    print("samples, 'nb50' = state estimated from z_val[:50], scored on samples 50..1023.\n")
    print_table(results)
    for result in results:
        print_details(result, data)
    print(f"\nfolds={args.folds}, max_iter={args.max_iter}, gammas={args.gammas}, k4={K4}")
    print(f"total time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
