"""Tests of reading a correction back into the declared physics: which declared constant
varies with which variable, by which closed form (`read_varying_parameters`)."""

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest

from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel
from sk_offwhite.datasets._varying import (
    make_hardening_spring,
    make_piezoviscous_bearing,
    make_saturating_inductor,
    make_valve_tank,
)
from sk_offwhite.loop._reading import FAMILIES, VaryingReading, read_varying_parameters

GENERATORS = {
    "spring": make_hardening_spring,
    "inductor": make_saturating_inductor,
    "valve": make_valve_tank,
    "bearing": make_piezoviscous_bearing,
}
N = 600
FITS = {  # settings of the end-to-end fits (gamma as fit_gamma_path(cv=3) chooses it)
    "spring": {"gamma": 4.8e-3, "delta_states": [1]},
    "inductor": {"gamma": 5.2e-4},
    "valve": {"gamma": 1.9e-5},
    "bearing": {"gamma": 1.5e-4},
}
SLOW = ("valve", "bearing")


@pytest.fixture(scope="module")
def generated():
    return {name: make(n_samples=N, random_state=0) for name, make in GENERATORS.items()}


def exact_correction(data, states=None, inputs=None) -> np.ndarray:
    """`f_true - f_declared` at the true parameters along the true trajectory."""
    states = data.x_est if states is None else states
    inputs = data.u_est if inputs is None else inputs
    with jax.enable_x64(True):
        steps = [jax.vmap(p.step, in_axes=(0, 0, None)) for p in (data.true_physics, data.physics)]
        x, u = jnp.asarray(states), jnp.asarray(inputs)
        true_next, declared_next = (step(x, u, data.true_parameters) for step in steps)
    return np.asarray(true_next - declared_next)


@pytest.fixture(scope="module")
def exact_readings(generated):
    return {
        name: read_varying_parameters(
            data.physics, data.true_parameters, data.x_est, data.u_est, exact_correction(data)
        )
        for name, data in generated.items()
    }


def law_at(data, v) -> np.ndarray:
    r"""The true law $\theta_j(v)$ from the ground truth's words."""
    varying = data.varying
    theta = data.true_parameters[varying["parameter"]]
    scaled = np.asarray(v) / varying["constants"]["x_s"]
    family = varying["family"]
    if family == "polynomial":
        return theta * (1 + scaled**2)
    if family == "rational":
        return theta / (1 + scaled**2)
    if family == "power":
        return theta * np.abs(scaled) ** varying["constants"]["p"]
    return theta * np.exp(scaled)


def assert_names_the_law(reading: VaryingReading, data, tolerance: float) -> None:
    """Parameter, variable, family and sign as the truth's; constants within `tolerance`;
    the law itself within `tolerance` at the truth's scale."""
    varying = data.varying
    found = (reading.parameter, reading.variable, reading.family, reading.sign)
    assert found == tuple(varying[key] for key in ("parameter", "variable", "family", "sign"))
    x_s = varying["constants"]["x_s"]
    np.testing.assert_allclose(reading.law(x_s), law_at(data, x_s), rtol=tolerance)
    if reading.family == "power":  # its scale depends on the coefficient it is read with
        np.testing.assert_allclose(reading.constants["p"], varying["constants"]["p"],
                                   rtol=tolerance)  # fmt: skip
    else:
        np.testing.assert_allclose(reading.constants["x_s"], x_s, rtol=tolerance)
        true_value = data.true_parameters[varying["parameter"]]
        np.testing.assert_allclose(reading.value, true_value, rtol=1.5 * tolerance)


# --------------------------------------------------------------------------------------
# On the exact correction
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(GENERATORS))
def test_reads_the_exact_correction(generated, exact_readings, name):
    readings = exact_readings[name]
    assert readings, "no reading counts"
    assert_names_the_law(readings[0], generated[name], tolerance=0.02)
    assert readings[0].explained > 0.9999
    explained = [reading.explained for reading in readings]
    assert explained == sorted(explained, reverse=True)
    assert all(reading.explained >= 0.9 for reading in readings)


def test_sentence_says_the_law(exact_readings):
    spring, inductor = exact_readings["spring"][0], exact_readings["inductor"][0]
    assert spring.sentence.startswith("the stiffness k depends on the position q: k(q) = 20·(1 +")
    assert "hardening; explains 100.0 % of δ" in spring.sentence
    assert inductor.formula == "L(i) = 0.05/(1 + (i/1)²)" and "falling" in inductor.sentence
    assert spring.formula == "k(q) = 20·(1 + (q/0.04)²)"


def test_first_order_alone_would_misread_the_inductor(generated):
    """A coefficient that divides the rate: to first order the saturating inductance is a
    polynomial that falls with $i^2$; the exact substitution reads it as rational, and its
    polynomial explains clearly less."""
    data = generated["inductor"]
    correction = exact_correction(data)
    with jax.enable_x64(True):
        jacobian = jax.vmap(jax.jacfwd(data.physics.step, argnums=2), in_axes=(0, 0, None))
        theta = data.true_parameters
        direction = np.asarray(jacobian(data.x_est, data.u_est, theta)["L"]) * theta["L"]
    columns = np.hstack([direction, direction * data.x_est**2])
    (offset, curvature), *_ = np.linalg.lstsq(columns, correction[:, 0], rcond=None)
    first_order = correction[:, 0] - columns @ [offset, curvature]
    assert curvature < 0 and np.sum(first_order**2) < 1e-2 * np.sum(correction**2)
    readings = read_varying_parameters(data.physics, theta, data.x_est, data.u_est,
                                       correction, min_explained=0.0)  # fmt: skip
    by_family = {r.family: r for r in readings if (r.parameter, r.variable) == ("L", "i")}
    assert by_family["rational"].explained > 0.9999
    assert by_family.get("polynomial") is None or by_family["polynomial"].explained < 0.99


def _rescaled(physics: PhysicsModel, state_scale, input_scale) -> PhysicsModel:
    """The same model in other units: `x' = S x`, `u' = C u`."""
    state_scale, input_scale = np.asarray(state_scale), np.asarray(input_scale)

    def rhs(x, u, theta):
        return state_scale * physics.rhs(x / state_scale, u / input_scale, theta)

    return PhysicsModel.from_ode(
        rhs, physics.sampling_time, output=0, parameters=physics.parameters,
        n_states=physics.n_states, n_inputs=physics.n_inputs, method=physics.method,
        state_names=physics.state_names, input_names=physics.input_names,
        state_kinds=physics.state_kinds, input_kinds=physics.input_kinds,
    )  # fmt: skip


@pytest.mark.parametrize(
    ("name", "state_scale", "input_scale"),
    [("spring", (1e3, 1e3), (1e-3,)), ("bearing", (60 / (2 * np.pi),), (1e3, 1e-6))],
)
def test_units_do_not_change_the_reading(generated, exact_readings, name, state_scale,
                                         input_scale):  # fmt: skip
    """Millimetres and kilonewtons, rpm and megapascals: the same readings in the same
    order, the scales in the new units."""
    data = generated[name]
    physics = _rescaled(data.physics, state_scale, input_scale)
    states, inputs = data.x_est * state_scale, data.u_est * input_scale
    correction = exact_correction(data) * np.asarray(state_scale)
    readings = read_varying_parameters(physics, data.true_parameters, states, inputs, correction)
    before = exact_readings[name]
    assert [(r.parameter, r.variable, r.family) for r in readings] == [
        (r.parameter, r.variable, r.family) for r in before
    ]
    np.testing.assert_allclose([r.explained for r in readings], [r.explained for r in before],
                               atol=1e-6)  # fmt: skip
    names = list(physics.state_names + physics.input_names)
    scale = np.concatenate([state_scale, input_scale])[names.index(before[0].variable)]
    np.testing.assert_allclose(readings[0].constants["x_s"], before[0].constants["x_s"] * scale,
                               rtol=1e-6)  # fmt: skip


def _euler_spring(law: bool):
    """A discrete-time (not `from_ode`) spring, its stiffness hardening when `law`."""

    def step(x, u, theta):
        stiffness = theta["k"] * (1 + (x[0] / 0.05) ** 2) if law else theta["k"]
        accel = (u[0] - theta["c"] * x[1] - stiffness * x[0]) / theta["m"]
        return jnp.stack([x[0] + 0.01 * x[1], x[1] + 0.01 * accel])

    parameters = {"m": Parameter(0.5, fixed=True), "c": 0.6, "k": 20.0}
    return PhysicsModel(step, 0, parameters, 2, 1, state_names=("q", "v"),
                        state_kinds=("position", "velocity"))  # fmt: skip


def test_reads_a_discrete_step(generated):
    """The law substituted at the sample of a discrete step."""
    data = generated["spring"]
    theta = {"m": 0.5, "c": 0.6, "k": 20.0}
    declared, true = _euler_spring(False), _euler_spring(True)
    with jax.enable_x64(True):
        x, u = jnp.asarray(data.x_est), jnp.asarray(data.u_est)
        nexts = [jax.vmap(p.step, in_axes=(0, 0, None))(x, u, theta) for p in (true, declared)]
    correction = np.asarray(nexts[0] - nexts[1])
    first = read_varying_parameters(declared, theta, data.x_est, data.u_est, correction)[0]
    assert (first.parameter, first.variable, first.family, first.sign) == (
        "k",
        "q",
        "polynomial",
        "hardening",
    )
    np.testing.assert_allclose(first.constants["x_s"], 0.05, rtol=1e-6)


def test_no_law_no_reading(generated):
    """A constant error of a parameter, or noise, is not a varying law."""
    data = generated["spring"]
    off = {**data.true_parameters, "k": 1.1 * data.true_parameters["k"]}
    with jax.enable_x64(True):
        step = jax.vmap(data.physics.step, in_axes=(0, 0, None))
        x, u = jnp.asarray(data.x_est), jnp.asarray(data.u_est)
        constant = np.asarray(step(x, u, off) - step(x, u, data.true_parameters))
    args = (data.physics, data.true_parameters, data.x_est, data.u_est)
    assert read_varying_parameters(*args, constant) == []
    noise = np.random.default_rng(0).normal(size=constant.shape) * np.abs(constant).max()
    assert read_varying_parameters(*args, noise) == []
    assert read_varying_parameters(*args, np.zeros_like(constant)) == []


def test_threshold(generated, exact_readings):
    """A law buried in as much unrelated correction explains about half: it does not count,
    unless asked for."""
    data = generated["inductor"]
    exact = exact_correction(data)
    noise = np.random.default_rng(1).normal(size=exact.shape) * exact.std()
    args = (data.physics, data.true_parameters, data.x_est, data.u_est, exact + noise)
    assert read_varying_parameters(*args) == []
    kept = read_varying_parameters(*args, min_explained=0.0, families=["rational"])
    assert kept[0].family == "rational" and 0.3 < kept[0].explained < 0.7


def test_arguments_checked(generated):
    data = generated["inductor"]
    args = (data.physics, data.true_parameters, data.x_est, data.u_est)
    correction = exact_correction(data)
    with pytest.raises(ValueError, match="columns"):
        read_varying_parameters(*args, np.zeros((N, 2)))
    with pytest.raises(KeyError, match="R"):
        read_varying_parameters(data.physics, {"L": 0.05}, data.x_est, data.u_est, correction)
    with pytest.raises(ValueError, match="families"):
        read_varying_parameters(*args, correction, families=["cubic"])
    with pytest.raises(ValueError, match="declared"):
        read_varying_parameters(*args, correction, variables=["T"])
    only = read_varying_parameters(*args, correction, variables=["V"], parameters=["R"])
    assert all((r.variable, r.parameter) == ("V", "R") for r in only)
    assert set(FAMILIES) == {"polynomial", "rational", "power", "exponential"}


# --------------------------------------------------------------------------------------
# End to end: declared physics + sparse correction, then the reading
# --------------------------------------------------------------------------------------


def _fitted_reading(data, settings) -> list:
    est = GreyBoxSparseRegressor(data.physics, library=ps.PolynomialLibrary(degree=3), **settings)
    est.fit(data.u_est, data.z_est)
    run = est.simulate(data.u_est)
    return read_varying_parameters(data.physics, est.parameters_, run.states, data.u_est,
                                   run.correction)  # fmt: skip


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in GENERATORS],
)
def test_reads_the_fitted_correction(generated, name):
    """`simulate(u).correction` of a fit on the noisy estimation record names the law."""
    readings = _fitted_reading(generated[name], FITS[name])
    assert readings, "no reading counts"
    assert_names_the_law(readings[0], generated[name], tolerance=0.1)
