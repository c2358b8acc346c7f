"""Forces of a position: `PositionForce` (a spring, a cable, a slope) and a Coulomb friction
whose level varies along the stroke: the laws, their unit-free constants, and a fit on a
carriage of known parameters."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import driven_mass, driven_record

from sk_offwhite import (
    Friction,
    GreyBoxSparseRegressor,
    PhysicsModel,
    PositionForce,
    augment,
)

DT = 0.01
CENTER, SPREAD = 0.5, 0.2
TRUTH = {
    "M": 2.0,
    "Fv": 4.0,
    "friction_coulomb": 1.5,
    "friction_gradient": -0.3,
    "cable_c1": -8.0,
    "cable_c2": 2.0,
}


def term(effect, theta, q, v=1.0):
    with jax.enable_x64(True):
        return float(effect.term(jnp.array([q, v]), jnp.zeros(1), theta))


def test_the_position_force_is_a_polynomial_about_its_centre():
    force = PositionForce(1, 0, center=CENTER, reference=SPREAD, name="cable")
    theta = {"cable_c1": 2.0, "cable_c2": -1.0}
    assert term(force, theta, CENTER) == 0.0
    s = 0.3 / SPREAD
    assert term(force, theta, CENTER + 0.3) == pytest.approx(2.0 * s - s**2)
    assert list(force.parameters()) == ["cable_c1", "cable_c2"]


def test_the_coefficients_do_not_depend_on_the_position_unit_or_origin():
    theta = {"cable_c1": 2.0, "cable_c2": -1.0}
    metres = PositionForce(1, 0, center=CENTER, reference=SPREAD, name="cable")
    shifted_mm = PositionForce(1, 0, center=1e3 * CENTER + 7.0, reference=1e3 * SPREAD,
                               name="cable")  # fmt: skip
    assert term(shifted_mm, theta, 1e3 * 0.65 + 7.0) == pytest.approx(term(metres, theta, 0.65))


def test_the_friction_level_varies_along_the_position_by_its_gradient():
    friction = Friction(1, width=1e-6, position=0, center=CENTER, reference=SPREAD,
                        name="friction")  # fmt: skip
    theta = {"friction_coulomb": 1.5, "friction_width": 1e-6, "friction_gradient": -0.3}
    assert term(friction, theta, CENTER) == pytest.approx(-1.5)
    assert term(friction, theta, CENTER + SPREAD) == pytest.approx(-1.5 * np.exp(-0.3))
    assert term(friction, theta, CENTER + SPREAD, v=-1.0) == pytest.approx(1.5 * np.exp(-0.3))
    plain = Friction(1, width=1e-6, name="friction")
    assert "friction_gradient" not in plain.parameters()
    values = {"friction_gradient": -0.3}
    assert "falls along q" in friction.describe(("q", "v"), ["q"], values)
    assert "along" not in plain.describe(("q", "v"), ["q"], values)


def test_bad_settings_are_refused():
    with pytest.raises(ValueError, match="degree"):
        PositionForce(1, 0, degree=0)
    with pytest.raises(ValueError, match="reference"):
        PositionForce(1, 0, reference=0.0)
    with pytest.raises(ValueError, match="reference"):
        Friction(1, position=0, reference=-1.0)


def carriage(**values) -> PhysicsModel:
    return driven_mass(values.get("M", 1.0), values.get("Fv", 1.0), x0=(CENTER, 0.0))


def effects():
    friction = Friction(1, coulomb=0.1, width=1e-3, fit_width=False, position=0, center=CENTER,
                        reference=SPREAD, name="friction")  # fmt: skip
    return friction, PositionForce(1, 0, center=CENTER, reference=SPREAD, name="cable")


FORCES = ("friction_coulomb", "cable_c1", "cable_c2")
"""The effects' parameters that are forces; the effects' terms are rates (per unit mass)."""


def per_mass(values: dict) -> dict:
    """The effects' parameters of ``values`` as the augmented physics holds them."""
    return {k: v / values["M"] if k in FORCES else v for k, v in values.items()
            if k not in ("M", "Fv")}  # fmt: skip


def carriage_record(n: int, seed: int):
    """The carriage driven by a band-limited force about the centre of its stroke, its
    position measured with noise."""
    truth = augment(carriage(**TRUTH), *effects()).with_parameters(**per_mass(TRUTH))
    return driven_record(truth, n, seed, x0=(CENTER, 0.0))


def test_the_fit_recovers_the_varying_friction_and_the_position_force():
    u, z = carriage_record(1500, 0)
    assert np.ptp(z) > 2 * SPREAD  # the carriage travels along the varying friction
    est = GreyBoxSparseRegressor(augment(carriage(), *effects()), None, max_iter=300).fit(u, z)
    fitted = dict(est.parameters_)
    fitted.update({k: fitted[k] * fitted["M"] for k in FORCES})
    for name, value in TRUTH.items():
        assert fitted[name] == pytest.approx(value, rel=0.05), name
