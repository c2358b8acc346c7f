r"""Which $\hat\omega$ a certificate tests: the fit's own, pruned, optionally refitted.

Remark 1 of Donati et al. lets Theorems 3 and 5 certify *any* estimate. Section 5.1
certifies the multi-step fit's $\hat\omega$, so
[`certify_estimator`][sk_offwhite.certify.certify_estimator] does too by default. On the local
linearisation (`_linearise`) each term's size in the data is its contribution

$$
c_j = \|J_{\omega,j}\hat\omega_j\|_2 = |\hat\omega_j|\,\|J_{\omega,j}\|_2,
$$

and a term whose contribution is below ``prune_tol`` (1 %) of the largest is set to zero
([`prune_by_contribution`][sk_offwhite.certify.prune_by_contribution]): it moves the simulated
output by less than a hundredth of the main term and would otherwise enter $M$ with a tiny
$\eta(\hat\omega) = \min_S |\hat\omega_i|$. The estimator's own pruning stage uses
the same 1 % rule on its scaled penalty, so on a converged fit this seldom removes
anything. Optionally the estimate is the least-squares refit on that support
(`least_squares_refit`), which minimises the residual on it.

The noise bound $\mu$ can be *refined* to the residual the estimate actually
leaves ([`refined_mu`][sk_offwhite.certify.refined_mu]), $\mu_r = (1 + \epsilon)\,\min_\theta \|y -
\Phi_\theta\theta - \Phi\hat\omega\|_2$ with $\epsilon = 0.01$: the smallest bound
under which $\hat\omega$ is feasible, instead of the worst case $b\sqrt{T}$ of
a per-sample bound $|\eta_k| \le b$.
"""

from __future__ import annotations

import numpy as np

from ._relaxation import LinearProblem, contributions, least_squares_refit, solve_relaxation

__all__ = [
    "estimate_residual",
    "prune_by_contribution",
    "refined_mu",
    "refit_on_support",
    "select_estimate",
]


def prune_by_contribution(
    problem: LinearProblem, omega: np.ndarray, tol: float = 0.01
) -> np.ndarray:
    r"""Zero the terms with $c_j < \text{tol}\,\max_k c_k$.

    Parameters
    ----------
    problem : LinearProblem
        Gives $\Phi$ (the columns $J_{\omega,j}$ on a linearisation).
    omega : ndarray of shape (m,)
    tol : float, default=0.01
        Relative threshold; ``0`` keeps every non-zero term.

    Returns
    -------
    ndarray of shape (m,)
        A copy of ``omega`` with the negligible terms set to exactly 0.
    """
    omega = np.asarray(omega, float).copy()
    contribution = contributions(problem, omega)
    omega[contribution < tol * np.max(contribution, initial=0.0)] = 0.0
    return omega


def refit_on_support(problem: LinearProblem, omega: np.ndarray) -> np.ndarray:
    r"""The least-squares $\omega$ on the support of ``omega`` (zeros elsewhere).

    $(\theta, \omega_S) = \arg\min \|y - \Phi_\theta\theta - \Phi_S\omega_S\|_2$.
    """
    return least_squares_refit(problem, np.asarray(omega) != 0)[1]


def estimate_residual(problem: LinearProblem, omega: np.ndarray) -> float:
    r"""$\min_\theta \|y - \Phi_\theta\theta - \Phi\omega\|_2$ (θ free, ω fixed)."""
    target = problem.y - problem.phi @ np.asarray(omega, float)
    if problem.n_theta == 0:
        return float(np.linalg.norm(target))
    theta = np.linalg.lstsq(problem.phi_theta, target, rcond=None)[0]
    return float(np.linalg.norm(target - problem.phi_theta @ theta))


def refined_mu(problem: LinearProblem, omega: np.ndarray, factor: float = 1.01) -> float:
    r"""The refined noise bound $\mu_r = \text{factor} \cdot \min_\theta \|y -
    \Phi_\theta\theta - \Phi\omega\|_2$ (strictly positive: at least ``1e-12`` times
    $\|y\|$)."""
    floor = 1e-12 * max(float(np.linalg.norm(problem.y)), 1.0)
    return max(factor * estimate_residual(problem, omega), floor)


def select_estimate(
    problem: LinearProblem,
    fitted: np.ndarray,
    *,
    estimate: str = "fit",
    prune_tol: float = 0.01,
    refit: bool = False,
    normalize_columns: bool = False,
) -> np.ndarray:
    r"""The $\hat\omega$ to certify: the fit's or the relaxation's, pruned, refitted.

    Parameters
    ----------
    problem : LinearProblem
        The (local) problem; its $\mu$ is used only by ``estimate='relaxation'``.
    fitted : ndarray of shape (m,)
        The fit's own estimate (``Linearisation.omega_hat``).
    estimate : {'fit', 'relaxation'}, default='fit'
        ``'fit'``: ``fitted`` (what Section 5.1 certifies). ``'relaxation'``: the pruned
        solution of (10)/(15) on ``problem`` (``fitted`` when it is not solved).
    prune_tol : float, default=0.01
        [`prune_by_contribution`][sk_offwhite.certify.prune_by_contribution] threshold.
    refit : bool, default=False
        Replace the estimate by the least-squares refit on its support.
    normalize_columns : bool, default=False
        Passed to the relaxation.

    Returns
    -------
    ndarray of shape (m,)
    """
    if estimate not in ("fit", "relaxation"):
        raise ValueError(f"estimate must be 'fit' or 'relaxation', got {estimate!r}.")
    omega = np.asarray(fitted, float)
    if estimate == "relaxation":
        relaxation = solve_relaxation(problem, normalize_columns=normalize_columns)
        omega = relaxation.omega if relaxation.solved and np.any(relaxation.omega) else omega
    omega = prune_by_contribution(problem, omega, prune_tol)
    return refit_on_support(problem, omega) if refit and np.any(omega) else omega
