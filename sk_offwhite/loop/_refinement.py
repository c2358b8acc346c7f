r"""The stepwise refinement of the chosen effect set, in rounds.

Each round tries every other candidate of the ``beam`` added to the set (while it has fewer
than ``max_effects``) or exchanged for one of its effects, each of its effects exchanged for
its richer variant, and each of its effects dropped, started from the set's parameters. An
addition or exchange whose fit lowers the estimation error (by ``min_gain`` for an
addition), and a removal, or an exchange for an effect of fewer parameters, whose fit misses
the data by no more than a lighter set may, are cross-validated; the best is kept when its
CV error is lower by ``min_gain``, else the best lighter set within ``min_gain``: an effect
stays only when it lowers the CV error by ``min_gain``. Greedy forward selection misses a
set whose members help only in each other's company; the refinement reaches it through
another order. Promoted dictionary terms are left to forward selection, where they must
beat a named effect by ``tolerance``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..effects import DictionaryTerm
from ._fits import label, quick_fit, record_rmse, size, without
from ._search import Search
from ._sets import best_of, sets_cv
from ._variants import mechanism, representatives, richer, richer_start

__all__ = ["swap"]


class Chosen(NamedTuple):
    """A set a round starts from: its effects, their parameters, its CV RMSE and its
    `quick_fit` (``None``: not made yet)."""

    effects: tuple
    params: dict
    cv: float
    fit: tuple | None = None


def swap(search: Search, board, ranked, chosen, fits):
    """Stepwise refinement of the chosen set, in rounds (`swap_round`) until a round keeps
    its set or reaches one an earlier round left: the set a move reached is refined in turn.
    Every kept move lowers the CV RMSE by ``min_gain`` or makes the set smaller, so the
    rounds end.

    ``chosen``: ``(effects, parameters, CV RMSE)`` of the set. Returns the effects, their
    parameters and the CV trail rows of the moves tried (their fits on the whole record are
    added to ``fits``).
    """
    chosen, rows, left = Chosen(*chosen), [], set()
    while True:
        left.add(frozenset(chosen.effects))
        reached, tried = swap_round(search, board, ranked, chosen, fits)
        rows += tried
        if reached.effects is chosen.effects or frozenset(reached.effects) in left:
            return chosen.effects, chosen.params, rows
        chosen = reached


def swap_round(search: Search, board, ranked, chosen: Chosen, fits):
    """One round of the refinement (see the module docstring). Returns the set reached
    (``chosen`` itself when no move is kept) and the CV trail rows of the moves tried."""
    settings = search.settings
    effects, warm, cv, base = chosen
    if base is None:
        name = "effects " + label(effects)
        base = search.attempt(name, quick_fit, search, board, effects, warm)
    if base is None:
        return chosen, []
    rows, best = [], Chosen(effects, warm, (1.0 - settings.min_gain) * cv, base)
    lighter = Chosen(effects, warm, cv / (1.0 - settings.min_gain), base)
    passed = passed_moves(search, board, ranked, chosen._replace(fit=base), lighter.cv, fits)
    for (trial, params, quick), (name, score, fit) in zip(
        passed, sets_cv(search, board, passed), strict=True
    ):
        fits[name] = fit
        rows.append((name, score))
        if score < best.cv:
            best = Chosen(trial, params, score, quick)
        elif size(trial) < size(effects) and score <= lighter.cv:
            lighter = Chosen(trial, params, score, quick)
    if best.effects is not effects:
        return best, rows
    return (lighter if lighter.effects is not effects else chosen), rows


def passed_moves(search: Search, board, ranked, chosen: Chosen, lighter: float, fits) -> list:
    """``(effects, parameters, fit)`` of each move worth fitting whose best fit beats its
    bar and the earlier fit of its set, if any."""
    effects, warm, _, base = chosen
    moves = []
    for trial, starts, bar in all_moves(effects, warm, ranked, base[0], lighter, search, board):
        earlier = earlier_rmse(search, fits, board, trial)
        if worth_fitting(trial, effects, base[0], earlier):
            moves.append((trial, starts, min(bar, earlier)))
    fitted = best_of(search, board, [(trial, starts) for trial, starts, _ in moves])
    return [
        (trial, fit[1], fit)
        for (trial, _, bar), fit in zip(moves, fitted, strict=True)
        if fit is not None and fit[0] < bar
    ]


def earlier_rmse(search: Search, fits, board, effects) -> float:
    """Estimation RMSE of the earlier fit of ``effects`` that was cross-validated (``inf``
    when none was, or when it failed)."""
    earlier = fits.get(label(board.ordered(effects)))
    return np.inf if earlier is None else record_rmse(earlier.predict(search.u), search.z)


def worth_fitting(trial, effects, rmse: float, earlier: float) -> bool:
    """Whether a move from ``effects`` (estimation RMSE ``rmse``) to ``trial`` is fitted,
    given the estimation RMSE ``earlier`` of the set's earlier fit: a set not
    cross-validated yet, or an addition whose earlier fit missed the record by more than
    ``effects`` does (a set holding ``effects`` can fit the record at least as well; when
    its fit did not, that fit ended in a poor minimum, and the set is fitted again)."""
    return earlier == np.inf or (len(trial) > len(effects) and earlier > rmse)


def all_moves(effects, warm, ranked, rmse, lighter, search: Search, board):
    """``(effects, starts, RMSE to beat)`` of each addition and exchange of the beam's other
    named effects and of each refinement, to beat the set's estimation RMSE ``rmse``, then
    of each removal, to beat ``lighter`` (the bar of a smaller set)."""
    yield from additions_and_exchanges(effects, warm, ranked, rmse, lighter, search.settings)
    yield from refinements(effects, warm, rmse, board)
    if len(effects) > 1:
        for out in effects:
            kept = without(warm, out)
            yield tuple(e for e in effects if e != out), [kept], lighter


def additions_and_exchanges(effects, warm, ranked, rmse, lighter, settings):
    """The additions and exchanges of `all_moves` (a set never holds two variants of one
    mechanism). An exchange for an effect of fewer parameters makes a lighter set, and has
    the bar of one (``lighter``, when it is above ``rmse``)."""
    pool = [
        (c.effect, p)
        for _, c, p in representatives(ranked, settings.tolerance)[: settings.beam]
        if c.effect not in effects and not isinstance(c.effect, DictionaryTerm)
    ]
    taken = {mechanism(e) for e in effects}
    for effect, params in pool:
        if len(effects) < settings.max_effects and mechanism(effect) not in taken:
            gain = (1.0 - settings.min_gain) * rmse
            yield (*effects, effect), starts_with(warm, effect, params), gain
        for out in effects:
            rest = tuple(e for e in effects if e != out)
            if mechanism(effect) in {mechanism(e) for e in rest}:
                continue
            kept = without(warm, out)
            bar = max(rmse, lighter) if size((effect,)) < size((out,)) else rmse
            yield (*rest, effect), starts_with(kept, effect, params), bar


def starts_with(warm: dict, effect, params: dict) -> list[dict]:
    """Starts of a set that gains ``effect``: the set's parameters ``warm``, with the
    effect's from its fit alone (``params``) and from its proposal (values from the data).
    Fitted alone, an effect may take values that only make sense without the others."""
    alone = {name: value for name, value in params.items() if name in effect.parameters()}
    proposed = effect.parameters()
    return [{**warm, **alone}] + ([{**warm, **proposed}] if alone != proposed else [])


def refinements(effects, warm, rmse, board):
    """``(effects, starts, RMSE to beat)`` with one effect exchanged for its richer variant,
    started where it reproduces the effect: the variant nests the effect, so its fit can
    only match or lower ``rmse``, and the cross-validation decides whether the extra
    freedom is worth ``min_gain``. Only the variants on the ``board``."""
    for effect in effects:
        variant = richer(effect)
        if variant is None or not board.ordered((variant,)):
            continue
        rest = tuple(e for e in effects if e != effect)
        kept = without(warm, effect)
        start = richer_start(effect, {**effect.parameters(), **warm})
        yield (*rest, variant), [{**kept, **start}], rmse
