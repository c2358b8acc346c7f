r"""Sparse corrections with exact zeros: a scale-free penalty, $\gamma_{max}$, pruning.

A fit with a dictionary runs in three stages, all on one compiled cost (the stages differ
only in data: which variables are frozen and the weights):

1. **Physics reference.** $\Omega = 0$ frozen, $\theta$ and $\hat x_0$
   fitted. At this point the sensitivities of the normalised simulated output to every
   weight, $J_{ij} = \partial r_{fit} / \partial \Omega_{ij}$, give the penalty scales
   $s_{ij} = \|J_{ij}\|_2$ (the RMS output change per unit weight, in output standard
   deviations) and the smallest $\gamma$ for which $\Omega = 0$ is optimal,

   $$
   \gamma_{max} = \max_{ij} \frac{|\partial C / \partial \Omega_{ij}|}{s_{ij}}
                = \max_{ij} \frac{2\,|r^\top J_{ij}|}{\|J_{ij}\|_2}
                \le 2\sqrt{F},
   $$

   the KKT condition of the weighted $\ell_1$ problem (as scikit-learn's
   ``lasso_path`` computes $\alpha_{max}$).
2. **Penalised fit** of the whole cost with $\gamma\sum_{ij} s_{ij}|\Omega_{ij}|$.
   $\gamma$ is dimensionless: a term is worth keeping when the RMS change it makes in
   the simulated output exceeds about $\gamma$ output standard deviations.
3. **Pruning and debiased refit.** The smoothed $\ell_1$ leaves small weights, never
   exact zeros, and shrinks the large ones. Terms are visited in ascending order of their
   contribution $c_{ij} = s_{ij}|\Omega_{ij}|$; a term is removed when its contribution
   is below ``prune_tol`` times the largest, or when zeroing it (with those already removed)
   does not raise the penalised objective $F + \gamma\sum c_{ij}$ (exact absolute
   values) by more than ``prune_tol`` times $F$: what the term gains in fit does not
   pay for its penalty. The remaining support is refitted without the penalty; pruning
   repeats on the refit, now judged on $F$ alone (the refit is unpenalised), until the
   support is stable. This is sequential thresholding with refit (SINDy's STLSQ) on the multi-step
   cost, with thresholds on relative contributions, never on coefficient sizes, so the
   support does not depend on the units of the data or of the dictionary.

Why this scheme: Levenberg-Marquardt needs smooth residuals (no proximal step), the
contributions and the test on $F$ bound what pruning may cost, and the refit removes
the shrinkage bias of the $\ell_1$ term.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ._backend import to_device
from ._objective import n_fit_residuals
from .solvers._core import Problem, SolverResult, fit_cost, jacobian_columns

__all__ = [
    "Reference",
    "SparseFit",
    "SparseOptions",
    "TermEvidence",
    "block_columns",
    "fit_sparse",
    "output_scale",
    "penalty_scale",
    "state_scale",
    "term_evidence",
]

MAX_PRUNE_ROUNDS = 3
DEAD_TERM = 1e-12
"""A term whose sensitivity is below this fraction of the largest cannot move the output:
it stays at zero."""


class SparseOptions(NamedTuple):
    """Pruning settings: relative tolerance, whether the support is refitted, and
    ``reference_only`` to stop after stage 1 (the weights stay zero)."""

    prune_tol: float
    refit: bool
    reference_only: bool = False


class TermEvidence(NamedTuple):
    r"""What each dictionary term could explain that the physics cannot (first order).

    With $r$ the residual of the physics-only fit, $J_\theta$ the Jacobian
    columns of every other free variable (parameters, initial states) and
    $P_\perp$ the projector onto their orthogonal complement,
    $\tilde J_{ij} = P_\perp J_{ij}$ is the part of term $ij$'s effect on the
    simulated output that no re-adjustment of the physics can mimic. Then

    $$
    \text{gain}_{ij} = \frac{(r^\top \tilde J_{ij})^2}{\|\tilde J_{ij}\|^2\,\|r\|^2},
    \quad
    \text{absorbed}_{ij} = 1 - \frac{\|\tilde J_{ij}\|^2}{\|J_{ij}\|^2},
    \quad
    \hat\Omega_{ij} = -\frac{r^\top \tilde J_{ij}}{\|\tilde J_{ij}\|^2},
    $$

    the fraction of the cost the term removes alone once the physics re-adjusts, the
    fraction of its effect the physics parameters already produce (a term that only
    re-parametrises the physics has ``absorbed`` near 1 and ``gain`` 0) and its
    linearised weight. ``conditional`` is the gain of each term when orthogonal matching
    pursuit on the projected columns takes it (0 for terms it does not take): what a term
    adds beyond the stronger ones, so that of two nearly collinear terms only one counts.
    All are dimensionless or in the weight's own units, and do not depend on the units of
    the data (the paper's $\Upsilon$ projection, §4).
    """

    gain: np.ndarray
    absorbed: np.ndarray
    estimate: np.ndarray
    conditional: np.ndarray


ABSORBED = 1.0 - 1e-6
"""A term whose effect the physics reproduces to this fraction carries no evidence."""


def term_evidence(residual, physics_columns, omega_columns) -> TermEvidence:
    """`TermEvidence` from the residual and the Jacobian columns (numpy)."""
    residual = np.asarray(residual, float)
    basis = _column_space(np.asarray(physics_columns, float))
    projected = omega_columns - basis @ (basis.T @ omega_columns)
    full = np.sum(omega_columns**2, axis=0)
    left = np.sum(projected**2, axis=0)
    absorbed = np.divide(full - left, full, out=np.ones_like(full), where=full > 0)
    usable = absorbed < ABSORBED
    inner = residual @ projected
    total = max(float(residual @ residual), 1e-300)
    safe = np.where(usable, left, 1.0)
    gain = np.where(usable, inner**2 / safe / total, 0.0)
    estimate = np.where(usable, -inner / safe, 0.0)
    conditional = matching_pursuit(residual, projected, usable)
    return TermEvidence(gain, np.clip(absorbed, 0.0, 1.0), estimate, conditional)


def matching_pursuit(residual, columns, usable, max_terms: int = 8, rtol: float = 1e-3):
    r"""Gain of each column when orthogonal matching pursuit takes it, as a fraction of
    $\|r\|^2$ (0 for the others); a column whose norm falls below ``rtol`` of its
    own once the taken ones are projected out is redundant with them."""
    residual, columns = residual.copy(), columns.copy()
    own = np.sum(columns**2, axis=0)
    usable = usable & (own > 0)
    total = max(float(residual @ residual), 1e-300)
    conditional = np.zeros(columns.shape[1])
    for _ in range(max_terms):
        norms = np.sum(columns**2, axis=0)
        alive = usable & (norms > rtol * own)
        gains = np.where(alive, (residual @ columns) ** 2 / np.where(alive, norms, 1.0), 0.0)
        j = int(np.argmax(gains))
        if gains[j] <= 1e-9 * total:
            break
        conditional[j] = gains[j] / total
        direction = columns[:, j] / np.sqrt(norms[j])
        residual = residual - direction * (direction @ residual)
        columns = columns - np.outer(direction, direction @ columns)
        usable[j] = False
    return conditional


def _column_space(columns: np.ndarray, rtol: float = 1e-10) -> np.ndarray:
    """Orthonormal basis of the span of ``columns`` (rank-revealing SVD)."""
    if columns.size == 0:
        return np.zeros((columns.shape[0], 0))
    u, s, _ = np.linalg.svd(columns, full_matrices=False)
    return u[:, s > rtol * max(float(s[0]), 1e-300)]


class Reference(NamedTuple):
    r"""The physics-only stage: its solution, the penalty scales, $\gamma_{max}$ and
    the terms' `TermEvidence`.

    It depends on the data and the structure only, not on $\gamma$ or the pruning
    settings, so a path of fits over $\gamma$ computes it once.
    """

    result: SolverResult
    scale: np.ndarray
    gamma_max: float
    evidence: TermEvidence | None = None


class SparseFit(NamedTuple):
    r"""Outcome of `fit_sparse` (numpy); ``penalty_scale`` and ``evidence`` have the
    shape of $\Omega$ (masked weights: scale 0, no evidence)."""

    free: np.ndarray
    result: SolverResult
    penalty_scale: np.ndarray
    gamma_max: float
    reference: Reference | None
    evidence: TermEvidence | None = None


def _full(values: np.ndarray, omega_flat: np.ndarray, shape, fill: float) -> np.ndarray:
    r"""``values`` of the free weights placed in an array of the shape of $\Omega$."""
    full = np.full(int(np.prod(shape)), fill)
    full[omega_flat] = values
    return full.reshape(shape)


def _full_evidence(evidence: TermEvidence | None, omega_flat, shape) -> TermEvidence | None:
    if evidence is None:
        return None
    return TermEvidence(
        *(
            _full(np.asarray(values), omega_flat, shape, fill)
            for values, fill in zip(evidence, (0.0, 1.0, 0.0, 0.0), strict=True)
        )
    )


def _robust_scale(spread: np.ndarray, level: np.ndarray) -> np.ndarray:
    """``spread`` where it is positive, else ``level``, else 1."""
    spread = np.where(spread > 1e-12 * np.maximum(level, 1e-300), spread, level)
    return np.where(spread > 0, spread, 1.0)


def output_scale(records) -> np.ndarray:
    r"""Standard deviation $\sigma_o$ of every output over all records."""
    z = np.concatenate([np.asarray(z_r, float) for _, z_r in records])
    return _robust_scale(np.std(z, axis=0), np.sqrt(np.mean(z**2, axis=0)))


def state_scale(window_starts: np.ndarray) -> np.ndarray:
    r"""Scale $\varsigma_i$ of every state: the spread of the windows' initial states."""
    starts = np.asarray(window_starts, float)
    finite = np.where(np.isfinite(starts), starts, 0.0)
    return _robust_scale(np.std(finite, axis=0), np.max(np.abs(finite), axis=0))


def block_columns(layout, free_index: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions in the free vector of block ``name``'s free entries, and their flat index
    inside the block."""
    start = 0
    for block, shape in layout.blocks:
        size = int(np.prod(shape))
        if block == name:
            inside = (free_index >= start) & (free_index < start + size)
            return np.flatnonzero(inside), free_index[inside] - start
        start += size
    return np.zeros(0, int), np.zeros(0, int)


def penalty_scale(residual: np.ndarray, columns: np.ndarray, n_fit: int) -> tuple:
    r"""Penalty scales $s_{ij}$ and $\gamma_{max}$ from the Jacobian columns.

    ``residual`` is the full residual vector at $\Omega = 0$, ``columns`` the Jacobian
    columns of the weights (one per column). Dead terms (`DEAD_TERM`) get scale 0.
    """
    scale = np.linalg.norm(columns[:n_fit], axis=0)
    alive = scale > DEAD_TERM * np.max(scale, initial=0.0)
    gradient = 2.0 * np.abs(residual @ columns)
    ratio = np.divide(gradient, scale, out=np.zeros_like(scale), where=alive)
    return np.where(alive, scale, 0.0), float(np.max(ratio, initial=0.0))


def _combine(results: list[SolverResult], free: np.ndarray) -> SolverResult:
    """One `SolverResult` for consecutive stages (history joined, the last's end;
    converged when the last two stages converged, else the message of the one that did
    not)."""
    last = results[-1]
    history = np.concatenate([np.atleast_1d(r.history) for r in results])
    n_iter = sum(r.n_iter for r in results)
    unfinished = [r for r in results[-2:] if not r.converged]
    message = last.message if not unfinished else unfinished[-1].message
    if unfinished and unfinished[-1] is not last:
        message = f"the penalised stage before the refit: {message}"
    return SolverResult(free, last.cost, history, n_iter, not unfinished, message)


def _active(n_free: int, frozen: np.ndarray) -> jnp.ndarray:
    active = np.ones(n_free)
    active[frozen] = 0.0
    return to_device(active)


class _Stage(NamedTuple):
    """What the stages share: the solver, the problem and where the weights sit."""

    run: Callable
    problem: Problem
    omega_at: np.ndarray
    n_fit: int
    evaluate: Callable


def _reference(stage: _Stage, free0) -> SolverResult:
    """Stage 1: the physics alone (weights frozen at zero)."""
    start = _zeroed(free0, stage.omega_at)
    frozen = stage.problem._replace(active=_active(start.shape[0], stage.omega_at))
    return stage.run(frozen, start)


def _zeroed(free, at: np.ndarray) -> jnp.ndarray:
    """``free`` with the entries ``at`` set to zero, on the device (no program run)."""
    values = np.array(free, dtype=float)
    values[at] = 0.0
    return to_device(values)


def _prune(stage: _Stage, free: np.ndarray, scale: np.ndarray, tol: float, gamma: float):
    r"""Weights (positions in ``omega_at``) kept after the two pruning rules.

    The second rule compares the penalised objective $F + \gamma\sum s|\Omega|$
    (exact absolute values): a term goes when what it gains in fit does not pay for its
    penalty, up to a slack of ``tol`` times $F$.
    """
    weights = free[stage.omega_at]
    contribution = scale * np.abs(weights)
    keep = contribution > tol * np.max(contribution, initial=0.0)
    if tol == 0:
        return keep

    def objective(values) -> float:
        return stage.evaluate(values) + gamma * np.sum(scale * np.abs(values[stage.omega_at]))

    fit = stage.evaluate(free)
    bound = objective(free) + tol * fit
    trial = free.copy()
    trial[stage.omega_at[~keep]] = 0.0
    if not np.isfinite(stage.evaluate(trial)):  # small terms that keep the model stable
        keep[:], trial = contribution > 0, free.copy()
    for j in np.argsort(contribution):
        if not keep[j]:
            continue
        trial[stage.omega_at[j]] = 0.0
        if objective(trial) <= bound:
            keep[j] = False
        else:
            trial[stage.omega_at[j]] = free[stage.omega_at[j]]
    return keep


def _prune_and_refit(stage, free, scale, options, results) -> np.ndarray:
    """Stage 3: prune, refit the support without the penalty, until the support is stable."""
    unpenalised = stage.problem.weights._replace(gamma=to_device(0.0))
    gamma = float(stage.problem.weights.gamma)
    alive = scale > 0
    for round_ in range(MAX_PRUNE_ROUNDS):
        penalty = gamma if round_ == 0 else 0.0  # after the unpenalised refit: the fit alone
        keep = _prune(stage, free, scale, options.prune_tol, penalty) & alive
        dropped = np.any(free[stage.omega_at][~keep] != 0.0)
        free = free.copy()
        free[stage.omega_at[~keep]] = 0.0
        if not options.refit or (round_ > 0 and not dropped):
            break
        problem = stage.problem._replace(
            weights=unpenalised, active=_active(free.shape[0], stage.omega_at[~keep])
        )
        refit = stage.run(problem, to_device(free))
        if not np.isfinite(refit.cost):
            break
        results.append(refit)
        free = np.asarray(refit.free, float)
    return free


def _physics_reference(stage: _Stage, free0) -> Reference:
    """Stage 1 and the penalty scales at its solution (``gamma_max`` nan if it does not
    simulate)."""
    result = _reference(stage, free0)
    if not np.isfinite(result.cost):
        return Reference(result, np.zeros(stage.omega_at.shape[0]), np.nan)
    others = np.setdiff1d(np.flatnonzero(np.asarray(stage.problem.active) > 0), stage.omega_at)
    residual, columns = jacobian_columns(
        to_device(result.free),
        stage.problem,
        to_device(np.concatenate([stage.omega_at, others])),
        model=stage.evaluate.model,
        layout=stage.evaluate.layout,
    )
    residual, columns = np.asarray(residual), np.asarray(columns)
    n_omega = stage.omega_at.shape[0]
    scale, gamma_max = penalty_scale(residual, columns[:, :n_omega], stage.n_fit)
    evidence = term_evidence(residual, columns[:, n_omega:], columns[:, :n_omega])
    return Reference(result, scale, gamma_max, evidence)


def _penalised_problem(problem: Problem, omega_flat, scale, n_free, dead) -> Problem:
    """``problem`` with the penalty scales $s_{ij}$ and dead terms frozen."""
    shape = np.shape(problem.omega_free)
    full = np.ones(int(np.prod(shape)))
    full[omega_flat] = np.where(scale > 0, scale, 1.0)
    weights = problem.weights._replace(penalty_scale=to_device(full.reshape(shape)))
    return problem._replace(weights=weights, active=_active(n_free, dead))


class _FitCost:
    """`fit_cost` as a function of the free vector alone."""

    def __init__(self, problem, model, layout, n_fit):
        self.problem, self.model, self.layout, self.n_fit = problem, model, layout, n_fit

    def __call__(self, free) -> float:
        value = fit_cost(free, self.problem, model=self.model, layout=self.layout, n_fit=self.n_fit)
        return float(value)  # a NumPy ``free`` goes into the jitted cost as it is


def fit_sparse(
    run: Callable,
    problem: Problem,
    free0,
    layout,
    model,
    options: SparseOptions,
    reference: Reference | None = None,
) -> SparseFit:
    """The three stages of the module docstring.

    Parameters
    ----------
    run : callable
        ``run(problem, free0) -> SolverResult``, the chosen solver.
    problem : Problem
        The cost with unit penalty scales; ``free0`` its starting free vector (weights not
        all zero: a warm start, used for stage 2).
    layout, model :
        Static structure of the cost.
    options : SparseOptions
    reference : Reference, optional
        Stage 1 of an earlier fit of the same data and structure (skips it).

    Returns
    -------
    SparseFit
        When stage 1 does not simulate, its result with ``gamma_max = nan``.
    """
    omega_at, omega_flat = block_columns(layout, np.asarray(problem.free_index), "omega")
    n_fit = n_fit_residuals(problem.segments)
    stage = _Stage(run, problem, omega_at, n_fit, _FitCost(problem, model, layout, n_fit))
    shape = np.shape(problem.omega_free)
    if omega_at.size == 0:  # every weight masked: the physics alone
        result = run(problem, free0)
        return SparseFit(np.asarray(result.free), result, np.zeros(shape), np.nan, None)
    computed = reference is None
    reference = _physics_reference(stage, free0) if computed else reference
    if not np.isfinite(reference.gamma_max):
        return SparseFit(reference.result.free, reference.result, np.ones(shape), np.nan, None)
    scale = reference.scale
    final_scale = _full(scale, omega_flat, shape, 0.0)
    evidence = _full_evidence(reference.evidence, omega_flat, shape)
    if options.reference_only:
        free = np.asarray(reference.result.free, float)
        return SparseFit(
            free, reference.result, final_scale, reference.gamma_max, reference, evidence
        )
    warm = np.any(np.asarray(free0)[omega_at] != 0.0)
    dead = omega_at[scale == 0]
    start = _zeroed(free0 if warm else reference.result.free, dead)
    penalised = _penalised_problem(problem, omega_flat, scale, start.shape[0], dead)
    results = [reference.result] if computed else []
    results.append(run(penalised, start))
    stage = stage._replace(problem=penalised)
    free = _prune_and_refit(stage, np.asarray(results[-1].free, float), scale, options, results)
    result = _combine(results, free)
    if warm:
        result = _no_worse_than(stage, np.asarray(start, float), result)
    return SparseFit(result.free, result, final_scale, reference.gamma_max, reference, evidence)


def _no_worse_than(stage: _Stage, start: np.ndarray, result: SolverResult) -> SolverResult:
    r"""``result``, or the warm ``start`` when the start dominates it: no more terms and a
    lower simulation error $F$.

    A penalised stage stopped at ``max_iter`` can leave the true terms small enough for
    pruning to drop them, and the refit then settles in a worse minimum with other terms;
    a fit started from a solution (the previous $\gamma$ of a support path) must not
    return one that is both larger and worse.
    """
    free = np.asarray(result.free, float)
    start_fit, result_fit = stage.evaluate(start), stage.evaluate(free)
    fewer_or_as_many = np.count_nonzero(start[stage.omega_at]) <= np.count_nonzero(
        free[stage.omega_at]
    )
    if not (fewer_or_as_many and start_fit < result_fit):
        return result
    message = "the fit ended worse than its warm start, with no fewer terms; the start is kept"
    return SolverResult(start, start_fit, result.history, result.n_iter, False, message)
