"""Relaxing a declared law: a fixed, relaxable constant freed as a candidate change."""

import jax.numpy as jnp
import numpy as np
import pytest

from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel, RelaxedLaw, augment
from sk_offwhite.datasets import cascaded_tanks_physics
from sk_offwhite.effects import Overflow
from sk_offwhite.effects._laws import relaxations
from sk_offwhite.loop._switchboard import Switchboard

TRUE_EXPONENT = 0.3


def _tank_step(x, u, theta):
    """A tank draining through an outlet of law k x^a, Euler step of 1 s."""
    return jnp.array([x[0] + (-theta["k"] * jnp.maximum(x[0], 1e-6) ** theta["a"] + u[0])])


def _tank(exponent=0.5, relaxable=True):
    law = Parameter(exponent, (0.05, 1.5), fixed=True, relaxable=relaxable)
    parameters = {"k": Parameter(0.2, (1e-6, None)), "a": law}
    return PhysicsModel(_tank_step, [0], parameters, 1, 1, x0=[4.0], state_names=("level",))


@pytest.fixture(scope="module")
def tank_data():
    """A tank whose outlet follows x^0.3 (not Torricelli's x^0.5), 1 % noise."""
    rng = np.random.default_rng(1)
    u = np.repeat(rng.uniform(0.1, 0.6, size=(40, 1)), 10, axis=0)
    x, levels = 4.0, []
    for u_k in u[:, 0]:
        levels.append(x)
        x = x + (-0.3 * max(x, 1e-6) ** TRUE_EXPONENT + u_k)
    return u, np.asarray(levels)[:, None] * (1 + 0.01 * rng.normal(size=(400, 1)))


def test_relaxations_list_the_fixed_relaxable_parameters():
    physics = _tank()
    assert relaxations(physics) == [RelaxedLaw("a", 0.5, (0.05, 1.5))]
    assert relaxations(_tank(relaxable=False)) == []
    assert relaxations(cascaded_tanks_physics()) == []
    assert [
        law.parameter for law in relaxations(cascaded_tanks_physics(relaxable_exponents=True))
    ] == ["a1", "a2"]


def test_a_relaxable_parameter_must_be_fixed():
    with pytest.raises(ValueError, match="relaxable=True applies to a fixed parameter"):
        Parameter(0.5, relaxable=True)


def test_only_a_relaxable_parameter_can_be_freed():
    with pytest.raises(ValueError, match="'a' clashes"):
        augment(_tank(relaxable=False), RelaxedLaw("a", 0.5))


def test_relaxing_frees_the_constant_and_keeps_the_programs():
    physics = _tank()
    relaxed = augment(physics, *relaxations(physics))
    assert not relaxed.parameters["a"].fixed and relaxed.parameters["a"].value == 0.5
    assert physics.parameters["a"].fixed  # the declared model is left alone
    assert relaxed.step is physics.step and relaxed.output is physics.output


def test_the_relaxed_law_recovers_the_true_exponent(tank_data):
    u, z = tank_data
    declared = GreyBoxSparseRegressor(_tank()).fit(u, z)
    relaxed = GreyBoxSparseRegressor(augment(_tank(), RelaxedLaw("a", 0.5, (0.05, 1.5))))
    relaxed.fit(u, z)
    assert relaxed.parameters_["a"] == pytest.approx(TRUE_EXPONENT, abs=0.02)
    assert relaxed.score(u, z) > declared.score(u, z)
    law = RelaxedLaw("a", 0.5)
    assert "fitted at 0.3" in law.describe(["level"], ["level"], relaxed.parameters_)


def test_the_switchboard_applies_relaxed_laws_without_a_switch():
    physics = _tank()
    law, overflow = RelaxedLaw("a", 0.5, (0.05, 1.5)), Overflow(0, 5.0)
    board = Switchboard.of(physics, [law, overflow])
    assert board.ordered([overflow, law]) == (overflow, law)
    on = board.model([law])
    assert not on.parameters["a"].fixed and on.parameters["overflow_on"].value == 0.0
    assert board.model([overflow]).parameters["a"].fixed


@pytest.mark.slow
def test_the_loop_frees_a_declared_law_the_data_reject(tank_data):
    """The only thing wrong with the declared tank is Torricelli's exponent."""
    import pysindy as ps

    from sk_offwhite.loop import LoopSettings, close_the_loop

    u, z = tank_data
    settings = LoopSettings(n_folds=3, max_iter=100, fit_delta=False)
    result = close_the_loop(_tank(), ps.PolynomialLibrary(degree=2), u, z, settings=settings)
    assert [effect.name for effect in result.effects] == ["relax_a"]
    assert result.cv_errors["final"] < 0.2 * result.cv_errors["baseline"]
    assert result.final.parameters_["a"] == pytest.approx(TRUE_EXPONENT, abs=0.02)
