r"""A start that works when the initial guess's simulation explodes: continuation in the
horizon.

From an unstable guess (a pole outside the unit circle, a wrong sign) the simulation over
a long record grows like $|a|^N$ and its cost overflows or is so steep that no solver
step finds a descent. Over a short window the same guess is harmless: the error grows like
$|a|^T$. So the physical parameters are first fitted by multiple shooting over windows
of `FIRST_HORIZON` step, whose initial states start at the data (the measured states,
`within_reach`): the fit term then pins the window starts to
the measurements and the continuity term is the one-step (equation) error of the physics,
which has no explosive direction. Then over windows four times longer, each fit starting
from the previous one, until the model's free run over the whole records no longer
explodes or the windows reach the requested horizon.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterator

import jax.numpy as jnp
import numpy as np

from ..simulation._rollout import free_run_record

__all__ = ["FIRST_HORIZON", "continuation_start", "within_reach"]

FIRST_HORIZON = 1
"""Window length of the first fit of the continuation (steps)."""


def _horizons(target: int) -> Iterator[int]:
    """``FIRST_HORIZON``, four times longer, ..., every one shorter than ``target``."""
    horizon = FIRST_HORIZON
    while horizon < target:
        yield horizon
        horizon *= 4


def continuation_start(fit: Callable, settings) -> dict | None:
    """Starting blocks (``theta`` and each record's initial state under ``"starts"``) from
    physics-only fits over lengthening windows (module docstring).

    ``settings`` is the `FitSettings` of the fit to start;
    ``fit`` is `fit_records` without its restart, called as
    ``fit(settings, warm)`` with the physics alone, each window length and the
    Levenberg-Marquardt solver (the windows make it sparse, see
    `_structured`). Returns ``None`` when the requested horizon is no
    longer than `FIRST_HORIZON`.
    """
    model = dataclasses.replace(
        settings.model, basis=None, delta_states=(), delta_outputs=(), inner_names=()
    )
    plain = settings._replace(basis=None, model=model)
    plain = plain._replace(options=settings.options._replace(solver="lm"))
    target = settings.horizon or max(u.shape[0] for u, _ in settings.records)
    warm = None
    for window in _horizons(target):
        outcome = fit(plain._replace(horizon=window), warm)
        starts = np.asarray(outcome.blocks["x0"])[np.asarray(outcome.segments.linked) == 0]
        warm = {"theta": outcome.blocks["theta"], "starts": list(starts)}
        if _free_runs_within_reach(model, warm, settings.records):
            break
    return warm


def _free_runs_within_reach(model, warm, records) -> bool:
    """Whether the physics at ``warm`` simulates every record without exploding."""
    theta = jnp.asarray(warm["theta"])
    for start, (u, z) in zip(warm["starts"], records, strict=True):
        _, outputs, _ = free_run_record(model, {"theta": theta}, start, u)
        if not within_reach(outputs, z):
            return False
    return True


def within_reach(outputs, z, reach: float = 10.0) -> bool:
    """Whether simulated ``outputs`` are finite and stay within ``reach`` times the data's
    largest deviation from its mean (per output): the simulation does not explode."""
    outputs, z = np.asarray(outputs), np.asarray(z)
    centre = np.mean(z, axis=0)
    spread = np.max(np.abs(z - centre), axis=0)
    deviation = np.abs(outputs - centre)
    return bool(np.all(np.isfinite(outputs)) and np.all(deviation <= reach * spread + 1e-300))
