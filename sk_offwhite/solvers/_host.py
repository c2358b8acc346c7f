r"""Levenberg-Marquardt driven from the host: for a linear solve that runs there.

The run of the coloured Jacobian (`sk_offwhite.solvers._coloured`) solves its sparse normal
equations with SciPy, outside any compiled program, so its iterations are a Python loop over
two callables under the same rules as the run on the device (`sk_offwhite.solvers._rules`).
"""

from __future__ import annotations

import numpy as np

from .._objective import n_fit_residuals
from ._core import SolverResult
from ._rules import (
    OUTCOMES,
    START_DAMPING,
    checked_scaling,
    creep_note,
    next_damping,
    progress_line,
    small_decrease,
    stop_code,
)

__all__ = ["lm_loop"]


def lm_loop(
    linearise, trial, free0, problem, *, max_iter, tol, verbose=0, scaling="per-variable"
) -> SolverResult:
    r"""The Levenberg-Marquardt iteration over a linearisation and a trial step.

    ``linearise(free)`` returns a state with ``free``, ``residual``, ``cost`` and ``diag``
    ($\mathrm{diag}(J^TJ)$) at ``free``; ``trial(state, damping, scale)`` the damped,
    projected candidate, its cost and the state there when the trial formed it (``None``:
    ``linearise`` forms it if the step is accepted), where ``scale`` is ``None`` with
    ``scaling='global'`` and the elementwise largest ``diag`` of the run so far with
    ``scaling='per-variable'``.
    """
    state = linearise(free0)
    scale = np.asarray(state.diag) if checked_scaling(scaling) == "per-variable" else None
    damping, history, code = START_DAMPING, [float(state.cost)], 0
    for iteration in range(1, max_iter + 1):
        candidate, trial_cost, reached = trial(state, damping, scale)
        accepted = np.bool_(np.isfinite(trial_cost) and trial_cost < history[-1])
        small = np.False_
        if accepted:
            previous = history[-1]
            state = linearise(candidate) if reached is None else reached
            scale = None if scale is None else np.maximum(scale, np.asarray(state.diag))
            history.append(float(state.cost))
            _show(progress_line(verbose, iteration, history[-1], damping))
            small = small_decrease(previous, history[-1], tol, np)
        code = int(stop_code(np.True_, accepted, small, damping, history[-1], np))
        damping = float(next_damping(np.True_, accepted, damping, np))
        if code:
            break
    return _result(state, history, iteration, code, problem)


def _show(line: str | None) -> None:
    if line is not None:
        print(line)


def _result(state, history, n_iter: int, code: int, problem) -> SolverResult:
    """The `SolverResult` of a run that ended with `stop_code` ``code`` at ``state``."""
    message = OUTCOMES[code] + ("" if code else creep_note(history))
    fit_part = np.asarray(state.residual)[: n_fit_residuals(problem.segments)]
    with np.errstate(over="ignore"):
        fit = float(fit_part @ fit_part)
    free = np.asarray(state.free)
    return SolverResult(free, history[-1], np.asarray(history), n_iter, code > 0, message, fit)
