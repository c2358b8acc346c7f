"""SensorLag, a slow sensor whose reading is a hidden state that follows the declared
output: the law (exact for an output linear over the sample), its units, the output it
reads and the static output effects after it, the generator, the evidence that proposes it
(:func:`~sk_offwhite.diagnose.lagging_outputs`), a direct fit, and the closed loop on a
short record (the full-length run is the ``slow_sensor`` row of
``benchmarks/bench_loop_generators.py``). Its argument checks are the actuator lag's, in
``test_input_lag.py``.
"""

import pickle

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sk_offwhite import (
    GreyBoxSparseRegressor,
    InputLag,
    SensorCalibration,
    SensorLag,
    augment,
    switched,
)
from sk_offwhite._physics import Parameter, PhysicsModel
from sk_offwhite._problem import initial_state_guess
from sk_offwhite.datasets import lagged_reading, make_slow_sensor_tank
from sk_offwhite.datasets._sensor import SENSOR_LAG, SENSOR_THETA, _sensor_tank_physics
from sk_offwhite.datasets._synthetic import POSITIVE, tank_rhs
from sk_offwhite.diagnose import lagging_outputs
from sk_offwhite.effects._lags import sensor_lag_law
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._variants import mechanism, richer


@pytest.fixture(scope="module")
def tank():
    return make_slow_sensor_tank(n_samples=500, random_state=1)


def _lagged(model, x0, u, theta):
    """Outputs of ``model`` simulated from ``x0`` over ``u``, in double precision."""
    with jax.enable_x64(True):
        theta = {k: jnp.asarray(v) for k, v in theta.items()}
        x, out = jnp.asarray(x0, float), []
        for u_k in jnp.asarray(u, float):
            out.append(model.output(x, u_k, theta))
            x = model.step(x, u_k, theta)
        return np.asarray(jnp.stack(out))


@pytest.mark.parametrize("ratio", [0.05, 0.7, 1.0, 4.0, 30.0])
def test_the_law_is_exact_for_an_output_linear_over_the_sample(ratio):
    ts, now, after, start = 0.5, 1.3, -0.4, 2.0

    def rate(t, s):
        y = now + (after - now) * t / ts
        return (y - s) / (ratio * ts)

    exact = solve_ivp(rate, (0.0, ts), [start], rtol=1e-12, atol=1e-12).y[0, -1]
    assert sensor_lag_law(start, now, after, ratio, np) == pytest.approx(exact, abs=1e-9)
    with jax.enable_x64(True):
        assert float(sensor_lag_law(start, now, after, jnp.asarray(ratio))) == pytest.approx(exact)


def test_the_reading_follows_the_level_and_an_instant_sensor_reads_it():
    level = np.sin(np.linspace(0, 6, 50)) + 3.0
    slow = lagged_reading(level, 4.0, 1.0)
    assert slow[0] == level[0] and np.argmax(slow) > np.argmax(level) + 2
    np.testing.assert_allclose(lagged_reading(level, 1e-6, 1.0), level, atol=1e-12)
    np.testing.assert_array_equal(lagged_reading(level[:, None], 4.0, 1.0)[:, 0], slow)


def test_the_model_reads_the_lagged_output_and_simulates_the_generator(tank):
    truth = _sensor_tank_physics(SENSOR_THETA["k"], float(tank.x[0, 0]))
    effect = SensorLag(0, 1.0, initial=float(tank.x[0, 0]), name="slow")
    model = augment(truth, effect)
    assert model.n_states == 2 and model.n_declared_states == 1
    assert model.state_names == ("x", "slow_reading") and model.x0_fixed.tolist() == [0, 0]
    theta = {**SENSOR_THETA, "slow_time_constant": SENSOR_LAG}
    simulated = _lagged(model, model.x0, tank.u, theta)[:, 0]
    np.testing.assert_allclose(simulated, lagged_reading(tank.x[:, 0]), rtol=1e-10)
    np.testing.assert_allclose(tank.z[:, 0] - simulated, tank.noise["output_noise"][:, 0])


def test_the_static_output_effects_read_the_lagged_reading(tank):
    physics = tank.physics
    calibration = SensorCalibration(0, 5.0, 2.0, name="cal")
    model = augment(physics, SensorLag(0, 3.0, name="slow"), calibration)
    theta = {"k": 0.5, "b": 0.5, "slow_time_constant": 3.0, "cal_c0": 0.1, "cal_c1": 1.2}
    theta["cal_c2"] = 0.05
    with jax.enable_x64(True):
        z = model.output(jnp.array([4.0, 7.0]), jnp.array([2.0]), theta)
        read = calibration.apply_output(None, None, jnp.array([7.0]), theta)
    assert float(z[0]) == pytest.approx(float(read[0]))


def test_a_switched_off_sensor_lag_reads_the_declared_output_from_the_second_sample(tank):
    model = augment(tank.physics, switched(SensorLag(0, 4.0, name="slow")))
    theta = {"k": 0.5, "b": 0.5, "slow_time_constant": 4.0, "slow_on": 0.0}
    simulated = _lagged(model, [4.0, 9.0], tank.u[:30], theta)[:, 0]
    declared = _lagged(tank.physics, [4.0], tank.u[:30], theta)[:, 0]
    assert simulated[0] == 9.0
    np.testing.assert_allclose(simulated[1:], declared[1:], rtol=1e-12)


def test_a_record_starts_the_reading_at_its_first_measurement(tank):
    model = augment(tank.physics, SensorLag(0, 1.0, initial=0.0, name="slow"))
    guess = initial_state_guess(model.x0, model, tank.u[0], np.array([6.5]), {})
    np.testing.assert_array_equal(guess, [6.5, 6.5])
    fixed = np.array([False, True])
    kept = initial_state_guess([1.0, 2.0], model, tank.u[0], np.array([6.5]), {}, fixed)
    np.testing.assert_array_equal(kept, [6.5, 2.0])


def test_the_augmented_model_compares_by_value_and_pickles(tank):
    effect = SensorLag(0, 1.0, name="slow")
    model = augment(tank.physics, effect)
    again = augment(tank.physics, SensorLag(0, 1.0, name="slow"))
    assert model.step == again.step and model.output == again.output
    assert hash(model.output) == hash(again.output)
    restored = pickle.loads(pickle.dumps(model))
    assert restored.output == model.output and restored.step == model.step
    assert mechanism(effect) == "dynamics of the sensor of output 0"
    assert richer(effect) is None


def test_the_generator_reads_the_level_through_the_lag():
    data = make_slow_sensor_tank(n_samples=200, random_state=3, noise_std=0.0)
    np.testing.assert_allclose(data.z[:, 0], lagged_reading(data.x[:, 0]))
    assert data.hidden_effect["rates"] == {"time_constant": SENSOR_LAG}
    assert data.hidden_effect["target"] == "output"
    slower = make_slow_sensor_tank(n_samples=200, random_state=3, noise_std=0.0, time_constant=9)
    np.testing.assert_allclose(slower.z[:, 0], lagged_reading(slower.x[:, 0], 9.0))
    with pytest.raises(ValueError, match="time_constant"):
        make_slow_sensor_tank(n_samples=10, time_constant=-1.0)


def test_lagging_outputs_names_an_output_the_reading_lags_and_no_other():
    rng = np.random.default_rng(0)
    t = np.arange(800.0)
    level = np.sin(2 * np.pi * t / 60) + 0.5 * np.sin(2 * np.pi * t / 23)
    noise = 0.02 * rng.normal(size=(t.size, 2))
    measured = np.c_[lagged_reading(level, 3.0), level] + noise
    simulated = np.c_[level, level]
    assert lagging_outputs(measured - simulated, simulated) == (0,)
    assert lagging_outputs(level - lagged_reading(level, 3.0), lagged_reading(level, 3.0)) == ()
    assert lagging_outputs(measured[:, 0] - level, level) == (0,)  # one column, 1-D
    assert lagging_outputs(np.zeros((800, 1)), simulated[:, :1]) == ()  # nothing to test
    assert lagging_outputs(measured[:12] - simulated[:12], simulated[:12]) in ((), (0,), (0, 1))
    with pytest.raises(ValueError, match="outputs"):
        lagging_outputs(measured - simulated, simulated[:10])


def test_a_sensor_lag_is_proposed_for_each_lagging_output():
    states = np.random.default_rng(0).normal(size=(40, 2))
    outputs = states + 5.0
    found = propose_effects(
        [], [], ("x", "y"), ["x", "y"], states, dt=0.5, outputs=outputs, lagging_outputs=(1,)
    )
    lags = [c.effect for c in found if isinstance(c.effect, SensorLag)]
    assert [(e.name, e.output) for e in lags] == [("sensor_lag_y", 1)]
    assert lags[0].time_constant == lags[0].sampling_time == 0.5
    assert lags[0].initial == outputs[0, 1]


def test_fitting_the_sensor_lag_recovers_it_and_the_tank(tank):
    model = augment(tank.physics, SensorLag(0, 1.0, initial=float(tank.z[0, 0]), name="s"))
    est = GreyBoxSparseRegressor(model, max_iter=100).fit(tank.u, tank.z)
    assert est.converged_
    assert est.parameters_["s_time_constant"] == pytest.approx(SENSOR_LAG, rel=0.02)
    assert est.parameters_["k"] == pytest.approx(SENSOR_THETA["k"], rel=0.01)
    residual = np.ravel(est.predict(tank.u_val, z_init=tank.z_val[:50])) - tank.z_val[:, 0]
    assert np.sqrt(np.mean(residual[50:] ** 2)) < 1.1 * tank.noise["output"]["std"]


def _rescaled_tank(scale: float, x0: float):
    """The declared tank with its time in units of ``1 / scale`` seconds."""
    parameters = {
        "k": Parameter(0.4 / scale, POSITIVE),
        "b": Parameter(SENSOR_THETA["b"] / scale, fixed=True),
    }
    return PhysicsModel.from_ode(
        tank_rhs, scale, output=0, parameters=parameters, n_states=1, n_inputs=1,
        method="euler", x0=(x0,),
    )  # fmt: skip


def test_the_sensor_lag_fitted_in_milliseconds_is_the_lag_fitted_in_seconds(tank):
    def fitted(scale):  # units of time per second
        physics = _rescaled_tank(scale, float(tank.z[0, 0]))
        effect = SensorLag(0, scale, sampling_time=scale, initial=float(tank.z[0, 0]), name="s")
        est = GreyBoxSparseRegressor(augment(physics, effect), max_iter=100).fit(tank.u, tank.z)
        return est.parameters_

    seconds, milliseconds = fitted(1.0), fitted(1e3)
    lag = milliseconds["s_time_constant"]
    assert lag == pytest.approx(1e3 * seconds["s_time_constant"], rel=1e-6)
    assert milliseconds["k"] == pytest.approx(1e-3 * seconds["k"], rel=1e-6)


@pytest.mark.slow
def test_the_loop_names_the_slow_sensor_not_the_pump_and_recovers_the_tank():
    data = make_slow_sensor_tank(n_samples=400, random_state=0)
    # every candidate: the pump's hypothesis alone proposes six mechanisms before it
    settings = LoopSettings(n_folds=2, max_iter=100, fit_delta=False, max_effects=1)
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    assert [type(e) for e in result.effects] == [SensorLag] and result.failures == []
    fitted = result.final.parameters_
    assert fitted["sensor_lag_x_time_constant"] == pytest.approx(SENSOR_LAG, rel=0.05)
    assert fitted["k"] == pytest.approx(SENSOR_THETA["k"], rel=0.02)
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 0.1 * rmse["declared physics"], rmse
    assert InputLag not in [type(e) for e in result.effects]


def _pressure(x, u, theta):
    """A declared output map that is no reading of a state: twice the level, plus 1."""
    return jnp.atleast_1d(2.0 * x[0] + 1.0)


def test_a_sensor_lags_an_output_map_that_is_no_reading_of_a_state(tank):
    physics = PhysicsModel.from_ode(
        tank_rhs, 1.0, output=_pressure, parameters={"k": 0.5, "b": 0.5}, n_states=1,
        n_inputs=1, method="euler", x0=(4.0,),
    )  # fmt: skip
    model = augment(physics, SensorLag(0, 3.0, initial=9.0, name="slow"))
    theta = {"k": 0.5, "b": 0.5, "slow_time_constant": 3.0}
    simulated = _lagged(model, model.x0, tank.u[:80], theta)[:, 0]
    declared = _lagged(physics, physics.x0, tank.u[:80], theta)[:, 0]
    np.testing.assert_allclose(simulated, lagged_reading(declared, 3.0), rtol=1e-12)
