r"""A dictionary compiled to pure ``jax.numpy``: what the model evaluates.

`CompiledBasis.evaluate(inner_params, v)` returns $\Phi(v)$ of shape ``(n_delta, m)`` for
$v = [x; u]$, so that $\delta_i = \sum_j \Omega_{ij}\Phi_{ij}(v)$; it is jit-able,
vmap-able and differentiable with finite gradients everywhere for every built-in feature.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["CompiledBasis", "evaluate_matrix"]


def _xp(a):
    """``jax.numpy`` for JAX arrays and tracers, ``numpy`` otherwise: a feature function
    written with it runs in float64 numpy inside pysindy and in ``jax.numpy`` (also under
    ``jit``/``grad``) inside the compiled dictionary."""
    return jnp if isinstance(a, jax.Array) else np


#: A compiled feature row: ``phi(v) -> (m,)`` for ``v`` of shape ``(n,)``.
FeatureFn = Callable[[jnp.ndarray], jnp.ndarray]


@dataclass(frozen=True, eq=False)
class CompiledBasis:
    """A dictionary of basis functions compiled to pure JAX.

    Attributes
    ----------
    names : tuple of str
        The ``m`` feature names (column ``j`` of ``Φ``). For pysindy libraries
        these are exactly ``library.get_feature_names(input_features)``.
    init_params : dict of str to ndarray
        Initial inner parameters (``{"W", "B"}`` for [`RidgeBasis`][sk_offwhite.RidgeBasis],
        ``{}`` for pysindy libraries).
    trainable : dict of str to ndarray of bool
        Masks with the keys and shapes of ``init_params``; ``True`` entries are
        fitted, ``False`` entries stay at their initial value.
    omega_trainable : ndarray of bool, shape (n_delta, m)
        Mask of the outer weights ``Ω``; ``False`` entries are fixed at 0.
    evaluate : callable
        ``evaluate(inner_params, v) -> Φ`` with ``v`` of shape
        ``(n_features,)`` and ``Φ`` of shape ``(n_delta, m)``, so that
        ``δ = jnp.sum(Ω * Φ, axis=1)``. It is wrapped in ``jax.jit`` (cheap to
        call eagerly; inlined when called inside another transformation).
    input_features : tuple of str
        Names of the entries of ``v`` the basis was compiled for.
    """

    names: tuple[str, ...]
    init_params: dict[str, np.ndarray]
    trainable: dict[str, np.ndarray]
    omega_trainable: np.ndarray
    evaluate: Callable[[dict[str, Any], jnp.ndarray], jnp.ndarray]
    input_features: tuple[str, ...] = ()

    @property
    def n_basis(self) -> int:
        """Number ``m`` of basis functions per δ equation."""
        return len(self.names)

    @property
    def n_delta(self) -> int:
        """Number of state equations that receive a correction δ."""
        return int(self.omega_trainable.shape[0])


def evaluate_matrix(
    compiled: CompiledBasis, inner_params: dict[str, Any], V: jnp.ndarray
) -> jnp.ndarray:
    """Evaluate the basis on every row of ``V``.

    Parameters
    ----------
    compiled : CompiledBasis
        Output of [`compile_basis`][sk_offwhite.compile_basis].
    inner_params : dict
        Inner parameters (e.g. ``compiled.init_params``).
    V : array-like, shape (n_samples, n_features)
        Rows ``v = [x; u]``.

    Returns
    -------
    jax.Array, shape (n_samples, n_delta, m)
        ``Φ(v_k)`` stacked over the rows ``v_k`` of ``V``.
    """
    V = jnp.asarray(V)
    n = len(compiled.input_features)
    if V.ndim != 2 or (n and V.shape[1] != n):
        raise ValueError(f"V must have shape (n_samples, {n or 'n_features'}); got {V.shape}.")
    return _evaluate_rows(compiled.evaluate, inner_params, V)


@partial(jax.jit, static_argnums=0)
def _evaluate_rows(evaluate: Callable, inner_params: dict[str, Any], V: jnp.ndarray) -> jnp.ndarray:
    """Jitted row-wise ``evaluate`` (compiled once per basis and input shape)."""
    return jax.vmap(evaluate, in_axes=(None, 0))(inner_params, V)


def _as_vector(v: jnp.ndarray, n_features: int) -> jnp.ndarray:
    """Return ``v`` as a floating JAX vector of shape ``(n_features,)``."""
    v = jnp.asarray(v)
    if v.shape != (n_features,):
        raise ValueError(
            f"v must be a single vector [x; u] of shape ({n_features},); got shape {v.shape}. "
            "Use evaluate_matrix (or jax.vmap) for several rows."
        )
    if not jnp.issubdtype(v.dtype, jnp.floating):
        v = v.astype(jnp.result_type(float))
    return v


def _shared_row(phi: FeatureFn, names: tuple[str, ...], features, n_delta: int) -> CompiledBasis:
    """A dictionary whose row ``phi(v)`` is shared by all ``n_delta`` corrected rows (no
    inner parameters)."""
    n_features, m = len(features), len(names)

    def evaluate(inner_params: dict[str, Any], v: jnp.ndarray) -> jnp.ndarray:
        """Return ``Φ(v)`` of shape ``(n_delta, m)``; ``inner_params`` is unused."""
        return jnp.broadcast_to(phi(_as_vector(v, n_features)), (n_delta, m))

    omega = np.ones((n_delta, m), dtype=bool)
    return CompiledBasis(names, {}, {}, omega, jax.jit(evaluate), features)
