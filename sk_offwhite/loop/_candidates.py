"""Explicit effects proposed by the hypotheses and by the measured output range.

Each hypothesis "equation ``i`` lacks a term that removes / adds ``x_i``" and each measured
ceiling of an output becomes one or more :class:`~sk_offwhite.Effect` instances with
initial values read off the data (levels in the scale of the fitted baseline's simulated
states). Candidates are identified by the effect's name, so a cause proposed twice (an
overflow of ``x1`` into ``x2`` explains both a loss of ``x1`` and a gain of ``x2``) is
tried once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._effects import (
    Effect,
    Friction,
    InputSaturation,
    Leak,
    OutputOffset,
    OutputSaturation,
    Overflow,
)
from ._hypotheses import Hypothesis

__all__ = ["Candidate", "propose_effects"]

CONSTANT_FEATURE = "1"
"""Name of the constant term of pysindy libraries (``include_bias=True``)."""


@dataclass(frozen=True)
class Candidate:
    """An effect to try, and why it was proposed."""

    effect: Effect
    reason: str


def _level(hypothesis: Hypothesis | None, states: np.ndarray, index: int, name: str) -> float:
    """Where the hypothesis says the effect starts, else the 80th percentile of the state."""
    if hypothesis is not None and hypothesis.region is not None:
        variable, low, _ = hypothesis.region
        if variable == name and np.isfinite(low):
            return float(low)
    return float(np.quantile(states[:, index], 0.8))


def _overflow(source: int, level: float, sink: int | None, names) -> Overflow:
    """An overflow of ``names[source]`` above ``level``, part of it into ``names[sink]``."""
    if sink is None:
        return Overflow(source, level, name=f"overflow_{names[source]}")
    return Overflow(source, level, sink=sink, name=f"overflow_{names[source]}_to_{names[sink]}")


def _losses(hypothesis, states, names) -> list[Candidate]:
    """Something removes from a state: an overflow (a fraction of it reaching each other
    state, or leaving the system when there is none), a leak."""
    i, name = hypothesis.equation_index, hypothesis.equation
    level = _level(hypothesis, states, i, name)
    why = f"{hypothesis.sentence} An overflow of {name} above about {level:.3g}"
    sinks = [j for j in range(len(names)) if j != i] or [None]
    out = [
        Candidate(
            _overflow(i, level, j, names),
            why + (" leaving the system." if j is None else f", part of it reaching {names[j]}."),
        )
        for j in sinks
    ]
    out.append(Candidate(Leak(i, name=f"leak_{name}"), f"{hypothesis.sentence} A leak of {name}."))
    return out


def _gains(hypothesis, states, names) -> list[Candidate]:
    """Something adds to a state: an overflow of another state spilling into it."""
    i = hypothesis.equation_index
    return [
        Candidate(
            _overflow(j, _level(None, states, j, names[j]), i, names),
            f"{hypothesis.sentence} An overflow of {names[j]} spilling into {names[i]}.",
        )
        for j in range(len(names))
        if j != i
    ]


def _frictions(hypothesis, names) -> list[Candidate]:
    """A correction of a state's own equation in that state: perhaps a friction on it."""
    i, name = hypothesis.equation_index, hypothesis.equation
    if name not in hypothesis.variables:
        return []
    why = f"{hypothesis.sentence} A (Coulomb) friction braking {name}."
    return [Candidate(Friction(i, name=f"friction_{name}"), why)]


def _actuators(hypothesis, u, input_names) -> list[Candidate]:
    """A correction in an input: perhaps the actuator saturates."""
    return [
        Candidate(
            InputSaturation(j, float(np.quantile(np.abs(u[:, j]), 0.9)), name=f"actuator_{n}"),
            f"{hypothesis.sentence} The actuator of {n} may saturate.",
        )
        for j, n in enumerate(input_names)
        if n in hypothesis.variables and np.ptp(u[:, j]) > 0
    ]


def _offsets(hypotheses, measured, output_names) -> list[Candidate]:
    """A constant term in the equation of a measured state: perhaps the sensor's zero."""
    return [
        Candidate(
            OutputOffset(o, name=f"offset_{output_names[o]}"),
            f"{h.sentence} Its constant term may be a sensor reading {output_names[o]} "
            "with an offset (the physics then acts on the offset-free level).",
        )
        for h in hypotheses
        if any(t.feature == CONSTANT_FEATURE for t in h.terms)
        for o, state in enumerate(measured)
        if state == h.equation_index
    ]


def _ceilings(range_facts, output_names, measured, names) -> list[Candidate]:
    """A measured ceiling the model exceeds: a saturating sensor, or a capped state."""
    out = []
    for fact in range_facts:
        if not (fact.saturated and fact.side == "upper" and fact.n_model_beyond > 0):
            continue
        if fact.output not in output_names:
            continue
        o = output_names.index(fact.output)
        level = fact.measured_limit
        out.append(
            Candidate(OutputSaturation(o, level, name=f"saturation_{fact.output}"), fact.sentence)
        )
        if measured is not None:
            cap = _overflow(measured[o], level, None, names)
            out.append(Candidate(cap, f"{fact.sentence} The state itself may be capped."))
    return out


def propose_effects(
    hypotheses,
    range_facts,
    state_names,
    output_names,
    states,
    measured=None,
    *,
    u=None,
    input_names=(),
) -> list[Candidate]:
    """Candidate effects (list of :class:`Candidate`), one per effect name, by evidence.

    Parameters
    ----------
    hypotheses : list of Hypothesis
        From :func:`~sk_offwhite.loop.form_hypotheses`, strongest first.
    range_facts : list of RangeViolation
        From :func:`~sk_offwhite.diagnose.range_violations`.
    state_names, output_names : sequence of str
    states : ndarray of shape (n_samples, n_states)
        Simulated states of the fitted baseline (levels are read in their scale).
    measured : sequence of int, default=None
        Index of the state each output measures directly, when the output map is
        :class:`~sk_offwhite._physics.MeasuredStates`; enables offset and cap candidates.
    u : ndarray of shape (n_samples, n_inputs), default=None
        Inputs of the record, with ``input_names``; enable actuator-saturation candidates.
    input_names : sequence of str, default=()
    """
    names, output_names = tuple(state_names), list(output_names)
    proposals = []
    for hypothesis in hypotheses:
        if hypothesis.sign < 0:
            proposals += _losses(hypothesis, states, names)
        else:
            proposals += _gains(hypothesis, states, names)
        proposals += _frictions(hypothesis, names)
        if u is not None:
            proposals += _actuators(hypothesis, np.asarray(u, float), tuple(input_names))
    if measured is not None:
        proposals += _offsets(hypotheses, list(measured), output_names)
    proposals += _ceilings(range_facts, output_names, measured, names)
    unique = {}
    for candidate in proposals:
        unique.setdefault(candidate.effect.name, candidate)
    return list(unique.values())
