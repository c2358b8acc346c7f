"""Fitting behaviour of GreyBoxSparseRegressor on synthetic systems with known truth."""

import subprocess
import sys
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pysindy as ps
import pytest
from conftest import TANKS_TRUE, TANKS_X0, multisine, simulate_numpy, tanks_physics, tanks_step
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning

from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel
from sk_offwhite._layout import Layout
from sk_offwhite._problem import (
    bound_blocks,
    free_blocks,
    initial_blocks,
    make_problem,
)
from sk_offwhite._segments import make_segments
from sk_offwhite.solvers._core import free_residuals
from sk_offwhite.solvers._optax import _optax_iteration, default_optimizer


def _relative_errors(est):
    errors = [abs(est.parameters_[k] / v - 1) for k, v in TANKS_TRUE.items()]
    return np.array(errors + list(np.abs(est.x0_ / TANKS_X0 - 1)))


@pytest.mark.parametrize("horizon", [None, 256])
def test_noise_free_tanks_recovered(tanks_data, horizon):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    est = GreyBoxSparseRegressor(physics, horizon=horizon, max_iter=300).fit(u, z)
    assert _relative_errors(est).max() < 1e-3
    assert est.converged_
    assert est.parameters_["k4"] == TANKS_TRUE["k4"]


def test_multiple_experiments_each_get_an_initial_state():
    rng = np.random.default_rng(1)
    starts = [np.array([3.5, 5.2]), np.array([6.0, 2.0])]
    us = [multisine(400, rng), multisine(400, rng)]
    zs = [
        simulate_numpy(tanks_step, TANKS_TRUE, x0, u)[:, 1:2]
        for x0, u in zip(starts, us, strict=True)
    ]
    physics = tanks_physics(x0=[5.0, 5.0])
    est = GreyBoxSparseRegressor(physics, max_iter=300).fit(us, zs)
    np.testing.assert_allclose(est.initial_states_, np.stack(starts), rtol=1e-3)
    np.testing.assert_allclose(est.theta_, list(TANKS_TRUE.values()), rtol=1e-3)
    predictions = est.predict(us[1], x0=starts[1])
    np.testing.assert_allclose(predictions, zs[1], atol=1e-4)


def test_gap_in_sample_index_is_not_simulated_through(tanks_data):
    """Two non-adjacent blocks fitted with sample_index == the same blocks as a list."""
    u, z, _ = tanks_data
    keep = np.r_[0:300, 600:1024]
    physics = tanks_physics(x0=[5.0, 5.0])
    joined = GreyBoxSparseRegressor(physics, max_iter=300).fit(u[keep], z[keep], keep)
    split = GreyBoxSparseRegressor(physics, max_iter=300).fit(
        [u[:300], u[600:]], [z[:300], z[600:]]
    )
    np.testing.assert_allclose(joined.theta_, split.theta_, rtol=1e-6)
    np.testing.assert_allclose(joined.initial_states_, split.initial_states_, rtol=1e-6)
    assert joined.initial_states_.shape == (2, 2)


def test_score_estimates_the_initial_state_of_a_later_block(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    est = GreyBoxSparseRegressor(physics, max_iter=300).fit(u[:512], z[:512])
    assert est.score(u[700:], z[700:]) > 0.999
    # without initial-state estimation the later block starts from the wrong state
    from_x0 = GreyBoxSparseRegressor(physics, max_iter=300, init_window=0).fit(u[:512], z[:512])
    assert from_x0.score(u[700:], z[700:]) < est.score(u[700:], z[700:])


def _problem_for(est, physics, u, z, library=None):
    records = [(u, z)]
    est_basis, model = est._compile(physics)
    segments = make_segments(records, est.horizon)
    blocks = initial_blocks(physics, est_basis, model, records, segments, est.horizon)
    blocks["theta"] = blocks["theta"] * 1.1
    if "omega" in blocks:
        blocks["omega"] = np.random.default_rng(0).normal(size=blocks["omega"].shape) * 0.01
    free = free_blocks(physics, est_basis, model, segments)
    layout = Layout.from_arrays(blocks)
    weights = (est.gamma, 0.0, 0.0, est.shooting_weight, est.l1_smoothing)
    problem, free0 = make_problem(
        layout, blocks, free, bound_blocks(physics, blocks, records, segments), segments, weights
    )
    return model, layout, problem, free0


def test_gradient_matches_finite_differences(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[5.0, 5.0])
    est = GreyBoxSparseRegressor(
        physics, library=ps.PolynomialLibrary(degree=2), gamma=0.01, horizon=200, l1_smoothing=10.0
    )
    with jax.enable_x64(True):
        model, layout, problem, free0 = _problem_for(est, physics, u[:400], z[:400])

        @jax.jit
        def cost(free):
            r = free_residuals(free, problem, model, layout)
            return r @ r

        grad = np.asarray(jax.grad(cost)(free0))
        forward = np.asarray(jax.jacfwd(cost)(free0))
        eps = 1e-7
        fd = np.array(
            [
                (cost(free0.at[i].add(eps)) - cost(free0.at[i].add(-eps))) / (2 * eps)
                for i in range(free0.shape[0])
            ]
        )
    np.testing.assert_allclose(grad, fd, rtol=1e-4, atol=1e-8)
    np.testing.assert_allclose(forward, grad, rtol=1e-10, atol=1e-12)


def test_correction_has_exact_zeros_and_equations_print(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    est = GreyBoxSparseRegressor(physics, library=ps.PolynomialLibrary(degree=1), gamma=1e-3).fit(
        u[:300], z[:300]
    )
    assert est.coef_.shape == (2, 4)
    assert est.n_nonzero_ < est.coef_.size  # the physics is complete: pruning zeroes terms
    np.testing.assert_array_equal(est.support_, est.coef_ != 0)
    assert est.feature_names_ == ["1", "x1", "x2", "u"]
    lines = est.equations()
    assert lines[0].startswith("x1[k+1] = f_1(x[k], u[k]; θ)")
    assert len(lines) == 2


def test_delta_states_restricts_the_correction(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    est = GreyBoxSparseRegressor(
        physics, library=ps.PolynomialLibrary(degree=1), delta_states=[1], max_iter=20
    ).fit(u[:200], z[:200])
    assert est.coef_.shape == (1, 4)
    assert est.delta_states_ == (1,)


def test_divergent_optax_fit_keeps_best_finite_iterate(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    est = GreyBoxSparseRegressor(physics, solver="optax", optimizer=optax.sgd(1e6), max_iter=50)
    with pytest.warns(ConvergenceWarning, match="diverged"):
        est.fit(u[:200], z[:200])
    assert np.all(np.isfinite(est.theta_))
    assert np.all(np.isfinite(est.predict(u[:200])))


def test_optax_solver_decreases_the_cost(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    est = GreyBoxSparseRegressor(physics, solver="optax", max_iter=150)
    with pytest.warns(ConvergenceWarning):  # 150 Adam steps do not converge: said, not hidden
        est.fit(u[:300], z[:300])
    assert est.loss_history_[-1] < 0.2 * est.loss_history_[0]


def test_the_default_optax_optimizer_is_built_once_and_compiled_once(tanks_data):
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    assert default_optimizer(40) is default_optimizer(40)
    assert default_optimizer(40) is not default_optimizer(41)  # its schedule spans max_iter
    est = GreyBoxSparseRegressor(physics, solver="optax", max_iter=40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        est.fit(u[:200], z[:200])
        traced = _optax_iteration._cache_size()
        clone(est).fit(u[:200], z[:200])
    assert _optax_iteration._cache_size() == traced  # the clone's fit reused the program


def test_a_levenberg_marquardt_fit_does_not_import_optax():
    code = (
        "import sys, sk_offwhite; from sk_offwhite.datasets import make_cascaded_tanks;"
        "d = make_cascaded_tanks(n_samples=100, random_state=0);"
        "sk_offwhite.GreyBoxSparseRegressor(d.physics, max_iter=5).fit(d.u, d.z);"
        "assert 'optax' not in sys.modules, 'optax imported'"
    )
    subprocess.run([sys.executable, "-W", "ignore", "-c", code], check=True)


def test_continuous_time_model_matches_euler_discretisation(tanks_data):
    u, z, _ = tanks_data

    def rhs(x, u, theta):
        return (tanks_step(x, u, theta) - x) / 4.0

    parameters = {k: Parameter(v, fixed=(k == "k4")) for k, v in TANKS_TRUE.items()}
    physics = PhysicsModel.from_ode(
        rhs, 4.0, [1], parameters, 2, 1, method="euler", x0=TANKS_X0, x0_fixed=True
    )
    est = GreyBoxSparseRegressor(physics, max_iter=5).fit(u[:100], z[:100])
    np.testing.assert_allclose(est.predict(u[:100], x0=TANKS_X0), z[:100], atol=1e-8)


def test_penalties_change_the_fit(tanks_data):
    u, z, _ = tanks_data

    def k3_at_most(x, u, theta):
        return jnp.atleast_1d(theta["k3"] - 0.03)

    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    physics.inequality = k3_at_most
    plain = GreyBoxSparseRegressor(physics, max_iter=100).fit(u[:300], z[:300])
    penalised = GreyBoxSparseRegressor(physics, lam=100.0, max_iter=100).fit(u[:300], z[:300])
    assert plain.parameters_["k3"] > 0.04
    assert penalised.parameters_["k3"] < plain.parameters_["k3"] - 0.005


def test_global_jax_config_is_untouched(tanks_data):
    u, z, _ = tanks_data
    before = jax.config.jax_enable_x64
    GreyBoxSparseRegressor(tanks_physics(), max_iter=3).fit(u[:50], z[:50])
    assert jax.config.jax_enable_x64 == before
    assert jnp.ones(1).dtype == (jnp.float64 if before else jnp.float32)


def test_inputs_and_library_are_not_mutated(tanks_data):
    u, z, _ = tanks_data
    u_copy, z_copy = u[:100].copy(), z[:100].copy()
    library = ps.PolynomialLibrary(degree=2)
    GreyBoxSparseRegressor(tanks_physics(), library=library, max_iter=3).fit(u_copy, z_copy)
    np.testing.assert_array_equal(u_copy, u[:100])
    np.testing.assert_array_equal(z_copy, z[:100])
    assert not hasattr(library, "powers_") and not hasattr(library, "n_features_in_")


def test_warm_start_refines_a_multiple_shooting_fit(tanks_data):
    u, z, _ = tanks_data
    est = GreyBoxSparseRegressor(tanks_physics(x0=[5.2, 5.2]), horizon=128, max_iter=300)
    est.fit(u, z)
    cold = GreyBoxSparseRegressor(tanks_physics(init=0.07, x0=[5.2, 5.2]), max_iter=300).fit(u, z)
    est.set_params(horizon=None, warm_start=True).fit(u, z)
    assert _relative_errors(est).max() < 1e-6
    assert est.n_iter_ < cold.n_iter_
    assert est.parameters_["k4"] == TANKS_TRUE["k4"]


def test_simulate_returns_states_and_the_correction_along_the_trajectory(tanks_data):
    u, z, _ = tanks_data
    library = ps.PolynomialLibrary(degree=1)
    est = GreyBoxSparseRegressor(
        tanks_physics(x0=[5.2, 5.2]), library=library, gamma=1e-4, prune_tol=0.0, refit=False
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        est.fit(u[:300], z[:300] + 1e-3 * np.random.default_rng(0).standard_normal((300, 1)))
    assert est.n_nonzero_ > 0  # unpruned: the correction along the trajectory is not zero
    run = est.simulate(u[:300])
    np.testing.assert_allclose(run.outputs, est.predict(u[:300]))
    np.testing.assert_allclose(run.states[:, 1:2], run.outputs)
    features = ps.PolynomialLibrary(degree=1).fit_transform(np.hstack([run.states, u[:300]]))
    np.testing.assert_allclose(run.correction, features @ est.coef_.T, atol=1e-12)


def test_a_diverging_simulation_scores_minus_infinity():
    physics = PhysicsModel(
        lambda x, u, theta: theta["a"] * x + u, [0], {"a": Parameter(10.0, fixed=True)}, 1, 1
    )
    u = np.zeros((400, 1))
    z = 10.0 ** np.arange(5.0)[:, None]
    est = GreyBoxSparseRegressor(physics, init_window=0).fit(u[:5], z)
    np.testing.assert_allclose(est.x0_, [1.0])
    with pytest.warns(RuntimeWarning, match="diverged"):
        assert est.score(u, np.ones((400, 1))) == -np.inf
