r"""[`compile_basis`][sk_offwhite.compile_basis]: a dictionary description to a
[`CompiledBasis`][sk_offwhite.dictionaries.CompiledBasis], equal descriptions sharing one.

Equal library descriptions share one compiled basis, hence one ``evaluate`` object, so the
jitted rollout (whose static argument holds ``evaluate``) is compiled once for all clones
of an estimator (cross-validation, grid searches) instead of once per fit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ._compiled import CompiledBasis
from ._pysindy import _compile_pysindy, _library_key
from ._radial import RadialBasis, _compile_radial
from ._ridge import RidgeBasis, _compile_ridge

__all__ = ["compile_basis", "release_compiled_libraries"]


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
