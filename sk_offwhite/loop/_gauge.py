r"""Directions the data do not determine in the augmented physics, and a parameter held on each.

An added effect can leave the augmented physics without a scale: a sensor calibration
$z = x + c_0 + c_1 \xi + c_2 \xi^2$ ($\xi$ the centred, scaled level) on a
level $x$ whose dynamics a rescaling $x \to a x$ leaves unchanged (the inflow's
gain times $a$, Torricelli's outflow coefficient times $\sqrt a$, an overflow's
level times $a$) reads the same output for every $a$, up to what a bound or a
fixed corner breaks. Along that orbit the fit is flat or nearly so: its standard errors
describe the orbit, not the measurements, and the cross-validation folds land at different
points of it.

A direction counts as undetermined when the Gauss-Newton standard error of the relative
change along it, $\hat\sigma/\sqrt{\mu}$ for an eigenpair $(\mu, v)$ of
$D J^\top J D$ ($J$ the Jacobian of the simulated outputs, $D =
\operatorname{diag}|p|$, $\hat\sigma^2$ the residual variance, as in
[`identifiability`][sk_offwhite.certify.identifiability]), is at least `MAX_RELATIVE_ERROR`, or
when $\mu$ is below the verdict's tolerance (a singular matrix): the data then leave
the loaded parameters uncertain by half their values or more, whatever their units.

On each such direction along which variables of two sources trade off (each loading by
`MIN_EFFECT_LOADING`; a source is an added effect, or the declared physics with the
initial states), one parameter of an added effect is held at its fitted value (the one
that loads most): the effect made the direction, and the declared parameters keep what
the physics says of them. A direction the declared physics has on its own is left to the
user (the identifiability verdict reports it), as are initial states; so is a direction
within one effect's parameters, the uncertainty of that effect's own size or shape (a
calibration the data cannot tell from none has its coefficients fitted near zero, where any
small absolute change is a large relative one), which the effect set's cross-validation
judges.
"""

from __future__ import annotations

import jax
import numpy as np

from ..certify._ident_problem import local_problem
from ..certify._identifiability import (
    direction_loadings,
    fit_residual_and_jacobian,
    flat_indices,
    relative_spectrum,
    variable_scales,
)
from ..model._physics import Parameter, PhysicsModel

__all__ = [
    "fit_undetermined_directions",
    "held_note",
    "held_parameters",
    "holding",
    "undetermined_directions",
]

RTOL = 1e-9
r"""The relative eigenvalue below which $D J^\top J D$ counts as singular (the
default tolerance of [`identifiability`][sk_offwhite.certify.identifiability])."""

MAX_RELATIVE_ERROR = 0.5
"""The standard error of a relative change along a direction (in units of the
parameters' own values) from which the data count as not determining it. A scale an added
effect takes away has an error of the order of the values themselves, and the directions
the data determine are far below it, so half the values separates the two."""

MIN_EFFECT_LOADING = 0.1
"""The loading (in a unit eigenvector of relative changes) from which an added effect's
parameter counts as being on a direction."""


def relative_errors(values, jacobian, residual, rtol: float = RTOL):
    r"""Eigenvectors of $D J^\top J D$ (columns) and the standard error of the
    relative change along each (``inf`` where the matrix is singular)."""
    scales = variable_scales(values)
    eigenvalues, eigenvectors = relative_spectrum(jacobian.T @ jacobian, scales)
    variance = residual @ residual / max(residual.size - scales.size, 1)
    flat = np.zeros(eigenvalues.size, bool)
    flat[flat_indices(eigenvalues, rtol)] = True
    errors = np.sqrt(variance / np.where(flat, 1.0, eigenvalues))
    return eigenvectors, np.where(flat, np.inf, errors)


def undetermined_directions(
    names, values, jacobian, residual, max_relative_error: float = MAX_RELATIVE_ERROR
) -> tuple:
    r"""The directions of a fit the data do not determine, ``{name: loading}`` each
    (largest loading first): the eigenvectors of $D J^\top J D$ along which the
    relative standard error (`relative_errors`) reaches ``max_relative_error``.
    ``names`` and ``values`` are the fit's variables, ``jacobian`` $\partial \hat
    z/\partial p$ (one row per measured value) and ``residual`` $\hat z - z$."""
    eigenvectors, errors = relative_errors(np.asarray(values, float), jacobian, residual)
    weak = np.flatnonzero(errors >= max_relative_error)
    return tuple(direction_loadings(eigenvectors[:, i], names) for i in weak)


def fit_undetermined_directions(est, u, z) -> tuple:
    """`undetermined_directions` of a fitted estimator on its record (its free
    parameters and initial states; the Jacobian in double precision)."""
    with jax.enable_x64(True):
        local = local_problem(est, u, z, None, False)
        residual, jacobian = fit_residual_and_jacobian(local)
    return undetermined_directions(local.names, local.values, jacobian, residual)


def _held_on(direction: dict[str, float], sources: dict[str, str], holdable) -> str | None:
    """The parameter of ``holdable`` of largest loading on ``direction`` when it loads by
    `MIN_EFFECT_LOADING` and a variable of another source does too, else ``None``.
    ``sources`` maps each added effect's parameter to its effect's name; the other
    variables (the declared physics' and the initial states) are one source. A direction
    within one effect is the uncertainty of its own size or shape, which the effect set's
    CV judges, not a trade-off."""
    traded = [name for name, value in direction.items() if abs(value) >= MIN_EFFECT_LOADING]
    loads = {name: abs(direction[name]) for name in traded if name in holdable}
    if len({sources.get(name) for name in traded}) < 2 or not loads:
        return None
    return max(loads, key=loads.get)


def held_parameters(directions, physics: PhysicsModel, effects, fitted: dict) -> dict:
    """``{name: fitted value}`` of the parameter held on each undetermined direction.

    Parameters
    ----------
    directions : sequence of dict
        The undetermined directions, ``{name: loading}``
        (`undetermined_directions`).
    physics : PhysicsModel
        The augmented physics that was fitted.
    effects : sequence of Effect
        The effects added to it, whose free parameters may be held.
    fitted : dict
        The fitted parameter values (``parameters_``).

    Returns
    -------
    dict
        At most one parameter per direction, each held once, in the directions' order;
        empty when no added effect loads on any direction.
    """
    free = {name for name, spec in physics.parameters.items() if not spec.fixed}
    sources = {name: effect.name for effect in effects for name in effect.parameters()}
    held: dict[str, float] = {}
    for direction in directions:
        name = _held_on(direction, sources, (free & set(sources)) - set(held))
        if name is not None:
            held[name] = float(fitted[name])
    return held


def holding(physics: PhysicsModel, held: dict) -> PhysicsModel:
    """``physics`` with the parameters of ``held`` fixed at its values (bounds kept)."""
    fixed = {
        name: Parameter(value, physics.parameters[name].bounds, fixed=True)
        for name, value in held.items()
    }
    return physics.with_parameters(**fixed)


def held_note(held: dict, directions, rmse: tuple, cv: tuple) -> str:
    """The report's sentence on the ``held`` parameters: the directions they remove (the
    other variables that load by `MIN_EFFECT_LOADING` on the direction each loads on
    most), the estimation RMSE before and after (the fit is unchanged) and the CV RMSE
    before and after (the folds no longer wander along the directions)."""
    parts = []
    for name, value in held.items():
        direction = max(directions, key=lambda d: abs(d.get(name, 0.0)))
        loads = {other: abs(load) for other, load in direction.items() if other != name}
        others = ", ".join(n for n, load in loads.items() if load >= MIN_EFFECT_LOADING)
        parts.append(f"{name} = {value:.4g} (with {others})")
    return (
        "The data do not determine every parameter of the augmented physics' fit (a "
        "direction along which the relative standard error is at least "
        f"{MAX_RELATIVE_ERROR:g}, or that they do not determine at all); one added effect's "
        "parameter is held at its fitted value on each: "
        + "; ".join(parts)
        + f". Estimation RMSE {rmse[0]:.4g} -> {rmse[1]:.4g}; CV RMSE {cv[0]:.4g} -> "
        f"{cv[1]:.4g}."
    )


def held_on_fit(physics, est, u, z, effects) -> tuple[dict, tuple]:
    """``(held, directions)``: the directions of ``est``'s fit (of ``physics``, ``effects``
    added) the data do not determine (none when they cannot be computed) and
    ``{name: fitted value}`` of the parameter held on each (`held_parameters`)."""
    try:
        directions = fit_undetermined_directions(est, u, z)
    except (ValueError, TypeError, FloatingPointError, np.linalg.LinAlgError):
        directions = ()
    return held_parameters(directions, physics, effects, est.parameters_), directions
