"""Tests of sk_offwhite.datasets: the measured Cascaded Tanks data and synthetic systems."""

import hashlib
import pickle
from importlib import resources

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest

from sk_offwhite.datasets import (
    cascaded_tanks_physics,
    load_cascaded_tanks,
    make_cascaded_tanks,
    make_friction_oscillator,
    make_leaky_tank,
    make_saturating_actuator,
    make_vehicle_lateral,
    safe_sqrt,
)
from sk_offwhite.model._physics import PhysicsModel

GENERATORS = {
    "vehicle": make_vehicle_lateral,
    "tanks": make_cascaded_tanks,
    "friction": make_friction_oscillator,
    "actuator": make_saturating_actuator,
    "leaky": make_leaky_tank,
}
NAMES = list(GENERATORS)
SHAPES = {  # (n_samples, n_states, n_inputs)
    "vehicle": (2000, 6, 2),
    "tanks": (1024, 2, 1),
    "friction": (2000, 2, 1),
    "actuator": (1000, 1, 1),
    "leaky": (1000, 1, 1),
}
EXPLAINED = {"tanks": 0.95, "actuator": 0.999}  # library approximates the effect
OUTPUT_STATE = {"vehicle": 0, "tanks": 1, "friction": 0, "actuator": 0, "leaky": 0}


def _make(name, noise_free=False, **kwargs):
    if noise_free:
        kwargs["noise_bound" if name == "vehicle" else "noise_std"] = 0.0
    return GENERATORS[name](**kwargs)


@pytest.fixture(scope="module")
def generated():
    """One default and one noise-free data set per generator (same seed)."""
    return {
        name: (_make(name, random_state=0), _make(name, noise_free=True, random_state=0))
        for name in NAMES
    }


def _physics_next(data, x, u):
    """``physics.step`` with the true parameters, vectorised, in float64."""
    with jax.enable_x64(True):
        step = jax.vmap(data.physics.step, in_axes=(0, 0, None))
        return np.array(step(jnp.asarray(x), jnp.asarray(u), data.true_parameters))


def _hidden_residual(data):
    x, u = data.x, data.u
    return x[1:] - _physics_next(data, x[:-1], u[:-1])


# --------------------------------------------------------------------------------------
# Measured Cascaded Tanks
# --------------------------------------------------------------------------------------


def test_load_cascaded_tanks_layout():
    data = load_cascaded_tanks()
    for key in ("u_est", "z_est", "u_val", "z_val"):
        assert data[key].shape == (1024, 1)
        assert data[key].dtype == np.float64
    assert data.sampling_time == 4.0
    np.testing.assert_array_equal(data.time, 4.0 * np.arange(1024))
    assert data.input_names == ["u"] and data.output_names == ["x2"]
    assert data.units == {"u": "V", "x2": "V"}
    physics = cascaded_tanks_physics()
    assert set(data.units) == {*physics.input_names, *physics.output_names}
    assert data.saturation_level == 10.0
    assert data.protocols["original"]["init_window"] == 0
    assert data.protocols["nonlinear_benchmarks"]["init_window"] == 50
    assert {"method", "test_rms", "source", "note"} <= set(data.published_results[0])
    assert min(r["test_rms"] for r in data.published_results) == 0.18
    assert "Cascaded Tanks" in data.DESCR


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("u_est", (0.409368, 6.47121, 2.80000, 0.999512)),
        ("z_est", (2.91157, 10.0000, 5.58273, 2.16514)),
        ("u_val", (0.505116, 6.34995, 2.80000, 0.999512)),
        ("z_val", (2.16388, 10.0000, 5.73647, 2.09933)),
    ],
)
def test_load_cascaded_tanks_statistics(key, expected):
    column = load_cascaded_tanks()[key][:, 0]
    stats = (column.min(), column.max(), column.mean(), column.std())
    np.testing.assert_allclose(stats, expected, atol=1e-4, rtol=0)


def test_load_cascaded_tanks_samples_and_saturation():
    data = load_cascaded_tanks()
    np.testing.assert_allclose(data.u_est[0, 0], 3.25672, atol=1e-5)
    np.testing.assert_allclose(data.z_est[0, 0], 5.20500, atol=1e-5)
    np.testing.assert_allclose(data.u_val[0, 0], 0.976192, atol=1e-6)
    np.testing.assert_allclose(data.z_val[0, 0], 4.97276, atol=1e-5)
    for key, count, first in (("z_est", 47, 150), ("z_val", 37, 152)):
        at_ten = np.flatnonzero(data[key][:, 0] == 10.0)
        assert at_ten.size == count and at_ten[0] == first


def test_load_cascaded_tanks_returns_copies():
    first = load_cascaded_tanks()
    first.z_est[:] = 0.0
    first.protocols["original"]["init_window"] = 7
    first.published_results.clear()
    second = load_cascaded_tanks()
    assert second.z_est[0, 0] != 0.0
    assert second.protocols["original"]["init_window"] == 0
    assert second.published_results


def test_cascaded_tanks_data_files_match_attribution():
    folder = resources.files("sk_offwhite.datasets").joinpath("data")
    notes = folder.joinpath("CASCADED_TANKS.md").read_text("utf-8")
    for name in ("cascaded_tanks_estimation.csv", "cascaded_tanks_validation.csv"):
        digest = hashlib.sha256(folder.joinpath(name).read_bytes()).hexdigest()
        assert digest in notes
    assert "10.4121/12960104" in notes and "CC BY-SA 4.0" in notes


def test_cascaded_tanks_physics_model():
    model = cascaded_tanks_physics()
    assert isinstance(model, PhysicsModel)
    assert model.parameter_names == ("k1", "k2", "k3", "k4")
    assert model.state_names == ("x1", "x2") and model.input_names == ("u",)
    assert model.output_names == ("x2",) and model.sampling_time == 4.0
    np.testing.assert_allclose(model.parameter_values(), 0.05)
    assert all(p.bounds == (1e-6, None) for p in model.parameters.values())
    np.testing.assert_allclose(model.x0, load_cascaded_tanks().z_est[0, 0])
    x, u, k = np.array([4.0, 2.5]), np.array([3.0]), dict(k1=0.1, k2=0.2, k3=0.3, k4=0.4)
    expected = [4.0 + 4.0 * (-0.1 * 2.0 + 0.4 * 3.0), 2.5 + 4.0 * (0.2 * 2.0 - 0.3 * 2.5**0.5)]
    with jax.enable_x64(True):
        np.testing.assert_allclose(model.step(x, u, k), expected, rtol=1e-14)
        np.testing.assert_allclose(model.output(x, u, k), [2.5])


def test_cascaded_tanks_physics_options():
    model = cascaded_tanks_physics(fixed={"k4": 0.04}, k_init=(0.1, 0.2, 0.3, 0.4), x0=(1, 2))
    assert model.free_parameter_names == ("k1", "k2", "k3")
    np.testing.assert_allclose(model.parameter_values(), [0.1, 0.2, 0.3, 0.04])
    np.testing.assert_allclose(model.x0, [1.0, 2.0])
    assert pickle.loads(pickle.dumps(model)).step == model.step
    with pytest.raises(KeyError, match="k5"):
        cascaded_tanks_physics(fixed={"k5": 1.0})


def test_safe_sqrt_is_finite_with_finite_gradient():
    with jax.enable_x64(True):
        points = jnp.array([-1.0, 0.0, 1e-9, 4.0])
        grads = jax.vmap(jax.grad(safe_sqrt))(points)
        assert np.all(np.isfinite(safe_sqrt(points))) and np.all(np.isfinite(grads))
        np.testing.assert_allclose(safe_sqrt(4.0), 2.0)
        np.testing.assert_allclose(grads[-1], 0.25)


# --------------------------------------------------------------------------------------
# Synthetic generators: shared contract
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_generator_shapes(generated, name):
    data = generated[name][0]
    n, n_x, n_u = SHAPES[name]
    for key, shape in (("u", (n, n_u)), ("z", (n, 1)), ("x", (n, n_x))):
        assert data[key].shape == shape and data[key].dtype == np.float64
        assert data[key + "_val"].shape == shape
    assert data.true_x0.shape == (n_x,)
    np.testing.assert_array_equal(data.x[0], data.true_x0)
    assert set(data.true_parameters) == set(data.physics.parameter_names)
    assert data.physics.n_states == n_x and data.physics.n_inputs == n_u
    assert np.all(np.isfinite(data.x)) and np.all(np.isfinite(data.x_val))
    assert isinstance(data.DESCR, str) and data.noise["output"]["distribution"]


@pytest.mark.parametrize("name", NAMES)
def test_generator_physics_guess_is_not_the_truth(generated, name):
    data = generated[name][0]
    truth = np.array([data.true_parameters[p] for p in data.physics.parameter_names])
    assert not np.allclose(data.physics.parameter_values(), truth)


@pytest.mark.parametrize("name", NAMES)
def test_generator_is_deterministic(generated, name):
    data = generated[name][0]
    again = _make(name, random_state=0)
    for key in ("u", "z", "x", "u_val", "z_val", "x_val"):
        np.testing.assert_array_equal(again[key], data[key])
    other = _make(name, random_state=1, n_samples=50)
    assert not np.allclose(other.u, data.u[:50])


@pytest.mark.parametrize("name", NAMES)
def test_generator_validation_record_is_independent(generated, name):
    data = generated[name][0]
    assert not np.allclose(data.u, data.u_val)
    assert np.abs(np.corrcoef(data.u[:, 0], data.u_val[:, 0])[0, 1]) < 0.5


@pytest.mark.parametrize("name", NAMES)
def test_generator_noise_free_output_is_the_true_output(generated, name):
    data, clean = generated[name]
    np.testing.assert_array_equal(clean.x, data.x)  # noise does not shift the input stream
    idx = OUTPUT_STATE[name]
    np.testing.assert_array_equal(clean.z[:, 0], clean.x[:, idx])
    np.testing.assert_array_equal(clean.z_val[:, 0], clean.x_val[:, idx])
    assert not np.array_equal(data.z[:, 0], data.x[:, idx])
    if name != "tanks":  # the tanks sensor also clips at 10
        np.testing.assert_allclose(data.z, data.x[:, :1] + data.noise["output_noise"])


@pytest.mark.parametrize("name", NAMES)
def test_physics_plus_hidden_effect_reproduces_the_states(generated, name):
    data = generated[name][1]
    effect = data.hidden_effect
    for x, u in ((data.x, data.u), (data.x_val, data.u_val)):
        predicted = _physics_next(data, x[:-1], u[:-1]) + effect["state_function"](x[:-1], u[:-1])
        assert np.max(np.abs(predicted - x[1:])) < 1e-9


@pytest.mark.parametrize("name", NAMES)
def test_physics_alone_misses_the_hidden_effect(generated, name):
    data = generated[name][1]
    eq = data.hidden_effect["equation"]
    residual = _hidden_residual(data)[:, eq]
    assert np.max(np.abs(residual)) / np.std(np.diff(data.x[:, eq])) > 0.1
    np.testing.assert_allclose(
        residual, data.hidden_effect["function"](data.x[:-1], data.u[:-1]), atol=1e-9
    )


@pytest.mark.parametrize("name", NAMES)
def test_hidden_effect_description(generated, name):
    data = generated[name][0]
    effect = data.hidden_effect
    names = set(data.physics.state_names) | set(data.physics.input_names)
    assert set(effect["variables"]) <= names and effect["description"]
    eq = effect["equation"]
    x, u = data.x[:-1], data.u[:-1]
    np.testing.assert_array_equal(effect["function"](x, u), effect["state_function"](x, u)[:, eq])
    assert effect["sign"] == np.sign(np.sum(effect["function"](x, u) * x[:, eq]))
    assert effect["function"](x[0], u[0]).shape == ()


@pytest.mark.parametrize("name", NAMES)
def test_suggested_library_represents_the_hidden_effect(generated, name):
    data = generated[name][1]
    library = data.suggested_library
    features = np.hstack([data.x, data.u])[:-1]
    theta = np.asarray(library.fit(features).transform(features))
    assert theta.shape[1] <= 25
    residual = _hidden_residual(data)[:, data.hidden_effect["equation"]]
    coef, *_ = np.linalg.lstsq(theta, residual, rcond=None)
    explained = 1 - np.sum((theta @ coef - residual) ** 2) / np.sum(
        (residual - residual.mean()) ** 2
    )
    assert explained > EXPLAINED.get(name, 1 - 1e-9)  # exact unless approximated
    model = ps.DiscreteSINDy(feature_library=library, optimizer=ps.STLSQ(threshold=1e-3))
    model.fit(data.x, t=1, u=data.u)
    assert model.coefficients().shape == (data.x.shape[1], theta.shape[1])


@pytest.mark.parametrize("name", NAMES)
def test_custom_library_functions_accept_jax_arrays(generated, name):
    library = generated[name][0].suggested_library
    customs = getattr(library, "libraries", [library])
    values = np.linspace(-1.0, 11.0, 7)
    for custom in (lib for lib in customs if isinstance(lib, ps.CustomLibrary)):
        for function in custom.functions:
            args = [values + i for i in range(function.__code__.co_argcount)]
            with jax.enable_x64(True):
                traced = jax.jit(function)(*[jnp.asarray(a) for a in args])
            np.testing.assert_allclose(traced, function(*args), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_generator_output_pickles(generated, name):
    data = generated[name][0]
    clone = pickle.loads(pickle.dumps(data))
    x, u = data.x[:5], data.u[:5]
    np.testing.assert_array_equal(
        clone.hidden_effect["state_function"](x, u), data.hidden_effect["state_function"](x, u)
    )
    assert clone.physics.step == data.physics.step


def test_generators_validate_arguments():
    with pytest.raises(ValueError, match="n_samples"):
        make_leaky_tank(n_samples=1)
    with pytest.raises(ValueError, match="noise_std"):
        make_friction_oscillator(noise_std=-1.0)
    with pytest.raises(ValueError, match="noise_bound"):
        make_vehicle_lateral(noise_bound=float("nan"))


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"noise_std": "abc"}, TypeError, "noise_std must be a finite number >= 0, got 'abc'"),
        ({"noise_std": True}, TypeError, "noise_std"),
        ({"process_noise_std": "0.1"}, TypeError, "process_noise_std"),
        ({"random_state": "x"}, ValueError, "random_state must be None, an int"),
        ({"random_state": -1}, ValueError, "random_state"),
        ({"overflow_fraction": 2.0}, ValueError, r"overflow_fraction must be a number in \[0, 1\]"),
        ({"overflow_fraction": -0.1}, ValueError, "overflow_fraction"),
        ({"overflow_fraction": "half"}, TypeError, "overflow_fraction"),
    ],
)
def test_tanks_arguments_are_refused_by_name(kwargs, error, match):
    with pytest.raises(error, match=match):
        make_cascaded_tanks(n_samples=50, **kwargs)


@pytest.mark.parametrize("name", NAMES)
def test_every_generator_names_a_bad_seed_and_noise(name):
    noise = "noise_bound" if name == "vehicle" else "noise_std"
    with pytest.raises(ValueError, match="random_state"):
        GENERATORS[name](n_samples=50, random_state="x")
    with pytest.raises(TypeError, match=noise):
        GENERATORS[name](n_samples=50, **{noise: "abc"})


@pytest.mark.parametrize("fraction", [0.0, 1.0])
def test_an_overflow_fraction_at_either_end_is_accepted(fraction):
    data = make_cascaded_tanks(n_samples=50, overflow_fraction=fraction, random_state=0)
    assert data.hidden_effect["function"].params["fraction"] == fraction


def test_process_noise_is_recorded():
    data = make_leaky_tank(n_samples=200, process_noise_std=0.01, random_state=3)
    w = data.noise["process_noise"]
    assert w.shape == (199, 1) and np.std(w) > 0
    predicted = _physics_next(data, data.x[:-1], data.u[:-1])
    predicted += data.hidden_effect["state_function"](data.x[:-1], data.u[:-1]) + w
    np.testing.assert_allclose(predicted, data.x[1:], atol=1e-9)


# --------------------------------------------------------------------------------------
# System-specific checks
# --------------------------------------------------------------------------------------


def test_vehicle_index_convention(generated):
    data = generated["vehicle"][0]
    x, u = data.x, data.u
    np.testing.assert_array_equal(x[1:, 1], x[:-1, 0])  # x2 = y_(k-1)
    np.testing.assert_array_equal(x[1:, 2], u[:-1, 0])  # x3 = s_k, delivered by u_(k-1)
    np.testing.assert_array_equal(x[1:, 3], x[:-1, 2])
    np.testing.assert_array_equal(x[1:, 4], u[:-1, 1])
    np.testing.assert_array_equal(x[1:, 5], x[:-1, 4])
    speed = 1.0 / u[:, 1]
    assert speed.min() >= 12.0 - 1e-9 and speed.max() <= 28.0 + 1e-9


def test_vehicle_dictionary_reproduces_delta(generated):
    data = generated["vehicle"][1]
    library = data.suggested_library
    v = np.hstack([data.x, data.u])
    theta = np.asarray(library.fit(v).transform(v))
    names = library.get_feature_names(data.physics.state_names + data.physics.input_names)
    expected = ["1", "x3", "x4", "x5", "x6", "x3^2", "x4^2", "x5^2"]
    assert names == expected + ["x4 x6", "x1 x6", "x2 x6", "x2 x6^2"]
    np.testing.assert_array_equal(data.true_omega[:9], 0.0)
    np.testing.assert_array_equal(data.true_omega[9:], [-9.625, 10.69, -11.52])
    delta = data.hidden_effect["function"](data.x, data.u)
    np.testing.assert_allclose(theta @ data.true_omega, delta, atol=1e-15)
    np.testing.assert_allclose(_hidden_residual(data)[:, 0], delta[:-1], atol=1e-12)
    pairs = data.dictionary_functions
    assert [n for n, _ in pairs] == names
    np.testing.assert_allclose(np.column_stack([f(v) for _, f in pairs]), theta)
    with jax.enable_x64(True):
        np.testing.assert_allclose(pairs[-1][1](jnp.asarray(v)), theta[:, -1], rtol=1e-14)


def test_vehicle_physics_alone_is_unstable(generated):
    data = generated["vehicle"][1]
    x = data.true_x0
    with jax.enable_x64(True):
        for k in range(400):
            x = data.physics.step(x, data.u[k], data.true_parameters)
    assert abs(float(x[0])) > 100 * np.max(np.abs(data.x[:, 0]))
    with pytest.warns(RuntimeWarning, match="unstable"):
        control = make_vehicle_lateral(n_samples=400, include_delta=False, random_state=0)
    assert control.hidden_effect is None and not np.any(control.true_omega)


def test_synthetic_tanks_overflow_and_saturation(generated):
    data = generated["tanks"][1]
    assert np.isclose(data.x[:, 0].max(), 10.0) and np.isclose(data.x[:, 1].max(), 10.0)
    residual = _hidden_residual(data)
    assert 0.01 < np.mean(residual[:, 0] < 0) < 0.2  # overflow on a few percent of steps
    assert np.all(residual[:, 0] <= 1e-12)
    np.testing.assert_array_equal(data.x[0], data.x_val[0])  # shared initial state
    plain = make_cascaded_tanks(n_samples=300, overflow=False, saturation=False, random_state=0)
    assert plain.hidden_effect is None
    assert np.max(np.abs(_hidden_residual(plain))) < 1e-12
