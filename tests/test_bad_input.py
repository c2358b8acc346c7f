"""Every kind of bad input raises a clear error that names the offending argument."""

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest
from conftest import TANKS_TRUE, tanks_physics, tanks_step

from sk_offwhite import DivergenceWarning, GreyBoxSparseRegressor, Parameter, PhysicsModel


@pytest.fixture
def data(tanks_data):
    u, z, _ = tanks_data
    return u[:200].copy(), z[:200].copy()


def _fit(u, z, **params):
    params = {"max_iter": 5, **params}
    return GreyBoxSparseRegressor(tanks_physics(), **params).fit(u, z)


def _physics(step, output=(1,), n_states=2, **kwargs):
    parameters = {k: Parameter(v) for k, v in TANKS_TRUE.items()}
    return PhysicsModel(step, list(output), parameters, n_states, 1, x0=[5.0, 5.0], **kwargs)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_input_names_u(data, bad):
    u, z = data
    u[17, 0] = bad
    with pytest.raises(ValueError, match=r"u .*(NaN|infinity)"):
        _fit(u, z)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_output_names_z(data, bad):
    u, z = data
    z[3, 0] = bad
    with pytest.raises(ValueError, match=r"z .*(NaN|infinity)"):
        _fit(u, z)


def test_mismatched_lengths(data):
    u, z = data
    with pytest.raises(ValueError, match="u has 200 samples but z has 199"):
        _fit(u, z[:-1])


def test_three_dimensional_input_is_rejected(data):
    u, z = data
    with pytest.raises(ValueError, match="Found array with dim 3"):
        _fit(u[:, :, None], z)


def test_input_columns_must_match_the_physics(data):
    u, z = data
    with pytest.raises(ValueError, match=r"u has 2 column\(s\) but physics.n_inputs is 1"):
        _fit(np.hstack([u, u]), z)


def test_output_columns_must_match_the_physics(data):
    u, z = data
    with pytest.raises(ValueError, match=r"physics.output returned shape \(1,\), expected \(2,\)"):
        _fit(u, np.hstack([z, z]))


def test_step_of_the_wrong_shape_is_named(data):
    u, z = data
    physics = _physics(lambda x, u, theta: x[:1] * theta["k1"])
    with pytest.raises(ValueError, match=r"physics.step returned shape \(1,\), expected \(2,\)"):
        GreyBoxSparseRegressor(physics).fit(*data)


def test_step_with_non_finite_values_at_the_initial_guess(data):
    physics = _physics(lambda x, u, theta: jnp.log(x - 10.0) * theta["k1"])
    with pytest.raises(ValueError, match="physics.step returned non-finite values"):
        GreyBoxSparseRegressor(physics).fit(*data)


def test_step_that_jax_cannot_trace_is_named(data):
    def numpy_step(x, u, theta):
        return np.array([float(x[0]) * theta["k1"], float(x[1])])

    with pytest.raises(TypeError, match="physics.step cannot be evaluated with JAX"):
        GreyBoxSparseRegressor(_physics(numpy_step)).fit(*data)


class _SlottedStep:
    """A step object with no weak reference, which `jax.jit` cannot take as its function."""

    __slots__ = ()

    def __call__(self, x, u, theta):
        return tanks_step(x, u, theta)


class _UnhashableStep(_SlottedStep):
    __hash__ = None


def test_a_step_object_without_a_weak_reference_is_checked_and_fitted(data):
    est = GreyBoxSparseRegressor(_physics(_SlottedStep()), max_iter=5).fit(*data)
    assert np.all(np.isfinite(est.predict(data[0])))


def test_an_unhashable_step_object_is_named(data):
    with pytest.raises(TypeError, match="physics.step must be hashable"):
        GreyBoxSparseRegressor(_physics(_UnhashableStep())).fit(*data)


def test_horizon_longer_than_the_data(data):
    with pytest.raises(ValueError, match=r"horizon=500 is longer than the data \(200 samples\)"):
        _fit(*data, horizon=500)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("gamma", -1.0),
        ("lam", -0.1),
        ("nu", -2.0),
        ("horizon", 0),
        ("max_iter", 0),
        ("prune_tol", -1e-3),
        ("prune_tol", 1.5),
        ("refit", "yes"),
        ("l1_smoothing", 0.0),
        ("solver", "newton"),
        ("tol", -1.0),
    ],
)
def test_invalid_hyperparameters_name_themselves(data, name, value):
    with pytest.raises(ValueError, match=f"'{name}' parameter of GreyBoxSparseRegressor"):
        _fit(*data, **{name: value})


def test_a_single_sample_cannot_be_simulated(data):
    u, z = data
    with pytest.raises(ValueError, match="at least 2 consecutive samples"):
        _fit(u[:1], z[:1])


@pytest.mark.parametrize("states", [[2], [0, 0], [0.7], [], [[0, 1]]])
def test_delta_states_must_be_distinct_indices(data, states):
    with pytest.raises(ValueError, match=r"delta_states must be distinct integer indices"):
        _fit(*data, library=ps.PolynomialLibrary(degree=1), delta_states=states)


@pytest.mark.parametrize("name", ["horizon", "max_iter", "init_window"])
def test_integer_settings_refuse_booleans(data, name):
    with pytest.raises(ValueError, match=f"{name} must be an integer, got True"):
        _fit(*data, **{name: True})


def test_optimizer_must_be_an_optax_transformation(data):
    with pytest.raises(TypeError, match="optimizer must be an optax.GradientTransformation"):
        _fit(*data, solver="optax", optimizer="adam")


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"x0_bounds": (10.0, 0.0)}, "x0_bounds must satisfy lower <= upper"),
        ({"x0_bounds": (0.0, 1.0)}, "lies outside x0_bounds"),
        ({"x0_bounds": (0.0,)}, "x0_bounds must be a"),
        ({"x0_fixed": [True, False, True]}, "x0_fixed must be a scalar or have one entry"),
    ],
)
def test_initial_state_settings_are_checked(kwargs, message):
    with pytest.raises(ValueError, match=message):
        _physics(tanks_step, **kwargs)


def test_certificates_need_a_fitted_estimator(data):
    from sklearn.exceptions import NotFittedError

    from sk_offwhite.certify import parameter_error_bound

    with pytest.raises(NotFittedError):
        parameter_error_bound(GreyBoxSparseRegressor(tanks_physics()), *data)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"gammas": (-1.0, 1.0)}, "'gammas' parameter of LoopSettings"),
        ({"gammas": ()}, "'gammas' parameter of LoopSettings"),
        ({"n_folds": 1}, "'n_folds' parameter of LoopSettings"),
        ({"n_folds": 2.5}, "'n_folds' parameter of LoopSettings"),
        ({"fit_top": 0}, "'fit_top' parameter of LoopSettings"),
        ({"n_pairs": -1}, "'n_pairs' parameter of LoopSettings"),
    ],
)
def test_loop_settings_are_checked(kwargs, message):
    from sk_offwhite.loop import LoopSettings

    with pytest.raises(ValueError, match=message):
        LoopSettings(**kwargs)


def test_unsupported_library_is_rejected(data):
    pde = ps.PDELibrary(derivative_order=1, spatial_grid=np.linspace(0, 1, 10))
    with pytest.raises(TypeError, match="PDELibrary"):
        _fit(*data, library=pde)
    with pytest.raises(TypeError, match="str"):
        _fit(*data, library="poly")


def test_experiment_lists_must_pair_up(data):
    u, z = data
    with pytest.raises(ValueError, match="one entry per experiment"):
        _fit([u, u], [z])
    with pytest.raises(ValueError, match=r"u\[1\] has 100 samples but z\[1\] has 200"):
        _fit([u, u[:100]], [z, z])


def test_predict_checks_the_input_width(data):
    u, z = data
    est = _fit(u, z)
    with pytest.raises(
        ValueError, match="u has 2 features, but GreyBoxSparseRegressor is expecting"
    ):
        est.predict(np.hstack([u, u]))


def test_sample_index_of_the_wrong_length(data):
    u, z = data
    with pytest.raises(ValueError, match="sample_index must have one entry per sample"):
        GreyBoxSparseRegressor(tanks_physics(), max_iter=5).fit(u, z, sample_index=np.arange(10))


def test_parameter_definitions_are_checked():
    with pytest.raises(ValueError, match="outside its bounds"):
        Parameter(2.0, bounds=(0.0, 1.0))
    with pytest.raises(ValueError, match="must be finite"):
        Parameter(np.nan)
    with pytest.raises(ValueError, match="x0 must be 2 finite values"):
        PhysicsModel(tanks_step, [1], {"k1": Parameter(1.0)}, 2, 1, x0=[1.0, np.nan])


def test_fit_leaves_global_jax_configuration_alone(data):
    before = jax.config.jax_enable_x64
    _fit(*data)
    assert jax.config.jax_enable_x64 == before


def test_missing_outputs_are_named(data):
    with pytest.raises(ValueError, match="z is None"):
        _fit(data[0], None)


@pytest.fixture
def fitted(data):
    return _fit(*data, max_iter=20), data


@pytest.mark.parametrize(
    ("z_init", "message"),
    [
        (np.array([[1.0], [np.nan]]), "z_init must be finite"),
        (np.array([[1.0], [np.inf]]), "z_init must be finite"),
        (np.ones((3, 2)), r"z_init must have shape \(n_init, 1\)"),
        (np.ones((500, 1)), "n_init <= 200"),
        ([np.ones((3, 1)), np.ones((3, 1))], "z_init is a list, but u is one record"),
    ],
)
def test_predict_refuses_a_bad_z_init(fitted, z_init, message):
    est, (u, _) = fitted
    with pytest.raises(ValueError, match=message):
        est.predict(u, z_init=z_init)


def test_an_empty_z_init_starts_from_the_fitted_state(fitted):
    est, (u, _) = fitted
    np.testing.assert_array_equal(est.predict(u, z_init=np.zeros((0, 1))), est.predict(u))


def test_predict_on_records_takes_one_z_init_each(fitted):
    est, (u, z) = fitted
    records = [u[:100], u[100:]]
    with pytest.raises(ValueError, match="z_init must be None or a list of 2 arrays"):
        est.predict(records, z_init=z[:10])
    together = est.predict(records, z_init=[z[:10], z[100:110]])
    np.testing.assert_allclose(together[1], est.predict(u[100:], z_init=z[100:110]))
    assert not np.allclose(together[1], est.predict(u[100:]))  # z_init is not ignored


def test_a_diverging_simulation_says_where():
    from sk_offwhite.datasets import make_leaky_tank

    tank = make_leaky_tank(n_samples=300, random_state=0)
    est = GreyBoxSparseRegressor(None, max_iter=5).fit(tank.u, tank.z)  # linear x+ = A x + B u
    est.theta_ = np.where(np.array(est.physics_.parameter_names) == "A[0,0]", 1e3, est.theta_)
    with pytest.warns(DivergenceWarning, match="not finite from sample"):
        outputs = est.predict(tank.u)
    assert not np.all(np.isfinite(outputs))


def test_close_the_loop_refuses_outputs_of_another_length():
    from sk_offwhite.datasets import make_leaky_tank
    from sk_offwhite.loop import close_the_loop

    tank = make_leaky_tank(n_samples=100, random_state=0)
    with pytest.raises(ValueError, match="u has 100 samples but z has 200"):
        close_the_loop(None, None, tank.u, np.vstack([tank.z, tank.z]))


def test_dataset_bunches_print():
    """pysindy's CustomLibrary repr fails on its own; the datasets' libraries print."""
    from sk_offwhite.datasets import make_vehicle_lateral, vehicle_dictionary_library

    assert "CustomLibrary" in repr(make_vehicle_lateral(n_samples=50, random_state=0))
    assert repr(vehicle_dictionary_library()).startswith("CustomLibrary(function_names=")


@pytest.mark.parametrize("k_init", [[0.1, 0.2], [[0.1] * 4], np.nan])
def test_tank_guesses_of_the_wrong_length_are_named(k_init):
    from sk_offwhite.datasets import cascaded_tanks_physics

    with pytest.raises(ValueError, match="k_init must be one finite number or four"):
        cascaded_tanks_physics(k_init=k_init)


def test_warm_start_takes_parameters_by_name(data):
    """A physics with the same parameters in another order starts where the fit ended."""
    u, z = data
    est = GreyBoxSparseRegressor(tanks_physics(x0=[z[0, 0], z[0, 0]]), max_iter=30).fit(u, z)
    reordered = tanks_physics(x0=[z[0, 0], z[0, 0]])
    reordered.parameters = dict(reversed(list(reordered.parameters.items())))
    est.set_params(physics=reordered, warm_start=True, max_iter=1).fit(u, z)
    assert est.loss_history_[0] == pytest.approx(est.cost_, rel=0.5)
    assert est.loss_history_[0] < 1e-3


def test_certificates_refuse_data_other_than_the_fit(data):
    from sk_offwhite.certify import identifiability

    u, z = data
    est = _fit(u, z)
    with pytest.raises(ValueError, match="not the data the estimator was fitted on"):
        identifiability(est, u, z + 0.01)
