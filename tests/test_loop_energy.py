"""Where an added term's energy goes: dissipative, conservative or energy-adding."""

import numpy as np
import pytest

from sk_offwhite import Bias, Friction, Stiffness
from sk_offwhite.datasets import emps_physics
from sk_offwhite.loop._energy import net_power_share, power_sentence


@pytest.fixture(scope="module")
def oscillation():
    """A free oscillation q = sin t, v = cos t over ten periods, on the drive's physics
    (states q, v of kinds position, velocity)."""
    physics = emps_physics()
    t = np.linspace(0.0, 20 * np.pi, 4000)
    states = np.column_stack([np.sin(t), np.cos(t)])
    return physics, states, np.zeros((t.size, 1))


def test_the_share_is_unit_free_and_signed():
    rng = np.random.default_rng(0)
    v, g = rng.normal(size=200), rng.normal(size=200)
    assert net_power_share(v, g) == pytest.approx(net_power_share(1e3 * v, 1e-4 * g))
    assert net_power_share(v, -v) == -1.0 and net_power_share(v, 2 * v) == 1.0
    assert np.isnan(net_power_share(v, 0 * v))


def test_friction_dissipates_a_spring_conserves_a_push_adds(oscillation):
    physics, states, u = oscillation
    assert physics.state_kinds[1] == "velocity"
    friction = Friction(1, width=0.05, name="fr")
    spring = Stiffness(1, 0, reference=1.0, name="k")
    theta = {"fr_coulomb": 0.3, "fr_width": 0.05, "k_coefficient": 2.0}
    assert power_sentence(friction, physics, theta, states, u).startswith("dissipative")
    assert power_sentence(spring, physics, theta, states, u).startswith("conservative")
    pushed = states[states[:, 1] > 0]  # moving forward only: a positive constant drives it
    push = power_sentence(Bias(1, name="b"), physics, {"b_value": 1.0}, pushed, u[: len(pushed)])
    assert push.startswith("energy-adding") and "+1.00" in push


def test_no_reading_outside_a_velocity_equation(oscillation):
    physics, states, u = oscillation
    assert power_sentence(Bias(0, name="b"), physics, {"b_value": 1.0}, states, u) is None
