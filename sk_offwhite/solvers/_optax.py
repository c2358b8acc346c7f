r"""A first-order loop with any optax transformation and reverse-mode gradients.

For problems with many free variables and no shooting windows, where a Jacobian would be
wide: each iteration is one jitted call of the gradient of $\|r\|^2$ and the optimizer's
update, projected on the box bounds; the loop keeps the best finite iterate.
"""

from __future__ import annotations

import warnings
from functools import lru_cache, partial

import jax
import jax.numpy as jnp
import numpy as np
from sklearn.exceptions import ConvergenceWarning

from .._layout import Layout
from .._rollout import Model
from ._core import Problem, SolverResult, free_residuals
from ._host import _show
from ._rules import progress_line

__all__ = ["default_optimizer", "run_optax"]


@lru_cache(maxsize=8)
def default_optimizer(max_iter: int):
    """The optax loop's optimizer when none is given: Adam, its step cosine-decayed from
    1e-2 to 1e-4 over ``max_iter`` iterations, behind clipping of the gradient's global
    norm to 1. The same object for the same ``max_iter`` (a ``jit`` static argument: fits
    reuse the compiled iteration). optax is imported here, on the first fit that uses it."""
    import optax

    schedule = optax.cosine_decay_schedule(1e-2, decay_steps=max_iter, alpha=0.01)
    return optax.chain(optax.clip_by_global_norm(1.0), optax.adam(schedule))


@partial(jax.jit, static_argnames=("model", "layout", "optimizer"))
def _optax_iteration(free, opt_state, problem, *, model, layout, optimizer):
    import optax

    def cost(f):
        r = free_residuals(f, problem, model, layout)
        return r @ r

    value, grad = jax.value_and_grad(cost)(free)
    updates, opt_state = optimizer.update(grad, opt_state, free)
    new = jnp.clip(optax.apply_updates(free, updates), problem.lower, problem.upper)
    return new, opt_state, value


def run_optax(
    free0,
    problem: Problem,
    model: Model,
    layout: Layout,
    optimizer,
    *,
    max_iter: int,
    tol: float,
    patience: int = 100,
    verbose: int = 0,
) -> SolverResult:
    """First-order loop with any optax transformation (``None``: `default_optimizer`),
    keeping the best finite iterate.

    Stops after ``patience`` iterations without a relative improvement of ``tol`` of the
    best cost. A non-finite cost ends the loop: the best finite iterate is returned and a
    `ConvergenceWarning` says so.
    """
    optimizer = default_optimizer(max_iter) if optimizer is None else optimizer
    static = dict(model=model, layout=layout, optimizer=optimizer)
    free, opt_state = free0, optimizer.init(free0)
    best_free, best_cost, since_best, history = np.asarray(free0), np.inf, 0, []
    converged, message = False, "max_iter reached"
    for iteration in range(1, max_iter + 1):
        candidate, opt_state, value = _optax_iteration(free, opt_state, problem, **static)
        value = float(value)
        if not np.isfinite(value):
            message = f"non-finite cost at iteration {iteration}; kept the best finite iterate"
            warnings.warn(f"The fit diverged: {message}.", ConvergenceWarning, stacklevel=3)
            break
        history.append(value)
        _show(progress_line(verbose, iteration, value, best_cost))
        if value < best_cost * (1.0 - tol):
            since_best = 0
        else:
            since_best += 1
        if value < best_cost:
            best_free, best_cost = np.asarray(free), value
        if since_best >= patience:
            converged, message = True, f"no relative improvement of tol in {patience} iterations"
            break
        free = candidate
    return SolverResult(best_free, best_cost, np.asarray(history), iteration, converged, message)
