"""A step in a sensor's reading: the jump facts, the effect, its generator, and the loop."""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import SensorCalibration, SensorStep, augment
from sk_offwhite.datasets import make_stepped_sensor_tank, stepped_reading
from sk_offwhite.diagnose import output_jumps
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import propose_effects


def _slow_level(n=600, periods=3.0):
    """A level that crosses 5 (the default step) ``2 * periods`` times, 0.03 per sample
    at most, and a noisy stepped reading of it."""
    rng = np.random.default_rng(0)
    level = 5.0 + 2.0 * np.sin(2 * np.pi * periods * np.arange(n) / n)
    return level, stepped_reading(level) + 0.01 * rng.standard_normal(n)


def test_repeated_jumps_at_one_level_are_a_fact():
    level, reading = _slow_level()
    facts = output_jumps(reading, level, ["x"])
    assert len(facts) == 1
    fact = facts[0]
    assert len(fact.samples) == 6
    assert fact.height == pytest.approx(0.4, abs=0.03)
    assert fact.level == pytest.approx(5.2, abs=0.05)
    assert fact.low <= 5.0 and fact.high >= 5.4
    assert "jumps by 0.4" in fact.sentence and "6 times" in fact.sentence


def test_a_reading_that_steps_down_as_the_level_rises_has_a_negative_height():
    level, _ = _slow_level()
    reading = stepped_reading(level, step_height=-0.4)
    (fact,) = output_jumps(reading, level)
    assert fact.height == pytest.approx(-0.4, abs=0.01)
    assert "stepping down" in fact.sentence


def test_the_facts_follow_the_units_of_the_data():
    level, reading = _slow_level()
    (fact,) = output_jumps(reading, level)
    (scaled,) = output_jumps(1000.0 * reading + 7.0, 1000.0 * level + 7.0)
    assert scaled.samples == fact.samples
    assert scaled.level == pytest.approx(1000.0 * fact.level + 7.0)
    assert scaled.height == pytest.approx(1000.0 * fact.height)


def test_no_fact_without_a_step_from_a_lagging_model_or_from_one_jump():
    level, reading = _slow_level()
    assert output_jumps(level + 0.01, level) == []
    fast = np.concatenate([np.zeros(50), np.linspace(0.0, 5.0, 11), np.full(50, 5.0)])
    catching_up = 5.0 - 3.0 * 0.9 ** np.arange(50)
    lagging = np.concatenate([np.zeros(50), np.linspace(0.0, 2.0, 11), catching_up])
    assert output_jumps(np.tile(fast, 3), np.tile(lagging, 3)) == []
    once = np.where(np.arange(300) < 150, 1.0, 2.0) + 0.001 * np.sin(np.arange(300))
    assert output_jumps(once, np.ones(300) + 0.001 * np.sin(np.arange(300))) == []


@pytest.mark.parametrize(
    "kwargs, match",
    [({"threshold": 0.0}, "threshold"), ({"threshold": np.nan}, "threshold"),
     ({"min_jumps": 0}, "min_jumps")],
)  # fmt: skip
def test_jump_facts_refuse_bad_settings(kwargs, match):
    level, reading = _slow_level()
    with pytest.raises(ValueError, match=match):
        output_jumps(reading, level, **kwargs)


def test_the_step_acts_on_the_final_reading():
    """Listed before a calibration, the step still reads the calibrated output."""
    data = make_stepped_sensor_tank(n_samples=50, random_state=0)
    step = SensorStep(0, 5.0, 0.4, corner=0.1, name="step")
    calibration = SensorCalibration(0, 4.0, 2.0, degree=1, name="sensor")
    model = augment(data.physics, step, calibration)
    theta = {name: spec.value for name, spec in model.parameters.items()}
    theta.update(sensor_c0=0.5, sensor_c1=0.2)
    read = 6.0 + 0.5 + 0.2 * (6.0 - 4.0) / 2.0
    expected = read + 0.4 / (1.0 + np.exp(-(read - 5.0) / 0.1))
    got = float(model.output(jnp.array([6.0]), jnp.array([1.0]), theta)[0])
    assert got == pytest.approx(expected)
    assert float(step.apply_output(None, None, jnp.array([3.0]), theta)[0]) == pytest.approx(3.0)


def test_the_step_parameters_their_bounds_and_corner():
    step = SensorStep(0, 5.0, 0.4, level_bounds=(4.5, 5.5), corner=0.1, fit_corner=True)
    params = step.parameters()
    assert list(params) == ["step_level", "step_height", "step_corner"]
    assert params["step_level"].bounds == (4.5, 5.5)
    assert params["step_corner"].value == 0.1
    with pytest.raises(ValueError, match="corner"):
        SensorStep(0, 5.0, corner=0.0)


def test_a_jump_fact_proposes_a_step_started_from_the_data():
    level, reading = _slow_level()
    (fact,) = output_jumps(reading, level, ["x"])
    states = level[:, None]
    candidates = propose_effects([], [], ["x"], ["x"], states, [0], outputs=states, jumps=[fact])
    (step,) = [c.effect for c in candidates if isinstance(c.effect, SensorStep)]
    assert step.name == "step_x" and step.fit_corner
    assert step.level == pytest.approx(fact.level - fact.height / 2.0)
    assert step.height == fact.height
    lower, upper = step.level_bounds
    assert lower < 5.0 < upper
    assert step.corner == pytest.approx(0.025 * np.std(level))


@pytest.fixture(scope="module")
def stepped_loop():
    data = make_stepped_sensor_tank(n_samples=400, random_state=0)
    settings = LoopSettings(fit_delta=False, n_folds=2, max_iter=100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = close_the_loop(
            data.physics, data.suggested_library, data.u, data.z, settings=settings
        )
    return data, result


@pytest.mark.slow
def test_the_loop_adds_the_step_alone(stepped_loop):
    """The jumps name the step; the loop adds it and nothing else, with its level and
    height within 5 %, and the validation error falls by more than half."""
    data, result = stepped_loop
    assert [e.name for e in result.effects] == ["step_x"]
    assert any("jumps by" in c.reason for c in result.candidates)
    fitted, truth = result.final.parameters_, data.hidden_effect["rates"]
    assert fitted["step_x_height"] == pytest.approx(truth["step_height"], rel=0.05)
    assert fitted["step_x_level"] == pytest.approx(truth["step_level"], rel=0.05)
    rows = score_models(result, {"validation": (data.u_val, data.z_val)}, init_window=50)
    rmse = {r["model"]: r["rmse"] for r in rows if r["protocol"] == "init_window"}
    assert rmse["augmented physics"] < 0.5 * rmse["declared physics"]
