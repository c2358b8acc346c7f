r"""Physical plausibility of an effect set: does it keep the declared physics, or replace it?

An effect set that fits only by moving a declared parameter by orders of magnitude from
the declared physics' fit (a resistance from 2 to 751), or across zero, is a stand-in: it
lowers the error, but the physics it leaves is not the plant's; so is a set that holds a
promoted dictionary term, which names no law (`dictionary_reasons`), and a set whose
directional damping leaves a direction of motion driven rather than damped
(`direction_reasons`). The loop never
chooses a stand-in over a physical set within ``tolerance`` of its CV error, and says which
one is which (`stand_in_reasons`). A set whose effects do not each lower the
cross-validated error by ``min_gain`` over the set without them is not adopted
(`earns_every_effect`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ..effects import DictionaryTerm, DirectionalDamping
from ..model._physics import value_of
from ._energy import directional_dampings

__all__ = [
    "STAND_IN_FACTOR",
    "chosen_index",
    "dictionary_reasons",
    "direction_reasons",
    "earns_every_effect",
    "stand_in_reasons",
]

STAND_IN_FACTOR = 10.0
r"""A declared parameter that moves by more than this factor from its declared fit
($|\theta/\theta_0| > 10$ or $< 1/10$) makes the set a stand-in."""


def stand_in_reasons(declared: Mapping, fitted: Mapping) -> list[str]:
    """Why ``fitted`` is not physical: each declared parameter it flips in sign or moves
    beyond `STAND_IN_FACTOR` from its ``declared`` fit (empty: physical)."""
    reasons = []
    for name, parameter in declared.items():
        before = value_of(parameter)
        if name not in fitted or before == 0 or not np.isfinite(before):
            continue
        after = value_of(fitted[name])
        ratio = after / before
        if ratio < 0:
            reasons.append(f"{name} changes sign ({before:.4g} → {after:.4g})")
        elif not 1.0 / STAND_IN_FACTOR <= ratio <= STAND_IN_FACTOR:
            reasons.append(f"{name} moves from {before:.4g} to {after:.4g}")
    return reasons


def chosen_index(
    scores: Sequence[float],
    physical: Sequence[bool],
    tolerance: float,
    admissible: Sequence[bool] | None = None,
) -> int:
    """Index of the first ``admissible`` score within ``tolerance`` (relative) of the
    smallest admissible one, a ``physical`` one when any is within it (every score is
    admissible when ``admissible`` is ``None``; the first is always admissible)."""
    allowed = [True] * len(scores) if admissible is None else list(admissible)
    allowed[0] = True
    best = min(score for score, ok in zip(scores, allowed, strict=True) if ok)
    within = [
        k for k, score in enumerate(scores) if allowed[k] and score <= best * (1.0 + tolerance)
    ]
    return next((k for k in within if physical[k]), within[0])


def earns_every_effect(
    sets: Sequence[frozenset], scores: Sequence[float], min_gain: float
) -> list[bool]:
    r"""Whether each effect set earns each of its effects: no strict subset of it among
    ``sets`` scores within ``min_gain`` of it ($s_{sub} > s / (1 - g)$ for every subset).
    An effect that lowers the cross-validated error by less than ``min_gain`` over the set
    without it is not adopted, whatever else the set holds."""
    bar = 1.0 - min_gain
    return [
        all(
            not (other < members) or not other_score * bar <= score
            for other, other_score in zip(sets, scores, strict=True)
        )
        for members, score in zip(sets, scores, strict=True)
    ]


def dictionary_reasons(effects) -> list[str]:
    """Why a set holding promoted dictionary terms is no physical statement (empty: it
    holds none): a term lowers the error but names no law."""
    terms = [effect.name for effect in effects if isinstance(effect, DictionaryTerm)]
    if not terms:
        return []
    verb = "is a dictionary term" if len(terms) == 1 else "are dictionary terms"
    return [f"{', '.join(terms)} {verb} (no physical law)"]


def direction_reasons(physics, effects, fitted: Mapping) -> list[str]:
    """Why a set's directional damping is not physical: it leaves a direction's damping
    negative (an energy source), the declared damping taken at the declared initial state
    (`directional_dampings`, with the ``fitted`` values; empty: physical)."""
    values = {name: value_of(parameter) for name, parameter in fitted.items()}
    reasons = []
    for effect in (e for e in effects if isinstance(e, DirectionalDamping)):
        pair = directional_dampings(effect, physics, values)
        if pair is not None and min(pair) < 0:
            reasons.append(f"{effect.name} leaves a direction of motion undamped")
    return reasons
