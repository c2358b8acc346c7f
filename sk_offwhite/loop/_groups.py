r"""Effects that only help together, found by scanning the hypotheses' corrections.

A Coulomb friction and a force offset on a drive, or two terms that are one varying
coefficient, can each explain little alone, because the declared parameters absorb part of
each, and nearly everything together: forward selection, which adds one effect at a time
where it helps alone, never reaches them. Here every pair of candidate terms of one state
equation is scored linearly against that equation's hypothesis (the correction the
dictionary's evidence reads there): the fraction of the correction's energy the two terms'
least-squares fit explains. A pair is proposed when it explains at least `MIN_JOINT` of the
correction and `JOINT_GAIN` times what its better member explains alone; it is fitted once,
started at the least-squares coefficients, and cross-validated with the other sets. Scan
many, fit few: the scan costs a least-squares fit per pair, only the best pair of each
hypothesis is fitted.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np

from ..effects import AdditiveEffect
from ..model import Parameter

__all__ = ["JOINT_GAIN", "MIN_JOINT", "joint_groups"]

MIN_JOINT = 0.5
"""The fraction of a hypothesis' correction a pair must explain to be proposed."""

JOINT_GAIN = 1.2
"""How many times what its better member explains alone a pair must explain."""


def joint_groups(hypotheses, candidates, states, u, dt: float) -> list[tuple[tuple, dict]]:
    """``(effects, starts)`` of the best pair of each hypothesis (see the module docstring),
    the effects among ``candidates``' and ``starts`` their linear parameters at the pair's
    least-squares fit, as [`Parameter`][sk_offwhite.Parameter] by name."""
    terms = [c.effect for c in candidates if isinstance(c.effect, AdditiveEffect)]
    groups = []
    for hypothesis in hypotheses:
        if hypothesis.correction is None:
            continue
        members = [e for e in terms if e.state == hypothesis.equation_index]
        target = np.asarray(hypothesis.correction, float) / dt
        best = _best_pair(members, target, states, u)
        if best is not None and best[0] not in [g[0] for g in groups]:
            groups.append(best)
    return groups


def _best_pair(members, target, states, u):
    """The pair of ``members`` whose bases explain ``target`` best, if it qualifies."""
    bases = {e: _basis(e, states, u) for e in members}
    bases = {e: b for e, b in bases.items() if b is not None}
    alone = {e: _explained(np.column_stack([b]), target)[0] for e, b in bases.items()}
    best, best_share = None, MIN_JOINT
    for a, b in combinations(bases, 2):
        share, coefficients = _explained(np.column_stack([bases[a], bases[b]]), target)
        if share >= best_share and share >= JOINT_GAIN * max(alone[a], alone[b]):
            best, best_share = ((a, b), coefficients), share
    if best is None:
        return None
    (a, b), coefficients = best
    return (a, b), {**_start(a, coefficients[0]), **_start(b, coefficients[1])}


def _basis(effect, states, u) -> np.ndarray | None:
    basis = effect.basis(states, u)
    if basis is None:
        return None
    basis = np.asarray(basis, float).reshape(-1)
    return basis if np.all(np.isfinite(basis)) and np.any(basis) else None


def _explained(columns: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray]:
    """The fraction of ``target``'s energy the least-squares fit on ``columns`` explains,
    and its coefficients (unit-free: the fraction does not depend on the columns' scales)."""
    energy = float(target @ target)
    if not (energy > 0 and np.all(np.isfinite(target))):
        return 0.0, np.zeros(columns.shape[1])
    coefficients, *_ = np.linalg.lstsq(columns, target, rcond=None)
    residual = target - columns @ coefficients
    return 1.0 - float(residual @ residual) / energy, coefficients


def _start(effect, value: float) -> dict:
    """``effect``'s linear (first) parameter at ``value``, where its bounds allow it."""
    name, spec = next(iter(effect.parameters().items()))
    lower, upper = spec.bounds
    if (lower is not None and value <= lower) or (upper is not None and value >= upper):
        return {}
    return {name: Parameter(float(value), spec.bounds)}
