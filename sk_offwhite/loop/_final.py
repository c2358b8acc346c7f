"""Stage 5 of the loop: the augmented physics fitted, with a parameter held on each direction
its fit leaves undetermined.

Where an added effect leaves the augmented physics without a scale (a calibrated level whose
dynamics a rescaling leaves unchanged), the data do not determine the fit along that
direction: its standard errors describe the orbit, not the measurements, and the folds land
at different points of it. One of the effect's parameters is then held at its fitted value
(`sk_offwhite.loop._gauge`), when that leaves the fit and, within ``tolerance``, its
cross-validated error as they were.
"""

from __future__ import annotations

import numpy as np

from .._estimator import GreyBoxSparseRegressor
from ..effects import augment
from ._cv import structure_cv
from ._fits import fit_set, label, record_rmse, warm_physics
from ._gauge import held_note, held_on_fit, holding
from ._search import Search
from ._settings import LoopSettings

__all__ = ["HOLD_SLACK", "hold_undetermined_directions"]

HOLD_SLACK = 1e-3
"""The relative rise of the estimation RMSE a fit with a parameter held on an undetermined
direction may show (holding it there leaves the fit as it was, up to rounding)."""


def augmented_fit(search: Search, start, selection, baseline, declared_cv):
    """``(augmented physics, its fit, its CV RMSE, note)`` for the effects of ``selection``
    added to ``start``: the fit on the whole record (`final_fit`; without effects, or when it
    fails, the declared physics' fit ``baseline`` and its CV RMSE ``declared_cv``), with a
    parameter held on each direction it leaves undetermined (whose note it returns; ``None``
    without)."""
    effects, trail, _, warm, set_fits = selection
    augmented = augment(start, *effects).with_parameters(**warm)
    final = final_fit(search, augmented, effects, set_fits) or baseline
    final_cv = dict(trail).get(label(effects), declared_cv)
    if not effects or final is baseline:
        return augmented, final, final_cv, None
    augmented, final, cv, note = held_fit(search, augmented, final, effects, None, final_cv)
    return augmented, final, (final_cv if cv is None else cv), note


def final_fit(search: Search, augmented, effects, set_fits: dict):
    """The fit of the chosen effects' ``augmented`` physics on the whole record: the one the
    selection made of that set on a model of its own (the same model from the same start,
    so the same fit), else fitted now (``None`` when that fails)."""
    selected = set_fits.get(label(effects))
    if selected is not None and not search.settings.share_programs:
        return selected
    est = search.estimator(augmented)
    return search.attempt("augmented physics", fit_set, search, est, effects)


def hold_undetermined_directions(
    physics, est: GreyBoxSparseRegressor, u, z, *, effects=None, settings=None, cv=None,
    failures=None, held_cv=None,
):  # fmt: skip
    r"""Hold a parameter on each direction of an augmented physics' fit that the data do
    not determine.

    Where an added effect leaves a direction along which the relative standard error of the
    fit is at least `MAX_RELATIVE_ERROR`, or its Gauss-Newton matrix singular, the added
    effect's parameter that loads most on the direction is fixed at its fitted value, and
    the physics is refitted from ``est`` as the loop fits an effect set and
    cross-validated. The fit is kept when its estimation RMSE rose by at most `HOLD_SLACK`
    and its CV RMSE by at most ``settings.tolerance`` over ``cv`` (a model with fewer free
    parameters is preferred within it, as a smaller effect set is).

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
        The CV RMSE of ``physics`` as fitted (computed when ``None`` and a parameter is to
        be held: the note gives it, and it scores the model when the hold is not kept).
    failures : list, default=None
        Where a failed refit is recorded (a line), as the loop records its fits'.
    held_cv : float, default=None
        The CV RMSE of ``physics`` with the parameters held (computed when ``None``).

    Returns
    -------
    physics, est, cv, note
        The physics with the held parameters fixed, its fit, its CV RMSE and a sentence for
        the report; the arguments and ``None`` when nothing was held.
    """
    search = Search(u, z, settings or LoopSettings(), [] if failures is None else failures)
    effects = getattr(physics, "effects", ()) if effects is None else effects
    return held_fit(search, physics, est, effects, cv, held_cv)


def held_fit(search: Search, physics, est, effects, cv, held_cv):
    """[`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions] on the
    search's record and settings."""
    u, z = search.u, search.z
    held, directions = held_on_fit(physics, est, u, z, effects)
    if not held:
        return physics, est, cv, None
    if cv is None:  # the note's, or the score of the model left unheld
        cv = structure_cv(search, warm_physics(physics, est))
    held_physics = holding(warm_physics(physics, est), held)
    refit = search.attempt(
        "undetermined directions held", fit_set, search, search.estimator(held_physics), effects
    )
    if refit is None:
        return physics, est, cv, None
    rmse = (record_rmse(est.predict(u), z), record_rmse(refit.predict(u), z))
    if rmse[1] > (1.0 + HOLD_SLACK) * rmse[0]:
        return physics, est, cv, None
    if held_cv is None:
        held_cv = structure_cv(search, warm_physics(held_physics, refit))
    if held_cv > (1.0 + search.settings.tolerance) * cv:
        return physics, est, cv, None
    return held_physics, refit, held_cv, held_note(held, directions, rmse, (cv, held_cv))


def holding_as(template, fitted):
    """``template`` with the parameters that ``fitted`` (the same structure) holds fixed and
    ``template`` leaves free fixed as in ``fitted``: the augmented physics as the final model
    has it."""
    held = {
        name: spec.value
        for name, spec in fitted.parameters.items()
        if spec.fixed and not template.parameters[name].fixed
    }
    return holding(template, held)


def equivalents(effects, singles, tolerance: float) -> list[str]:
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
