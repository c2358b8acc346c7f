"""Sparse relaxation (10), certificates (Theorems 2-5) and FPS/SFPS (19)-(20).

A linear-in-parameters problem with a known sparse truth (3 physical parameters, 10
dictionary columns, 2 of them active, bounded noise with ``mu`` twice its norm) gives exact
answers; the vehicle of Section 5.1 (noise-free, short record) checks the multi-step, local
version through the fitted estimator.
"""

import itertools
import warnings

import numpy as np
import pytest

from sk_offwhite import GreyBoxSparseRegressor, fit_gamma_path
from sk_offwhite.certify import (
    Linearisation,
    certify_estimator,
    certify_sparsity,
    estimator_feasible_set,
    feasible_parameter_set,
    linearise_estimator,
    multistep_relaxation,
    prune_by_contribution,
    refined_mu,
    restricted_eigenvalue,
    sparse_relaxation,
    sparsest_feasible_support,
)
from sk_offwhite.certify._relaxation import linear_problem
from sk_offwhite.datasets import make_vehicle_lateral, vehicle_physics_known_registers

THETA = np.array([1.0, -2.0, 0.5])
TRUE_SUPPORT = [2, 7]


@pytest.fixture(scope="module")
def linear_case():
    rng = np.random.default_rng(0)
    xi, phi = rng.normal(size=(400, 3)), rng.normal(size=(400, 10))
    omega = np.zeros(10)
    omega[TRUE_SUPPORT] = [2.0, -1.5]
    noise = rng.uniform(-0.01, 0.01, 400)
    y = xi @ THETA + phi @ omega + noise
    return {"xi": xi, "phi": phi, "y": y, "omega": omega, "mu": 2.0 * np.linalg.norm(noise)}


def _args(case):
    return case["xi"], case["phi"], case["y"], case["mu"]


def _least_squares_on(case, support):
    """A feasible estimate using exactly the columns ``support``."""
    stacked = np.hstack([case["xi"], case["phi"][:, support]])
    coef = np.linalg.lstsq(stacked, case["y"], rcond=None)[0]
    omega = np.zeros(10)
    omega[support] = coef[3:]
    return omega


def test_relaxation_recovers_the_true_support(linear_case):
    result = sparse_relaxation(*_args(linear_case))
    assert result.solved
    np.testing.assert_array_equal(np.flatnonzero(result.support), TRUE_SUPPORT)
    assert result.selected() == ["phi2", "phi7"]
    assert result.residual_norm <= linear_case["mu"] * (1 + 1e-6)
    np.testing.assert_allclose(result.theta, THETA, atol=0.02)


def _incoherent_case(seed, rows=200, features=20, active=3, bound=1e-3):
    """Gaussian regressors, a 3-sparse omega of order one, noise uniform in +-bound."""
    rng = np.random.default_rng(seed)
    xi, phi = rng.normal(size=(rows, 2)), rng.normal(size=(rows, features))
    support = np.sort(rng.choice(features, active, replace=False))
    omega = np.zeros(features)
    omega[support] = rng.choice([-1.0, 1.0], active) * rng.uniform(0.5, 2.0, active)
    noise = rng.uniform(-bound, bound, rows)
    return xi, phi, xi @ [1.0, -2.0] + phi @ omega + noise, support, noise


def _refit_residual(xi, phi, y, support):
    """min over theta, omega_S of ||y - xi theta - phi_S omega_S||."""
    stacked = np.hstack([xi, phi[:, support]])
    return np.linalg.norm(y - stacked @ np.linalg.lstsq(stacked, y, rcond=None)[0])


@pytest.mark.parametrize("factor", [1.0, 1.05])
def test_pruning_returns_the_exact_support_on_incoherent_problems(factor):
    """At mu = ||eta|| the l1 solution keeps small spurious terms (1 exact draw in 10
    without pruning); the pruned support is exact."""
    exact = 0
    for seed in range(10):
        xi, phi, y, support, noise = _incoherent_case(seed)
        result = sparse_relaxation(xi, phi, y, factor * np.linalg.norm(noise))
        exact += np.array_equal(np.flatnonzero(result.support), support)
    assert exact >= 9


@pytest.mark.parametrize("normalize", [False, True])
@pytest.mark.parametrize("prune", [True, False])
def test_an_all_zero_optimum_has_an_empty_support(linear_case, prune, normalize):
    xi, phi, _, mu = _args(linear_case)
    y = linear_case["y"] - phi @ linear_case["omega"]  # physics and noise only
    result = sparse_relaxation(xi, phi, y, mu, prune=prune, normalize_columns=normalize)
    assert result.solved and not result.support.any() and result.selected() == []
    assert np.all(result.omega == 0)
    assert result.residual_norm <= mu * (1 + 1e-6)
    assert "support: (empty)" in result.summary()


@pytest.mark.parametrize("normalize", [False, True])
@pytest.mark.parametrize("column", [TRUE_SUPPORT[0], 4])
def test_a_column_rescaled_by_1e_3_keeps_the_support(linear_case, column, normalize):
    """True term (coefficient x 1000) or a spurious one: same support, same refit."""
    xi, phi, y, mu = _args(linear_case)
    units = np.ones(10)
    units[column] = 1e-3
    reference = sparse_relaxation(xi, phi, y, mu)
    rescaled = sparse_relaxation(xi, phi * units, y, mu, normalize_columns=normalize)
    np.testing.assert_array_equal(np.flatnonzero(rescaled.support), TRUE_SUPPORT)
    np.testing.assert_allclose(rescaled.omega * units, reference.omega, rtol=1e-8, atol=0)
    np.testing.assert_allclose(rescaled.theta, reference.theta, rtol=1e-8)


@pytest.mark.parametrize("prune", [True, False])
@pytest.mark.parametrize("normalize", [False, True])
@pytest.mark.parametrize("seed", [0, 1])
def test_residual_norm_is_that_of_the_returned_estimate(seed, normalize, prune):
    xi, phi, y, _, noise = _incoherent_case(seed)
    mu = np.linalg.norm(noise)
    result = sparse_relaxation(xi, phi, y, mu, normalize_columns=normalize, prune=prune)
    recomputed = np.linalg.norm(y - xi @ result.theta - phi @ result.omega)
    assert result.residual_norm == pytest.approx(recomputed, rel=1e-12)
    assert np.all((result.omega != 0) == result.support) and result.pruned is prune
    if prune:
        assert result.residual_norm <= mu * (1 + 1e-6)
        assert "least-squares refit" in result.summary()


def test_every_term_of_the_pruned_support_is_needed():
    """Removing any one term of the result violates the data constraint."""
    xi, phi, y, _, noise = _incoherent_case(3, active=5)
    mu = np.linalg.norm(noise)
    support = np.flatnonzero(sparse_relaxation(xi, phi, y, mu).support)
    assert _refit_residual(xi, phi, y, support) <= mu
    for j in support:
        assert _refit_residual(xi, phi, y, support[support != j]) > mu


def test_multistep_relaxation_prunes_like_the_linear_relaxation():
    """On a given linearisation (no estimator needed) (15) is (10) on (J_theta, J_omega)."""
    xi, phi, y, _, noise = _incoherent_case(0)
    lin = Linearisation(
        xi, phi, y, np.zeros(2), np.zeros(20), y, ("a", "b"), tuple("abcdefghijklmnopqrst"), 2
    )
    mu = np.linalg.norm(noise)
    for prune in (True, False):
        local = multistep_relaxation(None, None, None, mu, linearisation=lin, prune=prune)
        linear = sparse_relaxation(xi, phi, y, mu, prune=prune)
        np.testing.assert_array_equal(local.support, linear.support)
        np.testing.assert_allclose(local.omega, linear.omega, rtol=1e-9, atol=1e-12)
        assert local.pruned is prune


def test_certificate_holds_on_the_relaxation_support(linear_case):
    relaxation = sparse_relaxation(*_args(linear_case))
    cert = certify_sparsity(*_args(linear_case), relaxation.omega)
    assert cert.certified is True and cert.verdict == "yes"
    assert cert.margin > 0 and cert.threshold < cert.eta
    assert cert.kappa_bar == 0 and cert.sigma2_exact
    np.testing.assert_array_equal(np.flatnonzero(cert.lambda_set), TRUE_SUPPORT)
    assert "yes" in cert.summary()


def test_unit_norm_columns_make_relaxation_and_certificate_independent_of_units(linear_case):
    xi, phi, y, mu = _args(linear_case)
    units = np.random.default_rng(1).uniform(0.1, 10.0, 10)
    units[2] = 1e-3  # a true term with a tiny regressor and a large coefficient
    reference = sparse_relaxation(xi, phi, y, mu, normalize_columns=True)
    rescaled = sparse_relaxation(xi, phi * units, y, mu, normalize_columns=True)
    assert rescaled.solved and rescaled.normalize_columns
    np.testing.assert_array_equal(np.flatnonzero(rescaled.support), TRUE_SUPPORT)
    np.testing.assert_allclose(rescaled.omega * units, reference.omega, rtol=1e-5, atol=1e-8)
    assert "sum ||phi_j|| |omega_j|" in rescaled.summary()
    cert_reference = certify_sparsity(xi, phi, y, mu, reference.omega, normalize_columns=True)
    cert = certify_sparsity(xi, phi * units, y, mu, rescaled.omega, normalize_columns=True)
    assert cert.certified is True and cert_reference.certified is True
    np.testing.assert_allclose(cert.threshold, cert_reference.threshold, rtol=1e-4)
    np.testing.assert_allclose(cert.column_scales, np.linalg.norm(phi * units, axis=0))


@pytest.mark.parametrize("extra", [[4], [4, 5]])
def test_spurious_terms_are_not_certified(linear_case, extra):
    omega_hat = _least_squares_on(linear_case, TRUE_SUPPORT + extra)
    cert = certify_sparsity(*_args(linear_case), omega_hat)
    assert cert.status == "optimal"
    assert cert.certified is False and cert.verdict == "cannot certify"
    assert cert.margin < 0
    assert cert.kappa_bar == len(extra)  # bound (12): at most this many terms too many


def test_a_missing_term_is_not_certified(linear_case):
    omega_hat = _least_squares_on(linear_case, TRUE_SUPPORT[:1])
    cert = certify_sparsity(*_args(linear_case), omega_hat)
    assert cert.certified is not True


def test_fps_contains_the_truth_and_sfps_is_tighter(linear_case):
    relaxation = sparse_relaxation(*_args(linear_case))
    fps = feasible_parameter_set(*_args(linear_case), relaxation.theta)
    sfps = feasible_parameter_set(*_args(linear_case), relaxation.theta, support=relaxation.support)
    assert fps.solved and sfps.solved and (fps.kind, sfps.kind) == ("FPS", "SFPS")
    assert fps.contains(THETA) and sfps.contains(THETA)
    assert np.all(sfps.lower >= fps.lower - 1e-9) and np.all(sfps.upper <= fps.upper + 1e-9)
    assert np.all(sfps.worst_case <= fps.worst_case + 1e-9)
    assert sfps.worst_case_norm <= fps.worst_case_norm
    assert "worst-case error" in fps.summary()


def test_fps_extremes_match_the_ellipsoid(linear_case):
    """FPS is an ellipsoid: theta_i extremes are x_ls,i +- sqrt((mu^2 - r^2) (A'A)^-1_ii)."""
    xi, phi, y, mu = _args(linear_case)
    stacked = np.hstack([xi, phi])
    x_ls, r2 = np.linalg.lstsq(stacked, y, rcond=None)[:2]
    radius = np.sqrt((mu**2 - r2[0]) * np.diag(np.linalg.inv(stacked.T @ stacked)))[:3]
    fps = feasible_parameter_set(xi, phi, y, mu, x_ls[:3])
    np.testing.assert_allclose(fps.lower, x_ls[:3] - radius, rtol=0, atol=1e-8)
    np.testing.assert_allclose(fps.upper, x_ls[:3] + radius, rtol=0, atol=1e-8)
    np.testing.assert_allclose(fps.worst_case, radius, atol=1e-8)


def test_an_infeasible_mu_is_reported_not_turned_into_a_verdict(linear_case):
    xi, phi, y, mu = _args(linear_case)
    relaxation = sparse_relaxation(xi, phi, y, 1e-3 * mu)
    assert not relaxation.solved and relaxation.status == "infeasible"
    assert relaxation.omega is None and "NOT SOLVED" in relaxation.summary()
    cert = certify_sparsity(xi, phi, y, 1e-3 * mu, linear_case["omega"])
    assert cert.certified is None and cert.status == "infeasible"
    assert cert.verdict.startswith("not computed")
    fps = feasible_parameter_set(xi, phi, y, 1e-3 * mu, THETA)
    assert fps.status == "infeasible" and fps.worst_case is None


def test_a_dictionary_column_equal_to_a_regressor(linear_case):
    """Confounded with theta0: FPS unbounded in theta0, the certificate ignores the column."""
    xi, phi, y, mu = _args(linear_case)
    augmented = np.hstack([phi, xi[:, :1]])
    fps = feasible_parameter_set(xi, augmented, y, mu, THETA)
    assert fps.status.startswith("unbounded") and "theta0" in fps.status
    omega_hat = np.append(sparse_relaxation(xi, phi, y, mu).omega, 0.0)
    cert = certify_sparsity(xi, augmented, y, mu, omega_hat)
    assert cert.certified is True and cert.confounded.tolist() == [False] * 10 + [True]


def test_restricted_eigenvalue_exact_and_bound():
    q = np.random.default_rng(1).normal(size=(30, 7))
    brute = min(
        np.linalg.eigvalsh(q[:, s].T @ q[:, s])[0] for s in itertools.combinations(range(7), 3)
    )
    exact, is_exact = restricted_eigenvalue(q, 3)
    assert is_exact and exact == pytest.approx(brute, rel=1e-12)
    bound, is_exact = restricted_eigenvalue(q, 3, max_subsets=10)
    assert not is_exact and 0 <= bound <= exact


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"mu": 0.0}, "mu"),
        ({"mu": -1.0}, "mu"),
        ({"y": np.full(400, np.nan)}, "y"),
        ({"phi": np.ones((399, 10))}, "phi"),
        ({"xi": np.ones((400, 2, 2))}, "phi_theta"),
    ],
)
def test_bad_input_names_the_argument(linear_case, change, message):
    args = {**linear_case, **change}
    with pytest.raises(ValueError, match=message):
        sparse_relaxation(args["xi"], args["phi"], args["y"], args["mu"])


def test_all_zero_estimate_is_rejected(linear_case):
    with pytest.raises(ValueError, match="omega_hat"):
        certify_sparsity(*_args(linear_case), np.zeros(10))


@pytest.fixture(scope="module")
def vehicle_fit():
    """Noise-free vehicle, 300 samples, the support path of tests/test_vehicle.py.

    The initial values of the measured-input registers are fixed to the measured inputs
    (as in Section 3): free, they only touch the first samples and drift in a noise-free fit.
    The refit on the support reproduces noise-free data to rounding, so the bound is a
    tiny fraction of the record's norm rather than a multiple of the residual.
    """
    data = make_vehicle_lateral(n_samples=300, noise_bound=0.0, random_state=0)
    est = GreyBoxSparseRegressor(
        vehicle_physics_known_registers(data), data.suggested_library, delta_states=[0],
        max_iter=1000,
    )  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit_gamma_path(est, data.u, data.z)
    lin = linearise_estimator(est, data.u, data.z)
    mu = max(2.0 * np.linalg.norm(lin.residual), 1e-6 * np.linalg.norm(data.z))
    return data, est, lin, mu


def test_vehicle_local_certificate_holds_on_the_true_support(vehicle_fit):
    data, est, lin, mu = vehicle_fit
    assert lin.jac_theta.shape == (300, 6) and lin.jac_omega.shape == (300, 12)  # 4 θ + 2 x0
    cert = certify_estimator(est, data.u, data.z, mu, linearisation=lin)
    assert cert.certified is True, cert.summary()
    np.testing.assert_array_equal(cert.omega_hat != 0, data.true_omega != 0)
    assert cert.kappa_bar == 0
    assert cert.confounded[lin.feature_names.index("x4 x6")]  # duplicate of theta4 x4 x6


def test_vehicle_sfps_contains_the_truth_and_fps_is_unbounded(vehicle_fit):
    data, est, lin, mu = vehicle_fit
    theta_bar = [data.true_parameters[n] for n in est.physics_.parameter_names]
    sfps = estimator_feasible_set(est, None, None, mu, support="fit", linearisation=lin)
    assert sfps.solved and sfps.contains(theta_bar)
    fps = estimator_feasible_set(est, None, None, mu, linearisation=lin)
    assert fps.status.startswith("unbounded") and "theta4" in fps.status


def test_vehicle_multistep_relaxation_is_pruned_to_the_true_support(vehicle_fit):
    """Without pruning (15) keeps about 10 of the 12 terms; pruned, the true 3 remain and
    Theorem 5 certifies them."""
    data, est, lin, mu = vehicle_fit
    relaxation = multistep_relaxation(est, None, None, mu, linearisation=lin)
    assert relaxation.solved, relaxation.status
    np.testing.assert_array_equal(relaxation.support, data.true_omega.reshape(-1) != 0)
    assert relaxation.residual_norm <= mu * (1 + 1e-6)
    cert = certify_estimator(est, None, None, mu, omega_hat=relaxation.omega, linearisation=lin)
    assert cert.certified is True, cert.summary()


# --- Diagnosis: why a certificate holds or fails; the estimate certify_estimator tests ---


def _small_term_case(small=0.005, zero_physics=False):
    """Two terms, one of them (phi7) so small that {phi2} alone fits within mu.

    ``zero_physics``: both terms small, so the physics alone fits.
    """
    rng = np.random.default_rng(1)
    xi, phi = rng.normal(size=(400, 3)), rng.normal(size=(400, 10))
    omega = np.zeros(10)
    omega[TRUE_SUPPORT] = [small if zero_physics else 2.0, small]
    noise = rng.uniform(-0.01, 0.01, 400)
    case = {"xi": xi, "phi": phi, "y": xi @ THETA + phi @ omega + noise, "omega": omega}
    case["mu"] = 2.0 * np.linalg.norm(noise)
    return case


def test_a_certified_estimate_is_explained_as_certified(linear_case):
    cert = certify_sparsity(*_args(linear_case), _least_squares_on(linear_case, TRUE_SUPPORT))
    assert cert.certified is True
    d = cert.diagnosis
    assert d.cause == "certified" and d.sparser_support is None and d.exhaustive
    assert d.sparser_residual > linear_case["mu"] >= d.residual
    assert cert.explain().startswith("certified: tau")
    assert "why: certified" in cert.summary()


def test_a_sparser_feasible_support_is_named_in_the_diagnosis():
    """Small phi7 term (contribution 0.1 < mu = 0.23): {phi2} alone fits, so the true
    2-term support is not maximally sparse and the diagnosis says so."""
    case = _small_term_case()
    cert = certify_sparsity(*_args(case), _least_squares_on(case, TRUE_SUPPORT))
    assert cert.certified is False
    d = cert.diagnosis
    assert d.cause == "sparser support" and d.sparser_support == ("phi2",)
    assert d.sparser_residual <= case["mu"]
    assert "a 1-term support {phi2} already explains the data within mu" in cert.explain()
    assert "not maximally sparse at this noise level" in cert.explain()


def test_the_diagnosis_names_the_empty_support_when_the_physics_alone_fits():
    case = _small_term_case(small=0.003, zero_physics=True)
    cert = certify_sparsity(*_args(case), _least_squares_on(case, TRUE_SUPPORT))
    assert cert.certified is False
    assert cert.diagnosis.sparser_support == ()
    assert cert.explain().startswith("the physics alone (no correction)")


def test_an_infeasible_estimate_is_diagnosed(linear_case):
    omega = 0.9 * _least_squares_on(linear_case, TRUE_SUPPORT)
    cert = certify_sparsity(*_args(linear_case), omega)
    assert cert.certified is False
    assert cert.diagnosis.cause == "infeasible"
    assert cert.diagnosis.residual > linear_case["mu"]
    assert "not feasible" in cert.explain()


def test_a_conservative_verdict_is_told_apart_from_a_sparser_support(linear_case):
    """Two nearly equal columns: no sparser support fits, yet sigma^2_2M is tiny and
    Theorem 3 cannot certify; the diagnosis calls the test conservative."""
    case = dict(linear_case)
    phi = linear_case["phi"].copy()
    phi[:, 3] = phi[:, 2] + 1e-3 * phi[:, 3]
    case["phi"] = phi
    case["y"] = linear_case["y"] - linear_case["phi"] @ linear_case["omega"] + phi @ linear_case[
        "omega"]  # fmt: skip
    cert = certify_sparsity(*_args(case), _least_squares_on(case, TRUE_SUPPORT))
    assert cert.certified is False
    assert cert.diagnosis.cause == "conservative" and cert.diagnosis.exhaustive
    assert "sufficient test does not show it" in cert.explain()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparsest_feasible_support_matches_brute_force(seed):
    xi, phi, y, _, noise = _incoherent_case(seed, rows=60, features=8, bound=0.3)
    mu = 1.05 * np.linalg.norm(noise)
    problem = linear_problem(xi, phi, y, mu)
    found, residual, exhaustive = sparsest_feasible_support(problem, 8)
    sizes = [
        len(s)
        for k in range(9)
        for s in itertools.combinations(range(8), k)
        if _refit_residual(xi, phi, y, list(s)) <= mu
    ]
    assert exhaustive and found is not None and len(found) == min(sizes)
    np.testing.assert_allclose(residual, _refit_residual(xi, phi, y, list(found)), rtol=1e-8)


def test_greedy_search_is_flagged_as_not_exhaustive(linear_case):
    problem = linear_problem(*_args(linear_case))
    found, _, exhaustive = sparsest_feasible_support(problem, 3, max_subsets=5)
    assert not exhaustive
    assert sorted(found) == TRUE_SUPPORT  # greedy still finds the two strong terms


def _linearisation_of(case, omega):
    """A Linearisation whose Jacobians are the linear case's regressors."""
    names = tuple(f"phi{j}" for j in range(case["phi"].shape[1]))
    return Linearisation(
        case["xi"], case["phi"], case["y"], THETA.copy(), omega, case["y"] * 0,
        ("a", "b", "c"), names, 3,
    )  # fmt: skip


def test_certify_estimator_prunes_negligible_terms_of_the_fit(linear_case):
    omega = _least_squares_on(linear_case, TRUE_SUPPORT)
    omega[5] = 1e-4  # contribution 0.002, below 1 % of the largest (about 40)
    lin = _linearisation_of(linear_case, omega)
    cert = certify_estimator(None, None, None, linear_case["mu"], linearisation=lin)
    np.testing.assert_array_equal(np.flatnonzero(cert.omega_hat), TRUE_SUPPORT)
    assert cert.certified is True
    kept = certify_estimator(None, None, None, linear_case["mu"], linearisation=lin, prune_tol=0)
    assert kept.omega_hat[5] == 1e-4 and kept.certified is False  # phi5 is not needed
    assert kept.diagnosis.sparser_support == ("phi2", "phi7")


def test_certify_estimator_refined_mu_and_refit(linear_case):
    omega = 1.02 * _least_squares_on(linear_case, TRUE_SUPPORT)
    lin = _linearisation_of(linear_case, omega)
    cert = certify_estimator(None, None, None, "refined", linearisation=lin)
    problem = linear_problem(*_args(linear_case))
    np.testing.assert_allclose(cert.mu, refined_mu(problem, omega), rtol=1e-12)
    np.testing.assert_allclose(cert.mu, 1.01 * cert.diagnosis.residual, rtol=1e-9)
    refit = certify_estimator(None, None, None, "refined", linearisation=lin, refit=True)
    assert refit.mu < cert.mu  # the refit leaves the least residual on the support
    np.testing.assert_allclose(refit.omega_hat, _least_squares_on(linear_case, TRUE_SUPPORT))
    relax = certify_estimator(None, None, None, linear_case["mu"], linearisation=lin,
                              estimate="relaxation", omega_hat=None)  # fmt: skip
    np.testing.assert_array_equal(np.flatnonzero(relax.omega_hat), TRUE_SUPPORT)
    with pytest.raises(ValueError, match="refined"):
        certify_estimator(None, None, None, "refined", linearisation=lin, estimate="relaxation")
    with pytest.raises(ValueError, match="estimate"):
        certify_estimator(None, None, None, 1.0, linearisation=lin, estimate="lasso")


def test_prune_by_contribution_is_relative_to_the_largest_term(linear_case):
    problem = linear_problem(*_args(linear_case))
    omega = np.zeros(10)
    omega[[0, 1]] = [1.0, 0.009]
    pruned = prune_by_contribution(
        problem, omega * np.linalg.norm(problem.phi[:, 0]) / np.linalg.norm(problem.phi, axis=0)
    )
    assert np.count_nonzero(pruned) == 1 and pruned[0] != 0
