"""Identifiability, standard errors and the Theorem 1 bound, against exact answers.

* Cascaded Tanks (eq. 21) with only ``x2`` measured: scaling ``x1`` by ``a`` and
  ``(k1, k2, k4)`` by ``(sqrt(a), 1/sqrt(a), a)`` leaves the output unchanged, so ``H`` is
  singular along ``(k1, k2, k4, x1(0)) ~ (1/2, -1/2, 1, 1)`` in relative units, and regular
  once ``k1`` or ``k4`` is fixed.
* A model linear in its parameters: the Hessian is ``(2/N) X^T X``, the standard errors are
  the OLS ones and the output-noise sensitivity is ``-pinv(X)``.
* Vehicle lateral dynamics (Section 5.1), a small Monte Carlo study: every parametric error
  lies under the computed bound (5), with and without the black-box correction.
"""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest
from sklearn.exceptions import ConvergenceWarning, NotFittedError

from sk_offwhite import GreyBoxSparseRegressor, Parameter, PhysicsModel, fit_gamma_path
from sk_offwhite.certify import (
    UnidentifiableWarning,
    identifiability,
    induced_norm,
    parameter_error_bound,
)
from sk_offwhite.datasets import (
    cascaded_tanks_physics,
    make_cascaded_tanks,
    make_vehicle_lateral,
    vehicle_physics_known_registers,
)

TANKS_NAMES = ("k1", "k2", "k3", "k4")
SCALING_DIRECTION = {"k1": 0.5, "k2": -0.5, "k4": 1.0, "x1(0)": 1.0}


@pytest.fixture(scope="module")
def tanks():
    """Noise-free tanks record without overflow or saturation (eq. 21 is exact)."""
    return make_cascaded_tanks(
        n_samples=400, overflow=False, saturation=False, noise_std=0.0, random_state=0
    )


def _tanks_fit(data, fixed=None) -> GreyBoxSparseRegressor:
    """Fit started at the truth: the solution is the true parameters and initial state."""
    truth = [data.true_parameters[name] for name in TANKS_NAMES]
    physics = cascaded_tanks_physics(
        fixed=fixed, k_init=truth, x0=data.true_x0, sampling_time=data.sampling_time
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return GreyBoxSparseRegressor(physics, max_iter=40).fit(data.u, data.z)


def test_tanks_hessian_is_singular_along_the_x1_scaling(tanks):
    estimator = _tanks_fit(tanks)
    with pytest.warns(UnidentifiableWarning, match="k4"):
        report = identifiability(estimator, tanks.u, tanks.z)
    assert not report.identifiable
    assert len(report.unidentifiable_directions) == 1
    direction = report.unidentifiable_directions[0]
    expected = np.array(list(SCALING_DIRECTION.values())) / np.sqrt(2.5)
    assert set(direction) == set(SCALING_DIRECTION)
    np.testing.assert_allclose([direction[n] for n in SCALING_DIRECTION], expected, atol=1e-6)
    assert report.eigenvalues[0] < 1e-12 * report.eigenvalues[-1]
    assert all(np.isinf(report.standard_errors[name]) for name in SCALING_DIRECTION)
    assert np.isfinite(report.standard_errors["k3"])
    assert "NOT locally identifiable" in report.summary()


@pytest.mark.parametrize("fixed_name", ["k1", "k4"])
def test_tanks_hessian_is_regular_once_one_parameter_is_fixed(tanks, fixed_name):
    fixed = {fixed_name: tanks.true_parameters[fixed_name]}
    estimator = _tanks_fit(tanks, fixed)
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnidentifiableWarning)
        report = identifiability(estimator, tanks.u, tanks.z)
    assert report.identifiable
    assert report.unidentifiable_directions == ()
    assert fixed_name not in report.names
    assert report.eigenvalues[0] > 1e-7 * report.eigenvalues[-1]
    assert report.gradient_norm < 1e-10
    assert "locally identifiable" in report.summary()


def _fir_physics() -> PhysicsModel:
    """``x[k+1] = u[k]``, ``z[k] = a x[k] + b u[k]``: linear in ``(a, b)``, ``x0 = 0`` fixed."""

    def step(x, u, theta):
        return u[:1]

    def output(x, u, theta):
        return jnp.stack([theta["a"] * x[0] + theta["b"] * u[0]])

    params = {"a": Parameter(0.0), "b": Parameter(0.0)}
    return PhysicsModel(step, output, params, n_states=1, n_inputs=1, x0_fixed=True)


@pytest.fixture(scope="module")
def linear_fit():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(300, 1))
    regressors = np.column_stack([np.r_[0.0, u[:-1, 0]], u[:, 0]])
    noise = 0.1 * rng.uniform(-1, 1, size=300)
    z = regressors @ np.array([1.5, -0.7]) + noise
    estimator = GreyBoxSparseRegressor(_fir_physics(), max_iter=50).fit(u, z)
    return estimator, u, z, regressors, noise


def test_linear_model_standard_errors_match_ols(linear_fit):
    estimator, u, z, regressors, _ = linear_fit
    ols, rss, *_ = np.linalg.lstsq(regressors, z, rcond=None)
    np.testing.assert_allclose(estimator.theta_, ols, rtol=1e-8)
    n, p = regressors.shape
    sigma2 = rss[0] / (n - p)
    expected = np.sqrt(np.diag(sigma2 * np.linalg.inv(regressors.T @ regressors)))
    report = identifiability(estimator, u, z)
    assert report.names == ("a", "b")
    np.testing.assert_allclose(report.noise_variance, sigma2, rtol=1e-8)
    np.testing.assert_allclose([report.standard_errors[k] for k in "ab"], expected, rtol=1e-6)
    variance = estimator.output_scale_[0] ** 2  # the cost is normalised by the output's variance
    expected_hessian = 2.0 / (n * variance) * regressors.T @ regressors
    np.testing.assert_allclose(report.hessian, expected_hessian, rtol=1e-8)


def test_linear_model_sensitivity_is_the_least_squares_pseudo_inverse(linear_fit):
    estimator, u, z, regressors, noise = linear_fit
    bound = parameter_error_bound(estimator, u, z, noise_z=0.1)
    pseudo_inverse = np.linalg.pinv(regressors)
    np.testing.assert_allclose(bound.sensitivity_z, -pseudo_inverse, rtol=1e-6, atol=1e-12)
    m_z = np.linalg.norm(np.abs(pseudo_inverse).sum(axis=1))
    np.testing.assert_allclose(bound.m_z, m_z, rtol=1e-6)
    error = np.linalg.norm(estimator.theta_ - np.array([1.5, -0.7]))
    np.testing.assert_allclose(error, np.linalg.norm(pseudo_inverse @ noise), rtol=1e-6)
    assert error <= bound.bound
    np.testing.assert_allclose(bound.evaluate(noise_z=0.2), 2 * bound.bound)


def test_induced_norms_on_a_small_matrix():
    matrix = np.array([[1.0, -2.0], [3.0, 4.0]])
    assert induced_norm(matrix, np.inf, np.inf) == 7.0
    assert induced_norm(matrix, np.inf, 2) == pytest.approx(np.hypot(3.0, 7.0))
    assert induced_norm(matrix, 2, 2) == pytest.approx(np.linalg.norm(matrix, 2))
    assert induced_norm(matrix, 2, np.inf) == pytest.approx(5.0)
    with pytest.raises(ValueError, match="noise_norm"):
        induced_norm(matrix, 1, 2)


def test_clear_errors_on_unfitted_estimators_and_bad_arrays(linear_fit):
    estimator, u, z, *_ = linear_fit
    with pytest.raises(NotFittedError):
        identifiability(GreyBoxSparseRegressor(_fir_physics()), u, z)
    with pytest.raises(TypeError, match="GreyBoxSparseRegressor"):
        identifiability("not an estimator", u, z)
    with pytest.raises(ValueError, match="features"):
        identifiability(estimator, np.column_stack([u, u]), z)
    with pytest.raises(ValueError, match="z"):
        identifiability(estimator, u, np.r_[z[:-1], np.nan])
    with pytest.raises(ValueError, match="record"):
        identifiability(estimator, u, z, sample_index=np.r_[0:150, 160:310])
    with pytest.raises(ValueError, match="rtol"):
        identifiability(estimator, u, z, rtol=0.0)
    with pytest.raises(ValueError, match="noise_z"):
        parameter_error_bound(estimator, u, z, noise_z=-1.0)
    with pytest.raises(ValueError, match="error_norm"):
        parameter_error_bound(estimator, u, z, error_norm=1)


# ---------------------------------------------------------------- vehicle, Section 5.1
VEHICLE_SAMPLES = 300
VEHICLE_NOISE = 2e-4


def _vehicle_fits(data):
    """Physics + 12-term dictionary (support path as tests/test_vehicle.py), physics only."""
    physics = vehicle_physics_known_registers(data)
    with_delta = GreyBoxSparseRegressor(
        physics, data.suggested_library, delta_states=[0], max_iter=500
    )
    fit_gamma_path(with_delta, data.u, data.z)
    without = GreyBoxSparseRegressor(physics, None, max_iter=500).fit(data.u, data.z)
    return {"with": with_delta, "without": without}


def _monte_carlo_point(data, estimator) -> tuple[float, float]:
    """Parametric error and its Theorem 1 bound (inf-norm perturbations, 2-norm error).

    ``H`` is taken over ``theta`` and the free initial states with the weights held at their
    fitted values, as in Lemma 1 (the dictionary's ``x4 x6`` duplicates ``theta4 x4 x6``, so
    with that weight in the support ``H`` over the weights too is singular).
    """
    truth = np.array([data.true_parameters[n] for n in data.physics.parameter_names])
    corrections = estimator.simulate(data.u, x0=estimator.x0_).correction[:, 0]
    model_error = data.hidden_effect["function"](data.x, data.u) - corrections
    bound = parameter_error_bound(
        estimator,
        data.u,
        data.z,
        noise_z=VEHICLE_NOISE,
        delta_norm=float(np.max(np.abs(model_error))),
        disturbed_states=[0],
        include_omega=False,
    )
    assert bound.identifiable
    return float(np.linalg.norm(estimator.theta_ - truth)), bound.bound


@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
def test_every_vehicle_monte_carlo_point_lies_under_the_theorem_1_bound():
    for seed in range(2):
        data = make_vehicle_lateral(VEHICLE_SAMPLES, noise_bound=VEHICLE_NOISE, random_state=seed)
        errors = {}
        for case, estimator in _vehicle_fits(data).items():
            errors[case], bound = _monte_carlo_point(data, estimator)
            assert errors[case] <= bound, (seed, case, errors[case], bound)
        assert errors["with"] < errors["without"]
