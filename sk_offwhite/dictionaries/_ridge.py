r"""Ridge functions, the paper's basis: $\Phi_{ij}(v) = \sigma_j(W_{i,:,j} \cdot v + B_{ij})$,
with inner weights trainable per equation."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from sklearn.utils import check_random_state

from ._compiled import CompiledBasis, _as_vector

__all__ = ["RidgeBasis"]


_ACTIVATIONS: dict[str, Callable[[jnp.ndarray], jnp.ndarray]] = {
    "sigmoid": jax.nn.sigmoid,
    "softplus": jax.nn.softplus,
    "tanh": jnp.tanh,
    "sin": jnp.sin,
    "cos": jnp.cos,
    "identity": lambda z: z,
    "square": lambda z: z * z,
    "cube": lambda z: z * z * z,
}


_DEFAULT_ACTIVATIONS = ("sigmoid", "softplus", "tanh", "sin", "cos", "identity", "square", "cube")


class RidgeBasis:
    r"""Ridge-function basis with per-equation trainable inner weights.

    $$
    δ_i(v) = \sum_{j=1}^{m} Ω_{ij} \, σ_j\big(r_{ij}(v)\big), \qquad
    r_{ij}(v) = \sum_k W_{ikj} v_k + B_{ij},
    $$

    with ``W`` of shape ``(n_delta, n_features, m)`` and ``B`` of shape
    ``(n_delta, m)``. Feature ``j`` is named ``"<activation>(r<j>)"``, e.g.
    ``"tanh(r2)"``, where ``r<j>`` stands for the ridge ``r_ij`` of the
    equation ``i`` it enters.

    Parameters
    ----------
    activations : sequence of str
        One activation ``σ_j`` per basis function (``m = len(activations)``):
        ``"sigmoid"``, ``"softplus"``, ``"tanh"``, ``"sin"``, ``"cos"``,
        ``"identity"``, ``"square"`` (``z²``) or ``"cube"`` (``z³``).
    W_init, B_init : array-like or None
        Initial ``W`` (shape ``(n_delta, n_features, m)``) and ``B`` (shape
        ``(n_delta, m)``). ``None`` draws ``scale * N(0, 1)`` from
        ``random_state`` (``W`` is drawn before ``B``, both always, so ``B``
        does not depend on whether ``W_init`` is given).
    W_trainable, B_trainable : bool or array of bool
        Whether each entry of ``W``/``B`` is fitted; ``False`` entries stay at
        their initial value (to pin an entry to zero, give init 0 and
        ``False``).
    omega_trainable : bool or array of bool, shape (n_delta, m)
        Mask of the outer weights ``Ω``; ``False`` entries are fixed at 0.
    scale : float
        Standard deviation of the random initialisation.

    Notes
    -----
    Arguments are stored as given; shapes are validated by
    [`compile_basis`][sk_offwhite.compile_basis], which knows ``n_features`` and ``n_delta``.
    """

    def __init__(
        self,
        activations: Sequence[str] = _DEFAULT_ACTIVATIONS,
        W_init: Any = None,
        B_init: Any = None,
        W_trainable: bool | np.ndarray = True,
        B_trainable: bool | np.ndarray = True,
        omega_trainable: bool | np.ndarray = True,
        scale: float = 1.0,
    ) -> None:
        _check_activations(activations)
        self.activations = activations
        self.W_init = W_init
        self.B_init = B_init
        self.W_trainable = W_trainable
        self.B_trainable = B_trainable
        self.omega_trainable = omega_trainable
        self.scale = scale

    def __repr__(self) -> str:
        defaults = RidgeBasis.__init__.__defaults__
        names = RidgeBasis.__init__.__code__.co_varnames[1 : 1 + len(defaults)]
        args = [
            f"{name}={_short_repr(getattr(self, name))}"
            for name, default in zip(names, defaults, strict=True)
            if name == "activations" or not _same_value(getattr(self, name), default)
        ]
        return f"RidgeBasis({', '.join(args)})"


def _same_value(value: Any, default: Any) -> bool:
    """Whether a constructor argument still has its (scalar) default."""
    return not isinstance(value, np.ndarray) and type(value) is type(default) and value == default


def _short_repr(value: Any) -> str:
    """``repr`` that summarises arrays by shape and dtype."""
    if isinstance(value, np.ndarray | jax.Array) or np.ndim(value) > 1:
        arr = np.asarray(value)
        return f"<array shape={arr.shape} dtype={arr.dtype}>"
    return repr(tuple(value) if isinstance(value, list) else value)


def _check_activations(activations: Sequence[str]) -> tuple[str, ...]:
    """Validate activation names; return them as a tuple."""
    if isinstance(activations, str) or not isinstance(activations, Sequence | np.ndarray):
        raise TypeError(
            f"activations must be a sequence of names such as ('tanh', 'sin'); got {activations!r}."
        )
    acts = tuple(activations)
    if not acts:
        raise ValueError("activations must contain at least one activation name.")
    unknown = [a for a in acts if a not in _ACTIVATIONS]
    if unknown:
        raise ValueError(
            f"Unknown activation(s) {unknown} in activations; valid names are "
            f"{sorted(_ACTIVATIONS)}."
        )
    return acts


def _compile_ridge(
    basis: RidgeBasis, features: tuple[str, ...], n_delta: int, random_state: Any
) -> CompiledBasis:
    """Compile a [`RidgeBasis`][sk_offwhite.RidgeBasis] for ``len(features)`` inputs and ``n_delta``
    equations."""
    acts = _check_activations(basis.activations)
    n, m = len(features), len(acts)
    W0, B0 = _ridge_init(basis, (n_delta, n, m), (n_delta, m), random_state)
    trainable = {
        "W": _as_mask(basis.W_trainable, W0.shape, "W_trainable"),
        "B": _as_mask(basis.B_trainable, B0.shape, "B_trainable"),
    }
    omega = _as_mask(basis.omega_trainable, (n_delta, m), "omega_trainable")
    names = tuple(f"{act}(r{j})" for j, act in enumerate(acts))
    evaluate = _jitted_ridge_evaluate(acts, n)
    return CompiledBasis(names, {"W": W0, "B": B0}, trainable, omega, evaluate, features)


def _ridge_init(
    basis: RidgeBasis, w_shape: tuple, b_shape: tuple, random_state: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Initial ``(W, B)``: user arrays if given, else ``scale * N(0, 1)`` draws."""
    scale = float(basis.scale)
    if not np.isfinite(scale) or scale < 0:
        raise ValueError(f"scale must be a finite non-negative number; got {basis.scale!r}.")
    rng = _as_generator(random_state)
    W_rand = scale * rng.standard_normal(w_shape)
    B_rand = scale * rng.standard_normal(b_shape)
    W0 = W_rand if basis.W_init is None else _as_init(basis.W_init, w_shape, "W_init")
    B0 = B_rand if basis.B_init is None else _as_init(basis.B_init, b_shape, "B_init")
    return W0, B0


def _as_generator(random_state: Any) -> np.random.Generator | np.random.RandomState:
    """A numpy RNG from a seed, ``RandomState`` or ``Generator``."""
    if isinstance(random_state, np.random.Generator):
        return random_state
    return check_random_state(random_state)


def _as_init(value: Any, shape: tuple, name: str) -> np.ndarray:
    """Validate a user-given initial array (float64 copy of the exact shape)."""
    arr = np.array(value, dtype=float)
    if arr.shape != shape:
        what = "(n_delta, n_features, m)" if name == "W_init" else "(n_delta, m)"
        raise ValueError(f"{name} must have shape {what} = {shape}; got shape {arr.shape}.")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must contain only finite values.")
    return arr


def _as_mask(value: Any, shape: tuple, name: str) -> np.ndarray:
    """A boolean mask of ``shape`` from a bool or a boolean array."""
    if isinstance(value, bool | np.bool_):
        return np.full(shape, bool(value))
    arr = np.array(value)
    if arr.dtype != bool:
        raise TypeError(
            f"{name} must be a bool or a boolean array of shape {shape}; got dtype {arr.dtype}."
        )
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}; got shape {arr.shape}.")
    return arr


def _activation_groups(acts: tuple[str, ...]) -> tuple[list, np.ndarray | None]:
    """Group columns by activation; return groups and the inverse permutation."""
    order = list(dict.fromkeys(acts))
    groups = [(_ACTIVATIONS[a], np.array([j for j, b in enumerate(acts) if b == a])) for a in order]
    perm = np.concatenate([idx for _, idx in groups])
    inverse = None if np.array_equal(perm, np.arange(len(acts))) else np.argsort(perm)
    return groups, inverse


@functools.lru_cache(maxsize=64)
def _jitted_ridge_evaluate(acts: tuple[str, ...], n_features: int) -> Callable:
    """One jitted ``evaluate`` per activation tuple and input size (shared by clones)."""
    return jax.jit(_ridge_evaluate(acts, n_features))


def _ridge_evaluate(acts: tuple[str, ...], n_features: int) -> Callable:
    """Build ``evaluate(params, v) = σ(Σ_k W[:, k, :] v_k + B)``."""
    groups, inverse = _activation_groups(acts)

    def evaluate(inner_params: dict[str, Any], v: jnp.ndarray) -> jnp.ndarray:
        """Return ``Φ_ij = σ_j(W[i, :, j] · v + B[i, j])``, shape ``(n_delta, m)``."""
        v = _as_vector(v, n_features)
        W, B = _ridge_params(inner_params)
        z = B
        for k in range(n_features):  # multiply-adds, not einsum: see rollout.multiply_add
            z = z + W[:, k, :] * v[k]
        if len(groups) == 1:
            return groups[0][0](z)
        out = jnp.concatenate([fn(z[:, jnp.asarray(idx.tolist())]) for fn, idx in groups], axis=1)
        return out if inverse is None else out[:, jnp.asarray(inverse.tolist())]

    return evaluate


def _ridge_params(inner_params: dict[str, Any]) -> tuple[jnp.ndarray, jnp.ndarray]:
    """Extract ``(W, B)`` from the inner parameter dict with a clear error."""
    missing = {"W", "B"} - set(inner_params)
    if missing:
        raise KeyError(f"RidgeBasis inner_params must contain 'W' and 'B'; missing {missing}.")
    return jnp.asarray(inner_params["W"]), jnp.asarray(inner_params["B"])
