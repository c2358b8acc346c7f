"""Validation of the user's arrays and settings, with errors that name the argument.

Every function returns a fresh float64 copy (or a checked scalar), so the caller's arrays
are never modified. A 1-D array is one column.
"""

from __future__ import annotations

from collections.abc import Sequence
from numbers import Integral, Real

import numpy as np

__all__ = [
    "as_columns",
    "as_signal",
    "check_confidence",
    "check_integer",
    "check_rows",
    "column_names",
    "is_constant",
    "read_only",
]


def as_columns(values, name: str) -> np.ndarray:
    """Float64 copy of ``values`` shaped ``(n_samples, n_columns)``; 1-D becomes one column.

    Raises
    ------
    ValueError
        Naming ``name``, when ``values`` is not numeric, is 0-D or more than 2-D, is empty,
        or holds NaN or infinity.
    """
    try:
        array = np.array(values, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be a numeric array ({error}).") from error
    if array.ndim == 1:
        array = array.reshape(-1, 1)
    if array.ndim != 2:
        raise ValueError(
            f"{name} must be 1-D or 2-D (n_samples, n_columns), got shape {array.shape}."
        )
    if array.size == 0:
        raise ValueError(f"{name} is empty (shape {array.shape}).")
    _check_finite(array, name)
    return array


def _check_finite(array: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(array)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise ValueError(
            f"{name} contains {int(bad.sum())} NaN or infinite value(s), the first at row "
            f"{row}, column {column}."
        )


def as_signal(values, name: str) -> np.ndarray:
    """Float64 copy of a single signal (1-D, or 2-D with one column) as a 1-D array."""
    array = as_columns(values, name)
    if array.shape[1] != 1:
        raise ValueError(
            f"{name} must be one signal (1-D or a single column), got shape {array.shape}; "
            "pass one output's residual at a time."
        )
    return array[:, 0]


def check_rows(name: str, array: np.ndarray, n_samples: int, reference: str) -> None:
    """Raise unless ``array`` has ``n_samples`` rows, as ``reference`` has."""
    if array.shape[0] != n_samples:
        raise ValueError(f"{name} has {array.shape[0]} samples but {reference} has {n_samples}.")


def check_integer(value, name: str, low: int, high: int, why: str = "") -> int:
    """``value`` as an ``int`` in ``[low, high]``; ``why`` explains the bounds in the error."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}.")
    if not low <= value <= high:
        reason = f" ({why})" if why else ""
        raise ValueError(f"{name} must be in [{low}, {high}]{reason}, got {value}.")
    return int(value)


def check_confidence(confidence) -> float:
    """``confidence`` as a float strictly between 0 and 1."""
    if isinstance(confidence, bool) or not isinstance(confidence, Real):
        raise TypeError(f"confidence must be a number, got {type(confidence).__name__}.")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be strictly between 0 and 1, got {confidence}.")
    return float(confidence)


def column_names(names, n_columns: int, argument: str, prefix: str) -> tuple[str, ...]:
    """Checked names for ``n_columns`` columns; ``None`` gives ``prefix1, prefix2, ...``."""
    if names is None:
        return tuple(f"{prefix}{j + 1}" for j in range(n_columns))
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise TypeError(f"{argument} must be a sequence of strings, got {type(names).__name__}.")
    names = tuple(names)
    if len(names) != n_columns:
        raise ValueError(f"{argument} must have {n_columns} names, got {len(names)}: {names}.")
    if not all(isinstance(name, str) and name for name in names):
        raise TypeError(f"{argument} must hold non-empty strings, got {names}.")
    if len(set(names)) != len(names):
        raise ValueError(f"{argument} must not repeat a name, got {names}.")
    return names


def is_constant(signal: np.ndarray) -> bool:
    """True when every sample of ``signal`` is equal (its correlations are undefined)."""
    return bool(np.ptp(signal) == 0.0)


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` marked read-only, so a frozen result cannot be changed in place."""
    array.setflags(write=False)
    return array
