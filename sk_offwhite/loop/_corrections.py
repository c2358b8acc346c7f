r"""The models with a sparse correction: what the physics still lacks, shown as $\delta$.

The declared physics + $\delta$ (its hypotheses feed the candidates), the augmented physics +
$\delta$ of its state equations, and, where the outputs read states, the augmented physics
with a sparse correction of its output map (a sensor's static curve: Gaussian bumps of the
measured states over their simulated range). Each is fitted along the support path with
$\gamma$ chosen by the loop's cross-validation, and scored as the effect sets are.
"""

from __future__ import annotations

import numpy as np
from sklearn.base import clone

from .._path import GammaPath, fit_gamma_path
from ..dictionaries import RadialBasis
from ._cv import estimator_cv, held_out_splits
from ._fits import fit_continued, warm_physics
from ._scoring import MODEL_LABELS
from ._search import Search

__all__ = ["corrected_fits", "scored_delta"]


def fit_delta(search: Search, physics, library, evidence=None, targets=None):
    """Physics + δ on the support path, γ chosen by CV RMSE; the fitted estimator and the
    path (``None`` for a single γ, fitted directly). ``evidence``, an estimator with the
    same settings fitted to its physics-only stage, is refitted along the path, which then
    reuses that stage. ``targets``: the estimator's ``delta_states`` and ``delta_outputs``
    (default: the settings' ``delta_states``)."""
    u, z, settings = search.u, search.z, search.settings
    targets = targets or {"delta_states": settings.delta_states}
    est = evidence or search.estimator(physics, cv=True, library=library, **targets)
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


def delta_cv(search: Search, est, path: GammaPath | None) -> float:
    """CV RMSE of a fitted model with δ at its chosen γ, scored as the trail is: the mean
    over folds of the path's own fits at that γ, or, without a path (a single γ), the folds
    fitted now."""
    if path is not None and path.cv_rmse is not None:
        return float(np.mean(path.cv_rmse[path.best_index]))
    return estimator_cv(search, clone(est).set_params(horizon=search.settings.cv_horizon))


def scored_delta(search: Search, key, physics, library, evidence=None, targets=None):
    """``(estimator, path, CV RMSE)`` of ``physics`` + δ (``None, None, inf`` on failure);
    ``targets`` as for `fit_delta`."""
    fitted = search.attempt(
        MODEL_LABELS[key], fit_delta, search, physics, library, evidence, targets
    )
    if fitted is None:
        return None, None, np.inf
    cv = search.attempt(f"CV of {MODEL_LABELS[key]}", delta_cv, search, fitted[0], fitted[1])
    return fitted[0], fitted[1], np.inf if cv is None else cv


def scored_output_delta(search: Search, physics, fitted, measured, notes):
    """``(estimator, path, CV RMSE)`` of ``physics`` + a sparse correction of every output,
    each measuring the state ``measured[i]`` (``None``: the output map is not a reading of
    states, and a note says the stage was skipped), on the bumps of the measured states over
    the range ``fitted`` simulates."""
    key = "final_with_output_delta"
    if measured is None:
        notes.append(f"{MODEL_LABELS[key]} not fitted: the outputs do not read states directly.")
        return None, None, np.inf
    label = f"dictionary of {MODEL_LABELS[key]}"
    library = search.attempt(label, output_library, search, fitted, measured)
    if library is None:
        return None, None, np.inf
    targets = {"delta_states": (), "delta_outputs": tuple(range(len(measured)))}
    return scored_delta(search, key, physics, library, None, targets)


def output_library(search: Search, fitted, measured) -> RadialBasis:
    """Gaussian bumps of the ``measured`` states over the range of ``fitted``'s free run."""
    states = np.asarray(fitted.simulate(search.u).states, float)
    columns = sorted(set(int(i) for i in measured))
    names = [fitted.physics_.state_names[i] for i in columns]
    bumps = search.settings.output_bumps
    return RadialBasis.from_data(states[:, columns], names, n_bumps=bumps)


def corrected_fits(search: Search, augmented, final, library, measured, notes) -> dict:
    """The ``augmented`` physics, started at its ``final`` fit, with a sparse δ from
    ``library`` of its state equations and with one of its output map (whose outputs read
    the states ``measured``), as ``{key: (estimator, path, CV RMSE)}``, each as the settings
    ask."""
    fitted_augmented = warm_physics(augmented, final)
    fits, settings = {}, search.settings
    if settings.fit_delta:
        with search.stage(MODEL_LABELS["final_with_delta"]):
            fits["final_with_delta"] = scored_delta(
                search, "final_with_delta", fitted_augmented, library
            )
    if settings.fit_delta and settings.fit_output_delta:
        with search.stage(MODEL_LABELS["final_with_output_delta"]):
            fits["final_with_output_delta"] = scored_output_delta(
                search, fitted_augmented, final, measured, notes
            )
    return fits
