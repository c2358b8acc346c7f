"""How the package meets XLA's CPU backend: each simulation loop compiled into one kernel
(opt-in), and host arrays moved to the device without compiling anything.

XLA on CPU runs a ``while`` loop (a ``lax.scan``) in one of two ways: a loop whose cost
analysis counts fewer bytes accessed than a threshold (1 kB by default) is compiled into
one kernel; a larger one runs its body as separate operations, each dispatched at every
step. A grey-box step with a few effects and a dictionary is above that threshold, and
its derivatives far above, so each simulated step pays a dozen dispatches for a few
hundred floating-point operations. Raising the threshold compiles the whole loop into one
kernel, as XLA on CPU did before JAX 0.4.32. The package never raises it by itself: it is
set through ``XLA_FLAGS``, the process's configuration of XLA, which is the
application's to decide (the examples raise it; ``--no-fused-loops`` keeps them off it).

``jnp.asarray`` of a NumPy array outside a trace runs a one-operation XLA program, compiled
on its first use for each shape and dtype (a dozen of them in a first fit);
`to_device` transfers the same values with ``jax.device_put``, which compiles nothing.
"""

from __future__ import annotations

import os
import re
import warnings

import jax
import numpy as np

__all__ = ["FUSED_LOOP_BYTES", "enable_fused_loops", "fused_loops", "to_device"]

FUSED_LOOP_BYTES = 10**9
"""The threshold [`enable_fused_loops`][sk_offwhite.enable_fused_loops] sets (bytes accessed by one
loop, as XLA's cost analysis counts them): every loop of the package's programs is below it."""

_OPTION = "xla_cpu_small_while_loop_byte_threshold"
_EXTRA = "--xla_backend_extra_options="
_set_too_late = False  # enable_fused_loops set the option after this process's backend started


def enable_fused_loops(byte_limit: int = FUSED_LOOP_BYTES) -> bool:
    r"""Compile every ``while`` loop (simulation, Jacobian) accessing fewer than
    ``byte_limit`` bytes into one kernel on CPU, in this process and in the processes it
    starts afterwards (joblib and Dask workers, ``GridSearchCV(n_jobs=...)``).

    Adds ``xla_cpu_small_while_loop_byte_threshold`` to XLA's backend options in
    ``XLA_FLAGS``, which XLA reads once, when JAX starts its CPU backend: call this before
    the first JAX computation. The results are the same up to rounding; each simulated
    step then runs as one kernel instead of a dispatch per operation, which shortens the
    residuals, Jacobians and trial steps of models with effects or a dictionary (the speed
    benchmark's ``--fused-loops`` measures it).

    Parameters
    ----------
    byte_limit : int, default=FUSED_LOOP_BYTES
        Loops whose cost analysis counts fewer bytes accessed are compiled into one kernel.

    Returns
    -------
    bool
        Whether loops are compiled into one kernel in this process: ``False`` (with a
        warning) when JAX's backend had already started, in which case only processes
        started afterwards are; ``True`` when the option was set now or was already in
        ``XLA_FLAGS`` (then it is left as it is: the application's value wins).
    """
    global _set_too_late
    if int(byte_limit) <= 0:
        raise ValueError(f"byte_limit must be a positive number of bytes, got {byte_limit!r}.")
    flags = os.environ.get("XLA_FLAGS", "")
    if _OPTION in flags:
        return True
    os.environ["XLA_FLAGS"] = with_backend_option(flags, f"{_OPTION}={int(byte_limit)}")
    if _backend_started():
        _set_too_late = True
        warnings.warn(
            "enable_fused_loops: JAX's backend has already started in this process, so its "
            "loops keep XLA's default; processes started from now on compile them into one "
            "kernel. Call it before the first JAX computation.",
            RuntimeWarning,
            stacklevel=2,
        )
        return False
    return True


def fused_loops() -> bool:
    """Whether this process's loops are compiled into one kernel: the option of
    [`enable_fused_loops`][sk_offwhite.enable_fused_loops] is in ``XLA_FLAGS`` (an application's
    value is taken as it is), and was there before JAX started its backend."""
    return _OPTION in os.environ.get("XLA_FLAGS", "") and not _set_too_late


def with_backend_option(flags: str, option: str) -> str:
    """``flags`` (an ``XLA_FLAGS`` value) with ``option`` (``name=value``) added to its
    ``--xla_backend_extra_options`` list, which is created if missing."""
    match = re.search(r"--xla_backend_extra_options=(\S*)", flags)
    if match is None:
        return f"{flags} {_EXTRA}{option}".strip()
    merged = ",".join(filter(None, [match.group(1), option]))
    return flags[: match.start()] + _EXTRA + merged + flags[match.end() :]


def _backend_started() -> bool:
    """Whether JAX has started a backend in this process (``False`` if it cannot say)."""
    try:
        from jax._src.xla_bridge import backends_are_initialized
    except ImportError:  # pragma: no cover - a JAX without it
        return False
    return bool(backends_are_initialized())


def to_device(values, dtype=None):
    """``values`` as a JAX array of ``dtype`` (NumPy's rules; the enclosing ``enable_x64``
    decides the width), moved with ``jax.device_put``: no program is compiled or run."""
    return jax.device_put(np.asarray(values, dtype=dtype))
