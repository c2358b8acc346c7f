"""Checks of the estimator's arguments beyond its parameter table: index lists, counts that
must not be booleans, initial windows, sample weights and per-record arguments."""

from __future__ import annotations

import hashlib
import warnings

import numpy as np
from sklearn.utils.validation import _check_sample_weight

from ._validation import is_experiment_list
from .model._physics import LinearStateSpace


def _indices(given, size: int, name: str, allow_empty: bool) -> tuple[int, ...]:
    """``given`` as a tuple of distinct integer indices in ``[0, size)``, else a
    ``ValueError`` naming ``name``."""
    values = np.atleast_1d(np.asarray(given))
    usable = values.ndim == 1 and (values.dtype.kind in "iu" or values.size == 0)
    indices = tuple(int(i) for i in values) if usable else None
    if (
        indices is None
        or (not indices and not allow_empty)
        or not all(0 <= i < size for i in indices)
        or len(set(indices)) != len(indices)
    ):
        raise ValueError(f"{name} must be distinct integer indices in [0, {size}), got {given!r}.")
    return indices


def _check_counts(est) -> None:
    """Integer settings must not be booleans (``True`` passes as the integer 1)."""
    for name in ("horizon", "max_iter", "init_window"):
        if isinstance(getattr(est, name), bool | np.bool_):
            raise ValueError(f"{name} must be an integer, got {getattr(est, name)!r}.")


def _checked_z_init(z_init, n_samples: int, n_outputs: int) -> np.ndarray:
    """``z_init`` as ``(n_init, n_outputs)`` finite floats covering at most the record."""
    if is_experiment_list(z_init):
        raise ValueError("z_init is a list, but u is one record: pass one array.")
    try:
        values = np.asarray(z_init, float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"z_init must be an array of numbers, got {z_init!r}.") from error
    if values.size == 0:  # no initial window: the fitted initial state
        return values.reshape(0, n_outputs)
    values = values.reshape(len(values), -1) if values.ndim else values.reshape(1, -1)
    if values.shape[1] != n_outputs or len(values) > n_samples:
        raise ValueError(
            f"z_init must have shape (n_init, {n_outputs}) with n_init <= {n_samples} (the "
            f"length of u), got {np.shape(z_init)}."
        )
    if not np.all(np.isfinite(values)):
        raise ValueError("z_init must be finite: it holds NaN or inf.")
    return values


def _record_weights(sample_weight, records: list[tuple]) -> list[np.ndarray]:
    """``sample_weight`` cut into the records' rows (ones where it is ``None``)."""
    lengths = [u.shape[0] for u, _ in records]
    rows = np.empty((sum(lengths), 0))
    weights = _check_sample_weight(sample_weight, rows, ensure_non_negative=True)
    return np.split(weights, np.cumsum(lengths)[:-1])


def _per_record(name: str, values, n_records: int) -> list:
    """``values`` for each of ``n_records`` records: ``None`` for all, or a list of them."""
    if values is None:
        return [None] * n_records
    one_each = isinstance(values, list | tuple) and len(values) == n_records
    if not (one_each and all(v is None or np.ndim(v) >= 1 for v in values)):
        raise ValueError(
            f"with {n_records} input records, {name} must be None or a list of {n_records} "
            "arrays (one per record)."
        )
    return list(values)


def records_digest(records) -> str:
    """Fingerprint of the records' values (and so of where they are cut)."""
    digest = hashlib.sha1()
    for u, z in records:
        digest.update(np.ascontiguousarray(u, float).tobytes())
        digest.update(np.ascontiguousarray(z, float).tobytes())
    return digest.hexdigest()


def check_enough_data(physics, records) -> None:
    """Refuse records that hold fewer output values than the fit has unknowns (the free
    parameters and each record's free initial states): no fit can determine them. The
    linear black box of an estimator without physics is exempt: it stands in for a
    model, and scikit-learn's common checks fit it on fewer rows than it has entries."""
    if isinstance(physics.step, LinearStateSpace):
        return
    n_values = sum(z.size for _, z in records)
    n_parameters = len(physics.free_parameter_names)
    n_states = int(np.sum(~np.asarray(physics.x0_fixed))) * len(records)
    if n_values >= n_parameters + n_states:
        return
    n_samples = sum(len(z) for _, z in records)
    raise ValueError(
        f"z: {n_samples} samples give {n_values} output values for {n_parameters + n_states} "
        f"unknowns ({n_parameters} free parameters, {n_states} free initial states): too few "
        "samples to determine them; record more samples or fix some (Parameter(fixed=True), "
        "x0_fixed=True)."
    )


def warn_if_constant(records) -> None:
    """Warn when an output or an input column never changes over the records: a constant
    output carries nothing about the dynamics, a constant input cannot reveal the
    parameters through which it acts."""
    u = np.vstack([u for u, _ in records])
    z = np.vstack([z for _, z in records])
    for name, values, what in (
        ("z", z, "the parameters are not determined by it"),
        ("u", u, "the parameters through which it acts are not determined"),
    ):
        constant = [j for j in range(values.shape[1]) if np.ptp(values[:, j]) == 0]
        if constant and len(values) > 1:
            warnings.warn(
                f"{name} is constant over the records (column(s) {constant}): {what}; fit "
                "on a record that excites the system.",
                UserWarning,
                stacklevel=4,
            )
