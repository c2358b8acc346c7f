r"""A vertex for Theorem 3 chosen to pass its test: the searched $\omega^v$.

Theorem 3's proof uses three facts about $\omega^v$, none of them that it minimises
$\|\omega\|_1$ in (11):

1. $\|e^*(\omega^v)\|_2 \ge \mu \ge \|e^*(\bar\omega)\|_2$, so Theorem 2 applies to
   $\omega' = \bar\omega$ around $\omega^v$ (the paper asks for (11d) active,
   $= \mu$; $\ge$ is what Theorem 2 needs);
2. $\|\bar\omega\|_0 \le M \le \|\omega^v\|_0$ ($\hat\omega$ is feasible, and
   the test below makes every $\omega^v_i$, $i \in S$, non-zero), and the level
   of $\sigma^2_n$ covers the support of $\bar\omega - \omega^v$;
3. every $i \in S$ has $\mathrm{sign}(\hat\omega_i)\,\omega^v_i > \tau$.

Then $\|\bar\omega - \omega^v\|_\infty \le \tau$ puts every term of $S$ in
$\mathrm{supp}\,\bar\omega$ with the sign of $\hat\omega$, and
$\|\bar\omega\|_0 \le M$ leaves no room for another: $\mathrm{supp}\,\bar\omega
= S$. (11)'s $\ell_1$ minimiser is one such vector; this module looks for the one
with the largest margin $\min_{i \in S} \mathrm{sign}(\hat\omega_i)\omega^v_i - \tau$.

The search is the convex-concave procedure: with the conservative threshold (level
$m'$, every kept column)

$$
\tilde\tau(\omega) = \frac{\|Q^\top e\|_\infty + \|Q^\top e\|_2}{\lambda_{\min}(Q^\top Q)}
\ge \tau(\omega), \qquad e = \Upsilon_0 y - Q\omega,
$$

each step minimises the convex $\tilde\tau(\omega) - \min_{i \in S}
\mathrm{sign}(\hat\omega_i)\omega_i$ over the half-space
$\langle e_k, e(\omega)\rangle \ge \mu\|e_k\|_2$, which lies inside
$\{\|e(\omega)\|_2 \ge \mu\}$ (Cauchy-Schwarz): every step is a valid vertex, the
margin never decreases, and the start is (11)'s solution. Everything is in the
$m' \times m'$ Gram matrix, whatever $T$. The certificate then tests the vertex
found with the exact $\tau$ (`support_threshold`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cvxpy as cp
import numpy as np

from ._relaxation import solve_status

__all__ = ["search_vertex"]

MAX_STEPS = 30
"""Convex-concave steps of the search at most."""

STEP_RTOL = 1e-6
"""The search ends when a step raises the margin by less than this fraction of it."""

RESIDUAL_SLACK = 1e-9
"""Relative slack by which the half-space keeps $\\|e\\|_2$ above $\\mu$
(solver round-off must not bring a vertex below it)."""


@dataclass(frozen=True)
class _Gram:
    r"""The projected problem on the kept columns: $G = Q^\top Q$,
    $g = Q^\top\Upsilon_0 y$, $\|\Upsilon_0 y\|^2$, the support (as positions
    among the kept columns) and its signs, $\lambda_{\min}(G)$."""

    gram: np.ndarray
    inner: np.ndarray
    energy: float
    support: np.ndarray
    signs: np.ndarray
    sigma2: float


def _gram(projected, projected_y, kept, omega_hat) -> _Gram:
    q = projected[:, kept]
    gram = q.T @ q
    support = np.flatnonzero(omega_hat[kept])
    signs = np.sign(omega_hat[kept][support])
    sigma2 = float(np.linalg.eigvalsh(gram)[0])
    return _Gram(gram, q.T @ projected_y, float(projected_y @ projected_y), support, signs, sigma2)


def _surrogate_margin(gram: _Gram, omega: np.ndarray) -> float:
    r"""$\min_S \mathrm{sign}(\hat\omega_i)\omega_i - \tilde\tau(\omega)$."""
    inner = gram.inner - gram.gram @ omega
    tau = (np.max(np.abs(inner)) + np.linalg.norm(inner)) / gram.sigma2
    return float(np.min(gram.signs * omega[gram.support]) - tau)


def _half_space(gram: _Gram, omega: np.ndarray, mu: float) -> tuple[np.ndarray, float]:
    r"""``(a, b)`` with $a^\top\omega \le b$ the half-space
    $\langle e_k, e(\omega)\rangle \ge \mu(1 + \text{slack})\|e_k\|$ at ``omega``,
    scaled to a unit normal."""
    normal = gram.inner - gram.gram @ omega  # Q^T e_k
    norm_e = np.sqrt(max(gram.energy - 2 * gram.inner @ omega + omega @ gram.gram @ omega, 0.0))
    offset = gram.energy - omega @ gram.inner - mu * (1 + RESIDUAL_SLACK) * norm_e
    scale = np.linalg.norm(normal)
    return normal / scale, float(offset / scale)


def _step_program(gram: _Gram, start: np.ndarray):
    """The convex step as a cvxpy problem with the half-space as parameters (compiled once)."""
    omega = cp.Variable(start.size)
    normal, offset = cp.Parameter(start.size), cp.Parameter()
    weight = 1.0 / np.linalg.norm(gram.inner - gram.gram @ start)  # inner products of order 1
    inner = weight * (gram.inner - gram.gram @ omega)
    tau = cp.norm(inner, "inf") + cp.norm(inner, 2)
    lowest = cp.min(cp.multiply(gram.signs, omega[gram.support]))
    objective = cp.Minimize(tau - weight * gram.sigma2 * lowest)
    return cp.Problem(objective, [normal @ omega <= offset]), omega, normal, offset


def _climb(gram: _Gram, start: np.ndarray, mu: float) -> np.ndarray:
    r"""Convex-concave steps from ``start`` while the surrogate margin rises; ``start``
    itself when no step was taken. The first step is kept whatever its margin: ``start``
    meets $\|e\|_2 \ge \mu$ only to the tolerance of (11)'s solver, every step
    exactly."""
    if not np.any(gram.inner - gram.gram @ start):
        return start  # e is orthogonal to every column: tau = 0 at start already
    problem, omega, normal, offset = _step_program(gram, start)
    best, best_margin = start, -np.inf
    for _ in range(MAX_STEPS):
        normal.value, offset.value = _half_space(gram, best, mu)
        if solve_status(problem) != cp.OPTIMAL:
            break
        candidate = np.asarray(omega.value, float)
        margin = _surrogate_margin(gram, candidate)
        if np.isfinite(best_margin) and not margin > best_margin + STEP_RTOL * abs(best_margin):
            break
        best, best_margin = candidate, margin
    return best


def search_vertex(
    projected: np.ndarray,
    projected_y: np.ndarray,
    mu: float,
    kept: np.ndarray,
    omega_hat: np.ndarray,
    start: np.ndarray,
) -> np.ndarray | None:
    r"""A vertex $\omega^v$ with $\|e^*(\omega^v)\|_2 \ge \mu$ and the largest
    margin the search reaches from ``start`` (see the module notes).

    Parameters
    ----------
    projected : ndarray of shape (T, m)
        $Q = \Upsilon_0\Phi$.
    projected_y : ndarray of shape (T,)
        $\Upsilon_0 y$.
    mu : float
        The noise bound.
    kept : ndarray of bool, shape (m,)
        Columns not confounded with the physics (the others stay 0).
    omega_hat : ndarray of shape (m,)
        The estimate; its support and signs.
    start : ndarray of shape (m,)
        (11)'s solution.

    Returns
    -------
    ndarray of shape (m,) or None
        The vertex (zero on the confounded columns), or ``None`` when the search cannot
        run ($\lambda_{\min}(Q^\top Q) \le 0$) or no step raised the margin.
    """
    gram = _gram(projected, projected_y, kept, omega_hat)
    if not gram.sigma2 > 0:
        return None
    origin = start[kept]
    found = _climb(gram, origin, mu)
    if found is origin:
        return None
    vertex = np.zeros_like(start)
    vertex[kept] = found
    return vertex
