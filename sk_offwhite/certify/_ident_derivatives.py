r"""Derivatives of the multi-step cost at a fitted solution, with JAX.

All functions take the flat vector ``free`` of certified variables $p$ and a
`Problem` (see `_ident_problem`); the model and the layout
are static, so each function is compiled once per model structure and data shape.

* `cost_hessian` — $H = \partial^2 C_T / \partial p^2$, forward-over-reverse
  (``jacfwd`` of ``grad``): $P$ forward passes through one reverse pass.
* `output_jacobian` — the simulated outputs $\hat z$ and
  $J = \partial \hat z / \partial p$ in forward mode (Gauss-Newton covariance).
* `mixed_derivatives` — $G = \partial^2 C_T / \partial \eta\, \partial p$ for the
  three perturbations of Theorem 1: input noise $\eta^u$ (the model is simulated with
  $\tilde u = u + \eta^u$), output noise $\eta^z$ ($\tilde z = z + \eta^z$)
  and a model error $\tilde\Delta_k$ added to the state update of the system that
  produced the data, whose effect on the data is taken to first order along the fitted model,
  $\tilde z \leftarrow \tilde z + \hat z(p^*; \tilde\Delta) - \hat z(p^*; 0)$.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp

from ..simulation._layout import Layout
from ..simulation._objective import residuals, rollout_segments
from ..simulation._rollout import Model, sample_step, step_rows, theta_dict
from ..solvers._core import Problem, linearised

__all__ = ["Perturbation", "cost_hessian", "mixed_derivatives", "output_jacobian"]


class Perturbation(NamedTuple):
    """Perturbations of the data, each of shape ``(n_segments, length, n)``."""

    inputs: jax.Array
    outputs: jax.Array
    states: jax.Array


def _params(free, problem: Problem, layout: Layout) -> dict:
    return layout.unflatten(problem.base.at[problem.free_index].set(free))


def cost(free, problem: Problem, model: Model, layout: Layout):
    r"""$C_T = \|r\|^2$ as a function of the certified variables."""
    params = _params(free, problem, layout)
    r = residuals(model, params, problem.segments, problem.omega_free, problem.weights)
    return r @ r


@partial(jax.jit, static_argnames=("model", "layout"))
def cost_hessian(free, problem: Problem, *, model: Model, layout: Layout):
    r"""Value, gradient and Hessian $\partial^2 C_T/\partial p^2$ (forward-over-reverse)."""
    fun = partial(cost, problem=problem, model=model, layout=layout)
    value, gradient = jax.value_and_grad(fun)(free)
    return value, gradient, jax.jacfwd(jax.grad(fun))(free)


def simulated_outputs(free, problem: Problem, model: Model, layout: Layout):
    """Simulated outputs of every segment, shape ``(n_segments, length, n_outputs)``."""
    _, outputs, _ = rollout_segments(model, _params(free, problem, layout), problem.segments)
    return outputs


@partial(jax.jit, static_argnames=("model", "layout"))
def output_jacobian(free, problem: Problem, *, model: Model, layout: Layout):
    r"""Outputs $\hat z$ and $\partial \hat z/\partial p$ (last axis), forward mode."""
    fun = partial(simulated_outputs, problem=problem, model=model, layout=layout)
    return linearised(fun, free)


def disturbed_outputs(model: Model, params: dict, segments, disturbance):
    r"""Outputs of $x_{k+1} = f(x_k, u_k) + S\delta(x_k, u_k) + d_k$ per segment."""
    theta = theta_dict(model, params["theta"])

    def one(x0, u, d):
        n_inputs = u.shape[1]

        def advance(x, step):
            row, d_k = step
            x_next, z_k = sample_step(model, params, theta, x, row, n_inputs)
            return x_next + d_k, z_k

        return jax.lax.scan(advance, x0, (step_rows(model, u), d))[1]

    return jax.vmap(one)(params["x0"], segments.u, disturbance)


def perturbed_cost(free, perturbation: Perturbation, solution, problem, model, layout):
    """$C_T(p; \\eta^u, \\eta^z, \\tilde\\Delta)$; the data move, the model does not."""
    segments = problem.segments
    truth = _params(solution, problem, layout)
    disturbed = disturbed_outputs(model, truth, segments, perturbation.states)
    response = disturbed - jax.lax.stop_gradient(disturbed)  # value 0, derivative d z / d Delta
    moved = segments._replace(
        u=segments.u + perturbation.inputs, z=segments.z + perturbation.outputs + response
    )
    return cost(free, problem._replace(segments=moved), model, layout)


@partial(jax.jit, static_argnames=("model", "layout"))
def mixed_derivatives(free, problem: Problem, *, model: Model, layout: Layout) -> Perturbation:
    r"""$G = \partial^2 C_T/\partial\eta\,\partial p$ at zero perturbation.

    Returns a `Perturbation` whose fields have shape ``(n_segments, length, n, P)``.
    """
    segments = problem.segments
    n_states = _params(free, problem, layout)["x0"].shape[-1]
    zero = Perturbation(
        jnp.zeros_like(segments.u),
        jnp.zeros_like(segments.z),
        jnp.zeros(segments.u.shape[:2] + (n_states,)),
    )
    noise_gradient = jax.grad(perturbed_cost, argnums=1)
    return jax.jacfwd(noise_gradient, argnums=0)(free, zero, free, problem, model, layout)
