"""fit_gamma_path: continuation in γ equals the fits done by hand, and leaves settings as found."""

import warnings

import numpy as np
import pysindy as ps
import pytest
from conftest import tanks_physics

from sk_offwhite import GreyBoxSparseRegressor, fit_gamma_path

GAMMAS = [1e-1, 1e-4]


def _estimator(**params):
    library = ps.PolynomialLibrary(degree=1)
    return GreyBoxSparseRegressor(tanks_physics(x0=[5.2, 5.2]), library, max_iter=30, **params)


@pytest.fixture(scope="module")
def record(tanks_data):
    u, z, _ = tanks_data
    return u[:300], z[:300]


def _quiet(fit, *args):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit(*args)


def test_path_equals_a_cold_fit_then_warm_refits(record):
    u, z = record
    path = _quiet(fit_gamma_path, _estimator(), u, z, GAMMAS)
    by_hand = _quiet(_estimator(gamma=GAMMAS[0]).fit, u, z)
    _quiet(by_hand.set_params(gamma=GAMMAS[1], warm_start=True).fit, u, z)
    np.testing.assert_array_equal(path.coef_, by_hand.coef_)
    np.testing.assert_array_equal(path.theta_, by_hand.theta_)
    assert path.gamma == GAMMAS[-1] and path.warm_start is False


def test_the_last_gamma_starts_from_the_first_solution(record):
    u, z = record
    path = _quiet(fit_gamma_path, _estimator(), u, z, GAMMAS)
    cold = _quiet(_estimator(gamma=GAMMAS[-1]).fit, u, z)
    assert not np.array_equal(path.coef_, cold.coef_)


@pytest.mark.parametrize("gammas", [[], [1e-2, np.nan], [-1.0], [[np.inf]]])
def test_bad_gammas_are_named(record, gammas):
    u, z = record
    est = _estimator()
    with pytest.raises(ValueError, match="gammas must be one or more finite values >= 0"):
        fit_gamma_path(est, u, z, gammas)
    assert not hasattr(est, "coef_")
