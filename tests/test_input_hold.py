"""InputHold, the input interpolated linearly between samples (a first-order hold): the law
(exact on an integrator driven by a ramp), the refusals, its composition with an effect
with memory, where the loop proposes it, and a fit on a plant of known parameters driven
by a smooth signal."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sk_offwhite import (
    GreyBoxSparseRegressor,
    InputDelay,
    InputHold,
    Parameter,
    PhysicsModel,
    SensorLag,
    Stiffness,
    augment,
)
from sk_offwhite.fitting._problem import build_model
from sk_offwhite.loop._proposals import input_holds
from sk_offwhite.simulation._rollout import simulate

DT = 0.1


def integrator_rhs(x, u, theta):
    return theta["gain"] * u[:1]


def integrator(**kwargs) -> PhysicsModel:
    """$\\dot x = g u$, RK4, one state measured."""
    return PhysicsModel.from_ode(
        integrator_rhs, DT, output=0, parameters={"gain": 1.0}, n_states=1, n_inputs=1, **kwargs
    )


def outputs(physics, u) -> np.ndarray:
    """The physics' free run from ``x0 = 0`` on ``u``, in double precision."""
    model = build_model(physics, None, ())
    with jax.enable_x64(True):
        params = {"theta": jnp.asarray(physics.parameter_values())}
        _, z, _ = simulate(model, params, jnp.zeros(physics.n_states), jnp.asarray(u, float))
    return np.asarray(z)[:, 0]


def test_a_ramp_integrates_exactly_under_the_linear_hold_and_late_under_the_zero_hold():
    k = np.arange(20.0)
    u = k[:, None]  # u(t) = t / DT, sampled
    exact = DT * k**2 / 2  # the integral of the ramp up to t_k
    held = outputs(integrator(), u)
    linear = outputs(augment(integrator(), InputHold()), u)
    np.testing.assert_allclose(linear, exact, rtol=0, atol=1e-12)
    np.testing.assert_allclose(held, DT * k * (k - 1) / 2, rtol=0, atol=1e-12)


def test_a_physics_declared_with_a_linear_hold_is_the_augmented_one():
    u = np.sin(np.arange(30.0))[:, None]
    declared = outputs(integrator(hold="linear"), u)
    np.testing.assert_allclose(declared, outputs(augment(integrator(), InputHold()), u))


def test_the_hold_is_refused_where_there_is_no_time_between_samples():
    step = PhysicsModel(lambda x, u, th: x + u[:1], 0, {"a": 1.0}, 1, 1)
    with pytest.raises(ValueError, match="from_ode"):
        augment(step, InputHold())
    with pytest.raises(ValueError, match="hold must be one of"):
        integrator(hold="cubic")


def test_an_input_through_an_effect_with_memory_stays_held():
    """A dead time's output is known only up to this sample: it is held, and a dead time
    of almost nothing gives the zero-hold run."""
    u = np.cos(0.7 * np.arange(25.0))[:, None]
    delay = InputDelay(0, 1e-9 * DT, sampling_time=DT, max_delay=DT)
    both = augment(integrator(), InputHold(), delay)
    np.testing.assert_allclose(outputs(both, u), outputs(integrator(), u), atol=1e-8)


def test_a_sensor_that_follows_the_output_reads_the_held_model():
    """A sensor lag of almost no time constant reads what the held model outputs."""
    u = np.sin(0.4 * np.arange(30.0))[:, None]
    lag = SensorLag(0, 1e-6 * DT, sampling_time=DT)
    with_lag = outputs(augment(integrator(), InputHold(), lag), u)
    np.testing.assert_allclose(with_lag, outputs(augment(integrator(), InputHold()), u), atol=1e-6)


def test_the_loop_proposes_the_hold_for_an_input_that_moves_between_samples():
    moving = np.sin(0.3 * np.arange(200.0))[:, None]
    steps = np.repeat(np.sin(0.3 * np.arange(20.0)), 10)[:, None]
    proposed = input_holds(integrator(), moving)
    assert [c.effect for c in proposed] == [InputHold()]
    assert "u" in proposed[0].reason
    assert input_holds(integrator(), steps) == []  # a command in steps repeats its value
    assert input_holds(integrator(hold="linear"), moving) == []  # already declared
    discrete = PhysicsModel(lambda x, u, th: x + u[:1], 0, {"a": 1.0}, 1, 1)
    assert input_holds(discrete, moving) == []


def duffing_rhs(x, u, theta):
    acceleration = u[0] - theta["d"] * x[1] - theta["k"] * x[0]
    return jnp.stack([x[1], acceleration / theta["m"]])


def duffing_record(seed: int, n: int, dt: float):
    """A hardening oscillator ($k_3 = 4$) driven by a smooth multisine, integrated finely
    and sampled every ``dt``."""
    rng = np.random.default_rng(seed)
    freqs, phases = rng.uniform(0.2, 1.5, 8), rng.uniform(0, 2 * np.pi, 8)

    def force(t):
        return 0.4 * np.sum(np.sin(np.outer(t, freqs) + phases), axis=-1)

    def rhs(t, x):
        return [x[1], (force(t)[0] - 0.3 * x[1] - 2.0 * x[0] - 4.0 * x[0] ** 3) / 0.5]

    t = np.arange(n) * dt
    run = solve_ivp(rhs, (0, t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-12)
    return force(t)[:, None], run.y[0][:, None]


def test_the_hold_recovers_the_parameters_of_a_smoothly_driven_hardening_spring():
    dt = 0.2  # about 16 samples per period of the oscillator
    u, z = duffing_record(0, 1000, dt)
    parameters = {"m": Parameter(0.6, (0.01, None)), "d": 0.2, "k": 1.6}
    physics = PhysicsModel.from_ode(
        duffing_rhs, dt, output=0, parameters=parameters, n_states=2, n_inputs=1,
        state_names=("q", "v"), state_kinds=("position", "velocity"),
    )  # fmt: skip
    spring = Stiffness(1, 0, name="k3")
    truth = {"m": 0.5, "d": 0.3, "k": 2.0, "k3_coefficient": 8.0}  # k3 / m in the rate
    fits = {}
    for label, effects in {"zero": (spring,), "linear": (spring, InputHold())}.items():
        est = GreyBoxSparseRegressor(augment(physics, *effects), None, max_iter=200)
        fits[label] = est.fit(u, z).parameters_
    errors = {
        label: max(abs(values[name] / value - 1) for name, value in truth.items())
        for label, values in fits.items()
    }
    assert errors["linear"] < 0.02  # each parameter within 2 % of the truth
    assert errors["zero"] > 0.1  # held, the input reaches the plant half a sample late
