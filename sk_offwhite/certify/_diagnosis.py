r"""Why a sparsity certificate holds or fails: the sparsest feasible support, searched.

Theorem 3 (and its local form, Theorem 5) is a *sufficient* test: "cannot certify" means
either that the support $S$ of $\hat\omega$ is not the maximally sparse one
(Definition 3: a support with fewer terms also satisfies the data constraint) or that the
test is too conservative to tell. The two are told apart by looking for a sparser support
directly. On the problem $y = \Phi_\theta\theta + \Phi\omega + \eta$,
$\|\eta\|_2 \le \mu$, with $\Upsilon_0 = I - \Phi_\theta\Phi_\theta^\dagger$,
the best residual of a support $K$ is

$$
r(K) = \min_{\theta, \omega_K} \|y - \Phi_\theta\theta - \Phi_K\omega_K\|_2
     = \min_{\omega_K} \|\Upsilon_0 y - \Upsilon_0\Phi_K\omega_K\|_2 ,
$$

and $K$ is feasible when $r(K) \le \mu$.
[`sparsest_feasible_support`][sk_offwhite.certify.sparsest_feasible_support] tries every support of
size $k = 0, 1, \dots, M - 1$ (exhaustively while $\binom{m'}{k} \le$ ``max_subsets``, else by
greedy forward selection, which can miss one) and returns the first feasible one. The residuals are
computed exactly on a thin QR factorisation of $[\Upsilon_0\Phi\ \ \Upsilon_0 y]$, so each support
costs an $(m'+1) \times k$ least-squares problem whatever $T$.

The diagnosis also reports $\|\Upsilon_0\Phi\hat\omega\|_2$, the part of the
estimated correction the physics cannot absorb (an estimate of
$\|\Upsilon J_\omega\bar\omega\|_2$ in Section 5.1): when it is of the order of
$\mu$, the noise can hide the correction, or most of it, and a sparser support fits.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ._relaxation import LinearProblem

__all__ = ["SparsityDiagnosis", "diagnose", "sparsest_feasible_support"]


def _projector(phi_theta: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    r"""$(I - \Phi_\theta\Phi_\theta^\dagger)$ ``matrix`` (orthonormal basis by SVD)."""
    if phi_theta.shape[1] == 0:
        return matrix.copy()
    u, s, _ = np.linalg.svd(phi_theta, full_matrices=False)
    rank = int(np.sum(s > s[0] * max(phi_theta.shape) * np.finfo(float).eps)) if s.size else 0
    return matrix - u[:, :rank] @ (u[:, :rank].T @ matrix)


@dataclass(frozen=True)
class _Compressed:
    """$R$ of the thin QR of $[\\Upsilon_0\\Phi\\ \\Upsilon_0 y]$."""

    columns: np.ndarray
    target: np.ndarray


def _compress(problem: LinearProblem) -> _Compressed:
    stacked = _projector(problem.phi_theta, np.column_stack([problem.phi, problem.y]))
    r = np.linalg.qr(stacked, mode="r")
    return _Compressed(r[:, :-1], r[:, -1])


def _support_residual(compressed: _Compressed, support) -> float:
    r"""$r(K)$ of the support ``support`` (a sequence of column indices)."""
    if len(support) == 0:
        return float(np.linalg.norm(compressed.target))
    columns = compressed.columns[:, list(support)]
    coef = np.linalg.lstsq(columns, compressed.target, rcond=None)[0]
    return float(np.linalg.norm(compressed.target - columns @ coef))


def _best_of_size(compressed: _Compressed, candidates, k: int, max_subsets: int):
    """Smallest-residual support of size ``k``: exhaustive, or greedy past ``max_subsets``."""
    if math.comb(len(candidates), k) <= max_subsets:
        subsets = itertools.combinations(candidates, k)
        return min(((s, _support_residual(compressed, s)) for s in subsets), key=lambda p: p[1])
    return _greedy(compressed, candidates, k), None


def _greedy(compressed: _Compressed, candidates, k: int) -> tuple[int, ...]:
    """Forward selection: add, ``k`` times, the column that lowers the residual most."""
    chosen: tuple[int, ...] = ()
    for _ in range(k):
        rest = [j for j in candidates if j not in chosen]
        chosen = min((chosen + (j,) for j in rest), key=lambda s: _support_residual(compressed, s))
    return chosen


def sparsest_feasible_support(
    problem: LinearProblem,
    max_size: int,
    *,
    exclude=None,
    max_subsets: int = 20_000,
) -> tuple[tuple[int, ...] | None, float, bool]:
    r"""The smallest support $K$, $|K| \le$ ``max_size``, with $r(K) \le \mu$.

    Parameters
    ----------
    problem : LinearProblem
    max_size : int
        Largest support size tried (``M - 1`` to test the maximal sparsity of an
        ``M``-term estimate).
    exclude : array-like of bool, optional
        Columns never used (those confounded with the physics add nothing to $\theta$).
    max_subsets : int, default=20000
        Sizes with more supports than this are searched greedily.

    Returns
    -------
    support : tuple of int or None
        Column indices of the first feasible support found (smallest size, then smallest
        residual), or ``None``.
    residual : float
        Its $r(K)$; when none is feasible, the smallest residual found at
        ``max_size`` (``inf`` when ``max_size < 0``).
    exhaustive : bool
        ``True`` when every size was enumerated, so ``None`` proves that no such support
        exists.
    """
    compressed = _compress(problem)
    skip = np.zeros(problem.n_features, bool) if exclude is None else np.asarray(exclude, bool)
    candidates = [int(j) for j in np.flatnonzero(~skip)]
    best, exhaustive = (None, np.inf), True
    for k in range(min(max_size, len(candidates)) + 1):
        support, residual = _best_of_size(compressed, candidates, k, max_subsets)
        if residual is None:
            exhaustive, residual = False, _support_residual(compressed, support)
        if residual <= problem.mu:
            return tuple(support), residual, exhaustive
        best = (None, residual)
    return best[0], best[1], exhaustive


@dataclass(frozen=True)
class SparsityDiagnosis:
    r"""The data behind a certificate's verdict, and one sentence that states it.

    Attributes
    ----------
    support_size : int
        $M = |\mathrm{supp}\,\hat\omega|$.
    mu : float
        The noise bound used.
    residual : float
        $\min_\theta \|y - \Phi_\theta\theta - \Phi\hat\omega\|_2$, the residual
        $\hat\omega$ leaves (feasible when $\le \mu$).
    physics_residual : float
        $\|\Upsilon_0 y\|_2$, the residual with no correction at all.
    unexplained : float
        $\|\Upsilon_0\Phi\hat\omega\|_2$, the part of the estimated correction the
        physics cannot absorb (estimate of $\|\Upsilon J_\omega\bar\omega\|_2$).
    sparser_support : tuple of str or None
        A support with fewer than $M$ terms that fits within $\mu$ (the
        smallest found), or ``None``.
    sparser_residual : float
        Its residual, or (when ``None``) the best residual with $M - 1$ terms.
    exhaustive : bool
        Whether the search enumerated every support (``None`` is then a proof).
    sigma2, tau, eta : float
        $\sigma^2_n$, $\tau$ and $\eta(\hat\omega)$ of the certificate.
    certified : bool or None
        The certificate's verdict.
    reason : str
        The certificate's reason.
    sparsity_level : int
        The level $n$ of $\sigma^2_n$ (``sigma2``) used by $\tau$.
    vertex : {'l1', 'searched'}
        The certificate's vertex (see
        [`SparsityCertificate`][sk_offwhite.certify.SparsityCertificate]).
    compared : float
        What $\tau$ was compared with: $\eta(\hat\omega)$ at (11)'s
        solution, $\min_{i \in S}\mathrm{sign}(\hat\omega_i)\omega^v_i$ at a
        searched vertex.
    l1_ratio : float
        $\tau/\eta(\hat\omega)$ at (11)'s solution (``nan`` when not computed).
    """

    support_size: int
    mu: float
    residual: float
    physics_residual: float
    unexplained: float
    sparser_support: tuple[str, ...] | None
    sparser_residual: float
    exhaustive: bool
    sigma2: float
    tau: float
    eta: float
    certified: bool | None
    reason: str
    sparsity_level: int = 0
    vertex: str = "l1"
    compared: float = float("nan")
    l1_ratio: float = float("nan")

    @property
    def sparser_exists(self) -> bool:
        """A support with fewer terms than $\\hat\\omega$ fits within $\\mu$."""
        return self.sparser_support is not None

    @property
    def cause(self) -> str:
        """``'certified'``, ``'infeasible'``, ``'sparser support'``, ``'conservative'``
        or ``'not computed'``."""
        if self.residual > self.mu * (1 + 1e-3):
            return "infeasible"  # also when (11) is then infeasible and no verdict is made
        if self.certified is None:
            return "not computed"
        if self.sparser_exists:
            return "sparser support"
        return "certified" if self.certified else "conservative"

    def sentence(self) -> str:
        """Why the verdict is what it is, in one sentence with the numbers."""
        return _SENTENCES[self.cause](self)


def _set(names) -> str:
    return "{" + ", ".join(names) + "}"


def _sparser(d: SparsityDiagnosis) -> str:
    k = len(d.sparser_support)
    head = (
        "the physics alone (no correction) already explains the data within mu"
        if k == 0
        else f"a {k}-term support {_set(d.sparser_support)} already explains the data within mu"
    )
    return (
        f"{head} (residual {d.sparser_residual:.3g} <= mu = {d.mu:.3g}), so the {d.support_size}"
        f"-term support of omega_hat is not maximally sparse at this noise level; the part "
        f"of the estimated correction the physics cannot absorb, ||Upsilon Phi omega_hat|| "
        f"= {d.unexplained:.3g}, is of the order of mu."
    )


def _conservative(d: SparsityDiagnosis) -> str:
    search = "exhaustive search" if d.exhaustive else "greedy search (not a proof)"
    return (
        f"no support with fewer than {d.support_size} terms fits within mu = {d.mu:.3g} "
        f"({search}; best residual {d.sparser_residual:.3g}), so omega_hat may well be "
        f"maximally sparse, but the sufficient test does not show it: {d.reason}; "
        f"tau/eta = {d.tau / d.eta:.3g}, tau grows with mu (the error at omega^v has norm "
        f"mu, against {d.residual:.3g} at omega_hat) over sigma^2_n = {d.sigma2:.3g} "
        f"(n = {d.sparsity_level})."
    )


def _certified(d: SparsityDiagnosis) -> str:
    if d.vertex == "searched":
        head = (
            f"certified at a searched vertex omega^v (||e*(omega^v)|| >= mu): tau = "
            f"{d.tau:.3g} < min_S sign(omega_hat_i) omega^v_i = {d.compared:.3g} "
            f"(at (11)'s l1 solution tau/eta was {d.l1_ratio:.3g}; "
        )
    else:
        head = f"certified: tau = {d.tau:.3g} < eta = {d.eta:.3g} (tau/eta = {d.tau / d.eta:.3g}, "
    return head + (
        f"sigma^2_n = {d.sigma2:.3g}, n = {d.sparsity_level}); no support with fewer than "
        f"{d.support_size} terms "
        f"fits within mu = {d.mu:.3g} (best residual {d.sparser_residual:.3g})."
    )


def _infeasible(d: SparsityDiagnosis) -> str:
    return (
        f"omega_hat is not feasible: it leaves a residual {d.residual:.3g} > mu = {d.mu:.3g}; "
        f"a refined mu = 1.01 x {d.residual:.3g} makes it feasible."
    )


def _not_computed(d: SparsityDiagnosis) -> str:
    return f"no verdict: {d.reason}."


_SENTENCES = {
    "certified": _certified,
    "sparser support": _sparser,
    "conservative": _conservative,
    "infeasible": _infeasible,
    "not computed": _not_computed,
}


def diagnose(
    problem: LinearProblem, certificate, *, max_subsets: int = 20_000
) -> SparsityDiagnosis:
    r"""The [`SparsityDiagnosis`][sk_offwhite.certify.SparsityDiagnosis] of a
    [`SparsityCertificate`][sk_offwhite.certify.SparsityCertificate].

    Parameters
    ----------
    problem : LinearProblem
        The problem the certificate was computed on (same units as its ``omega_hat``).
    certificate : SparsityCertificate
    max_subsets : int, default=20000
        See [`sparsest_feasible_support`][sk_offwhite.certify.sparsest_feasible_support].

    Returns
    -------
    SparsityDiagnosis
    """
    omega = certificate.omega_hat
    size = int(np.count_nonzero(omega))
    found, best, exhaustive = sparsest_feasible_support(
        problem, size - 1, exclude=certificate.confounded, max_subsets=max_subsets
    )
    names = None if found is None else tuple(problem.feature_names[j] for j in found)
    projected = _projector(
        problem.phi_theta,
        np.column_stack([problem.y - problem.phi @ omega, problem.phi @ omega, problem.y]),
    )
    residual, unexplained, physics = np.linalg.norm(projected, axis=0)
    return SparsityDiagnosis(
        size, problem.mu, float(residual), float(physics), float(unexplained), names,
        float(best), exhaustive, certificate.sigma2, certificate.threshold, certificate.eta,
        certificate.certified, certificate.reason, certificate.sparsity_level,
        certificate.vertex, certificate.threshold + certificate.margin,
        certificate.l1_threshold / certificate.eta,
    )  # fmt: skip
