r"""Physical plausibility of an effect set: does it keep the declared physics, or replace it?

An effect set that fits only by moving a declared parameter by orders of magnitude from
the declared physics' fit (a resistance from 2 to 751), or across zero, is a stand-in: it
lowers the error, but the physics it leaves is not the plant's. The loop never chooses a
stand-in over a physical set within ``tolerance`` of its CV error, and says which one is
which (`stand_in_reasons`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["STAND_IN_FACTOR", "chosen_index", "stand_in_reasons"]

STAND_IN_FACTOR = 10.0
r"""A declared parameter that moves by more than this factor from its declared fit
($|\theta/\theta_0| > 10$ or $< 1/10$) makes the set a stand-in."""


def _value(parameter) -> float:
    return float(getattr(parameter, "value", parameter))


def stand_in_reasons(declared: Mapping, fitted: Mapping) -> list[str]:
    """Why ``fitted`` is not physical: each declared parameter it flips in sign or moves
    beyond `STAND_IN_FACTOR` from its ``declared`` fit (empty: physical)."""
    reasons = []
    for name, parameter in declared.items():
        before = _value(parameter)
        if name not in fitted or before == 0 or not np.isfinite(before):
            continue
        after = _value(fitted[name])
        ratio = after / before
        if ratio < 0:
            reasons.append(f"{name} changes sign ({before:.4g} → {after:.4g})")
        elif not 1.0 / STAND_IN_FACTOR <= ratio <= STAND_IN_FACTOR:
            reasons.append(f"{name} moves from {before:.4g} to {after:.4g}")
    return reasons


def chosen_index(scores: Sequence[float], physical: Sequence[bool], tolerance: float) -> int:
    """Index of the first score within ``tolerance`` (relative) of the smallest, a
    ``physical`` one when any is within it."""
    best = min(scores)
    within = [k for k, score in enumerate(scores) if score <= best * (1.0 + tolerance)]
    return next((k for k in within if physical[k]), within[0])
