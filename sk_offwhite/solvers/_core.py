r"""What every solver shares: the problem, the residual of the free variables, its derivatives.

A minimisation is the free vector of decision variables and a `Problem` (the dynamic data:
records, bounds, weights); the model and the layout of the blocks are static (``jit``
arguments), so a solver's programs are traced once per structure and record layout.
Derivatives: the residual Jacobian $J$ (``R x P``) is formed in forward mode when
$P \le R$ (few parameters, long records: the usual grey-box case) and in reverse mode
otherwise (`linearised`).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .._backend import fused_loops
from .._layout import Layout
from .._objective import CostWeights, n_fit_residuals, residuals
from .._rollout import Model
from .._segments import Segments

__all__ = [
    "Problem",
    "SolverResult",
    "fit_cost",
    "forward_mode",
    "free_residuals",
    "jacobian_columns",
    "linearised",
    "n_residuals",
    "pushed_forward",
]


class Problem(NamedTuple):
    """Dynamic data of one minimisation (a pytree: every leaf is an array)."""

    segments: Segments
    base: jax.Array
    free_index: jax.Array
    lower: jax.Array
    upper: jax.Array
    omega_free: jax.Array
    weights: CostWeights
    active: jax.Array


class SolverResult(NamedTuple):
    """Outcome of a solver run: best finite iterate and its diagnostics.

    ``fit`` is the normalised fit term $F$ at ``free`` (``nan`` where the solver did
    not compute it separately from ``cost``).
    """

    free: np.ndarray
    cost: float
    history: np.ndarray
    n_iter: int
    converged: bool
    message: str
    fit: float = float("nan")


def free_residuals(free, problem: Problem, model: Model, layout: Layout):
    """Residual vector as a function of the free variables only.

    Entries where ``problem.active`` is 0 are frozen: they keep their value, and their
    derivatives (Jacobian columns, gradient entries) are exactly zero, so every solver leaves
    them where they are. Freezing is data, not structure: it does not re-trace.
    """
    free = jnp.where(problem.active > 0, free, jax.lax.stop_gradient(free))
    params = layout.unflatten(problem.base.at[problem.free_index].set(free, mode="drop"))
    return residuals(model, params, problem.segments, problem.omega_free, problem.weights)


@partial(jax.jit, static_argnames=("model", "layout", "n_fit"))
def fit_cost(free, problem: Problem, *, model: Model, layout: Layout, n_fit: int):
    r"""The fit term $F = \|r_{fit}\|^2$ alone (the first ``n_fit`` residuals)."""
    r = free_residuals(free, problem, model, layout)[:n_fit]
    return r @ r


@partial(jax.jit, static_argnames=("model", "layout"))
def jacobian_columns(free, problem: Problem, columns, *, model: Model, layout: Layout):
    """Residuals and the Jacobian columns of the free variables at ``columns`` (forward mode).

    One tangent per column (a ``vmap`` of ``jvp``), so the cost grows with the number of
    columns asked for, not with the number of free variables.
    """
    fun = partial(free_residuals, problem=problem, model=model, layout=layout)
    tangents = jax.nn.one_hot(columns, free.shape[0], dtype=free.dtype)
    residual = fun(free)
    return residual, jax.vmap(lambda t: jax.jvp(fun, (free,), (t,))[1], out_axes=-1)(tangents)


def _omega(free, problem: Problem, layout: Layout):
    r"""$\Omega$ at the free vector ``free`` (an empty array without a dictionary)."""
    params = layout.unflatten(problem.base.at[problem.free_index].set(free, mode="drop"))
    return params.get("omega", jnp.zeros(0))


LINEARIZE_MAX_FREE = 10
"""Up to this many free variables, and unless the loops are fused
([`enable_fused_loops`][sk_offwhite.enable_fused_loops]), the forward-mode Jacobian pushes the
tangents through one linearisation (``jax.linearize``), which is the faster on XLA's default
loops for few tangents; otherwise through a ``vmap`` of ``jvp``."""


def _through_linearisation(n_tangents: int) -> bool:
    """Whether the forward-mode Jacobian of ``n_tangents`` columns goes through
    ``jax.linearize`` rather than ``jacfwd`` (see `LINEARIZE_MAX_FREE`)."""
    return n_tangents <= LINEARIZE_MAX_FREE and not fused_loops()


def pushed_forward(fun, x, tangents):
    """``(fun(x), J t)`` for each row ``t`` of ``tangents`` (the columns of the result), in
    one pass: through ``jax.linearize`` or a ``vmap`` of ``jvp``, by
    `_through_linearisation`. The value comes with the tangents, unbatched: ``fun``
    is simulated once."""
    if _through_linearisation(tangents.shape[0]):
        value, linear = jax.linearize(fun, x)
        return value, jax.vmap(linear, out_axes=-1)(tangents)
    return jax.vmap(lambda t: jax.jvp(fun, (x,), (t,)), out_axes=(None, -1))(tangents)


def linearised(fun, x, forward: bool = True):
    """``(fun(x), Jacobian of fun at x)``: forward mode (`pushed_forward` of the
    identity) or reverse mode (``jacrev``, for problems wider than long). ``fun`` is traced
    once: its value comes out of the differentiation, not from a second call."""
    if forward:
        return pushed_forward(fun, x, jnp.eye(x.shape[0], dtype=x.dtype))

    def with_value(y):
        value = fun(y)
        return value, value

    jac, value = jax.jacrev(with_value, has_aux=True)(x)
    return value, jac


_residuals_program = jax.jit(free_residuals, static_argnames=("model", "layout"))
"""`free_residuals` jitted, only for its shape: ``eval_shape`` traces it once per
model, layout and array shapes and keeps the trace with the package's other programs."""


def forward_mode(free, problem: Problem, model: Model, layout: Layout) -> bool:
    """Whether the Jacobian is formed in forward mode: no more free variables than
    residuals. The fit residuals alone (the leading `n_fit_residuals`) settle it
    without a trace in the usual case of a record longer than the free vector."""
    if free.shape[0] <= n_fit_residuals(problem.segments):
        return True
    return free.shape[0] <= n_residuals(free, problem, model, layout)


def n_residuals(free, problem: Problem, model: Model, layout: Layout) -> int:
    """Length of `free_residuals` at ``free`` (traced once per structure and
    shapes: the closed loop runs many fits of each)."""
    return int(_residuals_program.eval_shape(free, problem, model=model, layout=layout).shape[0])
