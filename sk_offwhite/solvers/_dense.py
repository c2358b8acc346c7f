r"""The dense Levenberg-Marquardt step: the normal equations of the whole Jacobian.

At the current iterate the state holds the residual $r$, $J^TJ$, $J^Tr$ and the penalised
cost with the smoothed $\ell_1$ term majorised there (a reweighted least-squares anchor, so
that the majoriser is exact at the anchor and a lower majorised cost is a lower penalised
cost). `_lm_advance` takes one damped step $(J^TJ + \mu D)\,s = -J^Tr$ over the variables
that can move, projects it on the box bounds, simulates the candidate and, if it is
accepted, linearises there: one compiled program per model and layout.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..simulation._layout import Layout
from ..simulation._objective import majoriser_constant
from ..simulation._rollout import Model
from ._core import Problem, _omega, free_residuals, linearised
from ._rules import damped_diagonal, held_at_bound

__all__ = ["damped_candidate", "first_state", "majorised_cost"]


class _LMState(NamedTuple):
    r"""Levenberg-Marquardt's state at ``free``: the residual, the normal equations
    ($J^TJ$, $J^Tr$), the penalised cost with the L1 term majorised at
    ``anchor`` ($\Omega$ at ``free``) and $\mathrm{diag}(J^TJ)$."""

    free: jax.Array
    residual: jax.Array
    jtj: jax.Array
    gradient: jax.Array
    cost: jax.Array
    anchor: jax.Array
    diag: jax.Array


def _anchored(problem: Problem, anchor) -> Problem:
    """``problem`` whose L1 term is majorised at ``anchor`` (see ``majorised_l1``)."""
    return problem._replace(weights=problem.weights._replace(l1_anchor=anchor))


def _penalised(r, anchored: Problem):
    """The penalised cost from the residuals of ``anchored`` (L1 term majorised at its
    anchor): their squares and the majoriser's constant."""
    weights = anchored.weights
    return r @ r + majoriser_constant(weights.l1_anchor, anchored.omega_free, weights)


def _state_at(free, problem: Problem, model: Model, layout: Layout, forward: bool) -> _LMState:
    """LM state at ``free``, the L1 term majorised there."""
    anchor = _omega(free, problem, layout)
    anchored = _anchored(problem, anchor)
    fun = partial(free_residuals, problem=anchored, model=model, layout=layout)
    r, jac = linearised(fun, free, forward)
    cost = _penalised(r, anchored)
    return _LMState(free, r, jac.T @ jac, jac.T @ r, cost, anchor, jnp.sum(jac**2, axis=0))


def damped_candidate(free, jtj, gradient, damping, scale, lower, upper):
    r"""Damped Gauss-Newton step $(J^TJ + \mu D)\,s = -J^Tr$ from ``free``,
    projected on the box ``[lower, upper]``; ``scale`` is the per-variable floors'
    reference or ``None`` (see `damped_diagonal`).

    Variables held at a bound by the gradient (at the lower bound with $J^Tr > 0$,
    at the upper with $J^Tr < 0$) take no part in the step: the others solve the
    system without them. Clipping a step computed with them in would move the others as
    if the held variable had moved too, and a run can then alternate accepted and
    rejected steps until ``max_iter``."""
    moving = ~held_at_bound(free, gradient, lower, upper)
    jtj = jnp.where(jnp.outer(moving, moving), jtj, 0.0)
    system = jtj + jnp.diag(damped_diagonal(jnp.diag(jtj), damping, moving, jnp, scale))
    step = jnp.linalg.solve(system, jnp.where(moving, -gradient, 0.0))
    return jnp.clip(free + step, lower, upper)


def _majorised_at(free, anchor, problem: Problem, model: Model, layout: Layout):
    """Residuals and penalised cost at ``free`` with the L1 term majorised at ``anchor``:
    one forward simulation, no derivative."""
    anchored = _anchored(problem, anchor)
    r = free_residuals(free, anchored, model, layout)
    return r, _penalised(r, anchored)


def _unreached(candidate, residual, cost, anchor) -> _LMState:
    """What `_lm_advance` returns for a rejected candidate: its residual and cost at
    the old anchor, no normal equations (the iteration reads neither)."""
    n, dtype = candidate.shape[0], candidate.dtype
    zeros = jnp.zeros(n, dtype)
    return _LMState(candidate, residual, jnp.zeros((n, n), dtype), zeros, cost, anchor, zeros)


@partial(jax.jit, static_argnames=("model", "layout", "forward"))
def _lm_advance(origin, damping, scale, step, problem, *, model, layout, forward):
    """One Levenberg-Marquardt iteration in one program. ``origin`` is ``(free, jtj,
    gradient, anchor, cost)`` of the current state (`_origin`). Returns the LM state
    at the damped step's candidate (`damped_candidate`; with ``step`` false there is
    no step and it is the state at ``free``), the candidate's cost with the L1 term
    majorised at ``anchor`` (below the current cost, the penalised cost has decreased: the
    majoriser is tight at its anchor) and whether the candidate was accepted; the state of
    a rejected one holds placeholders.

    The candidate is simulated first; its Jacobian is formed (in a ``lax.cond`` branch)
    only when its cost is finite and below the current one, so a rejected candidate costs
    one forward simulation. One program per model and layout holds the step, the
    simulation and the linearisation."""
    free, jtj, gradient, anchor, cost = origin
    stepped = damped_candidate(free, jtj, gradient, damping, scale, problem.lower, problem.upper)
    candidate = jnp.where(step, stepped, free)
    residual, trial_cost = _majorised_at(candidate, anchor, problem, model, layout)
    accepted = jnp.logical_not(step) | (jnp.isfinite(trial_cost) & (trial_cost < cost))
    new = jax.lax.cond(
        accepted,
        lambda: _state_at(candidate, problem, model, layout, forward),
        lambda: _unreached(candidate, residual, trial_cost, anchor),
    )
    return new, trial_cost, accepted


def majorised_cost(free, anchor, problem, model, layout):
    """Penalised cost at ``free`` with the L1 term majorised at ``anchor``."""
    return _majorised_at(free, anchor, problem, model, layout)[1]


def _origin(state: _LMState) -> tuple:
    """What `_lm_advance` steps from: ``(free, jtj, gradient, anchor, cost)``."""
    return state.free, state.jtj, state.gradient, state.anchor, state.cost


def first_state(free, problem: Problem, *, model, layout, forward, scaling) -> _LMState:
    r"""The LM state at ``free``: `_lm_advance` without a step, so that the run's
    first state and its iterations share one program. Its origin's normal equations and
    anchor (zeros of $\Omega$'s shape) are never read; ``scale`` is passed as the
    iterations pass it (an array with per-variable scaling, ``None`` with global)."""
    n = free.shape[0]
    omega_shape = dict(layout.blocks).get("omega", (0,))
    origin = (free, np.zeros((n, n)), np.zeros(n), np.zeros(omega_shape), np.array(np.inf))
    scale = np.ones(n) if scaling == "per-variable" else None
    static = dict(model=model, layout=layout, forward=forward)
    return _lm_advance(origin, 1.0, scale, False, problem, **static)[0]
