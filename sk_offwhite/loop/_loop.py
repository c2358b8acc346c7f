r"""The closed loop: residual -> evidence -> named effect -> refit -> before/after.

1. Fit the declared physics (multiple shooting, then the whole record).
2. **Evidence.** At that fit, every dictionary term's projected gain
   (`TermEvidence`): what it would explain that no
   re-adjustment of the declared parameters can. The strongest terms make up the
   hypotheses ([`evidence_hypotheses`][sk_offwhite.loop.evidence_hypotheses]). With ``fit_delta``,
   the declared physics + sparse $\delta$ (support path, $\gamma$ by CV) adds the
   hypotheses of its fitted correction ([`form_hypotheses`][sk_offwhite.loop.form_hypotheses]), only
   when it beats the declared physics under CV by ``min_gain`` (else a note says so):
   the linearised evidence misses effects far from the declared trajectory (an overflow
   of a state that the declared physics never fills).
3. **Candidates** from the hypotheses, the measured output range and the variables'
   physical kinds ([`propose_effects`][sk_offwhite.loop.propose_effects]), plus the strongest terms
   themselves promoted into the physics ([`DictionaryTerm`][sk_offwhite.DictionaryTerm]).
4. **Selection.** Each candidate is fitted alone on the estimation record; then forward
   selection adds, among the ``beam`` best, the candidate that lowers the estimation error
   most while it lowers it by ``min_gain`` (when no candidate helps alone, pairs of the best
   are tried: effects such as Coulomb friction and a force offset only help together). The
   sets of that order, and the nested sets of the candidates that helped alone in the order
   of their gain, are cross-validated, each from its own fit on the whole record; the
   smallest within ``tolerance`` of the best is kept if it beats the declared physics by
   ``min_gain``, then refined stepwise (each other named candidate added or exchanged for
   one of its effects, each of its effects dropped; see `_swap`).
5. Refit the augmented physics; where an added effect leaves its fit a direction the data
   do not determine (a calibrated level whose scale nothing else fixes), hold one of the
   effect's parameters on it at its fitted value (`_gauge`), when
   that leaves the fit and, within ``tolerance``, its CV error as they were. Then, with
   ``fit_delta``, fit the augmented physics with a sparse $\delta$ ($\gamma$
   chosen by CV on the support path); with ``fit_output_delta`` too, where outputs
   measure states, the augmented physics with a sparse correction of its output map
   instead (a static nonlinearity of the sensors: Gaussian bumps of the measured states,
   [`from_data`][sk_offwhite.RadialBasis.from_data], spread over the augmented physics'
   simulated range).
6. **Never worse.** Every final model is cross-validated the same way; ``result.chosen``
   names the CV-best, and a model is never preferred to one with a lower CV error.

Every fit that fails (a candidate, a fold, a $\gamma$) becomes a line of
``result.failures`` and the loop goes on; warnings are re-issued with the name of the fit
they come from. Cross-validation holds out contiguous blocks of the estimation record; each
held-out block's initial state is estimated from its first ``init_window`` samples, which
are not scored ([`held_out_rmse`][sk_offwhite.loop.held_out_rmse]). Validation data, when given, are
only scored.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from sklearn.base import clone
from sklearn.model_selection import KFold

from .._cache import release_package_programs
from .._equations import output_name
from .._estimator import GreyBoxSparseRegressor, RunawayParameterWarning
from .._kinds import Kinds, physical_kinds
from .._parallel import gather, launch, start_workers
from .._path import GammaPath, fit_gamma_path
from .._physics import Parameter, measured_states
from .._radial import RadialBasis
from .._validation import check_record
from ..certify import identifiability
from ..diagnose import (
    OutputJump,
    RangeViolation,
    analyse_residuals,
    correlated_inputs,
    lagging_outputs,
    output_jumps,
    range_violations,
)
from ..effects import DictionaryTerm, augment
from ..effects._augment import time_step
from ..effects._hidden import n_declared_states
from ..effects._laws import relaxations
from ..solvers._rules import LM_SCALINGS
from ._candidates import Candidate, promoted_terms, propose_effects, unique_by_name
from ._gauge import fit_undetermined_directions, held_note, held_parameters, holding
from ._hypotheses import evidence_hypotheses, form_hypotheses
from ._progress import StageClock, logger
from ._scoring import MODEL_LABELS, held_out_rmse
from ._switchboard import Switchboard, effect_sets, single_effect_models
from ._variants import mechanism, richer, richer_start

__all__ = [
    "LoopResult",
    "LoopSettings",
    "close_the_loop",
    "fit_continued",
    "held_out_splits",
    "hold_undetermined_directions",
    "warm_physics",
]


@dataclass(frozen=True)
class LoopSettings:
    r"""Settings of [`close_the_loop`][sk_offwhite.loop.close_the_loop], all applied on the
    estimation record only.

    ``gammas`` is the grid of the (dimensionless) $\gamma$; ``None`` uses
    ``n_gammas`` values from $\gamma_{max}$ down to ``gamma_eps`` times it
    ([`gamma_grid`][sk_offwhite.gamma_grid]); a single value is fitted without a search.
    ``horizon`` is the multiple-shooting window of the first stage of every fit on the
    record (the declared physics, each candidate and effect set, the final physics), each
    refined on the whole record (but a set with an effect on the output map is fitted on
    the whole record alone: ``_set_horizon``);
    ``cv_horizon`` that of the fits inside cross-validation (``None``: each training block
    is simulated whole, which is what the held-out blocks are scored on). ``min_gain`` is
    the relative reduction of the cross-validated RMSE an effect set must bring;
    ``tolerance`` the relative slack within which a smaller nested set is preferred.
    ``max_candidates`` caps how many proposed mechanisms are fitted, in the order they are
    proposed (strongest hypothesis first), each with all its variants (an overflow's
    destinations, a saturation's shapes); ``None`` fits them all. Each candidate costs a
    fit and a compilation, so a cap is the way to make a quick run quicker. ``beam`` is
    how many of the best single candidates forward selection combines; ``min_share`` the
    fraction of the strongest term's gain a term needs to be evidence; ``n_promoted`` how
    many of the strongest terms are proposed as they are; ``fit_delta`` whether the models
    with a sparse $\delta$ are fitted (they show what is left, and cost a path each);
    ``share_programs`` whether every effect set is fitted on one compiled program (a
    `Switchboard`: less compilation, see that
    module; off by default: measured faster in one process, slower with workers, and its
    rounding flipped a near-tie of the backlash servo's cross-validation). The single
    candidates share one board either way, but for those with memory of their own and
    relaxed laws (`single_effect_models`).
    ``selection`` is how every choice is scored: ``"cv"``, the mean held-out RMSE over
    ``n_folds`` contiguous blocks; ``"tail"``, the held-out RMSE of the last
    ``tail_fraction`` of the record (after its ``init_window``) when the rest is
    fitted, which is how the model will be used: fitted on the past, run into the future.
    ``n_jobs`` processes (joblib's convention: ``None`` one, ``-1`` all cores) fit the
    held-out folds, the candidate effects and the effect sets, with the same numbers as
    one; switch the persistent compilation cache on
    ([`enable_compilation_cache`][sk_offwhite.enable_compilation_cache]) so that they share compiled
    programs. ``lm_scaling`` is every fit's Levenberg-Marquardt scaling (``'per-variable'``,
    iterates that do not depend on the units, or ``'global'``; see
    [`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor]). ``one_standard_error`` chooses
    each $\delta$'s $\gamma$ as the largest whose CV error is within one standard
    error of the lowest (the sparser model the folds cannot tell from the best; see
    [`fit_gamma_path`][sk_offwhite.fit_gamma_path]) instead of the lowest. ``release_programs``
    drops the package's compiled programs
    ([`release_package_programs`][sk_offwhite.release_package_programs]) after each stage and each
    phase of the effect selection, and worker processes after each of their tasks: the structures
    fitted there are seldom fitted again, and the programs of those that are are traced again (and
    loaded from the disk cache when it is on). ``fit_output_delta`` whether, with ``fit_delta``, the
    augmented physics is also fitted with a sparse correction of its output map, where the outputs
    read states (a sensor's static nonlinearity; a path more), on ``output_bumps`` Gaussian bumps of
    each measured state.
    """

    gammas: tuple[float, ...] | None = None
    n_gammas: int = 5
    gamma_eps: float = 1e-6
    n_folds: int = 3
    horizon: int | None = 128
    cv_horizon: int | None = None
    max_iter: int = 300
    max_effects: int = 3
    min_gain: float = 0.05
    tolerance: float = 0.02
    delta_states: tuple[int, ...] | None = None
    init_window: int = 50
    max_candidates: int | None = None
    beam: int = 4
    min_share: float = 0.1
    n_promoted: int = 3
    fit_delta: bool = True
    share_programs: bool = False
    selection: str = "cv"
    tail_fraction: float = 0.25
    n_jobs: int | None = None
    lm_scaling: str = "per-variable"
    one_standard_error: bool = False
    release_programs: bool = True
    fit_output_delta: bool = True
    output_bumps: int = 7

    def __post_init__(self):
        if self.selection not in ("cv", "tail"):
            raise ValueError(f"selection must be 'cv' or 'tail', got {self.selection!r}.")
        if self.lm_scaling not in LM_SCALINGS:
            rules = " or ".join(map(repr, LM_SCALINGS))
            raise ValueError(f"lm_scaling must be {rules}, got {self.lm_scaling!r}.")
        if not 0.0 < self.tail_fraction < 1.0:
            raise ValueError(f"tail_fraction must be in (0, 1), got {self.tail_fraction!r}.")
        if self.max_candidates is not None and self.max_candidates < 1:
            raise ValueError(f"max_candidates must be None or >= 1, got {self.max_candidates}.")
        if self.gammas is not None and not (
            len(self.gammas) > 0 and all(np.isfinite(g) and g >= 0 for g in self.gammas)
        ):
            raise ValueError(f"gammas must be None or finite values >= 0, got {self.gammas}.")
        if isinstance(self.n_folds, bool) or not int(self.n_folds) == self.n_folds >= 2:
            raise ValueError(f"n_folds must be an integer >= 2, got {self.n_folds!r}.")
        bumps = self.output_bumps
        if isinstance(bumps, bool) or not int(bumps) == bumps >= 2:
            raise ValueError(f"output_bumps must be an integer >= 2, got {bumps!r}.")


@dataclass
class LoopResult:
    """Everything the loop found; the report is written from it.

    ``augmented_physics`` is the declared physics with the added effects (their parameters
    at their declared and proposed values), with the parameters the final model holds on the
    directions its fit leaves undetermined fixed at their fitted values
    ([`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions]). ``selection``
    holds ``(label, cross-validated RMSE)`` of the declared physics and of every nested effect set
    tried; ``single_fits`` ``(effect name, estimation RMSE)`` of each candidate fitted alone;
    ``gamma_path`` and ``final_gamma_path`` the support paths ([`GammaPath`][sk_offwhite.GammaPath],
    ``None`` for a single γ) of the two fits with δ (``with_delta`` and ``final_with_delta`` are
    ``None`` without ``fit_delta`` or when they failed). ``range_facts`` holds what the declared
    physics' simulation says of the measured outputs: their ceilings and floors
    ([`RangeViolation`][sk_offwhite.diagnose.RangeViolation]) and their repeated one-sample jumps
    ([`OutputJump`][sk_offwhite.diagnose.OutputJump]). ``evidence`` is the physics-only fit with
    the dictionary the hypotheses come from; ``final_with_output_delta`` the augmented
    physics with a sparse correction of its output map and ``output_gamma_path`` its path
    (``None`` without ``fit_output_delta``, when the outputs do not read states, or when it
    failed); ``cv_errors`` maps each fitted model's key (``"baseline"``, ``"with_delta"``,
    ``"final"``, ``"final_with_delta"``, ``"final_with_output_delta"``) to its
    cross-validated RMSE, ``chosen`` is the key of the lowest (a fit with δ that kept no
    term excepted: it is the physics it corrects); ``failures`` one line per fit that
    failed; ``notes`` what the loop decided not to use and why; ``timings`` the wall time of
    each stage in seconds (the stages are logged as they run, see
    `_progress`); ``set_fits`` each model of the ``selection`` trail
    fitted on the whole estimation record, by its label (``None`` where that fit failed), so
    that every structural step can be scored on validation data (the report does)."""

    physics: object
    augmented_physics: object
    baseline: GreyBoxSparseRegressor
    with_delta: GreyBoxSparseRegressor
    final: GreyBoxSparseRegressor
    final_with_delta: GreyBoxSparseRegressor
    gamma_path: GammaPath | None
    hypotheses: list
    range_facts: list
    candidates: list
    selection: list = field(default_factory=list)
    effects: tuple = ()
    single_fits: list = field(default_factory=list)
    final_gamma_path: GammaPath | None = None
    evidence: GreyBoxSparseRegressor | None = None
    cv_errors: dict = field(default_factory=dict)
    chosen: str = "baseline"
    failures: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    set_fits: dict = field(default_factory=dict)
    final_with_output_delta: GreyBoxSparseRegressor | None = None
    output_gamma_path: GammaPath | None = None

    @property
    def best(self) -> GreyBoxSparseRegressor:
        """The model with the lowest cross-validated error (``chosen``)."""
        return getattr(self, self.chosen)


def fit_continued(est: GreyBoxSparseRegressor, u, z, horizon):
    """Fit with multiple shooting first (``horizon``), then refine on the whole record."""
    if horizon is not None and horizon < len(u):
        est.set_params(horizon=horizon).fit(u, z)
        est.set_params(horizon=None, warm_start=True)
    est.fit(u, z)
    return est.set_params(warm_start=False)


def warm_physics(physics, est: GreyBoxSparseRegressor):
    """``physics`` whose free parameters and initial-state guess are those of ``est``.

    Parameters ``physics`` does not have (those of effects added since) are ignored; fixed
    ones keep their values; bounds are kept.
    """
    updates = {
        name: Parameter(float(value), spec.bounds)
        for name, value in est.parameters_.items()
        if (spec := physics.parameters.get(name)) is not None and not spec.fixed
    }
    model = physics.with_parameters(**updates)
    model.x0 = np.asarray(est.initial_states_[0], float).copy()
    return model


def _estimator(physics, settings, *, cv=False, **params) -> GreyBoxSparseRegressor:
    return GreyBoxSparseRegressor(
        physics,
        horizon=settings.cv_horizon if cv else settings.horizon,
        max_iter=settings.max_iter,
        init_window=settings.init_window,
        lm_scaling=settings.lm_scaling,
        **params,
    )


def _processes(settings: LoopSettings | None) -> tuple:
    """``(n_jobs, release_after)`` of `launch` for ``settings``
    (one process, nothing released, without)."""
    return (None, False) if settings is None else (settings.n_jobs, settings.release_programs)


def _released(settings: LoopSettings, value):
    """``value``, once the package's compiled programs are dropped (with
    ``settings.release_programs``): what a phase of the loop fitted is done with."""
    if settings.release_programs:
        release_package_programs()
    return value


@contextmanager
def _stage(clock: StageClock, name: str, settings: LoopSettings) -> Iterator[None]:
    """``clock.stage(name)``, then `_released`."""
    with clock.stage(name):
        yield
    _released(settings, None)


def held_out_splits(settings: LoopSettings, n_samples: int) -> list:
    """``(train, test)`` index pairs of ``settings.selection``: ``n_folds`` contiguous
    blocks, or the record's last ``tail_fraction`` held out."""
    if settings.selection == "cv":
        return list(KFold(settings.n_folds).split(np.zeros((n_samples, 1))))
    cut = n_samples - max(int(round(settings.tail_fraction * n_samples)), 1)
    if cut <= settings.init_window or n_samples - cut <= settings.init_window:
        raise ValueError(
            f"tail_fraction={settings.tail_fraction} of {n_samples} samples leaves a block no "
            f"longer than init_window={settings.init_window}."
        )
    return [(np.arange(cut), np.arange(cut, n_samples))]


FIT_ERRORS = (ValueError, TypeError, FloatingPointError, np.linalg.LinAlgError)
"""What a failing fit raises: `_attempt` turns these into lines of the report."""


def cross_validated_rmse(physics, u, z, settings: LoopSettings | None = None) -> float:
    """The loop's score of a structure: the mean held-out free-run RMSE of ``physics``
    (started from its parameter values) over the blocks of
    [`held_out_splits`][sk_offwhite.loop.held_out_splits], each fold fitted with ``settings`` (its
    ``cv_horizon``, ``max_iter``, ``init_window``, ``lm_scaling``) and scored after its
    ``init_window`` samples; a fold whose fit fails scores ``inf``. Every effect set of
    [`close_the_loop`][sk_offwhite.loop.close_the_loop] is scored so, from its own fit on the record
    ([`warm_physics`][sk_offwhite.loop.warm_physics])."""
    settings = LoopSettings() if settings is None else settings
    return _cv_rmse(_estimator(physics, settings, cv=True), u, z, settings)


def _cv_rmse(est, u, z, settings: LoopSettings) -> float:
    """Mean held-out simulation RMSE over the blocks of
    [`held_out_splits`][sk_offwhite.loop.held_out_splits], the folds fitted by ``settings.n_jobs``
    processes (a fold whose fit fails scores ``inf``)."""
    arguments = [
        (clone(est), u, z, train, test, settings.init_window)
        for train, test in held_out_splits(settings, len(u))
    ]
    jobs = launch(_fold_rmse, arguments, *_processes(settings))
    return float(np.mean(gather(jobs)))


def _fold_rmse(est, u, z, train, test, init_window: int) -> float:
    """Held-out RMSE of ``test`` (one block) after fitting ``train``; ``inf`` (and a
    warning naming the error) when the fit raises anything, as ``cross_val_score`` scores a
    failed fold with ``error_score``."""
    try:
        est.fit(u[train], z[train], sample_index=train)
    except Exception as error:  # any failure of one fold ranks the model last
        warnings.warn(
            f"a fold's fit failed and scores inf: {type(error).__name__}: {error}",
            UserWarning,
            stacklevel=2,
        )
        return np.inf
    return -held_out_rmse(init_window)(est, u[test], z[test])


def _set_cv(board, effects, warm, u, z, settings, failures):
    """CV RMSE of an effect set and its fit on the whole record (``None`` if that failed).

    Each fold starts from that fit ([`fit_continued`][sk_offwhite.loop.fit_continued] from
    ``warm``), the model that would be kept: an effect may move the declared parameters far (a
    sensor calibration rescales the levels the outflow laws act on), and folds started from the
    declared physics' fit would then judge the set from a start that belongs to another model.
    A parameter is held at its fitted value on each direction of that fit the data do not
    determine ([`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions],
    without its refit, which would end where the fit is, and without its comparison of the two CV
    errors, which the final model makes): otherwise the folds wander along the direction, and a set
    is judged by where its folds' fits stopped there (measured on the Cascaded Tanks' four effects:
    CV 0.1092 free, 0.1064 held; with the calibration of degree 3, 0.1133 and 0.1005)."""
    model = board.model(effects, warm)
    label = "effects " + _label(effects)
    fitted = _attempt(failures, label, _fit_set, _estimator(model, settings), effects, u, z,
                      settings)  # fmt: skip
    if fitted is None:
        return cross_validated_rmse(model, u, z, settings), fitted
    held, _ = _held_on_fit(model, fitted, u, z, effects)
    start = holding(warm_physics(model, fitted), held)
    return cross_validated_rmse(start, u, z, settings), fitted


def _sets_cv(board, steps, u, z, settings, failures) -> list:
    """``(label, score, fitted)`` of `_set_cv` for each step's effect set, the sets
    cross-validated by ``settings.n_jobs`` processes (each set's folds in its own one)."""
    labels = [_label(board.ordered(effects)) for effects, _, _ in steps]
    alone = replace(settings, n_jobs=None, release_programs=False)  # released per set
    arguments = [(board, effects, warm, u, z, alone) for effects, warm, _ in steps]

    def progress(k, _):
        logger.info("  CV of %s (%d of %d)", labels[k - 1], k, len(labels))

    jobs = launch(_set_cv_alone, arguments, *_processes(settings))
    outcomes = gather(jobs, progress=progress)
    failures.extend(line for _, _, lines in outcomes for line in lines)
    scores = [(label, *outcome[:2]) for label, outcome in zip(labels, outcomes, strict=True)]
    return _released(settings, scores)


def _set_cv_alone(board, effects, warm, u, z, settings):
    """`_set_cv` with failures of its own: ``(score, fitted, failures)``."""
    failures = []
    score, fitted = _set_cv(board, effects, warm, u, z, settings, failures)
    return score, fitted, failures


def _attempt(failures: list, label: str, function, *args):
    """``function(*args)``; a failure becomes a line of ``failures`` (and ``None``), and
    warnings are re-issued prefixed with ``label``."""
    return _attempt_all(failures, [(label, function, *args)])[0]


def _trying(function, *args):
    """``(function(*args), None)``, or ``(None, message)`` when it raises a fit error."""
    try:
        return function(*args), None
    except FIT_ERRORS as error:
        return None, str(error)


def _attempt_all(
    failures: list, calls, settings: LoopSettings | None = None, first: int = 1, total=None
) -> list:
    """`_attempt` of each ``(label, function, *args)`` of ``calls``, the calls run by
    ``settings.n_jobs`` processes (this one without ``settings``); values in order
    (``None`` where a call failed). Each value is logged as it arrives when there are
    several, as the ``first``-th, ... of ``total`` (default: of ``calls``)."""
    if not calls:
        return []  # no worker started for nothing
    labels = [call[0] for call in calls]
    total = len(calls) if total is None else total

    def progress(k, label):
        logger.info("  %s (%d of %d)", label, first + k - 1, total)

    jobs = launch(_trying, [call[1:] for call in calls], *_processes(settings))
    outcomes = gather(jobs, labels, progress if total > 1 else None)
    for label, (_, error) in zip(labels, outcomes, strict=True):
        if error is not None:
            failures.append(f"{label}: {error}")
    return [value for value, _ in outcomes]


def _fit_delta(physics, library, u, z, settings, evidence=None, targets=None):
    """Physics + δ on the support path, γ chosen by CV RMSE; the fitted estimator and the
    path (``None`` for a single γ, fitted directly). ``evidence``, an estimator with the
    same settings fitted to its physics-only stage, is refitted along the path, which then
    reuses that stage (the estimator's cache) instead of computing it again. ``targets``:
    the estimator's ``delta_states`` and ``delta_outputs`` (default: the settings'
    ``delta_states``)."""
    targets = targets or {"delta_states": settings.delta_states}
    est = evidence or _estimator(physics, settings, cv=True, library=library, **targets)
    if settings.gammas is not None and len(settings.gammas) == 1:
        est.set_params(gamma=settings.gammas[0], horizon=settings.horizon)
        return fit_continued(est, u, z, settings.horizon), None
    path = fit_gamma_path(
        est,
        u,
        z,
        settings.gammas,
        n_gammas=settings.n_gammas,
        eps=settings.gamma_eps,
        cv=held_out_splits(settings, len(u)),
        init_window=settings.init_window,
        n_jobs=settings.n_jobs,
        one_standard_error=settings.one_standard_error,
    )
    return path.estimator, path


def _evidence(physics, library, u, z, settings) -> GreyBoxSparseRegressor:
    """The physics-only fit on the whole record with the dictionary's evidence."""
    est = _estimator(physics, settings, library=library, delta_states=settings.delta_states)
    return est.set_params(horizon=None)._fit(u, z, None, reference_only=True)


def _rmse(outputs, z: np.ndarray) -> float:
    """RMSE of simulated ``outputs`` against ``z`` (2-D); ``inf`` for a diverged simulation."""
    with np.errstate(over="ignore", invalid="ignore"):
        error = np.reshape(outputs, z.shape) - z
        value = float(np.sqrt(np.mean(error**2)))
    return value if np.isfinite(value) else np.inf


def _effect_parameters(est, effects) -> dict:
    """The fitted free parameters of ``effects`` in ``est``, as
    [`Parameter`][sk_offwhite.Parameter]."""
    return {
        name: Parameter(est.parameters_[name], spec.bounds)
        for effect in effects
        for name, spec in effect.parameters().items()
        if not spec.fixed
    }


def _declared_parameters(est, board) -> dict:
    """The fitted free parameters of ``board``'s declared physics (none of a candidate
    effect's), as [`Parameter`][sk_offwhite.Parameter] with the declared bounds."""
    switched = {name for effect in getattr(board, "board", ()) for name in effect.parameters()}
    return {
        name: Parameter(est.parameters_[name], spec.bounds)
        for name, spec in board.physics.parameters.items()
        if not spec.fixed and name not in switched and name in est.parameters_
    }


def _quick_fit(board, effects, warm, u, z, settings):
    """``(estimation RMSE, fitted parameters)`` of the physics plus ``effects`` (switched on
    on ``board``), fitted as the set is kept (`_fit_set`: over ``horizon`` windows,
    then on the whole record) and scored by the free run of the record. The parameters are
    those of ``effects`` and of the declared physics: a set is refitted and
    cross-validated from where its own fit ended, since an effect may move the declared
    parameters far (a sensor calibration rescales the levels the outflow laws act on).

    Every set ends on the whole record, the protocol it is scored by: a set with an effect
    on the output map is fitted there alone (`_set_horizon`), and against fits that
    stopped at the windows it won by its protocol, not its effect (the Coulomb drive of
    [`make_coulomb_drive`][sk_offwhite.datasets.make_coulomb_drive]: a sensor calibration displaced
    the constant force, the declared stiffness came back 4 % off). Fitted on the whole record
    alone, without the windows, the ranking was fair but not robust: the same drive with
    ``max_iter=1000`` came back with a Coulomb level of 1.30 for 3.

    A proposed effect the record never exercises runs its level off toward infinity (the
    Cascaded Tanks' pump limits, to 10¹¹-10⁴¹ V): that is the ranking's finding, the set
    scoring as the one without it, so these fits do not raise
    [`RunawayParameterWarning`][sk_offwhite.RunawayParameterWarning]; the declared physics' fit and
    the final model's do."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunawayParameterWarning)
        est = _fit_set(_estimator(board.model(effects, warm), settings), effects, u, z, settings)
    fitted = {**_declared_parameters(est, board), **_effect_parameters(est, effects)}
    return _rmse(est.predict(u), z), fitted


def _set_horizon(effects, horizon: int | None) -> int | None:
    """The shooting window of a set's fit: ``None`` (the whole record from one initial
    state) when an effect of the set acts on the output map, ``horizon`` otherwise.

    With free initial states at every window, a calibration of the output can carry the
    record while the state equations do nothing: on the Cascaded Tanks with
    ``max_iter=1000`` the set of two overflows and a sensor calibration ended at a pump
    gain of 0 and calibration coefficients of -5·10⁴ (CV 1.36 against 0.17), and the loop
    added no effect. Simulated from one initial state, the state must follow the input."""
    return None if any(effect.target == "output" for effect in effects) else horizon


def _fit_set(est: GreyBoxSparseRegressor, effects, u, z, settings: LoopSettings):
    """[`fit_continued`][sk_offwhite.loop.fit_continued] of ``est`` (the physics with ``effects``)
    over the set's shooting window (`_set_horizon`): how an effect set and the final augmented
    physics are fitted on the record."""
    return fit_continued(est, u, z, _set_horizon(effects, settings.horizon))


def _starts(warm: dict, effect, params: dict) -> list[dict]:
    """Starts of a set that gains ``effect``: the set's parameters ``warm``, with the
    effect's from its fit alone (``params``) and from its proposal (values from the data).
    Fitted alone, an effect may take values that only make sense without the others (a
    sensor calibration absorbing what an overflow explains)."""
    alone, proposed = _own(params, effect), effect.parameters()
    return [{**warm, **alone}] + ([{**warm, **proposed}] if alone != proposed else [])


def _best_of(board, sets, u, z, settings, failures) -> list:
    """For each ``(effects, starts)`` of ``sets``, the `_quick_fit` of lowest
    estimation RMSE over its starts (``None`` if every one fails); all the fits run by
    ``settings.n_jobs`` processes."""
    calls = [
        ("effects " + _label(effects), _quick_fit, board, effects, start, u, z, settings)
        for effects, starts in sets
        for start in starts
    ]
    outcomes = iter(_attempt_all(failures, calls, settings))
    best = []
    for _, starts in sets:
        fits = [fit for fit in (next(outcomes) for _ in starts) if fit is not None]
        best.append(min(fits, key=lambda fit: fit[0]) if fits else None)
    return best


def _own(params: dict, effect) -> dict:
    """The entries of ``params`` that are ``effect``'s own parameters."""
    names = effect.parameters()
    return {name: value for name, value in params.items() if name in names}


def _without(params: dict, effect) -> dict:
    """The entries of ``params`` that are not ``effect``'s own parameters."""
    names = effect.parameters()
    return {name: value for name, value in params.items() if name not in names}


def _rank_alone(physics, candidates, u, z, settings, failures):
    """``(estimation RMSE, candidate, fitted effect parameters)`` of each candidate added
    to ``physics`` alone, best first (``inf`` and a line in ``failures`` where the fit
    failed); a named effect ranks before a promoted term unless the term is better by
    ``tolerance``.

    The candidates are fitted on a switchboard where they can share one
    (`single_effect_models`; with ``share_programs``
    all on one), in this process: each fit compiles nothing after the first, and a
    worker would compile the board's programs again for itself. The others are fitted by
    ``settings.n_jobs`` processes, each on its own model."""
    effects = [c.effect for c in candidates]
    if settings.share_programs:
        models = [effect_sets(physics, effects, True)] * len(effects)
    else:
        models = single_effect_models(physics, effects)
    calls = [
        (f"candidate {effect.name}", _quick_fit, model, (effect,), {}, u, z, settings)
        for effect, model in zip(effects, models, strict=True)
    ]
    on_board = [isinstance(model, Switchboard) for model in models]
    fitted = _attempt_split(failures, calls, on_board, settings)
    ranked = [
        (np.inf, candidate, {}) if fit is None else (fit[0], candidate, fit[1])
        for candidate, fit in zip(candidates, fitted, strict=True)
    ]
    return sorted(ranked, key=lambda item: item[0] * _handicap(item[1].effect, settings))


def _attempt_split(failures: list, calls, here, settings: LoopSettings) -> list:
    """`_attempt_all` of ``calls``, those where ``here`` is true in this process and
    the others by ``settings.n_jobs`` processes; values in the order of ``calls``."""
    local = [call for call, flag in zip(calls, here, strict=True) if flag]
    remote = [call for call, flag in zip(calls, here, strict=True) if not flag]
    total = len(calls)
    mine = iter(_attempt_all(failures, local, None, total=total))
    theirs = iter(_attempt_all(failures, remote, settings, first=len(local) + 1, total=total))
    return [next(mine) if flag else next(theirs) for flag in here]


def _handicap(effect, settings) -> float:
    """A promoted dictionary term must beat a named effect by ``tolerance`` to rank first."""
    return 1.0 + settings.tolerance if isinstance(effect, DictionaryTerm) else 1.0


def _forward(board, ranked, u, z, settings, base_rmse, failures):
    """Forward selection: ``[(effects, warm parameters, estimation RMSE)]`` for each step.

    The pool holds the ``beam`` best candidates alone of distinct mechanisms (one variant
    of each, `_representatives`; a set never holds two variants of one) and
    every relaxed declared law ([`RelaxedLaw`][sk_offwhite.RelaxedLaw]): a law the user marked
    relaxable is always tried on top of the effects chosen so far, whose absence may be
    what made it look useless alone.
    """
    finite = [item for item in ranked if np.isfinite(item[0])]
    fitted = [(c.effect, p, r) for r, c, p in _representatives(finite, settings.tolerance)]
    laws = [item for item in fitted[settings.beam :] if item[0].target == "law"]
    pool = fitted[: settings.beam] + laws
    steps, current, current_rmse = [], [], base_rmse
    if pool and pool[0][2] <= (1.0 - settings.min_gain) * base_rmse:
        steps.append(((pool[0][0],), pool[0][1], pool[0][2]))
        current, current_rmse = [pool[0][0]], pool[0][2]
    else:
        pool, steps = [], _best_pair(board, pool[:3], u, z, settings, base_rmse, failures)
        if steps:
            current, current_rmse = list(steps[0][0]), steps[0][2]
    while len(current) < settings.max_effects:
        taken = {mechanism(effect) for effect in current}
        added = [(effect, params) for effect, params, _ in pool if mechanism(effect) not in taken]
        calls = [
            ("effects " + _label((*current, effect)), _quick_fit, board, (*current, effect),
             {**steps[-1][1], **_own(params, effect)}, u, z, settings)
            for effect, params in added
        ]  # fmt: skip
        fitted = _attempt_all(failures, calls, settings)
        trials = [
            (f[0], effect, f[1])
            for (effect, _), f in zip(added, fitted, strict=True)
            if f is not None
        ]
        if not trials:
            break
        rmse, effect, params = min(trials, key=lambda t: t[0] * _handicap(t[1], settings))
        if rmse > (1.0 - settings.min_gain) * current_rmse:
            break
        current, current_rmse = [*current, effect], rmse
        steps.append((tuple(current), params, rmse))
    return steps


def _representatives(ranked, tolerance: float) -> list:
    """``ranked`` (``(RMSE, candidate, parameters)``, best first) with one variant per
    mechanism (`mechanism`), in the place of the mechanism's
    best: the variant with the fewest parameters among those within ``tolerance`` of that
    best (an overflow whose excess leaves the system rather than one with a fitted
    fraction, unless the fraction is worth it)."""
    groups: dict[str, list] = {}
    for item in ranked:
        groups.setdefault(mechanism(item[1].effect), []).append(item)
    return [min(_within(group, tolerance), key=_n_parameters) for group in groups.values()]


def _within(group, tolerance: float) -> list:
    """The items of ``group`` (best first) whose RMSE is within ``tolerance`` of the first."""
    return [item for item in group if item[0] <= group[0][0] * (1.0 + tolerance)]


def _n_parameters(item) -> int:
    return _size((item[1].effect,))


def _best_pair(board, pool, u, z, settings, base_rmse, failures):
    """When no candidate helps alone: the best pair of the ``pool`` if it helps."""
    best = None
    for a in range(len(pool)):
        for b in range(a + 1, len(pool)):
            effects = (pool[a][0], pool[b][0])
            label = "effects " + " + ".join(e.name for e in effects)
            warm = {**pool[a][1], **_own(pool[b][1], pool[b][0])}
            fitted = _attempt(failures, label, _quick_fit, board, effects, warm, u, z, settings)
            if fitted is not None and (best is None or fitted[0] < best[2]):
                best = (effects, fitted[1], fitted[0])
    if best is None or best[2] > (1.0 - settings.min_gain) * base_rmse:
        return []
    return [best]


def _nested(ranked, base_rmse, settings):
    """The nested sets of the candidates that helped alone, in the order of their gain
    (the declared parameters start from the first one's fit, each effect from its own)."""
    helped = [item for item in ranked if item[0] < base_rmse]
    kept = [(c.effect, p) for _, c, p in _representatives(helped, settings.tolerance)]
    kept = kept[: settings.max_effects]
    return [
        (
            tuple(e for e, _ in kept[:k]),
            {**kept[0][1], **{n: p for e, ps in kept[1:k] for n, p in _own(ps, e).items()}},
            None,
        )
        for k in range(1, len(kept) + 1)
    ]


def _capped(candidates: list, limit: int | None) -> list:
    """The candidates of the first ``limit`` mechanisms
    (`mechanism`) in the order proposed, every variant of those
    mechanisms included: a cap counts what is tried, not how many shapes of it are (a saturation's
    two, an overflow's destinations), so proposing one more variant does not push another effect
    out."""
    if limit is None:
        return list(candidates)
    kept, mechanisms = [], []
    for candidate in candidates:
        kind = mechanism(candidate.effect)
        if kind not in mechanisms and len(mechanisms) < limit:
            mechanisms.append(kind)
        if kind in mechanisms:
            kept.append(candidate)
    return kept


def _best_starts(board, steps, u, z, settings, failures) -> list:
    """``steps`` with each effect set that more than one step reaches from different
    starts (forward selection and the nested sets) fitted from all of them, the step
    keeping the fit of lowest estimation RMSE (in the place of its first occurrence).

    The loop's cost is not convex in the effects' parameters: one set started from the
    parameters forward selection carried and from the effects' own fits lands in
    different minima (measured on the Cascaded Tanks: a sensor calibration added to two
    overflows, estimation RMSE 2.17 and 0.142), and which step came first must not decide
    which one is cross-validated."""
    groups: dict[frozenset, list] = {}
    for step in steps:
        groups.setdefault(frozenset(e.name for e in step[0]), []).append(step)
    several = [g for g in groups.values() if len({_start_key(s[1]) for s in g}) > 1]
    fitted = _best_of(board, [(g[0][0], [s[1] for s in g]) for g in several], u, z, settings,
                      failures)  # fmt: skip
    best = {id(g[0]): (g[0][0], fit[1], fit[0]) for g, fit in zip(several, fitted, strict=True)
            if fit is not None}  # fmt: skip
    return [best.get(id(step), step) for step in steps]


def _start_key(start: dict) -> str:
    """A start's parameter values, comparable between steps."""
    return repr(sorted((name, repr(value)) for name, value in start.items()))


def _by_size(steps):
    """``steps`` without repeated effect sets, smallest sets first (stable)."""
    unique = {}
    for step in steps:
        unique.setdefault(frozenset(e.name for e in step[0]), step)
    return sorted(unique.values(), key=lambda step: len(step[0]))


def _smallest_within(scores: list[float], tolerance: float) -> int:
    """Index of the first score within ``tolerance`` (relative) of the smallest."""
    best = min(scores)
    return next(k for k, s in enumerate(scores) if s <= best * (1.0 + tolerance))


def _select_effects(
    physics, candidates, u, z, settings, base_rmse, failures=None, declared_cv=None
):
    """Effect sets by forward selection and nested by single gain, chosen by CV RMSE.

    A set's effects are composed in the order of the single fits; with ``share_programs``
    all sets are fitted on one `Switchboard`.
    Returns the chosen effects (in that order), the CV trail (starting with
    ``declared_cv``, computed when ``None``), the single-fit RMSEs, the effects' fitted
    parameters (the start of the final fit) and each set's fit on the whole record by
    the trail's labels.
    """
    failures = [] if failures is None else failures
    if declared_cv is None:
        declared_cv = cross_validated_rmse(physics, u, z, settings)
    candidates = _capped(candidates, settings.max_candidates)
    shared = settings.share_programs
    ranked = _released(settings, _rank_alone(physics, candidates, u, z, settings, failures))
    # sets compose their effects in the order of the single fits (best first)
    board = effect_sets(physics, _with_richer([c.effect for _, c, _ in ranked]), shared)
    singles = [(c.effect.name, r) for r, c, _ in ranked]
    steps = _released(settings, _forward(board, ranked, u, z, settings, base_rmse, failures))
    steps = _by_size(_best_starts(board, steps + _nested(ranked, base_rmse, settings), u, z,
                                  settings, failures))  # fmt: skip
    trail, fits = [("declared physics", declared_cv)], {}
    for label, score, fitted in _sets_cv(board, steps, u, z, settings, failures):
        fits[label] = fitted
        trail.append((label, score))
    k = _smallest_within([s for _, s in trail], settings.tolerance)
    if k == 0 or trail[k][1] > (1.0 - settings.min_gain) * trail[0][1]:
        return (), trail, singles, {}, fits
    chosen, warm, _ = steps[k - 1]
    chosen, warm, rows = _swap(board, ranked, (chosen, warm, trail[k][1]), u, z, settings,
                               failures, fits)  # fmt: skip
    rescored = {label for label, _ in rows}
    trail = [row for row in trail if row[0] not in rescored] + rows
    return board.ordered(chosen), trail, singles, warm, fits


def _with_richer(effects) -> list:
    """``effects`` with each one's richer variant (`richer`)
    right after it: the sets the refinement may reach."""
    pairs = ((effect, richer(effect)) for effect in effects)
    return [variant for pair in pairs for variant in pair if variant is not None]


class _Chosen(NamedTuple):
    """A set the refinement starts a round from: its effects, their parameters, its CV
    RMSE and its `_quick_fit` (``None``: not made yet)."""

    effects: tuple
    params: dict
    cv: float
    fit: tuple | None = None


def _swap(board, ranked, chosen, u, z, settings, failures, fits):
    """Stepwise refinement of the chosen set, in rounds (`_swap_round`) until a round
    keeps its set or reaches one an earlier round left: the set a move reached is refined
    in turn (on the Cascaded Tanks the first round adds the sensor calibration to three
    effects, the second refines it into the cubic one). Every kept move lowers the CV
    RMSE by ``min_gain`` or makes the set smaller, so the rounds end.

    ``chosen``: ``(effects, parameters, CV RMSE)`` of the set (a `_Chosen`). Returns
    the effects, their parameters and the CV trail rows of the moves tried (their fits on
    the whole record are added to ``fits``).
    """
    chosen, rows, left = _Chosen(*chosen), [], set()
    while True:
        left.add(frozenset(chosen.effects))
        reached, tried = _swap_round(board, ranked, chosen, u, z, settings, failures, fits)
        rows += tried
        if reached.effects is chosen.effects or frozenset(reached.effects) in left:
            return chosen.effects, chosen.params, rows
        chosen = reached


def _swap_round(board, ranked, chosen: _Chosen, u, z, settings, failures, fits):
    """One round of the stepwise refinement of the chosen set: each other candidate of the
    ``beam`` added to it (while it has fewer than ``max_effects``) or exchanged for one of
    its effects, each of its effects exchanged for its richer variant
    (`_refinements`), and each of its effects dropped, started from the set's
    parameters. An addition or exchange whose fit lowers the estimation RMSE (by
    ``min_gain`` for an addition), and a removal, or an exchange for an effect of fewer
    parameters, whose fit on the whole record misses the data by no more than the chosen
    set's CV RMSE allows a lighter set (``tolerance``), are cross-validated, and the best
    is kept when its CV RMSE is lower by ``min_gain``. The
    removal's bar rests on the error a model makes on the data it was fitted to being an
    optimistic estimate of its held-out error (measured on the Cascaded Tanks: the two
    removals the bar excludes had CV RMSEs 38 and 18 times the chosen set's, and took 7 of
    the loop's 31 s). Greedy forward selection misses a set whose members help only in each
    other's company, reached through another order (a nonlinear sensor that needs the levels
    an overflow leaves). When no move improves, the best lighter set (fewer parameters)
    whose CV RMSE is within ``tolerance`` is kept: an effect whose fitted parameters make it
    vanish, or that another effect made redundant, is not carried into the final model, and
    of two effects that fit alike the one of fewer parameters is (a relaxed declared law
    rather than an added loss).

    Returns the set reached (``chosen`` itself when no move is kept) and the CV trail rows
    of the moves tried (their fits on the whole record are added to ``fits``).
    """
    effects, warm, cv, base = chosen
    if base is None:
        base = _attempt(failures, "effects " + _label(effects), _quick_fit, board, effects,
                        warm, u, z, settings)  # fmt: skip
    if base is None:
        return chosen, []
    rows, best = [], _Chosen(effects, warm, (1.0 - settings.min_gain) * cv, base)
    lighter = _Chosen(effects, warm, (1.0 + settings.tolerance) * cv, base)
    moves = []  # each to beat its bar and the earlier fit of its set, if any
    for trial, starts, bar in _moves(effects, warm, ranked, base[0], lighter.cv, settings,
                                     board):  # fmt: skip
        earlier = _earlier_rmse(fits, board, trial, u, z)
        if _worth_fitting(trial, effects, base[0], earlier):
            moves.append((trial, starts, min(bar, earlier)))
    fitted = _best_of(board, [(trial, starts) for trial, starts, _ in moves], u, z, settings,
                      failures)  # fmt: skip
    passed = [
        (trial, fit[1], fit)
        for (trial, _, bar), fit in zip(moves, fitted, strict=True)
        if fit is not None and fit[0] < bar
    ]
    for (trial, params, quick), (label, score, fit) in zip(
        passed, _sets_cv(board, passed, u, z, settings, failures), strict=True
    ):
        fits[label] = fit
        rows.append((label, score))
        if score < best.cv:
            best = _Chosen(trial, params, score, quick)
        elif _size(trial) < _size(effects) and score <= lighter.cv:
            lighter = _Chosen(trial, params, score, quick)
    if best.effects is not effects:
        return best, rows
    return (lighter if lighter.effects is not effects else chosen), rows


def _size(effects) -> int:
    """The number of parameters ``effects`` add: what makes a set lighter."""
    return sum(len(effect.parameters()) for effect in effects)


def _earlier_rmse(fits, board, effects, u, z) -> float:
    """Estimation RMSE of the earlier fit of ``effects`` that was cross-validated (``inf``
    when none was, or when it failed)."""
    earlier = fits.get(_label(board.ordered(effects)))
    return np.inf if earlier is None else _rmse(earlier.predict(u), z)


def _worth_fitting(trial, effects, rmse: float, earlier: float) -> bool:
    """Whether a move of the refinement from ``effects`` (estimation RMSE ``rmse``) to
    ``trial`` is fitted, given the estimation RMSE ``earlier`` of the set's earlier fit
    (`_earlier_rmse`): a set not cross-validated yet, or an addition whose earlier
    fit missed the record by more than ``effects`` does. A set holding ``effects`` can fit
    the record at least as well as they do; when its fit did not, that fit ended in a poor
    minimum, and the set is fitted again from the chosen set's parameters (and scored
    again if it then fits the record better than before). Measured on the Cascaded Tanks
    with an earlier form of the sensor step: added to two overflows before the
    calibration, CV 2.66; added to the three effects, 0.115. The order the sets were
    reached in must not decide which of their fits is judged."""
    return earlier == np.inf or (len(trial) > len(effects) and earlier > rmse)


def _moves(effects, warm, ranked, rmse, lighter, settings, board):
    """``(effects, starts, RMSE to beat)`` of each addition and exchange of the beam's
    other named effects (see `_starts`) and of each refinement
    (`_refinements`), to beat the set's estimation RMSE ``rmse``, then of each
    removal, to beat ``lighter`` (the bar of a smaller set).
    Promoted dictionary terms are left to forward selection, where they must beat a named
    effect by ``tolerance``: a term can always absorb a little more, and would take the
    place of the effect it resembles."""
    yield from _additions_and_exchanges(effects, warm, ranked, rmse, lighter, settings)
    yield from _refinements(effects, warm, rmse, board)
    if len(effects) > 1:
        for out in effects:
            kept = _without(warm, out)
            yield tuple(e for e in effects if e != out), [kept], lighter


def _additions_and_exchanges(effects, warm, ranked, rmse, lighter, settings):
    """The additions and exchanges of `_moves` (a set never holds two variants of
    one mechanism). An exchange for an effect of fewer parameters makes a lighter set, and
    has the bar of one (``lighter``, when it is above ``rmse``): on the convective block
    with its exponent declared relaxable, the relaxed law fitted 0.02 % worse than the
    loss of fitted power the loop had added, and was never cross-validated."""
    pool = [
        (c.effect, p)
        for _, c, p in _representatives(ranked, settings.tolerance)[: settings.beam]
        if c.effect not in effects and not isinstance(c.effect, DictionaryTerm)
    ]
    taken = {mechanism(e) for e in effects}
    for effect, params in pool:
        if len(effects) < settings.max_effects and mechanism(effect) not in taken:
            gain = (1.0 - settings.min_gain) * rmse
            yield (*effects, effect), _starts(warm, effect, params), gain
        for out in effects:
            rest = tuple(e for e in effects if e != out)
            if mechanism(effect) in {mechanism(e) for e in rest}:
                continue
            kept = _without(warm, out)
            bar = max(rmse, lighter) if _size((effect,)) < _size((out,)) else rmse
            yield (*rest, effect), _starts(kept, effect, params), bar


def _refinements(effects, warm, rmse, board):
    """``(effects, starts, RMSE to beat)`` with one effect exchanged for its richer
    variant, started where it reproduces the effect (`richer`,
    `richer_start`): the variant nests the effect, so its fit
    on the record can only match or lower ``rmse``, and the cross-validation decides
    whether the extra freedom is worth ``min_gain``. Only the variants on the ``board``
    (`_with_richer`: one step richer than each proposed effect)."""
    for effect in effects:
        variant = richer(effect)
        if variant is None or not board.ordered((variant,)):
            continue
        rest = tuple(e for e in effects if e != effect)
        kept = _without(warm, effect)
        start = richer_start(effect, {**effect.parameters(), **warm})
        yield (*rest, variant), [{**kept, **start}], rmse


def _delta_cv(est, path: GammaPath | None, u, z, settings) -> float:
    """CV RMSE of a fitted model with δ at its chosen γ, scored as the trail is: the mean
    over folds of the path's own fits at that γ (the same fits on the same blocks, scored
    the same way when a block is at least twice ``init_window`` long), or, without a path
    (a single γ), the folds fitted now."""
    if path is not None and path.cv_rmse is not None:
        return float(np.mean(path.cv_rmse[path.best_index]))
    template = clone(est).set_params(horizon=settings.cv_horizon)
    return _cv_rmse(template, u, z, settings)


def _choose(cv_errors: dict, models: dict, notes: list) -> str:
    """Key of the lowest finite CV error (``"baseline"`` when none is finite) among the
    ``models`` that are models of their own: a fit with δ that kept no term is the physics
    it corrects, refitted, and its score (from other fold fits) does not stand for a
    different model; a note says so."""
    empty = [k for k, est in models.items() if est is not None and _empty_delta(est)]
    for key in empty:
        notes.append(
            f"{MODEL_LABELS[key]} kept no term (it is the physics it corrects): not chosen "
            f"on its own score ({cv_errors.get(key, np.inf):.4g})."
        )
    finite = {k: v for k, v in cv_errors.items() if np.isfinite(v) and k not in empty}
    return min(finite, key=finite.get) if finite else "baseline"


def _empty_delta(est) -> bool:
    """Whether ``est`` was fitted with a dictionary and kept none of its terms."""
    return est.library is not None and est.n_nonzero_ == 0


def _candidates(physics, library, hypotheses, facts, run, u, z, settings):
    """Catalogue effects and promoted dictionary terms, one per name, without those of a
    mechanism the physics already models (`_not_modelled`)."""
    dt = time_step(physics)
    names = list(physics.state_names) + list(physics.input_names)
    n_declared, kinds = _declared_kinds(physics)
    found = propose_effects(
        [h for h in hypotheses if h.equation_index < n_declared],
        [fact for fact in facts if isinstance(fact, RangeViolation)],
        physics.state_names[:n_declared],
        _output_names(physics, run.outputs.shape[1]),
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
    promoted = _promoted(physics, hypotheses, library, names, dt, settings)
    return _not_modelled(physics, unique_by_name(found + promoted + declared))


def _declared_kinds(physics) -> tuple[int, Kinds]:
    """The number of declared states and their kinds (`physical_kinds`), the hidden
    states' left out: effects act on declared states only. An effect's hidden states are
    no levels or velocities of the plant; on a physics with a dead time, whose 25 past
    commands of a one-signed generic input read as levels, the overflows between them
    alone made 600 candidates that act on nothing."""
    n_declared = n_declared_states(physics)
    kinds = physical_kinds(physics)
    partner = {v: p for v, p in kinds.partner.items() if max(v, p) < n_declared}
    return n_declared, kinds._replace(states=kinds.states[:n_declared], partner=partner)


def _promoted(physics, hypotheses, library, names, dt: float, settings) -> list:
    """The strongest dictionary terms as candidates
    ([`promoted_terms`][sk_offwhite.loop.promoted_terms]), none on a physics with hidden states (an
    effect with memory, `sk_offwhite.effects._hidden`): the dictionary reads the commands, where a
    term in the declared step would read the input the effects deliver (a backlash's, a delay's),
    another function."""
    if physics.n_states > n_declared_states(physics):
        return []
    return promoted_terms(hypotheses, library, names, dt, settings.n_promoted)


def _not_modelled(physics, candidates: list) -> list:
    """``candidates`` without those whose mechanism (`mechanism`)
    an effect of ``physics`` already models: run on an augmented physics (its own result,
    say), the loop would otherwise propose an effect it holds, whose parameters clash with
    its own, or a second variant of one mechanism, which no effect set may hold."""
    modelled = {mechanism(effect) for effect in getattr(physics, "effects", ())}
    return [c for c in candidates if mechanism(c.effect) not in modelled]


def _read_evidence(physics, library, u, z, settings, failures):
    """The physics-only fit with the dictionary's evidence and its hypotheses."""
    evidence = _attempt(failures, "evidence", _evidence, physics, library, u, z, settings)
    if evidence is None:
        return None, []
    run = evidence.simulate(u)
    return evidence, evidence_hypotheses(evidence, run, u, min_share=settings.min_share)


def _scored_delta(key, physics, library, u, z, settings, failures, evidence=None, targets=None):
    """``(estimator, path, CV RMSE)`` of ``physics`` + δ (``None, None, inf`` on failure);
    ``targets`` as for `_fit_delta`."""
    fitted = _attempt(
        failures, MODEL_LABELS[key], _fit_delta, physics, library, u, z, settings, evidence,
        targets,
    )  # fmt: skip
    if fitted is None:
        return None, None, np.inf
    label = f"CV of {MODEL_LABELS[key]}"
    cv = _attempt(failures, label, _delta_cv, fitted[0], fitted[1], u, z, settings)
    return fitted[0], fitted[1], np.inf if cv is None else cv


def _scored_output_delta(physics, fitted, measured, u, z, settings, failures, notes):
    """``(estimator, path, CV RMSE)`` of ``physics`` + a sparse correction of every output,
    each measuring the state ``measured[i]`` (``None``: the output map is not a reading of
    states, and a note says the stage was skipped), on the bumps of the measured states
    over the range ``fitted`` simulates."""
    key = "final_with_output_delta"
    if measured is None:
        notes.append(f"{MODEL_LABELS[key]} not fitted: the outputs do not read states directly.")
        return None, None, np.inf
    label = f"dictionary of {MODEL_LABELS[key]}"
    library = _attempt(failures, label, _output_library, fitted, u, measured, settings)
    if library is None:
        return None, None, np.inf
    targets = {"delta_states": (), "delta_outputs": tuple(range(len(measured)))}
    return _scored_delta(key, physics, library, u, z, settings, failures, None, targets)


def _output_library(fitted, u, measured, settings) -> RadialBasis:
    """Gaussian bumps of the ``measured`` states over the range of ``fitted``'s free run."""
    states = np.asarray(fitted.simulate(u).states, float)
    columns = sorted(set(int(i) for i in measured))
    names = [fitted.physics_.state_names[i] for i in columns]
    return RadialBasis.from_data(states[:, columns], names, n_bumps=settings.output_bumps)


def _delta_hypotheses(est, u, cv, declared_cv, settings, notes):
    """The hypotheses of the declared physics + δ when it beats the declared physics under
    CV by ``min_gain``; else a note says why there are none."""
    if est is None:
        return []
    if not cv < (1.0 - settings.min_gain) * declared_cv:
        notes.append(
            f"{MODEL_LABELS['with_delta']} does not beat the declared physics under CV "
            f"({cv:.4g} against {declared_cv:.4g}): no hypothesis is read from its correction."
        )
        return []
    return form_hypotheses(est, est.simulate(u), u)


def _fit_declared(physics, u, z, settings):
    """The declared physics fitted (multiple shooting, then whole), the physics started from
    that fit, its free run and its CV RMSE."""
    workers = start_workers(settings.n_jobs)  # they start while this process fits
    try:
        baseline = fit_continued(_estimator(physics, settings), u, z, settings.horizon)
    finally:
        gather(workers)
    start, reset = _start_of_later_fits(physics, baseline, u, z)
    declared_cv = cross_validated_rmse(start, u, z, settings)
    return baseline, start, baseline.simulate(u), declared_cv, reset


def _start_of_later_fits(physics, baseline: GreyBoxSparseRegressor, u, z):
    """The physics started from the declared fit ([`warm_physics`][sk_offwhite.loop.warm_physics]),
    but for the parameters that fit does not determine, which start from their declared values; and
    ``{name: fitted value}`` of those.

    Along a flat direction the fitted point is arbitrary, and a parameter that ran off
    toward a limit can leave the later fits no way back: the RC circuit behind a diode
    ([`make_diode_rc`][sk_offwhite.datasets.make_diode_rc]) fitted its load's time constant to
    3.7·10²⁴ s (the charging path's loss mimicked the load), where the curve no longer
    depends on it, and from there the loop added a promoted ``e**2`` term (validation
    0.86 V) instead of the diode's drop (0.020 V from the declared 0.075 s)."""
    start = warm_physics(physics, baseline)
    reset = {  # the names are the free parameters and initial states ("x1(0)")
        name: baseline.parameters_[name]
        for name in _undetermined(baseline, u, z)
        if name in physics.parameters
    }
    return start.with_parameters(**{name: physics.parameters[name] for name in reset}), reset


HOLD_SLACK = 1e-3
"""The relative rise of the estimation RMSE a fit with a parameter held on an undetermined
direction may show (holding it there leaves the fit as it was, up to rounding)."""


def _held_on_fit(physics, est: GreyBoxSparseRegressor, u, z, effects) -> tuple[dict, tuple]:
    """``(held, directions)``: the directions of ``est``'s fit (of ``physics``, ``effects``
    added) the data do not determine (`undetermined_directions`;
    none when they cannot be computed) and ``{name: fitted value}`` of the parameter held
    on each (`held_parameters`)."""
    try:
        directions = fit_undetermined_directions(est, u, z)
    except FIT_ERRORS:
        directions = ()
    return held_parameters(directions, physics, effects, est.parameters_), directions


def hold_undetermined_directions(
    physics, est: GreyBoxSparseRegressor, u, z, *, effects=None, settings=None, cv=None,
    failures=None, held_cv=None,
):  # fmt: skip
    r"""Hold a parameter on each direction of an augmented physics' fit that the data do
    not determine.

    Where an added effect leaves a direction along which the relative standard error of
    the fit is at least `MAX_RELATIVE_ERROR`, or its
    Gauss-Newton matrix singular (a calibrated level whose scale nothing else fixes: see
    `_gauge`), the added effect's parameter that loads most on the
    direction is fixed at its fitted value, and the physics is refitted from ``est`` as
    the loop fits an effect set and cross-validated. The fit is kept when its estimation
    RMSE rose by at most `HOLD_SLACK` and its CV RMSE by at most
    ``settings.tolerance`` over ``cv`` (a model with fewer free parameters is preferred
    within it, as a smaller effect set is).

    Parameters
    ----------
    physics : PhysicsModel
        The augmented physics ``est`` was fitted with.
    est : GreyBoxSparseRegressor
        Its fit on ``(u, z)``.
    u, z : ndarray
        The estimation record.
    effects : sequence of Effect, default=None
        The added effects (``physics.effects`` when ``None``): only their parameters are
        held.
    settings : LoopSettings, default=None
        The fits' and the CV's settings (``LoopSettings()`` when ``None``).
    cv : float, default=None
        The CV RMSE of ``physics`` as fitted (computed when ``None`` and a parameter is
        to be held: the note gives it, and it scores the model when the hold is not kept).
    failures : list, default=None
        Where a failed refit is recorded (a line), as the loop records its fits'.
    held_cv : float, default=None
        The CV RMSE of ``physics`` with the parameters held (computed when ``None``): the
        loop's trail holds it, each effect set being cross-validated so
        ([`close_the_loop`][sk_offwhite.loop.close_the_loop]).

    Returns
    -------
    physics, est, cv, note
        The physics with the held parameters fixed, its fit, its CV RMSE and a sentence
        for the report; the arguments and ``None`` when nothing was held.
    """
    settings = settings or LoopSettings()
    effects = getattr(physics, "effects", ()) if effects is None else effects
    held, directions = _held_on_fit(physics, est, u, z, effects)
    if not held:
        return physics, est, cv, None
    if cv is None:  # the note's, or the score of the model left unheld
        cv = cross_validated_rmse(warm_physics(physics, est), u, z, settings)
    held_physics = holding(warm_physics(physics, est), held)
    refit = _attempt([] if failures is None else failures, "undetermined directions held", _fit_set,
                     _estimator(held_physics, settings), effects, u, z, settings)  # fmt: skip
    if refit is None:
        return physics, est, cv, None
    rmse = (_rmse(est.predict(u), z), _rmse(refit.predict(u), z))
    if rmse[1] > (1.0 + HOLD_SLACK) * rmse[0]:
        return physics, est, cv, None
    if held_cv is None:
        held_cv = cross_validated_rmse(warm_physics(held_physics, refit), u, z, settings)
    if held_cv > (1.0 + settings.tolerance) * cv:
        return physics, est, cv, None
    return held_physics, refit, held_cv, held_note(held, directions, rmse, (cv, held_cv))


def _holding_as(template, fitted):
    """``template`` with the parameters that ``fitted`` (the same structure) holds fixed
    and ``template`` leaves free fixed as in ``fitted``: the augmented physics as the final
    model has it
    ([`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions])."""
    held = {
        name: spec.value
        for name, spec in fitted.parameters.items()
        if spec.fixed and not template.parameters[name].fixed
    }
    return holding(template, held)


def _undetermined(est: GreyBoxSparseRegressor, u, z) -> list[str]:
    """Names of the variables of ``est``'s fit with an infinite standard error (on a flat
    direction of the relative Hessian: [`identifiability`][sk_offwhite.certify.identifiability]);
    none when that cannot be computed."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            report = identifiability(est, u, z, include_omega=False)
    except FIT_ERRORS:
        return []
    return [name for name, error in report.standard_errors.items() if not np.isfinite(error)]


def _reset_notes(reset: dict, physics) -> list[str]:
    """A note per declared parameter that later fits start from its declared value."""
    return [
        f"The declared physics' fit does not determine {name} (fitted {value:.4g}, its "
        f"standard error infinite): the later fits start it from its declared value "
        f"{physics.parameters[name].value:.4g}."
        for name, value in reset.items()
    ]


def close_the_loop(physics, library, u, z, *, settings: LoopSettings | None = None):
    """Run the whole loop on one estimation record ``(u, z)``; see the module docstring.

    Returns
    -------
    LoopResult
        The fitted models, the evidence, the selection trail, the CV errors of the final
        models and the failures. Score validation data with
        [`score_models`][sk_offwhite.loop.score_models].

    Raises
    ------
    ValueError
        When the declared physics itself cannot be fitted (nothing to compare with).
    """
    settings = settings or LoopSettings()
    u, z = check_record(u, z)
    failures: list[str] = []
    notes: list[str] = []
    clock = StageClock()
    with _stage(clock, "declared physics", settings):
        baseline, start, run, declared_cv, reset = _fit_declared(physics, u, z, settings)
        notes += _reset_notes(reset, physics)
        facts = _record_facts(physics, z, run)
    with _stage(clock, "evidence", settings):
        evidence, hypotheses = _read_evidence(start, library, u, z, settings, failures)
        snapshot = copy.copy(evidence)  # the physics-only fit, kept when the path refits it
    fits = {"baseline": (baseline, None, declared_cv)}
    if settings.fit_delta:
        with _stage(clock, MODEL_LABELS["with_delta"], settings):
            # the evidence estimator has the path's settings when CV fits whole blocks
            reuse = evidence if settings.cv_horizon is None else None
            fits["with_delta"] = _scored_delta(
                "with_delta", start, library, u, z, settings, failures, reuse
            )
            hypotheses = hypotheses + _delta_hypotheses(
                fits["with_delta"][0], u, fits["with_delta"][2], declared_cv, settings, notes
            )
    with _stage(clock, "effect selection", settings):
        candidates = _candidates(start, library, hypotheses, facts, run, u, z, settings)
        selection = _select_effects(
            start, candidates, u, z, settings, _rmse(run.outputs, z), failures, declared_cv
        )
        effects, trail, singles, _, set_fits = selection
        notes += _equivalents(effects, singles, settings.tolerance)
    with _stage(clock, MODEL_LABELS["final"], settings):
        augmented, final, final_cv, note = _augmented_fit(
            start, selection, baseline, declared_cv, u, z, settings, failures
        )
        notes += [note] if note else []
    fits["final"] = (final, None, final_cv)
    fits |= _corrected_fits(
        augmented, final, library, measured_states(physics.output), u, z, settings, failures,
        notes, clock,
    )  # fmt: skip
    found = dict(
        hypotheses=hypotheses, range_facts=facts, candidates=candidates, selection=trail,
        effects=effects, single_fits=singles, evidence=snapshot, failures=failures, notes=notes,
        timings=clock.seconds, set_fits={"declared physics": baseline, **set_fits},
    )  # fmt: skip
    return _loop_result(physics, _holding_as(augment(physics, *effects), augmented), fits, found)


def _record_facts(physics, z, run) -> list:
    """What the declared physics' simulation ``run`` says of the measured outputs ``z``:
    their ceilings and floors, and their repeated one-sample jumps."""
    names = _output_names(physics, z.shape[1])
    return range_violations(z, run.outputs, names) + output_jumps(z, run.outputs, names)


def _augmented_fit(start, selection, baseline, declared_cv, u, z, settings, failures):
    """``(augmented physics, its fit, its CV RMSE, note)`` for the effects of
    ``selection`` (`_select_effects`' value) added to ``start``: the fit on the whole
    record (`_final_fit`; without effects, or when it fails, the declared physics'
    fit ``baseline`` and its CV RMSE ``declared_cv``), with a parameter held on each
    direction it leaves undetermined
    ([`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions], whose note it
    returns; ``None`` without)."""
    effects, trail, _, warm, set_fits = selection
    augmented = augment(start, *effects).with_parameters(**warm)
    final = _final_fit(augmented, effects, set_fits, u, z, settings, failures) or baseline
    final_cv = dict(trail).get(_label(effects), declared_cv)
    if not effects or final is baseline:
        return augmented, final, final_cv, None
    augmented, final, cv, note = hold_undetermined_directions(
        augmented, final, u, z, effects=effects, settings=settings, failures=failures,
        held_cv=final_cv,
    )  # fmt: skip
    return augmented, final, (final_cv if cv is None else cv), note


def _corrected_fits(augmented, final, library, measured, u, z, settings, failures, notes, clock):
    """The ``augmented`` physics, started at its ``final`` fit, with a sparse δ from
    ``library`` of its state equations and with one of its output map (whose outputs read
    the states ``measured``), as ``fits`` holds them (``{key: (estimator, path, CV
    RMSE)}``), each as ``settings`` asks."""
    fitted_augmented = warm_physics(augmented, final)
    fits = {}
    if settings.fit_delta:
        with _stage(clock, MODEL_LABELS["final_with_delta"], settings):
            fits["final_with_delta"] = _scored_delta(
                "final_with_delta", fitted_augmented, library, u, z, settings, failures
            )
    if settings.fit_delta and settings.fit_output_delta:
        with _stage(clock, MODEL_LABELS["final_with_output_delta"], settings):
            fits["final_with_output_delta"] = _scored_output_delta(
                fitted_augmented, final, measured, u, z, settings, failures, notes
            )
    return fits


def _loop_result(physics, augmented_physics, fits: dict, found: dict) -> LoopResult:
    """The [`LoopResult`][sk_offwhite.loop.LoopResult] of ``fits`` (``{key: (estimator, path, CV
    RMSE)}``, the models of `MODEL_LABELS` that were fitted) and of what else the loop ``found``
    (the other fields, by name); the CV-best model is chosen here."""
    models = {key: fit[0] for key, fit in fits.items()}
    paths = {key: fit[1] for key, fit in fits.items()}
    cv_errors = {key: fit[2] for key, fit in fits.items() if fit[0] is not None}
    chosen = _choose(cv_errors, models, found["notes"])
    return LoopResult(
        physics=physics, augmented_physics=augmented_physics, baseline=models["baseline"],
        with_delta=models.get("with_delta"), final=models["final"],
        final_with_delta=models.get("final_with_delta"), gamma_path=paths.get("with_delta"),
        final_gamma_path=paths.get("final_with_delta"), cv_errors=cv_errors, chosen=chosen,
        final_with_output_delta=models.get("final_with_output_delta"),
        output_gamma_path=paths.get("final_with_output_delta"), **found,
    )  # fmt: skip


def _final_fit(augmented, effects, set_fits: dict, u, z, settings, failures):
    """The fit of the chosen effects' ``augmented`` physics on the whole record: the one
    the selection made of that set when it fitted it on a model of its own (the same
    model from the same start, so the same fit), else fitted now (``None`` when that
    fails, with a line in ``failures``)."""
    selected = set_fits.get(_label(effects))
    if selected is not None and not settings.share_programs:
        return selected
    return _attempt(failures, "augmented physics", _fit_set, _estimator(augmented, settings),
                    effects, u, z, settings)  # fmt: skip


def _equivalents(effects, singles, tolerance: float) -> list[str]:
    """Notes on candidates that, fitted alone, explain the record as well as a chosen one."""
    alone = dict(singles)
    notes = []
    for effect in effects:
        rmse = alone.get(effect.name, np.inf)
        same = [
            name
            for name, value in singles
            if name != effect.name and np.isfinite(rmse) and abs(value - rmse) <= tolerance * rmse
        ]
        if same:
            notes.append(
                f"`{effect.name}` alone fits the estimation record as well as "
                f"{', '.join(f'`{n}`' for n in same)} (within {tolerance:.0%}): the data may "
                "not tell them apart."
            )
    return notes


def _label(effects) -> str:
    return " + ".join(e.name for e in effects) if effects else "declared physics"


def _output_names(physics, n_outputs: int) -> list[str]:
    return [output_name(physics, i) for i in range(n_outputs)]


def analyse_model(est, u, z, physics, *, x0=None, z_init_window=0):
    """Residual report of a fitted model on one record (see
    [`sk_offwhite.diagnose`][sk_offwhite.diagnose])."""
    u, z = check_record(u, z)
    z_init = z[:z_init_window] if z_init_window else None
    run = est.simulate(u, x0=x0, z_init=z_init)
    taken = set(physics.state_names) | set(physics.input_names)
    outputs = [f"{n} (output)" if n in taken else n for n in _output_names(physics, z.shape[1])]
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
