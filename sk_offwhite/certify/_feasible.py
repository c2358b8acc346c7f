r"""Worst-case parameter errors over the feasible sets FPS (19) and SFPS (20).

On a linear-in-parameters problem $y = \Phi_\theta\theta + \Phi\omega + \eta$,
$\|\eta\|_2 \le \mu$ (`_relaxation`):

$$
\mathrm{FPS} &= \{(\theta, \omega) : \|y - \Phi_\theta\theta - \Phi\omega\|_2 \le \mu\},
\\
\mathrm{SFPS} &= \mathrm{FPS} \cap \{\omega_j = 0,\ j \notin S\},
$$

with $S$ the support of a (certified) sparse estimate $\hat\omega$ (the paper's
$\mathrm{supp}(\omega) = \mathrm{supp}(\bar\omega)$, closed so that the set is
convex). So $\mathrm{SFPS} \subseteq \mathrm{FPS}$.

The worst-case errors $e^{\mathrm{FPS}}(\hat\theta) = \sup_{\mathrm{FPS}}
\|\theta - \hat\theta\|_p$ (19) and $e^{\mathrm{SFPS}}$ (20) are computed from the
per-parameter extremes, two second-order cone programs per parameter,

$$
\theta_i^{\max} = \max_{(\theta,\omega) \in \text{set}} \theta_i, \qquad
\theta_i^{\min} = \min_{(\theta,\omega) \in \text{set}} \theta_i, \qquad
e_i = \max(\theta_i^{\max} - \hat\theta_i,\ \hat\theta_i - \theta_i^{\min}).
$$

$\|e\|_\infty$ is exactly (19)/(20) for $p = \infty$; $\|e\|_2$ is the
error to the farthest corner of the bounding box, an upper bound of (19)/(20) for
$p = 2$. A set that is unbounded in some $\theta_i$ (a dictionary column
confounded with the physics, e.g. a term equal to a physical regressor) makes the program
``'unbounded'``: the status is reported and no number is given.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cvxpy as cp
import numpy as np

from ._relaxation import (
    LinearProblem,
    column_scales,
    feasible_region,
    linear_problem,
    solve_status,
)

__all__ = ["FeasibleSetBounds", "feasible_parameter_set", "feasible_set_bounds"]


@dataclass(frozen=True)
class FeasibleSetBounds:
    r"""Per-parameter extremes of FPS or SFPS and the worst-case errors (19)/(20).

    Attributes
    ----------
    kind : str
        ``'FPS'`` or ``'SFPS'``.
    status : str
        ``'optimal'`` when all programs were solved; otherwise the first other cvxpy
        status (``'infeasible'``: ``mu`` below the least-squares residual; ``'unbounded'``:
        a parameter is not bounded by the data), and the numbers below are ``None``.
    names : tuple of str
        The bounded parameters.
    theta_hat : ndarray
        The estimate the errors are measured from.
    lower, upper : ndarray or None
        $\theta^{\min}$, $\theta^{\max}$.
    worst_case : ndarray or None
        $e_i = \max(\theta_i^{\max} - \hat\theta_i, \hat\theta_i - \theta_i^{\min})$.
    support : ndarray of bool or None
        Dictionary columns allowed to be nonzero (``None`` for FPS: all).
    mu : float
    """

    kind: str
    status: str
    names: tuple[str, ...]
    theta_hat: np.ndarray
    lower: np.ndarray | None
    upper: np.ndarray | None
    worst_case: np.ndarray | None
    support: np.ndarray | None
    mu: float

    @property
    def solved(self) -> bool:
        """``True`` when every extreme was solved to optimality."""
        return self.status == cp.OPTIMAL

    @property
    def worst_case_norm(self) -> float | None:
        r"""$\|e\|_2$ (box bound of (19)/(20) for $p = 2$)."""
        return None if self.worst_case is None else float(np.linalg.norm(self.worst_case))

    @property
    def worst_case_inf(self) -> float | None:
        r"""$\|e\|_\infty$, exactly (19)/(20) for $p = \infty$."""
        return None if self.worst_case is None else float(np.max(self.worst_case, initial=0.0))

    def contains(self, theta) -> bool:
        """Whether ``theta`` lies in the bounding box ``[lower, upper]`` (necessary condition)."""
        theta = np.asarray(theta, float)
        return bool(np.all((self.lower <= theta) & (theta <= self.upper)))

    def summary(self) -> str:
        """The extremes per parameter and the worst-case error norms."""
        if not self.solved:
            return f"{self.kind}: NOT SOLVED, cvxpy status '{self.status}'."
        rows = [
            f"  {n}: [{lo:.6g}, {hi:.6g}], estimate {t:.6g}, worst-case error {e:.6g}"
            for n, lo, hi, t, e in zip(
                self.names, self.lower, self.upper, self.theta_hat, self.worst_case, strict=True
            )
        ]
        head = (
            f"{self.kind} (mu = {self.mu:.6g}): worst-case error ||e||_2 = "
            f"{self.worst_case_norm:.6g}, ||e||_inf = {self.worst_case_inf:.6g}"
        )
        return "\n".join([head, *rows])


def _extreme_program(problem: LinearProblem):
    """The cone of ``problem`` with a parametric linear objective ``max c @ theta``."""
    theta, _, cone = feasible_region(problem)
    direction = cp.Parameter(problem.n_theta)
    return cp.Problem(cp.Maximize(direction @ theta), [cone]), direction, theta


def _extremes(problem: LinearProblem, indices: np.ndarray):
    """``(status, lower, upper)`` of ``theta[indices]`` over the feasible set."""
    prob, direction, theta = _extreme_program(problem)
    bounds = np.empty((2, len(indices)))
    for k, i in enumerate(indices):
        for side, sign in enumerate((-1.0, 1.0)):
            direction.value = sign * np.eye(problem.n_theta)[i]
            status = solve_status(prob)
            if status != cp.OPTIMAL:
                return status, None, None
            bounds[side, k] = theta.value[i]
    return cp.OPTIMAL, bounds[0], bounds[1]


def unbounded_parameters(problem: LinearProblem, indices: np.ndarray, rtol: float = 1e-9):
    r"""Which ``theta[indices]`` the set leaves unbounded: a null direction of
    $[\Phi_\theta\ \Phi]$ (columns scaled to unit norm) that moves them."""
    scales = 1.0 / column_scales(np.hstack([problem.phi_theta, problem.phi]))
    stacked = np.hstack([problem.phi_theta, problem.phi]) * scales
    _, s, vt = np.linalg.svd(stacked, full_matrices=True)
    rank = int(np.sum(s > rtol * s[0])) if s.size else 0
    null = vt[rank:, :]
    return np.linalg.norm(null[:, indices], axis=0) > np.sqrt(rtol)


def _parameter_indices(problem: LinearProblem, parameters) -> np.ndarray:
    """Indices of the bounded parameters (``None``: all); names or integers accepted."""
    if parameters is None:
        return np.arange(problem.n_theta)
    names = list(problem.theta_names)
    index = [names.index(p) if isinstance(p, str) else int(p) for p in parameters]
    if any(not 0 <= i < problem.n_theta for i in index):
        raise ValueError(f"parameters must index the {problem.n_theta} columns of phi_theta.")
    return np.asarray(index, dtype=int)


def _restricted(problem: LinearProblem, support) -> tuple[LinearProblem, np.ndarray | None]:
    """``problem`` with the dictionary restricted to ``support`` (``None``: unchanged)."""
    if support is None:
        return problem, None
    support = np.asarray(support, dtype=bool).reshape(-1)
    if support.shape != (problem.n_features,):
        raise ValueError(f"support must be {problem.n_features} booleans (one per column of phi).")
    names = tuple(n for n, s in zip(problem.feature_names, support, strict=True) if s)
    return replace(problem, phi=problem.phi[:, support], feature_names=names), support


def _unbounded_status(problem: LinearProblem, free: np.ndarray) -> str:
    names = ", ".join(problem.theta_names[i] for i in free)
    return f"unbounded: {names} not determined by the data (a dictionary column is confounded)"


def feasible_set_bounds(
    problem: LinearProblem, theta_hat, *, support=None, parameters=None
) -> FeasibleSetBounds:
    """[`feasible_parameter_set`][sk_offwhite.certify.feasible_parameter_set] on an already
    validated `LinearProblem`."""
    index = _parameter_indices(problem, parameters)
    theta_hat = np.asarray(theta_hat, dtype=float).reshape(-1)
    if theta_hat.shape != index.shape or not np.all(np.isfinite(theta_hat)):
        raise ValueError(f"theta_hat must be {index.size} finite values (one per parameter).")
    restricted, support = _restricted(problem, support)
    free = unbounded_parameters(restricted, index)
    if np.any(free):
        status, lower, upper = _unbounded_status(restricted, index[free]), None, None
    else:
        status, lower, upper = _extremes(restricted, index)
    worst = None if lower is None else np.maximum(upper - theta_hat, theta_hat - lower)
    kind = "FPS" if support is None else "SFPS"
    names = tuple(problem.theta_names[i] for i in index)
    return FeasibleSetBounds(
        kind, status, names, theta_hat, lower, upper, worst, support, problem.mu
    )


def feasible_parameter_set(
    phi_theta,
    phi,
    y,
    mu: float,
    theta_hat,
    *,
    support=None,
    parameters=None,
    theta_names=None,
    feature_names=None,
) -> FeasibleSetBounds:
    r"""Worst-case parameter error over FPS (19), or over SFPS (20) when ``support`` is given.

    Parameters
    ----------
    phi_theta : array-like of shape (T, n_theta)
        Physical regressors $\Phi_\theta$ ($J_\theta$ on a linearisation).
    phi : array-like of shape (T, m)
        Dictionary $\Phi$ ($J_\omega$).
    y : array-like of shape (T,)
        Observations.
    mu : float
        Noise bound $\mu > 0$.
    theta_hat : array-like
        Estimate of the bounded parameters (same length as ``parameters``).
    support : array-like of bool of shape (m,), optional
        Dictionary columns allowed to be nonzero: SFPS. ``None``: every column, FPS.
    parameters : sequence of int or str, optional
        Which columns of ``phi_theta`` to bound (default all; the others are free nuisance
        parameters, e.g. initial states).
    theta_names, feature_names : sequence of str, optional

    Returns
    -------
    FeasibleSetBounds
        Extremes, worst-case error vector and norms; ``status`` other than ``'optimal'``
        (infeasible ``mu``, unbounded set, solver error) leaves the numbers ``None``.
    """
    problem = linear_problem(
        phi_theta, phi, y, mu, theta_names=theta_names, feature_names=feature_names
    )
    return feasible_set_bounds(problem, theta_hat, support=support, parameters=parameters)
