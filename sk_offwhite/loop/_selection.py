r"""Stage 4 of the loop: which effects the physics gains.

The candidates are scanned by the error one Gauss-Newton step would reach
(`sk_offwhite.loop._scan`) and the best of them fitted alone on the estimation record
(`rank_alone`), with the pairs the scan finds helping only together; forward selection
then adds, among the ``beam`` best, the candidate that lowers the estimation error most
while it lowers it by ``min_gain`` (`forward`; when no candidate helps alone, the best pair
of the strongest is tried: effects such as Coulomb friction and a force offset only help
together). The sets of that order, and the nested sets of the candidates that helped alone
in the order of their gain, are cross-validated, each from its own fit on the whole record;
the smallest within ``tolerance`` of the best, among the sets each of whose effects lowers
the CV error by ``min_gain``, is kept if it beats the declared physics by ``min_gain``, then
refined stepwise (`sk_offwhite.loop._refinement`). A set that moves a declared parameter
tenfold, flips its sign, holds a promoted dictionary term or leaves a direction of motion
undamped is a stand-in, kept only when no physical set comes within ``tolerance`` of it
(`sk_offwhite.loop._plausibility`).
"""

from __future__ import annotations

import numpy as np

from ..effects import DictionaryTerm, VaryingParameter
from ._cv import structure_cv
from ._fits import label, member_start, own, quick_fit
from ._plausibility import (
    chosen_index,
    dictionary_reasons,
    direction_reasons,
    earns_every_effect,
    stand_in_reasons,
)
from ._proposals import capped
from ._refinement import swap
from ._scan import scan_note, scan_scores, scanned_pairs, to_fit
from ._search import Search
from ._sets import best_of, sets_cv
from ._switchboard import effect_sets, single_effect_models
from ._variants import mechanism, representatives, richer

__all__ = ["select_effects"]


def select_effects(search: Search, physics, candidates, base_rmse, declared_cv=None, groups=()):
    """Effect sets by forward selection and nested by single gain, chosen by CV RMSE.

    A set's effects are composed in the order of the single fits; with ``share_programs``
    all sets are fitted on one `Switchboard`, in this process (`board_search`). Returns the
    chosen effects (in that order), the CV trail (starting with ``declared_cv``, computed
    when ``None``), the single-fit RMSEs, the effects' fitted parameters (the start of the
    final fit) and each set's fit on the whole record by the trail's labels. ``groups``
    are ``(effects, starts)`` of effects that may only help together (`joint_groups`):
    each is fitted and cross-validated as a set of its own.
    """
    settings = search.settings
    if declared_cv is None:
        declared_cv = structure_cv(search, physics)
    candidates = capped(candidates, settings.max_candidates)
    ranked, groups = scan_and_fit(search, physics, candidates, groups)
    # sets compose their effects in the order of the single fits (best first)
    variants = with_richer([c.effect for _, c, _ in ranked])
    board = effect_sets(physics, variants, settings.share_programs)
    search = board_search(search, board)
    singles = [(c.effect.name, r) for r, c, _ in ranked]
    steps = search.released(forward(search, board, ranked, base_rmse))
    steps += joint_steps(search, board, groups, steps, base_rmse)
    steps = by_size(best_starts(search, board, steps + nested(ranked, base_rmse, settings)))
    trail, fits = [("declared physics", declared_cv)], {}
    for name, score, fitted in sets_cv(search, board, steps):
        fits[name] = fitted
        trail.append((name, score))
    k = physical_choice(search, physics, trail, steps)
    if k == 0 or trail[k][1] > (1.0 - settings.min_gain) * trail[0][1]:
        return (), trail, singles, {}, fits
    chosen, warm, _ = steps[k - 1]
    chosen, warm, rows = swap(search, board, ranked, (chosen, warm, trail[k][1]), fits)
    rescored = {name for name, _ in rows}
    trail = [row for row in trail if row[0] not in rescored] + rows
    chosen, warm = physical_instead(search, physics, board, trail, steps, (chosen, warm))
    return board.ordered(chosen), trail, singles, warm, fits


def board_search(search: Search, board) -> Search:
    """``search``, or its view whose fits run in this process (`Search.here`) for a board
    whose fits share their compiled programs (``fitted_here``)."""
    return search.here() if board.fitted_here else search


def physical_instead(search: Search, physics, board, trail, steps, chosen):
    """``chosen`` (``(effects, parameters)``, the refined set), or, when it holds a
    promoted dictionary term, the best physical set among ``steps`` (named effects, the
    declared parameters kept, `stand_in_reasons`) that is no larger and whose CV error comes
    within ``tolerance`` of it (a cubic stiffness rather than the term ``q^3`` it equals); a
    note says so. ``physics`` holds the declared fit's values."""
    effects, _ = chosen
    if not dictionary_reasons(effects):
        return chosen
    scores = dict(trail)
    bar = scores.get(label(board.ordered(effects)), np.inf) * (1.0 + search.settings.tolerance)
    named = [
        (scores.get(label(board.ordered(step[0])), np.inf), step)
        for step in steps
        if len(step[0]) <= len(effects) and not stand_in_steps(physics, [step])[0]
    ]
    within = [(score, step) for score, step in named if score <= bar]
    if not within:
        return chosen
    _, (found, params, _) = min(within, key=lambda item: item[0])
    search.notes.append(
        f"{label(found)} replaces {label(effects)}: named effects within tolerance of the "
        "dictionary term's CV error."
    )
    return found, params


def rank_alone(search: Search, candidates, models):
    """``(estimation RMSE, candidate, fitted effect parameters)`` of each candidate added
    alone to the declared physics, best first (``inf`` and a line in ``failures`` where the fit
    failed); a named effect ranks before a promoted term unless the term is better by
    ``tolerance``. ``models`` are what each candidate's fit builds its model from
    (`candidate_models`).

    The candidates are fitted on a switchboard where they can share one, in this process:
    each fit compiles nothing after the first, and a worker would compile the board's
    programs again for itself. The others are fitted by ``n_jobs`` processes, each on its
    own model."""
    settings = search.settings
    effects = [c.effect for c in candidates]
    worker = search.detached()
    calls = [
        (f"candidate {effect.name}", quick_fit, worker, model, (effect,), {})
        for effect, model in zip(effects, models, strict=True)
    ]
    fitted = search.attempt_split(calls, [model.fitted_here for model in models])
    ranked = [
        (np.inf, candidate, {}) if fit is None else (fit[0], candidate, fit[1])
        for candidate, fit in zip(candidates, fitted, strict=True)
    ]
    return sorted(ranked, key=lambda item: item[0] * handicap(item[1].effect, settings))


def scan_and_fit(search: Search, physics, candidates, groups):
    """``(ranked, groups)``: the single fits (`rank_alone`) of the candidates the scan
    keeps (`sk_offwhite.loop._scan`: the ``fit_top`` best, those it cannot judge, the
    members of ``groups`` and of the scanned pairs, the laws read from δ, the loop's
    own strongest evidence, and the effects at a level a hypothesis located), best first,
    and ``groups`` with the scanned pairs (`pair_groups`). A note says how many were
    scanned and fitted."""
    settings = search.settings
    models = candidate_models(physics, candidates, settings.share_programs)
    scores = scan_scores(search, models, candidates)
    pairs = scanned_pairs(search, models, candidates, scores, settings.n_pairs)
    needed = {k for i, j, _ in pairs for k in (i, j)} | always_fitted(candidates, groups)
    fitted = [keep or k in needed for k, keep in enumerate(to_fit(scores, settings.fit_top))]
    search.notes.append(scan_note(candidates, scores, fitted))
    kept = [k for k, keep in enumerate(fitted) if keep]
    ranked = rank_alone(search, [candidates[k] for k in kept], [models[k] for k in kept])
    return search.released(ranked), [*groups, *pair_groups(candidates, pairs, ranked)]


def always_fitted(candidates, groups) -> set[int]:
    """Indices of the ``candidates`` fitted whatever their scan score: the members of
    ``groups``, the laws read from δ and the effects at a level a hypothesis located
    (``located``)."""
    members = {id(effect) for effects, _ in groups for effect in effects}
    return {
        k
        for k, c in enumerate(candidates)
        if id(c.effect) in members or isinstance(c.effect, VaryingParameter) or c.located
    }


def pair_groups(candidates, pairs, ranked) -> list[tuple[tuple, dict]]:
    """``(effects, starts)`` of each scanned pair, started from its members' single fits
    (each member's own parameters, `member_start`; the declared ones from the better
    member's fit)."""
    fits = {id(candidate): (rmse, params) for rmse, candidate, params in ranked}
    groups = []
    for i, j, _ in pairs:
        a, b = candidates[i], candidates[j]
        fit_a, fit_b = fits.get(id(a), (np.inf, {})), fits.get(id(b), (np.inf, {}))
        declared = min(fit_a, fit_b, key=lambda fit: fit[0])[1]
        warm = {**declared, **member_start(fit_a[1], a.effect), **member_start(fit_b[1], b.effect)}
        groups.append(((a.effect, b.effect), warm))
    return groups


def candidate_models(physics, candidates, shared: bool) -> list:
    """What each candidate's fit alone builds its model from: one board for all when
    ``shared``, else `single_effect_models`."""
    effects = [c.effect for c in candidates]
    if shared:
        return [effect_sets(physics, effects, True)] * len(effects)
    return single_effect_models(physics, effects)


def handicap(effect, settings) -> float:
    """A promoted dictionary term must beat a named effect by ``tolerance`` to rank first."""
    return 1.0 + settings.tolerance if isinstance(effect, DictionaryTerm) else 1.0


def forward(search: Search, board, ranked, base_rmse):
    """Forward selection: ``[(effects, warm parameters, estimation RMSE)]`` for each step.

    The pool holds the ``beam`` best candidates alone of distinct mechanisms (one variant
    of each, `representatives`; a set never holds two variants of one) and every relaxed
    declared law: a law the user marked relaxable is always tried on top of the effects
    chosen so far, whose absence may be what made it look useless alone.
    """
    settings = search.settings
    pool = forward_pool(ranked, settings)
    steps, current, current_rmse = [], [], base_rmse
    if pool and pool[0][2] <= (1.0 - settings.min_gain) * base_rmse:
        steps.append(((pool[0][0],), pool[0][1], pool[0][2]))
        current, current_rmse = [pool[0][0]], pool[0][2]
    else:
        pool, steps = [], best_pair(search, board, pool[:3], base_rmse)
        if steps:
            current, current_rmse = list(steps[0][0]), steps[0][2]
    while len(current) < settings.max_effects:
        step = forward_step(search, board, pool, current, steps[-1][1] if steps else {})
        if step is None or step[2] > (1.0 - settings.min_gain) * current_rmse:
            break
        current, current_rmse = list(step[0]), step[2]
        steps.append(step)
    return steps


def joint_steps(search: Search, board, groups, steps, base_rmse) -> list:
    """``(effects, parameters, RMSE)`` of each group of effects that may only help
    together, fitted from its starts, where no step holds it yet and its fit helps."""
    reached = {frozenset(e.name for e in step[0]) for step in steps}
    todo = [(e, s) for e, s in groups if frozenset(x.name for x in e) not in reached]
    worker = search.detached()
    calls = [
        ("effects " + label(effects), quick_fit, worker, board, effects, starts)
        for effects, starts in todo
    ]
    fitted = search.attempt_all(calls)
    bar = (1.0 - search.settings.min_gain) * base_rmse
    return [
        (effects, fit[1], fit[0])
        for (effects, _), fit in zip(todo, fitted, strict=True)
        if fit is not None and fit[0] <= bar
    ]


def forward_pool(ranked, settings) -> list:
    """``(effect, parameters, RMSE)`` of the ``beam`` best representatives and every
    relaxed law beyond them."""
    finite = [item for item in ranked if np.isfinite(item[0])]
    fitted = [(c.effect, p, r) for r, c, p in representatives(finite, settings.tolerance)]
    laws = [item for item in fitted[settings.beam :] if item[0].target == "law"]
    return fitted[: settings.beam] + laws


def forward_step(search: Search, board, pool, current, warm):
    """The best set of ``current`` and one more effect of ``pool`` of another mechanism,
    ``(effects, parameters, RMSE)``, or ``None`` when no such fit succeeds."""
    taken = {mechanism(effect) for effect in current}
    added = [(effect, params) for effect, params, _ in pool if mechanism(effect) not in taken]
    worker = search.detached()
    calls = [
        ("effects " + label((*current, effect)), quick_fit, worker, board, (*current, effect),
         {**warm, **member_start(params, effect)})
        for effect, params in added
    ]  # fmt: skip
    fitted = search.attempt_all(calls)
    trials = [
        (f[0], effect, f[1]) for (effect, _), f in zip(added, fitted, strict=True) if f is not None
    ]
    if not trials:
        return None
    rmse, effect, params = min(trials, key=lambda t: t[0] * handicap(t[1], search.settings))
    return (*current, effect), params, rmse


def best_pair(search: Search, board, pool, base_rmse):
    """When no candidate helps alone: the best pair of the ``pool`` if it helps."""
    best = None
    for a in range(len(pool)):
        for b in range(a + 1, len(pool)):
            effects = (pool[a][0], pool[b][0])
            name = "effects " + " + ".join(e.name for e in effects)
            warm = {**pool[a][1], **member_start(pool[a][1], pool[a][0]),
                    **member_start(pool[b][1], pool[b][0])}  # fmt: skip
            fitted = search.attempt(name, quick_fit, search, board, effects, warm)
            if fitted is not None and (best is None or fitted[0] < best[2]):
                best = (effects, fitted[1], fitted[0])
    if best is None or best[2] > (1.0 - search.settings.min_gain) * base_rmse:
        return []
    return [best]


def nested(ranked, base_rmse, settings):
    """The nested sets of the candidates that helped alone, in the order of their gain
    (the declared parameters start from the first one's fit, each effect from its own)."""
    helped = [item for item in ranked if item[0] < base_rmse]
    kept = [(c.effect, p) for _, c, p in representatives(helped, settings.tolerance)]
    kept = kept[: settings.max_effects]
    return [
        (
            tuple(e for e, _ in kept[:k]),
            {**kept[0][1], **{n: p for e, ps in kept[1:k] for n, p in own(ps, e).items()}},
            None,
        )
        for k in range(1, len(kept) + 1)
    ]


def best_starts(search: Search, board, steps) -> list:
    """``steps`` with each effect set that more than one step reaches from different
    starts (forward selection and the nested sets) fitted from all of them, the step
    keeping the fit of lowest estimation RMSE (in the place of its first occurrence): the
    loop's cost is not convex in the effects' parameters, and which step came first must
    not decide which of a set's fits is cross-validated."""
    groups: dict[frozenset, list] = {}
    for step in steps:
        groups.setdefault(frozenset(e.name for e in step[0]), []).append(step)
    several = [g for g in groups.values() if len({start_key(s[1]) for s in g}) > 1]
    fitted = best_of(search, board, [(g[0][0], [s[1] for s in g]) for g in several])
    best = {id(g[0]): (g[0][0], fit[1], fit[0]) for g, fit in zip(several, fitted, strict=True)
            if fit is not None}  # fmt: skip
    return [best.get(id(step), step) for step in steps]


def start_key(start: dict) -> str:
    """A start's parameter values, comparable between steps."""
    return repr(sorted((name, repr(value)) for name, value in start.items()))


def by_size(steps):
    """``steps`` without repeated effect sets, smallest sets first (stable)."""
    unique = {}
    for step in steps:
        unique.setdefault(frozenset(e.name for e in step[0]), step)
    return sorted(unique.values(), key=lambda step: len(step[0]))


def physical_choice(search: Search, physics, trail, steps) -> int:
    """Index in ``trail`` of the smallest set within ``tolerance`` of the best CV error
    among the sets that earn each of their effects (`earns_every_effect`), a physical one
    when any is (`chosen_index`); each stand-in that beats the declared physics is noted
    (``physics`` holds the declared fit's values)."""
    reasons = [[]] + stand_in_steps(physics, steps)
    scores = [score for _, score in trail]
    sets = [frozenset()] + [frozenset(e.name for e in step[0]) for step in steps]
    earned = earns_every_effect(sets, scores, search.settings.min_gain)
    k = chosen_index(scores, [not r for r in reasons], search.settings.tolerance, earned)
    for (name, score), why in zip(trail, reasons, strict=True):
        if why and np.isfinite(score) and score < scores[0]:
            chosen = (
                " (kept: no physical set comes within tolerance)" if name == trail[k][0] else ""
            )
            search.notes.append(f"{name} fits, but not physical: {'; '.join(why)}{chosen}.")
    return k


def stand_in_steps(physics, steps) -> list[list[str]]:
    """Why each step's effect set is a stand-in (`stand_in_reasons` against the declared
    fit's values in ``physics``, `dictionary_reasons` and `direction_reasons`); empty where it
    is physical."""
    declared = {name: p.value for name, p in physics.parameters.items()}
    return [
        stand_in_reasons(declared, params)
        + dictionary_reasons(effects)
        + direction_reasons(physics, effects, params)
        for effects, params, _ in steps
    ]


def with_richer(effects) -> list:
    """``effects`` with each one's richer variant right after it: the sets the refinement
    may reach."""
    pairs = ((effect, richer(effect)) for effect in effects)
    return [variant for pair in pairs for variant in pair if variant is not None]
