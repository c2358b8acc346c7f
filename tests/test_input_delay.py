"""InputDelay, a dead time of an input with the past commands as hidden states: the law
(the exact mean of the delayed held command), its units, the delayed-plant generators,
where the loop proposes it (beside the lag), a direct fit, and the closed loop on a short
record (the full-length runs are the ``delayed_*`` rows of
``benchmarks/bench_loop_generators.py``).
"""

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest

from sk_offwhite import GreyBoxSparseRegressor, InputDelay, InputLag, augment, switched
from sk_offwhite.datasets import delayed_command, make_delayed_drive, make_delayed_heater
from sk_offwhite.datasets._lag import DRIVE_DELAY, DRIVE_DT, DRIVE_THETA, HEATER_DELAY
from sk_offwhite.datasets._synthetic import _first_order_physics, motor_rhs
from sk_offwhite.effects import HiddenStates
from sk_offwhite.effects._hidden import hidden_start
from sk_offwhite.fitting._problem import free_blocks, initial_blocks
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._hypotheses import Hypothesis
from sk_offwhite.loop._proposals import candidates as _candidates
from sk_offwhite.loop._search import Search
from sk_offwhite.loop._variants import mechanism, richer, richer_start
from sk_offwhite.model._kinds import Kinds
from sk_offwhite.simulation._segments import make_segments


@pytest.fixture(scope="module")
def drive():
    return make_delayed_drive(n_samples=600, random_state=1)


def _seen(effect, commands, delay, past=None):
    """What the declared step sees, sample by sample, through ``effect`` (traceable)."""
    theta = {f"{effect.name}_delay": jnp.asarray(delay)}
    hidden = jnp.full(effect.n_taps, commands[0] if past is None else past)
    seen = []
    for command in commands:
        u, hidden = effect.advance(hidden, jnp.array([command]), theta)
        seen.append(u[0])
    return jnp.stack(seen)


def _run(effect, commands, delay, past=None):
    """:func:`_seen` in double precision, as NumPy."""
    with jax.enable_x64(True):
        return np.asarray(_seen(effect, commands, delay, past))


def _mean_of_delayed_staircase(commands, delay, ts, fine=2000):
    """The mean over each sample of the held command delayed by ``delay``, by quadrature."""
    t = (np.arange(len(commands) * fine) + 0.5) * ts / fine - delay
    index = np.clip(np.floor(t / ts).astype(int), 0, None)
    return commands[index].reshape(len(commands), fine).mean(axis=1)


@pytest.mark.parametrize("delay", [0.0, 0.3, 1.0, 2.4, 3.99])
def test_the_delay_is_the_mean_of_the_delayed_held_command(delay):
    ts = 0.5
    commands = np.random.default_rng(0).normal(size=12)
    exact = _mean_of_delayed_staircase(commands, delay * ts, ts)
    np.testing.assert_allclose(delayed_command(commands, delay * ts, ts), exact, atol=1e-3)
    effect = InputDelay(0, ts, sampling_time=ts, max_delay=4 * ts)
    np.testing.assert_allclose(_run(effect, commands, delay * ts), exact, atol=1e-3)
    np.testing.assert_allclose(
        _run(effect, commands, delay * ts), delayed_command(commands, delay * ts, ts), atol=1e-14
    )


def test_a_delay_of_whole_samples_moves_the_command_and_is_differentiable_there():
    effect = InputDelay(0, 1.0, max_delay=3.0)
    commands = np.array([1.0, 2.0, 4.0, 8.0, 16.0])
    np.testing.assert_allclose(_run(effect, commands, 2.0, past=0.5), [0.5, 0.5, 1, 2, 4])

    with jax.enable_x64(True):
        slope = jax.grad(lambda d: _seen(effect, commands, d)[-1])(jnp.asarray(2.0))
    assert float(slope) == pytest.approx(2.0 - 4.0)  # u_{k-3} - u_{k-2}: the one-sided slope


def test_the_delay_does_not_depend_on_the_unit_of_time():
    commands = np.random.default_rng(1).normal(size=20)
    seconds = _run(InputDelay(0, 0.05, sampling_time=0.05), commands, 0.12)
    milliseconds = _run(InputDelay(0, 50.0, sampling_time=50.0), commands, 120.0)
    np.testing.assert_allclose(seconds, milliseconds, rtol=1e-13)


def test_the_delay_adds_fixed_hidden_states_of_the_inputs_kind(drive):
    effect = InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, initial=0.3, name="delay_u")
    model = augment(drive.physics, effect)
    assert effect.n_taps == 8 and model.n_states == 9 and model.n_declared_states == 1
    assert model.state_names[1:3] == ("delay_u_past_1", "delay_u_past_2")
    assert set(model.state_kinds[1:]) == {"voltage"}
    np.testing.assert_array_equal(model.x0_fixed, [False] + [True] * 8)
    np.testing.assert_array_equal(model.x0[1:], 0.3)
    assert model.parameters["delay_u_delay"].bounds == (0.0, pytest.approx(8 * DRIVE_DT))
    assert InputDelay(0, 3.0).n_taps == 12  # four times a delay longer than two samples


def test_every_record_starts_the_past_commands_at_its_first_command(drive):
    model = augment(drive.physics, InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, max_delay=0.1))
    x0 = hidden_start(model.step, [0.2, 9.0, 9.0], np.array([-0.7]), {}, model.x0_fixed)
    np.testing.assert_array_equal(x0, [0.2, -0.7, -0.7])
    lag = augment(drive.physics, InputLag(0, 0.1))
    kept = hidden_start(lag.step, [0.2, 9.0], np.array([-0.7]), {}, np.array([False, True]))
    np.testing.assert_array_equal(kept, [0.2, 9.0])  # a fixed entry of a free hidden state


def test_a_switched_off_delay_is_the_declared_model(drive):
    model = augment(drive.physics, switched(InputDelay(0, 0.1, sampling_time=DRIVE_DT)))
    theta = {"a": 2.0, "b": 4.0, "delay_delay": 0.1, "delay_on": 0.0}
    with jax.enable_x64(True):
        x = jnp.array([0.5, -0.7, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7])
        step = model.step(x, jnp.array([1.2]), theta)
        declared = drive.physics.step(x[:1], jnp.array([1.2]), theta)
    assert float(step[0]) == pytest.approx(float(declared[0]))


def test_a_switched_delay_keeps_following_the_commands_when_off(drive):
    effect = switched(InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, max_delay=3 * DRIVE_DT))
    assert not effect.hidden_free
    u = drive.u[:6]
    np.testing.assert_array_equal(effect.hidden_path(u, {}), effect.effect.hidden_path(u, {}))
    for on in (0.0, 1.0):
        theta = {"delay_delay": jnp.asarray(DRIVE_DT), "delay_on": jnp.asarray(on)}
        with jax.enable_x64(True):
            seen, memory = effect.advance(jnp.array([0.1, 0.2, 0.3]), jnp.array([0.7]), theta)
        np.testing.assert_allclose(memory, [0.7, 0.1, 0.2])
        assert float(seen[0]) == pytest.approx(0.1 if on else 0.7)


def test_the_richer_delay_reaches_twice_as_far_from_the_fitted_delay():
    effect = InputDelay(0, 0.05, sampling_time=0.05, name="delay_u")
    variant = richer(effect)
    assert variant.name == "delay_u_longer" and variant.n_taps == 2 * effect.n_taps == 16
    assert mechanism(variant) == mechanism(effect)
    assert variant.parameters()["delay_u_longer_delay"].bounds == (0.0, pytest.approx(0.8))
    assert richer_start(effect, {"delay_u_delay": 0.4}) == {"delay_u_longer_delay": 0.4}


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"delay": 0.0}, "delay"),
        ({"delay": float("inf")}, "delay"),
        ({"delay": 1.0, "sampling_time": 0.0}, "sampling_time"),
        ({"delay": 2.0, "max_delay": 1.0}, "max_delay"),
    ],
)
def test_arguments_are_validated(kwargs, match):
    with pytest.raises(ValueError, match=match):
        InputDelay(0, **kwargs)


@pytest.mark.parametrize(
    "make, delay, gain",
    [
        (make_delayed_drive, DRIVE_DELAY, lambda theta: theta["b"]),
        (make_delayed_heater, HEATER_DELAY, lambda theta: 1.0 / theta["capacity"]),
    ],
)
def test_the_generators_drive_the_plant_with_the_delayed_command(make, delay, gain):
    data = make(n_samples=300, random_state=2, noise_std=0.0)
    seen = data.hidden_effect["seen"]
    ts = data.sampling_time
    np.testing.assert_array_equal(seen, delayed_command(data.u[:, 0], delay, ts))
    with jax.enable_x64(True):
        theta = {k: jnp.asarray(v) for k, v in data.true_parameters.items()}
        step = jax.vmap(data.physics.step, in_axes=(0, 0, None))
        predicted = np.asarray(step(jnp.asarray(data.x[:-1]), jnp.asarray(seen[:-1, None]), theta))
    np.testing.assert_allclose(predicted, data.x[1:], rtol=1e-12, atol=1e-12)
    contribution = ts * gain(data.true_parameters) * (seen[:-1] - data.u[:-1, 0])
    np.testing.assert_allclose(data.hidden_effect["contribution"], contribution)
    assert data.hidden_effect["rates"] == {"delay": delay}
    assert data.hidden_effect["variables"] == tuple(data.physics.input_names)
    longer = make(n_samples=300, random_state=2, noise_std=0.0, delay=3 * delay)
    np.testing.assert_array_equal(
        longer.hidden_effect["seen"], delayed_command(longer.u[:, 0], 3 * delay, ts)
    )
    with pytest.raises(ValueError, match="delay"):
        make(n_samples=10, delay=0.0)


def test_a_delay_is_proposed_beside_the_lag_for_each_correlated_input_that_varies():
    hypothesis = Hypothesis("x", 0, ("x",), -1, None, sentence="x lacks a term.")
    rng = np.random.default_rng(0)
    states = rng.normal(size=(40, 1))
    u = np.c_[rng.normal(size=40), np.full(40, 3.0)]
    kinds = Kinds(("generic",), ("position", "force"), {})
    found = propose_effects([hypothesis], [], ("x",), ["x"], states, u=u, input_names=("s", "f"),
                            kinds=kinds, dt=0.02, correlated_inputs=(0, 1))  # fmt: skip
    delays = [c.effect for c in found if isinstance(c.effect, InputDelay)]
    lags = [c.effect for c in found if isinstance(c.effect, InputLag)]
    assert [d.name for d in delays] == ["delay_s"] and [g.name for g in lags] == ["lag_s"]
    assert delays[0].delay == delays[0].sampling_time == 0.02 and delays[0].initial == u[0, 0]
    assert delays[0].n_taps == 25  # the lags over which the residual's correlation was found
    assert mechanism(delays[0]) == mechanism(lags[0])  # variants: at most one in a set


def test_fitting_the_delay_recovers_it_and_the_motor(drive):
    model = augment(drive.physics, InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, name="d"))
    est = GreyBoxSparseRegressor(model, max_iter=100).fit(drive.u, drive.z)
    assert est.converged_
    assert est.parameters_["d_delay"] == pytest.approx(DRIVE_DELAY, rel=0.02)
    for name, value in DRIVE_THETA.items():
        assert est.parameters_[name] == pytest.approx(value, rel=0.01), name
    window = drive.z_val[:50]
    residual = np.ravel(est.predict(drive.u_val, z_init=window)) - drive.z_val[:, 0]
    assert np.sqrt(np.mean(residual[50:] ** 2)) < 1.1 * drive.noise["output"]["std"]


def test_the_delay_fitted_in_milliseconds_is_the_delay_fitted_in_seconds(drive):
    def fitted(scale):  # units of time per second
        rates = {"a": 1.5 / scale, "b": 3.0 / scale}
        names, kinds = ("omega", "u"), ("rate", "voltage")
        physics = _first_order_physics(motor_rhs, rates, (0.0,), DRIVE_DT * scale, names, kinds)
        delay = InputDelay(0, DRIVE_DT * scale, sampling_time=DRIVE_DT * scale, name="d")
        est = GreyBoxSparseRegressor(augment(physics, delay), max_iter=100).fit(drive.u, drive.z)
        return est.parameters_

    seconds, milliseconds = fitted(1.0), fitted(1e3)
    assert milliseconds["d_delay"] == pytest.approx(1e3 * seconds["d_delay"], rel=1e-9)
    for name in ("a", "b"):
        assert milliseconds[name] == pytest.approx(1e-3 * seconds[name], rel=1e-9)


@pytest.mark.slow
def test_the_loop_names_the_dead_time_not_the_lag_and_recovers_the_motor():
    data = make_delayed_drive(n_samples=400, random_state=0)
    settings = LoopSettings(n_folds=2, max_iter=100, fit_delta=False, max_effects=1)
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    assert [type(e) for e in result.effects] == [InputDelay] and result.failures == []
    fitted = result.final.parameters_
    assert fitted["delay_u_delay"] == pytest.approx(DRIVE_DELAY, rel=0.05)
    for name, value in DRIVE_THETA.items():
        assert fitted[name] == pytest.approx(value, rel=0.05), name
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 0.1 * rmse["declared physics"], rmse


def test_the_past_commands_at_every_sample_are_the_commands_before_it():
    effect = InputDelay(0, 1.0, max_delay=3.0)
    u = np.array([[1.0, 0.0], [2.0, 0.0], [4.0, 0.0], [8.0, 0.0], [16.0, 0.0]])
    path = effect.hidden_path(u, {})
    expected = [[1, 1, 1], [1, 1, 1], [2, 1, 1], [4, 2, 1], [8, 4, 2]]
    np.testing.assert_array_equal(path, expected)
    commands = np.random.default_rng(0).normal(size=(300, 1)) * 1e3  # not exact in float32
    longer = InputDelay(0, 1.0, max_delay=25.0)
    stepped = HiddenStates.hidden_path(longer, commands, {"delay_delay": jnp.asarray(1.5)})
    np.testing.assert_array_equal(stepped, longer.hidden_path(commands, {}))  # the default
    assert not jax.config.jax_enable_x64


@pytest.mark.parametrize("wrap", [lambda effect: effect, switched], ids=["plain", "switched"])
def test_shooting_windows_start_the_past_commands_at_the_commands_before_them(drive, wrap):
    effect = wrap(InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, name="d"))
    model = augment(drive.physics, effect)
    est = GreyBoxSparseRegressor(model, horizon=50)
    records = [(drive.u, drive.z)]
    basis, compiled = est._compile(model)
    segments = make_segments(records, 50)
    x0 = initial_blocks(model, basis, compiled, records, segments, 50)["x0"]
    free = free_blocks(model, basis, compiled, segments)["x0"]
    later = np.flatnonzero(np.asarray(segments.linked) != 0)
    assert later.size == len(drive.u) // 50 - 1
    np.testing.assert_array_equal(free, np.tile([True] + [False] * 8, (later.size + 1, 1)))
    for window in later:
        k = 50 * window
        np.testing.assert_array_equal(x0[window, 1:], drive.u[k - 1 : k - 9 : -1, 0])


def test_the_correction_reads_and_corrects_the_declared_states_only(drive):
    model = augment(drive.physics, InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, name="d"))
    library = ps.PolynomialLibrary(degree=2)
    est = GreyBoxSparseRegressor(model, library=library, gamma=1e-3, max_iter=20)
    est.fit(drive.u[:200], drive.z[:200])
    assert est.delta_states_ == (0,) and np.shape(est.coef_) == (1, 6)
    assert est.feature_names_ == ["1", "omega", "u", "omega^2", "omega u", "u^2"]
    assert np.all(np.isfinite(est.predict(drive.u_val[:100])))


def test_multiple_shooting_fits_the_delay_with_the_windows_past_commands_known(drive):
    model = augment(drive.physics, InputDelay(0, DRIVE_DT, sampling_time=DRIVE_DT, name="d"))
    est = GreyBoxSparseRegressor(model, horizon=50, max_iter=100).fit(drive.u, drive.z)
    assert est.converged_ and est.parameters_["d_delay"] == pytest.approx(DRIVE_DELAY, rel=0.05)
    est.set_params(horizon=None, warm_start=True).fit(drive.u, drive.z)
    assert est.parameters_["d_delay"] == pytest.approx(DRIVE_DELAY, rel=0.01)


def test_the_loop_proposes_no_effect_on_the_past_commands_of_a_delay():
    data = make_delayed_heater(n_samples=200, random_state=0)
    delay = InputDelay(0, 2.0, sampling_time=2.0, max_delay=50.0, name="delay_P")
    physics = augment(data.physics, delay)
    run = SimpleNamespace(states=np.c_[data.x, np.repeat(data.u, 25, axis=1)], outputs=data.z)
    found = _candidates(Search(data.u, data.z, LoopSettings()), physics, None, [], [], run)
    targets = [getattr(c.effect, "state", 0) for c in found]
    assert found and max(targets) == 0  # 25 one-signed generic past commands: no levels
    assert not any(isinstance(c.effect, InputDelay | InputLag) for c in found)
