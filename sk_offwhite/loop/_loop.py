r"""The closed loop: residual -> sparse correction -> named effect -> refit -> before/after.

1. Fit the declared physics; analyse its simulation residual on the estimation record.
2. Fit the physics plus a sparse correction :math:`\delta`, with :math:`\gamma` chosen by
   cross-validation on the estimation record; turn the selected terms into hypotheses.
3. Propose explicit effects from the hypotheses and the measured output range; add them one
   at a time (greedy forward selection) while the cross-validated :math:`R^2` on the
   estimation record improves.
4. Refit the augmented physics, and the augmented physics with :math:`\delta` to show what is
   left. Validation data, when given, are only scored.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from sklearn.model_selection import GridSearchCV, KFold, cross_val_score

from .._effects import augment
from .._estimator import GreyBoxSparseRegressor
from ..diagnose import analyse_residuals, range_violations
from ._candidates import propose_effects
from ._hypotheses import form_hypotheses

__all__ = ["LoopResult", "LoopSettings", "close_the_loop", "fit_continued"]


@dataclass(frozen=True)
class LoopSettings:
    """Settings of :func:`close_the_loop`, all applied on the estimation record only."""

    gammas: tuple[float, ...] = (1e-5, 1e-4, 1e-3, 1e-2)
    n_folds: int = 3
    horizon: int | None = 128
    max_iter: int = 300
    max_effects: int = 3
    min_gain: float = 0.05
    delta_states: tuple[int, ...] | None = None
    init_window: int = 50


@dataclass
class LoopResult:
    """Everything the loop found; the report is written from it."""

    physics: object
    augmented_physics: object
    baseline: GreyBoxSparseRegressor
    with_delta: GreyBoxSparseRegressor
    final: GreyBoxSparseRegressor
    final_with_delta: GreyBoxSparseRegressor
    gamma_scores: dict
    hypotheses: list
    range_facts: list
    candidates: list
    selection: list = field(default_factory=list)
    effects: tuple = ()
    metrics: dict = field(default_factory=dict)
    residuals: dict = field(default_factory=dict)


def fit_continued(est: GreyBoxSparseRegressor, u, z, horizon):
    """Fit with multiple shooting first (``horizon``), then refine on the whole record."""
    if horizon is not None and horizon < len(u):
        est.set_params(horizon=horizon).fit(u, z)
        est.set_params(horizon=None, warm_start=True)
    est.fit(u, z)
    return est.set_params(warm_start=False)


def _cv_r2(est, u, z, settings: LoopSettings) -> float:
    scores = cross_val_score(
        est, u, z, cv=KFold(settings.n_folds), params={"sample_index": np.arange(len(u))}
    )
    return float(np.mean(scores))


def _estimator(physics, settings, **params) -> GreyBoxSparseRegressor:
    return GreyBoxSparseRegressor(
        physics,
        horizon=settings.horizon,
        max_iter=settings.max_iter,
        init_window=settings.init_window,
        **params,
    )


def _fit_delta(physics, library, u, z, settings):
    est = _estimator(physics, settings, library=library, delta_states=settings.delta_states)
    search = GridSearchCV(est, {"gamma": list(settings.gammas)}, cv=KFold(settings.n_folds))
    search.fit(u, z, sample_index=np.arange(len(u)))
    best = fit_continued(search.best_estimator_, u, z, settings.horizon)
    scores = dict(zip(settings.gammas, search.cv_results_["mean_test_score"], strict=True))
    return best, scores


def _select_effects(physics, candidates, u, z, settings):
    """Greedy forward selection on the cross-validated R² of the estimation record."""
    chosen, trail = [], []
    current = _cv_r2(_estimator(physics, settings), u, z, settings)
    trail.append(("declared physics", current))
    remaining = list(candidates)
    for _ in range(settings.max_effects):
        scored = [
            (_cv_r2(_estimator(augment(physics, *chosen, c.effect), settings), u, z, settings), c)
            for c in remaining
        ]
        trail += [(c.effect.name, s) for s, c in scored]
        if not scored:
            break
        best_score, best = max(scored, key=lambda item: item[0])
        if (1.0 - best_score) > (1.0 - settings.min_gain) * (1.0 - current):
            break
        chosen.append(best.effect)
        remaining.remove(best)
        current = best_score
    return tuple(chosen), trail


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
    run = baseline.simulate(u)
    output_names = _output_names(physics, z.shape[1])
    facts = range_violations(z, run.outputs, output_names)
    with_delta, gamma_scores = _fit_delta(physics, library, u, z, settings)
    hypotheses = form_hypotheses(with_delta, with_delta.simulate(u), u)
    candidates = propose_effects(hypotheses, facts, physics.state_names, output_names, run.states)
    effects, trail = _select_effects(physics, candidates, u, z, settings)
    augmented = augment(physics, *effects)
    final = fit_continued(_estimator(augmented, settings), u, z, settings.horizon)
    final_delta = _estimator(
        augmented,
        settings,
        library=library,
        gamma=with_delta.gamma,
        delta_states=settings.delta_states,
    )
    final_delta = fit_continued(final_delta, u, z, settings.horizon)
    return LoopResult(
        physics,
        augmented,
        baseline,
        with_delta,
        final,
        final_delta,
        gamma_scores,
        hypotheses,
        facts,
        candidates,
        trail,
        effects,
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
