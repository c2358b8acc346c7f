"""pysindy baselines: delay embedding, free run with divergence guard, GridSearchCV."""

import numpy as np
import pysindy as ps
import pytest
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV, KFold

from sk_offwhite.baselines import (
    DelaySINDyRegressor,
    Embedding,
    access_statement,
    embed_record,
    monomials,
    tune_delay_sindy,
)
from sk_offwhite.baselines._embedding import regressor_row

ARX = (0.7, 0.2, 0.5)  # z[k+1] = 0.7 z[k] + 0.2 z[k-1] + 0.5 u[k]


def arx_record(n=400, seed=0):
    """A stable second-order ARX system with a random input, noise-free."""
    u = np.random.default_rng(seed).uniform(-1, 1, (n, 1))
    z = np.zeros((n, 1))
    for k in range(1, n - 1):
        z[k + 1] = ARX[0] * z[k] + ARX[1] * z[k - 1] + ARX[2] * u[k]
    return u, z


def test_monomials_match_pysindy_polynomial_library():
    w = np.random.default_rng(1).normal(size=(30, 4))
    library = ps.PolynomialLibrary(degree=3).fit(w)
    assert np.allclose(monomials(w, library.powers_), library.transform(w))


def test_regressor_row_equals_embedded_row():
    u, z = arx_record(50)
    z = np.abs(z)
    embedding = Embedding(3, 2, True)
    regressors, targets = embed_record(u, z, embedding)
    assert regressors.shape == (47, 3 + 3 + 2) and np.array_equal(targets, z[3:])
    assert np.allclose(regressor_row(u, z, 10, embedding), regressors[10 - 2])


def test_arx_system_recovered_and_simulated_exactly():
    u, z = arx_record()
    est = DelaySINDyRegressor(n_output_lags=2, n_input_lags=1, degree=1, threshold=1e-3)
    est.fit(u, z)
    names = dict(zip(est.feature_names_, est.coef_[0], strict=True))
    assert names["z[k]"] == pytest.approx(0.7) and names["z[k-1]"] == pytest.approx(0.2)
    assert names["u[k]"] == pytest.approx(0.5) and est.support_.sum() == 3
    u_val, z_val = arx_record(seed=1)
    assert est.score(u_val, z_val) == pytest.approx(1.0)
    assert est.predict(u_val, z_init=z_val[:2]).shape == (400, 1)


@pytest.mark.parametrize("optimizer", ["stlsq", "sr3"])
def test_both_optimizers_fit_and_simulate(optimizer):
    u, z = arx_record()
    est = DelaySINDyRegressor(degree=2, optimizer=optimizer, threshold=0.05).fit(u, z[:, 0])
    assert est.predict(u).shape == (400,)
    assert est.score(u, z[:, 0]) > 0.99


def test_diverging_free_run_is_flagged_not_raised():
    u, z = arx_record()
    est = DelaySINDyRegressor(n_output_lags=1, n_input_lags=1, degree=1).fit(u, z)
    est.coef_ = np.zeros_like(est.coef_)
    est.coef_[0, est.feature_names_.index("z[k]")] = 1.5  # unstable
    with pytest.warns(RuntimeWarning, match="diverged"):
        z_sim = est.predict(u, z_init=z[:5] + 1.0)
    assert np.all(np.isfinite(z_sim))
    assert np.all(z_sim <= est.output_box_[1] + 1e-12)
    with pytest.warns(RuntimeWarning, match="-inf"):
        assert est.score(u, z + 1.0) == -np.inf


def test_gaps_in_sample_index_start_new_records():
    u, z = arx_record()
    keep = np.r_[0:150, 250:400]
    est = DelaySINDyRegressor(degree=1, threshold=1e-3)
    est.fit(u[keep], z[keep], sample_index=keep)
    assert est.score(u[keep], z[keep], sample_index=keep) == pytest.approx(1.0)


def test_grid_search_on_free_run_score():
    u, z = arx_record(300)
    search = GridSearchCV(
        DelaySINDyRegressor(degree=1),
        {"n_output_lags": [1, 2], "threshold": [1e-3, 0.3]},
        cv=KFold(2),
    )
    search.fit(u, z, sample_index=np.arange(len(u)))
    assert search.best_params_ == {"n_output_lags": 2, "threshold": 1e-3}
    assert clone(search.best_estimator_).get_params()["n_output_lags"] == 2


def test_tune_delay_sindy_and_access_statement():
    u, z = arx_record(300)
    grid = {"n_output_lags": [2], "n_input_lags": [1], "threshold": [1e-3]}
    search = tune_delay_sindy(u, z, optimizer="sr3", param_grid=grid, n_splits=2)
    assert search.best_score_ > 0.99
    assert "no unmeasured state" in access_statement(search.best_estimator_)


def test_bad_arguments_are_named():
    u, z = arx_record(40)
    est = DelaySINDyRegressor(n_output_lags=3).fit(u, z)
    with pytest.raises(ValueError, match="z_init"):
        est.predict(u, z_init=z[:1])
    with pytest.raises(ValueError, match="n_output_lags"):
        DelaySINDyRegressor(n_output_lags=50).fit(u, z)
    with pytest.raises(ValueError, match="optimizer"):
        DelaySINDyRegressor(optimizer="lasso").fit(u, z)
