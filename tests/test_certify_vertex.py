"""The searched vertex of Theorem 3 (``vertex='search'``): valid, and tighter than (11)'s.

The problem mimics the vehicle's: two nearly collinear true terms (``v p`` and ``v p^2``
over a narrow range of ``p``) and a third, with ``mu = b sqrt(T)`` for uniform noise in
``[-b, b]``. At ``b = 0.05`` the paper's test at (11)'s l1 solution fails (tau/eta 1.16)
while the support is the only 3-term one that fits.
"""

import itertools

import numpy as np
import pytest

from sk_offwhite.certify import certify_sparsity
from sk_offwhite.certify._certificates import project_out

SUPPORT = [0, 1, 4]


def _collinear_case(seed=0, bound=0.05, rows=300):
    rng = np.random.default_rng(seed)
    xi = rng.normal(size=(rows, 2))
    p, v = rng.uniform(0.5, 1.0, rows), rng.normal(size=rows)
    phi = np.column_stack([v * p, v * p**2, rng.normal(size=(rows, 6))])
    omega = np.zeros(8)
    omega[SUPPORT] = [3.0, -2.0, 1.0]
    y = xi @ [1.0, -2.0] + phi @ omega + rng.uniform(-bound, bound, rows)
    return xi, phi, y, bound * np.sqrt(rows)


def _least_squares(xi, phi, y, support):
    coef = np.linalg.lstsq(np.hstack([xi, phi[:, support]]), y, rcond=None)[0]
    omega = np.zeros(phi.shape[1])
    omega[support] = coef[xi.shape[1] :]
    return omega


def _residual(xi, phi, y, omega):
    return float(np.linalg.norm(project_out(xi, (y - phi @ omega)[:, None])))


@pytest.fixture(scope="module")
def certificates():
    xi, phi, y, mu = _collinear_case()
    omega_hat = _least_squares(xi, phi, y, SUPPORT)
    l1 = certify_sparsity(xi, phi, y, mu, omega_hat, vertex="l1")
    searched = certify_sparsity(xi, phi, y, mu, omega_hat)
    return (xi, phi, y, mu, omega_hat), l1, searched


def test_the_searched_vertex_certifies_where_the_l1_vertex_cannot(certificates):
    _, l1, searched = certificates
    assert l1.certified is False and l1.vertex == "l1" and l1.threshold > l1.eta
    assert l1.diagnosis.cause == "conservative"  # no sparser support fits
    assert searched.certified is True and searched.vertex == "searched"
    assert searched.margin > 0 and searched.kappa_bar == 0
    np.testing.assert_array_equal(np.flatnonzero(searched.lambda_set), SUPPORT)
    assert np.all(np.sign(searched.omega_v[SUPPORT]) == np.sign(searched.omega_hat[SUPPORT]))
    np.testing.assert_allclose(searched.l1_threshold, l1.threshold)
    assert searched.explain().startswith("certified at a searched vertex")


def test_the_searched_vertex_is_valid_for_theorem_2(certificates):
    """||e*(omega^v)|| >= mu, and every feasible representation with M terms lies within
    tau of omega^v (Theorem 2's bound, checked on the boundary of the feasible set of the
    support and on every other 3-term support that fits)."""
    (xi, phi, y, mu, omega_hat), _, cert = certificates
    assert _residual(xi, phi, y, cert.omega_v) >= mu
    projected = project_out(xi, phi[:, SUPPORT])
    centre = _least_squares(xi, phi, y, SUPPORT)
    radius = np.sqrt(mu**2 - _residual(xi, phi, y, centre) ** 2)
    r_factor = np.linalg.qr(projected, mode="r")
    directions = np.random.default_rng(1).normal(size=(500, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    for direction in directions:
        other = centre.copy()
        other[SUPPORT] += radius * np.linalg.solve(r_factor, direction)
        assert _residual(xi, phi, y, other) <= mu * (1 + 1e-9)
        assert np.max(np.abs(other - cert.omega_v)) <= cert.threshold
    for support in itertools.combinations(range(8), 3):
        fitted = _least_squares(xi, phi, y, list(support))
        if _residual(xi, phi, y, fitted) <= mu:
            assert np.max(np.abs(fitted - cert.omega_v)) <= cert.threshold


def test_a_spurious_term_is_not_certified_by_any_vertex():
    xi, phi, y, mu = _collinear_case()
    omega_hat = _least_squares(xi, phi, y, [*SUPPORT, 6])
    cert = certify_sparsity(xi, phi, y, mu, omega_hat)
    assert cert.certified is False and cert.margin < 0
    assert cert.diagnosis.cause == "sparser support"


def test_without_noise_slack_both_vertices_agree():
    """Where (11)'s vertex passes, it is the one reported (no search)."""
    xi, phi, y, mu = _collinear_case(bound=0.01)
    omega_hat = _least_squares(xi, phi, y, SUPPORT)
    cert = certify_sparsity(xi, phi, y, mu, omega_hat, diagnose=False)
    assert cert.certified is True and cert.vertex == "l1"
    np.testing.assert_allclose(cert.threshold, cert.l1_threshold)


def test_the_vertex_rule_is_validated():
    xi, phi, y, mu = _collinear_case()
    with pytest.raises(ValueError, match="vertex must be 'search' or 'l1'"):
        certify_sparsity(xi, phi, y, mu, _least_squares(xi, phi, y, SUPPORT), vertex="best")
