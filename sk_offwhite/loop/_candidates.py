"""Explicit effects proposed by the hypotheses and by the measured output range."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._effects import Effect, Leak, OutputSaturation, Overflow
from ._hypotheses import Hypothesis

__all__ = ["Candidate", "propose_effects"]


@dataclass(frozen=True)
class Candidate:
    """An effect to try, and why it was proposed."""

    effect: Effect
    reason: str


def _level(hypothesis: Hypothesis | None, states: np.ndarray, index: int, name: str) -> float:
    """Where the hypothesis says the effect starts, else the 90th percentile of the state."""
    if hypothesis is not None and hypothesis.region is not None:
        variable, low, _ = hypothesis.region
        if variable == name and np.isfinite(low):
            return float(low)
    return float(np.quantile(states[:, index], 0.9))


def _losses(hypothesis, states, names) -> list[Candidate]:
    """Something removes from a state: an overflow (to nowhere or to each other state), a leak."""
    i, name = hypothesis.equation_index, hypothesis.equation
    level = _level(hypothesis, states, i, name)
    why = f"{hypothesis.sentence} An overflow of {name} above about {level:.3g}"
    out = [Candidate(Overflow(i, level, name=f"overflow_{name}"), why + " leaving the system.")]
    out += [
        Candidate(
            Overflow(i, level, sink=j, name=f"overflow_{name}_to_{names[j]}"),
            f"{why}, part of it reaching {names[j]}.",
        )
        for j in range(len(names))
        if j != i
    ]
    out.append(Candidate(Leak(i, name=f"leak_{name}"), f"{hypothesis.sentence} A leak of {name}."))
    return out


def _gains(hypothesis, states, names, sources: set[int]) -> list[Candidate]:
    """Something adds to a state: an overflow of another state spilling into it."""
    i = hypothesis.equation_index
    return [
        Candidate(
            Overflow(
                j,
                _level(None, states, j, names[j]),
                sink=i,
                name=f"overflow_{names[j]}_to_{names[i]}",
            ),
            f"{hypothesis.sentence} An overflow of {names[j]} spilling into {names[i]}.",
        )
        for j in range(len(names))
        if j != i and j not in sources
    ]


def _saturations(range_facts, output_names) -> list[Candidate]:
    return [
        Candidate(
            OutputSaturation(
                output_names.index(f.output), f.measured_limit, name=f"saturation_{f.output}"
            ),
            f.sentence,
        )
        for f in range_facts
        if f.saturated and f.side == "upper" and f.n_model_beyond > 0 and f.output in output_names
    ]


def propose_effects(hypotheses, range_facts, state_names, output_names, states):
    """Candidate effects (list of :class:`Candidate`), without duplicates, by evidence."""
    names, output_names = tuple(state_names), list(output_names)
    sources = {h.equation_index for h in hypotheses if h.sign < 0}
    proposals = []
    for hypothesis in hypotheses:
        if hypothesis.sign < 0:
            proposals += _losses(hypothesis, states, names)
        else:
            proposals += _gains(hypothesis, states, names, sources)
    proposals += _saturations(range_facts, output_names)
    unique = {}
    for candidate in proposals:
        unique.setdefault(candidate.effect, candidate)
    return list(unique.values())
