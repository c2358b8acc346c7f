"""A parameter held on each flat direction of the augmented physics' fit."""

import warnings

import numpy as np
import pytest

from sk_offwhite import Bias, Leak, Parameter, SensorCalibration, augment
from sk_offwhite.certify import identifiability
from sk_offwhite.datasets import make_nonlinear_sensor_tank
from sk_offwhite.loop import (
    LoopSettings,
    cross_validated_rmse,
    fit_continued,
    hold_undetermined_directions,
    warm_physics,
)
from sk_offwhite.loop._final import holding_as as _holding_as
from sk_offwhite.loop._fits import record_rmse as _rmse
from sk_offwhite.loop._gauge import (
    fit_undetermined_directions,
    held_note,
    held_parameters,
    holding,
    undetermined_directions,
)
from sk_offwhite.loop._search import Search

CALIBRATION = SensorCalibration(0, center=4.0, scale=2.0, name="sensor_x")


def _tank(free_gain: bool):
    """The sensor tank's record and its physics plus a calibration of the reading; with
    ``free_gain`` the pump gain is free, so that the level's scale is not determined (the
    calibration reads any rescaled level as well)."""
    data = make_nonlinear_sensor_tank(n_samples=300, random_state=3)
    physics = data.physics
    if free_gain:
        physics = physics.with_parameters(b=Parameter(0.4, (1e-6, None)))
    return data, augment(physics, CALIBRATION)


def _fitted(physics, data, settings):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = Search(data.u, data.z, settings).estimator(physics)
        return fit_continued(est, data.u, data.z, None)


def test_an_effects_parameter_is_held_before_a_declared_one():
    data, physics = _tank(free_gain=True)
    fitted = {"k": 0.5, "b": 0.4, "sensor_x_c0": 0.1, "sensor_x_c1": 0.2, "sensor_x_c2": 0.3}
    direction = {"b": 0.8, "x(0)": 0.5, "sensor_x_c1": -0.3, "k": 0.1}
    assert held_parameters([direction], physics, [CALIBRATION], fitted) == {"sensor_x_c1": 0.2}


def test_nothing_is_held_where_no_added_effect_loads_on_the_direction():
    """A direction of the declared physics' own is the user's to fix: it is reported."""
    data, physics = _tank(free_gain=True)
    fitted = {"k": 0.5, "b": 0.4, "sensor_x_c0": 0.1, "sensor_x_c1": 0.2, "sensor_x_c2": 0.3}
    direction = {"x(0)": 0.9, "b": 0.4, "k": -0.2, "sensor_x_c1": 0.05}
    assert held_parameters([direction], physics, [CALIBRATION], fitted) == {}


def test_a_direction_of_one_parameter_alone_is_not_a_trade_off_and_nothing_is_held():
    """A calibration coefficient the data cannot tell from zero: its own uncertainty."""
    data, physics = _tank(free_gain=True)
    fitted = {"k": 0.5, "b": 0.4, "sensor_x_c0": 0.1, "sensor_x_c1": 0.2, "sensor_x_c2": 1e-4}
    alone = {"sensor_x_c2": 0.999, "k": 0.04}
    assert held_parameters([alone], physics, [CALIBRATION], fitted) == {}
    traded = {"sensor_x_c2": 0.9, "k": 0.4}
    assert held_parameters([traded], physics, [CALIBRATION], fitted) == {"sensor_x_c2": 1e-4}


def test_a_direction_within_one_effect_is_its_own_uncertainty_and_nothing_is_held():
    """A calibration fitted to nearly nothing: its coefficients' relative errors are large
    together (the stepped-sensor tank), but no other source trades off with them; with a
    second effect on the direction, the effect's parameter is held."""
    data, physics = _tank(free_gain=True)
    physics = augment(physics, Leak(0))
    fitted = {"k": 0.5, "b": 0.4, "sensor_x_c0": -0.006, "sensor_x_c1": 0.0, "sensor_x_c2": 0.0}
    fitted["leak_rate"] = 0.01
    within = {"sensor_x_c2": 0.72, "sensor_x_c0": 0.69}
    assert held_parameters([within], physics, [CALIBRATION, Leak(0)], fitted) == {}
    across = {"sensor_x_c2": 0.72, "leak_rate": 0.69}
    held = held_parameters([across], physics, [CALIBRATION, Leak(0)], fitted)
    assert held == {"sensor_x_c2": 0.0}


def _record(values, gains, noise=0.1, n=100):
    """``(jacobian, residual)`` whose relative Gauss-Newton matrix is ``diag(gains**2)``
    and whose residual variance is ``noise**2``: relative standard errors
    ``noise / gains``."""
    basis, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(n, len(values))))
    residual = np.random.default_rng(1).normal(size=n)
    residual *= noise * np.sqrt(n - len(values)) / np.linalg.norm(residual)
    return basis * np.asarray(gains) / np.asarray(values), residual


def test_a_direction_is_undetermined_when_its_relative_error_reaches_the_bound():
    """Relative standard errors 1.0, 0.1 and 0.3 along the axes: only the first is
    undetermined, and the third too at a bound of 0.25; a singular direction always is;
    a parameter in other units (times 1000) gives the same directions."""
    names, values = ("a", "b", "c"), np.array([2.0, 4.0, 10.0])
    jacobian, residual = _record(values, [0.1, 1.0, 1 / 3])
    found = undetermined_directions(names, values, jacobian, residual)
    assert found == ({"a": pytest.approx(1.0)},)
    assert len(undetermined_directions(names, values, jacobian, residual, 0.25)) == 2
    singular, residual = _record(values, [1.0, 1.0, 0.0])
    assert undetermined_directions(names, values, singular, residual) == ({"c": 1.0},)
    units = np.array([1000.0, 1.0, 1.0])
    jacobian, residual = _record(values, [0.1, 1.0, 1 / 3])
    rescaled = undetermined_directions(names, values * units, jacobian / units, residual)
    assert rescaled == found


def test_initial_states_and_fixed_parameters_are_never_held_and_each_parameter_once():
    data, physics = _tank(free_gain=False)  # b is fixed
    fitted = {"k": 0.5, "b": 0.5, "sensor_x_c0": 0.1, "sensor_x_c1": 0.2, "sensor_x_c2": 0.3}
    assert held_parameters([{"x(0)": 1.0, "b": 0.2}], physics, [CALIBRATION], fitted) == {}
    directions = [
        {"sensor_x_c2": 0.9, "k": 0.4},
        {"sensor_x_c2": 0.7, "sensor_x_c0": 0.6, "k": 0.2},
    ]
    held = held_parameters(directions, physics, [CALIBRATION], fitted)
    assert held == {"sensor_x_c2": 0.3, "sensor_x_c0": 0.1}


def test_holding_fixes_the_values_keeps_the_bounds_and_leaves_the_physics_alone():
    data, physics = _tank(free_gain=True)
    held = holding(physics, {"b": 0.7})
    assert held.parameters["b"].fixed and held.parameters["b"].value == 0.7
    assert held.parameters["b"].bounds == physics.parameters["b"].bounds
    assert not physics.parameters["b"].fixed and physics.parameters["b"].value == 0.4


def test_the_note_names_the_held_parameter_and_what_it_is_flat_with():
    note = held_note(
        {"c2": 0.1086}, [{"c2": 0.67, "k2": -0.34, "k1": 1e-4}], (0.0928, 0.0928), (0.11, 0.1)
    )
    assert "c2 = 0.1086 (with k2)" in note
    assert "0.0928 -> 0.0928" in note and "0.11 -> 0.1" in note


def test_a_calibrated_level_of_free_scale_gets_a_parameter_held_and_the_same_fit():
    """With the pump gain free, the calibrated level's scale is a direction the data do
    not determine: a calibration coefficient is held, the fit is the same, the held fit is
    locally identifiable and determines every direction."""
    data, physics = _tank(free_gain=True)
    settings = LoopSettings(n_folds=2, max_iter=100)
    final = _fitted(physics, data, settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert not identifiability(final, data.u, data.z, include_omega=False).identifiable
        cv = cross_validated_rmse(warm_physics(physics, final), data.u, data.z, settings)
        held_physics, held_fit, held_cv, note = hold_undetermined_directions(
            physics, final, data.u, data.z, settings=settings, cv=cv
        )
        report = identifiability(held_fit, data.u, data.z, include_omega=False)
    (name,) = [n for n, spec in held_physics.parameters.items() if spec.fixed and n != "b"]
    assert name.startswith("sensor_x_c") and name in note
    assert held_physics.parameters[name].value == pytest.approx(final.parameters_[name])
    before, after = _rmse(final.predict(data.u), data.z), _rmse(held_fit.predict(data.u), data.z)
    assert after <= before * (1 + 1e-3)
    assert held_cv <= cv * (1 + settings.tolerance)
    assert report.identifiable and fit_undetermined_directions(held_fit, data.u, data.z) == ()


def test_a_hold_not_kept_returns_the_unheld_models_cv(monkeypatch):
    """Where the held refit fails, the model stays unheld and is scored by its own CV,
    not by the held CV the loop passed in (the trail's)."""
    from sk_offwhite.loop import _final

    data, physics = _tank(free_gain=True)
    settings = LoopSettings(n_folds=2, max_iter=100)
    final = _fitted(physics, data, settings)

    def failing(*args):
        raise ValueError("the held refit failed")

    monkeypatch.setattr(_final, "fit_set", failing)
    failures = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = hold_undetermined_directions(
            physics, final, data.u, data.z, settings=settings, held_cv=0.001, failures=failures
        )
        free = cross_validated_rmse(warm_physics(physics, final), data.u, data.z, settings)
    assert out[0] is physics and out[1] is final and out[3] is None
    assert out[2] == pytest.approx(free) and "held refit failed" in failures[0]


def test_a_fit_the_data_determine_is_left_as_it_is():
    data, physics = _tank(free_gain=False)
    settings = LoopSettings(n_folds=2, max_iter=100)
    final = _fitted(physics, data, settings)
    out = hold_undetermined_directions(physics, final, data.u, data.z, settings=settings, cv=0.5)
    assert out[0] is physics and out[1] is final and out[2:] == (0.5, None)


def test_an_exact_symmetry_of_two_biases_is_broken_by_holding_one():
    """Two constants in one equation: only their sum is determined, one is held."""
    data = make_nonlinear_sensor_tank(n_samples=300, random_state=4)
    first, second = Bias(0, name="bias_a"), Bias(0, name="bias_b")
    physics = augment(data.physics, first, second)
    settings = LoopSettings(n_folds=2, max_iter=100)
    final = _fitted(physics, data, settings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        held_physics, _, held_cv, note = hold_undetermined_directions(
            physics, final, data.u, data.z, effects=(first, second), settings=settings
        )
    fixed = [n for n in ("bias_a_value", "bias_b_value") if held_physics.parameters[n].fixed]
    assert len(fixed) == 1 and fixed[0] in note and np.isfinite(held_cv)
    with warnings.catch_warnings():  # a held CV already known (the loop's trail) is taken
        warnings.simplefilter("ignore")
        _, _, given, note = hold_undetermined_directions(
            physics, final, data.u, data.z, effects=(first, second), settings=settings,
            held_cv=held_cv * 1.001,
        )  # fmt: skip
    assert given == held_cv * 1.001 and f"{held_cv * 1.001:.4g}" in note


def test_the_results_augmented_physics_holds_what_the_final_model_holds():
    data, template = _tank(free_gain=True)
    fitted = holding(template.with_parameters(k=0.7), {"sensor_x_c2": 0.25})
    held = _holding_as(template, fitted)
    assert held.parameters["sensor_x_c2"].fixed and held.parameters["sensor_x_c2"].value == 0.25
    assert held.parameters["k"].value == template.parameters["k"].value  # starts unchanged
    assert not template.parameters["sensor_x_c2"].fixed
