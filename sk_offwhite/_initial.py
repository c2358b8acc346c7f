r"""The initial state that best explains a short window of measurements, every other block
of the model fixed (as MATLAB's ``compare`` does).

The problem is small (the states are the only variables) and is solved often: once per
scored record, so once per cross-validation fold of every structure the closed loop tries.
Its whole Levenberg-Marquardt run is therefore one compiled program (a ``lax.while_loop``
over the trial steps), traced once per model and window length, rather than the general
solver's two programs and one dispatch per step.

The cost is the normalised output error over the window,

$$
C(x_0) = \frac{1}{N n_z} \sum_{k<N} \big\|(\hat z_k(x_0) - z_k) / \sigma_o\big\|^2,
$$

with $\sigma_o$ the outputs' scale; the steps follow the rules of every Levenberg-Marquardt
run of the package (`sk_offwhite.solvers._rules`: Marquardt's per-variable scaling, the same
damping updates and stopping rules).
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ._backend import to_device
from ._rollout import simulate
from ._sparsity import output_scale
from .solvers._rules import (
    START_DAMPING,
    damped_diagonal,
    next_damping,
    small_decrease,
    stop_code,
)

__all__ = ["estimate_initial_state"]


class _Iterate(NamedTuple):
    """The run's state: the last accepted ``x0`` with its residual, Jacobian and cost, the
    damping, the per-variable scale (`damped_diagonal`), the
    trial steps taken, whether a stopping rule has fired and whether ``x0`` has been
    evaluated (the first pass of the loop only evaluates the start)."""

    x0: jax.Array
    residual: jax.Array
    jacobian: jax.Array
    cost: jax.Array
    damping: jax.Array
    scale: jax.Array
    iteration: jax.Array
    done: jax.Array
    evaluated: jax.Array


def window_residual(model, params: dict, x0, u, z, scale):
    r"""Normalised output errors of a free run from ``x0`` over the window (``C = r^Tr``)."""
    _, outputs, _ = simulate(model, params, x0, u)
    return ((outputs - z) / scale).reshape(-1) / jnp.sqrt(z.size)


def _linearised(model, params, x0, u, z, scale, free):
    """Residual, Jacobian (zero columns for the fixed states) and cost at ``x0``."""

    def with_value(x):
        value = window_residual(model, params, x, u, z, scale)
        return value, value

    jacobian, residual = jax.jacfwd(with_value, has_aux=True)(x0)
    return residual, jnp.where(free, jacobian, 0.0), residual @ residual


def _damped_step(it: _Iterate, free):
    r"""Marquardt's step $(J^TJ + \mu D)\,s = -J^Tr$ over the free states."""
    jtj = it.jacobian.T @ it.jacobian
    system = jtj + jnp.diag(damped_diagonal(jnp.diag(jtj), it.damping, free, jnp, it.scale))
    return jnp.linalg.solve(system, jnp.where(free, -it.jacobian.T @ it.residual, 0.0))


@partial(jax.jit, static_argnums=0)
def _solve_window(model, params: dict, x0, u, z, scale, free, max_iter, tol):
    """The whole Levenberg-Marquardt run; returns the last accepted iterate. Its first pass
    only evaluates the start (no step), so the linearisation is traced once, in the loop."""
    linearise = partial(_linearised, model, params, u=u, z=z, scale=scale, free=free)
    n, m = x0.shape[0], z.size
    start = _Iterate(
        x0, jnp.zeros(m, x0.dtype), jnp.zeros((m, n), x0.dtype), jnp.asarray(jnp.inf, x0.dtype),
        jnp.asarray(START_DAMPING, x0.dtype), jnp.zeros(n, x0.dtype), jnp.asarray(0),
        jnp.asarray(False), jnp.asarray(False),
    )  # fmt: skip

    def step(it: _Iterate) -> _Iterate:
        first = ~it.evaluated
        move = jnp.where(first, 0.0, _damped_step(it, free))
        residual, jacobian, cost = linearise(it.x0 + move)
        accepted = first | (jnp.isfinite(cost) & (cost < it.cost))
        small = small_decrease(it.cost, cost, tol)
        done = stop_code(~first, accepted, small, it.damping, cost) > 0
        damping = next_damping(~first, accepted, it.damping)
        scale = jnp.maximum(it.scale, jnp.sum(jacobian**2, axis=0))
        count = it.iteration + jnp.where(first, 0, 1)
        kept = _Iterate(it.x0 + move, residual, jacobian, cost, damping, scale, count, done, True)
        rejected = it._replace(damping=damping, iteration=count, done=done)
        return jax.tree.map(partial(jnp.where, accepted), kept, rejected)

    def going(it: _Iterate):
        return ~it.done & (it.iteration < max_iter)

    return jax.lax.while_loop(going, step, start).x0


def estimate_initial_state(model, blocks, u, z, x0_guess, x0_free, *, max_iter=100):
    """Initial state that best explains ``z`` (the outputs over the window ``u``) with every
    other block (``blocks``: ``theta`` and the correction's) fixed, started from
    ``x0_guess``; only the states where ``x0_free`` is true move (in double precision)."""
    guess = np.asarray(x0_guess, float).reshape(-1)
    free = np.asarray(x0_free, bool).reshape(-1)
    if not free.any():
        return guess
    z = np.asarray(z, float).reshape(len(u), -1)
    with jax.enable_x64(True):
        params = {name: to_device(value) for name, value in blocks.items() if name != "x0"}
        x0 = _solve_window(
            model, params, to_device(guess), to_device(np.asarray(u, float)), to_device(z),
            to_device(output_scale([(u, z)])), to_device(free), max_iter, 1e-10,
        )  # fmt: skip
        return np.asarray(x0)
