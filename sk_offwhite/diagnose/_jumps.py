r"""Jump facts: the measured output steps in one sample, at one level, where the model does not.

A sensor whose reading is discontinuous (a seam in a capacitive level strip, a worn spot
on a potentiometer, an encoder that skips) makes the measured output jump each time the
quantity it reads passes one value, whatever the dynamics. In the increments of the
simulation residual, $d_k = (z_{k+1} - z_k) - (\hat z_{k+1} - \hat z_k)$, such a
jump is an *isolated* outlier: $|d_k| > t\,s$ with $s = 1.4826\,
\mathrm{median}|d - \mathrm{median}(d)|$ (a robust standard deviation of the increments)
and $t$ = ``threshold``, while $|d_{k-1}|$ and $|d_{k+1}|$ are not: a
fast phase of the dynamics that the model follows too slowly makes a run of outliers,
not one.

The jumps of one discontinuity share its level: the measured spans
$[\min(z_k, z_{k+1}), \max(z_k, z_{k+1})]$ of the jumps overlap. Overlapping spans
are grouped; a group of ``min_jumps`` or more whose jumps all step the same way as the
level (up when the level rises, or all the other way) is a fact. Its level is the median
midpoint of the spans, its height the median of $\mathrm{sign}(\hat z_{k+1} -
\hat z_k)\,d_k$, signed by the way the model's level moves there (positive: the reading
steps up as the level rises). Both are in the output's units and
the threshold is relative to the increments' spread, so rescaling the data rescales the
fact and changes nothing else.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._arrays import check_integer, column_names
from ._metrics import scored_pair

__all__ = ["OutputJump", "output_jumps"]

MAD_TO_SD = 1.4826
"""The standard deviation of a normal sample over its median absolute deviation."""

SPREAD_FLOOR = 1e-9
"""The least robust spread of the increments, as a fraction of the largest one."""


@dataclass(frozen=True)
class OutputJump:
    """Repeated one-sample jumps of one measured output at one level.

    Attributes
    ----------
    output : str
    level : float
        Median midpoint of the jumps' measured spans (output units).
    height : float
        Median jump beyond the model's own step, signed by the level's direction: positive
        when the reading steps up as the level rises (output units).
    low, high : float
        The union of the jumps' measured spans: where the reading crossed the step.
    samples : tuple of int
        Index ``k`` of each jump (from sample ``k`` to ``k + 1``).
    model_step : float
        Largest ``|z_sim[k+1] - z_sim[k]|`` of the model at those samples.
    sentence : str
        The fact in words.
    """

    output: str
    level: float
    height: float
    low: float
    high: float
    samples: tuple[int, ...]
    model_step: float
    sentence: str = ""


def output_jumps(
    z,
    z_sim,
    names: Sequence[str] | None = None,
    *,
    threshold: float = 6.0,
    min_jumps: int = 2,
) -> list[OutputJump]:
    """Repeated one-sample jumps of each measured output that the simulation does not make.

    Parameters
    ----------
    z : array of shape (n_samples, n_outputs) or (n_samples,)
        Measured outputs.
    z_sim : array of the same shape
        Simulated outputs.
    names : sequence of str, optional
        One name per output; defaults to ``z1, z2, ...``.
    threshold : float, default 6.0
        An increment of the residual is an outlier beyond ``threshold`` robust standard
        deviations of all increments (see the module docstring).
    min_jumps : int, default 2
        Isolated outliers with overlapping spans that make a fact.

    Returns
    -------
    list of OutputJump
        At most one per output (its largest group), largest height first.
    """
    measured, simulated = scored_pair(z, z_sim, 0)
    names = column_names(names, measured.shape[1], "names", "z")
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError(f"threshold must be a positive number, got {threshold!r}.")
    min_jumps = check_integer(min_jumps, "min_jumps", 1, measured.shape[0])
    facts = [
        _output_fact(name, measured[:, j], simulated[:, j], threshold, min_jumps)
        for j, name in enumerate(names)
    ]
    return sorted((f for f in facts if f is not None), key=lambda f: -abs(f.height))


def isolated_outliers(increments: np.ndarray, threshold: float) -> np.ndarray:
    """Indices ``k`` where ``|increments[k]|`` exceeds ``threshold`` robust standard
    deviations and neither neighbour does. Noise-free increments that are mostly exactly
    equal have no spread: their floor is `SPREAD_FLOOR` of the largest."""
    centred = increments - np.median(increments)
    largest = np.max(np.abs(centred), initial=0.0)
    spread = max(MAD_TO_SD * np.median(np.abs(centred)), SPREAD_FLOOR * largest)
    if not spread > 0:
        return np.zeros(0, int)
    outlier = np.abs(centred) > threshold * spread
    padded = np.concatenate([[False], outlier, [False]])
    return np.flatnonzero(outlier & ~padded[:-2] & ~padded[2:])


def overlapping_groups(low: np.ndarray, high: np.ndarray) -> list[np.ndarray]:
    """Indices of the intervals ``[low[i], high[i]]`` grouped where they overlap (chains
    of overlaps included), each group sorted by ``low``."""
    groups, reach = [], -np.inf
    for i in np.argsort(low, kind="stable"):
        if groups and low[i] <= reach:
            groups[-1].append(i)
            reach = max(reach, high[i])
        else:
            groups.append([i])
            reach = high[i]
    return [np.asarray(group) for group in groups]


def _output_fact(name, measured, simulated, threshold, min_jumps) -> OutputJump | None:
    """The fact of one output: its largest group of jumps that step one way, or None."""
    steps, model_steps = np.diff(measured), np.diff(simulated)
    beyond = steps - model_steps
    jumps = isolated_outliers(beyond, threshold)
    if len(jumps) < min_jumps:
        return None
    low = np.minimum(measured[jumps], measured[jumps + 1])
    high = np.maximum(measured[jumps], measured[jumps + 1])
    group = max(overlapping_groups(low, high), key=len)
    signed = _direction(steps, model_steps, jumps[group]) * beyond[jumps[group]]
    if len(group) < min_jumps or not (np.all(signed > 0) or np.all(signed < 0)):
        return None
    fact = OutputJump(
        output=name,
        level=float(np.median((low[group] + high[group]) / 2.0)),
        height=float(np.median(signed)),
        low=float(np.min(low[group])),
        high=float(np.max(high[group])),
        samples=tuple(int(k) for k in np.sort(jumps[group])),
        model_step=float(np.max(np.abs(model_steps[jumps[group]]))),
    )
    return OutputJump(**{**vars(fact), "sentence": describe_jump(fact)})


def _direction(steps, model_steps, jumps) -> np.ndarray:
    """Which way the level moves at each jump (+1 up, -1 down, 0 unknown): the model's
    step, or where the model stands still, the measured steps before and after it."""
    before = steps[np.maximum(jumps - 1, 0)]
    after = steps[np.minimum(jumps + 1, len(steps) - 1)]
    return np.where(model_steps[jumps] != 0, np.sign(model_steps[jumps]), np.sign(before + after))


def describe_jump(fact: OutputJump) -> str:
    """The fact in words, e.g. "the measured z1 jumps by 0.43 in one sample at about 5.3..."."""
    direction = "up" if fact.height > 0 else "down"
    return (
        f"the measured {fact.output} jumps by {abs(fact.height):.3g} in one sample at about "
        f"{fact.level:.4g}, {len(fact.samples)} times (after samples "
        f"{', '.join(str(k) for k in fact.samples[:6])}{', ...' if len(fact.samples) > 6 else ''}),"
        f" stepping {direction} as it rises, where the model moves by at most "
        f"{fact.model_step:.3g}: a step in the sensor's reading?"
    )
