r"""The multi-step cost $C_T$ as a stacked residual vector.

Every term of eq. (3) of Donati et al. is written as squared residuals, so that
$C = \|r\|_2^2$ can be minimised by Gauss-Newton / Levenberg-Marquardt as well as by
first-order methods:

$$
C = \underbrace{\frac{1}{N n_z}\sum_{k,o} \frac{(\hat z_{ko} - z_{ko})^2}{\sigma_o^2}}
      _{\text{normalised simulation MSE } F}
  + \gamma \sum_{ij} |s_{ij}\Omega_{ij}|_\beta
  + \frac{\lambda}{N} \sum_k \|\max(p(\hat x_k), 0)\|^2
  + \frac{\nu}{N} \sum_k \|q(\hat x_k)\|^2
  + \frac{\rho}{n_\ell n_x} \sum_{\ell, i}
    \frac{(\hat x^{(\ell-1)}_{T,i} - \hat x^{(\ell)}_{0,i})^2}{\varsigma_i^2}
$$

with $|w|_\beta = (\mathrm{softplus}(\beta w) + \mathrm{softplus}(-\beta w))/\beta$,
a smooth, strictly positive surrogate of $|w|$ (its residual
$\sqrt{\gamma |w|_\beta}$ is differentiable everywhere), and the last term the
continuity of consecutive shooting windows (only when a ``horizon`` cuts records). The L1
weight is counted once, not once per time step as in the paper's sum over $k$.

Every term is dimensionless, so that rescaling inputs, outputs, states or a dictionary
column changes neither the minimiser nor the meaning of the weights: $\sigma_o$ is the
standard deviation of output $o$ over the data, $\varsigma_i$ a scale of state
$i$ (the spread of the shooting windows' initial states) and $s_{ij}$ the RMS
sensitivity of the normalised simulated output to $\Omega_{ij}$
(`penalty_scale`), so $s_{ij}|\Omega_{ij}|$ is the RMS
change of the simulated output that term $j$ of equation $i$ makes, in units
of the output's standard deviation.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ._rollout import Model, theta_dict

__all__ = [
    "CostWeights",
    "ResidualParts",
    "majorised_l1",
    "majoriser_constant",
    "n_fit_residuals",
    "residual_parts",
    "residuals",
    "rollout_segments",
    "smooth_abs",
]


class CostWeights(NamedTuple):
    r"""Dynamic weights and scales of the cost terms (changing them does not re-trace).

    ``output_scale`` ($\sigma_o$), ``state_scale`` ($\varsigma_i$) and
    ``penalty_scale`` ($s_{ij}$) broadcast against the outputs, the states and
    $\Omega$; the defaults (1) leave the terms in the data's own units.
    ``l1_anchor`` ($\Omega$ at the current iterate, set by Levenberg-Marquardt)
    replaces the smoothed $\ell_1$ term by its quadratic majoriser
    (`majorised_l1`).
    """

    gamma: float
    lam: float
    nu: float
    shooting: float
    beta: float
    output_scale: float = 1.0
    state_scale: float = 1.0
    penalty_scale: float = 1.0
    l1_anchor: object = None


def smooth_abs(w, beta):
    r"""Smooth, positive surrogate of $|w|$: $\sqrt{w^2 + \beta^{-2}}$.

    It exceeds $|w|$ by at most $1/\beta$, and is quadratic for
    $|w| \ll 1/\beta$.
    """
    return jnp.sqrt(w**2 + beta**-2.0)


def majorised_l1(scaled, anchor, beta):
    r"""Residuals and constant of the quadratic majoriser of $\sum_j|x_j|_\beta$ at
    ``anchor`` $a$:

    $$
    |x|_\beta \le \frac{x^2}{2|a|_\beta} + |a|_\beta - \frac{a^2}{2|a|_\beta},
    $$

    with equality at $x = a$ (the square root is concave in $x^2$). Written as
    residuals $x/\sqrt{2|a|_\beta}$ it is exactly quadratic, so Gauss-Newton models it
    without error; minimising it and moving the anchor is reweighted least squares, which
    never increases the penalised cost.
    """
    size = smooth_abs(anchor, beta)
    return scaled / jnp.sqrt(2.0 * size), jnp.sum(size - anchor**2 / (2.0 * size))


def rollout_segments(model: Model, params: dict, segments):
    """Simulate every segment from its own initial state ``params['x0'][s]`` (vmapped)."""
    from ._rollout import simulate

    def one(x0, u):
        return simulate(model, params, x0, u)

    return jax.vmap(one)(params["x0"], segments.u)


def _fit_residual(outputs, segments, output_scale):
    n_valid = jnp.maximum(jnp.sum(segments.mask) * outputs.shape[-1], 1.0)
    error = (outputs - segments.z) / output_scale * segments.mask[..., None]
    return error.reshape(-1) / jnp.sqrt(n_valid)


def _shooting_residual(states_final, params, segments, weights):
    gap = (states_final[:-1] - params["x0"][1:]) / weights.state_scale
    gap = gap * segments.linked[1:, None]
    n_links = jnp.maximum(jnp.sum(segments.linked) * gap.shape[-1], 1.0)
    return jnp.sqrt(weights.shooting / n_links) * gap.reshape(-1)


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
    scaled = params["omega"] * weights.penalty_scale
    if weights.l1_anchor is None:
        root = jnp.sqrt(smooth_abs(scaled, weights.beta))
    else:
        root, _ = majorised_l1(scaled, weights.l1_anchor * weights.penalty_scale, weights.beta)
    return (jnp.sqrt(weights.gamma) * root * omega_free).reshape(-1)


def majoriser_constant(omega, omega_free, weights):
    r"""Constant that makes $\|r\|^2$ the majorised cost (0 without an anchor)."""
    if weights.l1_anchor is None or omega is None:
        return jnp.zeros(())
    anchor = weights.l1_anchor * weights.penalty_scale * omega_free
    _, constant = majorised_l1(anchor, anchor, weights.beta)
    return weights.gamma * constant


class ResidualParts(NamedTuple):
    r"""The parts of `residuals`, in stacking order: ``fit`` and the two constraint
    parts are segment-major (each segment's rows together), ``shooting`` one row block per
    link between consecutive segments, ``sparsity`` one row per entry of $\Omega$."""

    fit: jax.Array
    shooting: jax.Array
    sparsity: jax.Array
    inequality: jax.Array
    equality: jax.Array


def residual_parts(model: Model, params: dict, segments, omega_free, weights: CostWeights):
    """The terms of the cost as residual vectors (`ResidualParts`)."""
    states, outputs, finals = rollout_segments(model, params, segments)
    return ResidualParts(
        _fit_residual(outputs, segments, weights.output_scale),
        _shooting_residual(finals, params, segments, weights),
        _sparsity_residual(params, omega_free, weights),
        _constraint_residual(model, model.inequality, params, states, segments, weights.lam, True),
        _constraint_residual(model, model.equality, params, states, segments, weights.nu, False),
    )


def residuals(model: Model, params: dict, segments, omega_free, weights: CostWeights):
    r"""Stacked residual vector $r$ with $C = \|r\|^2$ (see module docstring)."""
    return jnp.concatenate(residual_parts(model, params, segments, omega_free, weights))


def n_fit_residuals(segments) -> int:
    """Number of leading entries of `residuals` that are the (normalised) fit errors."""
    return int(np.prod(np.shape(segments.z)))
