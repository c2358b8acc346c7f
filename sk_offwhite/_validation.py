"""Validation of user data and of the physics functions, with errors that name the argument."""

from __future__ import annotations

import weakref

import jax
import numpy as np
from sklearn.utils import check_array

from .model._physics import PhysicsModel
from .runtime._backend import to_device

__all__ = ["as_records", "check_inputs", "check_pair", "check_physics", "is_experiment_list"]


def is_experiment_list(data) -> bool:
    """True for a list/tuple of 2-D arrays: several experiments rather than rows."""
    return (
        isinstance(data, list | tuple)
        and len(data) > 0
        and all(isinstance(item, np.ndarray) and item.ndim == 2 for item in data)
    )


def _named(name: str, values, **options) -> np.ndarray:
    """``check_array(values, **options)`` whose errors begin with the argument's ``name``
    (scikit-learn's messages do not always say which array they mean)."""
    try:
        return check_array(values, input_name=name, **options)
    except (TypeError, ValueError) as error:
        message = str(error)
        if message.startswith(f"{name}:") or message.startswith(f"{name} "):
            raise
        raise type(error)(f"{name}: {message}") from error


def _check_one(name: str, values, ensure_2d: bool = True) -> np.ndarray:
    values = _named(
        name,
        values,
        dtype=np.float64,
        ensure_2d=ensure_2d,
        ensure_all_finite=True,
        ensure_min_samples=1,
        copy=False,
    )
    return values if values.ndim == 2 else values.reshape(-1, 1)


LARGEST_VALUE = 1e150
"""Magnitude past which a record's squares overflow float64 in the fit's cost; such data
are refused (a rescaled record gives the same model: the fit is unit-free)."""


def check_magnitude(name: str, values: np.ndarray) -> None:
    """Refuse finite values whose squares overflow (`LARGEST_VALUE`)."""
    largest = float(np.max(np.abs(values), initial=0.0))
    if largest > LARGEST_VALUE:
        raise ValueError(
            f"{name} holds values up to {largest:.3g}, whose squares overflow in the fit's "
            f"cost: rescale {name} (the model is unit-free, so a rescaled record gives the "
            "same fit up to the scale)."
        )


def _refuse_flat_records(u) -> None:
    """A list of 1-D arrays would be read as rows of one record: refuse it, naming ``u``."""
    if isinstance(u, list | tuple) and u and all(isinstance(item, np.ndarray) for item in u):
        shapes = [item.shape for item in u]
        if any(len(shape) != 2 for shape in shapes):
            raise ValueError(
                "u: a list of records must hold 2-D arrays of shape (n_samples, n_inputs), "
                f"got arrays of shapes {shapes}; reshape each 1-D record with "
                "u_e.reshape(-1, 1)."
            )


def check_inputs(u) -> np.ndarray:
    """Validated input array ``u`` of shape ``(n_samples, n_inputs)``, finite, float64."""
    return _named("u", u, dtype=np.float64, ensure_all_finite=True)


def check_input_width(estimator, n_inputs: int) -> None:
    """Raise if ``u`` has another number of columns than the fitted ``n_features_in_``."""
    if n_inputs != estimator.n_features_in_:
        raise ValueError(
            f"u has {n_inputs} features, but {type(estimator).__name__} is expecting "
            f"{estimator.n_features_in_} features as input."
        )


def check_pair(u, z) -> tuple[np.ndarray, np.ndarray]:
    """Validated ``u`` and ``z`` (1-D or 2-D) with one row each per sample."""
    if z is None:
        raise ValueError(
            "z is None: this estimator requires y to be passed, but the target y is None "
            "(z holds the measured outputs)."
        )
    _refuse_flat_records(u)
    u = check_inputs(u)
    z = _named("z", z, dtype=np.float64, ensure_2d=False, ensure_all_finite=True)
    check_magnitude("u", u)
    check_magnitude("z", z)
    if z.ndim > 2:
        raise ValueError(f"z must be 1-D or 2-D, got an array of shape {z.shape}.")
    if u.shape[0] != z.shape[0]:
        raise ValueError(f"u has {u.shape[0]} samples but z has {z.shape[0]}.")
    return u, z


def check_record(u, z) -> tuple[np.ndarray, np.ndarray]:
    """`check_pair` with ``z`` as a 2-D array ``(n_samples, n_outputs)``: one record (a
    list of records is refused, naming it)."""
    if is_experiment_list(u) or is_experiment_list(z):
        raise ValueError(
            "u and z must be one record here (2-D arrays), not a list of records: fit each "
            "record apart, or join records that follow each other."
        )
    u, z = check_pair(u, z)
    return u, z.reshape(z.shape[0], -1)


def _checked_experiment(e: int, u, z) -> tuple[np.ndarray, np.ndarray]:
    """Experiment ``e``'s ``(u, z)``, each 2-D, finite, of a representable size, and of
    equal lengths."""
    u, z = _check_one(f"u[{e}]", u), _check_one(f"z[{e}]", z, False)
    check_magnitude(f"u[{e}]", u)
    check_magnitude(f"z[{e}]", z)
    if u.shape[0] != z.shape[0]:
        raise ValueError(f"u[{e}] has {u.shape[0]} samples but z[{e}] has {z.shape[0]}.")
    return u, z


def as_records(u, z) -> list[tuple[np.ndarray, np.ndarray]]:
    """Validate a list of experiments ``[(u_e, z_e)]`` (each 2-D, finite, equal lengths)."""
    if not is_experiment_list(u) or len(u) != len(z):
        raise ValueError(
            "u and z must both be lists of 2-D arrays with one entry per experiment; got "
            f"{type(u).__name__} of length {len(u)} and {type(z).__name__} of length {len(z)}."
        )
    records = [_checked_experiment(e, ue, ze) for e, (ue, ze) in enumerate(zip(u, z, strict=True))]
    widths = {(ue.shape[1], ze.shape[1]) for ue, ze in records}
    if len(widths) != 1:
        raise ValueError(f"all experiments must have the same numbers of columns, got {widths}.")
    return records


def _traceable(name: str, fun, *args, evaluate: bool = False):
    """``fun``'s output shapes at ``args`` (``jax.eval_shape``) or, with ``evaluate``, its
    value, computed by one jitted program (traced once, not one program per operation)."""
    try:
        return jax.jit(fun)(*args) if evaluate else jax.eval_shape(fun, *args)
    except Exception as error:  # any failure to trace is the user's function, re-raised
        raise TypeError(
            f"{name} cannot be evaluated with JAX ({type(error).__name__}: {error}). "
            "Write it with jax.numpy operations so it can be simulated and differentiated."
        ) from error


def _check_hashable(name: str, fun) -> None:
    """Refuse a function object without a hash: its compiled programs are kept per function."""
    try:
        hash(fun)
    except TypeError:
        raise TypeError(
            f"{name} must be hashable (a function, or an object that defines __hash__ and "
            "__eq__): the programs compiled from it are kept per function."
        ) from None


def _cacheable(fun):
    """``fun`` itself where `jax.jit` can keep its program between calls (a physics checked
    again compiles nothing), else a wrapper of it (an object with no weak reference)."""
    try:
        weakref.ref(fun)
    except TypeError:
        return lambda *args: fun(*args)
    return fun


def _returned_type(fun):
    """``fun`` wrapped to record the type of what it returns while it is traced (a JAX
    array, or what the user's code built: a Python float, a dict, ...), and that record."""
    returned = []

    def recorded(*args):
        value = fun(*args)
        returned.append(value)
        return value

    return recorded, returned


def _check_kind(name: str, value, where: str) -> None:
    """Refuse a result that is not an array of real floating-point numbers (a Python
    scalar, a container, booleans, integers or complex numbers)."""
    if not isinstance(value, jax.Array | np.ndarray):
        raise TypeError(
            f"{name} returned a {type(value).__name__}, not an array ({where}): return a "
            "jax.numpy array of real numbers, for example jnp.stack([...])."
        )
    if np.dtype(value.dtype).kind != "f":
        raise TypeError(
            f"{name} returned an array of dtype {value.dtype} ({where}): it must return real "
            "floating-point numbers (a boolean, integer or complex result cannot be "
            "simulated and differentiated as a model)."
        )


def _check_result(name: str, value, expected: tuple[int, ...], where: str) -> None:
    shape = tuple(np.shape(value))
    if shape != expected and not (expected == (1,) and shape == ()):
        raise ValueError(f"{name} returned shape {shape}, expected {expected} ({where}).")


def check_physics(physics: PhysicsModel, n_inputs: int, n_outputs: int, u0) -> None:
    """Check dimensions, traceability, shapes and finiteness at the initial guess."""
    if physics.n_inputs != n_inputs:
        raise ValueError(f"u has {n_inputs} column(s) but physics.n_inputs is {physics.n_inputs}.")
    x0 = to_device(physics.x0)
    u0 = to_device(u0)
    theta = {k: to_device(p.value) for k, p in physics.parameters.items()}
    where = "at the initial guess of x0 and the parameters"
    checks = [
        ("physics.step", physics.step, (physics.n_states,)),
        ("physics.output", physics.output, (n_outputs,)),
    ]
    constraints = [
        (name, fun, None)
        for name, fun in (
            ("physics.inequality", physics.inequality),
            ("physics.equality", physics.equality),
        )
        if fun is not None
    ]
    for name, fun, expected in checks + constraints:
        _check_hashable(name, fun)
        recorded, returned = _returned_type(fun)
        _traceable(name, recorded, x0, u0, theta)
        _check_kind(name, returned[0], where)
        value = _traceable(name, _cacheable(fun), x0, u0, theta, evaluate=True)
        if expected is not None:
            _check_result(name, value, expected, where)
        _check_finite(name, np.asarray(value), where)


def _check_finite(name: str, value: np.ndarray, where: str) -> None:
    if not np.all(np.isfinite(value)):
        raise ValueError(
            f"{name} returned non-finite values {value} {where}; "
            "change physics.x0 or the parameter values."
        )
