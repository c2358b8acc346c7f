"""DirectionalDamping, a viscous friction that differs with the direction of motion: the law,
its units, where the loop proposes it, the damping of each direction it leaves, a fit on a
drive of known parameters, and the loop naming it on such a drive (a loop of about a minute
and a half on two cores: with ``--run-slow`` only, as tests/test_loop_mechanical.py)."""

import jax
import jax.numpy as jnp
import numpy as np
import pysindy as ps
import pytest
from conftest import driven_mass, driven_record

from sk_offwhite import DirectionalDamping, GreyBoxSparseRegressor, augment
from sk_offwhite.loop import LoopSettings, close_the_loop, score_models
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._energy import direction_reasons, power_sentence
from sk_offwhite.loop._hypotheses import Hypothesis
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


def damping():
    return DirectionalDamping(1, width=1e-3, name="dd")


def directional_record(n: int, seed: int):
    """The drive damped more forward than back, driven by a band-limited force, its position
    measured with noise."""
    truth = augment(driven_mass(**TRUTH), damping())
    truth = truth.with_parameters(dd_difference=DIFFERENCE / TRUTH["M"])
    return driven_record(truth, n, seed)


def test_the_fit_recovers_the_difference_and_the_declared_parameters():
    u, z = directional_record(1500, 0)
    est = GreyBoxSparseRegressor(augment(driven_mass(), damping()), None, max_iter=300)
    fitted = dict(est.fit(u, z).parameters_)
    assert fitted["M"] == pytest.approx(TRUTH["M"], rel=0.05)
    assert fitted["Fv"] == pytest.approx(TRUTH["Fv"], rel=0.05)
    assert fitted["dd_difference"] * fitted["M"] == pytest.approx(DIFFERENCE, rel=0.05)


@pytest.fixture(scope="module")
def loop_run():
    """The loop from a wrong guess of the drive, allowed one effect, and a validation record."""
    u, z = directional_record(1000, 1)
    u_val, z_val = directional_record(600, 2)
    settings = LoopSettings(n_folds=2, max_iter=100, max_effects=1, fit_delta=False,
                            init_window=5, n_jobs=1)  # fmt: skip
    result = close_the_loop(
        driven_mass(M=1.5, Fv=3.0), ps.PolynomialLibrary(degree=2), u, z, settings=settings
    )
    return result, {"validation": (u_val, z_val)}


@pytest.mark.slow
def test_the_loop_names_the_directional_damping_with_its_sign(loop_run):
    result, _ = loop_run
    added = [effect for effect in result.effects if isinstance(effect, DirectionalDamping)]
    assert len(added) == 1 and len(result.effects) == 1
    params = result.final.parameters_
    difference = params[f"{added[0].name}_difference"] * params["M"]
    assert difference == pytest.approx(DIFFERENCE, rel=0.05)
    assert "damped more while it is positive" in added[0].describe(("q", "v"), ("q",), params)
    assert params["Fv"] == pytest.approx(TRUTH["Fv"], rel=0.05)


@pytest.mark.slow
def test_the_loop_cuts_the_validation_error_by_half(loop_run):
    result, records = loop_run
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
