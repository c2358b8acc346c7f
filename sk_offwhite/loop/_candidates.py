r"""Explicit effects proposed by the hypotheses and by the measured output range.

Each hypothesis "equation ``i`` lacks a term in ... that removes / adds ``x_i``" and each
measured ceiling of an output becomes one or more [`Effect`][sk_offwhite.Effect] instances,
only where they make physical sense for the variables' kinds
(`physical_kinds`):

* levels (and one-signed generic states): overflows, leaks, caps;
* velocities and rates: Coulomb friction, quadratic drag and a damping that depends on the
  direction of motion (velocities), a polynomial stiffness in the kinematic partner (the
  position), a constant (a force offset); a hypothesis on a position's equation brings
  these to its velocity's too (`on_the_velocity`: the position's equation is kinematics);
* any equation: a constant ([`Bias`][sk_offwhite.Bias]), a leak for generic states and
  temperatures; temperatures: a loss of fitted power ([`PowerLoss`][sk_offwhite.PowerLoss]);
* inputs in the hypothesis that are efforts or flows: a saturating actuator and a dead zone;
* inputs of a state's declared kind, whatever the hypotheses say: a threshold on their
  difference with that state, two- or one-sided
  ([`DifferenceDeadZone`][sk_offwhite.DifferenceDeadZone]: a clearance, a diode);
* inputs that are positions or angles: play in the transmission
  ([`Backlash`][sk_offwhite.Backlash], an effect with a hidden state);
* inputs the simulation residual correlates with
  ([`correlated_inputs`][sk_offwhite.diagnose.correlated_inputs]): a first-order lag of their
  actuator ([`InputLag`][sk_offwhite.InputLag], a hidden state too) and a dead time
  ([`InputDelay`][sk_offwhite.InputDelay], the past commands as hidden states);
* outputs whose residual runs against the simulated rate
  ([`lagging_outputs`][sk_offwhite.diagnose.lagging_outputs]): a slow sensor
  ([`SensorLag`][sk_offwhite.SensorLag], its reading a hidden state);
* measured states: a sensor offset and a sensor calibration (offset, gain, curvature:
  [`SensorCalibration`][sk_offwhite.SensorCalibration]); measured ceilings: an output saturation;
  repeated one-sample jumps of a measured output at one level
  ([`output_jumps`][sk_offwhite.diagnose.output_jumps]): a step in its reading
  ([`SensorStep`][sk_offwhite.SensorStep]).

The strongest dictionary terms are also proposed as they are
([`DictionaryTerm`][sk_offwhite.DictionaryTerm], when ``library`` is given): that is how an effect
outside the catalogue enters the physics. Initial values come from the data: a term
$p\,b(x, u)$ linear in its parameter starts at the least-squares fit of
$b$ to the hypothesis' correction (converted to the physics' time unit); thresholds
and widths from quantiles and RMS values of the record, the corners of overflows, caps and
sensor ceilings from the variable's standard deviation (``CORNER_FRACTION``). Candidates
are identified by the effect's name, so a cause proposed twice is tried once.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from ..effects import (
    Backlash,
    Bias,
    DeadZone,
    DictionaryTerm,
    DifferenceDeadZone,
    DirectionalDamping,
    Effect,
    Friction,
    InputDelay,
    InputLag,
    InputSaturation,
    Leak,
    OutputOffset,
    OutputSaturation,
    Overflow,
    PowerLoss,
    QuadraticDrag,
    SensorCalibration,
    SensorLag,
    SensorStep,
    Stiffness,
    TransmissionFriction,
)
from ..model._kinds import ACTUATOR_KINDS, LEVEL_KINDS, POSITION_KINDS, VELOCITY_KINDS, Kinds
from ._hypotheses import Hypothesis

__all__ = ["Candidate", "promoted_terms", "propose_effects", "unique_by_name"]

CONSTANT_FEATURE = "1"
"""Name of the constant term of pysindy libraries (``include_bias=True``)."""


@dataclass(frozen=True)
class Candidate:
    """An effect to try, and why it was proposed.

    ``located`` marks an effect that acts beyond a level which a hypothesis located (the
    region of the state where the correction acts): one linear step from its start cannot
    judge how far moving that level would take the fit, so the loop fits it whatever the
    scan's rank (`sk_offwhite.loop._scan`)."""

    effect: Effect
    reason: str
    located: bool = False


def _region_level(hypothesis: Hypothesis, name: str) -> float | None:
    """Where ``hypothesis`` says its effect starts on the variable ``name`` (the low end of
    its region), or ``None`` when its region is on another variable or there is none."""
    if hypothesis.region is None:
        return None
    variable, low, _ = hypothesis.region
    return float(low) if variable == name and np.isfinite(low) else None


def _level(states: np.ndarray, index: int) -> float:
    """Where an effect of a state starts when nothing locates it: the state's 80th
    percentile."""
    return float(np.quantile(states[:, index], 0.8))


CORNER_FRACTION = 0.025
"""Rounding of a hinge (overflow, cap, sensor ceiling) as a fraction of the variable's
standard deviation on the record, so that it follows the data's units."""


DEAD_ZONE_START = 0.02
"""Start of a proposed dead zone's half-width as a fraction of the input's RMS on the
record: narrow, so that the candidate starts next to the model without it and the fit
widens it as far as the data ask; a wide start can leave the fit in a poorer local
minimum (see *Effects started next to the declared model* in the design notes)."""


def _corner(values) -> dict[str, float]:
    """``corner=`` for a hinge on ``values``, or nothing (the effect's default) when the
    variable does not vary or is not finite."""
    spread = CORNER_FRACTION * float(np.std(values))
    return {"corner": spread} if np.isfinite(spread) and spread > 0 else {}


def _overflow(source: int, level: float, sink: int | None, names, states) -> Overflow:
    """An overflow of ``names[source]`` above ``level``, part of it into ``names[sink]``,
    rounded over a corner in the state's scale."""
    corner = _corner(states[:, source])
    if sink is None:
        return Overflow(source, level, name=f"overflow_{names[source]}", **corner)
    name = f"overflow_{names[source]}_to_{names[sink]}"
    return Overflow(source, level, sink=sink, name=name, **corner)


def _losses(hypothesis, states, names) -> list[Candidate]:
    """Something removes from a state: an overflow (a fraction of it reaching each other
    state, or leaving the system when there is none), a leak."""
    i, name = hypothesis.equation_index, hypothesis.equation
    located = _region_level(hypothesis, name)
    level = _level(states, i) if located is None else located
    why = f"{hypothesis.sentence} An overflow of {name} above about {level:.3g}"
    sinks = [j for j in range(len(names)) if j != i] or [None]
    out = [
        Candidate(
            _overflow(i, level, j, names, states),
            why + (" leaving the system." if j is None else f", part of it reaching {names[j]}."),
            located is not None,
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
            _overflow(j, _level(states, j), i, names, states),
            f"{hypothesis.sentence} An overflow of {names[j]} spilling into {names[i]}.",
        )
        for j in range(len(names))
        if j != i
    ]


def _fitted_start(effect: Effect, hypothesis: Hypothesis, states, u, dt: float):
    """``effect`` with its linear (first) parameter at the least-squares fit of its term to
    the hypothesis' correction (per unit time); unchanged when that fit has no finite
    value or lies outside the parameter's bounds."""
    basis = effect.basis(states, u) if hasattr(effect, "basis") else None
    if basis is None or hypothesis.correction is None:
        return effect
    target = np.asarray(hypothesis.correction, float) / dt
    norm = float(basis @ basis)
    if not (norm > 0 and np.all(np.isfinite(target))):
        return effect
    value = float(basis @ target) / norm
    name, spec = next(iter(effect.parameters().items()))
    lower, upper = spec.bounds
    if (lower is not None and value <= lower) or (upper is not None and value >= upper):
        return effect  # the correction points the other way: keep the default start
    field = name[len(effect.name) + 1 :]
    return effect.replace(**{field: value})


def _one_signed(column: np.ndarray) -> bool:
    """The variable never changes sign on the record (a level, an amount)."""
    return bool(np.all(column >= 0) or np.all(column <= 0))


def _rms(column: np.ndarray) -> float:
    """The root mean square of ``column`` (1 where it is 0: a scale for the effects)."""
    return float(np.sqrt(np.mean(column**2)) or 1.0)


SIGN_WIDTH = 0.01
"""Width of a friction's smooth sign, as a fraction of its velocity's RMS on the record."""


def _mechanical(hypothesis, states, names, kinds: Kinds) -> list[Candidate]:
    """Friction, drag, a directional damping and a stiffness in a velocity's (or rate's)
    equation."""
    i, name = hypothesis.equation_index, hypothesis.equation
    kind = kinds.states[i]
    generic_velocity = (
        kind == "generic" and name in hypothesis.variables and not _one_signed(states[:, i])
    )
    if kind not in VELOCITY_KINDS and not generic_velocity:
        return []
    rms, why = _rms(states[:, i]), hypothesis.sentence
    out = [
        Candidate(
            Friction(i, width=SIGN_WIDTH * rms, name=f"friction_{name}"),
            f"{why} A Coulomb friction.",
        ),
        Candidate(QuadraticDrag(i, reference=rms, name=f"drag_{name}"), f"{why} A quadratic drag."),
        Candidate(
            DirectionalDamping(i, width=SIGN_WIDTH * rms, name=f"directional_damping_{name}"),
            f"{why} A damping that depends on the direction of motion.",
        ),
    ]
    position = kinds.partner.get(i)
    if position is not None:
        partner, reference = names[position], _rms(states[:, position])
        spring = Stiffness(i, position, reference=reference, name=f"stiffness_{partner}")
        out.append(Candidate(spring, f"{why} A cubic stiffness in {partner}."))
    return out


def _constants(hypothesis, states, kinds: Kinds) -> list[Candidate]:
    """A constant in the equation (a force offset, an inflow); a leak for generic states
    and temperatures, and for a temperature a loss of another law than the declared one."""
    i, name = hypothesis.equation_index, hypothesis.equation
    out = [Candidate(Bias(i, name=f"bias_{name}"), f"{hypothesis.sentence} A constant term.")]
    if kinds.states[i] in ("generic", "temperature") and hypothesis.sign < 0:
        out.append(Candidate(Leak(i, name=f"leak_{name}"), f"{hypothesis.sentence} A leak."))
    if kinds.states[i] == "temperature" and hypothesis.sign < 0:
        out.append(_power_loss(hypothesis, states[:, i]))
    return out


def _power_loss(hypothesis, temperature: np.ndarray) -> Candidate:
    """A heat loss in a fitted power of the excess over a level
    ([`PowerLoss`][sk_offwhite.PowerLoss]): convection or radiation where the physics declares
    Newton's law. The level starts at the lowest simulated temperature, the exponent at 2; the
    reference excess is the temperature's RMS deviation on the record."""
    i, name = hypothesis.equation_index, hypothesis.equation
    level, reference = float(np.min(temperature)), _rms(temperature - np.mean(temperature))
    loss = PowerLoss(i, level=level, reference=reference, name=f"loss_{name}")
    return Candidate(loss, f"{hypothesis.sentence} A loss of {name} in a power of its excess.")


def _actuators(hypothesis, u, input_names, kinds: Kinds) -> list[Candidate]:
    """A correction in an input that is an effort or a flow: perhaps the actuator
    saturates, softly (``tanh``) or at a hard limit (``clip``), or has a dead zone. Each
    starts where it barely changes the declared model: the saturations at the 90 %
    quantile of $|u_j|$, the dead zone's half-width at `DEAD_ZONE_START` of
    the input's RMS (the fit widens it as far as the data ask)."""
    out = []
    for j, n in enumerate(input_names):
        if n not in hypothesis.variables or np.ptp(u[:, j]) == 0:
            continue
        if kinds.inputs[j] not in ACTUATOR_KINDS:
            continue
        rms = _rms(u[:, j])  # positive: the input varies
        level = float(np.quantile(np.abs(u[:, j]), 0.9))
        if not level > 0:  # an input at zero most of the time: no level to start from
            continue
        out += [
            Candidate(
                InputSaturation(j, level, name=f"actuator_{n}"),
                f"{hypothesis.sentence} The actuator of {n} may saturate.",
            ),
            Candidate(
                InputSaturation(j, level, shape="clip", name=f"actuator_limit_{n}"),
                f"{hypothesis.sentence} The actuator of {n} may reach a hard limit.",
            ),
            Candidate(
                DeadZone(j, DEAD_ZONE_START * rms, name=f"dead_zone_{n}"),
                f"{hypothesis.sentence} The actuator of {n} may have a dead zone.",
            ),
        ]
    return out


EFFORT_KINDS = ("force", "torque")
"""Input kinds a mechanical transmission carries."""


def _transmission_losses(hypothesis, u, input_names, states, kinds: Kinds) -> list[Candidate]:
    """A force or torque named by a hypothesis on a velocity's equation may reach it through
    a screw or gear whose friction grows with that force
    ([`TransmissionFriction`][sk_offwhite.TransmissionFriction]), its sign as smooth as a
    Coulomb friction's (`SIGN_WIDTH`)."""
    i = hypothesis.equation_index
    if kinds.states[i] not in VELOCITY_KINDS:
        return []
    out = []
    for j, n in enumerate(input_names):
        if n not in hypothesis.variables or kinds.inputs[j] not in EFFORT_KINDS:
            continue
        effect = TransmissionFriction(
            j, i, width=SIGN_WIDTH * _rms(states[:, i]), name=f"load_friction_{n}"
        )
        why = f"{hypothesis.sentence} The friction of the transmission of {n} may grow with it."
        out.append(Candidate(effect, why))
    return out


def _drives(u, states, input_names, names, kinds: Kinds) -> list[Candidate]:
    """An input that has the declared kind of a state (a source voltage and a capacitor's,
    a drive's angle and its load's) may drive through their difference past a threshold,
    in both directions (a clearance) or in one (a diode, a check valve). Proposed whatever
    the hypotheses say, as the overflows: the linearised evidence of a threshold can name
    other variables (a clearance in a coupling read as a term in the load's speed). The
    threshold starts at 10 % of the RMS difference on the record."""
    out = []
    for j, n in enumerate(input_names):
        if kinds.inputs[j] == "generic":
            continue
        for i in (i for i, kind in enumerate(kinds.states) if kind == kinds.inputs[j]):
            width = 0.1 * float(np.sqrt(np.mean((u[:, j] - states[:, i]) ** 2)))
            if not (np.isfinite(width) and width > 0):
                continue
            drive = f"{n} - {names[i]}"
            why = f"{n} and {names[i]} are both {kinds.inputs[j]}s: {n} may drive through {drive}"
            out += [
                Candidate(
                    DifferenceDeadZone(j, i, width, name=f"dead_zone_{n}_{names[i]}"),
                    f"{why} only beyond a dead zone (a clearance).",
                ),
                Candidate(
                    DifferenceDeadZone(j, i, width, one_sided=True, name=f"drop_{n}_{names[i]}"),
                    f"{why} in one direction only, past a forward drop (a diode).",
                ),
            ]
    return out


def _transmissions(hypothesis, u, input_names, kinds: Kinds) -> list[Candidate]:
    """Play in the transmission of an input that is a position or an angle (a gear, a
    lead screw): [`Backlash`][sk_offwhite.Backlash], its half-width started at 5 % of the
    input's standard deviation and its driven side at the first input. Proposed whatever
    variables the hypothesis names: an effect with memory is no function of them."""
    out = []
    for j, n in enumerate(input_names):
        spread = float(np.std(u[:, j]))
        if kinds.inputs[j] not in POSITION_KINDS or not spread > 0:
            continue
        effect = Backlash(j, 0.05 * spread, position=float(u[0, j]), name=f"backlash_{n}")
        reason = f"{hypothesis.sentence} The transmission of {n} may have play (backlash)."
        out.append(Candidate(effect, reason))
    return out


DELAY_REACH = 25
"""Samples a proposed dead time may reach: the lags over which
[`correlated_inputs`][sk_offwhite.diagnose.correlated_inputs] (its default ``max_lag``) looks
for the correlation that proposes it, so that every delay that correlation can point to lies
within the fit's bound (a delay longer than the bound stops the fit at the bound)."""


def _lags(hypothesis, u, input_names, dt: float, correlated) -> list[Candidate]:
    """A first-order lag of the actuator of each input in ``correlated`` that varies
    ([`InputLag`][sk_offwhite.InputLag]), its time constant started at one sample (``dt``,
    the effects' unit of time) and its output settled at the first command, and a dead
    time of the input ([`InputDelay`][sk_offwhite.InputDelay], started at one sample, up to
    `DELAY_REACH`), the other variant of how a command reaches the plant. Proposed whatever
    variables the hypothesis names, as the play (an effect with memory is no function of
    them), but only for an input the residual correlates with: a lag's or a delay's
    effect is, to first order, a linear function of the input's history."""
    out = []
    for j, n in enumerate(input_names):
        if j not in correlated or not np.ptp(u[:, j]) > 0:
            continue
        first = float(u[0, j])
        lag = InputLag(j, dt, sampling_time=dt, initial=first, name=f"lag_{n}")
        delay = InputDelay(j, dt, sampling_time=dt, max_delay=DELAY_REACH * dt,
                           initial=first, name=f"delay_{n}")  # fmt: skip
        out.append(
            Candidate(lag, f"{hypothesis.sentence} The actuator of {n} may lag its command.")
        )
        out.append(Candidate(delay, f"{hypothesis.sentence} {n} may reach the plant late."))
    return out


def _sensor_lags(lagging, output_names, outputs, dt: float) -> list[Candidate]:
    """A first-order lag of the sensor of each output in ``lagging``
    ([`SensorLag`][sk_offwhite.SensorLag]), its time constant started at one sample (``dt``)
    and its reading at the simulated output's first value."""
    out = []
    for o in lagging:
        name = output_names[o]
        first = 0.0 if outputs is None else float(outputs[0, o])
        effect = SensorLag(o, dt, sampling_time=dt, initial=first, name=f"sensor_lag_{name}")
        reason = (
            f"The residual of {name} runs against its simulated rate: the sensor of {name} "
            "may lag what it measures."
        )
        out.append(Candidate(effect, reason))
    return out


def _slug(text: str) -> str:
    return re.sub(r"[^0-9A-Za-z]+", "_", text).strip("_") or "term"


def promoted_terms(hypotheses, library, input_features, dt: float, limit=3) -> list[Candidate]:
    """The ``limit`` strongest dictionary terms as
    [`DictionaryTerm`][sk_offwhite.DictionaryTerm]."""
    terms = sorted(
        ((h.gain * t.share, h, t) for h in hypotheses for t in h.terms if t.column >= 0),
        key=lambda item: -item[0],
    )[:limit]
    return [
        Candidate(
            DictionaryTerm(
                h.equation_index,
                library,
                input_features,
                t.column,
                coefficient=t.coefficient / dt,
                name=f"term_{h.equation}_{_slug(t.feature)}",
            ),
            f"{h.sentence} The term {t.feature} itself, promoted into the {h.equation} equation.",
        )
        for _, h, t in terms
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


def _calibrations(states, measured, output_names) -> list[Candidate]:
    """A static quadratic map of each measured state: an uncalibrated, nonlinear sensor,
    centred and scaled by the simulated state so its coefficients are in output units."""
    out = []
    for o, state in enumerate(measured):
        level = states[:, state]
        center, scale = float(np.mean(level)), float(np.std(level))
        if not (np.isfinite(center) and np.isfinite(scale) and scale > 0):
            continue
        name = output_names[o]
        out.append(
            Candidate(
                SensorCalibration(o, center, scale, name=f"sensor_{name}"),
                f"The sensor of {name} may not read {name} linearly: an offset, a gain and "
                "a curvature of its reading (a static map of the output; no state equation "
                "changes).",
            )
        )
    return out


def _ceilings(range_facts, output_names, measured, names, states, outputs) -> list[Candidate]:
    """A measured ceiling the model exceeds: a saturating sensor, or a capped state."""
    out = []
    for fact in range_facts:
        if not (fact.saturated and fact.side == "upper" and fact.n_model_beyond > 0):
            continue
        if fact.output not in output_names:
            continue
        o = output_names.index(fact.output)
        level, name = fact.measured_limit, f"saturation_{fact.output}"
        corner = {} if outputs is None else _corner(outputs[:, o])
        out.append(Candidate(OutputSaturation(o, level, name=name, **corner), fact.sentence))
        if measured is not None:
            cap = _overflow(measured[o], level, None, names, states)
            out.append(Candidate(cap, f"{fact.sentence} The state itself may be capped."))
    return out


def _steps(jumps, output_names, outputs) -> list[Candidate]:
    """A step in the reading of each output that jumps repeatedly at one level, started
    at the jumps' height and at their level less half of it (the step's level is that of
    the reading below it), kept within the values the reading jumped across (widened by
    the height), rounded over a corner in the output's scale."""
    out = []
    for fact in jumps:
        if fact.output not in output_names:
            continue
        o = output_names.index(fact.output)
        corner = {} if outputs is None else _corner(outputs[:, o])
        level, margin = fact.level - fact.height / 2.0, abs(fact.height)
        bounds, name = (fact.low - margin, fact.high + margin), f"step_{fact.output}"
        step = SensorStep(
            o, level, fact.height, level_bounds=bounds, name=name, fit_corner=True, **corner
        )
        out.append(Candidate(step, fact.sentence))
    return out


def _level_effects(hypothesis, states, names, kinds: Kinds) -> list[Candidate]:
    """Overflows and leaks, for levels and one-signed generic states."""
    i = hypothesis.equation_index
    if not _is_level(i, states, kinds):
        return []
    if hypothesis.sign < 0:
        return _losses(hypothesis, states, names)
    return [
        c for c in _gains(hypothesis, states, names) if _is_level(c.effect.state, states, kinds)
    ]


def _spills(states, names, kinds: Kinds) -> list[Candidate]:
    """An overflow of every level, started at its 80th percentile, into each other level
    (its fraction in [0, 1] covers an excess that leaves the system) or, with no other
    level, out of the system: proposed whatever the hypotheses say, because the linearised
    evidence cannot see an effect that acts only where the declared physics seldom takes
    the state (a tank it never fills)."""
    levels = [i for i in range(len(names)) if _is_level(i, states, kinds)]
    out = []
    for i in levels:
        level = _level(states, i)
        for j in [k for k in levels if k != i] or [None]:
            where = "out of the system" if j is None else f"part of it into {names[j]}"
            reason = f"{names[i]} is a level: it may overflow above about {level:.3g}, {where}."
            out.append(Candidate(_overflow(i, level, j, names, states), reason))
    return out


def _is_level(state: int, states, kinds: Kinds) -> bool:
    """A declared level, or a generic state that never changes sign."""
    kind = kinds.states[state]
    return kind in LEVEL_KINDS or (kind == "generic" and _one_signed(states[:, state]))


def unique_by_name(candidates) -> list[Candidate]:
    """``candidates`` without repeated effect names: of each name the first located
    proposal, else the first (in the place of the name's first proposal)."""
    unique: dict[str, Candidate] = {}
    for candidate in candidates:
        kept = unique.setdefault(candidate.effect.name, candidate)
        if candidate.located and not kept.located:
            unique[candidate.effect.name] = candidate
    return list(unique.values())


def on_the_velocity(hypothesis: Hypothesis, names, kinds: Kinds) -> Hypothesis | None:
    r"""A hypothesis on a position's equation, moved to the equation of its declared velocity:
    $\dot q = v$ is kinematics, so what it seems to lack (a drift, a term in $v$) is a force
    the velocity's equation lacks, integrated once. The moved hypothesis has no correction
    of its own to start the effects from. ``None`` where the state has no velocity."""
    i = hypothesis.equation_index
    velocity = next((j for j, position in kinds.partner.items() if position == i), None)
    if velocity is None:
        return None
    why = (
        f"{hypothesis.sentence} {names[i]}'s equation is kinematics: the force on "
        f"{names[velocity]} may lack it instead."
    )
    return replace(hypothesis, equation=names[velocity], equation_index=velocity,
                   correction=None, sentence=why)  # fmt: skip


def with_kinematics_moved(hypotheses, names, kinds: Kinds) -> list[Hypothesis]:
    """``hypotheses``, each one on a position's equation followed by its move to the
    velocity's (`on_the_velocity`)."""
    out = []
    for hypothesis in hypotheses:
        moved = on_the_velocity(hypothesis, names, kinds)
        out += [hypothesis] if moved is None else [hypothesis, moved]
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
    kinds: Kinds | None = None,
    dt: float = 1.0,
    outputs=None,
    jumps=(),
    correlated_inputs=(),
    lagging_outputs=(),
) -> list[Candidate]:
    """Candidate effects (list of [`Candidate`][sk_offwhite.loop.Candidate]), one per effect name,
    by evidence.

    Parameters
    ----------
    hypotheses : list of Hypothesis
        From [`evidence_hypotheses`][sk_offwhite.loop.evidence_hypotheses], strongest first.
    range_facts : list of RangeViolation
        From [`range_violations`][sk_offwhite.diagnose.range_violations].
    state_names, output_names : sequence of str
    states : ndarray of shape (n_samples, n_states)
        Simulated states of the fitted baseline (levels are read in their scale).
    measured : sequence of int, default=None
        Index of the state each output measures directly, when the output map is
        `MeasuredStates`; enables offset, calibration and cap
        candidates.
    u : ndarray of shape (n_samples, n_inputs), default=None
        Inputs of the record, with ``input_names``; enable actuator candidates.
    input_names : sequence of str, default=()
    kinds : Kinds, default=None
        Physical kinds (`physical_kinds`); ``None``: generic.
    dt : float, default=1.0
        Time unit of the effects' rates (`time_step`).
    outputs : ndarray of shape (n_samples, n_outputs), default=None
        Simulated outputs of the fitted baseline: an output saturation's corner is 2.5 %
        of their standard deviation (overflows take theirs from ``states``), and so is a
        sensor step's; ``None`` keeps the effect's default corner.
    jumps : sequence of OutputJump, default=()
        From [`output_jumps`][sk_offwhite.diagnose.output_jumps]: a step in the reading of each
        output that jumps.
    correlated_inputs : sequence of int, default=()
        From [`correlated_inputs`][sk_offwhite.diagnose.correlated_inputs] on the baseline's
        simulation residual: a lag of each of these inputs' actuators.
    lagging_outputs : sequence of int, default=()
        From [`lagging_outputs`][sk_offwhite.diagnose.lagging_outputs]: a lag of each of these
        outputs' sensors.
    """
    names, output_names = tuple(state_names), list(output_names)
    states = np.asarray(states, float)
    u_arr = None if u is None else np.asarray(u, float)
    if kinds is None:
        kinds = Kinds(("generic",) * len(names), ("generic",) * len(input_names), {})
    proposals = []
    for hypothesis in with_kinematics_moved(hypotheses, names, kinds):
        found = _level_effects(hypothesis, states, names, kinds)
        found += _mechanical(hypothesis, states, names, kinds)
        found += _constants(hypothesis, states, kinds)
        if u_arr is not None:
            found += _actuators(hypothesis, u_arr, tuple(input_names), kinds)
            found += _transmission_losses(hypothesis, u_arr, tuple(input_names), states, kinds)
            found += _transmissions(hypothesis, u_arr, tuple(input_names), kinds)
            found += _lags(hypothesis, u_arr, tuple(input_names), dt, correlated_inputs)
        u_rows = np.zeros((len(states), 0)) if u_arr is None else u_arr
        proposals += [
            replace(c, effect=_fitted_start(c.effect, hypothesis, states, u_rows, dt))
            for c in found
        ]
    if measured is not None:
        proposals += _offsets(hypotheses, list(measured), output_names)
        proposals += _calibrations(states, list(measured), output_names)
    outputs = None if outputs is None else np.asarray(outputs, float)
    proposals += _ceilings(range_facts, output_names, measured, names, states, outputs)
    proposals += _steps(jumps, output_names, outputs)
    proposals += _sensor_lags(lagging_outputs, output_names, outputs, dt)
    proposals += _spills(states, names, kinds)
    if u_arr is not None:
        proposals += _drives(u_arr, states, tuple(input_names), names, kinds)
    return unique_by_name(proposals)
