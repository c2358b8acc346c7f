"""Stage 3 of the loop: the candidate effects, from the hypotheses, the measured output range
and the variables' physical kinds, plus the strongest dictionary terms promoted into the
physics, every constant the user declared relaxable, and a first-order hold of inputs that
move between samples."""

from __future__ import annotations

import numpy as np

from ..diagnose import OutputJump, RangeViolation, correlated_inputs, lagging_outputs
from ..effects import InputHold, VaryingParameter
from ..effects._augment import continuous_time, time_step
from ..effects._hidden import n_declared_states
from ..effects._laws import relaxations
from ..model._kinds import Kinds, physical_kinds
from ..model._physics import measured_states, reads_next_input
from ._candidates import Candidate, promoted_terms, propose_effects, unique_by_name
from ._evidence import output_names
from ._groups import joint_groups
from ._reading import read_varying_parameters
from ._search import Search
from ._variants import mechanism

__all__ = ["candidates", "capped", "varying_candidates"]


def candidates(search: Search, physics, library, hypotheses, facts, run) -> list[Candidate]:
    """Catalogue effects and promoted dictionary terms, one per name, without those of a
    mechanism the physics already models (`not_modelled`)."""
    u, z = search.u, search.z
    dt = time_step(physics)
    names = list(physics.state_names) + list(physics.input_names)
    n_declared, kinds = declared_kinds(physics)
    found = propose_effects(
        [h for h in hypotheses if h.equation_index < n_declared],
        [fact for fact in facts if isinstance(fact, RangeViolation)],
        physics.state_names[:n_declared],
        output_names(physics, run.outputs.shape[1]),
        run.states[:, :n_declared],
        measured_states(physics.output),
        u=u,
        input_names=physics.input_names,
        kinds=kinds,
        dt=dt,
        outputs=run.outputs,
        jumps=[fact for fact in facts if isinstance(fact, OutputJump)],
        correlated_inputs=correlated_inputs(z - run.outputs, u),
        lagging_outputs=lagging_outputs(z - run.outputs, run.outputs),
    )
    declared = [
        Candidate(law, f"{law.parameter} is declared relaxable (fixed at {law.value:g})")
        for law in relaxations(physics)
    ]
    terms = promoted(physics, hypotheses, library, names, dt, search.settings.n_promoted)
    holds = input_holds(physics, u)
    return not_modelled(physics, unique_by_name(found + terms + declared + holds))


MOVING_SHARE = 0.5
"""An input moves between its samples when it changes from one sample to the next at more
than this share of the record's samples; a command in steps repeats its value."""


def input_holds(physics, u) -> list[Candidate]:
    """A first-order hold ([`InputHold`][sk_offwhite.InputHold]) when ``physics`` integrates a
    right-hand side under a zero-order hold and an input of the record ``u`` moves between
    samples (`MOVING_SHARE`): a sampled smooth signal, which the plant feels between its
    samples, where the declared physics holds it."""
    if not continuous_time(physics) or reads_next_input(physics) or u.shape[1] == 0:
        return []
    changes = np.mean(np.abs(np.diff(u, axis=0)) > 0, axis=0)
    moving = [name for name, share in zip(physics.input_names, changes, strict=True)
              if share > MOVING_SHARE]  # fmt: skip
    if not moving:
        return []
    verb = "changes" if len(moving) == 1 else "change"
    why = (
        f"{', '.join(moving)} {verb} at most samples, as a sampled smooth signal does; the "
        "declared physics holds each sample until the next. The inputs may move between "
        "samples."
    )
    return [Candidate(InputHold(), why)]


def declared_kinds(physics) -> tuple[int, Kinds]:
    """The number of declared states and their kinds (`physical_kinds`), the hidden
    states' left out: effects act on declared states only (an effect's hidden states are no
    levels or velocities of the plant)."""
    n_declared = n_declared_states(physics)
    kinds = physical_kinds(physics)
    partner = {v: p for v, p in kinds.partner.items() if max(v, p) < n_declared}
    return n_declared, kinds._replace(states=kinds.states[:n_declared], partner=partner)


def promoted(physics, hypotheses, library, names, dt: float, limit: int) -> list:
    """The strongest dictionary terms as candidates
    ([`promoted_terms`][sk_offwhite.loop.promoted_terms]), none on a physics with hidden
    states: the dictionary reads the commands, where a term in the declared step would read
    the input the effects deliver (a backlash's, a delay's), another function."""
    if physics.n_states > n_declared_states(physics):
        return []
    return promoted_terms(hypotheses, library, names, dt, limit)


def not_modelled(physics, proposed: list) -> list:
    """``proposed`` without the candidates whose mechanism an effect of ``physics`` already
    models: run on an augmented physics (its own result, say), the loop would otherwise
    propose an effect it holds, or a second variant of one mechanism."""
    modelled = {mechanism(effect) for effect in getattr(physics, "effects", ())}
    return [c for c in proposed if mechanism(c.effect) not in modelled]


def capped(proposed: list, limit: int | None) -> list:
    """The candidates of the first ``limit`` mechanisms in the order proposed, every
    variant of those mechanisms included: a cap counts what is tried, not how many shapes of
    it are (a saturation's two, an overflow's destinations)."""
    if limit is None:
        return list(proposed)
    kept, mechanisms = [], []
    for candidate in proposed:
        kind = mechanism(candidate.effect)
        if kind not in mechanisms and len(mechanisms) < limit:
            mechanisms.append(kind)
        if kind in mechanisms:
            kept.append(candidate)
    return kept


def proposed_groups(search: Search, physics, hypotheses, proposed, run) -> list:
    """The groups of ``proposed`` effects that may only help together
    (`joint_groups`), on the declared states."""
    n_declared, _ = declared_kinds(physics)
    declared = [h for h in hypotheses if h.equation_index < n_declared]
    states = run.states[:, :n_declared]
    return joint_groups(declared, proposed, states, search.u, time_step(physics))


MAX_READINGS = 2
"""Varying constants proposed from one δ: the best form of each of the first pairs
(parameter, variable) the readings rank."""


def varying_candidates(search: Search, physics, fitted) -> list[Candidate]:
    """The declared constants that the fitted ``physics`` + δ (``fitted``) reads as laws of
    a state or input (`read_varying_parameters`), each as a
    [`VaryingParameter`][sk_offwhite.VaryingParameter] started where the reading ends; none
    without a fit, on a physics with hidden states, or when no reading counts."""
    if fitted is None or physics.n_states > n_declared_states(physics):
        return []
    run = fitted.simulate(search.u)
    readings = read_varying_parameters(
        physics, fitted.parameters_, run.states, search.u, run.correction
    )
    best = {}
    for reading in readings:
        best.setdefault((reading.parameter, reading.variable), reading)
    chosen = list(best.values())[:MAX_READINGS]
    return [Candidate(varying_effect(physics, r), r.sentence) for r in chosen]


def varying_effect(physics, reading) -> VaryingParameter:
    """The effect that holds ``reading``'s law, its constants as the start."""
    states = list(physics.state_names)
    source = "state" if reading.variable in states else "input"
    names = states if source == "state" else list(physics.input_names)
    constants = reading.constants
    rising = reading.sign in ("rising", "hardening")
    if reading.family == "exponential":
        rising = constants["x_s"] > 0
    return VaryingParameter(
        reading.parameter,
        names.index(reading.variable),
        reading.family,
        abs(float(constants["x_s"])),
        exponent=float(constants.get("p", 1.0)),
        rising=rising,
        source=source,
        stiffness=reading.sign in ("hardening", "softening"),
        variable_name=reading.variable,
    )
