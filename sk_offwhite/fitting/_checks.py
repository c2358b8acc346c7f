r"""What makes a finished fit no model although its solver converged.

- **Multiple shooting.** Each window can fit while the whole does not: the windows' own
  initial states absorb what the dynamics get wrong, and the continuity penalty only keeps
  the defects small, not zero. The model the user gets is the free run from each record's
  first state; it is judged directly. With zero defects the free run *is* the windows'
  concatenation, so its error equals the windows'; small defects add a little. The fit is
  refused when the free run's RMS error, in output standard deviations, is not finite or
  exceeds both `FREE_RUN_FACTOR` times the windows' RMS error and one standard deviation
  (worse than predicting the mean): then the defects, not the dynamics, carried the fit.
- **Inputs that no longer matter.** A fit can end where the simulated output does not depend
  on the inputs at all (an input gain driven to zero, a constant held by the initial
  state): a perturbation of the inputs along their own variation then moves the output by
  less than `INSENSITIVE` of it.
- **A stop at the edge of the physics' domain.** A solver that finds no descent step left
  claims a stationary point; when a change of one free parameter by `EDGE_NUDGE` of itself
  already makes the free run not finite, the trial steps were refused because the
  simulation left the physics' domain (a square root or a logarithm of a state the data
  take elsewhere), not because the cost stopped falling.
- **Every parameter at a bound.** The solver stopped against the box, not at a minimum.
- **Features that are not finite.** A dictionary term undefined where the model goes (a
  logarithm of a negative level) makes the cost not finite; it is named, with the sample.
"""

from __future__ import annotations

import numpy as np

from ..dictionaries import evaluate_matrix
from ..runtime._backend import to_device
from ..simulation._rollout import free_run_record

__all__ = [
    "EDGE_NUDGE",
    "FREE_RUN_FACTOR",
    "INSENSITIVE",
    "bound_reason",
    "edge_reason",
    "fit_problems",
    "non_finite_feature",
]

FREE_RUN_FACTOR = 10.0
"""How much worse than the windows' RMS error a multiple-shooting fit's free run may be
(and than one output standard deviation) before the fit is refused."""

NUDGE = 1e-6
"""The relative perturbation of the inputs (along their own variation) the check applies."""

INSENSITIVE = 1e-6
"""The relative sensitivity of the simulated output to that perturbation below which the
output does not depend on the inputs (a model that uses them has one of order 1)."""


def fit_problems(model, blocks, records, first_states, output_scale, windows_fit, horizon):
    """Why a converged fit is no model (the module docstring), or ``None``.

    ``blocks`` are the fitted blocks (numpy), ``first_states`` each record's initial state,
    ``windows_fit`` the fit term $F$ the solver minimised."""
    params = {k: to_device(v) for k, v in blocks.items() if k != "x0"}
    pairs = zip(records, first_states, strict=True)
    runs = [free_run_record(model, params, x0, u)[1] for (u, _), x0 in pairs]
    if horizon is not None:
        reason = _free_run_reason(runs, records, output_scale, windows_fit)
        if reason:
            return reason
    return _input_reason(model, params, records, first_states, runs)


def _free_run_reason(runs, records, output_scale, windows_fit) -> str | None:
    errors = [((run - z) / output_scale) ** 2 for run, (_, z) in zip(runs, records, strict=True)]
    with np.errstate(invalid="ignore", over="ignore"):
        free = float(np.sqrt(np.mean(np.concatenate(errors))))
    windows = float(np.sqrt(max(windows_fit, 0.0)))
    if np.isfinite(free) and free <= max(FREE_RUN_FACTOR * windows, 1.0):
        return None
    return (
        f"the shooting windows fit (RMS error {windows:.3g} output standard deviations) but "
        f"the free run over the record does not ({free:.3g}): the windows' own initial states "
        "carried the fit; refine it with horizon=None and warm_start=True, or use longer "
        "windows"
    )


def _input_reason(model, params, records, first_states, runs) -> str | None:
    """Why the output does not depend on the inputs (``None`` when it does)."""
    moved, scale = 0.0, 0.0
    for (u, _), x0, run in zip(records, first_states, runs, strict=True):
        variation = u - np.mean(u, axis=0)
        if u.shape[1] == 0 or not np.any(variation):
            return None  # no input, or a constant one: nothing to depend on
        nudged = free_run_record(model, params, x0, u + NUDGE * variation)[1]
        with np.errstate(invalid="ignore", over="ignore"):
            moved += float(np.sum((nudged - run) ** 2))
            scale += float(np.sum(run**2)) + 1e-300
    if not np.isfinite(moved) or np.sqrt(moved / scale) > NUDGE * INSENSITIVE:
        return None
    return (
        "the fitted output does not depend on the inputs (its input sensitivities are zero: "
        "a gain driven to zero, the output held by the initial state); start from other "
        "parameter values"
    )


EDGE_NUDGE = 1e-4
"""The relative change of one free parameter with which `edge_reason` probes whether
a claimed stationary point sits on the edge of where the simulation is finite."""


def edge_reason(model, blocks, records, first_states, physics) -> str | None:
    """Why a fit that stopped with no descent step left sits where the simulation stops
    being finite (the module docstring), or ``None``."""
    theta = np.asarray(blocks["theta"], float)
    params = {k: to_device(v) for k, v in blocks.items() if k != "x0"}
    for j, name in enumerate(physics.parameter_names):
        if physics.parameters[name].fixed:
            continue
        for sign in (1.0, -1.0):
            nudged = theta.copy()
            nudged[j] += sign * EDGE_NUDGE * max(abs(theta[j]), 1e-12)
            if not _finite_runs(
                model, params | {"theta": to_device(nudged)}, records, first_states
            ):
                return (
                    f"the fit stopped where the simulation stops being finite: changing {name} "
                    f"by {sign * EDGE_NUDGE:+.0e} of itself makes the free run NaN or inf, so "
                    "the solver's steps were refused at the edge of the domain of physics.step "
                    "(a square root or logarithm of a state that the data take elsewhere), not "
                    "at a minimum; write the physics so it is defined where the data go"
                )
    return None


def _finite_runs(model, params, records, first_states) -> bool:
    for (u, _), x0 in zip(records, first_states, strict=True):
        if not np.all(np.isfinite(free_run_record(model, params, x0, u)[1])):
            return False
    return True


def bound_reason(physics, theta) -> str | None:
    """Why a fit whose every free parameter sits at a bound is no minimum (or ``None``)."""
    free = np.array([not p.fixed for p in physics.parameters.values()], bool)
    if not free.any():
        return None
    lower, upper = physics.parameter_bounds()
    fitted = np.asarray(theta, float)
    at_bound = (np.isfinite(lower) & np.isclose(fitted, lower)) | (
        np.isfinite(upper) & np.isclose(fitted, upper)
    )
    if not np.all(at_bound[free]):
        return None
    names = [n for n, f in zip(physics.parameter_names, free, strict=True) if f]
    return (
        f"every free parameter ({', '.join(names)}) ended at a bound: the solver stopped "
        "against the box, not at a minimum; widen the bounds or start elsewhere"
    )


def non_finite_feature(basis, states, inputs) -> str | None:
    """The first dictionary feature that is not finite on ``[states, inputs]`` (rows of a
    free run) where they are, named with its sample, or ``None`` (a row whose states are
    not finite is the simulation's failure, not the feature's)."""
    if basis is None:
        return None
    values = np.hstack([states, inputs])
    phi = np.asarray(evaluate_matrix(basis, basis.init_params, values))[:, 0, :]
    bad = ~np.isfinite(phi) & np.all(np.isfinite(values), axis=1)[:, None]
    if not bad.any():
        return None
    sample, column = np.argwhere(bad)[0]
    at = ", ".join(
        f"{name}={value:.4g}"
        for name, value in zip(basis.input_features, values[sample], strict=True)
    )
    return (
        f"library feature {basis.names[column]!r} is not finite at sample {sample} of the "
        f"simulated record ({at}): every term of the dictionary must be defined where the "
        "model goes"
    )
