r"""The closed loop: residual -> sparse correction -> named effect -> refit -> before/after.

1. Fit the declared physics (multiple shooting, then the whole record); analyse its
   simulation residual on the estimation record.
2. Fit the physics plus a sparse correction :math:`\delta` along the support path
   (:func:`~sk_offwhite.fit_gamma_path`, a grid relative to :math:`\gamma_{max}`), with
   :math:`\gamma` chosen by cross-validation on the estimation record; turn the selected
   terms into hypotheses.
3. Propose explicit effects from the hypotheses and the measured output range. Fit each
   alone on the estimation record, order them by how much they reduce its simulation error,
   and cross-validate the nested models (the best one, then the best two, ...): effects
   often act together (an overflow only explains the data once the sensor offset is right),
   which a one-at-a-time test cannot see. The smallest nested model within ``tolerance`` of
   the best cross-validated error is kept if it beats the declared physics by ``min_gain``.
4. Refit the augmented physics, and the augmented physics with :math:`\delta` (its
   :math:`\gamma` chosen again by cross-validation) to show what is left.

Every model starts from the previous stage's fitted values (parameters and initial state).
Cross-validation holds out contiguous blocks of the estimation record; each held-out block's
initial state is estimated from its first ``init_window`` samples, which are not scored
(:func:`~sk_offwhite.loop.held_out_rmse`). Validation data, when given, are only scored.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from sklearn.model_selection import KFold, cross_val_score

from .._effects import augment
from .._estimator import GreyBoxSparseRegressor
from .._path import GammaPath, fit_gamma_path
from .._physics import Parameter
from ..diagnose import analyse_residuals, range_violations
from ._candidates import propose_effects
from ._hypotheses import form_hypotheses
from ._scoring import held_out_rmse

__all__ = ["LoopResult", "LoopSettings", "close_the_loop", "fit_continued", "warm_physics"]


@dataclass(frozen=True)
class LoopSettings:
    r"""Settings of :func:`close_the_loop`, all applied on the estimation record only.

    ``gammas`` is the grid of the (dimensionless) :math:`\gamma`; ``None`` uses
    ``n_gammas`` values from :math:`\gamma_{max}` down to ``gamma_eps`` times it
    (:func:`~sk_offwhite.gamma_grid`); a single value is fitted without a search.
    ``horizon`` is the multiple-shooting window of the first stage of every final fit;
    ``cv_horizon`` that of the fits inside cross-validation (``None``: each training block
    is simulated whole, which is what the held-out blocks are scored on). ``min_gain`` is
    the relative reduction of the cross-validated RMSE an effect set must bring;
    ``tolerance`` the relative slack within which a smaller nested set is preferred.
    ``max_candidates`` caps how many proposed effects are fitted, in the order they are
    proposed (strongest hypothesis first); ``None`` fits them all. Each candidate costs a
    fit and a compilation, so a cap is the way to make a quick run quicker.
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

    def __post_init__(self):
        if self.max_candidates is not None and self.max_candidates < 1:
            raise ValueError(f"max_candidates must be None or >= 1, got {self.max_candidates}.")


@dataclass
class LoopResult:
    """Everything the loop found; the report is written from it.

    ``selection`` holds ``(label, cross-validated RMSE)`` of the declared physics and of
    every nested effect set tried; ``single_fits`` ``(effect name, estimation RMSE)`` of
    each candidate fitted alone; ``gamma_path`` and ``final_gamma_path`` the support paths
    (:class:`~sk_offwhite.GammaPath`, ``None`` for a single γ) of the two fits with δ.
    """

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
        **params,
    )


def _cv_rmse(est, u, z, settings: LoopSettings) -> float:
    """Mean held-out simulation RMSE over ``n_folds`` contiguous blocks."""
    scores = cross_val_score(
        est,
        u,
        z,
        cv=KFold(settings.n_folds),
        scoring=held_out_rmse(settings.init_window),
        params={"sample_index": np.arange(len(u))},
        error_score=-np.inf,
    )
    return float(-np.mean(scores))


def _fit_delta(physics, library, u, z, settings):
    """Physics + δ on the support path, γ chosen by CV RMSE; the fitted estimator and the
    path (``None`` for a single γ, fitted directly)."""
    est = _estimator(
        physics, settings, cv=True, library=library, delta_states=settings.delta_states
    )
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
        cv=KFold(settings.n_folds),
        init_window=settings.init_window,
    )
    return path.estimator, path


def _rmse(outputs, z: np.ndarray) -> float:
    """RMSE of simulated ``outputs`` against ``z`` (2-D); ``inf`` for a diverged simulation."""
    error = np.reshape(outputs, z.shape) - z
    value = float(np.sqrt(np.mean(error**2)))
    return value if np.isfinite(value) else np.inf


def _rank_alone(physics, candidates, u, z, settings):
    """``(estimation RMSE, candidate, fitted effect parameters)`` of each candidate added
    alone, best first.

    A quick fit ranks them: multiple shooting over ``horizon`` windows only (the whole
    record when ``horizon`` is ``None``), scored by the free run of the whole record. The
    effect's fitted parameters start the nested fits, so a threshold (a level, a cap) is
    not searched again from its first guess.
    """
    ranked = []
    for candidate in candidates:
        try:
            est = _estimator(augment(physics, candidate.effect), settings).fit(u, z)
        except ValueError:  # e.g. the effect's initial guess does not simulate
            ranked.append((np.inf, candidate, {}))
            continue
        own = candidate.effect.parameters()
        fitted = {
            name: Parameter(est.parameters_[name], spec.bounds)
            for name, spec in own.items()
            if not spec.fixed
        }
        ranked.append((_rmse(est.predict(u), z), candidate, fitted))
    return sorted(ranked, key=lambda item: item[0])


def _smallest_within(scores: list[float], tolerance: float) -> int:
    """Index of the first score within ``tolerance`` (relative) of the smallest."""
    best = min(scores)
    return next(k for k, s in enumerate(scores) if s <= best * (1.0 + tolerance))


def _select_effects(physics, candidates, u, z, settings, base_rmse):
    """Nested effect sets in the order of their single-fit gain, chosen by CV RMSE.

    Returns the chosen effects, the CV trail, the single-fit RMSEs and the effects'
    parameters as fitted alone (the start of the final fit).
    """
    ranked = _rank_alone(physics, candidates[: settings.max_candidates], u, z, settings)
    singles = [(c.effect.name, r) for r, c, _ in ranked]
    kept = [(c.effect, fitted) for r, c, fitted in ranked if r < base_rmse]
    useful = [effect for effect, _ in kept][: settings.max_effects]
    trail = [("declared physics", _cv_rmse(_estimator(physics, settings, cv=True), u, z, settings))]
    for k in range(1, len(useful) + 1):
        warm = {name: p for _, fitted in kept[:k] for name, p in fitted.items()}
        model = augment(physics, *useful[:k]).with_parameters(**warm)
        score = _cv_rmse(_estimator(model, settings, cv=True), u, z, settings)
        trail.append((" + ".join(e.name for e in useful[:k]), score))
    k = _smallest_within([s for _, s in trail], settings.tolerance)
    if k == 0 or trail[k][1] > (1.0 - settings.min_gain) * trail[0][1]:
        return (), trail, singles, {}
    warm = {name: p for _, fitted in kept[:k] for name, p in fitted.items()}
    return tuple(useful[:k]), trail, singles, warm


def close_the_loop(physics, library, u, z, *, settings: LoopSettings | None = None):
    """Run the whole loop on one estimation record ``(u, z)``; see the module docstring.

    Returns
    -------
    LoopResult
        The four fitted models, the evidence and the selection trail. Score validation
        data with :func:`~sk_offwhite.loop.score_models`.
    """
    settings = settings or LoopSettings()
    u, z = np.asarray(u, float), np.asarray(z, float).reshape(len(u), -1)
    baseline = fit_continued(_estimator(physics, settings), u, z, settings.horizon)
    start = warm_physics(physics, baseline)
    run = baseline.simulate(u)
    output_names = _output_names(physics, z.shape[1])
    facts = range_violations(z, run.outputs, output_names)
    with_delta, gamma_path = _fit_delta(start, library, u, z, settings)
    hypotheses = form_hypotheses(with_delta, with_delta.simulate(u), u)
    measured = getattr(physics.output, "indices", None)
    candidates = propose_effects(
        hypotheses,
        facts,
        physics.state_names,
        output_names,
        run.states,
        measured,
        u=u,
        input_names=physics.input_names,
    )
    effects, trail, singles, warm = _select_effects(
        start, candidates, u, z, settings, _rmse(run.outputs, z)
    )
    augmented = augment(start, *effects).with_parameters(**warm)
    final = fit_continued(_estimator(augmented, settings), u, z, settings.horizon)
    final_delta, final_path = _fit_delta(warm_physics(augmented, final), library, u, z, settings)
    return LoopResult(
        physics,
        augment(physics, *effects),
        baseline,
        with_delta,
        final,
        final_delta,
        gamma_path,
        hypotheses,
        facts,
        candidates,
        trail,
        effects,
        singles,
        final_path,
    )


def _output_names(physics, n_outputs: int) -> list[str]:
    if physics.output_names is not None:
        return list(physics.output_names)
    return [f"z{i + 1}" for i in range(n_outputs)]


def analyse_model(est, u, z, physics, *, x0=None, z_init_window=0):
    """Residual report of a fitted model on one record (see :mod:`sk_offwhite.diagnose`)."""
    z = np.asarray(z, float).reshape(len(u), -1)
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
