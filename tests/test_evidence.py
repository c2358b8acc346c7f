"""What the physics cannot explain: projected evidence, physical kinds, continuous-time effects."""

import pickle

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import Bias, DictionaryTerm, Friction, PhysicsModel, augment
from sk_offwhite._kinds import physical_kinds
from sk_offwhite._sparsity import matching_pursuit, term_evidence
from sk_offwhite.datasets import cascaded_tanks_physics, make_friction_oscillator
from sk_offwhite.effects._augment import time_step


def test_a_term_the_physics_can_absorb_carries_no_evidence():
    rng = np.random.default_rng(0)
    physics_columns = rng.normal(size=(200, 2))
    missing = rng.normal(size=200)
    residual = -0.5 * missing + 0.01 * rng.normal(size=200)
    residual -= physics_columns @ np.linalg.lstsq(physics_columns, residual, rcond=None)[0]
    absorbable = physics_columns @ np.array([1.0, -2.0])
    terms = np.column_stack([absorbable, missing])
    evidence = term_evidence(residual, physics_columns, terms)
    assert evidence.absorbed[0] > 1 - 1e-9 and evidence.gain[0] == 0.0
    assert evidence.gain[1] > 0.99
    assert evidence.estimate[1] == pytest.approx(0.5, rel=0.05)


def test_matching_pursuit_counts_one_of_two_collinear_terms():
    rng = np.random.default_rng(1)
    a = rng.normal(size=300)
    columns = np.column_stack([a, a + 1e-6 * rng.normal(size=300), rng.normal(size=300)])
    residual = 2.0 * a
    conditional = matching_pursuit(residual, columns, np.ones(3, bool))
    assert np.count_nonzero(conditional[:2] > 0.5) == 1 and conditional[2] < 1e-3


def test_evidence_does_not_depend_on_units():
    rng = np.random.default_rng(2)
    residual, physics, terms = (
        rng.normal(size=100),
        rng.normal(size=(100, 2)),
        rng.normal(size=(100, 3)),
    )
    plain = term_evidence(residual, physics, terms)
    column_units = np.array([1e-3, 1.0, 1e4])
    scaled = term_evidence(1e3 * residual, physics * [1e5, 1e-2], terms * column_units)
    np.testing.assert_allclose(scaled.gain, plain.gain, rtol=1e-9)
    np.testing.assert_allclose(scaled.absorbed, plain.absorbed, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(scaled.estimate, plain.estimate * 1e3 / column_units, rtol=1e-9)


def test_the_strongest_evidence_on_the_friction_oscillator_is_the_friction_term():
    from sk_offwhite import GreyBoxSparseRegressor

    data = make_friction_oscillator(n_samples=300, random_state=0)
    est = GreyBoxSparseRegressor(
        data.physics, library=data.suggested_library, horizon=None, max_iter=50
    )
    est._fit(data.u, data.z, None, reference_only=True)
    strongest = np.unravel_index(np.argmax(est.term_conditional_gain_), est.term_gain_.shape)
    assert strongest == (1, est.feature_names_.index("tanh(10 v)"))


def test_kinds_are_declared_or_read_off_the_step():
    oscillator = make_friction_oscillator(n_samples=50, random_state=0).physics
    kinds = physical_kinds(oscillator)
    assert kinds.states == ("position", "velocity") and kinds.partner == {1: 0}
    assert physical_kinds(cascaded_tanks_physics()).states == ("level", "level")
    with pytest.raises(ValueError, match="state_kinds has unknown kinds"):
        PhysicsModel(lambda x, u, t: x, 0, {}, 1, 1, state_kinds=("speed",))


def test_additive_effects_are_rates_inside_a_from_ode_physics():
    physics = PhysicsModel.from_ode(lambda x, u, t: jnp.zeros(1), 0.05, 0, {}, 1, 1, method="euler")
    model = augment(physics, Bias(0, value=2.0))
    assert time_step(model) == 0.05
    with jax.enable_x64(True):
        x_next = model.step(jnp.zeros(1), jnp.zeros(1), {"bias_value": 2.0})
    np.testing.assert_allclose(np.asarray(x_next), [0.1])  # dt * rate


def test_dictionary_terms_pickle_and_compare_by_value():
    data = make_friction_oscillator(n_samples=50, random_state=0)
    names = ["x", "v", "u"]
    term = DictionaryTerm(1, data.suggested_library, names, 3, coefficient=0.5, name="t")
    assert pickle.loads(pickle.dumps(term)) == term and term.feature == "u"
    model = augment(data.physics, term, Friction(1, coulomb=0.1, width=0.01))
    assert pickle.loads(pickle.dumps(model)).step == model.step
