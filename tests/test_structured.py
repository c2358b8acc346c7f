"""Levenberg-Marquardt with a coloured Jacobian for multiple shooting over many windows."""

import warnings
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import solver_problem, tanks_physics
from sklearn.exceptions import ConvergenceWarning

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite._objective import residual_parts
from sk_offwhite._sparsity import block_columns
from sk_offwhite.datasets import make_cascaded_tanks
from sk_offwhite.solvers import _core as core
from sk_offwhite.solvers._coloured import (
    _compressed,
    _linearise,
    colouring,
    structured_levenberg_marquardt,
)
from sk_offwhite.solvers._core import (
    LINEARIZE_MAX_FREE,
    _omega,
    forward_mode,
    free_residuals,
    jacobian_columns,
    linearised,
    n_residuals,
)
from sk_offwhite.solvers._dense import _anchored, _lm_advance, _origin, first_state, majorised_cost
from sk_offwhite.solvers._device import levenberg_marquardt_on_device as levenberg_marquardt


@pytest.fixture(autouse=True)
def _double_precision():
    """The estimator fits in double precision; so do these tests."""
    with jax.enable_x64(True):
        yield


def _windowed_problem(tanks_data, with_library: bool, horizon=16):
    """Two records cut into windows, a non-negativity constraint, optionally a dictionary."""
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    physics.inequality = lambda x, u, theta: -x
    records = [(u[:150], z[:150]), (u[200:330], z[200:330])]
    return solver_problem(physics, records, horizon, with_library, omega_start=1e-3)


@pytest.mark.parametrize("with_library", [False, True])
def test_coloured_jacobian_equals_the_dense_one(tanks_data, with_library):
    problem, free0, model, layout = _windowed_problem(tanks_data, with_library)
    anchored = _anchored(problem, _omega(free0, problem, layout))  # as the solver forms it
    columns = jnp.arange(free0.shape[0])
    dense = jacobian_columns(free0, anchored, columns, model=model, layout=layout)[1]
    parts = residual_parts(
        model,
        layout.unflatten(problem.base.at[problem.free_index].set(free0)),
        problem.segments,
        problem.omega_free,
        problem.weights,
    )
    sizes = [int(np.size(p)) for p in parts]
    plan = colouring(layout, np.asarray(problem.free_index), problem.segments, sizes)
    _, compressed, _, _ = _compressed(
        free0, jnp.asarray(plan.seeds), problem, model=model, layout=layout
    )
    assert sizes[3] > 0  # the constraint rows are covered
    assert plan.seeds.shape[1] == plan.glob.shape[0] + 2 * 2  # G + 2 n_x tangents
    rebuilt = np.zeros(np.shape(dense))
    rebuilt[plan.rows, plan.cols] = np.asarray(compressed)[plan.rows, plan.colours]
    np.testing.assert_allclose(rebuilt, np.asarray(dense), rtol=1e-10, atol=1e-12)
    state = _linearise(free0, problem, model, layout, plan)
    normal = np.asarray(dense).T @ np.asarray(dense)
    np.testing.assert_allclose(state.normal_gg, normal[np.ix_(plan.glob, plan.glob)], atol=1e-9)


@pytest.mark.parametrize("scaling", ["global", "per-variable"])
def test_coloured_and_dense_levenberg_marquardt_agree(tanks_data, scaling):
    problem, free0, model, layout = _windowed_problem(tanks_data, with_library=False)
    options = dict(max_iter=40, tol=1e-12, scaling=scaling)
    dense = levenberg_marquardt(free0, problem, model, layout, **options)
    coloured = structured_levenberg_marquardt(free0, problem, model, layout, **options)
    assert coloured.n_iter == dense.n_iter
    np.testing.assert_allclose(coloured.history, dense.history, rtol=1e-8)
    np.testing.assert_allclose(coloured.free, dense.free, rtol=1e-6, atol=1e-9)


def test_long_multiple_shooting_needs_no_solver_choice():
    """7000 samples with horizon 32: 441 free variables, where 'auto' used to switch to
    Adam and reach R2 = -94 on the training data."""
    tanks = make_cascaded_tanks(n_samples=7000, overflow=False, saturation=False, random_state=0)
    est = GreyBoxSparseRegressor(tanks.physics, horizon=32, max_iter=60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # creeps at the sqrt's floor
        est.fit(tanks.u, tanks.z)
    assert est.score(tanks.u, tanks.z) >= 0.998


def test_reverse_and_forward_jacobians_agree(tanks_data):
    problem, free0, model, layout = _windowed_problem(tanks_data, with_library=True)
    fun = partial(free_residuals, problem=problem, model=model, layout=layout)
    value_f, jac_f = linearised(fun, free0, forward=True)
    value_r, jac_r = linearised(fun, free0, forward=False)
    np.testing.assert_allclose(value_f, value_r, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(jac_r, jac_f, rtol=1e-9, atol=1e-12)


def test_the_linearisation_is_used_only_for_few_columns_and_loops_not_fused(monkeypatch):
    for fused in (False, True):
        monkeypatch.setattr(core, "fused_loops", lambda fused=fused: fused)
        assert core._through_linearisation(LINEARIZE_MAX_FREE) is not fused
        assert not core._through_linearisation(LINEARIZE_MAX_FREE + 1)


def test_the_linearisation_and_jacfwd_give_the_same_jacobian(monkeypatch):
    def simulated(x):  # a short rollout: the kind of function the solver differentiates
        def step(state, k):
            state = state + 0.1 * jnp.tanh(x * state + k)
            return state, state @ x

        return jax.lax.scan(step, jnp.ones(5), jnp.arange(20.0))[1]

    jacobians = []
    with jax.enable_x64(True):
        for fused in (False, True):  # through jax.linearize, then through jacfwd
            monkeypatch.setattr(core, "fused_loops", lambda fused=fused: fused)
            _, jacobian = linearised(simulated, jnp.linspace(0.1, 0.5, 5))
            jacobians.append(np.asarray(jacobian))
    assert jacobians[0].shape == (20, 5) and np.abs(jacobians[0]).max() > 0.1
    np.testing.assert_allclose(jacobians[0], jacobians[1], rtol=1e-12, atol=1e-15)


def test_the_mode_follows_the_residual_count_when_the_record_is_short(tanks_data):
    problem, free0, model, layout = _windowed_problem(tanks_data, with_library=True)
    assert forward_mode(free0, problem, model, layout)  # settled by the record's length
    segments = problem.segments
    first = {name: getattr(segments, name)[:, :1] for name in ("u", "z", "mask")}
    short = problem._replace(segments=segments._replace(**first))
    n_fit = int(np.size(short.segments.z))
    assert free0.shape[0] > n_fit  # the count has to be traced
    wide = forward_mode(free0, short, model, layout)
    assert wide == (free0.shape[0] <= n_residuals(free0, short, model, layout))


@pytest.mark.parametrize("forward", [True, False], ids=["jacfwd", "jacrev"])
def test_an_lm_iteration_forms_the_normal_equations_only_at_an_accepted_candidate(
    tanks_data, forward
):
    """The same program accepts or rejects (the current cost ``inf`` or ``-inf``): the
    candidate and its cost at the old anchor are the same either way; the normal equations
    are those at the candidate when it is accepted, zeros when it is rejected. In both
    modes of the Jacobian: they agree with each other."""
    problem, free0, model, layout = _windowed_problem(tanks_data, with_library=True)
    omega_at, _ = block_columns(layout, np.asarray(problem.free_index), "omega")
    start = np.array(free0)
    start[omega_at] = 1e-4 * np.arange(1, omega_at.size + 1)  # the anchor matters
    static = dict(model=model, layout=layout, forward=forward)
    state = first_state(jnp.asarray(start), problem, scaling="per-variable", **static)
    origin = _origin(state)
    outcome = {
        name: _lm_advance((*origin[:-1], np.array(current)), 10.0, state.diag, True, problem,
                          **static)
        for name, current in (("accepted", np.inf), ("rejected", -np.inf))
    }  # fmt: skip
    (accepted, cost, taken), (rejected, rejected_cost, refused) = outcome.values()
    assert bool(taken) and not bool(refused)
    np.testing.assert_array_equal(rejected.free, accepted.free)
    assert np.isfinite(cost) and float(rejected_cost) == float(cost)
    at_old_anchor = majorised_cost(accepted.free, state.anchor, problem, model, layout)
    np.testing.assert_allclose(cost, at_old_anchor, rtol=1e-12)
    assert not np.any(np.asarray(rejected.jtj)) and not np.any(np.asarray(rejected.gradient))
    there = first_state(accepted.free, problem, scaling="per-variable", **static)
    for name in ("jtj", "gradient", "diag", "cost", "anchor"):
        np.testing.assert_allclose(getattr(accepted, name), getattr(there, name), rtol=1e-10)
    assert not np.allclose(accepted.anchor, state.anchor)
    other = first_state(
        accepted.free, problem, scaling="per-variable", **static | {"forward": not forward}
    )
    np.testing.assert_allclose(accepted.jtj, other.jtj, rtol=1e-9, atol=1e-12)
