"""Find the reads of a traced function past the end of an array.

JAX does not raise for an index beyond an array's length: it clamps it to the last element,
so a physics that reads ``u[3]`` of a single input silently reads ``u[0]``. Here the
function is traced once (``jax.make_jaxpr``) and every slice it takes at a position known
when it is traced (a literal index, an index array of constants) is checked against the
length of the array it slices, in nested programs too.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.extend.core as jcore
import numpy as np

__all__ = ["OutOfRange", "out_of_range_reads"]

_EVALUATED = 10_000
"""Index arithmetic with at most this many elements is evaluated at trace time."""


class OutOfRange(NamedTuple):
    """A read of element ``index`` of an array of ``length`` elements."""

    index: int
    length: int


def out_of_range_reads(function, *args) -> list[OutOfRange]:
    """Every read of ``function(*args)`` beyond an array's length whose position is fixed
    when the function is traced (none when it cannot be traced).

    Traced under ``enable_x64``, as every fit is: a first trace at another width would
    leave the constants JAX caches for ``function`` at that width."""
    try:
        with jax.enable_x64(True):
            closed = jax.make_jaxpr(function)(*args)
    except Exception:  # noqa: BLE001 - the physics' own checks report untraceable code
        return []
    values = dict(zip(closed.jaxpr.constvars, map(np.asarray, closed.consts), strict=True))
    return _scan(closed.jaxpr, values)


def _scan(jaxpr, values: dict) -> list[OutOfRange]:
    found = []
    for eqn in jaxpr.eqns:
        inputs = [_value(var, values) for var in eqn.invars]
        found += _reads(eqn, inputs)
        found += _nested(eqn, inputs)
        for var, value in zip(eqn.outvars, _evaluated(eqn, inputs), strict=True):
            if value is not None:
                values[var] = value
    return found


def _value(var, values: dict):
    """The concrete value of ``var`` (a literal, a constant, or computed from them)."""
    if isinstance(var, jcore.Literal):
        return np.asarray(var.val)
    return values.get(var)


def _evaluated(eqn, inputs: list) -> list:
    """The outputs of ``eqn`` where every input is known and small, else ``None``s."""
    unknown = [None] * len(eqn.outvars)
    if not inputs or any(v is None or np.size(v) > _EVALUATED for v in inputs):
        return unknown
    if any(isinstance(p, jcore.ClosedJaxpr | jcore.Jaxpr) for p in eqn.params.values()):
        return unknown
    try:
        out = eqn.primitive.bind(*inputs, **eqn.params)
    except Exception:  # noqa: BLE001 - an operation we cannot evaluate leaves it unknown
        return unknown
    out = out if eqn.primitive.multiple_results else [out]
    return [np.asarray(o) for o in out]


def _reads(eqn, inputs: list) -> list[OutOfRange]:
    """The out-of-range reads of one slicing operation."""
    name = eqn.primitive.name
    if name == "dynamic_slice":
        shape, sizes = eqn.invars[0].aval.shape, eqn.params["slice_sizes"]
        return [
            OutOfRange(int(start), int(dim))
            for start, size, dim in zip(inputs[1:], sizes, shape, strict=True)
            if start is not None and not 0 <= int(start) <= dim - size
        ]
    if name == "gather" and inputs[1] is not None:
        return _gather_reads(eqn, inputs[1])
    return []


def _gather_reads(eqn, indices) -> list[OutOfRange]:
    shape = eqn.invars[0].aval.shape
    numbers, sizes = eqn.params["dimension_numbers"], eqn.params["slice_sizes"]
    starts = np.asarray(indices).reshape(-1, len(numbers.start_index_map))
    found = []
    for column, dim in enumerate(numbers.start_index_map):
        bad = (starts[:, column] < 0) | (starts[:, column] > shape[dim] - sizes[dim])
        found += [OutOfRange(int(i), int(shape[dim])) for i in np.unique(starts[bad, column])]
    return found


def _nested(eqn, inputs: list) -> list[OutOfRange]:
    """The reads of the programs nested in ``eqn`` (a ``jit``, a branch, a loop body)."""
    found = []
    for param in eqn.params.values():
        for sub in param if isinstance(param, tuple | list) else (param,):
            jaxpr, consts = _program(sub)
            if jaxpr is None:
                continue
            values = dict(zip(jaxpr.constvars, map(np.asarray, consts), strict=True))
            if len(jaxpr.invars) == len(inputs):  # a call: its inputs are the equation's
                values.update({v: x for v, x in zip(jaxpr.invars, inputs, strict=True)
                               if x is not None})  # fmt: skip
            found += _scan(jaxpr, values)
    return found


def _program(param):
    """``(jaxpr, consts)`` of a nested program parameter, else ``(None, ())``."""
    if isinstance(param, jcore.ClosedJaxpr):
        return param.jaxpr, param.consts
    if isinstance(param, jcore.Jaxpr):
        return param, ()
    return None, ()
