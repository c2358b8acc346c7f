r"""pysindy 2.1 feature libraries as pure ``jax.numpy`` features.

pysindy's ``transform`` is NumPy-only, so every feature is re-implemented in ``jax.numpy``
from the library's description (`powers_`, frequencies, functions, names) and checked
against ``transform`` on dummy data: polynomial, Fourier, identity, custom (functions
written with ``jax.numpy``), concatenated, tensored and generalized libraries, nested
arbitrarily. The row $\varphi(v)$ is shared by all corrected equations. PDE, weak-PDE,
SINDy-PI and parameterized libraries are refused with the reason.
"""

from __future__ import annotations

import copy
import functools
import itertools
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import numpy as np

if TYPE_CHECKING:
    from pysindy.feature_library import (
        ConcatLibrary,
        CustomLibrary,
        FourierLibrary,
        GeneralizedLibrary,
        PolynomialLibrary,
        TensoredLibrary,
    )

from ..simulation._rollout import take
from ._compiled import CompiledBasis, FeatureFn, _shared_row

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
