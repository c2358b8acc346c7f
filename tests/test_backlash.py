"""Backlash, an effect with memory: hidden states, the servo generator, and the loop on it.

The loop test runs a short record with the sparse-δ fits skipped, as in
``test_loop_mechanical.py``. The hypothesis' sign is not checked: the effect is relative to
the refitted stiffness and damping, which absorb part of it (measured: the hypothesis on the
rate equation has sign +1 where the play's contribution along the true trajectory has -1).
"""

import pickle

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import Backlash, GreyBoxSparseRegressor, Parameter, augment, switched
from sk_offwhite._kinds import Kinds
from sk_offwhite._problem import initial_state_guess
from sk_offwhite.datasets import make_backlash_servo, play
from sk_offwhite.datasets._backlash import SERVO_THETA, SERVO_WIDTH
from sk_offwhite.effects._hidden import hidden_bounds, hidden_start
from sk_offwhite.loop import LoopSettings, _loop, close_the_loop, score_models, write_report
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._hypotheses import Hypothesis, Term


def _values(physics, **updates):
    values = {name: p.value for name, p in physics.parameters.items()}
    return {name: jnp.asarray(v) for name, v in {**values, **updates}.items()}


def _simulate(physics, theta, u):
    step = jax.jit(physics.step)
    x, states = jnp.asarray(physics.x0), []
    for row in u:
        states.append(np.asarray(x))
        x = step(x, jnp.asarray(row), theta)
    return np.array(states)


@pytest.fixture(scope="module")
def servo():
    return make_backlash_servo(n_samples=400, random_state=3)


def test_backlash_adds_a_free_hidden_state_after_the_declared_ones(servo):
    physics = servo.physics
    augmented = augment(physics, Backlash(0, 0.1, position=0.2, name="play"))
    assert physics.n_states == 2 and augmented.n_states == 3
    assert augmented.n_declared_states == 2
    assert augmented.state_names == ("theta", "omega", "play_position")
    assert augmented.state_kinds == ("angle", "rate", "angle")
    np.testing.assert_array_equal(augmented.x0, [0.0, 0.0, 0.2])
    np.testing.assert_array_equal(augmented.x0_fixed, [False, False, False])
    assert list(augmented.parameters)[-1] == "play_width"
    twice = augment(augmented, Backlash(0, 0.3, name="second"))
    assert twice.n_states == 4 and twice.state_names[-2:] == ("play_position", "second_position")
    restored = pickle.loads(pickle.dumps(twice))
    assert restored.step == twice.step and restored.n_states == 4


def test_a_backlash_on_an_input_the_physics_lacks_is_refused(servo):
    with pytest.raises(ValueError, match="acts on input 1, but the physics has 1"):
        augment(servo.physics, Backlash(1, 0.05))


def test_a_sharp_backlash_is_the_exact_play_and_the_output_ignores_it(servo):
    augmented = augment(servo.physics, Backlash(0, 0.05, position=float(servo.u[0, 0])))
    augmented = augmented.with_parameters(**{"backlash_width": Parameter(0.05)})
    sharp = augment(servo.physics, Backlash(0, 0.05, position=float(servo.u[0, 0]), sharpness=1e4))
    theta = _values(sharp, **SERVO_THETA)
    states = _simulate(sharp, theta, servo.u)
    played = play(servo.u[:, 0], SERVO_WIDTH)
    np.testing.assert_allclose(states[1:, 2], played[:-1], atol=1e-5)
    np.testing.assert_allclose(states[:, :2], servo.x, atol=1e-4)
    z = sharp.output(jnp.asarray(states[5]), jnp.asarray(servo.u[5]), theta)
    assert np.shape(z) == (1,) and float(z[0]) == pytest.approx(states[5, 0])


def test_a_switched_off_backlash_is_the_declared_model(servo):
    effect = switched(Backlash(0, 0.05))
    model = augment(servo.physics, effect)
    off = _values(model, backlash_on=0.0, **SERVO_THETA)
    u = jnp.asarray(servo.u[10])
    x = jnp.array([0.1, -0.2, 0.3])
    declared = servo.physics.step(x[:2], u, _values(servo.physics, **SERVO_THETA))
    np.testing.assert_allclose(model.step(x, u, off)[:2], declared)
    assert float(model.step(x, u, off)[2]) == pytest.approx(0.3)


def test_the_width_has_a_finite_gradient_everywhere_in_the_play(servo):
    model = augment(servo.physics, Backlash(0, 0.05))

    def moved(width, position, command):
        theta = _values(model, backlash_width=width, **SERVO_THETA)
        x = jnp.array([0.0, 0.0, position])
        return model.step(x, jnp.array([command]), theta)[2]

    for position, command in [(0.0, 0.0), (0.0, 0.2), (0.0, -0.2), (0.049, 0.0)]:
        slope = jax.grad(moved)(0.05, position, command)
        assert np.isfinite(float(slope))
    assert float(jax.grad(moved)(0.05, 0.0, 0.2)) == pytest.approx(-1.0, abs=1e-6)


def test_fitting_the_width_recovers_the_play(servo):
    model = augment(servo.physics, Backlash(0, 0.02, position=float(servo.u[0, 0])))
    est = GreyBoxSparseRegressor(model, max_iter=100).fit(servo.u, servo.z)
    assert est.parameters_["backlash_width"] == pytest.approx(SERVO_WIDTH, rel=0.05)
    assert est.parameters_["k"] == pytest.approx(SERVO_THETA["k"], rel=0.02)
    assert est.initial_states_.shape[-1] == 3
    # the first fit pushes the play's start beyond the play; the restart from inside wins
    assert est.solver_message_.startswith("restarted with the hidden states inside")
    start, command = est.initial_states_[0, 2], servo.u[0, 0]
    assert abs(start - command) <= est.parameters_["backlash_width"]


def test_a_record_starts_the_play_inside_it(servo):
    play_at = {"play_width": 0.05}
    effect = Backlash(0, 0.05, name="play")
    assert effect.hidden_start([0.22], np.array([0.2]), play_at) == (0.22,)
    assert effect.hidden_start([3.0], np.array([0.2]), play_at) == (0.2,)
    assert switched(effect).hidden_start([3.0], np.array([0.2]), play_at) == (0.2,)
    model = augment(servo.physics, Backlash(0, 0.05, position=1e6, name="play"))
    x0 = np.array([0.1, -0.2, 1e6])
    np.testing.assert_array_equal(hidden_start(model.step, x0, [0.2], play_at), [0.1, -0.2, 0.2])
    fixed = np.array([False, False, True])
    np.testing.assert_array_equal(hidden_start(model.step, x0, [0.2], play_at, fixed), x0)
    np.testing.assert_array_equal(hidden_start(servo.physics.step, x0[:2], [0.2], {}), x0[:2])
    theta = {name: p.value for name, p in model.parameters.items()}
    guess = initial_state_guess(model.x0, model, servo.u[0], servo.z[0], theta, model.x0_fixed)
    assert guess[2] == servo.u[0, 0] and model.x0[2] == 1e6


def test_a_record_bounds_the_play_start_by_its_input_range(servo):
    effect = Backlash(0, 0.05, name="play")
    commands = np.array([[0.1], [0.4], [0.2]])
    np.testing.assert_allclose(effect.hidden_bounds(commands), [[-0.2, 0.7]])
    np.testing.assert_allclose(switched(effect).hidden_bounds(commands), [[-0.2, 0.7]])
    assert effect.hidden_bounds(np.full((5, 1), 0.3)) == ((-np.inf, np.inf),)
    model = augment(servo.physics, effect)
    lower, upper = hidden_bounds(model.step, servo.u, model.n_states)
    span = np.ptp(servo.u[:, 0])
    np.testing.assert_allclose(lower, [-np.inf, -np.inf, servo.u[:, 0].min() - span])
    np.testing.assert_allclose(upper, [np.inf, np.inf, servo.u[:, 0].max() + span])
    unbounded = hidden_bounds(servo.physics.step, servo.u, 2)
    np.testing.assert_array_equal(unbounded, [[-np.inf] * 2, [np.inf] * 2])


def test_a_play_position_beyond_the_play_does_not_freeze_the_initial_state(servo):
    """A fit can end with the play's start far beyond the play (the first step then puts
    it at the edge whatever it is): a later record's initial state is estimated from
    inside the play, not from that value, where the output does not depend on it."""
    model = augment(servo.physics, Backlash(0, SERVO_WIDTH, position=float(servo.u[0, 0])))
    est = GreyBoxSparseRegressor(model, max_iter=100).fit(servo.u, servo.z)
    other = make_backlash_servo(n_samples=400, random_state=5)
    window = slice(0, 50)

    def error(x0_hidden):
        est.x0_ = np.array([*est.x0_[:2], x0_hidden])
        z = np.ravel(est.predict(other.u, z_init=other.z[window]))
        return float(np.sqrt(np.mean((z - other.z[:, 0]) ** 2)))

    inside = error(float(other.u[0, 0]))
    assert error(1e6) == pytest.approx(inside, rel=1e-6)
    assert error(-1e6) == pytest.approx(inside, rel=1e-6)


def test_the_generator_simulates_the_played_input_and_is_reproducible():
    data = make_backlash_servo(n_samples=300, random_state=1, noise_std=0.0)
    again = make_backlash_servo(n_samples=300, random_state=1, noise_std=0.0)
    np.testing.assert_array_equal(data.u, again.u)
    np.testing.assert_array_equal(data.z[:, 0], data.x[:, 0])
    played = data.hidden_effect["played"]
    np.testing.assert_array_equal(played, play(data.u[:, 0], SERVO_WIDTH))
    assert np.all(np.abs(played - data.u[:, 0]) <= SERVO_WIDTH + 1e-12)
    with jax.enable_x64(True):
        theta = {k: jnp.asarray(v) for k, v in data.true_parameters.items()}
        step = jax.jit(data.physics.step)
        rows = zip(data.x, played, strict=True)
        predicted = np.array([step(x, jnp.array([p]), theta) for x, p in rows])
    np.testing.assert_allclose(predicted[:-1], data.x[1:], atol=1e-12)
    assert data.kinds == {"states": ("angle", "rate"), "inputs": ("angle",)}


def test_backlash_is_proposed_for_angle_inputs_only():
    hypothesis = Hypothesis("omega", 1, ("omega",), -1, None, sentence="omega lacks a term.")
    states = np.random.default_rng(0).normal(size=(50, 2))
    u = np.random.default_rng(1).normal(size=(50, 1))
    names = ("theta", "omega")

    def proposed(input_kind):
        kinds = Kinds(("angle", "rate"), (input_kind,), {1: 0})
        found = propose_effects([hypothesis], [], names, ["theta"], states, u=u,
                                input_names=("u",), kinds=kinds)  # fmt: skip
        return {c.effect.name: c.effect for c in found}

    angle, force = proposed("angle"), proposed("force")
    assert "backlash_u" in angle and "backlash_u" not in force
    assert angle["backlash_u"].width == pytest.approx(0.05 * np.std(u))
    assert angle["backlash_u"].position == pytest.approx(u[0, 0])


@pytest.fixture(scope="module")
def loop_run():
    data = make_backlash_servo(n_samples=1000, random_state=0)
    settings = LoopSettings(n_folds=2, max_iter=100, fit_delta=False, max_candidates=6)
    return data, close_the_loop(
        data.physics, data.suggested_library, data.u, data.z, settings=settings
    )


@pytest.mark.slow
def test_the_loop_names_the_backlash_and_recovers_the_play(loop_run):
    data, result = loop_run
    assert [h.equation_index for h in result.hypotheses][:1] == [data.hidden_effect["equation"]]
    assert isinstance(result.effects[0], Backlash) and result.failures == []
    fitted = result.final.parameters_
    assert fitted["backlash_u_width"] == pytest.approx(SERVO_WIDTH, rel=0.05)
    for name, value in data.true_parameters.items():
        assert fitted[name] == pytest.approx(value, rel=0.05), name


@pytest.mark.slow
def test_the_loop_adds_the_backlash_alone(loop_run):
    _, result = loop_run
    assert [type(e) for e in result.effects] == [Backlash]


@pytest.mark.slow
def test_the_loop_cuts_the_validation_error_and_reports_the_hidden_state(loop_run, tmp_path):
    data, result = loop_run
    records = {"estimation": (data.u, data.z), "validation": (data.u_val, data.z_val)}
    rows = score_models(result, records)
    rmse = {
        r["model"]: r["rmse"]
        for r in rows
        if r["protocol"] == "init_window" and r["record"] == "validation"
    }
    assert rmse["augmented physics"] < 0.5 * rmse["declared physics"], rmse
    assert result.chosen == "final"
    assert result.cv_errors["final"] == min(result.cv_errors.values())
    text = write_report(result, rows, records, tmp_path, title="servo").read_text()
    assert "play (backlash)" in text


def test_no_dictionary_term_is_promoted_on_a_physics_with_hidden_states():
    """A promoted term reads the declared states and the inputs in the step; with a
    backlash's hidden state in the physics the dictionary's features hold that state too,
    so no term is promoted there (each had failed as a candidate before)."""
    data = make_backlash_servo(n_samples=50, random_state=0)
    term = Term("omega", "u", 1.0, 0.1, 1.0, ("u",), column=1)
    hypothesis = Hypothesis("omega", 1, ("u",), 1, None, terms=(term,), gain=0.2)

    def promoted(physics):
        names = [*physics.state_names, *physics.input_names]
        library, dt = data.suggested_library, 1.0
        found = _loop._promoted(physics, [hypothesis], library, names, dt, LoopSettings())
        return [c.effect.name for c in found]

    assert promoted(data.physics) == ["term_omega_u"]
    assert promoted(augment(data.physics, Backlash(0, 0.05, name="backlash_u"))) == []
