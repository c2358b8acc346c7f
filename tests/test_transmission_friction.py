"""TransmissionFriction, a friction that grows with the force a screw or gear carries: the
law, its unit-free share, where the loop proposes it, and a fit on a drive of known
parameters."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import driven_mass, driven_record

from sk_offwhite import (
    Friction,
    GreyBoxSparseRegressor,
    PhysicsModel,
    TransmissionFriction,
    augment,
)
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._hypotheses import Hypothesis
from sk_offwhite.model._kinds import Kinds

DT = 0.01
TRUTH = {"M": 2.0, "Fv": 4.0, "friction_coulomb": 1.5, "load_share": 0.2}


def seen(share, force, velocity, width=1e-6):
    effect = TransmissionFriction(0, 1, width=width, name="load")
    theta = {"load_share": share}
    with jax.enable_x64(True):
        u = effect.apply_input(jnp.array([0.0, velocity]), jnp.array([force]), theta)
    return float(u[0])


def test_the_drive_loses_the_share_while_pushing_and_brakes_more_while_braking():
    assert seen(0.2, 10.0, 1.0) == pytest.approx(8.0)  # forward efficiency 1 - μ
    assert seen(0.2, -10.0, 1.0) == pytest.approx(-12.0)  # braking, friction helps
    assert seen(0.2, -10.0, -1.0) == pytest.approx(-8.0)
    assert seen(0.0, 10.0, 1.0) == pytest.approx(10.0)


def test_the_share_is_unit_free():
    """Force in N or kN, velocity in m/s or mm/s: the same share does the same."""
    base = seen(0.3, 7.0, 0.2, width=0.01)
    assert seen(0.3, 7e-3, 0.2, width=0.01) == pytest.approx(1e-3 * base)
    assert seen(0.3, 7.0, 200.0, width=10.0) == pytest.approx(base)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="share"):
        TransmissionFriction(0, 1, share=1.5)
    with pytest.raises(ValueError, match="width"):
        TransmissionFriction(0, 1, width=0.0)


def drive(**values) -> PhysicsModel:
    return driven_mass(values.get("M", 1.0), values.get("Fv", 1.0))


def effects():
    friction = Friction(1, coulomb=0.1, width=1e-3, fit_width=False, name="friction")
    return friction, TransmissionFriction(0, 1, width=1e-3, name="load")


def screw_record(n: int, seed: int):
    """The drive with a Coulomb friction and a load friction, driven by a band-limited
    force, its position measured with noise."""
    truth = augment(drive(**TRUTH), *effects()).with_parameters(
        friction_coulomb=TRUTH["friction_coulomb"] / TRUTH["M"], load_share=TRUTH["load_share"]
    )
    return driven_record(truth, n, seed)


def test_the_fit_recovers_the_share_and_the_declared_parameters():
    u, z = screw_record(1500, 0)
    est = GreyBoxSparseRegressor(augment(drive(), *effects()), None, max_iter=300).fit(u, z)
    fitted = dict(est.parameters_)
    fitted["friction_coulomb"] *= fitted["M"]  # the friction is a rate, per unit mass
    for name, value in TRUTH.items():
        assert fitted[name] == pytest.approx(value, rel=0.05), name


def test_the_loop_proposes_it_for_a_force_on_a_velocity():
    states = np.column_stack([np.linspace(0, 1, 50), np.sin(np.arange(50.0))])
    u = np.cos(np.arange(50.0))[:, None]
    hypothesis = Hypothesis("v", 1, ("v", "tau"), 1, None)
    kinds = Kinds(("position", "velocity"), ("force",), {1: 0})
    found = propose_effects([hypothesis], [], ("q", "v"), ["q"], states, u=u,
                            input_names=("tau",), kinds=kinds)  # fmt: skip
    losses = [c.effect for c in found if isinstance(c.effect, TransmissionFriction)]
    assert [(e.input, e.velocity) for e in losses] == [(0, 1)]
    assert losses[0].width == pytest.approx(0.01 * np.sqrt(np.mean(states[:, 1] ** 2)))
    voltage = kinds._replace(inputs=("voltage",))
    found = propose_effects([hypothesis], [], ("q", "v"), ["q"], states, u=u,
                            input_names=("tau",), kinds=voltage)  # fmt: skip
    assert not any(isinstance(c.effect, TransmissionFriction) for c in found)
