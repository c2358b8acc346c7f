"""Entry points check what they are given before any fit, naming the argument at fault."""

import warnings

import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest
from conftest import TANKS_TRUE, tanks_physics, tanks_step

from sk_offwhite import (
    GreyBoxSparseRegressor,
    GreyBoxSparseRegressorCV,
    Parameter,
    PhysicsModel,
    fit_gamma_path,
)
from sk_offwhite.loop import EffectSearchCV, score_models


@pytest.fixture
def data(tanks_data):
    u, z, _ = tanks_data
    return u[:200].copy(), z[:200].copy()


def _physics(step, **kwargs):
    parameters = {k: Parameter(v) for k, v in TANKS_TRUE.items()}
    return PhysicsModel(step, [1], parameters, 2, 1, x0=[5.0, 5.0], **kwargs)


def _fit(u, z, physics=None, **params):
    return GreyBoxSparseRegressor(physics or tanks_physics(), max_iter=5, **params).fit(u, z)


@pytest.mark.parametrize(
    ("step", "message"),
    [
        (lambda x, u, theta: 1.0, "physics.step returned a float, not an array"),
        (lambda x, u, theta: {"x": x}, "physics.step returned a dict, not an array"),
        (lambda x, u, theta: x > 0, "physics.step returned an array of dtype bool"),
        (lambda x, u, theta: x * (1 + 1j), "physics.step returned an array of dtype complex"),
    ],
)
def test_a_step_must_return_real_floats(data, step, message):
    with pytest.raises(TypeError, match=message):
        _fit(*data, physics=_physics(step))


def test_an_inequality_not_finite_at_the_guess_is_named(data):
    physics = _physics(tanks_step, inequality=lambda x, u, theta: jnp.log(theta["k1"] - 1.0)[None])
    with pytest.raises(ValueError, match="physics.inequality returned non-finite values"):
        _fit(*data, physics=physics)


@pytest.mark.parametrize("argument", ["u", "z"])
def test_values_whose_squares_overflow_are_refused(data, argument):
    u, z = data
    arrays = {"u": u, "z": z}
    arrays[argument] = arrays[argument] * 1e200
    with pytest.raises(ValueError, match=f"{argument} holds values up to .*rescale {argument}"):
        _fit(arrays["u"], arrays["z"])


def test_too_few_samples_for_the_unknowns_names_z(data):
    u, z = data
    with pytest.raises(ValueError, match=r"z: 4 samples give 4 output values for 5 unknowns"):
        _fit(u[:4], z[:4])


@pytest.mark.parametrize(("column", "name"), [("z", "z"), ("u", "u")])
def test_a_constant_column_warns(data, column, name):
    u, z = data
    arrays = {"u": u, "z": z}
    arrays[column] = np.full_like(arrays[column], 3.0)
    with pytest.warns(UserWarning, match=f"{name} is constant over the records"):
        _fit(arrays["u"], arrays["z"])


def test_a_list_of_one_dimensional_records_is_refused(data):
    u, z = data
    with pytest.raises(ValueError, match=r"u: a list of records must hold 2-D arrays"):
        _fit([u[:100, 0], u[100:, 0]], [z[:100], z[100:]])


def test_parameter_settings_are_checked():
    with pytest.raises(TypeError, match="fixed"):
        Parameter(1.0, fixed="yes")
    assert Parameter(1.0, fixed=np.bool_(True)).fixed
    with pytest.raises(TypeError, match="parameters must be"):
        PhysicsModel(tanks_step, [1], [("k1", Parameter(1.0))], 2, 1)
    with pytest.raises(ValueError, match=r"parameters\['k1'\] must be finite"):
        PhysicsModel(tanks_step, [1], {"k1": np.nan}, 2, 1)


def test_an_init_window_longer_than_the_record_is_refused_at_fit(data):
    with pytest.raises(ValueError, match="init_window=300 leaves fewer than 2 samples"):
        _fit(*data, init_window=300)


def test_score_checks_its_outputs_and_window(data):
    u, z = data
    est = _fit(u, z, init_window=10)
    with pytest.raises(ValueError, match=r"z has 2 output column\(s\), the model was fitted on 1"):
        est.score(u, np.hstack([z, z]))
    with pytest.raises(ValueError, match="score needs at least 2 samples after each record"):
        est.score(u[:11], z[:11])


def test_fit_gamma_path_checks_its_data(data):
    u, z = data
    library = ps.PolynomialLibrary(degree=2)
    est = GreyBoxSparseRegressor(tanks_physics(), library=library, max_iter=5)
    with pytest.raises(ValueError, match="not lists of records"):
        fit_gamma_path(est, [u[:100], u[100:]], [z[:100], z[100:]], gammas=[1e-3])
    with pytest.raises(ValueError, match=r"z .*(NaN|infinity)"):
        fit_gamma_path(est, u, np.full_like(z, np.nan), gammas=[1e-3])
    windowed = GreyBoxSparseRegressor(tanks_physics(), library=library, init_window=90)
    with pytest.raises(ValueError, match="init_window=90 leaves fewer than 2 samples"):
        fit_gamma_path(windowed, u, z, gammas=[1e-3], cv=3)


def test_the_cv_estimator_refuses_a_boolean_horizon(data):
    cv = GreyBoxSparseRegressorCV(tanks_physics(), gammas=[1e-3], horizon=True, max_iter=5)
    with pytest.raises((TypeError, ValueError), match="horizon"):
        cv.fit(*data)


def test_score_models_checks_its_records(data):
    with pytest.raises(TypeError, match="result must be the LoopResult"):
        score_models(object(), {"estimation": data})
    with pytest.raises(TypeError, match="records must be a non-empty dict"):
        score_models(object(), [data])
    with pytest.raises(ValueError, match=r"records\['estimation'\] must be a \(u, z\) pair"):
        score_models(object(), {"estimation": data[0]})


def test_effect_search_without_physics_refuses_automatic_candidates(data):
    search = EffectSearchCV(GreyBoxSparseRegressor(None, max_iter=5), candidates="auto", cv=2)
    with pytest.raises(ValueError, match="the estimator has no physics"):
        search.fit(*data)


def test_a_well_posed_fit_raises_none_of_these(data):
    """The checks refuse what is wrong, not what is unusual: a polynomial library on the
    shipped data fits without any of the warnings above."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        est = _fit(*data, library=ps.PolynomialLibrary(degree=2))
    assert not [w for w in caught if "constant over the records" in str(w.message)]
    assert np.isfinite(est.score(*data))
