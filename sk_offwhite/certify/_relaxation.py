r"""The convex sparse relaxation (10) of Donati et al. and the linear problem it lives on.

A *linear-in-parameters* problem is the data model

$$
y = \Phi_\theta\, \theta + \Phi\, \omega + \eta, \qquad \|\eta\|_2 \le \mu,
$$

with $\Phi_\theta \in \mathbb{R}^{T \times n_\theta}$ the physical regressors (the
matrix $\Xi$ of eq. 7), $\Phi \in \mathbb{R}^{T \times m}$ the dictionary and
$\mu$ a bound on the noise norm (Assumption 2). The relaxation (10) is

$$
(\hat\theta, \hat\omega) = \arg\min_{\theta, \omega} \|\omega\|_1
\quad \text{s.t.} \quad \|y - \Phi_\theta \theta - \Phi \omega\|_2 \le \mu,
$$

with $\theta$ free (unpenalised). The same problem on the local linearisation of a
multi-step fit (``y`` the shifted residual, $\Phi_\theta = J_\theta$,
$\Phi = J_\omega$, see `_linearise`) is the local form of the multi-step
relaxation (15).

Numerics: the $T$-row constraint is compressed exactly with a thin QR factorisation
$[\Phi_\theta\ \Phi] = QR$,
$\|y - Ax\|_2 = \|[Q^\top y - Rx;\ \|y - QQ^\top y\|_2]\|_2$, so every cone has
$n_\theta + m + 1$ entries whatever $T$; the dictionary columns are rescaled to
unit norm inside the solver (the objective keeps the original $\|\omega\|_1$).

Support: the interior-point solution is never exactly sparse. Terms whose contribution
$\|\varphi_j\hat\omega_j\|_2$ is negligible against the largest one or against
$\mu$ are set to 0 (`support_of`); by default the remaining ones are then
pruned by backward elimination against the data constraint (`prune_support`) and
the estimate is the least-squares refit on the final support (`least_squares_refit`),
so the support is exact and every term in it is needed to fit within $\mu$.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import cvxpy as cp
import numpy as np

__all__ = [
    "LinearProblem",
    "SparseRelaxation",
    "linear_problem",
    "sparse_relaxation",
    "solve_status",
    "feasible_region",
]

SOLVER = "CLARABEL"


@dataclass(frozen=True)
class LinearProblem:
    r"""Validated data of $y = \Phi_\theta \theta + \Phi \omega + \eta$,
    $\|\eta\|_2 \le \mu$.

    Attributes
    ----------
    phi_theta : ndarray of shape (T, n_theta)
    phi : ndarray of shape (T, m)
    y : ndarray of shape (T,)
    mu : float
    theta_names, feature_names : tuple of str
    """

    phi_theta: np.ndarray
    phi: np.ndarray
    y: np.ndarray
    mu: float
    theta_names: tuple[str, ...]
    feature_names: tuple[str, ...]

    @property
    def n_theta(self) -> int:
        return self.phi_theta.shape[1]

    @property
    def n_features(self) -> int:
        return self.phi.shape[1]


def _finite_matrix(name: str, value, n_rows: int | None) -> np.ndarray:
    """``value`` as a finite 2-D float array (a 1-D array is one column)."""
    array = np.asarray(value, dtype=float)
    array = array.reshape(-1, 1) if array.ndim == 1 else array
    if array.ndim != 2:
        raise ValueError(f"{name} must be a 2-D array, got shape {np.shape(value)}.")
    if n_rows is not None and array.shape[0] != n_rows:
        raise ValueError(f"{name} must have {n_rows} rows (len(y)), got shape {array.shape}.")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} contains NaN or inf.")
    return array


def _names(name: str, names, count: int, prefix: str) -> tuple[str, ...]:
    if names is None:
        return tuple(f"{prefix}{i}" for i in range(count))
    names = tuple(str(n) for n in names)
    if len(names) != count:
        raise ValueError(f"{name} must have {count} entries, got {len(names)}.")
    return names


def linear_problem(
    phi_theta, phi, y, mu: float, *, theta_names=None, feature_names=None
) -> LinearProblem:
    r"""Validate the data of a linear-in-parameters problem.

    Parameters
    ----------
    phi_theta : array-like of shape (T, n_theta)
        Physical regressors $\Phi_\theta$ (``n_theta`` may be 0).
    phi : array-like of shape (T, m)
        Dictionary $\Phi$.
    y : array-like of shape (T,)
        Observations.
    mu : float
        Noise bound $\mu > 0$ on $\|\eta\|_2$.
    theta_names, feature_names : sequence of str, optional
        Names used in summaries (default ``theta0, ...`` and ``phi0, ...``).

    Returns
    -------
    LinearProblem

    Raises
    ------
    ValueError
        On a wrong shape, NaN/inf, or $\mu \le 0$.
    """
    y = np.asarray(y, dtype=float).reshape(-1)
    if not np.all(np.isfinite(y)):
        raise ValueError("y contains NaN or inf.")
    if not (np.isfinite(mu) and mu > 0):
        raise ValueError(f"mu must be a finite noise bound > 0, got {mu!r}.")
    phi_theta = _finite_matrix("phi_theta", phi_theta, len(y))
    phi = _finite_matrix("phi", phi, len(y))
    return LinearProblem(
        phi_theta,
        phi,
        y,
        float(mu),
        _names("theta_names", theta_names, phi_theta.shape[1], "theta"),
        _names("feature_names", feature_names, phi.shape[1], "phi"),
    )


def column_scales(matrix: np.ndarray) -> np.ndarray:
    """Euclidean norm of every column, zero norms replaced by 1."""
    norms = np.linalg.norm(matrix, axis=0)
    return np.where(norms > 0, norms, 1.0)


def unit_norm_problem(problem: LinearProblem) -> tuple[LinearProblem, np.ndarray]:
    r"""The problem in unit-norm dictionary columns, and the column norms $d$.

    With $D = \mathrm{diag}(d)$, $d_j = \|\varphi_j\|_2$ and
    $\omega' = D\omega$, $\Phi\omega = (\Phi D^{-1})\omega'$: the data model
    and every support are unchanged, and $\|\omega'\|_1 = \sum_j
    \|\varphi_j\|_2\, |\omega_j|$ weighs each term by the size of its regressor, so
    the relaxation no longer depends on the units of the dictionary.
    """
    scales = column_scales(problem.phi)
    return replace(problem, phi=problem.phi / scales), scales


def compress(matrix: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    r"""``(R, c, r_perp)`` with $\|y - Ax\|_2^2 = \|c - Rx\|_2^2 + r_\perp^2$ for all x.

    From the thin QR factorisation $A = QR$: $c = Q^\top y$ and
    $r_\perp = \|y - Qc\|_2$. Exact for any ``A`` (rank-deficient included).
    """
    if matrix.shape[1] == 0:
        return np.zeros((0, 0)), np.zeros(0), float(np.linalg.norm(y))
    q, r = np.linalg.qr(matrix, mode="reduced")
    c = q.T @ y
    return r, c, float(np.linalg.norm(y - q @ c))


def _unit_scales(problem: LinearProblem) -> tuple[np.ndarray, np.ndarray]:
    """Column multipliers that give ``phi_theta`` and ``phi`` unit-norm columns."""
    return 1.0 / column_scales(problem.phi_theta), 1.0 / column_scales(problem.phi)


def feasible_region(problem: LinearProblem):
    r"""Expressions ``theta``, ``omega`` and the cone of $\|y - A x\|_2 \le \mu$.

    Written for accuracy relative to $\mu$ (a noise-free record can have
    $\mu \ll \|y\|$): with unit-norm columns $A = [\Phi_\theta\ \Phi] D$, its
    compressed form ``(R, c, r_perp)`` (`compress`) and the least-squares solution
    $x_{LS}$, the variables are $x = x_{LS} + \mu d$ and the cone reads
    $\|[(c - Rx_{LS})/\mu - Rd;\ r_\perp/\mu]\|_2 \le 1$: every entry is of order
    one. ``theta`` (``omega``) is ``None`` when there is no such column.
    """
    s_theta, s_omega = _unit_scales(problem)
    r, c, r_perp = compress(
        np.hstack([problem.phi_theta * s_theta, problem.phi * s_omega]), problem.y
    )
    x_ls = np.linalg.lstsq(r, c, rcond=None)[0]
    d = cp.Variable(r.shape[1])
    mu = problem.mu
    cone = cp.norm(cp.hstack([(c - r @ x_ls) / mu - r @ d, np.array([r_perp / mu])]), 2) <= 1
    x = x_ls + mu * d
    n = problem.n_theta
    theta = cp.multiply(s_theta, x[:n]) if n else None
    omega = cp.multiply(s_omega, x[n:]) if problem.n_features else None
    return theta, omega, cone


def solve_status(prob: cp.Problem) -> str:
    """Solve ``prob`` with Clarabel; the cvxpy status, or ``'solver_error: ...'``."""
    try:
        prob.solve(solver=SOLVER)
    except cp.error.SolverError as error:
        return f"solver_error: {error}"
    return str(prob.status)


def contributions(problem: LinearProblem, omega: np.ndarray) -> np.ndarray:
    r"""Size of every term in the data: $c_j = \|\varphi_j\omega_j\|_2 =
    |\omega_j|\,\|\varphi_j\|_2$ (in the units of $y$, whatever those of
    $\omega_j$)."""
    return np.abs(omega) * np.linalg.norm(problem.phi, axis=0)


def support_of(contribution: np.ndarray, mu: float, tol: float) -> np.ndarray:
    r"""Terms whose contribution is not negligible: $c_j > \text{tol}\,
    \max(\max_k c_k,\ \mu)$.

    Interior-point solutions are never exactly sparse. The threshold is relative twice
    over, never an absolute coefficient size: to the largest term (round-off of the
    solver) and to the noise bound $\mu$ (a term that moves the residual by less
    than ``tol`` $\mu$ is below anything the data can tell). The second makes an
    all-zero optimum ($\hat\omega = 0$ up to the solver's $10^{-10}$) give
    an empty support, which a threshold relative to the largest entry alone cannot.
    """
    return contribution > tol * max(np.max(contribution, initial=0.0), mu)


def residual_norm(problem: LinearProblem, theta: np.ndarray, omega: np.ndarray) -> float:
    r"""$\|y - \Phi_\theta\theta - \Phi\omega\|_2$."""
    return float(np.linalg.norm(problem.y - problem.phi_theta @ theta - problem.phi @ omega))


def least_squares_refit(
    problem: LinearProblem, support: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    r"""The debiased estimate on a support: $(\theta, \omega)$ and its residual norm.

    $$
    (\theta, \omega_S) = \arg\min \|y - \Phi_\theta\theta - \Phi_S\omega_S\|_2,
    \qquad \omega_{S^c} = 0,
    $$

    solved on unit-norm columns (minimum-norm solution when they are dependent, the
    residual is the least one either way).
    """
    columns = np.hstack([problem.phi_theta, problem.phi[:, support]])
    scales = column_scales(columns)
    coef = np.linalg.lstsq(columns / scales, problem.y, rcond=None)[0] / scales
    theta, omega = coef[: problem.n_theta], np.zeros(problem.n_features)
    omega[support] = coef[problem.n_theta :]
    return theta, omega, residual_norm(problem, theta, omega)


def prune_support(
    problem: LinearProblem, support: np.ndarray, contribution: np.ndarray
) -> np.ndarray:
    r"""Backward elimination: drop every term the data constraint does not need.

    The terms of ``support`` are visited once, in ascending order of ``contribution``;
    term $j$ is removed when the least-squares refit without it is still feasible,
    $\min_{\theta, \omega_{S \setminus j}} \|y - \Phi_\theta\theta -
    \Phi_{S \setminus j}\omega_{S \setminus j}\|_2 \le \mu$. A term kept at its
    visit stays needed at the end (the refit residual only grows as the support
    shrinks), so no single term of the result can be removed.
    """
    support = support.copy()
    candidates = np.flatnonzero(support)
    for j in candidates[np.argsort(contribution[candidates], kind="stable")]:
        trial = support.copy()
        trial[j] = False
        if least_squares_refit(problem, trial)[2] <= problem.mu:
            support = trial
    return support


@dataclass(frozen=True)
class SparseRelaxation:
    r"""Solution of the relaxation (10) (or its local multi-step form (15)).

    Attributes
    ----------
    status : str
        cvxpy status (``'optimal'`` is the only one whose numbers are a solution).
    theta, omega : ndarray or None
        $\hat\theta$, $\hat\omega$ (``None`` unless the solve is optimal);
        ``omega`` is exactly 0 off the support. With ``pruned`` they are the
        least-squares refit on the support, otherwise the $\ell_1$ solution.
    support : ndarray of bool or None
        $\mathrm{supp}(\hat\omega)$.
    residual_norm : float or None
        $\|y - \Phi_\theta\hat\theta - \Phi\hat\omega\|_2$ for the returned
        ``theta`` and ``omega``.
    mu : float
    theta_names, feature_names : tuple of str
    normalize_columns : bool
        Whether the objective was $\sum_j \|\varphi_j\|_2 |\omega_j|$ (``omega``
        is in the dictionary's own units either way).
    pruned : bool
        Whether the support was pruned and the estimate refitted by least squares
        (``prune=True`` of [`sparse_relaxation`][sk_offwhite.certify.sparse_relaxation]).
    """

    status: str
    theta: np.ndarray | None
    omega: np.ndarray | None
    support: np.ndarray | None
    residual_norm: float | None
    mu: float
    theta_names: tuple[str, ...] = field(default=())
    feature_names: tuple[str, ...] = field(default=())
    normalize_columns: bool = False
    pruned: bool = False

    @property
    def solved(self) -> bool:
        """``True`` when cvxpy reports ``'optimal'``."""
        return self.status == cp.OPTIMAL

    def selected(self) -> list[str]:
        """Names of the dictionary terms in the support."""
        if self.support is None:
            return []
        return [n for n, keep in zip(self.feature_names, self.support, strict=True) if keep]

    def summary(self) -> str:
        """A few lines: status, support, coefficients and the residual against ``mu``."""
        if not self.solved:
            return f"Sparse relaxation (10): NOT SOLVED, cvxpy status '{self.status}'."
        terms = ", ".join(
            f"{n} = {w:.6g}"
            for n, w, s in zip(self.feature_names, self.omega, self.support, strict=True)
            if s
        )
        theta = ", ".join(
            f"{n} = {v:.6g}" for n, v in zip(self.theta_names, self.theta, strict=True)
        )
        objective = "sum ||phi_j|| |omega_j|" if self.normalize_columns else "||omega||_1"
        estimate = "pruned, least-squares refit" if self.pruned else "l1 solution"
        return "\n".join(
            [
                f"Sparse relaxation (10), min {objective}: optimal, "
                f"|supp| = {int(self.support.sum())} ({estimate})",
                f"  support: {terms or '(empty)'}",
                f"  theta: {theta or '(none)'}",
                f"  residual norm {self.residual_norm:.6g} <= mu = {self.mu:.6g}",
            ]
        )


def _estimate(problem, theta, omega, tol, prune):
    r"""``(theta, omega, support)`` from the solver's $\ell_1$ solution: thresholded
    (`support_of`), or pruned and refitted (`prune_support`,
    `least_squares_refit`)."""
    theta_l1 = np.asarray(theta.value, float) if problem.n_theta else np.zeros(0)
    omega_l1 = np.asarray(omega.value, float)
    contribution = contributions(problem, omega_l1)
    support = support_of(contribution, problem.mu, tol)
    if prune:
        support = prune_support(problem, support, contribution)
        return *least_squares_refit(problem, support)[:2], support
    return theta_l1, np.where(support, omega_l1, 0.0), support


def _relaxation_result(problem, status, theta, omega, tol, prune) -> SparseRelaxation:
    names = (problem.theta_names, problem.feature_names)
    if status != cp.OPTIMAL:
        return SparseRelaxation(status, None, None, None, None, problem.mu, *names)
    theta_hat, omega_hat, support = _estimate(problem, theta, omega, tol, prune)
    norm = residual_norm(problem, theta_hat, omega_hat)
    return SparseRelaxation(
        status, theta_hat, omega_hat, support, norm, problem.mu, *names, pruned=prune
    )


def solve_relaxation(
    problem: LinearProblem,
    *,
    support_tol: float = 1e-6,
    normalize_columns: bool = False,
    prune: bool = True,
) -> SparseRelaxation:
    r"""[`sparse_relaxation`][sk_offwhite.certify.sparse_relaxation] on an already validated
    `LinearProblem`.

    Solves $\min \|\omega\|_1$ (or $\sum_j \|\varphi_j\|_2|\omega_j|$
    with ``normalize_columns``) s.t. $\|y - \Phi_\theta\theta - \Phi\omega\|_2
    \le \mu$, keeps the terms with $c_j = \|\varphi_j\hat\omega_j\|_2 >$
    ``support_tol`` $\max(\max_k c_k, \mu)$ and, with ``prune``, removes in
    ascending $c_j$ every term whose removal keeps the least-squares refit within
    $\mu$, then returns that refit on the final support (see
    [`sparse_relaxation`][sk_offwhite.certify.sparse_relaxation] for the details).
    """
    if normalize_columns:
        scaled, scales = unit_norm_problem(problem)
        result = solve_relaxation(scaled, support_tol=support_tol, prune=prune)
        omega = None if result.omega is None else result.omega / scales
        return replace(result, omega=omega, normalize_columns=True)
    theta, omega, cone = feasible_region(problem)
    prob = cp.Problem(cp.Minimize(cp.norm(omega, 1)), [cone])
    status = solve_status(prob)
    return _relaxation_result(problem, status, theta, omega, support_tol, prune)


def sparse_relaxation(
    phi_theta,
    phi,
    y,
    mu: float,
    *,
    support_tol: float = 1e-6,
    normalize_columns: bool = False,
    prune: bool = True,
    theta_names=None,
    feature_names=None,
) -> SparseRelaxation:
    r"""Solve the convex relaxation (10): the smallest-$\ell_1$ correction within the bound.

    $$
    (\hat\theta, \hat\omega) = \arg\min_{\theta, \omega} \|\omega\|_1
    \quad \text{s.t.} \quad \|y - \Phi_\theta\theta - \Phi\omega\|_2 \le \mu .
    $$

    Parameters
    ----------
    phi_theta : array-like of shape (T, n_theta)
        Physical regressors $\Phi_\theta$ ($\Xi$ in the paper); $\theta$ is
        free.
    phi : array-like of shape (T, m)
        Dictionary $\Phi$.
    y : array-like of shape (T,)
        Observations.
    mu : float
        Noise bound $\mu > 0$ (Assumption 2: $\|\eta\|_2 \le \mu$).
    support_tol : float, default=1e-6
        Round-off threshold, relative (never an absolute coefficient size). With the
        contributions $c_j = \|\varphi_j\hat\omega_j\|_2 = |\hat\omega_j|\,
        \|\varphi_j\|_2$ of the $\ell_1$ solution, term $j$ is a candidate
        when $c_j >$ ``support_tol`` $\cdot \max(\max_k c_k,\ \mu)$; the
        others are set to exactly 0. The floor ``support_tol`` $\mu$ (a term that
        moves the residual by less than that is negligible against the noise) makes an
        all-zero optimum return an empty support.
    normalize_columns : bool, default=False
        Minimise $\sum_j \|\varphi_j\|_2\, |\omega_j|$ instead of
        $\|\omega\|_1$: the relaxation (10) on the dictionary rescaled to unit-norm
        columns (as pysindy's ``normalize_columns``). The plain $\ell_1$ norm favours
        terms with large regressors whatever their role; the weighted one does not depend
        on the units of the dictionary. ``omega`` is returned in the original units.
    prune : bool, default=True
        Make the support exact. With a tight $\mu$ the $\ell_1$ solution can
        carry small spurious terms, negligible against the largest contribution but
        above the threshold, that the threshold above keeps. With ``prune``,
        the candidate terms are visited once in ascending order of $c_j$, and term
        $j$ is removed from the current support $S$ when the least-squares
        refit without it still satisfies the data constraint,

        $$
        \min_{\theta,\ \omega_{S \setminus j}}
        \|y - \Phi_\theta\theta - \Phi_{S \setminus j}\omega_{S \setminus j}\|_2
        \le \mu,
        $$

        so a term is kept only if removing it violates the constraint (this holds for
        every term of the final support, not only at its visit: the refit residual
        only grows as $S$ shrinks). The returned estimate is then the debiased
        least-squares refit on the final support $S$,
        $(\hat\theta, \hat\omega_S) = \arg\min \|y - \Phi_\theta\theta -
        \Phi_S\omega_S\|_2$, $\hat\omega_{S^c} = 0$: its residual is
        $\le \mu$ whenever a term was removed, and otherwise no larger than that of
        the thresholded $\ell_1$ solution (which is a candidate of the same least
        squares), so it is kept over the latter in every case. ``prune=False`` returns
        the thresholded $\ell_1$ solution itself.
    theta_names, feature_names : sequence of str, optional
        Names for the summary.

    Returns
    -------
    SparseRelaxation
        ``residual_norm`` is recomputed for the returned ``theta`` and ``omega``. With
        ``status`` other than ``'optimal'`` (e.g. ``'infeasible'`` when ``mu`` is below
        the least-squares residual) the numbers are ``None``: a failed solve is never
        reported as a solution.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> xi, phi = rng.normal(size=(200, 2)), rng.normal(size=(200, 6))
    >>> y = xi @ [1.0, -2.0] + 3.0 * phi[:, 4] + rng.uniform(-0.01, 0.01, 200)
    >>> sparse_relaxation(xi, phi, y, mu=0.2).selected()
    ['phi4']
    """
    problem = linear_problem(
        phi_theta, phi, y, mu, theta_names=theta_names, feature_names=feature_names
    )
    options = dict(support_tol=support_tol, normalize_columns=normalize_columns, prune=prune)
    return solve_relaxation(problem, **options)
