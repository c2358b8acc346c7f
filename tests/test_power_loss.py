"""A loss of fitted power (:class:`PowerLoss`): its law, its units, where the loop proposes
it (a temperature's equation that loses, not a level's), and what it does for a block that
loses heat by natural convection where its physics declares Newton's law."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import PowerLoss, augment
from sk_offwhite.datasets import make_convective_block
from sk_offwhite.loop import LoopSettings, fit_continued, warm_physics
from sk_offwhite.loop._candidates import propose_effects
from sk_offwhite.loop._hypotheses import Hypothesis
from sk_offwhite.loop._search import Search
from sk_offwhite.model._kinds import Kinds


def _term(loss, x, theta):
    return float(loss.term(jnp.asarray([x]), None, theta))


def test_the_power_loss_follows_its_law_and_has_finite_derivatives_at_its_level():
    loss = PowerLoss(0, level=300.0, reference=4.0, name="q")
    theta = {"q_rate": 0.3, "q_level": 300.0, "q_exponent": 4.0 / 3.0}
    for x in (290.0, 300.0, 304.0, 317.5):
        excess = x - 300.0
        expected = -0.3 * 4.0 * np.sign(excess) * (abs(excess) / 4.0) ** (4.0 / 3.0)
        assert _term(loss, x, theta) == pytest.approx(expected, rel=1e-5, abs=1e-6)
    assert _term(loss, 304.0, theta) == pytest.approx(-0.3 * 4.0)  # c Δ_r at Δ = Δ_r, any a

    def term(x, level, exponent):
        return loss.term(jnp.stack([x]), None, {**theta, "q_level": level, "q_exponent": exponent})

    gradient = jax.grad(term, argnums=(0, 1, 2))(300.0, 300.0, 4.0 / 3.0)
    assert all(np.isfinite(float(g)) for g in gradient)
    assert set(loss.parameters()) == {"q_rate", "q_level", "q_exponent"}
    assert loss.parameters()["q_exponent"].bounds == (1.0, 3.0)
    assert loss.parameters()["q_rate"].bounds == (0.0, None)
    assert "power 1.33" in loss.describe(("T",), ("T",), {"q_exponent": 4.0 / 3.0})
    assert "power 2" in loss.describe(("T",), ("T",))  # the start, before a fit
    with pytest.raises(ValueError, match="exponent"):
        PowerLoss(0, exponent=0.5)
    with pytest.raises(ValueError, match="reference"):
        PowerLoss(0, reference=-1.0)


@pytest.mark.parametrize("factor", [1e-3, 1.0, 40.0])
def test_the_power_losss_rate_does_not_depend_on_the_states_units(factor):
    """In units where the state reads ``factor`` times larger (level and reference with it),
    the term (a rate of the state) reads ``factor`` times larger at the same rate constant,
    whatever the exponent."""
    for exponent in (1.0, 1.25, 2.5):
        theta = {"q_rate": 0.2, "q_level": 1.5, "q_exponent": exponent}
        scaled = {**theta, "q_level": 1.5 * factor}
        base = _term(PowerLoss(0, reference=0.8, name="q"), 2.7, theta)
        other = _term(PowerLoss(0, reference=0.8 * factor, name="q"), 2.7 * factor, scaled)
        assert other == pytest.approx(factor * base, rel=1e-5)  # float32 terms


def _proposed(kind: str, sign: int) -> dict:
    rng = np.random.default_rng(0)
    states = 300.0 + np.cumsum(rng.normal(size=(200, 1)), axis=0)
    hypothesis = Hypothesis("T", 0, ("T",), sign, None, sentence="T lacks a term.")
    kinds = Kinds((kind,), ("generic",), {})
    found = propose_effects([hypothesis], [], ("T",), ("T",), states, kinds=kinds)
    return {c.effect.name: c.effect for c in found}, states[:, 0]


def test_a_temperature_that_loses_is_offered_a_loss_of_fitted_power_started_from_the_record():
    found, temperature = _proposed("temperature", -1)
    loss = found["loss_T"]
    assert isinstance(loss, PowerLoss) and "leak_T" in found
    assert loss.level == pytest.approx(temperature.min()) and loss.exponent == 2.0
    assert loss.reference == pytest.approx(np.std(temperature))
    assert "loss_T" not in _proposed("temperature", 1)[0]  # a gain is not a loss
    for kind in ("level", "generic", "velocity"):
        assert not any(isinstance(e, PowerLoss) for e in _proposed(kind, -1)[0].values())


def test_a_loss_of_fitted_power_takes_the_convective_block_to_the_sensors_noise():
    """Newton's law declared, natural convection (power 4/3) true: with the loss of fitted
    power added as the loop proposes it, the fit simulates the validation record at the
    sensor's noise, and the heat capacity (which no loss law trades with) comes back."""
    data = make_convective_block(n_samples=600, random_state=0)
    temperature = data.x[:, 0]  # the record's range, as the loop's simulated one
    loss = PowerLoss(0, level=temperature.min(), reference=np.std(temperature), name="loss_T")
    settings = LoopSettings(max_iter=100)
    search = Search(data.u, data.z, settings)
    declared = fit_continued(search.estimator(data.physics), data.u, data.z, 128)
    physics = augment(warm_physics(data.physics, declared), loss)
    augmented = fit_continued(search.estimator(physics), data.u, data.z, 128)

    def validation(est):
        return float(np.sqrt(np.mean((est.predict(data.u_val) - data.z_val) ** 2)))

    noise = data.noise["output"]["std"]
    assert validation(augmented) < 1.1 * noise < 0.5 * validation(declared)
    assert augmented.parameters_["capacity"] == pytest.approx(800.0, rel=0.01)
    assert 1.0 < augmented.parameters_["loss_T_exponent"] < 3.0
