r"""Compile a dictionary of basis functions into pure ``jax.numpy`` functions.

The black-box correction of the model ``x[k+1] = f(x, u; θ) + δ(x, u; ω)`` is
a sparse linear combination of basis functions evaluated on ``v = [x; u]``:

$$
δ_i(v) = \sum_{j=1}^{m} Ω_{ij} \, Φ_{ij}(v), \qquad i = 1, \dots, n_δ,
$$

where ``Φ = evaluate(inner_params, v)`` has shape ``(n_delta, m)``. Two kinds
of dictionaries are supported:

* **pysindy 2.1 feature libraries** (polynomial, Fourier, identity, custom,
  concatenated, tensored and generalized libraries). pysindy's ``transform``
  is numpy-only, so every feature is re-implemented in ``jax.numpy`` from the
  library's description. The row ``φ(v)`` is shared by all δ equations:
  ``Φ_{ij}(v) = φ_j(v)``. There are no inner parameters.
* **ridge functions** ([`RidgeBasis`][sk_offwhite.RidgeBasis]), the paper's basis, whose inner
  weights are trainable per equation:
  ``Φ_{ij}(v) = σ_j(W_{i,:,j} · v + B_{ij})``.

[`compile_basis`][sk_offwhite.compile_basis] returns a `CompiledBasis` whose ``evaluate`` is
jit-able, vmap-able and differentiable with finite gradients everywhere
(including ``v = 0``) for all built-in features.
"""

from __future__ import annotations

import copy
import functools
import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import numpy as np
from sklearn.utils import check_random_state

from ._radial import RadialBasis
from ._rollout import take

if TYPE_CHECKING:
    from pysindy.feature_library import (
        ConcatLibrary,
        CustomLibrary,
        FourierLibrary,
        GeneralizedLibrary,
        PolynomialLibrary,
        TensoredLibrary,
    )

__all__ = ["CompiledBasis", "RidgeBasis", "compile_basis", "evaluate_matrix"]

#: A compiled feature row: ``phi(v) -> (m,)`` for ``v`` of shape ``(n,)``.
FeatureFn = Callable[[jnp.ndarray], jnp.ndarray]

_N_DUMMY_SAMPLES = 6
_DUMMY_SEED = 20240611


@functools.cache
def _rejected_libraries() -> tuple[tuple[type, str], ...]:
    """pysindy libraries refused, with the reason; checked with isinstance, most specific
    first (ParameterizedLibrary is a GeneralizedLibrary). pysindy is imported here, on the
    first dictionary, not with the package."""
    from pysindy import feature_library as fl

    return (
        (
            fl.ParameterizedLibrary,
            "use a GeneralizedLibrary or TensoredLibrary with inputs_per_library",
        ),
        (fl.WeakPDELibrary, "weak-form features integrate over a grid, not a function of one v"),
        (fl.PDELibrary, "its features need spatial derivatives, not a function of one v"),
        (fl.SINDyPILibrary, "implicit x_dot terms (deprecated in pysindy) are not a function of v"),
    )


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


# ---------------------------------------------------------------------------
# Public entry points
# ---------------------------------------------------------------------------


def compile_basis(
    library: Any,
    input_features: Sequence[str],
    n_delta: int,
    random_state: int | np.random.RandomState | np.random.Generator | None = None,
) -> CompiledBasis:
    """Compile a basis description into pure ``jax.numpy`` functions.

    Parameters
    ----------
    library : RidgeBasis, RadialBasis or pysindy feature library
        The dictionary. Supported pysindy 2.1 libraries: ``PolynomialLibrary``
        (and ``IdentityLibrary()``, which returns one), ``FourierLibrary``,
        ``CustomLibrary`` (functions written with ``jax.numpy`` or plain
        arithmetic), ``ConcatLibrary`` (``a + b``), ``TensoredLibrary``
        (``a * b``) and ``GeneralizedLibrary``, nested arbitrarily. The object
        is never modified: a deep copy is fitted on dummy data.
    input_features : sequence of str
        Names of the entries of ``v = [x; u]`` the features are evaluated on.
    n_delta : int
        Number of state equations receiving a correction ``δ``.
    random_state : int, RandomState, Generator or None, optional
        Seed of the random initialisation of [`RidgeBasis`][sk_offwhite.RidgeBasis] weights.
        Ignored for pysindy libraries.

    Returns
    -------
    CompiledBasis
        ``evaluate(inner_params, v)`` returns ``Φ`` of shape ``(n_delta, m)``.

    Raises
    ------
    TypeError
        If the library type is not supported, or a ``CustomLibrary`` function
        cannot be traced by JAX.
    ValueError
        If the arguments are invalid or the compiled features disagree with
        the library's own ``transform``.
    """
    features = _check_input_features(input_features)
    n_delta = _check_n_delta(n_delta)
    if isinstance(library, RidgeBasis):
        return _compile_ridge(library, features, n_delta, random_state)
    if isinstance(library, RadialBasis):
        key = (library.key(), features, n_delta)
        return _cached(key, _compile_radial, library, features, n_delta)
    key = _library_key(library, features, n_delta)
    if key is None:
        return _compile_pysindy(library, features, n_delta)
    return _cached(key, _compile_pysindy, library, features, n_delta)


def _cached(key, compile_, *args) -> CompiledBasis:
    """``compile_(*args)``, kept under ``key`` (a bounded cache, oldest dropped first)."""
    if key not in _COMPILED_LIBRARIES:
        if len(_COMPILED_LIBRARIES) >= _CACHE_SIZE:
            _COMPILED_LIBRARIES.pop(next(iter(_COMPILED_LIBRARIES)))
        _COMPILED_LIBRARIES[key] = compile_(*args)
    return _COMPILED_LIBRARIES[key]


def release_compiled_libraries() -> None:
    """Forget the compiled dictionaries (see [`compile_basis`][sk_offwhite.compile_basis])."""
    _COMPILED_LIBRARIES.clear()


# Equal library descriptions share one CompiledBasis, hence one ``evaluate`` object, so the
# jitted rollout (whose static argument holds ``evaluate``) is compiled once for all clones
# of an estimator (cross-validation, grid searches) instead of once per fit.
_CACHE_SIZE = 64
_COMPILED_LIBRARIES: dict = {}


def _fingerprint(value: Any) -> Any:
    """Hashable description of a library's configuration (functions by identity)."""
    if value is None or isinstance(value, (str, int, float, bool, np.generic)):
        return value
    if isinstance(value, np.ndarray):
        return (value.shape, value.dtype.str, value.tobytes())
    if isinstance(value, (list, tuple)):
        return tuple(_fingerprint(item) for item in value)
    if isinstance(value, dict):
        return tuple(sorted((str(k), _fingerprint(v)) for k, v in value.items()))
    if hasattr(value, "get_params"):
        settings = {k: v for k, v in vars(value).items() if not k.endswith("_")}
        return (type(value), _fingerprint(settings))
    if callable(value):
        return value
    raise TypeError(f"cannot fingerprint {type(value).__name__}")


def _library_key(library: Any, features: tuple[str, ...], n_delta: int) -> tuple | None:
    """Cache key of a pysindy library, or ``None`` when it cannot be described."""
    try:
        key = (_fingerprint(library), features, n_delta)
        hash(key)
    except TypeError:
        return None
    return key


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


# ---------------------------------------------------------------------------
# Argument validation shared by both kinds of bases
# ---------------------------------------------------------------------------


def _check_input_features(input_features: Sequence[str]) -> tuple[str, ...]:
    """Validate ``input_features`` and return it as a tuple of str."""
    if isinstance(input_features, str) or not isinstance(input_features, Sequence | np.ndarray):
        raise TypeError(
            "input_features must be a sequence of feature names, e.g. ['x1', 'x2', 'u']; "
            f"got {input_features!r}."
        )
    features = tuple(input_features)
    if not features or not all(isinstance(name, str) for name in features):
        raise ValueError(
            f"input_features must be a non-empty sequence of str; got {input_features!r}."
        )
    return features


def _check_n_delta(n_delta: int) -> int:
    """Validate ``n_delta`` (a positive integer)."""
    if isinstance(n_delta, bool) or not isinstance(n_delta, int | np.integer) or n_delta < 1:
        raise ValueError(f"n_delta must be a positive integer; got {n_delta!r}.")
    return int(n_delta)


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


# ---------------------------------------------------------------------------
# Gaussian bumps
# ---------------------------------------------------------------------------


def _compile_radial(library: RadialBasis, features: tuple[str, ...], n_delta: int):
    """Compile a `RadialBasis` (the row shared by all rows)."""
    missing = [name for name in library.centers if name not in features]
    if missing:
        raise ValueError(f"RadialBasis names {missing}, which are not among {list(features)}.")
    groups = [
        (features.index(name), centers, library.widths[name], library.limits.get(name))
        for name, centers in library.centers.items()
    ]

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        columns = [jnp.ones((), v.dtype)] if library.linear else []
        for j, centers, width, limits in groups:
            value = v[j] if limits is None else jnp.clip(v[j], *limits)
            columns += [value] if library.linear else []
            columns += [jnp.exp(-0.5 * ((value - c) / width) ** 2) for c in centers]
        return jnp.stack(columns)

    return _shared_row(phi, tuple(library.feature_names()), features, n_delta)


def _shared_row(phi: FeatureFn, names: tuple[str, ...], features, n_delta: int) -> CompiledBasis:
    """A dictionary whose row ``phi(v)`` is shared by all ``n_delta`` corrected rows (no
    inner parameters)."""
    n_features, m = len(features), len(names)

    def evaluate(inner_params: dict[str, Any], v: jnp.ndarray) -> jnp.ndarray:
        """Return ``Φ(v)`` of shape ``(n_delta, m)``; ``inner_params`` is unused."""
        return jnp.broadcast_to(phi(_as_vector(v, n_features)), (n_delta, m))

    omega = np.ones((n_delta, m), dtype=bool)
    return CompiledBasis(names, {}, {}, omega, jax.jit(evaluate), features)


# ---------------------------------------------------------------------------
# pysindy libraries
# ---------------------------------------------------------------------------


def _compile_pysindy(library: Any, features: tuple[str, ...], n_delta: int) -> CompiledBasis:
    """Compile a pysindy feature library (the row φ(v) is shared by all δ_i)."""
    _check_supported(library)
    fitted = _fit_copy(library, len(features))
    phi = _build_features(fitted)
    names = tuple(str(name) for name in fitted.get_feature_names(list(features)))
    _check_against_transform(fitted, phi, names)
    return _shared_row(phi, names, features, n_delta)


def _supported_message() -> str:
    """List the supported dictionary types for error messages."""
    names = [cls.__name__ for cls in _builders()] + ["IdentityLibrary()"]
    return "Supported: RidgeBasis and pysindy " + ", ".join(names) + " (nested freely)."


def _check_supported(library: Any) -> None:
    """Recursively reject unsupported library types before fitting anything."""
    for rejected, reason in _rejected_libraries():
        if isinstance(library, rejected):
            raise TypeError(
                f"{type(library).__name__} is not supported as a correction basis ({reason}). "
                f"{_supported_message()}"
            )
    if type(library) not in _builders():
        raise TypeError(f"Unsupported basis type {type(library).__name__}. {_supported_message()}")
    if _builders()[type(library)] is _custom_features:
        _check_custom_callables(library)
    for sub in getattr(library, "libraries", None) or []:
        _check_supported(sub)


def _check_custom_callables(library: CustomLibrary) -> None:
    """Require plain python functions (pysindy counts args via ``__code__``)."""
    for i, func in enumerate(library.functions):
        if not hasattr(func, "__code__"):
            raise TypeError(
                f"CustomLibrary function {i} ({func!r}) must be a python function (def or "
                "lambda) written with jax.numpy; pysindy counts its arguments via __code__."
            )


def _dummy_data(n_features: int) -> np.ndarray:
    """Small deterministic float64 data, positive and away from 0."""
    rng = np.random.default_rng(_DUMMY_SEED)
    return rng.uniform(0.2, 1.0, size=(_N_DUMMY_SAMPLES, n_features))


def _fit_copy(library: Any, n_features: int) -> Any:
    """Fit a deep copy of ``library`` on dummy data; the original is untouched."""
    fitted = copy.deepcopy(library)
    try:
        fitted.fit(_dummy_data(n_features))
    except Exception as err:
        raise ValueError(
            f"Could not fit a copy of {type(library).__name__} on dummy data with "
            f"{n_features} input features: {err}"
        ) from err
    return fitted


def _build_features(library: Any) -> FeatureFn:
    """Dispatch on the (fitted, supported) library type."""
    return _builders()[type(library)](library)


def _check_against_transform(library: Any, phi: FeatureFn, names: tuple[str, ...]) -> None:
    """Compare the JAX features with pysindy's own ``transform`` on dummy data.

    ``n_output_features_`` is not trusted (it is wrong for some composite
    libraries in pysindy 2.1); the actual ``transform`` output is.
    """
    name = type(library).__name__
    dummy = _dummy_data(library.n_features_in_)
    reference = np.asarray(library.transform(dummy), dtype=float)
    if len(names) != reference.shape[1]:
        raise ValueError(
            f"{name} is inconsistent in pysindy: get_feature_names gives {len(names)} names "
            f"but transform gives {reference.shape[1]} features (e.g. exclude_libraries "
            "pointing at a tensored library of a GeneralizedLibrary)."
        )
    if not names:
        raise ValueError(f"{name} produces no features for these input_features.")
    ours = np.asarray(jax.jit(jax.vmap(phi))(jnp.asarray(dummy)), dtype=float)
    if ours.shape != reference.shape or not np.allclose(
        ours, reference, rtol=1e-4, atol=1e-6, equal_nan=True
    ):
        raise ValueError(
            f"Compiled JAX features of {name} (shape {ours.shape}) do not match its "
            f"transform (shape {reference.shape}); this library variant is not supported."
        )


def _concat_features(parts: list[tuple[FeatureFn, np.ndarray]]) -> FeatureFn:
    """Concatenate sub-features ``φ_k(v[idx_k])`` in order."""

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        return jnp.concatenate([fn(take(v, idx)) for fn, idx in parts])

    return phi


def _unique(indices: Sequence[int]) -> np.ndarray:
    """Remove duplicates preserving order (pysindy's ``_unique``)."""
    return np.asarray(list(dict.fromkeys(int(i) for i in indices)), dtype=int)


def _polynomial_features(library: PolynomialLibrary) -> FeatureFn:
    """Monomials ``Π_k v_k^{p_jk}`` from the integer ``powers_`` matrix.

    Each monomial is a plain product of entries (``v_0 v_0 v_1`` for powers
    ``(2, 1)``), starting from 1, so gradients are finite at ``v = 0``. The term
    order is pysindy's. Entries are taken one by one with static indices (see
    `take`): no gather inside the simulation loop.
    """
    powers = np.asarray(library.powers_, dtype=int)
    factors = [tuple(np.repeat(np.arange(powers.shape[1]), row).tolist()) for row in powers]

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        one = jnp.ones((), v.dtype)
        monomials = [functools.reduce(lambda a, k: a * v[k], f, one) for f in factors]
        return jnp.stack(monomials) if monomials else jnp.zeros((0,), v.dtype)

    return phi


def _fourier_features(library: FourierLibrary) -> FeatureFn:
    """``sin(k v_j)``, ``cos(k v_j)`` for ``k = 1..n_frequencies`` (pysindy order)."""
    rows = [
        (k + 1, j, is_sin)
        for k in range(library.n_frequencies)
        for j in range(library.n_features_in_)
        for is_sin in (True, False)
        if (library.include_sin if is_sin else library.include_cos)
    ]
    freq, feat, sin_mask = (np.asarray(col) for col in zip(*rows, strict=True))
    freq = freq.astype(float)

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        arg = jnp.asarray(freq, dtype=v.dtype) * take(v, feat)
        return jnp.where(sin_mask, jnp.sin(arg), jnp.cos(arg))

    return phi


def _custom_combinations(n_features: int, n_args: int, interaction_only: bool) -> list[tuple]:
    """Argument index tuples of a custom function (pysindy's order)."""
    comb = itertools.combinations if interaction_only else itertools.combinations_with_replacement
    return list(comb(range(n_features), n_args))


def _custom_features(library: CustomLibrary) -> FeatureFn:
    """``f_i(v_a, v_b, ...)`` over argument combinations, optional bias first."""
    _check_custom_traceable(library)
    n = library.n_features_in_
    terms = [
        (func, combo)
        for func in library.functions
        for combo in _custom_combinations(n, func.__code__.co_argcount, library.interaction_only)
    ]
    bias = bool(library.include_bias)

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        cols = [jnp.ones((), v.dtype)] if bias else []
        cols += [jnp.asarray(f(*(v[j] for j in c))).astype(v.dtype) for f, c in terms]
        return jnp.stack(cols) if cols else jnp.zeros((0,), v.dtype)

    return phi


def _check_custom_traceable(library: CustomLibrary) -> None:
    """Trace every custom function abstractly; fail early if JAX cannot."""
    for i, func in enumerate(library.functions):
        n_args = func.__code__.co_argcount
        args = [jax.ShapeDtypeStruct((), jnp.result_type(float))] * n_args
        label = _custom_label(library, i, func)
        try:
            out = jax.eval_shape(func, *args)
        except Exception as err:
            raise TypeError(
                f"CustomLibrary function {label} cannot be evaluated on JAX arrays "
                f"({type(err).__name__}). Write it with jax.numpy (jnp.exp, jnp.sin, ...) "
                "instead of numpy/math, and avoid python control flow on its arguments."
            ) from err
        if getattr(out, "shape", None) != ():
            raise TypeError(
                f"CustomLibrary function {label} must return one scalar per scalar "
                f"argument; it returned {out!r}."
            )


def _custom_label(library: CustomLibrary, index: int, func: Callable) -> str:
    """Human-readable identification of custom function ``index``."""
    label = f"{index} ({getattr(func, '__name__', repr(func))!r}"
    names = library.function_names
    if names is not None and index < len(names):
        args = [f"x{k}" for k in range(func.__code__.co_argcount)]
        try:
            label += f", feature name {names[index](*args)!r}"
        except Exception:  # a broken name function must not hide the real error
            pass
    return label + ")"


def _concat_library_features(library: ConcatLibrary) -> FeatureFn:
    """Concatenation ``[φ_1(v), φ_2(v), ...]`` of the sub-libraries."""
    everything = np.arange(library.n_features_in_)
    return _concat_features([(_build_features(sub), everything) for sub in library.libraries])


def _tensored_features(library: TensoredLibrary) -> FeatureFn:
    """Row-wise Kronecker product ``φ_1(v[I_1]) ⊗ φ_2(v[I_2]) ⊗ ...``.

    Feature ``a * m_2 + b`` of a two-factor product is ``φ_1a · φ_2b``,
    matching pysindy's ordering and the names ``"<name_a> <name_b>"``.
    """
    parts = [
        (_build_features(sub), _unique(inputs))
        for sub, inputs in zip(library.libraries, library.inputs_per_library, strict=True)
    ]

    def phi(v: jnp.ndarray) -> jnp.ndarray:
        out = parts[0][0](take(v, parts[0][1]))
        for fn, idx in parts[1:]:
            out = (out[:, None] * fn(take(v, idx))[None, :]).reshape(-1)
        return out

    return phi


def _generalized_features(library: GeneralizedLibrary) -> FeatureFn:
    """Base libraries on their input subsets (minus excluded), then tensor products.

    Mirrors ``GeneralizedLibrary.transform`` of pysindy 2.1: indices in
    ``exclude_libraries`` only drop *base* libraries; tensored libraries
    receive the full ``v`` and subselect internally.
    """
    n_base = len(library.inputs_per_library)
    excluded = set(library.exclude_libraries or [])
    everything = np.arange(library.n_features_in_)
    parts = []
    for i, sub in enumerate(library.libraries_full_):
        if i >= n_base:
            parts.append((_build_features(sub), everything))
        elif i not in excluded:
            parts.append((_build_features(sub), _unique(library.inputs_per_library[i])))
    return _concat_features(parts)


@functools.cache
def _builders() -> dict[type, Callable[[Any], FeatureFn]]:
    """The compiler of each supported pysindy library type (imports pysindy)."""
    from pysindy import feature_library as fl

    return {
        fl.PolynomialLibrary: _polynomial_features,
        fl.FourierLibrary: _fourier_features,
        fl.CustomLibrary: _custom_features,
        fl.ConcatLibrary: _concat_library_features,
        fl.TensoredLibrary: _tensored_features,
        fl.GeneralizedLibrary: _generalized_features,
    }


# ---------------------------------------------------------------------------
# Ridge basis
# ---------------------------------------------------------------------------

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
