r"""The multi-step cost :math:`C_T` as a stacked residual vector.

Every term of eq. (3) of Donati et al. is written as squared residuals, so that
:math:`C = \|r\|_2^2` can be minimised by Gauss-Newton / Levenberg-Marquardt as well as by
first-order methods:

.. math::

    C = \underbrace{\frac{1}{N n_z}\sum_k \|\hat z_k - z_k\|^2}_{\text{simulation MSE}}
      + \gamma \sum_{ij} |\Omega_{ij}|_\beta
      + \frac{\lambda}{N} \sum_k \|\max(p(\hat x_k), 0)\|^2
      + \frac{\nu}{N} \sum_k \|q(\hat x_k)\|^2
      + \frac{\rho}{n_\ell n_x} \sum_{\ell} \|\hat x^{(\ell-1)}_{T} - \hat x^{(\ell)}_0\|^2

with :math:`|w|_\beta = (\mathrm{softplus}(\beta w) + \mathrm{softplus}(-\beta w))/\beta`,
a smooth, strictly positive surrogate of :math:`|w|` (its residual
:math:`\sqrt{\gamma |w|_\beta}` is differentiable everywhere), and the last term the
continuity of consecutive shooting windows (only when a ``horizon`` cuts records). The L1
weight is counted once, not once per time step as in the paper's sum over :math:`k`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp

from ._rollout import Model, theta_dict

__all__ = ["CostWeights", "smooth_abs", "rollout_segments", "residuals"]


class CostWeights(NamedTuple):
    """Dynamic weights of the cost terms (changing them does not re-trace)."""

    gamma: float
    lam: float
    nu: float
    shooting: float
    beta: float


def smooth_abs(w, beta):
    r"""Smooth, positive surrogate of :math:`|w|`: :math:`(s(\beta w) + s(-\beta w))/\beta`.

    ``s`` is the softplus; the surrogate exceeds :math:`|w|` by at most :math:`2\log 2/\beta`.
    """
    return (jax.nn.softplus(beta * w) + jax.nn.softplus(-beta * w)) / beta


def rollout_segments(model: Model, params: dict, segments):
    """Simulate every segment from its own initial state ``params['x0'][s]`` (vmapped)."""
    from ._rollout import simulate

    def one(x0, u):
        return simulate(model, params, x0, u)

    return jax.vmap(one)(params["x0"], segments.u)


def _fit_residual(outputs, segments):
    n_valid = jnp.maximum(jnp.sum(segments.mask) * outputs.shape[-1], 1.0)
    error = (outputs - segments.z) * segments.mask[..., None]
    return error.reshape(-1) / jnp.sqrt(n_valid)


def _shooting_residual(states_final, params, segments, weight):
    gap = (states_final[:-1] - params["x0"][1:]) * segments.linked[1:, None]
    n_links = jnp.maximum(jnp.sum(segments.linked) * gap.shape[-1], 1.0)
    return jnp.sqrt(weight / n_links) * gap.reshape(-1)


def _constraint_residual(model: Model, constraint, params, states, segments, weight, hinge):
    if constraint is None:
        return jnp.zeros(0)
    theta = theta_dict(model, params["theta"])
    values = jax.vmap(jax.vmap(lambda x, u: jnp.atleast_1d(constraint(x, u, theta))))(
        states, segments.u
    )
    values = jnp.maximum(values, 0.0) if hinge else values
    n_valid = jnp.maximum(jnp.sum(segments.mask), 1.0)
    return jnp.sqrt(weight / n_valid) * (values * segments.mask[..., None]).reshape(-1)


def _sparsity_residual(params, omega_free, weights):
    if "omega" not in params:
        return jnp.zeros(0)
    root = jnp.sqrt(smooth_abs(params["omega"], weights.beta)) * omega_free
    return (jnp.sqrt(weights.gamma) * root).reshape(-1)


def residuals(model: Model, params: dict, segments, omega_free, weights: CostWeights):
    r"""Stacked residual vector :math:`r` with :math:`C = \|r\|^2` (see module docstring)."""
    states, outputs, finals = rollout_segments(model, params, segments)
    parts = [
        _fit_residual(outputs, segments),
        _shooting_residual(finals, params, segments, weights.shooting),
        _sparsity_residual(params, omega_free, weights),
        _constraint_residual(model, model.inequality, params, states, segments, weights.lam, True),
        _constraint_residual(model, model.equality, params, states, segments, weights.nu, False),
    ]
    return jnp.concatenate(parts)
