"""DirectionalDamping, a viscous friction that differs with the direction of motion: the law,
its units, where the loop proposes it, the damping of each direction it leaves, a fit on a
drive of known parameters, and the loop naming it on a drive, an oscillator and a pendulum
(a loop of a minute or two each: with ``--run-slow`` only, as tests/test_loop_mechanical.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest
from conftest import driven_mass, driven_record

from sk_offwhite import DirectionalDamping, GreyBoxSparseRegressor, Parameter, PhysicsModel, augment
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import on_the_velocity, propose_effects
from sk_offwhite.loop._energy import power_sentence
from sk_offwhite.loop._hypotheses import Hypothesis
from sk_offwhite.loop._plausibility import direction_reasons
from sk_offwhite.model._kinds import Kinds

TRUTH = {"M": 2.0, "Fv": 4.0}
DIFFERENCE = 1.6
"""N s/m: the drive is damped by 5.6 N s/m moving forward and by 2.4 N s/m moving back."""


def term(difference, velocity, width=1e-6):
    effect = DirectionalDamping(1, width=width, name="dd")
    with jax.enable_x64(True):
        x = jnp.array([0.0, velocity])
        return float(effect.term(x, jnp.zeros(1), {"dd_difference": difference}))


def test_it_adds_damping_one_way_and_removes_it_the_other():
    assert term(0.5, 2.0) == pytest.approx(-1.0)  # forward: braked more
    assert term(0.5, -2.0) == pytest.approx(-1.0)  # backward: pushed, braked less
    assert term(-0.5, -2.0) == pytest.approx(1.0)
    assert term(0.0, 3.0) == 0.0


def test_the_difference_is_a_damping_whatever_the_velocity_unit():
    """Velocity in m/s or mm/s (the width with it): the term scales as the velocity, so the
    same difference is the same damping."""
    assert term(0.3, 2e3, width=1.0) == pytest.approx(1e3 * term(0.3, 2.0, width=1e-3))


def test_bad_width_is_refused():
    with pytest.raises(ValueError, match="width"):
        DirectionalDamping(1, width=0.0)


def test_the_loop_proposes_it_in_a_velocity_equation_only():
    states = np.column_stack([np.linspace(0, 1, 50), np.sin(np.arange(50.0))])
    u = np.cos(np.arange(50.0))[:, None]
    hypothesis = Hypothesis("v", 1, ("v",), -1, None)
    kinds = Kinds(("position", "velocity"), ("force",), {1: 0})
    found = propose_effects([hypothesis], [], ("q", "v"), ["q"], states, u=u,
                            input_names=("tau",), kinds=kinds)  # fmt: skip
    dampings = [c.effect for c in found if isinstance(c.effect, DirectionalDamping)]
    assert [(e.state, e.velocity) for e in dampings] == [(1, 1)]
    assert dampings[0].width == pytest.approx(0.01 * np.sqrt(np.mean(states[:, 1] ** 2)))
    levels = kinds._replace(states=("level", "level"), partner={})
    found = propose_effects([hypothesis], [], ("q", "v"), ["q"], states, u=u,
                            input_names=("tau",), kinds=levels)  # fmt: skip
    assert not any(isinstance(c.effect, DirectionalDamping) for c in found)


def test_a_drift_in_a_position_s_equation_is_sought_in_its_velocity_s_force():
    """A |v| force drifts the position: the evidence can name the kinematic equation
    q' = v instead of the force on v. The loop proposes the velocity's effects as well."""
    states = np.column_stack([np.linspace(0, 1, 50), np.sin(np.arange(50.0))])
    drift = Hypothesis("q", 0, (), 1, None, correction=np.ones(50))
    kinds = Kinds(("position", "velocity"), ("force",), {1: 0})
    moved = on_the_velocity(drift, ("q", "v"), kinds)
    assert (moved.equation, moved.equation_index, moved.correction) == ("v", 1, None)
    assert "kinematics" in moved.sentence
    names = {c.effect.name for c in propose_effects([drift], [], ("q", "v"), ["q"], states,
                                                    u=np.ones((50, 1)), kinds=kinds)}  # fmt: skip
    assert {"bias_q", "directional_damping_v", "friction_v", "bias_v"} <= names
    assert on_the_velocity(moved, ("q", "v"), kinds) is None  # a velocity stays where it is
    assert on_the_velocity(drift, ("q", "v"), kinds._replace(partner={})) is None


def damping():
    return DirectionalDamping(1, width=1e-3, name="dd")


def damped(make, truth: dict, difference: float):
    """The plant ``make(**truth)`` with `damping` of ``difference`` (per unit of its first,
    inertial, parameter)."""
    inertia = next(iter(truth))
    plant = augment(make(**truth), damping())
    return plant.with_parameters(dd_difference=difference / truth[inertia])


def directional_record(n: int, seed: int):
    """The drive damped more forward than back, driven by a band-limited force, its position
    measured with noise."""
    return driven_record(damped(driven_mass, TRUTH, DIFFERENCE), n, seed)


def test_the_fit_recovers_the_difference_and_the_declared_parameters():
    u, z = directional_record(1500, 0)
    est = GreyBoxSparseRegressor(augment(driven_mass(), damping()), None, max_iter=300)
    fitted = dict(est.fit(u, z).parameters_)
    assert fitted["M"] == pytest.approx(TRUTH["M"], rel=0.05)
    assert fitted["Fv"] == pytest.approx(TRUTH["Fv"], rel=0.05)
    assert fitted["dd_difference"] * fitted["M"] == pytest.approx(DIFFERENCE, rel=0.05)


def oscillator_rhs(x, u, theta):
    """A mass on a spring: q' = v, M v' = f - k q - c v."""
    return jnp.stack([x[1], (u[0] - theta["k"] * x[0] - theta["c"] * x[1]) / theta["M"]])


def pendulum_rhs(x, u, theta):
    """A driven pendulum: theta' = omega, J omega' = torque - mgl sin(theta) - b omega."""
    angle, rate = x[0], x[1]
    return jnp.stack(
        [rate, (u[0] - theta["mgl"] * jnp.sin(angle) - theta["b"] * rate) / theta["J"]]
    )


def second_order(rhs, names, kinds, **values) -> PhysicsModel:
    """``rhs`` at 100 Hz, its first parameter (the inertia) positive."""
    inertia, *others = values
    parameters = {inertia: Parameter(values[inertia], (0.01, None))}
    parameters.update({name: values[name] for name in others})
    return PhysicsModel.from_ode(
        rhs, 0.01, output=0, parameters=parameters, n_states=2, n_inputs=1,
        state_names=names[:2], input_names=names[2:], state_kinds=kinds[:2],
        input_kinds=kinds[2:],
    )  # fmt: skip


def oscillator(**values) -> PhysicsModel:
    kinds = ("position", "velocity", "force")
    return second_order(oscillator_rhs, ("q", "v", "f"), kinds, **values)


def pendulum(**values) -> PhysicsModel:
    kinds = ("angle", "rate", "torque")
    return second_order(pendulum_rhs, ("theta", "omega", "torque"), kinds, **values)


PLANTS = {
    "drive": (driven_mass, TRUTH, {"M": 1.5, "Fv": 3.0}, DIFFERENCE),
    "oscillator": (oscillator, {"M": 1.0, "k": 40.0, "c": 0.6}, {"M": 0.8, "k": 30.0, "c": 0.5},
                   0.3),
    "pendulum": (pendulum, {"J": 0.5, "mgl": 12.0, "b": 0.3}, {"J": 0.4, "mgl": 9.0, "b": 0.25},
                 0.12),
}  # fmt: skip
"""Each plant's physics, its truth, the loop's starting guess and the true difference of
damping (in the units of its torque or force per velocity). The pendulum's drift reads
first as a term of its angle's equation, which the loop moves to its rate's."""


@pytest.fixture(scope="module", params=sorted(PLANTS))
def loop_run(request):
    """The loop from a wrong guess of the plant, allowed one effect, and a validation record."""
    make, truth, guess, difference = PLANTS[request.param]
    plant = damped(make, truth, difference)
    (u, z), validation = driven_record(plant, 1000, 1), driven_record(plant, 600, 2)
    settings = LoopSettings(n_folds=2, max_iter=100, max_effects=1, fit_delta=False,
                            init_window=5, n_jobs=1)  # fmt: skip
    result = close_the_loop(make(**guess), ps.PolynomialLibrary(degree=2), u, z, settings=settings)
    return result, {"validation": validation}, truth, difference


@pytest.mark.slow
def test_the_loop_names_the_directional_damping_with_its_sign(loop_run):
    result, _, truth, difference = loop_run
    added = [effect for effect in result.effects if isinstance(effect, DirectionalDamping)]
    assert len(added) == 1 and len(result.effects) == 1
    params = result.final.parameters_
    inertia = next(iter(truth))
    fitted = params[f"{added[0].name}_difference"] * params[inertia]
    assert fitted == pytest.approx(difference, rel=0.05)
    names = result.physics.state_names
    assert "damped more while it is positive" in added[0].describe(names, ("z",), params)
    for name, value in truth.items():
        assert params[name] == pytest.approx(value, rel=0.05), name


@pytest.mark.slow
def test_the_loop_cuts_the_validation_error_by_half(loop_run):
    result, records, *_ = loop_run
    rows = {
        (row["model"], row["protocol"]): row["rmse"]
        for row in score_models(result, records, init_window=5)
    }
    declared = rows[("declared physics", "init_window")]
    assert rows[("augmented physics", "init_window")] <= 0.5 * declared


def test_the_report_gives_the_damping_of_each_direction():
    physics = driven_mass(**TRUTH)  # b = Fv / M = 2 per second
    effect = damping()
    states = np.column_stack([np.zeros(4), np.array([-1.0, -0.5, 0.5, 1.0])])
    theta = {**TRUTH, "dd_difference": 0.5}
    sentence = power_sentence(effect, physics, theta, states, np.zeros((4, 1)))
    assert sentence.startswith("dissipative both ways") and "2.5 moving forward" in sentence
    assert "1.5 moving back" in sentence
    assert direction_reasons(physics, [effect], theta) == []


def test_a_direction_left_undamped_makes_the_set_a_stand_in():
    physics = driven_mass(**TRUTH)
    theta = {**TRUTH, "dd_difference": -3.0}  # forward 2 - 3 < 0: driven
    (reason,) = direction_reasons(physics, [damping()], theta)
    assert "undamped" in reason
    states = np.column_stack([np.zeros(2), np.array([-1.0, 1.0])])
    sentence = power_sentence(damping(), physics, theta, states, np.zeros((2, 1)))
    assert sentence.startswith("not physical")
