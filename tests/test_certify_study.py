"""Section 5.1 study pieces: Fig. 2 hulls, the sparsity level of tau, the vehicle's eta^v.

Small problems with answers known in closed form; each test takes well under a second.
"""

import numpy as np
import pytest

from sk_offwhite.certify import (
    certify_sparsity,
    hull_errors,
    hull_polygon,
    principal_components,
)
from sk_offwhite.certify._certificates import project_out, restricted_eigenvalue
from sk_offwhite.datasets import make_vehicle_lateral
from sk_offwhite.datasets._vehicle import VEHICLE_DELTA, VEHICLE_THETA, _vehicle_delta

# --- Fig. 2 the paper's way: convex hulls of Monte Carlo estimates ---


def test_hull_errors_of_a_square_are_its_diagonal():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    mean, std = hull_errors(square)
    assert mean == pytest.approx(np.sqrt(2.0)) and std == pytest.approx(0.0, abs=1e-15)


def test_hull_errors_mean_and_std_over_the_estimates():
    """On a line at 0, 1, 3 the worst-case errors are 3, 2, 3."""
    mean, std = hull_errors([[0.0], [1.0], [3.0]])
    assert mean == pytest.approx(8.0 / 3.0)
    assert std == pytest.approx(np.std([3.0, 2.0, 3.0]))


def test_hull_errors_need_two_estimates():
    assert np.all(np.isnan(hull_errors([[1.0, 2.0]])))


def test_hull_errors_do_not_depend_on_interior_points():
    """max_j ||theta_j - theta_i|| is attained at a vertex: an interior estimate adds its own
    row only."""
    square = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0], [2.0, 2.0]])
    with_centre = np.vstack([square, [1.0, 1.0]])
    mean, _ = hull_errors(with_centre)
    assert mean == pytest.approx((4 * np.sqrt(8.0) + np.sqrt(2.0)) / 5)


def test_principal_components_recover_a_line_and_share_axes():
    direction = np.array([1.0, 2.0, -2.0, 4.0]) / 5.0
    reference = np.outer(np.linspace(-1.0, 1.0, 7), direction) + np.array([2.0, -1.0, -1.0, 3.7])
    pcs = principal_components(reference)
    np.testing.assert_allclose(np.abs(pcs[:, 0]), np.abs(np.linspace(-1.0, 1.0, 7)), atol=1e-12)
    np.testing.assert_allclose(pcs[:, 1], 0.0, atol=1e-12)
    subset = principal_components(reference[[0, 6]], reference)
    np.testing.assert_allclose(subset, pcs[[0, 6]], atol=1e-12)  # same plane for SFPS


def test_principal_components_keep_distances_in_their_plane():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(20, 2)) @ rng.normal(size=(2, 4))  # rank 2 in R^4
    pcs = principal_components(points)
    np.testing.assert_allclose(hull_errors(pcs), hull_errors(points), rtol=1e-10)


def test_hull_polygon_keeps_the_vertices_only():
    points = [[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [1.0, 1.0], [1.0, 0.0]]
    polygon = hull_polygon(points)
    assert polygon.shape == (5, 2)
    np.testing.assert_array_equal(polygon[0], polygon[-1])
    assert {tuple(p) for p in polygon} == {(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)}


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: hull_errors([1.0, 2.0]), "points"),
        (lambda: hull_errors([[np.nan, 1.0], [0.0, 0.0]]), "points"),
        (lambda: principal_components([[0.0, 1.0]] * 3, [[0.0, 1.0, 2.0]] * 3), "reference"),
        (lambda: principal_components([[0.0, 1.0], [1.0, 0.0]], n_components=3), "n_components"),
        (lambda: hull_polygon([[0.0, 1.0, 2.0]] * 3), "points"),
    ],
)
def test_hull_functions_name_the_bad_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_hull_functions_do_not_mutate_their_input():
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    before = points.copy()
    hull_errors(points), principal_components(points), hull_polygon(points)
    np.testing.assert_array_equal(points, before)


# --- The sparsity level n of sigma^2_n and ||e||_(Q,n) in tau ---


@pytest.fixture(scope="module")
def dense_vertex_case():
    """Two true terms among 10 columns, five of them large and made of the true two: the
    l1 objective of (11) is then cheaper with many small coefficients on the large columns,
    so omega^v has more non-zeros than M = 2 and the levels ||omega^v||_0 + M and 2M
    differ."""
    rng = np.random.default_rng(0)
    xi, phi = rng.normal(size=(300, 2)), rng.normal(size=(300, 10))
    phi[:, 5:] = 5.0 * (phi[:, [1]] - phi[:, [4]] + 0.5 * rng.normal(size=(300, 5)))
    omega = np.zeros(10)
    omega[[1, 4]] = [3.0, -2.0]
    noise = rng.uniform(-0.05, 0.05, 300)
    y = xi @ np.array([1.0, -1.0]) + phi @ omega + noise
    coef = np.linalg.lstsq(np.hstack([xi, phi[:, [1, 4]]]), y, rcond=None)[0]
    omega_hat = np.zeros(10)
    omega_hat[[1, 4]] = coef[2:]
    return xi, phi, y, 3.0 * np.linalg.norm(noise), omega_hat


def test_the_vertex_level_counts_the_non_zeros_of_omega_v(dense_vertex_case):
    xi, phi, y, mu, omega_hat = dense_vertex_case
    cert = certify_sparsity(xi, phi, y, mu, omega_hat)
    size = np.abs(cert.omega_v) * np.linalg.norm(phi, axis=0)
    expected = int(np.sum(size > 1e-6 * size.max()))
    assert cert.vertex_size == expected and expected > 2
    assert cert.sparsity_level == min(expected + 2, 10)
    q = project_out(xi, phi)
    assert cert.sigma2 == pytest.approx(restricted_eigenvalue(q, cert.sparsity_level)[0])


def test_the_vertex_level_is_never_less_conservative_than_2m(dense_vertex_case):
    xi, phi, y, mu, omega_hat = dense_vertex_case
    rigorous = certify_sparsity(xi, phi, y, mu, omega_hat)
    paper = certify_sparsity(xi, phi, y, mu, omega_hat, level="2M")
    assert paper.sparsity_level == 4 and rigorous.sparsity_level > 4
    assert rigorous.sigma2 < paper.sigma2
    assert rigorous.threshold > paper.threshold
    assert rigorous.theorem2_bound == pytest.approx(paper.theorem2_bound)  # always at 2M
    assert f"n = {rigorous.sparsity_level}" in rigorous.explain()


def test_a_bad_level_is_named(dense_vertex_case):
    xi, phi, y, mu, omega_hat = dense_vertex_case
    with pytest.raises(ValueError, match="level"):
        certify_sparsity(xi, phi, y, mu, omega_hat, level="M")


def test_an_estimate_infeasible_under_mu_is_diagnosed_even_without_a_verdict(
    dense_vertex_case,
):
    """mu below the residual omega_hat leaves: (11) has no solution, so no verdict, and the
    diagnosis says why (e.g. a mu that does not cover process noise)."""
    xi, phi, y, mu, omega_hat = dense_vertex_case
    cert = certify_sparsity(xi, phi, y, 0.1 * mu, omega_hat)
    assert cert.certified is None and cert.status == "infeasible"
    assert cert.diagnosis.cause == "infeasible"
    assert cert.explain().startswith("omega_hat is not feasible")


# --- The vehicle's process noise eta^v enters the recursion ---


def test_vehicle_process_noise_enters_the_yaw_recursion():
    data = make_vehicle_lateral(
        n_samples=150, noise_bound=0.0, process_noise_bound=1e-3, random_state=2
    )
    x, u, w = data.x, data.u, data.noise["process_noise"]
    assert 0 < np.max(np.abs(w[:, 0])) <= 1e-3 and not np.any(w[:, 1:])
    theta = np.array([VEHICLE_THETA[f"theta{i}"] for i in (1, 2, 3, 4)])
    y, y1, s1, p, p1 = x[:-1, 0], x[:-1, 1], x[:-1, 3], x[:-1, 4], x[:-1, 5]
    regressors = np.column_stack([y, y1, y * p, s1 * p1])
    known = regressors @ theta
    delta = _vehicle_delta(x[:-1], u[:-1], *VEHICLE_DELTA)[:, 0]
    np.testing.assert_allclose(x[1:, 0] - known - delta, w[: len(x) - 1, 0], atol=1e-12)
    np.testing.assert_allclose(data.z[:, 0], x[:, 0])  # no output noise
    plain = make_vehicle_lateral(n_samples=150, noise_bound=0.0, random_state=2)
    np.testing.assert_array_equal(plain.u, data.u)  # same inputs, only eta^v differs
    assert not np.allclose(plain.z, data.z)


def test_vehicle_process_noise_bound_is_checked():
    with pytest.raises(ValueError, match="process_noise_bound"):
        make_vehicle_lateral(n_samples=50, process_noise_bound=-1.0)


# --- The sweep's tables, on made-up runs (no fitting) ---


def _sweep_module():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / "certificates_sweep.py"
    spec = importlib.util.spec_from_file_location("certificates_sweep", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _made_up_run(seed, certified, theta, fps=0.4, sfps=0.07, alone=None):
    verdict = {"certified": certified, "mu": 0.00224}
    physics_only = {} if alone is None else {"theta_physics_only": alone}
    return physics_only | {
        "noise_bound": 5e-5,
        "seed": seed,
        "b sqrt(T)": verdict,
        "refined": {"certified": True, "mu": 0.0013},
        "b sqrt(T), n = 2M": {"certified": certified, "mu": 0.00224},
        "b sqrt(T), (11)'s vertex": {"certified": False, "mu": 0.00224},
        "theta_hat": theta,
        "fit_support_exact": True,
        "exact_sets": {"FPS": fps, "SFPS": sfps},
    }


def test_sweep_tables_count_and_hull_the_right_runs(tmp_path):
    sweep = _sweep_module()
    thetas = [[2.0, -1.0, -1.0, 3.7], [2.0, -1.0, -1.0, 3.7 + 3.0], [2.0 + 4.0, -1.0, -1.0, 3.7]]
    runs = [_made_up_run(0, True, thetas[0]), _made_up_run(1, True, thetas[1]),
            _made_up_run(2, False, thetas[2], fps=0.6)]  # fmt: skip
    assert "| 5e-05 | 2/3 | 3/3 | 2/3 | 0/3 | 3/3 |" in sweep.table(runs, [5e-5])
    hulls = sweep.hull_table(runs, [5e-5]).splitlines()
    # FPS over the three estimates (sides 3, 4, 5): worst-case errors 4, 5, 5; SFPS over the
    # two certified: 3, 3
    assert hulls[2].startswith("| paper | PCA | 1.79 +- 0.28 | 1.19 +- 0.19")
    assert hulls[3].startswith("| 5e-05 | theta | 4.67 +- 0.47 (3) | 3 +- 0 (2) | 4.67 +- 0.47 (3)")
    assert hulls[4].startswith("| 5e-05 | PCA | 4.67 +- 0.47 (3) | 3 +- 0 (2)")
    exact = sweep.exact_table(runs, [5e-5]).splitlines()[2]
    assert exact.startswith("| 5e-05 | 0.00224 | 0.467 +- 0.094 (3) | 0.07 +- 0 (3) | 0.4 +- 0 (2)")
    sweep.plot_hulls(runs, [5e-5], tmp_path / "hulls.png")
    sweep.plot_fraction(runs, [5e-5], tmp_path / "fraction.png")
    assert (tmp_path / "hulls.png").stat().st_size > 0 and (tmp_path / "fraction.png").exists()


def test_paper_populations_hull_the_fits_with_and_without_delta(tmp_path):
    sweep = _sweep_module()
    a = np.array([2.0, -1.0, -1.0, 3.7])
    with_delta = [a, a + [0, 0, 0, 3.0], a + [4.0, 0, 0, 0]]
    alone = (a + [0, 12.0, 0, 0]).tolist()
    runs = [_made_up_run(k, k < 2, t.tolist(), alone=alone) for k, t in enumerate(with_delta)]
    lines = sweep.paper_populations_table(runs, [5e-5]).splitlines()
    assert lines[2] == "| paper | PCA | 1.79 +- 0.28 | 1.19 +- 0.19 |"
    # largest distances: 12 from a, sqrt(9 + 144) from b, sqrt(16 + 144) from c and from each
    # of the three fits of the physics alone (at one point); SFPS: a and b, 3 apart
    farthest = [12.0, np.sqrt(153.0)] + [np.sqrt(160.0)] * 4
    expected = f"{np.mean(farthest):.3g} +- {np.std(farthest):.2g} (6) | 3 +- 0 (2) |"
    assert lines[3] == f"| 5e-05 | theta | {expected}"
    assert lines[4].startswith("| 5e-05 | PCA |") and lines[4].endswith("(2) |")
    without = [{k: v for k, v in r.items() if k != "theta_physics_only"} for r in runs]
    assert len(sweep.paper_populations_table(without, [5e-5]).splitlines()) == 3  # no rows
    sweep.plot_paper_populations(runs, [5e-5], tmp_path / "populations.png")
    assert (tmp_path / "populations.png").stat().st_size > 0
