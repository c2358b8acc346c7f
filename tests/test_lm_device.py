"""Levenberg-Marquardt with the whole run on the device takes the host loop's steps: the two
runners of the package apply one set of rules."""

import dataclasses

import jax
import numpy as np
import pysindy as ps
import pytest
from conftest import solver_problem, tanks_physics

from sk_offwhite import GreyBoxSparseRegressor
from sk_offwhite.solvers._core import forward_mode, free_residuals, linearised
from sk_offwhite.solvers._dense import _lm_advance, _origin, first_state
from sk_offwhite.solvers._device import _padded, levenberg_marquardt_on_device, padded_size
from sk_offwhite.solvers._host import lm_loop


def levenberg_marquardt(free0, problem, model, layout, *, max_iter, tol, scaling="per-variable"):
    """The dense step driven by the host runner: the reference the device run must match."""
    static = dict(model=model, layout=layout, forward=forward_mode(free0, problem, model, layout))

    def linearise(free):
        return first_state(free, problem, scaling=scaling, **static)

    def trial(state, damping, scale):
        new, cost, accepted = _lm_advance(_origin(state), damping, scale, True, problem, **static)
        cost, accepted = jax.device_get((cost, accepted))
        return new.free, float(cost), new if accepted else None

    options = dict(max_iter=max_iter, tol=tol, scaling=scaling)
    return lm_loop(linearise, trial, free0, problem, **options)


@pytest.fixture(autouse=True)
def _double_precision():
    """The estimator fits in double precision; so do these tests."""
    with jax.enable_x64(True):
        yield


def _problem(tanks_data, with_library: bool, horizon=None):
    """One record (cut into windows of ``horizon`` samples, if given), optionally with a
    degree-2 dictionary whose weights start just off zero (away from the L1 kink)."""
    u, z, _ = tanks_data
    physics = tanks_physics(x0=[z[0, 0], z[0, 0]])
    return solver_problem(physics, [(u[:400], z[:400])], horizon, with_library, 1e-6)


@pytest.mark.parametrize(
    "with_library, scaling, max_iter, horizon",
    [
        (False, "per-variable", 100, None),
        (True, "per-variable", 60, None),
        (True, "global", 60, None),
        (True, "per-variable", 3, None),
        (False, "global", 100, 64),
    ],
)
def test_the_device_run_takes_the_host_loops_steps(
    tanks_data, with_library, scaling, max_iter, horizon
):
    problem, free0, model, layout = _problem(tanks_data, with_library, horizon)
    options = dict(max_iter=max_iter, tol=1e-10, scaling=scaling)
    host = levenberg_marquardt(free0, problem, model, layout, **options)
    device = levenberg_marquardt_on_device(free0, problem, model, layout, **options)
    assert (device.n_iter, device.converged, device.message) == (
        host.n_iter,
        host.converged,
        host.message,
    )
    np.testing.assert_allclose(device.history, host.history, rtol=1e-10)
    np.testing.assert_allclose(device.free, host.free, rtol=1e-8, atol=1e-12)
    assert device.cost == device.history[-1]
    np.testing.assert_allclose(device.fit, host.fit, rtol=1e-10)


def test_padding_adds_variables_without_influence(tanks_data):
    problem, free0, model, layout = _problem(tanks_data, with_library=True)
    n_free = free0.shape[0]
    assert [padded_size(n, 4) for n in (8, 9, 12)] == [8, 12, 12]
    padded_free, padded = _padded(free0, problem, layout.size, n_free + 3)
    assert padded_free.shape == (n_free + 3,)
    residual = free_residuals(free0, problem, model, layout)
    np.testing.assert_array_equal(free_residuals(padded_free, padded, model, layout), residual)
    _, jac = linearised(lambda free: free_residuals(free, padded, model, layout), padded_free)
    assert np.any(jac[:, :n_free]) and not np.any(jac[:, n_free:])
    options = dict(max_iter=20, tol=1e-10)
    run = levenberg_marquardt(padded_free, padded, model, layout, **options)
    plain = levenberg_marquardt(free0, problem, model, layout, **options)
    assert np.all(run.free[n_free:] == 0.0) and run.n_iter == plain.n_iter
    np.testing.assert_allclose(run.history, plain.history, rtol=1e-8)
    np.testing.assert_allclose(run.free[:n_free], plain.free, rtol=1e-6, atol=1e-10)
    # a model with switched effects is padded by the device run itself
    switchboard = dataclasses.replace(model, free_multiple=n_free + 3)
    device = levenberg_marquardt_on_device(free0, problem, switchboard, layout, **options)
    assert device.free.shape == (n_free,) and device.n_iter == run.n_iter
    np.testing.assert_allclose(device.history, run.history, rtol=1e-10)


def test_a_run_from_its_own_solution_stops_as_the_host_loop_does(tanks_data):
    problem, free0, model, layout = _problem(tanks_data, with_library=False)
    options = dict(max_iter=200, tol=1e-10)
    solution = levenberg_marquardt(free0, problem, model, layout, **options).free
    host = levenberg_marquardt(solution, problem, model, layout, **options)
    device = levenberg_marquardt_on_device(solution, problem, model, layout, **options)
    assert device.converged and device.message == host.message
    assert device.n_iter == host.n_iter
    np.testing.assert_array_equal(device.free, host.free)


def test_the_device_run_names_a_wrong_scaling(tanks_data):
    problem, free0, model, layout = _problem(tanks_data, with_library=False)
    with pytest.raises(ValueError, match="scaling must be one of"):
        levenberg_marquardt_on_device(
            free0, problem, model, layout, max_iter=5, tol=1e-10, scaling="unit"
        )


def test_a_verbose_fit_prints_its_progress_and_takes_the_same_steps(tanks_data, capsys):
    u, z, _ = tanks_data
    library = ps.PolynomialLibrary(degree=2)
    quiet = GreyBoxSparseRegressor(tanks_physics(), library=library, gamma=1e-3, max_iter=50)
    quiet.fit(u[:400], z[:400])
    assert "iter" not in capsys.readouterr().out
    loud = GreyBoxSparseRegressor(
        tanks_physics(), library=library, gamma=1e-3, max_iter=50, verbose=2
    ).fit(u[:400], z[:400])
    printed = [line for line in capsys.readouterr().out.splitlines() if " iter " in line]
    assert len(printed) >= 2 and printed[0].split()[2] == "1"  # from the first step on
    assert loud.n_iter_ == quiet.n_iter_
    np.testing.assert_array_equal(loud.coef_, quiet.coef_)
    np.testing.assert_array_equal(loud.loss_history_, quiet.loss_history_)
