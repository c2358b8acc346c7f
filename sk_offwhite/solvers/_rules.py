r"""Levenberg-Marquardt's rules, in one place for every run of it in the package.

A run holds the free vector, its damping $\mu$ and Marquardt's scaling $D$; each pass
solves the damped normal equations $(J^TJ + \mu D)\,s = -J^Tr$ over the variables that can
move (`held_at_bound`, `damped_diagonal`), tries the step and decides:

- an accepted step (a finite cost below the current one) divides $\mu$ by `DAMPING_DOWN`,
  a rejected one multiplies it by `DAMPING_UP` (`next_damping`);
- the run stops (`stop_code`) when a nearly undamped accepted step ($\mu < 1$) lowers the
  cost by less than ``tol`` of itself, when the cost reaches `ROUNDING_COST` (the data are
  reproduced to rounding; the cost is dimensionless) or when $\mu$ grows past `MAX_DAMPING`
  (no descent step is left: a stationary point). A small decrease under heavy damping only
  means the step was short.

The rules are written for NumPy or JAX arrays (``xp``), so the run on the device
(`sk_offwhite.solvers._device`), the one on the host over a coloured Jacobian
(`sk_offwhite.solvers._coloured`) and the initial-state estimation make the same decisions.
"""

from __future__ import annotations

import jax.numpy as jnp

__all__ = [
    "DAMPING_DOWN",
    "DAMPING_UP",
    "LM_SCALINGS",
    "MAX_DAMPING",
    "OUTCOMES",
    "ROUNDING_COST",
    "START_DAMPING",
    "checked_scaling",
    "creep_note",
    "damped_diagonal",
    "held_at_bound",
    "next_damping",
    "progress_line",
    "stop_code",
]

START_DAMPING, DAMPING_DOWN, DAMPING_UP, MAX_DAMPING = 1e-3, 3.0, 4.0, 1e10
"""Marquardt's damping: its start, its divisor after an accepted step and its factor after
a rejected one, and the value past which no descent step is left."""

ROUNDING_COST = 1e-24
"""A (dimensionless) cost at which the simulation reproduces the data to rounding: an RMS
error of 1e-12 output standard deviations."""

LM_SCALE_FLOOR = 1e-9
r"""Marquardt's scaling $D = \mathrm{diag}(J^TJ)$ gets this fraction of a largest entry
added (`damped_diagonal`), so that a variable the cost barely sees is not thrown by a huge
step."""

LM_SCALINGS = ("per-variable", "global")
"""The rules for the floor of Marquardt's scaling $D$ (`damped_diagonal`)."""

OUTCOMES = (
    "max_iter reached",
    "relative cost decrease below tol",
    "cost at rounding level (the data are reproduced)",
    "no descent step left (stationary point)",
)
"""Why a run ended, by the code of `stop_code` (0: it ran out of iterations)."""


def checked_scaling(scaling: str) -> str:
    """``scaling`` if it is one of `LM_SCALINGS`, else a ``ValueError``."""
    if scaling not in LM_SCALINGS:
        raise ValueError(f"scaling must be one of {LM_SCALINGS}, got {scaling!r}.")
    return scaling


def held_at_bound(free, gradient, lower, upper):
    r"""Which variables sit on a bound that the descent direction $-\nabla$ points out of
    (NumPy or JAX arrays): they take no part in the step."""
    return ((free <= lower) & (gradient > 0)) | ((free >= upper) & (gradient < 0))


def damped_diagonal(diag, damping, moving, xp, scale=None):
    r"""Marquardt's damping $\mu D$, $D = \mathrm{diag}(J^TJ) + \epsilon\,f$
    (`LM_SCALE_FLOOR`), with 1 on the rows of variables that are not ``moving`` (their rows
    and columns of $J^TJ$ are zero, so their step is zero) or that no residual has depended
    on yet; ``xp`` is ``numpy`` or ``jax.numpy``.

    ``scale=None`` (``scaling='global'``): $f = \max_j (J^TJ)_{jj}$, one floor for all
    variables, so the steps depend on their units. ``scale`` given (``'per-variable'``):
    $f_i$ = ``scale[i]``, the largest $(J^TJ)_{ii}$ variable $i$ has had so far in the run;
    $D_i$ then carries the units of $1/x_i^2$ alone, so rescaling a variable (a state in
    other units, a dictionary column times a constant) leaves the iterates the same up to
    rounding."""
    if scale is None:
        floor = LM_SCALE_FLOOR * xp.maximum(xp.max(diag), 1e-30)
        return xp.where(moving, damping * (diag + floor), 1.0)
    damped = damping * (diag + LM_SCALE_FLOOR * scale)
    return xp.where(moving & (scale > 0), damped, 1.0)


def next_damping(step, accepted, damping, xp=jnp):
    """Marquardt's update after a pass: divided after an accepted step, multiplied after a
    rejected one, unchanged after a pass that only evaluated the start (``step`` false)."""
    updated = xp.where(accepted, damping / DAMPING_DOWN, damping * DAMPING_UP)
    return xp.where(step, updated, damping)


def stop_code(step, accepted, small, damping, new_cost, xp=jnp):
    """The stopping rule that fires on a pass (an index of `OUTCOMES`, 0: none). ``small``:
    the accepted step lowered the cost by less than ``tol`` of itself; ``damping`` is the
    damping the step was taken with."""
    converged = step & accepted & small & (damping < 1.0)
    reproduced = step & accepted & (new_cost <= ROUNDING_COST)
    stationary = step & ~accepted & (damping * DAMPING_UP > MAX_DAMPING)
    return xp.select([converged, reproduced, stationary], [1, 2, 3], 0)


def small_decrease(previous, cost, tol, xp=jnp):
    """Whether ``cost`` lies less than ``tol`` (relative) below ``previous``."""
    return previous - cost <= tol * xp.maximum(previous, 1e-300)


CREEP_STEPS, CREEP_DECREASE = 20, 1e-4
"""A run stopped by ``max_iter`` whose last ``CREEP_STEPS`` accepted steps lowered the cost
by less than ``CREEP_DECREASE`` of itself was creeping, as along a direction the data do
not determine."""


def creep_note(history) -> str:
    """The note added to an unfinished run's message when it was creeping (else '')."""
    if len(history) <= CREEP_STEPS or not history[-1] > 0:
        return ""
    decrease = (history[-CREEP_STEPS - 1] - history[-1]) / history[-1]
    if decrease >= CREEP_DECREASE:
        return ""
    return (
        f" (the last {CREEP_STEPS} steps lowered the cost by {decrease:.1e} of itself: the fit "
        "may be moving along a direction the data do not determine, which "
        "sk_offwhite.certify.identifiability names)"
    )


def progress_line(verbose: int, iteration: int, cost: float, damping: float) -> str | None:
    """The line a ``verbose`` run prints after an accepted step (every 10th and the first,
    every one when ``verbose > 1``), or ``None``."""
    if verbose and (verbose > 1 or iteration % 10 == 0 or iteration == 1):
        return f"[sk_offwhite] iter {int(iteration):5d}  cost {float(cost):.6e}  ({damping:.2e})"
    return None
