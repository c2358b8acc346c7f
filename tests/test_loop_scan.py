"""The loop's scan: candidates ranked by the error one Gauss-Newton step would reach."""

import numpy as np
import pytest

from sk_offwhite import Bias, Friction, GreyBoxSparseRegressor, Leak, OutputOffset, Parameter
from sk_offwhite.datasets import make_leaky_tank
from sk_offwhite.loop import LoopSettings, warm_physics
from sk_offwhite.loop._candidates import Candidate
from sk_offwhite.loop._fits import member_start
from sk_offwhite.loop._scan import scan_note, scan_scores, step_error, to_fit
from sk_offwhite.loop._search import Search
from sk_offwhite.loop._switchboard import single_effect_models


def test_a_residual_in_the_span_of_the_jacobian_is_removed():
    rng = np.random.default_rng(0)
    jacobian = rng.normal(size=(50, 3)) * [1e-6, 1.0, 1e4]  # the scales must not matter
    assert step_error(jacobian @ [2.0, -1.0, 0.5], jacobian) < 1e-9
    residual = rng.normal(size=50)
    assert step_error(residual, np.zeros((50, 2))) == pytest.approx(np.sqrt(np.mean(residual**2)))


def test_the_best_scores_and_the_unjudged_are_fitted():
    assert to_fit([0.3, np.nan, 0.1, 0.9, 0.2], 2) == [False, True, True, False, True]
    assert to_fit([0.3, 0.1], None) == [True, True]
    note = scan_note([Candidate(Leak(0), "r")] * 2, [0.5, 0.1], [False, True])
    assert "2 proposed, 2 scanned" in note and "1 fitted" in note and "leak (0.5)" in note


@pytest.fixture(scope="module")
def leaky():
    tank = make_leaky_tank(n_samples=400, random_state=0)
    declared = GreyBoxSparseRegressor(tank.physics, max_iter=100).fit(tank.u, tank.z)
    return tank, warm_physics(tank.physics, declared), declared


def test_the_missing_leak_scans_best(leaky):
    """On a tank whose physics lacks a leak, the leak's scan score is the lowest and
    removes most of the declared error, well ahead of a bias or an output offset."""
    tank, start, declared = leaky
    candidates = [Candidate(e, "test") for e in (OutputOffset(0), Bias(0), Leak(0))]
    models = single_effect_models(start, [c.effect for c in candidates])
    search = Search(tank.u, tank.z, LoopSettings())
    scores = scan_scores(search, models, candidates)
    error = np.reshape(declared.predict(tank.u), tank.z.shape) - tank.z
    declared_error = np.sqrt(np.mean(error**2))
    declared_error /= np.std(tank.z)
    assert np.argmin(scores) == 2
    assert scores[2] < 0.2 * declared_error
    assert scores[2] < 0.6 * min(scores[:2])


def test_a_pair_restarts_a_member_its_single_fit_left_on_a_bound():
    """A Coulomb friction fitted alone at level 0 (its bound: it helps only with a force
    offset) enters a joint fit at its own start; a level off the bound is kept."""
    friction = Friction(1, coulomb=0.2, width=0.01, name="fr")
    stuck = {"M": 3.0, "fr_coulomb": 0.0, "fr_width": 0.005}
    assert member_start(stuck, friction) == {"fr_coulomb": 0.2, "fr_width": 0.005}
    moved = {"fr_coulomb": Parameter(0.3, (0.0, None)), "fr_width": 0.005}
    assert member_start(moved, friction) == moved
    held = {"fr_coulomb": Parameter(0.0, (0.0, None))}
    assert member_start(held, friction)["fr_coulomb"].value == 0.2
