r"""The first stages of the loop: the declared physics fitted, and what it cannot explain.

1. The declared physics is fitted (multiple shooting, then the whole record) and
   cross-validated. A parameter that fit leaves undetermined (an infinite standard error)
   starts the later fits from its declared value: along a flat direction the fitted point
   is arbitrary, and one that ran off toward a limit can leave the later fits no way back.
2. **Evidence.** At that fit, every dictionary term's projected gain: what it would explain
   that no re-adjustment of the declared parameters can. The strongest terms make up the
   hypotheses ([`evidence_hypotheses`][sk_offwhite.loop.evidence_hypotheses]); the fitted
   sparse $\delta$ adds its own when it beats the declared physics under cross-validation.
   With ``kind_notes`` (the default) and a pysindy dictionary, the functions a physicist
   tries first for each variable (`with_kind_terms`: a velocity's sign and $v|v|$, a
   level's square root, powers of a temperature's excess, the size of a variable that
   changes sign, a saturation of a measured state or an input) are read too, on a fit of
   their own: a note names those that explain more than the dictionary's best term.
"""

from __future__ import annotations

import warnings

import numpy as np

from .._estimator import GreyBoxSparseRegressor
from .._validation import check_record
from ..certify import identifiability
from ..diagnose import analyse_residuals, output_jumps, range_violations
from ..model._equations import output_name
from ..runtime._parallel import gather, start_workers
from ._fits import fit_continued, warm_physics
from ._hypotheses import evidence_hypotheses, form_hypotheses
from ._kind_terms import (
    column_meaning,
    declared_slopes,
    kind_columns,
    kind_groups,
    with_kind_terms,
)
from ._scoring import MODEL_LABELS
from ._search import FIT_ERRORS, Search

__all__ = ["analyse_model"]


def fit_declared(search: Search, physics):
    """The declared physics fitted (multiple shooting, then whole), the physics started from
    that fit, its free run and the parameters reset to their declared values."""
    workers = start_workers(search.settings.n_jobs)  # they start while this process fits
    try:
        est = search.estimator(physics)
        baseline = fit_continued(est, search.u, search.z, search.settings.horizon)
    finally:
        gather(workers)
    start, reset = start_of_later_fits(physics, baseline, search.u, search.z)
    return baseline, start, baseline.simulate(search.u), reset


def unfit_notes(baseline) -> list[str]:
    """A note when the declared physics' fit is no model the search should build on."""
    if baseline.converged_:
        return []
    return [
        f"The declared physics' fit did not converge ({baseline.solver_message_}): every "
        "later fit starts from it, so its results are to be read with care."
    ]


def start_of_later_fits(physics, baseline: GreyBoxSparseRegressor, u, z):
    """The physics started from the declared fit
    ([`warm_physics`][sk_offwhite.loop.warm_physics]), but for the parameters that fit does
    not determine, which start from their declared values; and ``{name: fitted value}`` of
    those."""
    start = warm_physics(physics, baseline)
    reset = {  # the names are the free parameters and initial states ("x1(0)")
        name: baseline.parameters_[name]
        for name in undetermined(baseline, u, z)
        if name in physics.parameters
    }
    return start.with_parameters(**{name: physics.parameters[name] for name in reset}), reset


def undetermined(est: GreyBoxSparseRegressor, u, z) -> list[str]:
    """Names of the variables of ``est``'s fit with an infinite standard error (on a flat
    direction of the relative Hessian:
    [`identifiability`][sk_offwhite.certify.identifiability]); none when that cannot be
    computed."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            report = identifiability(est, u, z, include_omega=False)
    except FIT_ERRORS:
        return []
    return [name for name, error in report.standard_errors.items() if not np.isfinite(error)]


def reset_notes(reset: dict, physics) -> list[str]:
    """A note per declared parameter that later fits start from its declared value."""
    return [
        f"The declared physics' fit does not determine {name} (fitted {value:.4g}, its "
        f"standard error infinite): the later fits start it from its declared value "
        f"{physics.parameters[name].value:.4g}."
        for name, value in reset.items()
    ]


def record_facts(physics, z, run) -> list:
    """What the declared physics' simulation ``run`` says of the measured outputs ``z``:
    their ceilings and floors, and their repeated one-sample jumps."""
    names = output_names(physics, z.shape[1])
    return range_violations(z, run.outputs, names) + output_jumps(z, run.outputs, names)


def output_names(physics, n_outputs: int) -> list[str]:
    """The names the report gives the outputs."""
    return [output_name(physics, i) for i in range(n_outputs)]


def read_evidence(search: Search, physics, library):
    """The physics-only fit with the dictionary's evidence, and its hypotheses."""
    evidence = search.attempt("evidence", evidence_fit, search, physics, library)
    if evidence is None:
        return None, []
    run = evidence.simulate(search.u)
    share = search.settings.min_share
    return evidence, evidence_hypotheses(evidence, run, search.u, min_share=share)


def read_kind_notes(search: Search, physics, library, states) -> None:
    """With the setting ``kind_notes``, the note on the functions of the variables' kinds
    (`kind_notes` on ``states``, ``physics``' free run) joins ``search.notes`` (a failed
    fit: a line of ``search.failures``)."""
    if search.settings.kind_notes:
        arguments = (search, physics, library, states)
        notes = search.attempt("evidence of the kinds", kind_notes, *arguments)
        search.notes.extend(notes or [])


def kind_notes(search: Search, physics, library, states) -> list[str]:
    """A line per equation on the functions of the variables' kinds (`kind_groups`, on
    ``states``) that would explain more than the dictionary's best term there,
    each in the equation where it explains most, with the share of the declared physics'
    cost each removes alone (at least ``min_gain``, the share a step of the loop must
    gain) and what its fitted sign says (`column_meaning`). Read on a fit of their own,
    so that they inform the reader and leave the loop's hypotheses and candidates as the
    dictionary makes them. None where the dictionary is no pysindy library or no
    variable has such a kind."""
    groups = kind_groups(physics, search.u, states)
    combined = with_kind_terms(library, physics, groups)
    if combined is None:
        return []
    est = evidence_fit(search, physics, combined)
    slopes = declared_slopes(physics, states, search.u)
    return _kind_lines(est, kind_columns(groups), slopes, search.settings.min_gain)


def _kind_lines(est, columns, slopes: np.ndarray, floor: float) -> list[str]:
    """The notes of the evidence fit ``est`` whose last columns are the kinds' ``columns``,
    the declared physics' slopes (`declared_slopes`) reading their signs; a function that
    removes less than ``floor`` of the declared physics' cost is not named."""
    own = len(est.feature_names_) - len(columns)  # the dictionary's columns come first
    gains = np.nan_to_num(np.asarray(est.term_gain_, float))
    # a kind function is named in the equation where it explains most, and only above floor
    elsewhere = (gains < np.max(gains, axis=0, keepdims=True)) | (gains < floor)
    gains[:, own:] = np.where(elsewhere[:, own:], 0.0, gains[:, own:])
    lines = []
    for row, state in enumerate(est.delta_states_):
        weights = est.term_estimate_[row, own:]
        meanings = [
            column_meaning(column, state, float(weight), slopes[state])
            for column, weight in zip(columns, weights, strict=True)
        ]
        equation = est.physics_.state_names[state]
        lines.append(_kind_line(equation, est.feature_names_, meanings, gains[row], own))
    return [line for line in lines if line]


def _kind_line(equation: str, names, meanings, gains: np.ndarray, own: int) -> str:
    """The note for one equation, or ``""`` when no kind function (columns from ``own``,
    each with what it says in ``meanings``) beats the dictionary's best term."""
    best = int(np.argmax(gains[:own]))
    better = [j for j in np.argsort(-gains[own:]) + own if gains[j] > gains[best]]
    if not better:
        return ""
    found = ", ".join(f"{names[j]} {gains[j]:.0%} ({meanings[j - own]})" for j in better)
    return (
        f"In the {equation} equation the functions of the variables' kinds explain more than "
        f"the dictionary: {found} of the declared physics' cost, each alone (the "
        f"dictionary's best, {names[best]}: {gains[best]:.0%})."
    )


def evidence_fit(search: Search, physics, library) -> GreyBoxSparseRegressor:
    """The physics-only fit on the whole record with the dictionary's evidence."""
    targets = dict(library=library, delta_states=search.settings.delta_states)
    est = search.estimator(physics, **targets).set_params(horizon=None)
    return est._fit(search.u, search.z, None, reference_only=True)


def delta_hypotheses(search: Search, est, cv: float, declared_cv: float, notes: list) -> list:
    """The hypotheses of the declared physics + δ when it beats the declared physics under
    CV by ``min_gain``; else a note says why there are none."""
    if est is None:
        return []
    if not cv < (1.0 - search.settings.min_gain) * declared_cv:
        notes.append(
            f"{MODEL_LABELS['with_delta']} does not beat the declared physics under CV "
            f"({cv:.4g} against {declared_cv:.4g}): no hypothesis is read from its correction."
        )
        return []
    return form_hypotheses(est, est.simulate(search.u), search.u)


def analyse_model(est, u, z, physics, *, x0=None, z_init_window=0):
    """Residual report of a fitted model on one record (see
    [`sk_offwhite.diagnose`][sk_offwhite.diagnose])."""
    u, z = check_record(u, z)
    z_init = z[:z_init_window] if z_init_window else None
    run = est.simulate(u, x0=x0, z_init=z_init)
    taken = set(physics.state_names) | set(physics.input_names)
    outputs = [f"{n} (output)" if n in taken else n for n in output_names(physics, z.shape[1])]
    return analyse_residuals(
        z,
        run.outputs,
        u,
        run.states,
        state_names=list(physics.state_names),
        input_names=list(physics.input_names),
        output_names=outputs,
        skip=z_init_window,
    )
