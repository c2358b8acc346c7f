"""Tests of the mechanical, thermal and electrical synthetic generators (drive, Duffing,
pendulum, dead-zone motor, coupling with a clearance, heated block, convective block, RC
circuit behind a diode)."""

import pickle

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest

from sk_offwhite.datasets import (
    make_clearance_coupling,
    make_convective_block,
    make_coulomb_drive,
    make_dead_zone_motor,
    make_diode_rc,
    make_duffing_oscillator,
    make_heated_block,
    make_pendulum_drag,
)
from sk_offwhite.effects._terms import signed_power

GENERATORS = {
    "drive": make_coulomb_drive,
    "duffing": make_duffing_oscillator,
    "pendulum": make_pendulum_drag,
    "motor": make_dead_zone_motor,
    "heater": make_heated_block,
    "convection": make_convective_block,
    "diode": make_diode_rc,
    "clearance": make_clearance_coupling,
}
NAMES = list(GENERATORS)
THERMAL = ("heater", "convection")
N = 500
SHAPES = {"drive": (2, 1), "duffing": (2, 1), "pendulum": (2, 1), "motor": (1, 1), "heater": (1, 1),
          "convection": (1, 1), "diode": (1, 1), "clearance": (2, 1)}  # fmt: skip
KINDS = {
    "position", "velocity", "angle", "rate", "force", "voltage", "torque", "temperature",
    "generic",
}  # fmt: skip
BOUNDS = {  # largest |x| per state: well inside Euler's stable region, no rotations
    "drive": (0.1, 5.0),
    "duffing": (np.sqrt(2.0), 5.0),
    "pendulum": (np.pi, 10.0),
    "motor": (8.0,),
    "heater": (340.0,),  # kelvin: absolute temperatures
    "convection": (340.0,),
    "diode": (15.0,),  # volts: never above the source's peaks
    "clearance": (3.0, 40.0),  # the load is jerked from rest at the first samples
}
KEYS = {
    "u", "z", "u_val", "z_val", "x", "x_val", "physics", "true_parameters", "true_x0",
    "true_x0_val", "hidden_effect", "suggested_library", "noise", "sampling_time", "DESCR",
    "state_names", "input_names", "output_names",
}  # fmt: skip
EFFECT_KEYS = {
    "equation", "variables", "sign", "description", "function", "state_function", "rates",
    "kinds",
}  # fmt: skip


@pytest.fixture(scope="module")
def generated():
    """One default and one noise-free data set per generator (same seed)."""
    return {
        name: (make(n_samples=N, random_state=0), make(n_samples=N, noise_std=0.0, random_state=0))
        for name, make in GENERATORS.items()
    }


def _physics_next(data, x, u):
    """``physics.step`` with the true parameters, vectorised, in float64."""
    with jax.enable_x64(True):
        step = jax.vmap(data.physics.step, in_axes=(0, 0, None))
        return np.array(step(jnp.asarray(x), jnp.asarray(u), data.true_parameters))


def _rate(name, rates, x, u):
    """The hidden effect's continuous-time rate rebuilt from ``hidden_effect["rates"]``."""
    if name == "drive":
        return -rates["coulomb"] * np.tanh(x[..., 1] / rates["width"]) + rates["offset"]
    if name == "duffing":
        return -rates["cubic"] * x[..., 0] ** 3
    if name == "pendulum":
        return -rates["quadratic_drag"] * x[..., 1] * np.abs(x[..., 1])
    if name == "heater":
        return -np.maximum(u[..., 0] - rates["limit"], 0.0) / rates["capacity"]
    if name == "convection":
        excess = x[..., 0] - rates["ambient"]
        power = signed_power(excess, 10.0, 1, rates["exponent"], xp=np)
        return -rates["conductance"] * (power - excess) / rates["capacity"]
    if name == "diode":
        drive = u[..., 0] - x[..., 0]
        return (np.maximum(drive - rates["drop"], 0.0) - drive) / rates["tau"]
    if name == "clearance":
        deflection = u[..., 0] - x[..., 0]
        slack = np.sign(deflection) * np.maximum(np.abs(deflection) - rates["gap"], 0.0)
        return rates["k"] * (slack - deflection)
    return -rates["gain"] * np.clip(u[..., 0], -rates["dead_zone"], rates["dead_zone"])


@pytest.mark.parametrize("name", NAMES)
def test_shapes_and_keys(generated, name):
    data = generated[name][0]
    n_x, n_u = SHAPES[name]
    assert KEYS <= set(data) and EFFECT_KEYS <= set(data.hidden_effect)
    for key, shape in (("u", (N, n_u)), ("z", (N, 1)), ("x", (N, n_x))):
        assert data[key].shape == shape and data[key].dtype == np.float64
        assert data[key + "_val"].shape == shape
    assert data.true_x0.shape == (n_x,) and data.true_x0_val.shape == (n_x,)
    np.testing.assert_array_equal(data.x[0], data.true_x0)
    assert set(data.true_parameters) == set(data.physics.parameter_names)
    assert data.physics.n_states == n_x and data.physics.n_inputs == n_u
    assert data.sampling_time == data.physics.sampling_time > 0
    assert data.physics.method == "euler" and data.output_names == data.state_names[:1]
    kinds = data.hidden_effect["kinds"]
    assert len(kinds["states"]) == n_x and len(kinds["inputs"]) == n_u
    assert set(kinds["states"]) | set(kinds["inputs"]) <= KINDS and data.kinds == kinds
    assert isinstance(data.DESCR, str) and data.hidden_effect["description"]


@pytest.mark.parametrize("name", NAMES)
def test_reproducible_with_the_same_seed(generated, name):
    data = generated[name][0]
    again = GENERATORS[name](n_samples=N, random_state=0)
    for key in ("u", "z", "x", "u_val", "z_val", "x_val"):
        np.testing.assert_array_equal(again[key], data[key])
    other = GENERATORS[name](n_samples=50, random_state=1)
    assert not np.allclose(other.u, data.u[:50])
    assert not np.allclose(data.u, data.u_val)


@pytest.mark.parametrize("name", NAMES)
def test_physics_plus_hidden_effect_reproduces_the_states(generated, name):
    data, clean = generated[name]
    np.testing.assert_array_equal(clean.x, data.x)
    np.testing.assert_array_equal(clean.z[:, 0], clean.x[:, 0])
    np.testing.assert_allclose(data.z, data.x[:, :1] + data.noise["output_noise"])
    effect = clean.hidden_effect["state_function"]
    for x, u in ((clean.x, clean.u), (clean.x_val, clean.u_val)):
        predicted = _physics_next(clean, x[:-1], u[:-1]) + effect(x[:-1], u[:-1])
        assert np.max(np.abs(predicted - x[1:])) < 1e-10


@pytest.mark.parametrize("name", NAMES)
def test_trajectories_are_finite_and_bounded(generated, name):
    for x in (generated[name][0].x, generated[name][0].x_val):
        assert np.all(np.isfinite(x))
        assert np.all(np.max(np.abs(x), axis=0) < BOUNDS[name])


@pytest.mark.parametrize("name", NAMES)
def test_hidden_effect_is_a_sizeable_part_of_the_dynamics(generated, name):
    data = generated[name][1]
    effect, eq = data.hidden_effect, data.hidden_effect["equation"]
    x, u = data.x, data.u
    contribution = effect["function"](x[:-1], u[:-1])
    ratio = np.sqrt(np.mean(contribution**2) / np.mean(np.diff(x[:, eq]) ** 2))
    # the diode blocks the reverse current the declared physics would drive: its
    # contribution is larger than the increments it leaves
    assert 0.05 < ratio < (20.0 if name == "diode" else 0.8)
    np.testing.assert_array_equal(contribution, effect["state_function"](x[:-1], u[:-1])[:, eq])
    assert effect["sign"] == np.sign(np.sum(contribution * x[:-1, eq]))
    assert effect["function"](x[0], u[0]).shape == ()


@pytest.mark.parametrize("name", NAMES)
def test_rates_describe_the_hidden_effect(generated, name):
    data = generated[name][1]
    effect, dt = data.hidden_effect, data.sampling_time
    x, u = data.x_val, data.u_val
    rate = _rate(name, effect["rates"], x, u)
    np.testing.assert_allclose(effect["function"](x, u), dt * rate, rtol=1e-12, atol=1e-15)
    others = np.delete(effect["state_function"](x, u), effect["equation"], axis=-1)
    assert not np.any(others)


def test_rates_of_the_drive_away_from_zero_velocity(generated):
    effect, dt = generated["drive"][0].hidden_effect, 1e-3
    rates = effect["rates"]
    assert rates == {"coulomb": 3.0, "offset": 1.5, "width": 0.005}
    for v in (-0.5, 0.2, 1.0):  # v >> eps: full Coulomb force
        got = effect["function"](np.array([0.01, v]), np.array([2.0]))
        assert got == pytest.approx(dt * (-rates["coulomb"] * np.sign(v) + rates["offset"]))


def test_rates_of_the_dead_zone_motor(generated):
    effect = generated["motor"][0].hidden_effect
    dt, (w, b) = 0.05, (effect["rates"]["dead_zone"], effect["rates"]["gain"])
    assert (w, b) == (0.3, 4.0)
    for u in (-0.2, 0.1, 0.7, -2.0):  # dz(u) - u
        dead_zone = np.sign(u) * max(abs(u) - w, 0.0)
        got = effect["function"](np.array([0.5]), np.array([u]))
        assert got == pytest.approx(dt * b * (dead_zone - u))
    assert 0.15 < np.mean(np.abs(generated["motor"][0].u) < w) < 0.5


@pytest.mark.parametrize("name", NAMES)
def test_physics_guess_differs_from_the_truth(generated, name):
    data = generated[name][0]
    names = [p for p in data.physics.parameter_names if p != "ambient"]
    guess = np.array([data.physics.parameters[p].value for p in names])
    truth = np.array([data.true_parameters[p] for p in names])
    assert np.all((np.abs(guess - truth) / truth > 0.15) & (np.abs(guess - truth) / truth < 0.35))
    if name in THERMAL:  # an absolute temperature: a few kelvin off, not a fraction of it
        assert 2.0 < abs(data.physics.parameters["ambient"].value - 295.0) < 10.0


@pytest.mark.parametrize("name", NAMES)
def test_default_output_noise_is_about_one_percent(generated, name):
    data = generated[name][0]
    ratio = data.noise["output"]["std"] / np.std(data.x[:, 0])
    assert 0.003 < ratio < 0.03 and data.noise["process"]["std"] == 0.0


@pytest.mark.parametrize("name", NAMES)
def test_suggested_library_represents_the_hidden_effect(generated, name):
    data = generated[name][1]
    features = np.hstack([data.x, data.u])[:-1]
    theta = np.asarray(data.suggested_library.fit(features).transform(features))
    assert theta.shape[1] <= 25
    target = data.hidden_effect["function"](data.x[:-1], data.u[:-1])
    coef, *_ = np.linalg.lstsq(theta, target, rcond=None)
    explained = 1 - np.sum((theta @ coef - target) ** 2) / np.sum((target - target.mean()) ** 2)
    approximate = ("motor", *THERMAL, "diode", "clearance")  # the library only approximates
    assert explained > (0.8 if name in approximate else 1 - 1e-9)
    customs = getattr(data.suggested_library, "libraries", [])
    for custom in (lib for lib in customs if isinstance(lib, ps.CustomLibrary)):
        for function in custom.functions:
            values = np.linspace(-0.02, 0.02, 7)
            with jax.enable_x64(True):
                traced = jax.jit(function)(jnp.asarray(values))
            np.testing.assert_allclose(traced, function(values), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("name", NAMES)
def test_output_pickles(generated, name):
    data = generated[name][0]
    clone = pickle.loads(pickle.dumps(data))
    x, u = data.x[:5], data.u[:5]
    np.testing.assert_array_equal(
        clone.hidden_effect["state_function"](x, u), data.hidden_effect["state_function"](x, u)
    )
    assert clone.physics.step == data.physics.step
    assert clone.hidden_effect["rates"] == data.hidden_effect["rates"]


def test_process_noise_is_recorded():
    data = make_pendulum_drag(n_samples=200, process_noise_std=0.01, random_state=3)
    w = data.noise["process_noise"]
    assert w.shape == (199, 2) and np.std(w[:, 1]) > 0 and not np.any(w[:, 0])
    predicted = _physics_next(data, data.x[:-1], data.u[:-1])
    predicted += data.hidden_effect["state_function"](data.x[:-1], data.u[:-1]) + w
    np.testing.assert_allclose(predicted, data.x[1:], atol=1e-10)


@pytest.mark.parametrize("make", list(GENERATORS.values()))
def test_arguments_are_validated(make):
    with pytest.raises(ValueError, match="n_samples"):
        make(n_samples=1)
    with pytest.raises(TypeError, match="n_samples"):
        make(n_samples=10.0)
    with pytest.raises(ValueError, match="noise_std"):
        make(n_samples=10, noise_std=-1.0)
    with pytest.raises(ValueError, match="process_noise_std"):
        make(n_samples=10, process_noise_std=float("nan"))


def test_convective_block_declares_a_relaxable_loss_law_on_request(generated):
    data = generated["convection"][0]
    relaxable = make_convective_block(n_samples=N, random_state=0, relaxable=True)
    for key in ("u", "z", "x", "u_val", "z_val", "x_val"):
        np.testing.assert_array_equal(relaxable[key], data[key])
    law = relaxable.physics.parameters["loss_exponent"]
    assert (law.value, law.fixed, law.relaxable, law.bounds) == (1.0, True, True, (0.5, 3.0))
    assert "loss_exponent" not in data.physics.parameters
    x, u, theta = data.x[:-1], data.u[:-1], dict(data.true_parameters)
    linear = _physics_next(data, x, u)
    with jax.enable_x64(True):
        step = jax.vmap(relaxable.physics.step, in_axes=(0, 0, None))
        at_one = np.array(step(jnp.asarray(x), jnp.asarray(u), {**theta, "loss_exponent": 1.0}))
        true_law = {**theta, "loss_exponent": data.hidden_effect["rates"]["exponent"]}
        convective = np.array(step(jnp.asarray(x), jnp.asarray(u), true_law))
    np.testing.assert_allclose(at_one, linear, rtol=0, atol=1e-10)
    np.testing.assert_allclose(convective, data.x[1:], rtol=0, atol=1e-10)
    assert data.hidden_effect["rates"]["exponent"] == pytest.approx(4.0 / 3.0)


@pytest.mark.parametrize("exponent", [0.4, 3.5, float("nan")])
def test_convective_block_exponent_is_validated(exponent):
    with pytest.raises(ValueError, match="exponent"):
        make_convective_block(n_samples=10, exponent=exponent)
