r"""The closed loop as a scikit-learn meta-estimator: residual, evidence, named effects,
refit, before and after.

[`EffectSearchCV`][sk_offwhite.loop.EffectSearchCV] is to the closed loop what ``GridSearchCV``
is to a grid: it takes an estimator (the declared physics, the dictionary and the fit
settings), searches on the estimation record for the effects the physics lacks, choosing
every step by cross-validation on that record only, and keeps the model with the lowest
cross-validated error; ``predict`` and ``score`` are that model's.
[`close_the_loop`][sk_offwhite.loop.close_the_loop] is the same search as a function.

The stages, each a module of this package:

1. the declared physics fitted and cross-validated (`_evidence`);
2. the evidence: what each dictionary term would explain that the declared parameters cannot
   absorb (and, in a note, the functions a physicist tries first for each variable: a
   velocity's sign, a level's square root, a saturation, `_kind_terms`), and the
   hypotheses of the fitted sparse $\delta$ (`_evidence`, `_corrections`);
3. the candidates, from the hypotheses, the measured range and the variables' kinds
   (`_proposals`, `_candidates`);
4. the selection: single fits, forward selection, nested sets, cross-validated, then
   refined stepwise (`_selection`, `_refinement`);
5. the augmented physics, with a parameter held on each direction its fit leaves
   undetermined (`_final`), and its corrections (`_corrections`);
6. never worse: every final model cross-validated the same way, the CV-best chosen
   (`_result`).

A fit that fails becomes a line of ``failures_`` and the search goes on.
"""

from __future__ import annotations

import copy
import warnings
from numbers import Integral

import numpy as np
from sklearn.base import BaseEstimator, MetaEstimatorMixin, RegressorMixin, clone
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils._param_validation import HasMethods, InvalidParameterError
from sklearn.utils.validation import check_is_fitted

from .._estimator import GreyBoxSparseRegressor, _compiled_library
from .._validation import check_record
from ..effects import Effect, augment
from ..effects._hidden import n_declared_states
from ..model import PhysicsModel
from ..model._physics import measured_states
from ..model_selection import SequenceSplit
from ._candidates import Candidate
from ._corrections import corrected_fits, scored_delta
from ._cv import held_out_splits, structure_cv
from ._evidence import (
    delta_hypotheses,
    fit_declared,
    read_evidence,
    read_kind_notes,
    record_facts,
    reset_notes,
    unfit_notes,
)
from ._final import augmented_fit, equivalents, holding_as
from ._fits import record_rmse
from ._proposals import candidates as propose
from ._proposals import proposed_groups, varying_candidates
from ._result import LoopResult, loop_result, warning_counts
from ._scoring import MODEL_LABELS
from ._search import Search
from ._selection import select_effects
from ._settings import CONSTRAINTS, LoopSettings

__all__ = ["EffectSearchCV", "close_the_loop"]

_ESTIMATOR_SETTINGS = ("horizon", "max_iter", "init_window", "lm_scaling", "delta_states")
"""The loop's settings that the estimator of an [`EffectSearchCV`][sk_offwhite.loop.EffectSearchCV]
holds."""

_SEARCH_SETTINGS = tuple(name for name in CONSTRAINTS if name not in _ESTIMATOR_SETTINGS)


def close_the_loop(physics, library, u, z, *, settings: LoopSettings | None = None):
    """Run the whole loop on one estimation record ``(u, z)``
    ([`EffectSearchCV`][sk_offwhite.loop.EffectSearchCV] as a function).

    Parameters
    ----------
    physics : PhysicsModel
        The declared physics.
    library : pysindy feature library, RidgeBasis or RadialBasis
        The dictionary of the evidence and of the sparse corrections.
    u, z : array-like of shape (n_samples, n_inputs) and (n_samples, n_outputs)
        The estimation record (one record).
    settings : LoopSettings, default=None
        ``LoopSettings()`` when ``None``.

    Returns
    -------
    LoopResult
        The fitted models, the evidence, the selection trail, the CV errors of the final
        models and the failures. Score validation data with
        [`score_models`][sk_offwhite.loop.score_models].

    Raises
    ------
    ValueError
        When an argument is wrong (before any fit), or when the declared physics itself
        cannot be fitted (nothing to compare with).
    """
    settings = LoopSettings() if settings is None else settings
    if not isinstance(settings, LoopSettings):
        raise TypeError(f"settings must be a LoopSettings, got {type(settings).__name__}.")
    check_record(u, z)
    if not isinstance(physics, PhysicsModel):
        raise TypeError(
            "physics must be a PhysicsModel (the declared physics the loop adds effects to), "
            f"got {type(physics).__name__}."
        )
    search = EffectSearchCV.from_settings(physics, library, settings)
    return search.fit(u, z).result_


def run_loop(search: Search, physics, library, given=None) -> LoopResult:
    """The whole loop on the search's record (the module docstring's stages); ``given``
    effects, when not ``None``, are the candidates instead of the proposed ones.

    The warnings of the declared physics' fit are the user's and are shown; those of the
    search's many internal fits (a candidate stopped at ``max_iter``, a fold that diverged)
    are counted in ``LoopResult.warnings`` and the report, and only a chosen model that did
    not converge is warned of again."""
    with search.stage("declared physics"):
        declared = fit_declared(search, physics)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = _search_from(search, physics, library, given, declared)
    result.warnings = warning_counts(caught)
    _warn_if_chosen_unconverged(result)
    return result


def _search_from(search: Search, physics, library, given, declared) -> LoopResult:
    """The stages after the declared physics' fit (``declared``: `fit_declared`'s value)."""
    settings, notes = search.settings, []
    baseline, start, run, reset = declared
    with search.stage("declared physics"):
        declared_cv = structure_cv(search, start)
        notes += reset_notes(reset, physics) + unfit_notes(baseline)
        facts = record_facts(physics, search.z, run)
    with search.stage("evidence"):
        evidence, hypotheses = read_evidence(search, start, library)
        read_kind_notes(search, start, library, run.states)
        snapshot = copy.copy(evidence)  # the physics-only fit, kept when the path refits it
    fits = {"baseline": (baseline, None, declared_cv)}
    readings = []
    if settings.fit_delta:
        with search.stage(MODEL_LABELS["with_delta"]):
            # the evidence estimator has the path's settings when CV fits whole blocks
            reuse = evidence if settings.cv_horizon is None else None
            fits["with_delta"] = scored_delta(search, "with_delta", start, library, reuse)
            est, _, cv = fits["with_delta"]
            hypotheses = hypotheses + delta_hypotheses(search, est, cv, declared_cv, notes)
            if cv < declared_cv:  # a correction that does not validate holds no law
                readings = search.attempt("reading of δ", varying_candidates, search, start, est)
    with search.stage("effect selection"):
        candidates = (
            propose(search, start, library, hypotheses, facts, run) + (readings or [])
            if given is None
            else [Candidate(effect, "given") for effect in given]
        )
        groups = proposed_groups(search, start, hypotheses, candidates, run)
        base_rmse = record_rmse(run.outputs, search.z)
        selection = select_effects(search, start, candidates, base_rmse, declared_cv, groups)
        effects, trail, singles, _, set_fits = selection
        notes += equivalents(effects, singles, settings.tolerance)
    with search.stage(MODEL_LABELS["final"]):
        augmented, final, final_cv, note = augmented_fit(
            search, start, selection, baseline, declared_cv
        )
        notes += [note] if note else []
    fits["final"] = (final, None, final_cv)
    notes += search.notes
    measured = measured_states(physics.output)
    fits |= corrected_fits(search, augmented, final, library, measured, notes)
    found = dict(
        hypotheses=hypotheses, range_facts=facts, candidates=candidates, selection=trail,
        effects=effects, single_fits=singles, evidence=snapshot, failures=search.failures,
        notes=notes, timings=search.clock.seconds,
        set_fits={"declared physics": baseline, **set_fits},
    )  # fmt: skip
    augmented_physics = holding_as(augment(physics, *effects), augmented)
    return loop_result(physics, augmented_physics, fits, found)


def _warn_if_chosen_unconverged(result: LoopResult) -> None:
    """One warning when the chosen model's own fit did not converge (the user's model)."""
    best = result.best
    if result.chosen != "baseline" and not best.converged_:
        warnings.warn(
            f"The chosen model ({MODEL_LABELS[result.chosen]}) did not converge: "
            f"{best.solver_message_}.",
            ConvergenceWarning,
            stacklevel=3,
        )


class EffectSearchCV(MetaEstimatorMixin, RegressorMixin, BaseEstimator):
    r"""Search the effects the declared physics lacks, every step chosen by cross-validation.

    ``fit(u, z)`` runs the closed loop on the estimation record: the declared physics (the
    estimator's ``physics``) is fitted, its residual traced to what it cannot explain (the
    dictionary's evidence, the fitted sparse $\delta$, the measured range, the variables'
    kinds), the candidate effects fitted alone and in sets, and the sets, refined stepwise,
    compared by their cross-validated simulation error; the model with the lowest, never
    worse than the declared physics, is ``best_estimator_``.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        The declared physics, its dictionary (``library``) and the settings every fit of the
        search uses: ``horizon`` (the multiple-shooting window of each fit's first stage,
        refined on the whole record; ``None``: the whole record at once), ``max_iter``,
        ``init_window`` (``None``: ``min(50, n_samples // 5)``), ``lm_scaling`` and
        ``delta_states``.
    cv : int or SequenceSplit, default=3
        How every choice is scored: an int is that many contiguous blocks held out in turn
        (``SequenceSplit(cv, train="rest")``, each fitted on the rest as separate records);
        ``SequenceSplit(1, train="forward", test_size=f)`` holds out the record's last
        fraction ``f`` (fitted on the past, run into the future).
    candidates : 'auto' or sequence of Effect, default='auto'
        The effects to try: ``'auto'`` proposes them from the evidence (the catalogue, the
        promoted dictionary terms and the declared relaxable constants); a sequence tries
        those instead.
    n_jobs : int, default=None
        Processes that fit the folds, the candidates and the sets (joblib's convention);
        the numbers are the same as with one.
    gammas, n_gammas, gamma_eps, cv_horizon, max_effects, min_gain, tolerance, \
max_candidates, beam, fit_top, n_pairs, min_share, n_promoted, fit_delta, share_programs, \
one_standard_error, release_programs, fit_output_delta, output_bumps, kind_notes
        As [`LoopSettings`][sk_offwhite.loop.LoopSettings].

    Attributes
    ----------
    best_estimator_ : GreyBoxSparseRegressor
        The model of lowest cross-validated error (``chosen_`` names it).
    effects_ : tuple of Effect
        The effects added to the declared physics, with ``augmented_physics_`` the physics
        holding them.
    hypotheses_ : list of Hypothesis
        What the declared physics cannot explain.
    candidates_ : list of Candidate
        The effects tried, each with why.
    cv_results_ : dict of lists
        One entry per model cross-validated (effect sets and final models): ``model``,
        ``effects``, ``mean_cv_rmse`` and ``kind`` (``"effect set"`` or ``"final model"``);
        ``pandas.DataFrame(cv_results_)`` reads it.
    cv_errors_ : dict
        The final models' cross-validated errors by key.
    failures_, notes_ : list of str
        One line per fit that failed; what the search decided not to use and why.
    result_ : LoopResult
        Everything above, as [`write_report`][sk_offwhite.loop.write_report] and
        [`score_models`][sk_offwhite.loop.score_models] take it.
    """

    _parameter_constraints: dict = {
        "estimator": [HasMethods(["fit", "predict"])],
        "cv": [Integral, SequenceSplit],
        "candidates": ["array-like", str],
        **{name: CONSTRAINTS[name] for name in _SEARCH_SETTINGS if name != "selection"},
    }
    _parameter_constraints.pop("n_folds")
    _parameter_constraints.pop("tail_fraction")

    def __init__(
        self,
        estimator: GreyBoxSparseRegressor,
        *,
        cv: int | SequenceSplit = 3,
        candidates="auto",
        n_jobs: int | None = None,
        gammas=None,
        n_gammas: int = 5,
        gamma_eps: float = 1e-6,
        cv_horizon: int | None = None,
        max_effects: int = 3,
        min_gain: float = 0.05,
        tolerance: float = 0.02,
        max_candidates: int | None = None,
        beam: int = 4,
        fit_top: int | None = 8,
        n_pairs: int = 2,
        min_share: float = 0.1,
        n_promoted: int = 3,
        fit_delta: bool = True,
        share_programs: bool = False,
        one_standard_error: bool = False,
        release_programs: bool = True,
        fit_output_delta: bool = True,
        output_bumps: int = 7,
        kind_notes: bool = True,
    ):
        self.estimator = estimator
        self.cv = cv
        self.candidates = candidates
        self.n_jobs = n_jobs
        self.gammas = gammas
        self.n_gammas = n_gammas
        self.gamma_eps = gamma_eps
        self.cv_horizon = cv_horizon
        self.max_effects = max_effects
        self.min_gain = min_gain
        self.tolerance = tolerance
        self.max_candidates = max_candidates
        self.beam = beam
        self.fit_top = fit_top
        self.n_pairs = n_pairs
        self.min_share = min_share
        self.n_promoted = n_promoted
        self.fit_delta = fit_delta
        self.share_programs = share_programs
        self.one_standard_error = one_standard_error
        self.release_programs = release_programs
        self.fit_output_delta = fit_output_delta
        self.output_bumps = output_bumps
        self.kind_notes = kind_notes

    @classmethod
    def from_settings(cls, physics, library, settings: LoopSettings) -> EffectSearchCV:
        """The search that [`close_the_loop`][sk_offwhite.loop.close_the_loop] runs with
        ``settings``."""
        fit = {name: getattr(settings, name) for name in _ESTIMATOR_SETTINGS}
        estimator = GreyBoxSparseRegressor(physics, library, **fit)
        own = {name: getattr(settings, name) for name in _SEARCH_SETTINGS}
        selection, n_folds, fraction = (
            own.pop("selection"),
            own.pop("n_folds"),
            own.pop("tail_fraction"),
        )
        cv = n_folds if selection == "cv" else SequenceSplit(1, train="forward", test_size=fraction)
        return cls(estimator, cv=cv, **own)

    def settings(self, n_samples: int | None = None) -> LoopSettings:
        """The [`LoopSettings`][sk_offwhite.loop.LoopSettings] of this search on a record of
        ``n_samples`` (validated: a wrong value raises at once, naming it). An estimator's
        ``init_window=None`` is its own rule, ``min(50, n_samples // 5)``."""
        est = self.estimator
        fit = {name: getattr(est, name) for name in _ESTIMATOR_SETTINGS}
        if fit["init_window"] is None:
            fit["init_window"] = 50 if n_samples is None else min(50, n_samples // 5)
        fit["delta_states"] = None if fit["delta_states"] is None else tuple(fit["delta_states"])
        own = {
            name: getattr(self, name)
            for name in _SEARCH_SETTINGS
            if name not in ("selection", "n_folds", "tail_fraction")
        }
        own["gammas"] = None if self.gammas is None else tuple(np.ravel(self.gammas))
        return LoopSettings(**fit, **own, **_selection(self.cv))

    def fit(self, u, z):
        """Run the search on the estimation record ``(u, z)`` (one record).

        Every argument and setting is checked before the first fit; a fit that fails
        during the search becomes a line of ``failures_``.

        Returns
        -------
        self : EffectSearchCV
        """
        self._z_was_1d = z is not None and np.asarray(z).ndim == 1
        u, z = check_record(u, z)
        physics, library = _checked_estimator(self.estimator, u.shape[1], z.shape[1])
        if self.estimator.physics is None and _is_auto(self.candidates):
            raise ValueError(
                "the estimator has no physics: the automatic candidates are effects missing "
                "from a declared physics; give the estimator a PhysicsModel, or list the "
                "candidates to try (candidates=[...])."
            )
        settings = self.settings(len(u))
        _check_settings_fit_record(settings, physics, len(u))
        search = Search(u, z, settings)
        given = None if _is_auto(self.candidates) else _given(self.candidates)
        self.result_ = run_loop(search, physics, library, given)
        self._store(self.result_, u)
        return self

    def _store(self, result: LoopResult, u) -> None:
        self.best_estimator_ = result.best
        self.chosen_ = result.chosen
        self.effects_ = result.effects
        self.augmented_physics_ = result.augmented_physics
        self.hypotheses_ = result.hypotheses
        self.candidates_ = result.candidates
        self.cv_errors_ = dict(result.cv_errors)
        self.cv_results_ = cv_results(result)
        self.failures_ = list(result.failures)
        self.notes_ = list(result.notes)
        self.n_features_in_ = np.shape(u)[1]

    def predict(self, u, **kwargs):
        """The chosen model's simulation of ``u`` (see
        [`GreyBoxSparseRegressor.predict`][sk_offwhite.GreyBoxSparseRegressor.predict])."""
        check_is_fitted(self)
        z = self.best_estimator_.predict(u, **kwargs)
        return np.ravel(z) if getattr(self, "_z_was_1d", False) and np.ndim(z) == 2 else z

    def score(self, u, z, **kwargs):
        """The chosen model's $R^2$ of the simulation (see
        [`GreyBoxSparseRegressor.score`][sk_offwhite.GreyBoxSparseRegressor.score])."""
        check_is_fitted(self)
        return self.best_estimator_.score(u, z, **kwargs)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True
        tags.non_deterministic = False
        return tags

    def __sklearn_clone__(self):
        params = self.get_params(deep=False)
        params["estimator"] = clone(self.estimator)
        return type(self)(**params)


def _selection(cv) -> dict:
    """The loop's ``selection``, ``n_folds`` and ``tail_fraction`` of an
    [`EffectSearchCV`][sk_offwhite.loop.EffectSearchCV]'s ``cv``."""
    if isinstance(cv, Integral) and not isinstance(cv, bool) and cv >= 2:
        return {"selection": "cv", "n_folds": int(cv)}
    if isinstance(cv, SequenceSplit) and cv.train == "rest" and cv.gap == 0:
        return {"selection": "cv", "n_folds": cv.n_splits}
    if isinstance(cv, SequenceSplit) and cv.train == "forward" and cv.n_splits == 1:
        if isinstance(cv.test_size, float) and cv.gap == 0:
            return {"selection": "tail", "tail_fraction": cv.test_size}
    raise InvalidParameterError(
        "The 'cv' parameter of EffectSearchCV must be an int >= 2, a "
        "SequenceSplit(n, train='rest') or SequenceSplit(1, train='forward', test_size=f) "
        f"with 0 < f < 1, got {cv!r}."
    )


def _check_settings_fit_record(settings: LoopSettings, physics, n_samples: int) -> None:
    """Refuse, before any fit, settings that the record or the physics cannot honour:
    ``delta_states`` outside the declared states or repeated, and held-out blocks too short
    for ``init_window`` (`held_out_splits`)."""
    states = list(settings.delta_states or ())
    n_states = n_declared_states(physics)
    if any(not 0 <= k < n_states for k in states) or len(set(states)) != len(states):
        raise ValueError(
            f"delta_states must be distinct indices of the {n_states} declared states, "
            f"got {tuple(states)}."
        )
    held_out_splits(settings, n_samples)


def _checked_estimator(estimator, n_inputs: int, n_outputs: int):
    """``(physics, library)`` of the search's estimator, checked before any fit: a
    physics model (``None``: the linear black box of one state per output), and a
    dictionary that compiles on its states and inputs."""
    if not isinstance(estimator, GreyBoxSparseRegressor):
        raise TypeError(
            f"estimator must be a GreyBoxSparseRegressor, got {type(estimator).__name__}."
        )
    physics, library = estimator.physics, estimator.library
    if physics is None:
        physics = PhysicsModel.linear(n_inputs, n_outputs)
    if not isinstance(physics, PhysicsModel):
        raise TypeError(
            "the estimator's physics must be a PhysicsModel (the declared physics the search "
            f"adds effects to), got {type(physics).__name__}."
        )
    if library is not None:
        states = physics.state_names[: n_declared_states(physics)]
        _compiled_library(library, list(states) + list(physics.input_names), 1, None)
    return physics, library


def _is_auto(candidates) -> bool:
    return isinstance(candidates, str) and candidates == "auto"


def _given(candidates) -> list:
    """The effects of ``candidates`` (a sequence of Effect), checked."""
    if isinstance(candidates, str) or not all(isinstance(e, Effect) for e in candidates):
        raise InvalidParameterError(
            "The 'candidates' parameter of EffectSearchCV must be 'auto' or a sequence of "
            f"Effect, got {candidates!r}."
        )
    return list(candidates)


def cv_results(result: LoopResult) -> dict:
    """``cv_results_`` of a search: one entry per model it cross-validated, the effect sets
    of the trail then the final models."""
    sets = [(label, score, "effect set") for label, score in result.selection]
    finals = [(MODEL_LABELS[k], v, "final model") for k, v in result.cv_errors.items()]
    rows = sets + finals
    return {
        "model": [label for label, _, _ in rows],
        "effects": [_set_effects(label, kind) for label, _, kind in rows],
        "mean_cv_rmse": [float(score) for _, score, _ in rows],
        "kind": [kind for _, _, kind in rows],
    }


def _set_effects(label: str, kind: str) -> tuple:
    """The effect names of a trail row's label (none for the declared physics or a final
    model)."""
    if kind != "effect set" or label == "declared physics":
        return ()
    return tuple(label.split(" + "))
