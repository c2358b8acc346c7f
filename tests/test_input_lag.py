"""InputLag, an actuator's first-order lag with a hidden state: the law, its units, the
lagged-drive generator, where the loop proposes it (inputs the residual correlates with),
a direct fit, and the closed loop on a short record (the full-length run is the
``lagged_drive`` row of ``benchmarks/bench_loop_generators.py``).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import GreyBoxSparseRegressor, InputLag, SensorLag, augment, switched
from sk_offwhite.datasets import lagged_command, make_lagged_drive, make_lagged_heater
from sk_offwhite.datasets._lag import DRIVE_DT, DRIVE_LAG, DRIVE_THETA
from sk_offwhite.datasets._synthetic import _first_order_physics, motor_rhs
from sk_offwhite.diagnose import correlated_inputs
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._hypotheses import Hypothesis
from sk_offwhite.model._kinds import Kinds


@pytest.fixture(scope="module")
def drive():
    return make_lagged_drive(n_samples=600, random_state=1)


def _advance(effect, output, command, time_constant):
    with jax.enable_x64(True):
        theta = {f"{effect.name}_time_constant": jnp.asarray(time_constant)}
        seen, hidden = effect.advance(jnp.array([output]), jnp.array([command]), theta)
        return float(seen[0]), float(hidden[0])


def test_the_lag_adds_a_free_hidden_state_of_the_inputs_kind(drive):
    model = augment(drive.physics, InputLag(0, 0.1, sampling_time=DRIVE_DT, initial=0.3))
    assert model.n_states == 2 and model.n_declared_states == 1
    assert model.state_names == ("omega", "lag_output")
    assert model.state_kinds == ("rate", "voltage")
    np.testing.assert_array_equal(model.x0, [0.0, 0.3])
    assert list(model.parameters)[-1] == "lag_time_constant"
    assert model.parameters["lag_time_constant"].bounds[0] > 0


def test_the_lag_is_the_exact_first_order_response_to_a_held_step():
    tau, ts = 0.3, 0.1
    effect = InputLag(0, tau, sampling_time=ts)
    output, means = 0.0, []
    for _ in range(20):
        seen, output = _advance(effect, output, 1.0, tau)
        means.append(seen)
    t = ts * np.arange(21)
    exact = 1.0 - np.exp(-t / tau)
    assert output == pytest.approx(exact[-1], rel=1e-12)
    mean_over_sample = 1.0 - tau / ts * (np.exp(-t[:-1] / tau) - np.exp(-t[1:] / tau))
    np.testing.assert_allclose(means, mean_over_sample, rtol=1e-12)
    np.testing.assert_allclose(means, lagged_command(np.ones(20), tau, ts, start=0.0), rtol=1e-12)


def test_a_short_lag_is_the_command_and_a_long_one_holds_its_output():
    effect = InputLag(0, 1.0)
    seen, output = _advance(effect, 0.2, 1.5, 1e-9)
    assert seen == pytest.approx(1.5, abs=1e-8) and output == pytest.approx(1.5)
    seen, output = _advance(effect, 0.2, 1.5, 1e9)
    assert seen == pytest.approx(0.2, abs=1e-8) and output == pytest.approx(0.2, abs=1e-8)


def test_the_lag_does_not_depend_on_the_unit_of_time():
    seconds = _advance(InputLag(0, 0.15, sampling_time=0.05), 0.4, -1.0, 0.15)
    milliseconds = _advance(InputLag(0, 150.0, sampling_time=50.0), 0.4, -1.0, 150.0)
    np.testing.assert_allclose(seconds, milliseconds, rtol=1e-13)


def test_a_switched_off_lag_is_the_declared_model(drive):
    model = augment(drive.physics, switched(InputLag(0, 0.1, sampling_time=DRIVE_DT)))
    theta = {"a": 2.0, "b": 4.0, "lag_time_constant": 0.1, "lag_on": 0.0}
    with jax.enable_x64(True):
        x = jnp.array([0.5, -0.7])
        step = model.step(x, jnp.array([1.2]), theta)
        declared = drive.physics.step(x[:1], jnp.array([1.2]), theta)
    np.testing.assert_allclose(step, [float(declared[0]), -0.7])


def test_a_record_starts_the_lag_at_its_first_command_within_the_inputs_range():
    effect = InputLag(0, 0.1)
    assert effect.hidden_start([9.0], np.array([0.25]), {}) == (0.25,)
    np.testing.assert_allclose(effect.hidden_bounds(np.array([[0.1], [0.4]])), [[-0.2, 0.7]])
    assert effect.hidden_bounds(np.full((4, 1), 2.0)) == ((-np.inf, np.inf),)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"time_constant": 0.0}, "time_constant"),
        ({"time_constant": float("nan")}, "time_constant"),
        ({"time_constant": 1.0, "sampling_time": -1.0}, "sampling_time"),
    ],
)
@pytest.mark.parametrize("lag", [InputLag, SensorLag])
def test_the_lags_arguments_are_validated(lag, kwargs, match):
    with pytest.raises(ValueError, match=match):
        lag(0, **kwargs)


def test_the_generator_drives_the_motor_with_the_lagged_command():
    data = make_lagged_drive(n_samples=300, random_state=2, noise_std=0.0)
    again = make_lagged_drive(n_samples=300, random_state=2, noise_std=0.0)
    np.testing.assert_array_equal(data.z, again.z)
    np.testing.assert_array_equal(data.z, data.x)
    seen = data.hidden_effect["seen"]
    np.testing.assert_array_equal(seen, lagged_command(data.u[:, 0], DRIVE_LAG, DRIVE_DT))
    with jax.enable_x64(True):
        theta = {k: jnp.asarray(v) for k, v in data.true_parameters.items()}
        step = jax.vmap(data.physics.step, in_axes=(0, 0, None))
        predicted = np.asarray(step(jnp.asarray(data.x[:-1]), jnp.asarray(seen[:-1, None]), theta))
    np.testing.assert_allclose(predicted, data.x[1:], atol=1e-12)
    contribution = DRIVE_DT * DRIVE_THETA["b"] * (seen[:-1] - data.u[:-1, 0])
    np.testing.assert_allclose(data.hidden_effect["contribution"], contribution)
    assert data.kinds == {"states": ("rate",), "inputs": ("voltage",)}
    assert data.hidden_effect["rates"] == {"time_constant": DRIVE_LAG}
    assert data.hidden_effect["variables"] == ("u",)
    with pytest.raises(ValueError, match="noise_std"):
        make_lagged_drive(n_samples=10, noise_std=-1.0)


def test_the_heater_generator_heats_the_block_with_the_lagged_power():
    data = make_lagged_heater(n_samples=300, random_state=2, noise_std=0.0)
    seen = data.hidden_effect["seen"]
    np.testing.assert_array_equal(seen, lagged_command(data.u[:, 0], 30.0, data.sampling_time))
    assert data.u.min() >= 0.0 and data.x[0, 0] == pytest.approx(295.0 + 45.0 / 2.5)
    with jax.enable_x64(True):
        theta = {k: jnp.asarray(v) for k, v in data.true_parameters.items()}
        step = jax.vmap(data.physics.step, in_axes=(0, 0, None))
        predicted = np.asarray(step(jnp.asarray(data.x[:-1]), jnp.asarray(seen[:-1, None]), theta))
    np.testing.assert_allclose(predicted, data.x[1:], rtol=1e-13)
    capacity = data.true_parameters["capacity"]
    contribution = data.sampling_time * (seen[:-1] - data.u[:-1, 0]) / capacity
    np.testing.assert_allclose(data.hidden_effect["contribution"], contribution)
    assert data.kinds == {"states": ("temperature",), "inputs": ("generic",)}
    assert data.hidden_effect["rates"] == {"time_constant": 30.0}
    assert data.hidden_effect["variables"] == ("P",)  # the physics' name of the input


def test_a_lag_is_proposed_for_each_input_the_residual_correlates_with_that_varies():
    hypothesis = Hypothesis("x", 0, ("x",), -1, None, sentence="x lacks a term.")
    rng = np.random.default_rng(0)
    states = rng.normal(size=(40, 1))
    u = np.c_[rng.normal(size=40), np.full(40, 3.0), rng.normal(size=40)]
    kinds = Kinds(("generic",), ("position", "force", "flow"), {})

    def lags(correlated):
        found = propose_effects([hypothesis], [], ("x",), ["x"], states, u=u,
                                input_names=("s", "f", "q"), kinds=kinds, dt=0.02,
                                correlated_inputs=correlated)  # fmt: skip
        return [c.effect for c in found if isinstance(c.effect, InputLag)]

    assert lags(()) == []
    proposed = lags((0, 1))  # the constant input has no lag to show
    assert [lag.name for lag in proposed] == ["lag_s"]
    assert proposed[0].time_constant == proposed[0].sampling_time == 0.02
    assert proposed[0].initial == u[0, 0]


def test_the_inputs_a_residual_correlates_with_are_named():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(800, 2))
    lagged = np.convolve(u[:, 1], [0.0, 0.5, 0.3, 0.1])[:800]
    residual = np.c_[0.05 * rng.normal(size=800), lagged + 0.05 * rng.normal(size=800)]
    assert correlated_inputs(residual, u) == (1,)
    assert correlated_inputs(residual[:, 0], u) == ()
    residual[3, 1] = np.nan  # a column that cannot be tested names nothing
    assert correlated_inputs(residual, u) == ()
    assert correlated_inputs(np.ones(800), u) == ()


def test_fitting_the_lag_recovers_the_time_constant_and_the_motor(drive):
    model = augment(drive.physics, InputLag(0, DRIVE_DT, sampling_time=DRIVE_DT, name="lag_u"))
    est = GreyBoxSparseRegressor(model, max_iter=100).fit(drive.u, drive.z)
    assert est.parameters_["lag_u_time_constant"] == pytest.approx(DRIVE_LAG, rel=0.02)
    for name, value in DRIVE_THETA.items():
        assert est.parameters_[name] == pytest.approx(value, rel=0.02), name
    declared = GreyBoxSparseRegressor(drive.physics, max_iter=100).fit(drive.u, drive.z)
    window = drive.z_val[:50]
    lagged = np.ravel(est.predict(drive.u_val, z_init=window)) - drive.z_val[:, 0]
    plain = np.ravel(declared.predict(drive.u_val, z_init=window)) - drive.z_val[:, 0]
    assert np.sqrt(np.mean(lagged**2)) < 0.15 * np.sqrt(np.mean(plain**2))


def test_the_lag_fitted_in_milliseconds_is_the_lag_fitted_in_seconds(drive):
    def fitted(scale):  # units of time per second
        rates = {"a": 1.5 / scale, "b": 3.0 / scale}
        names, kinds = ("omega", "u"), ("rate", "voltage")
        physics = _first_order_physics(motor_rhs, rates, (0.0,), DRIVE_DT * scale, names, kinds)
        lag = InputLag(0, DRIVE_DT * scale, sampling_time=DRIVE_DT * scale, name="lag_u")
        est = GreyBoxSparseRegressor(augment(physics, lag), max_iter=100).fit(drive.u, drive.z)
        return est.parameters_

    seconds, milliseconds = fitted(1.0), fitted(1e3)
    assert milliseconds["lag_u_time_constant"] == pytest.approx(
        1e3 * seconds["lag_u_time_constant"], rel=1e-9
    )
    for name in ("a", "b"):
        assert milliseconds[name] == pytest.approx(1e-3 * seconds[name], rel=1e-9)


@pytest.mark.slow
def test_the_loop_names_the_lag_and_recovers_the_motor():
    data = make_lagged_drive(n_samples=400, random_state=0)
    settings = LoopSettings(n_folds=2, max_iter=100, fit_delta=False, max_effects=1)
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    # the motor is linear: a lag of its command and a lag of its speed's reading commute, and
    # only the record's start tells them apart (the loop notes that both fit as well)
    (lag,) = result.effects
    assert isinstance(lag, InputLag | SensorLag) and result.failures == []
    fitted = result.final.parameters_
    assert fitted[f"{lag.name}_time_constant"] == pytest.approx(DRIVE_LAG, rel=0.05)
    for name, value in DRIVE_THETA.items():
        assert fitted[name] == pytest.approx(value, rel=0.05), name
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 0.2 * rmse["declared physics"], rmse
