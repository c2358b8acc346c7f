"""Tests of the generators whose declared constant in truth varies with a state or input
(hardening spring, saturating inductor, valve tank, piezoviscous bearing)."""

import pickle

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.datasets._varying import (
    make_hardening_spring,
    make_piezoviscous_bearing,
    make_saturating_inductor,
    make_valve_tank,
)
from sk_offwhite.model._physics import DiscretizedStep

GENERATORS = {
    "spring": make_hardening_spring,
    "inductor": make_saturating_inductor,
    "valve": make_valve_tank,
    "bearing": make_piezoviscous_bearing,
}
NAMES = list(GENERATORS)
N = 600
SHAPES = {"spring": (2, 1), "inductor": (1, 1), "valve": (1, 1), "bearing": (1, 2)}
KINDS = {
    "spring": (("position", "velocity"), ("force",)),
    "inductor": (("current",), ("voltage",)),
    "valve": (("level",), ("generic",)),
    "bearing": (("rate",), ("torque", "generic")),
}
TRUTH = {  # parameter, variable, family of each plant's law
    "spring": ("k", "q", "polynomial"),
    "inductor": ("L", "i", "rational"),
    "valve": ("Cv", "a", "power"),
    "bearing": ("b", "p", "exponential"),
}
KEYS = {
    "u_est", "z_est", "x_est", "u_val", "z_val", "x_val", "physics", "true_physics",
    "true_parameters", "true_x0", "varying", "kinds", "noise", "sampling_time",
    "state_names", "input_names", "output_names", "DESCR",
}  # fmt: skip
SIGNS = {"hardening", "softening", "rising", "falling"}


@pytest.fixture(scope="module")
def generated():
    """One default and one noise-free data set per generator (same seed)."""
    return {
        name: (make(n_samples=N, random_state=0), make(n_samples=N, noise_std=0.0, random_state=0))
        for name, make in GENERATORS.items()
    }


def _factor(varying: dict, v):
    """$g(v)$ written from the ground truth's words alone (not the generator's code)."""
    constants, family = varying["constants"], varying["family"]
    scaled = v / constants["x_s"]
    if family == "polynomial":
        return 1.0 + (1.0 if varying["sign"] in ("hardening", "rising") else -1.0) * scaled**2
    if family == "rational":
        return 1.0 / (1.0 + scaled**2)
    if family == "power":
        return jnp.abs(scaled) ** constants["p"]
    return jnp.exp(scaled)


def _substituted_rhs(data):
    """The declared right-hand side with the ground truth's law substituted."""
    varying, physics = data.varying, data.physics
    names = list(physics.state_names), list(physics.input_names)

    def rhs(x, u, theta):
        v = x[names[0].index(varying["variable"])] if varying["variable"] in names[0] else None
        if v is None:
            v = u[names[1].index(varying["variable"])]
        scaled = {**theta, varying["parameter"]: theta[varying["parameter"]] * _factor(varying, v)}
        return physics.rhs(x, u, scaled)

    return rhs


def _simulate(step, theta, x0, u):
    """`x[k+1] = step(x[k], u[k])` in float64."""
    with jax.enable_x64(True):
        jitted = jax.jit(step)
        x = [np.asarray(x0, float)]
        for k in range(len(u) - 1):
            x.append(np.asarray(jitted(x[-1], u[k], theta)))
    return np.array(x)


@pytest.mark.parametrize("name", NAMES)
def test_shapes_and_keys(generated, name):
    data = generated[name][0]
    n_x, n_u = SHAPES[name]
    assert KEYS <= set(data)
    for record in ("est", "val"):
        for key, shape in (("u", (N, n_u)), ("z", (N, 1)), ("x", (N, n_x))):
            array = data[f"{key}_{record}"]
            assert array.shape == shape and array.dtype == np.float64
            assert np.all(np.isfinite(array))
    assert data.physics.n_states == n_x and data.physics.n_inputs == n_u
    assert data.physics.method == "rk4" and data.true_physics.method == "rk4"
    assert data.sampling_time == data.physics.sampling_time > 0
    assert set(data.true_parameters) == set(data.physics.parameter_names)
    np.testing.assert_array_equal(data.x_est[0], data.true_x0)
    assert data.output_names == data.state_names[:1]


@pytest.mark.parametrize("name", NAMES)
def test_ground_truth_entry(generated, name):
    varying = generated[name][0].varying
    assert (varying["parameter"], varying["variable"], varying["family"]) == TRUTH[name]
    assert varying["sign"] in SIGNS and varying["formula"].startswith(f"{varying['parameter']}(")
    expected = {"x_s", "p"} if varying["family"] == "power" else {"x_s"}
    assert set(varying["constants"]) == expected
    assert all(np.isfinite(value) and value > 0 for value in varying["constants"].values())


@pytest.mark.parametrize("name", NAMES)
def test_kinds_declared(generated, name):
    data = generated[name][0]
    states, inputs = KINDS[name]
    assert data.kinds == {"states": states, "inputs": inputs}
    assert data.physics.state_kinds == states and data.physics.input_kinds == inputs


@pytest.mark.parametrize("name", NAMES)
def test_law_substituted_reproduces_the_records(generated, name):
    """The declared right-hand side with the ground truth's law inside, integrated by the
    declared physics' own RK4, reproduces both noise-free records to rounding; the
    declared constant law does not."""
    data = generated[name][1]
    step = data.physics.step
    truth = DiscretizedStep(_substituted_rhs(data), data.sampling_time, step.method, 1)
    for record in ("est", "val"):
        u, x = data[f"u_{record}"], data[f"x_{record}"]
        np.testing.assert_allclose(_simulate(truth, data.true_parameters, x[0], u), x,
                                   rtol=1e-9, atol=1e-12 * np.abs(x).max())  # fmt: skip
        np.testing.assert_array_equal(data[f"z_{record}"], x[:, :1])
    constant = _simulate(step, data.true_parameters, data.x_est[0], data.u_est)
    assert np.sqrt(np.mean((constant - data.x_est) ** 2)) > 0.05 * data.x_est.std()


@pytest.mark.parametrize("name", NAMES)
def test_noise_and_seeds(generated, name):
    noisy, clean = generated[name]
    np.testing.assert_array_equal(noisy.x_est, clean.x_est)
    error = noisy.z_est - clean.z_est
    std = noisy.noise["output_std"]
    assert std > 0 and 0.85 * std < error.std() < 1.15 * std
    again = GENERATORS[name](n_samples=N, random_state=0)
    np.testing.assert_array_equal(again.z_est, noisy.z_est)
    other = GENERATORS[name](n_samples=N, random_state=1)
    assert not np.allclose(other.u_est, noisy.u_est)
    assert not np.allclose(noisy.u_val, noisy.u_est)  # two realisations of the excitation


def test_physical_ranges(generated):
    spring, inductor, valve, bearing = (generated[name][1] for name in NAMES)
    qs = spring.varying["constants"]["x_s"]
    assert 1.5 * qs < np.abs(spring.x_est[:, 0]).max() < 4 * qs  # the spring hardens
    assert 2 < np.abs(inductor.x_est[:, 0]).max() / inductor.varying["constants"]["x_s"] < 6
    assert valve.u_est.min() >= 0.2 and valve.u_est.max() <= 1.0 and valve.x_est.min() > 0
    assert bearing.u_est[:, 1].min() >= 0.0  # a pressure
    assert bearing.u_est[:, 1].max() > 2.5 * bearing.varying["constants"]["x_s"]


def test_arguments_checked():
    with pytest.raises(ValueError, match="n_samples"):
        make_hardening_spring(n_samples=1)
    with pytest.raises(ValueError, match="noise_std"):
        make_valve_tank(n_samples=50, noise_std=-1.0)
    with pytest.raises(TypeError, match="n_samples"):
        make_saturating_inductor(n_samples=10.5)


def test_process_noise_enters_one_equation():
    clean = make_hardening_spring(n_samples=200, noise_std=0.0, random_state=3)
    noisy = make_hardening_spring(n_samples=200, noise_std=0.0, random_state=3,
                                  process_noise_std=1e-3)  # fmt: skip
    assert not np.allclose(clean.x_est, noisy.x_est)
    np.testing.assert_array_equal(noisy.x_est[:2, 0], clean.x_est[:2, 0])


def test_pickles(generated):
    data = generated["valve"][0]
    copy = pickle.loads(pickle.dumps(data))
    assert copy.true_physics.step == data.true_physics.step
    np.testing.assert_array_equal(copy.z_val, data.z_val)


@pytest.mark.parametrize("name", NAMES)
def test_declared_physics_fails(generated, name):
    """The declared physics' best fit validates far above the noise: the constant cannot
    stand in for the law over the excited range."""
    data, init = generated[name][0], 50
    est = GreyBoxSparseRegressor(data.physics, horizon=50).fit(data.u_est, data.z_est)
    simulated = est.predict(data.u_val, z_init=data.z_val[:init])
    error = np.sqrt(np.mean((simulated.ravel() - data.z_val.ravel())[init:] ** 2))
    assert error > 5 * data.noise["output_std"]
