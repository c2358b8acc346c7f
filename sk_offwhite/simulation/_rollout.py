r"""Pure JAX simulation of the grey-box model.

The model adds a black-box correction to selected state equations and outputs,

$$
x_{k+1} = f(x_k, u_k; \theta) + S\, \delta(x_k, u_k; \omega), \qquad
\delta_i = \sum_j \Omega_{ij}\, \Phi_{ij}([x_k; u_k]), \qquad
z_k = h(x_k, u_k; \theta) + R\, \delta(x_k, u_k; \omega),
$$

where $S$ scatters the corrected state equations (``delta_states``, the first rows
of $\Omega$) into the state, $R$ the corrected outputs (``delta_outputs``, the
rows after them; a static correction of the output map, such as a sensor's nonlinearity)
into the output, and $\Phi$ is the dictionary (a pysindy library or a ridge basis,
see ``_basis``).
Simulation runs the recursion with ``jax.lax.scan`` (a *multi-step* prediction: the model
feeds back its own states, never the measurements).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ..runtime._backend import to_device
from ._segments import pad_rows, padded_length

__all__ = [
    "Model",
    "correction",
    "free_run",
    "free_run_record",
    "model_output",
    "model_step",
    "multiply_add",
    "output_correction",
    "sample_step",
    "simulate",
    "step_rows",
    "take",
    "theta_dict",
]


@dataclass(frozen=True)
class Model:
    """Static structure of the grey-box model (hashable, a ``jit`` static argument).

    Attributes
    ----------
    step, output : callable
        The physics ``f(x, u, theta)`` and ``h(x, u, theta)``.
    parameter_names : tuple of str
        Names of all physical parameters, the order of the ``theta`` vector.
    delta_states : tuple of int
        State equations that receive the correction (the first rows of ``omega``).
    basis : callable or None
        ``basis(inner_params, v) -> (n_rows, m)`` dictionary evaluation, ``n_rows =
        len(delta_states) + len(delta_outputs)``.
    inner_names : tuple of str
        Names of the basis' own trainable blocks (``W``, ``B`` of a ridge basis).
    inequality, equality : callable or None
        Physics constraints ``p(x, u, theta) <= 0`` and ``q(x, u, theta) = 0``.
    delta_outputs : tuple of int
        Outputs that receive the correction (the rows of ``omega`` after those of
        ``delta_states``; empty: the declared output map).
    free_multiple : int
        The solver pads the free vector to a multiple of this many variables (1: none; a
        model with switched effects, so that its switch settings share one program).
    feature_states : int or None
        The dictionary reads the first ``feature_states`` states and the inputs (the
        declared states of a model whose effects carry hidden states); ``None``: all.
    next_input : bool
        The physics' step takes ``[u_k, u_{k+1}]`` (an input interpolated between samples,
        a first-order hold); the output map and the correction read ``u_k`` alone.
    """

    step: Callable
    output: Callable
    parameter_names: tuple[str, ...]
    delta_states: tuple[int, ...] = ()
    basis: Callable | None = None
    inner_names: tuple[str, ...] = ()
    inequality: Callable | None = None
    equality: Callable | None = None
    free_multiple: int = 1
    delta_outputs: tuple[int, ...] = ()
    feature_states: int | None = None
    next_input: bool = False


def theta_dict(model: Model, theta) -> dict:
    """Map the parameter vector to the ``{name: scalar}`` dict the physics functions take."""
    return {name: theta[i] for i, name in enumerate(model.parameter_names)}


def correction(model: Model, params: dict, x, u):
    r"""Black-box term $S\delta(x, u; \omega)$ added to the state update."""
    if model.basis is None or not model.delta_states:
        return jnp.zeros_like(x)
    delta = _delta_rows(model, params, x, u)[: len(model.delta_states)]
    return _scattered(delta, model.delta_states, x.shape[0], x.dtype)


def output_correction(model: Model, params: dict, x, u, n_outputs: int):
    r"""Black-box term $R\delta(x, u; \omega)$ added to the output map."""
    if model.basis is None or not model.delta_outputs:
        return jnp.zeros((n_outputs,), x.dtype)
    delta = _delta_rows(model, params, x, u)[len(model.delta_states) :]
    return _scattered(delta, model.delta_outputs, n_outputs, x.dtype)


def _delta_rows(model: Model, params: dict, x, u):
    r"""Every row of the correction, $\sum_j \Omega_{ij} \Phi_{ij}([x; u])$, with
    $x$ the states the dictionary reads (``model.feature_states``)."""
    inner = {name: params[name] for name in model.inner_names}
    features = model.basis(inner, jnp.concatenate([x[: model.feature_states], u]))
    return multiply_add(params["omega"], features)


def _scattered(delta, targets: tuple[int, ...], size: int, dtype):
    """A vector of ``size`` with ``delta[k]`` added at ``targets[k]``, built entry by entry
    (a scatter would not fuse with the rest of a simulation step)."""
    zero = jnp.zeros((), dtype)
    rows = [[k for k, t in enumerate(targets) if t == i] for i in range(size)]
    return jnp.stack([sum((delta[k] for k in ks), zero) for ks in rows])


def multiply_add(weights, features):
    r"""$\sum_j W_{ij} F_{ij}$ for arrays of shape ``(n, m)``, as a chain of ``m``
    multiply-adds.

    Inside a ``scan``, XLA on CPU fuses this chain with the rest of the step, but not a
    reduction (``jnp.sum``, ``@``, ``einsum``) in the forward-mode derivative of the step,
    which then runs as separate operations at every step and costs many times the
    simulation itself; with the chain the derivative costs about as much as the step.
    """
    total = jnp.zeros(features.shape[:1], features.dtype)
    for j in range(features.shape[1]):
        total = total + weights[:, j] * features[:, j]
    return total


def take(v, indices):
    """``v[indices]`` for static integer ``indices``, entry by entry.

    Static slices fuse with the rest of a simulation step; an indexed read with an index
    array is a gather, which XLA on CPU runs as a separate operation at every step of a
    ``scan``, many times slower than the fused step.
    """
    entries = [v[int(i)] for i in np.ravel(indices)]
    return jnp.stack(entries) if entries else jnp.zeros((0,), v.dtype)


def step_rows(model: Model, u):
    """What the step reads at each sample of the input sequence ``u`` (shape ``(L, n_u)``):
    ``u`` itself, or ``[u_k, u_{k+1}]`` (shape ``(L, 2 n_u)``, the last sample repeated)
    when the step reads the next input (``model.next_input``)."""
    if not model.next_input:
        return u
    following = jnp.concatenate([u[1:], u[-1:]], axis=0)
    return jnp.concatenate([u, following], axis=1)


def model_step(model: Model, params: dict, x, u, step_input=None):
    r"""One step of the augmented model: $f(x, u; \theta) + S\delta(x, u; \omega)$;
    the physics reads ``step_input`` when given (a row of `step_rows`), else ``u``."""
    seen = u if step_input is None else step_input
    physics = model.step(x, seen, theta_dict(model, params["theta"]))
    return jnp.asarray(physics, dtype=x.dtype).reshape(x.shape) + correction(model, params, x, u)


def model_output(model: Model, params: dict, x, u, theta: dict):
    r"""The output of the augmented model: $h(x, u; \theta) + R\delta(x, u; \omega)$
    (``theta`` the physical parameters by name, `theta_dict`)."""
    declared = jnp.atleast_1d(model.output(x, u, theta))
    if not model.delta_outputs:
        return declared
    return declared + output_correction(model, params, x, u, declared.shape[0])


def sample_step(model: Model, params: dict, theta: dict, x, row, n_inputs: int):
    """``(next state, output)`` of one sample from ``x``, ``row`` a row of `step_rows`
    (its first ``n_inputs`` entries the sample's input, which the output and the correction
    read)."""
    u_k = row[:n_inputs]
    return model_step(model, params, x, u_k, row), model_output(model, params, x, u_k, theta)


@partial(jax.jit, static_argnums=0)
def simulate(model: Model, params: dict, x0, u):
    r"""Free-run simulation from ``x0`` over the input sequence ``u`` of shape ``(L, n_u)``.

    Jitted, so that a program calling it several times (a solver's residual, its
    Jacobian's push-forward and its trial step) traces the model once per shape.

    Returns
    -------
    states : array of shape (L, n_x)
        $\hat x_0, \dots, \hat x_{L-1}$.
    outputs : array of shape (L, n_z)
        $\hat z_k = h(\hat x_k, u_k; \theta) + R\delta(\hat x_k, u_k; \omega)$.
    final_state : array of shape (n_x,)
        $\hat x_L$, used to link consecutive shooting windows.
    """
    theta, n_inputs = theta_dict(model, params["theta"]), u.shape[1]

    def advance(x, row):
        x_next, z_k = sample_step(model, params, theta, x, row, n_inputs)
        return x_next, (x, z_k)

    final_state, (states, outputs) = jax.lax.scan(advance, x0, step_rows(model, u))
    return states, outputs, final_state


@partial(jax.jit, static_argnums=0)
def free_run(model: Model, params: dict, x0, u):
    r"""Jitted `simulate` plus the correction $S\delta(\hat x_k, u_k)$ at every step.

    Returns ``(states, outputs, corrections)``, the last of shape ``(L, n_x)``.
    """
    states, outputs, _ = simulate(model, params, x0, u)
    corrections = jax.vmap(lambda x, u_k: correction(model, params, x, u_k))(states, u)
    return states, outputs, corrections


def free_run_record(model: Model, params: dict, x0, u) -> tuple[np.ndarray, ...]:
    """`free_run` of one record ``u``, as numpy arrays.

    The input is padded to `padded_length` (its last row
    repeated) and the run cut back to the record: records of nearby lengths (the training
    records and held-out blocks of a cross-validation, 341 and 342 samples) then share one
    compiled program, and a step depends only on the steps before it.
    """
    n_samples = np.shape(u)[0]
    padded = pad_rows(np.asarray(u), padded_length(n_samples))
    run = free_run(model, params, to_device(x0, float), to_device(padded))
    return tuple(np.asarray(values)[:n_samples] for values in run)
