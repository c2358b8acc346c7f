"""The sparse correction: exact zeros, a scale-free penalty, gamma_max and the support path.

The plant is ``x[k+1] = a x + b u + c x^2`` with the quadratic term undeclared: the physics
is ``a x + b u`` and the dictionary (degree-2 monomials of ``x`` and ``u``) must find
``x^2`` alone; the linear terms duplicate the physics and must stay out.
"""

import copy
import warnings

import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest
from sklearn.base import clone
from sklearn.model_selection import KFold, cross_val_score

from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel, fit_gamma_path, gamma_grid
from sk_offwhite._path import (
    _better_start,
    _choose,
    _cut_at_divergence,
    _fold_errors,
    _folds_together,
    penalised_objective,
)
from sk_offwhite.fitting._sparsity import _no_worse_than, _Stage
from sk_offwhite.loop import held_out_rmse
from sk_offwhite.solvers._core import SolverResult

TRUE = {"a": 0.8, "b": 0.5, "c": -0.15}
N_SAMPLES = 300


def _plant(n: int, seed: int = 0, noise: float = 0.0):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.uniform(0.0, 1.0, n // 10 + 1), 10)[:n, None]
    x, states = 0.0, []
    for u_k in u[:, 0]:
        states.append(x)
        x = TRUE["a"] * x + TRUE["b"] * u_k + TRUE["c"] * x**2
    z = np.asarray(states)[:, None]
    return u, z + noise * rng.standard_normal(z.shape)


def _physics(b_guess: float = 0.3) -> PhysicsModel:
    def step(x, u, theta):
        return jnp.stack([theta["a"] * x[0] + theta["b"] * u[0]])

    return PhysicsModel(
        step, [0], {"a": Parameter(0.5), "b": Parameter(b_guess)}, n_states=1, n_inputs=1
    )


def _estimator(b_guess: float = 0.3, **params) -> GreyBoxSparseRegressor:
    library = ps.PolynomialLibrary(degree=2)
    return GreyBoxSparseRegressor(_physics(b_guess), library, max_iter=200, **params)


def _quiet(fit, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit(*args, **kwargs)


def _terms(est) -> list[str]:
    return [n for n, keep in zip(est.feature_names_, est.support_[0], strict=True) if keep]


@pytest.fixture(scope="module")
def record():
    return _plant(N_SAMPLES)


@pytest.fixture(scope="module")
def fitted(record):
    return _quiet(_estimator(gamma=1e-3).fit, *record)


def test_the_missing_term_alone_with_exact_zeros(fitted):
    assert _terms(fitted) == ["x1^2"]
    assert fitted.n_nonzero_ == 1 and np.count_nonzero(fitted.coef_) == 1
    np.testing.assert_array_equal(fitted.support_, fitted.coef_ != 0)
    assert fitted.coef_[0, fitted.feature_names_.index("x1^2")] == pytest.approx(TRUE["c"], 1e-6)
    assert fitted.parameters_["a"] == pytest.approx(TRUE["a"], 1e-6)


def test_penalty_scales_and_gamma_max_are_reported(fitted):
    assert fitted.penalty_scale_.shape == fitted.coef_.shape
    assert np.all(fitted.penalty_scale_ >= 0) and np.all(np.isfinite(fitted.penalty_scale_))
    assert 0 < fitted.gamma_max_ < np.inf
    np.testing.assert_allclose(fitted.output_scale_, [np.std(_plant(N_SAMPLES)[1])])


def test_no_correction_above_gamma_max(record, fitted):
    above = _quiet(_estimator(gamma=1.5 * fitted.gamma_max_).fit, *record)
    assert above.n_nonzero_ == 0
    below = _quiet(_estimator(gamma=0.1 * fitted.gamma_max_).fit, *record)
    assert below.n_nonzero_ >= 1


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_rescaled_units_give_the_same_model(record, fitted, scale):
    u, z = record
    in_units = _quiet(_estimator(b_guess=0.3 * scale, gamma=1e-3).fit, u, z * scale)
    np.testing.assert_array_equal(in_units.support_, fitted.support_)
    assert in_units.score(u, z * scale) == pytest.approx(fitted.score(u, z), abs=1e-3)
    column = fitted.feature_names_.index("x1^2")
    assert in_units.coef_[0, column] * scale == pytest.approx(fitted.coef_[0, column], rel=1e-4)


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_per_variable_scaling_takes_the_same_solver_steps_in_any_units(record, scale):
    # Marquardt's damping floor in each variable's own units (its largest diag(J^T J) so
    # far): the iterates, not only the optimum, do not depend on the units; with one
    # floor for all variables they do
    u, z = record
    steps = {}
    for rule in ("per-variable", "global"):
        est = _estimator(gamma=1e-3, lm_scaling=rule)
        volts = _quiet(clone(est).fit, u, z).loss_history_
        other = _quiet(clone(est).fit, u * scale, z * scale).loss_history_
        steps[rule] = volts.shape == other.shape and np.allclose(other, volts, rtol=1e-7)
    assert steps == {"per-variable": True, "global": False}


def test_rescaled_dictionary_column_gives_the_same_support(record, fitted):
    library = ps.CustomLibrary(
        library_functions=[lambda x: x, lambda x: 1e3 * x**2],
        function_names=[lambda x: x, lambda x: f"1000 {x}^2"],
    )
    est = _quiet(GreyBoxSparseRegressor(_physics(), library, gamma=1e-3, max_iter=200).fit, *record)
    kept = _terms(est)
    assert kept == ["1000 x1^2"]
    assert est.coef_[est.support_][0] * 1e3 == pytest.approx(TRUE["c"], rel=1e-6)


def test_refit_removes_the_shrinkage(record):
    biased = _quiet(_estimator(gamma=3e-2, refit=False).fit, *record)
    debiased = _quiet(_estimator(gamma=3e-2).fit, *record)
    column = debiased.feature_names_.index("x1^2")
    assert debiased.coef_[0, column] == pytest.approx(TRUE["c"], rel=1e-6)
    assert abs(biased.coef_[0, column]) < abs(debiased.coef_[0, column])


def test_prune_tol_zero_keeps_the_penalised_weights(record):
    est = _quiet(_estimator(gamma=1e-3, prune_tol=0.0, refit=False).fit, *record)
    assert est.n_nonzero_ > 1  # smoothed L1 leaves small weights: pruning is what zeroes them


def test_gamma_grid_is_geometric_from_gamma_max():
    grid = gamma_grid(2.0, n_gammas=5, eps=1e-4)
    np.testing.assert_allclose(grid, 2.0 * np.logspace(0, -4, 5))
    with pytest.raises(ValueError, match="gamma_max must be finite and > 0"):
        gamma_grid(0.0)
    with pytest.raises(ValueError, match="0 < eps < 1"):
        gamma_grid(1.0, eps=2.0)


@pytest.fixture(scope="module")
def path():
    u, z = _plant(N_SAMPLES, seed=1, noise=1e-3)
    return _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=5, cv=3)


def test_path_reports_support_coefficients_and_errors(path):
    n = len(path.gammas)
    assert path.coefs.shape == (n, 1, 6) and path.cv_error.shape == (n, 3)
    assert np.all(np.diff(path.gammas) < 0) and path.gammas[0] == pytest.approx(path.gamma_max)
    assert path.n_nonzero[0] <= 1 and np.all(np.isfinite(path.train_error))
    assert "<- chosen" in path.summary()


def test_path_chooses_the_true_support_by_cv(path):
    assert path.selected() == ["x1: x1^2"]
    est = path.estimator
    assert est.gamma == path.best_gamma and est.warm_start is False
    np.testing.assert_array_equal(est.coef_, path.coefs[path.best_index])


def test_one_standard_error_prefers_a_sparser_model():
    u, z = _plant(N_SAMPLES, seed=1, noise=1e-3)
    sparse = _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=5, cv=3, one_standard_error=True)
    assert sparse.best_gamma >= sparse.gammas[int(np.argmin(sparse.cv_mean))]


def test_path_refuses_shuffled_folds_and_bad_grids(record):
    with pytest.raises(ValueError, match="cv must keep time order"):
        fit_gamma_path(_estimator(), *record, gammas=[1e-3], cv=KFold(3, shuffle=True))
    with pytest.raises(ValueError, match="gammas must be one or more finite values >= 0"):
        fit_gamma_path(_estimator(), *record, gammas=[np.nan])
    with pytest.raises(ValueError, match="needs an estimator with a library"):
        fit_gamma_path(GreyBoxSparseRegressor(_physics()), *record)


def test_a_warm_fit_never_returns_a_larger_and_worse_solution():
    omega_at = np.array([1, 2, 3])
    stage = _Stage(None, None, omega_at, 10, lambda free: float(np.sum(free**2)))
    start = np.array([0.1, 0.0, 0.2, 0.0])  # one term, fit 0.05
    worse = SolverResult(np.array([0.5, 0.1, 0.2, 0.0]), 1.0, np.ones(2), 5, True, "ok")
    kept = _no_worse_than(stage, start, worse)
    np.testing.assert_array_equal(kept.free, start)
    assert not kept.converged and "warm start" in kept.message
    sparser = SolverResult(np.array([0.5, 0.0, 0.0, 0.0]), 1.0, np.ones(2), 5, True, "ok")
    assert _no_worse_than(stage, start, sparser) is sparser  # fewer terms may cost fit
    better = SolverResult(np.array([0.0, 0.1, 0.1, 0.0]), 1.0, np.ones(2), 5, True, "ok")
    assert _no_worse_than(stage, start, better) is better


def test_path_cv_in_output_units_is_what_refitting_the_folds_scores(record):
    # the loop scores a model with delta from the path's own fold fits instead of fitting
    # the folds again at the chosen gamma: the two must be the same number
    u, z = record
    folds = list(KFold(3).split(u))
    path = _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=3, cv=folds, init_window=20)
    refitted = clone(path.estimator).set_params(gamma=path.best_gamma)
    scores = _quiet(
        cross_val_score,
        refitted,
        u,
        z,
        cv=folds,
        scoring=held_out_rmse(20),
        params={"sample_index": np.arange(len(u))},
    )
    assert path.cv_rmse.shape == path.cv_error.shape == (len(path.gammas), 3)
    np.testing.assert_allclose(path.cv_rmse[path.best_index], -scores, rtol=1e-12)


class _FailingFit(GreyBoxSparseRegressor):
    def fit(self, u, z, **params):
        raise ValueError("made to fail")


def test_a_fold_fit_that_fails_scores_inf_with_a_warning(record):
    u, z = record
    est = _FailingFit(_physics(), ps.PolynomialLibrary(degree=2), max_iter=200)
    train, test = np.arange(100, N_SAMPLES), np.arange(100)
    with pytest.warns(UserWarning, match=r"fold's fit at gamma=0.01 failed \(made to fail\)"):
        errors = _fold_errors(est, u, z, train, test, [1e-2, 1e-3], 20, 1e-3)
    assert errors.shape == (2, 2) and np.all(np.isinf(errors))


def test_the_path_ends_where_a_smaller_gamma_no_longer_changes_the_fit():
    # noise 1e-3: once x1^2 is in, the fit error is the noise's and a weaker penalty buys
    # nothing; the path ends there, a prefix of the whole grid's path
    u, z = _plant(N_SAMPLES, seed=1, noise=1e-3)
    full = _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=8, min_improvement=0.0)
    short = _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=8, min_improvement=1e-3)
    n = len(short.gammas)
    assert len(full.gammas) == 8 and 1 < n < 8
    np.testing.assert_array_equal(short.gammas, full.gammas[:n])
    np.testing.assert_allclose(short.coefs, full.coefs[:n], rtol=1e-9, atol=1e-12)
    assert short.selected(n - 1) == ["x1: x1^2"]
    with pytest.raises(ValueError, match="min_improvement"):
        fit_gamma_path(_estimator(), u, z, min_improvement=1.0)


class _Plateau:
    """A stand-in estimator whose fit error stops improving below gamma = 1e-3 and whose
    held-out error is gamma."""

    output_scale_ = np.ones(1)
    n_fits = 0

    def set_params(self, gamma):
        self.gamma = gamma
        return self

    def fit(self, u, z, sample_index=None):
        self.fit_error_, self.n_fits = max(self.gamma, 1e-3), self.n_fits + 1
        return self

    def predict(self, u, z_init=None):
        return np.full((len(u), 1), self.gamma)


def test_a_fold_path_ends_by_the_same_rule_and_keeps_its_last_errors():
    u, z = np.zeros((40, 1)), np.zeros((40, 1))
    est, gammas = _Plateau(), [1e-1, 1e-2, 1e-3, 1e-4, 1e-5]
    errors = _fold_errors(est, u, z, np.arange(20), np.arange(20, 40), gammas, 0, 1e-3)
    np.testing.assert_allclose(errors[:, 0], [1e-1, 1e-2, 1e-3, 1e-3, 1e-3])
    assert est.n_fits == 4  # the fourth fit bought nothing: no fifth


@pytest.mark.parametrize(
    "stop, expected", [(True, 1), (False, 3)], ids=["stop at divergence", "every finite"]
)
def test_the_choice_stops_at_the_first_diverged_gamma(stop, expected):
    cv_error = np.array([[0.5, 0.5], [0.4, 0.4], [np.inf, 0.3], [0.1, 0.1], [np.inf, 0.2]])
    gammas = np.logspace(0, -4, 5)
    assert _choose(cv_error, gammas, False, stop) == expected


def test_a_diverged_first_gamma_leaves_every_finite_one_to_choose_from():
    cv_error = np.array([[np.inf, 0.5], [0.4, 0.4], [0.2, 0.2]])
    assert _choose(cv_error, np.logspace(0, -2, 3), False, True) == 2


class _Unstable(_Plateau):
    """A stand-in whose held-out simulation diverges below gamma = 1e-2."""

    def predict(self, u, z_init=None):
        return np.full((len(u), 1), self.gamma if self.gamma >= 1e-2 else np.nan)


def test_a_fold_fits_nothing_below_its_first_divergence():
    u, z = np.zeros((40, 1)), np.zeros((40, 1))
    est, gammas = _Unstable(), [1e-1, 1e-2, 1e-3, 1e-4, 1e-5]
    with np.errstate(invalid="ignore"):
        errors = _fold_errors(est, u, z, np.arange(20), np.arange(20, 40), gammas, 0, 0.0, True)
    np.testing.assert_allclose(errors[:, 0], [1e-1, 1e-2, np.inf, np.inf, np.inf])
    assert est.n_fits == 3


class _UnstableBelow(_Plateau):
    """A stand-in whose held-out simulation diverges below ``limit``."""

    def __init__(self, limit):
        self.limit = limit

    def predict(self, u, z_init=None):
        return np.full((len(u), 1), self.gamma if self.gamma >= self.limit else np.nan)


def _fold_arguments(estimators, gammas):
    u, z = np.zeros((40, 1)), np.zeros((40, 1))
    train, test = np.arange(20), np.arange(20, 40)
    return [(est, u, z, train, test, gammas, 0, 0.0) for est in estimators]


@pytest.mark.parametrize(
    "limits, fitted, cut",
    [((1e-2, 0.0), (3, 3), 2), ((1.0, 1e-3), (1, 4), None)],
    ids=["one diverges later", "one diverges at the first gamma"],
)
def test_the_folds_stop_together_where_the_choice_stops(limits, fitted, cut):
    gammas = [1e-1, 1e-2, 1e-3, 1e-4, 1e-5]
    together = [_UnstableBelow(limit) for limit in limits]
    apart = [_UnstableBelow(limit) for limit in limits]
    with np.errstate(invalid="ignore"):
        errors = _folds_together(_fold_arguments(together, gammas), True)
        separate = np.stack([_fold_errors(*args, True) for args in _fold_arguments(apart, gammas)])
    assert tuple(est.n_fits for est in together) == fitted
    if cut is not None:  # nothing after the first diverged gamma, in either fold
        assert np.all(np.isinf(errors[:, cut + 1 :])) and np.all(np.isfinite(errors[1, :cut]))
    # folds fitted apart (in worker processes) report the same once cut
    np.testing.assert_array_equal(_cut_at_divergence(separate), errors)
    if cut is not None:
        assert _choose(errors[..., 0].T, np.asarray(gammas), False, True) < cut


def test_the_chosen_fit_is_the_better_of_two_starts(path):
    u, z = _plant(N_SAMPLES, seed=1, noise=1e-3)
    good = path.estimator
    assert path.start in ("continuation", "reference")
    kept, start = _better_start(copy.copy(good), u, z, None)
    assert start == "continuation" and kept.fit_error_ == good.fit_error_
    # a continuation stuck in a worse basin (its objective inflated) gives way to the fit
    # from the physics reference, which reaches the good one's objective
    stuck = copy.copy(good)
    stuck.fit_error_ = 10 * good.fit_error_
    fresh, start = _better_start(stuck, u, z, None)
    assert start == "reference" and fresh is not stuck
    assert penalised_objective(fresh) == pytest.approx(penalised_objective(good), rel=1e-6)
    assert penalised_objective(good) >= good.fit_error_**2
    without_cv = _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=3)
    assert without_cv.start == "continuation"  # nothing scored a fit from the reference
    # asked for, the two starts run without CV too, and never end above the continuation
    restarted = _quiet(fit_gamma_path, _estimator(), u, z, n_gammas=3, restart=True)
    assert restarted.start in ("continuation", "reference")
    assert penalised_objective(restarted.estimator) <= penalised_objective(without_cv.estimator)
