"""The sparse correction of the output map (``delta_outputs``), its dictionary of bumps
(``RadialBasis``) and the loop's stage that fits it: a static sensor nonlinearity."""

import pickle
import warnings
from types import SimpleNamespace

import jax
import numpy as np
import pysindy as ps
import pytest
from sklearn.base import clone

from sk_offwhite import (
    GreyBoxSparseRegressor,
    PhysicsModel,
    RadialBasis,
    compile_basis,
    fit_gamma_path,
)
from sk_offwhite.certify import identifiability
from sk_offwhite.datasets import make_nonlinear_sensor_tank
from sk_offwhite.datasets._synthetic import tank_rhs
from sk_offwhite.loop import LoopSettings, cross_validated_rmse, warm_physics
from sk_offwhite.loop._corrections import scored_output_delta
from sk_offwhite.loop._result import choose as _choose
from sk_offwhite.loop._search import Search


@pytest.fixture(scope="module")
def sensor_data():
    return make_nonlinear_sensor_tank(n_samples=600, random_state=0)


def _library():
    return ps.PolynomialLibrary(degree=2, include_bias=True)


@pytest.fixture(scope="module")
def output_fit(sensor_data):
    """The sensor tank fitted with a correction of its output map."""
    return _fit(sensor_data.physics, sensor_data.u, sensor_data.z, delta_outputs=[0])


def _fit(physics, u, z, **kwargs):
    est = GreyBoxSparseRegressor(physics, _library(), gamma=1e-3, max_iter=300, **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return est.fit(u, z)


def _validation_rmse(est, data) -> float:
    return float(np.sqrt(np.mean((est.predict(data.u_val).ravel() - data.z_val.ravel()) ** 2)))


def _read_as(physics: PhysicsModel, gain: float) -> PhysicsModel:
    """The sensor tank's declared physics with its output map multiplied by ``gain``."""
    return PhysicsModel.from_ode(
        tank_rhs,
        1.0,
        output=lambda x, u, theta: gain * x[:1],
        parameters=dict(physics.parameters),
        n_states=1,
        n_inputs=1,
        method="euler",
        x0=tuple(physics.x0),
        state_names=("x",),
        input_names=("u",),
    )


def test_the_output_correction_finds_the_sensor_curve_and_the_true_outflow(output_fit):
    est = output_fit
    names = list(est.feature_names_)
    assert est.coef_.shape == (1, len(names))
    assert est.delta_states_ == () and est.delta_outputs_ == (0,)
    assert est.n_nonzero_ == 1
    np.testing.assert_allclose(est.coef_[0, names.index("x^2")], 0.04, rtol=0.05)
    np.testing.assert_allclose(est.parameters_["k"], 0.5, rtol=0.01)
    curve = est.coef_[0, names.index("x^2")]
    assert est.equations() == [
        "x[k+1] = f_1(x[k], u[k]; θ)",
        f"output x = h_1(x[k], u[k]; θ) + {curve:.4g} x^2",
    ]


def test_on_a_sensor_fault_it_validates_better_than_a_state_correction(sensor_data, output_fit):
    on_state = _fit(sensor_data.physics, sensor_data.u, sensor_data.z)
    assert _validation_rmse(output_fit, sensor_data) < 0.6 * _validation_rmse(on_state, sensor_data)
    assert _validation_rmse(output_fit, sensor_data) < 1.2 * 0.02  # the noise level


def test_the_output_correction_does_not_depend_on_the_output_units(sensor_data, output_fit):
    gain, base = 1000.0, output_fit
    scaled = _fit(
        _read_as(sensor_data.physics, gain), sensor_data.u, gain * sensor_data.z, delta_outputs=[0]
    )
    np.testing.assert_array_equal(scaled.support_, base.support_)
    np.testing.assert_allclose(scaled.coef_, gain * base.coef_, rtol=1e-4, atol=1e-12)
    np.testing.assert_allclose(scaled.parameters_["k"], base.parameters_["k"], rtol=1e-5)


def test_state_and_output_rows_together(sensor_data):
    est = _fit(
        sensor_data.physics, sensor_data.u, sensor_data.z, delta_states=[0], delta_outputs=[0]
    )
    assert est.coef_.shape == (2, len(est.feature_names_))
    assert est.delta_states_ == (0,) and est.delta_outputs_ == (0,)
    lines = est.equations()
    assert lines[0].startswith("x[k+1] = f_1") and lines[1].startswith("output x = h_1")
    # the fault is in the sensor: the output row carries the curve
    names = list(est.feature_names_)
    np.testing.assert_allclose(est.coef_[1, names.index("x^2")], 0.04, rtol=0.15)


def test_the_gamma_path_names_output_rows(sensor_data):
    est = GreyBoxSparseRegressor(sensor_data.physics, _library(), delta_outputs=[0], max_iter=40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = fit_gamma_path(est, sensor_data.u[:150], sensor_data.z[:150], n_gammas=3, cv=None)
    assert all(name.startswith("output x: ") for name in path.selected(len(path.gammas) - 1))


def test_identifiability_of_an_output_correction(sensor_data, output_fit):
    report = identifiability(output_fit, sensor_data.u, sensor_data.z)
    assert report.identifiable
    assert "omega[output x: x^2]" in report.names


def test_an_output_correction_survives_clone_and_pickle(sensor_data, output_fit):
    est = output_fit
    assert clone(est).get_params()["delta_outputs"] == [0]
    restored = pickle.loads(pickle.dumps(est))
    np.testing.assert_array_equal(
        restored.predict(sensor_data.u_val), est.predict(sensor_data.u_val)
    )


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"delta_outputs": [1]}, r"delta_outputs must be distinct integer indices in \[0, 1\)"),
        ({"delta_outputs": [0, 0]}, "delta_outputs must be distinct"),
        ({"delta_outputs": []}, "delta_outputs must be distinct"),
        ({"delta_outputs": [0.5]}, "delta_outputs must be distinct"),
        ({"delta_states": []}, "delta_states must be distinct"),
    ],
)
def test_bad_correction_targets_are_named(sensor_data, kwargs, match):
    est = GreyBoxSparseRegressor(sensor_data.physics, _library(), max_iter=5, **kwargs)
    with pytest.raises(ValueError, match=match):
        est.fit(sensor_data.u[:50], sensor_data.z[:50])


def test_no_state_rows_when_only_outputs_are_corrected(sensor_data):
    est = GreyBoxSparseRegressor(
        sensor_data.physics, _library(), max_iter=5, delta_outputs=[0], delta_states=[]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est.fit(sensor_data.u[:50], sensor_data.z[:50])
    assert est.delta_states_ == () and est.coef_.shape[0] == 1


# --------------------------------------------------------------------- the dictionary


def test_the_radial_dictionary_is_its_formula_clipped_to_its_limits():
    library = RadialBasis({"x2": [1.0, 3.0]}, {"x2": 0.5}, limits={"x2": (0.0, 4.0)})
    compiled = compile_basis(library, ["x1", "x2", "u"], 2)
    assert compiled.names == (
        "1",
        "clip(x2)",
        "exp(-0.5 ((clip(x2) - 1) / 0.5)^2)",
        "exp(-0.5 ((clip(x2) - 3) / 0.5)^2)",
    )
    for x2, held in [(2.2, 2.2), (9.0, 4.0), (-3.0, 0.0)]:
        with jax.enable_x64(True):
            phi = np.asarray(compiled.evaluate({}, np.array([7.0, x2, 5.0])))
        bumps = np.exp(-0.5 * ((held - np.array([1.0, 3.0])) / 0.5) ** 2)
        np.testing.assert_allclose(phi, np.tile([1.0, held, *bumps], (2, 1)), rtol=1e-12)


def test_the_radial_dictionary_from_data_does_not_depend_on_units():
    rng = np.random.default_rng(0)
    values = rng.normal(5.0, 2.0, size=(200, 1))
    probe = np.array([[0.0, v] for v in np.linspace(-5.0, 15.0, 9)])
    features = []
    for gain in (1.0, 250.0):
        library = RadialBasis.from_data(gain * values, ["x"], n_bumps=5)
        compiled = compile_basis(library, ["u", "x"], 1)
        with jax.enable_x64(True):
            rows = np.array([compiled.evaluate({}, gain * row)[0] for row in probe])
        features.append(rows[:, 2:])  # the bumps (the constant and x scale with the units)
        assert library.limits["x"] == (gain * values.min(), gain * values.max())
    np.testing.assert_allclose(features[1], features[0], rtol=1e-9, atol=1e-12)


def test_equal_radial_dictionaries_share_a_compiled_program():
    make = lambda: RadialBasis({"x": [0.0, 1.0]}, {"x": 1.0})  # noqa: E731
    assert make() == make() and hash(make()) == hash(make())
    assert compile_basis(make(), ["x"], 1) is compile_basis(make(), ["x"], 1)
    assert pickle.loads(pickle.dumps(make())) == make()


@pytest.mark.parametrize(
    "args, kwargs, match",
    [
        (({"x": [0.0]}, {"y": 1.0}), {}, "name the same"),
        (({"x": []}, {"x": 1.0}), {}, "non-empty"),
        (({"x": [np.nan]}, {"x": 1.0}), {}, "finite"),
        (({"x": [0.0]}, {"x": 0.0}), {}, r"widths\['x'\]"),
        (({"x": [0.0]}, {"x": 1.0}), {"limits": {"x": (2.0, 1.0)}}, r"limits\['x'\]"),
        (({"x": [0.0]}, {"x": 1.0}), {"limits": {"y": (0.0, 1.0)}}, r"limits\['y'\]"),
    ],
)
def test_bad_radial_dictionaries_are_refused(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        RadialBasis(*args, **kwargs)


def test_a_radial_dictionary_must_name_known_variables():
    with pytest.raises(ValueError, match=r"names \['h'\]"):
        compile_basis(RadialBasis({"h": [0.0]}, {"h": 1.0}), ["x", "u"], 1)
    with pytest.raises(ValueError, match="n_bumps"):
        RadialBasis.from_data(np.arange(5.0), ["x"], n_bumps=1)
    with pytest.raises(ValueError, match="vary"):
        RadialBasis.from_data(np.ones(5), ["x"])


# --------------------------------------------------------------------- the loop's stage


def test_the_loop_corrects_the_output_map_where_the_sensor_is_wrong(sensor_data):
    u, z = sensor_data.u[:300], sensor_data.z[:300]
    settings = LoopSettings(n_folds=2, max_iter=100, gammas=(1e-3,))
    declared = GreyBoxSparseRegressor(sensor_data.physics, max_iter=100).fit(u, z)
    start = warm_physics(sensor_data.physics, declared)
    search, notes = Search(u, z, settings), []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est, path, cv = scored_output_delta(search, start, declared, (0,), notes)
        declared_cv = cross_validated_rmse(start, u, z, settings)
    assert search.failures == [] and notes == [] and path is None
    assert est.delta_outputs_ == (0,) and est.delta_states_ == ()
    states = declared.simulate(u).states[:, 0]
    assert est.library.limits == {"x": (states.min(), states.max())}
    assert cv < 0.5 * declared_cv


def test_no_output_correction_where_the_outputs_do_not_read_states(sensor_data):
    search, notes = Search(sensor_data.u, sensor_data.z, LoopSettings()), []
    outcome = scored_output_delta(search, sensor_data.physics, None, None, notes)
    assert outcome == (None, None, np.inf) and search.failures == []
    assert notes == ["augmented physics + output δ not fitted: the outputs do not read states "
                     "directly."]  # fmt: skip


def test_output_bumps_must_be_an_integer_of_at_least_two():
    for bad in (1, 2.5, True):
        with pytest.raises(ValueError, match="output_bumps"):
            LoopSettings(output_bumps=bad)


def test_a_correction_that_kept_no_term_is_not_chosen_on_its_own_score():
    physics = SimpleNamespace(library=None, n_nonzero_=0)
    empty = SimpleNamespace(library="a dictionary", n_nonzero_=0)
    kept = SimpleNamespace(library="a dictionary", n_nonzero_=3)
    models = {"final": physics, "final_with_output_delta": empty, "final_with_delta": kept}
    cv = {"final": 0.2, "final_with_output_delta": 0.15, "final_with_delta": 0.18}
    notes = []
    assert _choose(cv, models, notes) == "final_with_delta"
    assert notes == [
        "augmented physics + output δ kept no term (it is the physics it corrects): not "
        "chosen on its own score (0.15)."
    ]
    assert _choose({**cv, "final_with_delta": 0.25}, models, []) == "final"
