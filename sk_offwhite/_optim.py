r"""Solvers for the multi-step cost: Levenberg-Marquardt and optax first-order loops.

Both work on the flat vector of free decision variables and project onto the box bounds
after every step. Each iteration is one jitted call, traced once per fit (the model and
the layout are static arguments, data and weights are dynamic), so the Python loop only
keeps the best finite iterate, the loss history and the stopping rules. A quiet
Levenberg-Marquardt fit runs the same iterations and rules inside one program
(`_lm_device`); the Python loop `lm_loop` drives ``verbose`` runs
and the coloured Jacobian of `_structured`.

Derivatives: Levenberg-Marquardt needs the residual Jacobian $J$ (``R x P``); it is
built in forward mode (``jacfwd``) when ``P <= R`` (few parameters, long records: the usual
grey-box case) and in reverse mode otherwise. The optax loop needs only the gradient of
$\|r\|^2$ and uses reverse mode. With many multiple-shooting windows the Jacobian is sparse;
`_structured` runs the same iteration (`lm_loop`) on a coloured
Jacobian and sparse normal equations.
"""

from __future__ import annotations

import warnings
from functools import lru_cache, partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from sklearn.exceptions import ConvergenceWarning

from ._backend import fused_loops
from ._layout import Layout
from ._objective import CostWeights, majoriser_constant, n_fit_residuals, residuals
from ._rollout import Model
from ._segments import Segments

__all__ = [
    "Problem",
    "SolverResult",
    "default_optimizer",
    "fit_cost",
    "forward_mode",
    "free_residuals",
    "jacobian_columns",
    "levenberg_marquardt",
    "linearised",
    "lm_loop",
    "majorised_cost",
    "n_residuals",
    "pushed_forward",
    "run_optax",
]


class Problem(NamedTuple):
    """Dynamic data of one minimisation (a pytree: every leaf is an array)."""

    segments: Segments
    base: jax.Array
    free_index: jax.Array
    lower: jax.Array
    upper: jax.Array
    omega_free: jax.Array
    weights: CostWeights
    active: jax.Array


class SolverResult(NamedTuple):
    """Outcome of a solver run: best finite iterate and its diagnostics.

    ``fit`` is the normalised fit term $F$ at ``free`` (``nan`` where the solver did
    not compute it separately from ``cost``).
    """

    free: np.ndarray
    cost: float
    history: np.ndarray
    n_iter: int
    converged: bool
    message: str
    fit: float = float("nan")


def free_residuals(free, problem: Problem, model: Model, layout: Layout):
    """Residual vector as a function of the free variables only.

    Entries where ``problem.active`` is 0 are frozen: they keep their value, and their
    derivatives (Jacobian columns, gradient entries) are exactly zero, so every solver leaves
    them where they are. Freezing is data, not structure: it does not re-trace.
    """
    free = jnp.where(problem.active > 0, free, jax.lax.stop_gradient(free))
    params = layout.unflatten(problem.base.at[problem.free_index].set(free, mode="drop"))
    return residuals(model, params, problem.segments, problem.omega_free, problem.weights)


@partial(jax.jit, static_argnames=("model", "layout", "n_fit"))
def fit_cost(free, problem: Problem, *, model: Model, layout: Layout, n_fit: int):
    r"""The fit term $F = \|r_{fit}\|^2$ alone (the first ``n_fit`` residuals)."""
    r = free_residuals(free, problem, model, layout)[:n_fit]
    return r @ r


@partial(jax.jit, static_argnames=("model", "layout"))
def jacobian_columns(free, problem: Problem, columns, *, model: Model, layout: Layout):
    """Residuals and the Jacobian columns of the free variables at ``columns`` (forward mode).

    One tangent per column (a ``vmap`` of ``jvp``), so the cost grows with the number of
    columns asked for, not with the number of free variables.
    """
    fun = partial(free_residuals, problem=problem, model=model, layout=layout)
    tangents = jax.nn.one_hot(columns, free.shape[0], dtype=free.dtype)
    residual = fun(free)
    return residual, jax.vmap(lambda t: jax.jvp(fun, (free,), (t,))[1], out_axes=-1)(tangents)


ROUNDING_COST = 1e-24
"""A (dimensionless) cost at which the simulation reproduces the data to rounding: an RMS
error of 1e-12 output standard deviations."""


class _LMState(NamedTuple):
    r"""Levenberg-Marquardt's state at ``free``: the residual, the normal equations
    ($J^TJ$, $J^Tr$), the penalised cost with the L1 term majorised at
    ``anchor`` ($\Omega$ at ``free``) and $\mathrm{diag}(J^TJ)$."""

    free: jax.Array
    residual: jax.Array
    jtj: jax.Array
    gradient: jax.Array
    cost: jax.Array
    anchor: jax.Array
    diag: jax.Array


def _anchored(problem: Problem, anchor) -> Problem:
    """``problem`` whose L1 term is majorised at ``anchor`` (see ``majorised_l1``)."""
    return problem._replace(weights=problem.weights._replace(l1_anchor=anchor))


LM_SCALE_FLOOR = 1e-9
r"""Marquardt's scaling $D = \mathrm{diag}(J^TJ)$ gets this fraction of a largest
entry added (`damped_diagonal`), so a variable the cost barely sees is not thrown by
a huge step."""

LM_SCALINGS = ("per-variable", "global")
"""The rules for the floor of Marquardt's scaling $D$ (`damped_diagonal`)."""


def checked_scaling(scaling: str) -> str:
    """``scaling`` if it is one of `LM_SCALINGS`, else a ``ValueError``."""
    if scaling not in LM_SCALINGS:
        raise ValueError(f"scaling must be one of {LM_SCALINGS}, got {scaling!r}.")
    return scaling


def _omega(free, problem: Problem, layout: Layout):
    r"""$\Omega$ at the free vector ``free`` (an empty array without a dictionary)."""
    params = layout.unflatten(problem.base.at[problem.free_index].set(free, mode="drop"))
    return params.get("omega", jnp.zeros(0))


LINEARIZE_MAX_FREE = 10
"""Up to this many free variables, and unless the loops are fused
([`enable_fused_loops`][sk_offwhite.enable_fused_loops]), the forward-mode Jacobian pushes the
tangents through one linearisation (``jax.linearize``); otherwise through ``jacfwd``
(`_through_linearisation`). Measured on the Cascaded Tanks cost, 1024 samples (jax
0.10.2, CPU, XLA's default loops), linearize against jacfwd: 5 free, 0.23 against 1.5 ms;
19 free, 0.61 against 0.42 ms; 25 free (with a 20-term dictionary), 7.0 against 5.5 ms.
Tangents one at a time (``lax.map`` of ``jvp``) were slower still (2.7 and 97 ms). With
fused loops ``jacfwd`` is the faster at every size measured (an accepted LM iteration,
physics only, 5 free: 0.197 against 0.254 ms at 1000 samples, 0.77 against 0.95 ms at
10 000; 11 free with a 6-term dictionary, 0.31 against 0.34 ms) and its program compiles
in less time (the first fit's first iteration 0.68 against 0.82 s)."""


def _through_linearisation(n_tangents: int) -> bool:
    """Whether the forward-mode Jacobian of ``n_tangents`` columns goes through
    ``jax.linearize`` rather than ``jacfwd`` (see `LINEARIZE_MAX_FREE`)."""
    return n_tangents <= LINEARIZE_MAX_FREE and not fused_loops()


def pushed_forward(fun, x, tangents):
    """``(fun(x), J t)`` for each row ``t`` of ``tangents`` (the columns of the result), in
    one pass: through ``jax.linearize`` or a ``vmap`` of ``jvp``, by
    `_through_linearisation`. The value comes with the tangents, unbatched: ``fun``
    is simulated once."""
    if _through_linearisation(tangents.shape[0]):
        value, linear = jax.linearize(fun, x)
        return value, jax.vmap(linear, out_axes=-1)(tangents)
    return jax.vmap(lambda t: jax.jvp(fun, (x,), (t,)), out_axes=(None, -1))(tangents)


def linearised(fun, x, forward: bool = True):
    """``(fun(x), Jacobian of fun at x)``: forward mode (`pushed_forward` of the
    identity) or reverse mode (``jacrev``, for problems wider than long). ``fun`` is traced
    once: its value comes out of the differentiation, not from a second call."""
    if forward:
        return pushed_forward(fun, x, jnp.eye(x.shape[0], dtype=x.dtype))

    def with_value(y):
        value = fun(y)
        return value, value

    jac, value = jax.jacrev(with_value, has_aux=True)(x)
    return value, jac


def _penalised(r, anchored: Problem):
    """The penalised cost from the residuals of ``anchored`` (L1 term majorised at its
    anchor): their squares and the majoriser's constant."""
    weights = anchored.weights
    return r @ r + majoriser_constant(weights.l1_anchor, anchored.omega_free, weights)


def _state_at(free, problem: Problem, model: Model, layout: Layout, forward: bool) -> _LMState:
    """LM state at ``free``, the L1 term majorised there."""
    anchor = _omega(free, problem, layout)
    anchored = _anchored(problem, anchor)
    fun = partial(free_residuals, problem=anchored, model=model, layout=layout)
    r, jac = linearised(fun, free, forward)
    cost = _penalised(r, anchored)
    return _LMState(free, r, jac.T @ jac, jac.T @ r, cost, anchor, jnp.sum(jac**2, axis=0))


def damped_candidate(free, jtj, gradient, damping, scale, lower, upper):
    r"""Damped Gauss-Newton step $(J^TJ + \mu D)\,s = -J^Tr$ from ``free``,
    projected on the box ``[lower, upper]``; ``scale`` is the per-variable floors'
    reference or ``None`` (see `damped_diagonal`).

    Variables held at a bound by the gradient (at the lower bound with $J^Tr > 0$,
    at the upper with $J^Tr < 0$) take no part in the step: the others solve the
    system without them. Clipping a step computed with them in would move the others as
    if the held variable had moved too; measured on the tanks with a dictionary, such runs
    alternated accepted and rejected steps until ``max_iter``."""
    moving = ~held_at_bound(free, gradient, lower, upper)
    jtj = jnp.where(jnp.outer(moving, moving), jtj, 0.0)
    system = jtj + jnp.diag(damped_diagonal(jnp.diag(jtj), damping, moving, jnp, scale))
    step = jnp.linalg.solve(system, jnp.where(moving, -gradient, 0.0))
    return jnp.clip(free + step, lower, upper)


def _majorised_at(free, anchor, problem: Problem, model: Model, layout: Layout):
    """Residuals and penalised cost at ``free`` with the L1 term majorised at ``anchor``:
    one forward simulation, no derivative."""
    anchored = _anchored(problem, anchor)
    r = free_residuals(free, anchored, model, layout)
    return r, _penalised(r, anchored)


def _unreached(candidate, residual, cost, anchor) -> _LMState:
    """What `_lm_advance` returns for a rejected candidate: its residual and cost at
    the old anchor, no normal equations (the iteration reads neither)."""
    n, dtype = candidate.shape[0], candidate.dtype
    zeros = jnp.zeros(n, dtype)
    return _LMState(candidate, residual, jnp.zeros((n, n), dtype), zeros, cost, anchor, zeros)


@partial(jax.jit, static_argnames=("model", "layout", "forward"))
def _lm_advance(origin, damping, scale, step, problem, *, model, layout, forward):
    """One Levenberg-Marquardt iteration in one program. ``origin`` is ``(free, jtj,
    gradient, anchor, cost)`` of the current state (`_origin`). Returns the LM state
    at the damped step's candidate (`damped_candidate`; with ``step`` false there is
    no step and it is the state at ``free``), the candidate's cost with the L1 term
    majorised at ``anchor`` (below the current cost, the penalised cost has decreased: the
    majoriser is tight at its anchor) and whether the candidate was accepted; the state of
    a rejected one holds placeholders.

    The candidate is simulated first; its Jacobian is formed (in a ``lax.cond`` branch)
    only when its cost is finite and below the current one. A rejected candidate costs one
    forward simulation. The closed loop on the Cascaded Tanks rejects 41 % of its
    candidates (7,853 of 19,098; some leave the region where the simulation stays finite),
    and with a 10-term dictionary an accepted iteration costs 4 (1000 samples) to 11
    (10 000) rejected ones. One program per model and layout holds the step, the
    simulation and the linearisation; the simulation makes it longer to compile."""
    free, jtj, gradient, anchor, cost = origin
    stepped = damped_candidate(free, jtj, gradient, damping, scale, problem.lower, problem.upper)
    candidate = jnp.where(step, stepped, free)
    residual, trial_cost = _majorised_at(candidate, anchor, problem, model, layout)
    accepted = jnp.logical_not(step) | (jnp.isfinite(trial_cost) & (trial_cost < cost))
    new = jax.lax.cond(
        accepted,
        lambda: _state_at(candidate, problem, model, layout, forward),
        lambda: _unreached(candidate, residual, trial_cost, anchor),
    )
    return new, trial_cost, accepted


def held_at_bound(free, gradient, lower, upper):
    """Which variables sit on a bound that the descent direction $-\\nabla$ points out
    of (numpy or JAX arrays)."""
    return ((free <= lower) & (gradient > 0)) | ((free >= upper) & (gradient < 0))


def damped_diagonal(diag, damping, moving, xp, scale=None):
    r"""Marquardt's damping $\mu D$, $D = \mathrm{diag}(J^TJ) + \epsilon\,f$
    (`LM_SCALE_FLOOR`), with 1 on the rows of variables that are not ``moving``
    (their rows and columns of $J^TJ$ are zero, so their step is zero) or that no
    residual has depended on yet; ``xp`` is ``numpy`` or ``jax.numpy``. The floor keeps a
    variable the cost barely sees from being thrown by a huge step.

    ``scale=None`` (``lm_scaling='global'``): $f = \max_j (J^TJ)_{jj}$, one floor
    for all variables (``diag`` is that of the moving ones), so the steps depend on their
    units: a variable in units $10^3$ times smaller has a column $10^3$ times
    larger and raises everyone else's damping.

    ``scale`` given (``lm_scaling='per-variable'``): $f_i$ = ``scale``$_i$,
    the largest $(J^TJ)_{ii}$ variable $i$ has had so far in the run
    (`lm_loop`). $D_i$ then carries the units of $1/x_i^2$ alone, so
    rescaling a variable (a state in other units, a dictionary column times a constant)
    leaves the iterates the same up to rounding."""
    if scale is None:
        floor = LM_SCALE_FLOOR * xp.maximum(xp.max(diag), 1e-30)
        return xp.where(moving, damping * (diag + floor), 1.0)
    damped = damping * (diag + LM_SCALE_FLOOR * scale)
    return xp.where(moving & (scale > 0), damped, 1.0)


def majorised_cost(free, anchor, problem, model, layout):
    """Penalised cost at ``free`` with the L1 term majorised at ``anchor``."""
    return _majorised_at(free, anchor, problem, model, layout)[1]


def levenberg_marquardt(
    free0,
    problem: Problem,
    model: Model,
    layout: Layout,
    *,
    max_iter: int,
    tol: float,
    verbose: int = 0,
    scaling: str = "per-variable",
) -> SolverResult:
    r"""Projected Levenberg-Marquardt on $\|r(\cdot)\|^2$ with the dense Jacobian
    (see `lm_loop` for the steps and stopping rules)."""
    forward = forward_mode(free0, problem, model, layout)
    static = dict(model=model, layout=layout, forward=forward)

    def linearise(free):
        return first_state(free, problem, scaling=scaling, **static)

    def trial(state, damping, scale):  # a NumPy ``scale`` goes in as it is: no conversion
        new, cost, accepted = _lm_advance(_origin(state), damping, scale, True, problem, **static)
        cost, accepted = jax.device_get((cost, accepted))  # one transfer for both
        return new.free, float(cost), new if accepted else None

    return lm_loop(
        linearise, trial, free0, problem, max_iter=max_iter, tol=tol, verbose=verbose,
        scaling=scaling,
    )  # fmt: skip


def _origin(state: _LMState) -> tuple:
    """What `_lm_advance` steps from: ``(free, jtj, gradient, anchor, cost)``."""
    return state.free, state.jtj, state.gradient, state.anchor, state.cost


def first_state(free, problem: Problem, *, model, layout, forward, scaling) -> _LMState:
    r"""The LM state at ``free``: `_lm_advance` without a step, so that the run's
    first state and its iterations share one program. Its origin's normal equations and
    anchor (zeros of $\Omega$'s shape) are never read; ``scale`` is passed as the
    iterations pass it (an array with per-variable scaling, ``None`` with global)."""
    n = free.shape[0]
    omega_shape = dict(layout.blocks).get("omega", (0,))
    origin = (free, np.zeros((n, n)), np.zeros(n), np.zeros(omega_shape), np.array(np.inf))
    scale = np.ones(n) if scaling == "per-variable" else None
    static = dict(model=model, layout=layout, forward=forward)
    return _lm_advance(origin, 1.0, scale, False, problem, **static)[0]


_residuals_program = jax.jit(free_residuals, static_argnames=("model", "layout"))
"""`free_residuals` jitted, only for its shape: ``eval_shape`` traces it once per
model, layout and array shapes and keeps the trace with the package's other programs."""


def forward_mode(free, problem: Problem, model: Model, layout: Layout) -> bool:
    """Whether the Jacobian is formed in forward mode: no more free variables than
    residuals. The fit residuals alone (the leading `n_fit_residuals`) settle it
    without a trace in the usual case of a record longer than the free vector."""
    if free.shape[0] <= n_fit_residuals(problem.segments):
        return True
    return free.shape[0] <= n_residuals(free, problem, model, layout)


def n_residuals(free, problem: Problem, model: Model, layout: Layout) -> int:
    """Length of `free_residuals` at ``free`` (traced once per structure and
    shapes: the closed loop runs many fits of each)."""
    return int(_residuals_program.eval_shape(free, problem, model=model, layout=layout).shape[0])


START_DAMPING, DAMPING_DOWN, DAMPING_UP, MAX_DAMPING = 1e-3, 3.0, 4.0, 1e10
"""Marquardt's damping: its start, its divisor after an accepted step and its factor after
a rejected one, and the value past which no descent step is left (`lm_loop`, and
the initial-state solver of `sk_offwhite._initial`)."""


def lm_loop(
    linearise, trial, free0, problem, *, max_iter, tol, verbose=0, scaling="per-variable"
) -> SolverResult:
    r"""The Levenberg-Marquardt iteration over a linearisation and a trial step.

    ``linearise(free)`` returns a state with ``free``, ``residual``, ``cost`` and ``diag``
    ($\mathrm{diag}(J^TJ)$) at ``free``; ``trial(state, damping, scale)`` the
    damped, projected candidate, its cost and the state there when the trial formed it
    (``None``: ``linearise`` forms it if the step is accepted), where ``scale`` is ``None``
    with ``scaling='global'`` and the elementwise largest ``diag`` of the run so far with
    ``scaling='per-variable'`` (`damped_diagonal`).

    Stops when a nearly undamped (Gauss-Newton, damping below ``1``) accepted step lowers
    the cost by less than ``tol`` (relative), when the cost reaches `ROUNDING_COST`
    (the cost is dimensionless), or when the damping grows past `MAX_DAMPING` (no
    descent step exists: a stationary point up to numerical precision). A small decrease
    under heavy damping only means the step was short, not that the fit has converged.
    """
    state = linearise(free0)
    scale = np.asarray(state.diag) if checked_scaling(scaling) == "per-variable" else None
    damping = START_DAMPING
    history, message, converged = [float(state.cost)], "max_iter reached", False
    for iteration in range(1, max_iter + 1):
        previous = history[-1]
        candidate, trial_cost, reached = trial(state, damping, scale)
        if np.isfinite(trial_cost) and trial_cost < previous:
            state = linearise(candidate) if reached is None else reached
            scale = None if scale is None else np.maximum(scale, np.asarray(state.diag))
            history.append(float(state.cost))
            _report(verbose, iteration, history[-1], damping)
            small = previous - history[-1] <= tol * max(previous, 1e-300)
            if small and damping < 1.0:
                converged, message = True, "relative cost decrease below tol"
                break
            damping /= DAMPING_DOWN
            if history[-1] <= ROUNDING_COST:
                converged, message = True, "cost at rounding level (the data are reproduced)"
                break
        else:
            damping *= DAMPING_UP
            if damping > MAX_DAMPING:
                converged, message = True, "no descent step left (stationary point)"
                break
    if not converged:
        message += _creep(history)
    fit_part = np.asarray(state.residual)[: n_fit_residuals(problem.segments)]
    with np.errstate(over="ignore"):
        fit = float(fit_part @ fit_part)
    return SolverResult(
        np.asarray(state.free), history[-1], np.asarray(history), iteration, converged, message, fit
    )


CREEP_STEPS, CREEP_DECREASE = 20, 1e-4
"""A run stopped by ``max_iter`` whose last ``CREEP_STEPS`` accepted steps lowered the cost
by less than ``CREEP_DECREASE`` of itself was creeping, as along a direction the data do not
determine (measured on the tanks with ``k4`` free: 2e-6 per step for 190 steps; with ``k4``
fixed the same fit converges in 13 iterations)."""


def _creep(history) -> str:
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


def _report(verbose: int, iteration: int, cost: float, extra: float) -> None:
    if verbose and (verbose > 1 or iteration % 10 == 0 or iteration == 1):
        print(f"[sk_offwhite] iter {iteration:5d}  cost {cost:.6e}  ({extra:.2e})")


@lru_cache(maxsize=8)
def default_optimizer(max_iter: int):
    """The optax loop's optimizer when none is given: Adam, its step cosine-decayed from
    1e-2 to 1e-4 over ``max_iter`` iterations, behind clipping of the gradient's global
    norm to 1. The same object for the same ``max_iter`` (a ``jit`` static argument: fits
    reuse the compiled iteration). optax is imported here, on the first fit that uses it."""
    import optax

    schedule = optax.cosine_decay_schedule(1e-2, decay_steps=max_iter, alpha=0.01)
    return optax.chain(optax.clip_by_global_norm(1.0), optax.adam(schedule))


@partial(jax.jit, static_argnames=("model", "layout", "optimizer"))
def _optax_iteration(free, opt_state, problem, *, model, layout, optimizer):
    import optax

    def cost(f):
        r = free_residuals(f, problem, model, layout)
        return r @ r

    value, grad = jax.value_and_grad(cost)(free)
    updates, opt_state = optimizer.update(grad, opt_state, free)
    new = jnp.clip(optax.apply_updates(free, updates), problem.lower, problem.upper)
    return new, opt_state, value


def run_optax(
    free0,
    problem: Problem,
    model: Model,
    layout: Layout,
    optimizer,
    *,
    max_iter: int,
    tol: float,
    patience: int = 100,
    verbose: int = 0,
) -> SolverResult:
    """First-order loop with any optax transformation (``None``: `default_optimizer`),
    keeping the best finite iterate.

    Stops after ``patience`` iterations without a relative improvement of ``tol`` of the
    best cost. A non-finite cost ends the loop: the best finite iterate is returned and a
    `ConvergenceWarning` says so.
    """
    optimizer = default_optimizer(max_iter) if optimizer is None else optimizer
    static = dict(model=model, layout=layout, optimizer=optimizer)
    free, opt_state = free0, optimizer.init(free0)
    best_free, best_cost, since_best, history = np.asarray(free0), np.inf, 0, []
    converged, message = False, "max_iter reached"
    for iteration in range(1, max_iter + 1):
        candidate, opt_state, value = _optax_iteration(free, opt_state, problem, **static)
        value = float(value)
        if not np.isfinite(value):
            message = f"non-finite cost at iteration {iteration}; kept the best finite iterate"
            warnings.warn(f"The fit diverged: {message}.", ConvergenceWarning, stacklevel=3)
            break
        history.append(value)
        _report(verbose, iteration, value, best_cost)
        if value < best_cost * (1.0 - tol):
            since_best = 0
        else:
            since_best += 1
        if value < best_cost:
            best_free, best_cost = np.asarray(free), value
        if since_best >= patience:
            converged, message = True, f"no relative improvement of tol in {patience} iterations"
            break
        free = candidate
    return SolverResult(best_free, best_cost, np.asarray(history), iteration, converged, message)
