"""The hand-built Cascaded Tanks effects: eq. (21) without them, each limit where it acts."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite.datasets import cascaded_tanks_physics
from sk_offwhite.datasets._tanks_effects import EFFECTS, tanks_effects_physics

THETA = {"k1": 0.05, "k2": 0.04, "k3": 0.06, "k4": 0.05}


def _step(model, x, u, theta):
    with jax.enable_x64(True):
        return np.asarray(model.step(jnp.asarray(x, float), jnp.asarray([u], float), theta))


def test_without_effects_it_is_eq21():
    plain, ours = cascaded_tanks_physics(), tanks_effects_physics(())
    assert ours.parameter_names == ("k1", "k2", "k3", "k4")
    for x in ([5.0, 3.0], [0.0, 7.0], [12.0, 9.5]):
        np.testing.assert_allclose(_step(ours, x, 4.0, THETA), _step(plain, x, 4.0, THETA))


def test_parameters_follow_the_effects_in_declaration_order():
    model = tanks_effects_physics(EFFECTS, fixed={"k4": 0.04})
    assert model.parameter_names == (
        "k1", "k2", "k3", "k4", "h_max", "k_overflow", "x2_max", "z_out", "a2", "u_dead", "a1",
    )  # fmt: skip
    assert model.parameters["k4"].fixed and model.parameters["k4"].value == 0.04


def test_overflow_caps_the_upper_tank_and_feeds_the_lower_one():
    model = tanks_effects_physics(("overflow",), sharpness=200.0)
    theta = dict(THETA, h_max=10.0, k_overflow=0.5)
    plain = _step(tanks_effects_physics(()), [9.9, 2.0], 10.0, THETA)
    capped = _step(model, [9.9, 2.0], 10.0, theta)
    assert plain[0] > 10.5 and capped[0] == pytest.approx(10.0, abs=0.01)
    np.testing.assert_allclose(capped[1] - plain[1], 0.5 * (plain[0] - capped[0]), atol=0.01)


def test_tank_and_sensor_limits():
    model = tanks_effects_physics(("tank_limit", "sensor_limit"), sharpness=200.0)
    theta = dict(THETA, x2_max=9.0)
    assert _step(model, [100.0, 8.99], 0.0, theta)[1] == pytest.approx(9.0, abs=0.01)
    with jax.enable_x64(True):
        reading = model.output(jnp.array([1.0, 12.0]), jnp.zeros(1), theta)
    assert float(reading[0]) == pytest.approx(10.0, abs=0.01)


def test_outlet_law_with_offset_and_exponent():
    model = tanks_effects_physics(("offset", "outlet_exponent"))
    theta = dict(THETA, z_out=2.0, a2=0.25)
    x_next = _step(model, [0.0, 18.0], 0.0, theta)
    expected = 18.0 + 4.0 * (0.04 * np.sqrt(1e-6) - 0.06 * 16.0**0.25)
    assert x_next[1] == pytest.approx(expected, rel=1e-9)


def test_unknown_names_are_refused():
    with pytest.raises(ValueError, match="unknown effects"):
        tanks_effects_physics(("leak",))
    with pytest.raises(KeyError, match="h_max"):
        tanks_effects_physics((), init={"h_max": 3.0})
