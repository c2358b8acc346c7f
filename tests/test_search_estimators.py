"""The closed loop as an estimator (EffectSearchCV) and the CV-chosen sparsity weight
(GreyBoxSparseRegressorCV): scikit-learn citizenship, the same results as the functions they
wrap, and settings refused before any fit."""

import pickle
import time

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV
from sklearn.utils.estimator_checks import parametrize_with_checks

from sk_offwhite import (
    GreyBoxSparseRegressor,
    GreyBoxSparseRegressorCV,
    SequenceSplit,
    expected_failed_checks,
    fit_gamma_path,
)
from sk_offwhite.datasets import make_leaky_tank, make_vehicle_lateral
from sk_offwhite.loop import EffectSearchCV, LoopSettings, close_the_loop

QUICK = dict(cv=2, fit_delta=False, max_candidates=2, max_effects=1)


@parametrize_with_checks(
    [
        GreyBoxSparseRegressorCV(library=None, max_iter=20),
        # programs kept between fits: the checks refit many times on a few data shapes
        EffectSearchCV(
            GreyBoxSparseRegressor(max_iter=5),
            cv=2,
            candidates=[],
            fit_delta=False,
            release_programs=False,
        ),
    ],
    expected_failed_checks=expected_failed_checks,
)
def test_sklearn_compatible_search_estimators(estimator, check):
    check(estimator)


@pytest.fixture(scope="module")
def vehicle():
    return make_vehicle_lateral(n_samples=600, noise_bound=2e-4, random_state=0)


@pytest.fixture(scope="module")
def tank():
    return make_leaky_tank(n_samples=300, random_state=0)


def test_the_cv_estimator_is_the_path_at_its_chosen_gamma(vehicle):
    common = dict(delta_states=[0], max_iter=100)
    cv = GreyBoxSparseRegressorCV(vehicle.physics, vehicle.suggested_library, n_gammas=4, **common)
    cv.fit(vehicle.u, vehicle.z)
    base = GreyBoxSparseRegressor(vehicle.physics, vehicle.suggested_library, **common)
    path = fit_gamma_path(base, vehicle.u, vehicle.z, n_gammas=4, cv=3)
    assert cv.gamma_ == path.best_gamma == cv.gamma
    np.testing.assert_array_equal(cv.coef_, base.coef_)
    results = cv.cv_results_
    assert len(results["gamma"]) == len(results["mean_cv_rmse"]) == len(path.gammas)
    assert np.argmin(results["mean_cv_rmse"]) == path.best_index
    assert cv.score(vehicle.u, vehicle.z) > 0.99
    restored = pickle.loads(pickle.dumps(cv))
    np.testing.assert_array_equal(restored.predict(vehicle.u), cv.predict(vehicle.u))
    assert clone(cv).get_params()["n_gammas"] == 4 and clone(cv).gamma is None


def test_the_cv_estimator_refuses_bad_settings_before_fitting(vehicle):
    for bad in (dict(n_gammas=0), dict(eps=2.0), dict(cv="x"), dict(one_standard_error="yes")):
        est = GreyBoxSparseRegressorCV(vehicle.physics, vehicle.suggested_library, **bad)
        start = time.perf_counter()
        with pytest.raises((ValueError, TypeError), match=next(iter(bad))):
            est.fit(vehicle.u, vehicle.z)
        assert time.perf_counter() - start < 5.0  # no fit was started


def test_effect_search_is_close_the_loop(tank):
    settings = LoopSettings(n_folds=2, fit_delta=False, max_candidates=2, max_effects=1)
    result = close_the_loop(tank.physics, tank.suggested_library, tank.u, tank.z, settings=settings)
    estimator = GreyBoxSparseRegressor(
        tank.physics, tank.suggested_library, horizon=128, max_iter=300, init_window=50
    )
    search = EffectSearchCV(estimator, **QUICK).fit(tank.u, tank.z)
    assert search.effects_ == result.effects and search.chosen_ == result.chosen
    assert search.cv_errors_ == result.cv_errors
    assert search.best_estimator_ is search.result_.best
    np.testing.assert_array_equal(search.predict(tank.u), result.best.predict(tank.u))
    table = search.cv_results_
    assert table["model"][0] == "declared physics" and len(set(map(len, table.values()))) == 1
    restored = pickle.loads(pickle.dumps(search))
    np.testing.assert_array_equal(restored.predict(tank.u_val), search.predict(tank.u_val))
    assert clone(search).get_params()["cv"] == 2


def test_a_grid_search_over_sequence_folds_clones_and_pickles(tank):
    grid = GridSearchCV(
        GreyBoxSparseRegressor(tank.physics, max_iter=30), {"max_iter": [10, 30]},
        cv=SequenceSplit(3),
    ).fit(tank.u, tank.z)  # fmt: skip
    assert grid.best_params_["max_iter"] in (10, 30)
    restored = pickle.loads(pickle.dumps(clone(grid).fit(tank.u, tank.z)))
    np.testing.assert_allclose(restored.predict(tank.u), grid.predict(tank.u))


@pytest.mark.parametrize(
    "bad",
    [
        dict(cv=1),
        dict(cv="tail"),
        dict(max_effects=-1),
        dict(beam=0),
        dict(min_gain=float("nan")),
        dict(n_gammas=0),
        dict(gamma_eps=-1.0),
        dict(cv_horizon=0),
        dict(n_jobs="many"),
        dict(candidates="poly"),
        dict(fit_delta="yes"),
    ],
    ids=lambda bad: next(iter(bad)),
)
def test_every_wrong_setting_of_the_search_is_refused_at_once(tank, bad):
    search = EffectSearchCV(GreyBoxSparseRegressor(tank.physics), **bad)
    start = time.perf_counter()
    with pytest.raises((ValueError, TypeError), match=next(iter(bad))):
        search.fit(tank.u, tank.z)
    assert time.perf_counter() - start < 1.0


@pytest.mark.parametrize(
    "call",
    [
        lambda t: close_the_loop(t.physics, "poly", t.u, t.z),
        lambda t: close_the_loop(None, t.suggested_library, t.u, t.z),
        lambda t: close_the_loop(t.physics, None, t.u, t.z, settings={"n_folds": 2}),
        lambda t: close_the_loop(t.physics, None, [t.u, t.u], [t.z, t.z]),
    ],
    ids=["library", "physics", "settings", "records"],
)
def test_close_the_loop_refuses_wrong_arguments_at_once(tank, call):
    start = time.perf_counter()
    with pytest.raises((ValueError, TypeError)) as caught:
        call(tank)
    assert time.perf_counter() - start < 1.0
    assert any(word in str(caught.value) for word in ("library", "physics", "settings", "record"))
