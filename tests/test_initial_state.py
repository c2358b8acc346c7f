"""The initial state estimated from a window of measurements (``predict(..., z_init=...)``)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import TANKS_TRUE, simulate_numpy, tanks_physics
from scipy.optimize import least_squares

from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel
from sk_offwhite.simulation._initial import _solve_window, estimate_initial_state, window_residual


@pytest.fixture(scope="module")
def fitted(tanks_data):
    u, z, _ = tanks_data
    est = GreyBoxSparseRegressor(tanks_physics(), max_iter=50).fit(u[:300], z[:300])
    return est, u


def _record_from(est, u, x0):
    """The fitted model's own outputs from ``x0``: the window's exact initial state is known."""
    return est.predict(u, x0=x0).reshape(-1, 1)


@pytest.mark.parametrize("start", [(3.0, 2.0), (0.4, 6.0), (9.0, 0.5)])
def test_the_hidden_state_comes_back_from_the_outputs(fitted, start):
    est, u = fitted
    window_u = u[400:450]
    z = _record_from(est, window_u, np.array(start))
    found = est.simulate(window_u, z_init=z).x0
    np.testing.assert_allclose(found, start, rtol=1e-6)


def test_it_agrees_with_a_general_least_squares_solver(fitted):
    est, u = fitted
    window_u = u[600:650]
    z = _record_from(est, window_u, np.array([4.0, 3.0])) + 0.05 * np.sin(np.arange(50))[:, None]
    model, blocks = est._fitted_model(), est._fitted_blocks()
    guess = np.array([2.0, 2.0])
    found = estimate_initial_state(model, blocks, window_u, z, guess, [True, True])

    def residual(x0):
        with jax.enable_x64(True):
            params = {k: jnp.asarray(v) for k, v in blocks.items()}
            return np.asarray(window_residual(model, params, jnp.asarray(x0), window_u, z, 1.0))

    reference = least_squares(residual, guess, xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    np.testing.assert_allclose(found, reference, rtol=1e-6)


def test_fixed_states_stay_at_the_guess(fitted):
    est, u = fitted
    window_u = u[400:450]
    z = _record_from(est, window_u, np.array([3.0, 2.0]))
    model, blocks = est._fitted_model(), est._fitted_blocks()
    found = estimate_initial_state(model, blocks, window_u, z, [5.0, 1.0], [True, False])
    assert found[1] == 1.0
    assert found[0] != 5.0
    none_free = estimate_initial_state(model, blocks, window_u, z, [5.0, 1.0], [False, False])
    np.testing.assert_array_equal(none_free, [5.0, 1.0])


def _bare_torricelli(x, u, theta):
    """The tanks with a bare square root: NaN once a state is negative."""
    ts = 4.0
    q1, q2 = theta["k1"] * jnp.sqrt(x[0]), theta["k3"] * jnp.sqrt(x[1])
    return x + ts * jnp.stack([-q1 + theta["k4"] * u[0], theta["k2"] / theta["k1"] * q1 - q2])


def test_steps_into_undefined_states_are_rejected():
    """A start next to the empty tanks: steps that cross zero give NaN outputs and must be
    refused, and the state is still found."""
    u = np.full((60, 1), 3.0)
    x0_true = np.array([0.2, 0.3])
    theta = {name: Parameter(value, fixed=True) for name, value in TANKS_TRUE.items()}
    physics = PhysicsModel(_bare_torricelli, [1], theta, n_states=2, n_inputs=1)
    z = simulate_numpy(_bare_torricelli, TANKS_TRUE, x0_true, u)[:, 1:2]
    est = GreyBoxSparseRegressor(physics, max_iter=1).fit(u, z)
    model, blocks = est._fitted_model(), est._fitted_blocks()
    for guess in ([0.01, 0.01], [3.0, 0.02]):
        found = estimate_initial_state(model, blocks, u[:30], z[:30], guess, [True, True])
        np.testing.assert_allclose(found, x0_true, rtol=1e-5)


def test_one_program_per_model_and_window_length(fitted):
    est, u = fitted
    before = _solve_window._cache_size()
    for start in (100, 300, 500):
        est.predict(u[start : start + 200], z_init=_record_from(est, u[start : start + 40], [2, 2]))
    est.predict(u[:200], z_init=_record_from(est, u[:40], [2, 2]))
    assert _solve_window._cache_size() - before <= 1
