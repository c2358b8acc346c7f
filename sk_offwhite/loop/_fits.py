"""How the loop fits a structure on the estimation record, and reads what a fit found.

A structure is fitted over multiple-shooting windows first, then refined on the whole
record (`fit_continued`); a set with an effect on the output map is fitted on the whole
record alone (`set_horizon`): with free initial states at every window, a calibration of
the output could carry the record while the state equations do nothing. Every set is then
scored by the free run of the whole record, the protocol it will be used under.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
from sklearn.exceptions import ConvergenceWarning

from .._estimator import GreyBoxSparseRegressor
from .._warnings import RunawayParameterWarning
from ..model import Parameter
from ._search import Search

__all__ = ["fit_continued", "warm_physics"]


def fit_continued(est: GreyBoxSparseRegressor, u, z, horizon):
    """Fit with multiple shooting first (``horizon``), then refine on the whole record.

    Only the refinement's verdict is reported: the windows' fit is a start, and a
    ``ConvergenceWarning`` of it (windows that fit
    while their free run over the record does not) is what the refinement is for."""
    if horizon is not None and horizon < len(u):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
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


def record_rmse(outputs, z: np.ndarray) -> float:
    """RMSE of simulated ``outputs`` against ``z`` (2-D); ``inf`` for a diverged simulation."""
    with np.errstate(over="ignore", invalid="ignore"):
        error = np.reshape(outputs, z.shape) - z
        value = float(np.sqrt(np.mean(error**2)))
    return value if np.isfinite(value) else np.inf


def set_horizon(effects, horizon: int | None) -> int | None:
    """The shooting window of a set's fit: ``None`` (the whole record from one initial
    state) when an effect of the set acts on the output map, ``horizon`` otherwise."""
    return None if any(effect.target == "output" for effect in effects) else horizon


def fit_set(search: Search, est: GreyBoxSparseRegressor, effects):
    """`fit_continued` of ``est`` (the physics with ``effects``) over the set's shooting
    window: how an effect set and the final augmented physics are fitted on the record."""
    return fit_continued(est, search.u, search.z, set_horizon(effects, search.settings.horizon))


def quick_fit(search: Search, board, effects, warm):
    """``(estimation RMSE, fitted parameters)`` of the physics plus ``effects`` (switched on
    on ``board``), fitted as the set is kept (`fit_set`) and scored by the free run of the
    record. The parameters are those of ``effects`` and of the declared physics: a set is
    refitted and cross-validated from where its own fit ended, since an effect may move the
    declared parameters far (a sensor calibration rescales the levels the outflow laws act
    on).

    A proposed effect the record never exercises runs its level off toward infinity: that
    is the ranking's finding (the set scores as the one without it), so these fits do not
    raise [`RunawayParameterWarning`][sk_offwhite.RunawayParameterWarning]; the declared
    physics' fit and the final model's do."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RunawayParameterWarning)
        est = fit_set(search, search.estimator(board.model(effects, warm)), effects)
    fitted = {**declared_parameters(est, board), **effect_parameters(est, effects)}
    return record_rmse(est.predict(search.u), search.z), fitted


def effect_parameters(est, effects) -> dict:
    """The fitted free parameters of ``effects`` in ``est``, as
    [`Parameter`][sk_offwhite.Parameter]."""
    return {
        name: Parameter(est.parameters_[name], spec.bounds)
        for effect in effects
        for name, spec in effect.parameters().items()
        if not spec.fixed
    }


def declared_parameters(est, board) -> dict:
    """The fitted free parameters of ``board``'s declared physics (none of a candidate
    effect's), as [`Parameter`][sk_offwhite.Parameter] with the declared bounds."""
    switched = {name for effect in getattr(board, "board", ()) for name in effect.parameters()}
    return {
        name: Parameter(est.parameters_[name], spec.bounds)
        for name, spec in board.physics.parameters.items()
        if not spec.fixed and name not in switched and name in est.parameters_
    }


def label(effects) -> str:
    """How the trail names a set: its effects' names joined by ``+``."""
    return " + ".join(e.name for e in effects) if effects else "declared physics"


def size(effects) -> int:
    """The number of parameters ``effects`` add: what makes a set lighter."""
    return sum(len(effect.parameters()) for effect in effects)


def own(params: dict, effect) -> dict:
    """The entries of ``params`` that are ``effect``'s own parameters."""
    names = effect.parameters()
    return {name: value for name, value in params.items() if name in names}


def member_start(params: dict, effect) -> dict:
    """``effect``'s own entries of ``params`` (its single fit) as a start for a joint fit,
    each one that ended on a bound back at the effect's own start: a single fit that
    pushed a level to its bound (a Coulomb friction at 0, which only helps with a force
    offset) leaves no start from which the joint fit moves it."""
    spec = effect.parameters()
    return {name: _restarted(value, spec[name]) for name, value in own(params, effect).items()}


def _restarted(value, start: Parameter):
    """``value`` (a number or a `Parameter`), at ``start``'s value where it lies on one of
    ``start``'s bounds."""
    number = getattr(value, "value", value)
    on_bound = np.ndim(number) == 0 and any(
        b is not None and np.isclose(float(number), b, rtol=1e-9, atol=0.0) for b in start.bounds
    )
    if not on_bound:
        return value
    return replace(value, value=start.value) if isinstance(value, Parameter) else start.value


def without(params: dict, effect) -> dict:
    """The entries of ``params`` that are not ``effect``'s own parameters."""
    names = effect.parameters()
    return {name: value for name, value in params.items() if name not in names}
