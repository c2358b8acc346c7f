r"""Levenberg-Marquardt with its whole run on the device: one program, one dispatch.

The iterations of the dense step (`sk_offwhite.solvers._dense`) run inside one
``lax.while_loop`` under the rules of `sk_offwhite.solvers._rules`, in double precision; the
first pass evaluates the start (no step), so the iteration is traced once, in the loop. A
``verbose`` run prints its progress from inside the loop through a host callback, which
leaves the iterations as they are.

The free vector of a model with switched effects is padded with inert variables to a
multiple of ``Model.free_multiple`` (`_padded`): fits with different switch settings (the
closed loop's candidates on one switchboard) then share one program. The padding adds zero
rows and columns to the normal equations, so the iterates are the same up to rounding.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._layout import Layout
from .._objective import n_fit_residuals
from .._rollout import Model
from ._core import Problem, SolverResult, forward_mode
from ._dense import _lm_advance, _LMState, _origin
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

__all__ = ["levenberg_marquardt_on_device"]


class _Run(NamedTuple):
    """The loop's carry: the last accepted state (its residual left out, an empty array:
    the loop needs only the fit term $F$ of it), $F$ there, Marquardt's
    per-variable scale, the damping, the accepted costs so far
    (``history[: n_accepted + 1]``), the passes made (the first evaluates the start, each
    later one is a trial step) and the outcome (an index of `OUTCOMES`, 0 while
    running)."""

    state: _LMState
    fit: jax.Array
    scale: jax.Array
    damping: jax.Array
    history: jax.Array
    n_accepted: jax.Array
    passes: jax.Array
    outcome: jax.Array


def _start(free0, omega_shape, max_iter: int) -> _Run:
    """The carry before the first pass, built on the host: a state of the right shapes at
    ``free0`` with an infinite cost (the first pass replaces it) and ``max_iter + 1``
    slots of history."""
    n = free0.shape[0]
    state = _LMState(
        free0, np.zeros(0), np.zeros((n, n)), np.zeros(n), np.array(np.inf),
        np.zeros(omega_shape), np.zeros(n),
    )  # fmt: skip
    history = np.full(max_iter + 1, np.nan)
    counts = (np.array(0), np.array(0), np.array(0))
    return _Run(state, np.array(np.nan), np.ones(n), np.array(START_DAMPING), history, *counts)


def _pass(run: _Run, problem: Problem, tol, *, model, layout, forward, per_variable, verbose):
    """One pass: the start's evaluation (first pass) or a trial step and its verdict."""
    step = run.passes > 0
    damping = jnp.where(step, run.damping, 1.0)
    scale = jnp.where(step, run.scale, 1.0) if per_variable else None
    static = dict(model=model, layout=layout, forward=forward)
    new, _, accepted = _lm_advance(_origin(run.state), damping, scale, step, problem, **static)
    fit_part = new.residual[: n_fit_residuals(problem.segments)]
    new = new._replace(residual=run.state.residual)
    small = small_decrease(run.state.cost, new.cost, tol)
    grown = jnp.where(step, jnp.maximum(run.scale, new.diag), new.diag)
    n_accepted = run.n_accepted + (accepted & step)
    if verbose:
        _report_progress(verbose, step & accepted, run.passes, new.cost, damping)
    return _Run(
        jax.tree.map(partial(jnp.where, accepted), new, run.state),
        jnp.where(accepted, fit_part @ fit_part, run.fit),
        jnp.where(accepted, grown, run.scale),
        next_damping(step, accepted, run.damping),
        jnp.where(accepted, run.history.at[n_accepted].set(new.cost), run.history),
        n_accepted,
        run.passes + 1,
        stop_code(step, accepted, small, damping, new.cost),
    )


def _report_progress(verbose: int, accepted, iteration, cost, damping) -> None:
    """Print `progress_line` from inside the loop after an accepted step (a host callback:
    the loop's values are left as they are)."""

    def show(accepted, iteration, cost, damping):
        line = progress_line(verbose, int(iteration), float(cost), float(damping))
        if bool(accepted) and line is not None:
            print(line)

    jax.debug.callback(show, accepted, iteration, cost, damping, ordered=True)


@partial(jax.jit, static_argnames=("model", "layout", "forward", "per_variable", "verbose"))
def _run_on_device(start: _Run, problem, tol, *, model, layout, forward, per_variable, verbose=0):
    """The whole run from ``start`` (`_start`): the start's evaluation, then trial
    steps until a stopping rule fires or the history is full."""
    static = dict(
        model=model, layout=layout, forward=forward, per_variable=per_variable, verbose=verbose
    )
    max_iter = start.history.shape[0] - 1

    def going(run: _Run):
        return (run.outcome == 0) & (run.passes <= max_iter)

    return jax.lax.while_loop(going, partial(_pass, problem=problem, tol=tol, **static), start)


PAD_TO = 4
"""The granularity of the size to which the device run pads the free vector of a model with
switched effects (``Model.free_multiple``, `padded_size`), so that fits with
different switch settings share one program."""


def padded_size(n_free: int, multiple: int) -> int:
    """``n_free`` rounded up to a multiple of ``multiple``."""
    return -(-n_free // multiple) * multiple


def _padded(free0, problem: Problem, n_entries: int, size: int):
    """``free0`` and ``problem`` with ``size - len(free0)`` inert variables appended: frozen
    (``active`` 0), held at 0 by their bounds, and written nowhere (their index is past the
    ``n_entries`` entries of the parameter vector, where the scatter drops them), so their
    Jacobian columns and gradient entries are zero and every step leaves them at 0."""
    extra = size - np.shape(free0)[0]
    if extra == 0:
        return free0, problem

    def grown(values, fill):
        values = np.asarray(values)
        return np.concatenate([values, np.full(extra, fill, dtype=values.dtype)])

    padded = problem._replace(
        free_index=grown(problem.free_index, n_entries),
        lower=grown(problem.lower, 0.0),
        upper=grown(problem.upper, 0.0),
        active=grown(problem.active, 0.0),
    )
    return grown(free0, 0.0), padded


def device_run(free0, problem: Problem, model: Model, layout: Layout, max_iter, scaling):
    """What `_run_on_device` takes for a run from ``free0``: ``(start, problem,
    static)``, the start carry (`_start`), the problem with its free vector padded
    (`_padded`) and the static arguments."""
    forward = forward_mode(free0, problem, model, layout)
    omega_shape = dict(layout.blocks).get("omega", (0,))
    size = padded_size(np.shape(free0)[0], model.free_multiple)
    free0, problem = _padded(free0, problem, layout.size, size)
    start = _start(free0, omega_shape, int(max_iter))
    per_variable = checked_scaling(scaling) == "per-variable"
    static = dict(model=model, layout=layout, forward=forward, per_variable=per_variable)
    return start, problem, static


def levenberg_marquardt_on_device(
    free0,
    problem: Problem,
    model: Model,
    layout: Layout,
    *,
    max_iter: int,
    tol: float,
    verbose: int = 0,
    scaling: str = "per-variable",
) -> SolverResult:
    r"""Projected Levenberg-Marquardt on $\|r(\cdot)\|^2$ with the dense Jacobian (the rules of
    `sk_offwhite.solvers._rules`), the whole run in one program; ``verbose`` prints the
    progress from inside it."""
    start, problem, static = device_run(free0, problem, model, layout, max_iter, scaling)
    run = jax.device_get(_run_on_device(start, problem, tol, verbose=int(verbose), **static))
    n_free = np.shape(free0)[0]
    history = np.asarray(run.history[: int(run.n_accepted) + 1])
    outcome = int(run.outcome)
    message = OUTCOMES[outcome] + ("" if outcome else creep_note(history))
    n_iter, free = int(run.passes) - 1, np.asarray(run.state.free)[:n_free]
    cost = float(history[-1])
    return SolverResult(free, cost, history, n_iter, outcome > 0, message, float(run.fit))
