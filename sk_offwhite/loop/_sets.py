"""Effect sets fitted and cross-validated: what every choice of the loop is made from.

A set is fitted on the whole record from its start (`best_of` keeps the best of several
starts) and cross-validated from that fit: each fold starts where the set's own fit ended,
the model that would be kept, with a parameter held at its fitted value on each direction
of that fit the data do not determine (otherwise the folds wander along the direction, and
a set is judged by where its folds' fits stopped there).
"""

from __future__ import annotations

from ..runtime._parallel import gather, launch
from ._cv import structure_cv
from ._fits import fit_set, label, quick_fit, warm_physics
from ._gauge import held_on_fit, holding
from ._progress import logger
from ._search import Search

__all__ = ["best_of", "set_cv", "sets_cv"]


def set_cv(search: Search, board, effects, warm):
    """CV RMSE of an effect set and its fit on the whole record (``None`` if that failed)."""
    model = board.model(effects, warm)
    est = search.estimator(model)
    fitted = search.attempt("effects " + label(effects), fit_set, search, est, effects)
    if fitted is None:
        return structure_cv(search, model), fitted
    held, _ = held_on_fit(model, fitted, search.u, search.z, effects)
    return structure_cv(search, holding(warm_physics(model, fitted), held)), fitted


def set_cv_alone(search: Search, board, effects, warm):
    """`set_cv` in a worker: ``(score, fitted, failures)``."""
    score, fitted = set_cv(search, board, effects, warm)
    return score, fitted, search.failures


def sets_cv(search: Search, board, steps) -> list:
    """``(label, score, fitted)`` of `set_cv` for each step's effect set, the sets
    cross-validated by ``n_jobs`` processes (each set's folds in its own one)."""
    labels = [label(board.ordered(effects)) for effects, _, _ in steps]
    arguments = [(search.detached(), board, effects, warm) for effects, warm, _ in steps]

    def progress(k, _):
        logger.info("  CV of %s (%d of %d)", labels[k - 1], k, len(labels))

    outcomes = gather(launch(set_cv_alone, arguments, *search.processes()), progress=progress)
    search.failures.extend(line for _, _, lines in outcomes for line in lines)
    scores = [(name, *outcome[:2]) for name, outcome in zip(labels, outcomes, strict=True)]
    return search.released(scores)


def best_of(search: Search, board, sets) -> list:
    """For each ``(effects, starts)`` of ``sets``, the `quick_fit` of lowest estimation RMSE
    over its starts (``None`` if every one fails); all the fits run by ``n_jobs``
    processes."""
    calls = [
        ("effects " + label(effects), quick_fit, search.detached(), board, effects, start)
        for effects, starts in sets
        for start in starts
    ]
    outcomes = iter(search.attempt_all(calls))
    best = []
    for _, starts in sets:
        fits = [fit for fit in (next(outcomes) for _ in starts) if fit is not None]
        best.append(min(fits, key=lambda fit: fit[0]) if fits else None)
    return best
