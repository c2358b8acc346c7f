r"""Whether a solver's answer is a model: the honest ``converged_``.

A solver stops at a point where its own rule is met (a small relative decrease, no descent
step left, no improvement for a while). From a guess whose simulation explodes every one of
these rules can be met at a cost of $10^{200}$. The verdict looks at the fit term
$F$ (the normalised simulation MSE of `_objective`, in units of
the output variance, so that predicting each output's mean scores $F = 1$) and calls
the run a failure when

* $F$ is not finite: the fitted model's simulation overflows;
* $F >$ `NO_MODEL_FIT`: the RMS simulation error exceeds ten output standard
  deviations;
* the free variables never moved and $F > 1$: the solver stayed at a guess that
  simulates worse than the outputs' means.
"""

from __future__ import annotations

import numpy as np

from ..simulation._objective import n_fit_residuals
from ..solvers._core import SolverResult, fit_cost

__all__ = [
    "NO_MODEL_FIT",
    "RUNAWAY_FACTOR",
    "judged",
    "needs_restart",
    "runaway_parameters",
    "with_fit_term",
]

NO_MODEL_FIT = 1e2
"""Normalised fit term above which a fitted model is no model (RMS error of 10 output
standard deviations)."""


def with_fit_term(result: SolverResult, problem, model, layout) -> SolverResult:
    """``result`` with its fit term $F$ filled in (one forward simulation if the
    solver did not report it)."""
    if np.isfinite(result.fit):
        return result
    n_fit = n_fit_residuals(problem.segments)
    value = fit_cost(result.free, problem, model=model, layout=layout, n_fit=n_fit)
    return result._replace(fit=float(value))


def failure_reason(fit: float, moved: bool) -> str | None:
    """Why a fit with fit term ``fit`` is no model (``None`` when it is one)."""
    if not np.isfinite(fit):
        return "the fitted model's simulation is not finite"
    if fit > NO_MODEL_FIT:
        return (
            f"the fitted model simulates the data with an RMS error of {np.sqrt(fit):.3g} "
            "output standard deviations"
        )
    if not moved and fit > 1.0:
        return (
            "the solver never left an initial guess that simulates worse than the mean (its "
            "derivatives there may not be finite, as a square root of a state started at "
            "zero gives: give physics.x0 a guess inside the physics' domain)"
        )
    return None


def judged(result: SolverResult, free0) -> SolverResult:
    """``result`` with ``converged=False`` and the reason in ``message`` when the fitted
    model is no model (see the module docstring); unchanged otherwise."""
    moved = not np.array_equal(np.asarray(result.free), np.asarray(free0))
    reason = failure_reason(result.fit, moved)
    if reason is None:
        return result
    advice = "start from other parameter values or initial states"
    message = f"{reason} (solver: {result.message}); {advice}"
    return result._replace(converged=False, message=message)


def needs_restart(result: SolverResult) -> bool:
    """Whether a judged result is worth a restart: its simulation explodes (fit term not
    finite or above `NO_MODEL_FIT`), or the solver stopped unconverged at a model
    that simulates worse than the outputs' means."""
    worse_than_mean = not result.converged and not result.fit <= 1.0
    return not result.fit <= NO_MODEL_FIT or worse_than_mean


RUNAWAY_FACTOR = 1e6
"""Factor by which a fitted parameter's magnitude must exceed its declared start's for
`runaway_parameters` to name it (a ratio: the same in any units)."""


def runaway_parameters(physics, theta) -> list[tuple[str, float, float]]:
    r"""``(name, start, fitted)`` of each free parameter of ``physics`` whose fitted value
    ``theta`` (declaration order) ran away from its declared start $\theta_0$:
    $|\hat\theta| >$ `RUNAWAY_FACTOR` $|\theta_0|$, unless it sits at a
    finite bound the user declared. A parameter started at zero has no scale to compare
    with and is not judged.

    Such a value is seldom a measurement: the simulation no longer depends on the
    parameter there (a load's time constant at $10^{19}$ s switches its
    discharge off), and the fit ran along a direction the data do not determine.
    """
    start = physics.parameter_values()
    fitted = np.asarray(theta, float)
    lower, upper = physics.parameter_bounds()
    free = np.array([not p.fixed for p in physics.parameters.values()])
    at_bound = np.isclose(fitted, lower) | np.isclose(fitted, upper)
    too_far = np.abs(fitted) > RUNAWAY_FACTOR * np.abs(start)
    runaway = free & (start != 0) & ~at_bound & too_far
    return [
        (name, float(start[k]), float(fitted[k]))
        for k, name in enumerate(physics.parameter_names)
        if runaway[k]
    ]
