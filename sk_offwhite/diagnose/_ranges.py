r"""Range facts: measured ceilings and floors, and model excursions beyond the measured range.

A sensor or actuator that saturates leaves a flat top in the data: the measured maximum
$M = \max_k z_k$ is reached again and again. With the tolerance
$\delta = \text{tolerance} \cdot (\max_k z_k - \min_k z_k)$, the samples *at the
ceiling* are those with $z_k \ge M - \delta$; ``min_repeats`` or more of them flag a
possible saturation. The model *exceeds* the measured range in the samples with
$\hat z_k > M + \delta$. Floors are the mirror image.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from numbers import Real

import numpy as np

from ._arrays import check_integer, column_names
from ._metrics import scored_pair

__all__ = ["RangeViolation", "range_violations"]


@dataclass(frozen=True)
class RangeViolation:
    """A fact about one output's measured range on one side.

    Attributes
    ----------
    output : str
    side : {"upper", "lower"}
    measured_limit : float
        Measured maximum (upper) or minimum (lower).
    n_at_limit : int
        Measured samples within the tolerance of the limit.
    longest_flat_run : int
        Longest run of consecutive measured samples at the limit.
    saturated : bool
        ``n_at_limit >= min_repeats``: a ceiling (floor), perhaps a saturation.
    n_model_beyond : int
        Simulated samples beyond the limit by more than the tolerance.
    model_extreme : float
        Largest (upper) or smallest (lower) simulated value.
    sentence : str
        The fact in words.
    """

    output: str
    side: str
    measured_limit: float
    n_at_limit: int
    longest_flat_run: int
    saturated: bool
    n_model_beyond: int
    model_extreme: float
    sentence: str = ""


def range_violations(
    z,
    z_sim,
    names: Sequence[str] | None = None,
    *,
    tolerance: float = 1e-6,
    min_repeats: int = 3,
) -> list[RangeViolation]:
    """Measured ceilings/floors and simulated excursions beyond the measured range.

    Parameters
    ----------
    z : array of shape (n_samples, n_outputs) or (n_samples,)
        Measured outputs.
    z_sim : array of the same shape
        Simulated outputs.
    names : sequence of str, optional
        One name per output; defaults to ``z1, z2, ...``.
    tolerance : float, default 1e-6
        Tolerance $\\delta$ as a fraction of each output's measured range.
    min_repeats : int, default 3
        Samples at the limit that make it a ceiling or floor; without one, fewer model
        excursions than this are not reported.

    Returns
    -------
    list of RangeViolation
        One per output and side with a ceiling/floor or model excursions (or both);
        saturations the model crosses first, then by the number of excursions.
    """
    measured, simulated = scored_pair(z, z_sim, 0)
    names = column_names(names, measured.shape[1], "names", "z")
    tolerance = _checked_tolerance(tolerance)
    min_repeats = check_integer(min_repeats, "min_repeats", 1, measured.shape[0])
    facts = [
        _side_fact(name, measured[:, j], simulated[:, j], side, tolerance, min_repeats)
        for j, name in enumerate(names)
        for side in ("upper", "lower")
    ]
    found = [fact for fact in facts if fact is not None]
    return sorted(found, key=lambda f: (not (f.saturated and f.n_model_beyond), -f.n_model_beyond))


def _checked_tolerance(tolerance) -> float:
    if isinstance(tolerance, bool) or not isinstance(tolerance, Real):
        raise TypeError(f"tolerance must be a number, got {type(tolerance).__name__}.")
    if not 0.0 <= tolerance < 1.0:
        raise ValueError(f"tolerance must be in [0, 1), got {tolerance}.")
    return float(tolerance)


def _side_fact(name, measured, simulated, side, tolerance, min_repeats) -> RangeViolation | None:
    """The fact for one output and side, or None when there is nothing to say."""
    sign = 1.0 if side == "upper" else -1.0
    limit = float(np.max(sign * measured))
    margin = tolerance * float(np.ptp(measured))
    at_limit = sign * measured >= limit - margin
    beyond = sign * simulated > limit + margin
    fact = RangeViolation(
        output=name,
        side=side,
        measured_limit=sign * limit,
        n_at_limit=int(at_limit.sum()),
        longest_flat_run=_longest_run(at_limit),
        saturated=bool(at_limit.sum() >= min_repeats),
        n_model_beyond=int(beyond.sum()),
        model_extreme=float(sign * np.max(sign * simulated)),
    )
    if not (fact.saturated or fact.n_model_beyond >= min_repeats):
        return None
    return dataclasses.replace(fact, sentence=describe_range_fact(fact))


def _longest_run(mask: np.ndarray) -> int:
    """Length of the longest run of consecutive ``True`` in ``mask``."""
    padded = np.concatenate([[False], mask, [False]])
    changes = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return int(np.max(changes[1::2] - changes[::2], initial=0))


def describe_range_fact(fact: RangeViolation) -> str:
    """The fact in words, e.g. "the measured z1 never exceeds 10 (reached in 47 samples...)"."""
    upper = fact.side == "upper"
    verb = "exceeds" if upper else "goes below"
    excursion = (
        f"{fact.n_model_beyond} samples, {'up' if upper else 'down'} to {fact.model_extreme:.4g}"
    )
    if not fact.saturated:
        extreme = "maximum" if upper else "minimum"
        return (
            f"the model {verb} the measured {extreme} of {fact.output} "
            f"({fact.measured_limit:.4g}) in {excursion}"
        )
    ceiling = (
        f"the measured {fact.output} never {verb} {fact.measured_limit:.4g} (reached in "
        f"{fact.n_at_limit} samples, longest flat run {fact.longest_flat_run}: a saturation?)"
    )
    if fact.n_model_beyond:
        return f"{ceiling} while the model {verb} it in {excursion}"
    return f"{ceiling}; the model stays within it"
