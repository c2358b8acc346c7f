"""From validated data and user settings to a solved minimisation (the pure core of ``fit``).

Data flow: ``physics`` + ``basis`` -> `Model` (static
structure); records -> `Segments`; initial values, free masks
and bounds per block -> `Problem`; solver -> fitted blocks.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..effects import Switched
from ..effects._hidden import (
    hidden_bounds,
    hidden_start,
    input_determined,
    n_declared_states,
    sensor_readings,
    with_input_determined,
)
from ..model._physics import PhysicsModel, measured_states, reads_next_input
from ..runtime._backend import to_device
from ..simulation._layout import Layout
from ..simulation._objective import CostWeights
from ..simulation._rollout import Model, free_run_record, theta_dict
from ..simulation._segments import Segments, make_segments
from ..solvers._core import Problem, SolverResult
from ..solvers._device import PAD_TO, padded_size
from ..solvers._solver import resolve_solver
from ._sparsity import SparseOptions, fit_sparse, output_scale, state_scale
from ._start import continuation_start, within_reach
from ._verdict import judged, needs_restart, with_fit_term

__all__ = [
    "FitOutcome",
    "build_model",
    "initial_blocks",
    "solve",
]


def build_model(
    physics: PhysicsModel, basis, delta_states: tuple[int, ...], delta_outputs: tuple[int, ...] = ()
) -> Model:
    """Static model structure from the physics and the compiled dictionary (or ``None``),
    its rows correcting the state equations ``delta_states`` then the outputs
    ``delta_outputs``."""
    return Model(
        step=physics.step,
        output=physics.output,
        parameter_names=physics.parameter_names,
        delta_states=delta_states if basis is not None else (),
        delta_outputs=delta_outputs if basis is not None else (),
        basis=None if basis is None else basis.evaluate,
        inner_names=() if basis is None else tuple(basis.init_params),
        inequality=physics.inequality,
        equality=physics.equality,
        free_multiple=_board_multiple(physics),
        feature_states=None if basis is None else n_declared_states(physics),
        next_input=reads_next_input(physics),
    )


def _switched(physics: PhysicsModel) -> tuple[Switched, ...]:
    """The effects of ``physics`` behind switches (a switchboard's model: not empty)."""
    return tuple(e for e in getattr(physics, "effects", ()) if isinstance(e, Switched))


def _board_multiple(physics: PhysicsModel) -> int:
    """The multiple to which the solver pads the free vector of ``physics``
    (``Model.free_multiple``): 1 without switched effects; with them, its parameters other
    than the switches plus its states, rounded up to `PAD_TO`.

    A fit on the board frees at most that many variables on the whole record (every
    parameter and one initial state), so every switch setting pads to the same size and
    shares one compiled program per record layout; over shooting windows, with more
    initial states, the sizes are the next multiples. Padding each setting's own number of
    free variables to a multiple of `PAD_TO` instead would give settings of different
    sizes a program each."""
    board = _switched(physics)
    if not board:
        return 1
    n_variables = len(physics.parameter_names) - len(board) + physics.n_states
    return padded_size(n_variables, PAD_TO)


def _window_initial_states(model, blocks, records, segments, horizon):
    """Initial states of every segment of each record: a free run of the initial guess, or,
    where that run explodes (`within_reach`), the record's first
    state with the directly measured states set to the measurement at the window's start;
    the states the inputs determine (a dead time's past commands) where the record's
    inputs put them."""
    params = {k: jnp.asarray(v) for k, v in blocks.items() if k != "x0"}
    theta = theta_dict(model, blocks["theta"])
    x0 = []
    for r, (u, z) in enumerate(records):
        start = blocks["x0"][np.flatnonzero(segments.record == r)[0]]
        n_windows = int(np.sum(segments.record == r))
        if n_windows == 1:
            x0.append(start)
            continue
        states, outputs, _ = free_run_record(model, params, start, u)
        if within_reach(outputs, z):
            starts = states[::horizon][:n_windows]
        else:
            starts = [
                initial_state_guess(start, model, u_k, z_k, theta)
                for u_k, z_k in zip(u[::horizon], z[::horizon], strict=True)
            ]
        samples = np.arange(n_windows) * horizon
        x0.extend(with_input_determined(model.step, starts, u, theta, samples))
    return np.asarray(x0)


def initial_state_guess(base, model, u_first, z_first, theta: dict, fixed=None) -> np.ndarray:
    """``base`` with its non-fixed states set from a record's first sample: the directly
    measured ones to the first measurement ``z_first`` (when ``model.output`` is
    `MeasuredStates`) and the readings of slow sensors
    ([`SensorLag`][sk_offwhite.SensorLag]) to it too, the hidden ones where the first input
    ``u_first`` starts them (`hidden_start`, ``theta`` the
    parameters by name). ``model`` is a physics or a compiled model (its ``step`` and
    ``output``)."""
    guess = np.array(base, dtype=float)
    indices = measured_states(model.output)
    if indices is not None:
        measured = np.asarray(indices)
        free = np.ones(measured.shape, bool) if fixed is None else ~fixed[measured]
        guess[measured[free]] = np.asarray(z_first)[free]
    for output, state in sensor_readings(model.step):
        if fixed is None or not fixed[state]:
            guess[state] = np.asarray(z_first)[output]
    return hidden_start(model.step, guess, u_first, theta, fixed)


def _apply_warm(blocks: dict, guesses: list, warm: dict, fixed: np.ndarray) -> list:
    """Replace initial values by those of an earlier fit where the shapes agree.

    Fixed physical parameters keep their declared values; returns the initial states.
    """
    declared = blocks["theta"]
    for name, value in warm.items():
        if name in blocks and np.shape(value) == np.shape(blocks[name]):
            blocks[name] = np.array(value, dtype=float)
    blocks["theta"] = np.where(fixed, declared, blocks["theta"])
    starts = warm.get("starts")
    if starts is not None and len(starts) == len(guesses):
        return [np.asarray(s, float) for s in starts]
    return guesses


def _theta_by_name(warm: dict, names, declared) -> dict:
    """``warm`` whose ``theta``, given as ``{name: value}``, is a vector in the order of
    ``names`` (declared values for the names it lacks)."""
    theta = warm.get("theta")
    if not isinstance(theta, dict):
        return warm
    values = [theta.get(name, value) for name, value in zip(names, declared, strict=True)]
    return dict(warm, theta=np.asarray(values, float))


def initial_blocks(physics, basis, model, records, segments, horizon, warm=None) -> dict:
    """Initial value of every block: physics guesses, zero Ω, basis inner values.

    Each record starts from ``physics.x0`` with its measured states set to the record's
    first measurement and its hidden states where its first input starts them
    (`initial_state_guess`). ``warm`` (blocks of an earlier fit, its
    per-record initial states under ``"starts"``, its ``theta`` a vector or a mapping by
    parameter name) replaces these values where the shapes or names agree; fixed
    parameters keep their declared values.
    """
    blocks = {"theta": physics.parameter_values()}
    declared = theta_dict(physics, blocks["theta"])
    guesses = [
        initial_state_guess(physics.x0, physics, u[0], z[0], declared, physics.x0_fixed)
        for u, z in records
    ]
    if model.basis is not None:
        blocks["omega"] = np.zeros(basis.omega_trainable.shape)
        blocks.update({k: np.asarray(v, float) for k, v in basis.init_params.items()})
    if warm is not None:
        warm = _theta_by_name(warm, physics.parameter_names, blocks["theta"])
        fixed = np.array([p.fixed for p in physics.parameters.values()], dtype=bool)
        guesses = _apply_warm(blocks, guesses, warm, fixed)
    blocks["x0"] = np.stack([guesses[r] for r in segments.record])
    if horizon is not None:
        blocks["x0"] = _window_initial_states(model, blocks, records, segments, horizon)
    return blocks


def free_blocks(physics, basis, model, segments) -> dict:
    """Boolean mask per block: True where the entry is fitted."""
    fixed = np.array([p.fixed for p in physics.parameters.values()], dtype=bool)
    record_start = segments.linked == 0
    x0_free = np.ones(segments.u.shape[0:1] + (physics.n_states,), dtype=bool)
    x0_free[~record_start] = ~input_determined(physics.step, physics.n_states)
    x0_free[record_start] = ~physics.x0_fixed
    free = {"theta": ~fixed, "x0": x0_free}
    if model.basis is not None:
        free["omega"] = np.asarray(basis.omega_trainable, bool)
        free.update({k: np.asarray(v, bool) for k, v in basis.trainable.items()})
    return free


def bound_blocks(physics, blocks, records, segments) -> tuple[dict, dict]:
    """Lower and upper bound per block (physical parameters and initial states only): the
    declared ones, and those of the hidden states on each segment's record
    (`hidden_bounds`)."""
    lower = {k: np.full(np.shape(v), -np.inf) for k, v in blocks.items()}
    upper = {k: np.full(np.shape(v), np.inf) for k, v in blocks.items()}
    lower["theta"], upper["theta"] = physics.parameter_bounds()
    lower["x0"][:], upper["x0"][:] = physics.x0_bounds
    for r, (u, _) in enumerate(records):
        low, high = hidden_bounds(physics.step, u, physics.n_states)
        rows = np.asarray(segments.record) == r
        lower["x0"][rows] = np.maximum(lower["x0"][rows], low)
        upper["x0"][rows] = np.minimum(upper["x0"][rows], high)
    return lower, upper


def cost_weights(weights) -> CostWeights:
    """`CostWeights` of JAX arrays from a ``CostWeights`` or the five scalar weights
    ``(gamma, lam, nu, shooting, beta)`` (scales 1)."""
    return CostWeights(*(None if w is None else to_device(w, float) for w in weights))


def make_problem(layout, blocks, free, bounds, segments, weights) -> tuple[Problem, jax.Array]:
    """Assemble the dynamic `Problem` (every free variable active) and the initial
    free vector; ``weights`` as for `cost_weights`."""
    free_index = np.flatnonzero(layout.flatten(free))
    base = layout.flatten(blocks)
    lower, upper = (layout.flatten(b)[free_index] for b in bounds)
    omega_free = free.get("omega", np.zeros((0, 0)))
    problem = Problem(
        Segments(*(to_device(a, float) for a in segments)),
        to_device(base),
        to_device(free_index),
        to_device(lower),
        to_device(upper),
        to_device(omega_free, float),
        cost_weights(_penalty_scale_per_entry(weights, np.shape(omega_free))),
        to_device(np.ones(free_index.shape[0])),
    )
    return problem, to_device(np.clip(base[free_index], lower, upper))


def _penalty_scale_per_entry(weights, omega_shape) -> tuple:
    """``weights`` with a scalar ``penalty_scale`` of a model with a dictionary spread over
    $\\Omega$'s shape: the physics-only stage of `_sparsity` (unit
    scales) and the penalised stages (an array of $s_{ij}$) then pass arrays of one
    shape, and share one compiled program (the same values: multiplying by 1 is exact)."""
    if not np.prod(omega_shape):
        return weights
    weights = weights if isinstance(weights, CostWeights) else CostWeights(*weights)
    if np.ndim(weights.penalty_scale) > 0:
        return weights
    return weights._replace(penalty_scale=np.full(omega_shape, float(weights.penalty_scale)))


class SolverOptions(NamedTuple):
    """Solver settings passed through from the estimator."""

    solver: str
    optimizer: object
    max_iter: int
    tol: float
    verbose: int
    lm_scaling: str = "per-variable"


class FitOutcome(NamedTuple):
    r"""What `fit_records` returns: fitted blocks, solver result, segments and scales.

    ``penalty_scale`` (shape of $\Omega$, empty without a dictionary) and
    ``gamma_max`` are those of `_sparsity`; ``weights`` the
    `CostWeights` with the data's scales; ``reference`` the physics-only stage, to
    reuse (``None`` without a dictionary); ``evidence`` its
    `TermEvidence` in the shape of $\Omega$.
    """

    blocks: dict
    result: SolverResult
    segments: Segments
    weights: CostWeights
    penalty_scale: np.ndarray
    gamma_max: float
    reference: object
    evidence: object = None


def scaled_weights(weights, records, window_starts) -> CostWeights:
    """``weights`` (the five scalars) with the output and state scales of the data."""
    return CostWeights(
        *weights,
        output_scale=output_scale(records),
        state_scale=state_scale(window_starts),
    )


def fit_records(
    physics,
    basis,
    model,
    records,
    horizon,
    weights,
    options,
    warm=None,
    sparse=None,
    reference=None,
) -> FitOutcome:
    """Minimise the cost over all records: the pure core of ``fit`` (the arguments are
    those of `FitSettings` and `_fit_once`).

    A fit whose model is no model (`needs_restart`) runs once more
    from the physics-only continuation of `continuation_start`;
    a fit that ends with a hidden state's initial value where the first step forgets it
    runs once more from its solution with that value inside (`_hidden_starts_inside`).
    Each time the run with the lower fit term is kept.
    """
    settings = FitSettings(physics, basis, model, records, horizon, weights, options)
    outcome = _fit_once(settings, warm, sparse, reference)
    if needs_restart(outcome.result):
        start = continuation_start(_fit_once, settings)
        if start is not None:
            retry = _fit_once(settings, {**(warm or {}), **start}, sparse, None)
            outcome = _better(outcome, retry, "restarted from fits over short windows")
    starts = _hidden_starts_inside(settings, outcome)
    if starts is None:
        return outcome
    retry = _fit_once(settings, {**outcome.blocks, "starts": starts}, sparse, None)
    return _better(outcome, retry, "restarted with the hidden states inside their reach")


def _better(outcome: FitOutcome, retry: FitOutcome, why: str) -> FitOutcome:
    """``retry`` (its message prefixed by ``why``) if its fit term is lower, else
    ``outcome``."""
    if not retry.result.fit < np.nan_to_num(outcome.result.fit, nan=np.inf):
        return outcome
    return retry._replace(result=retry.result._replace(message=f"{why}; {retry.result.message}"))


def _hidden_starts_inside(settings: FitSettings, outcome: FitOutcome) -> list | None:
    """Each record's fitted initial state with its hidden states where the record's first
    input starts them (`hidden_start`), or ``None`` when that
    moves none. A start the first step forgets (a play's position beyond the play) has
    no gradient: a fit that pushed it there cannot bring it back, and a fit restarted
    from inside can find a lower cost."""
    physics = settings.physics
    starts = np.asarray(outcome.blocks["x0"])[np.asarray(outcome.segments.linked) == 0]
    theta = theta_dict(physics, outcome.blocks["theta"])
    moved = [
        hidden_start(physics.step, x0, u[0], theta, physics.x0_fixed)
        for x0, (u, _) in zip(starts, settings.records, strict=True)
    ]
    return None if all(map(np.array_equal, moved, starts)) else moved


class FitSettings(NamedTuple):
    """What one minimisation fits: the model, the records and the solver settings."""

    physics: PhysicsModel
    basis: object
    model: Model
    records: list
    horizon: int | None
    weights: tuple
    options: SolverOptions


def _fit_once(settings: FitSettings, warm=None, sparse=None, reference=None) -> FitOutcome:
    """One minimisation of the cost over all records, from the initial blocks.

    ``settings`` holds the arguments of `fit_records`: ``weights`` are the five
    scalars ``(gamma, lam, nu, shooting, beta)``; the output and state scales are taken
    from the data (`scaled_weights`). ``options`` is a `SolverOptions`.
    ``warm`` optional starting blocks (see `initial_blocks`); ``sparse`` the
    `SparseOptions` of a fit with a dictionary (the three
    stages of `_sparsity`); ``reference`` the
    `Reference` of an earlier fit of the same data and
    structure, which skips the physics-only stage.
    """
    physics, basis, model, records, horizon, weights, options = settings
    segments = make_segments(records, horizon)
    blocks = initial_blocks(physics, basis, model, records, segments, horizon, warm)
    free = free_blocks(physics, basis, model, segments)
    layout = Layout.from_arrays(blocks)
    cost = scaled_weights(weights, records, blocks["x0"])
    problem, free0 = make_problem(
        layout, blocks, free, bound_blocks(physics, blocks, records, segments), segments, cost
    )
    if free0.shape[0] == 0:
        raise ValueError("nothing to fit: every parameter and initial state is fixed.")

    def run(prob, start):
        return solve(model, layout, prob, start, **options._asdict())

    def verdict(result):
        return judged(with_fit_term(result, problem, model, layout), free0)

    if model.basis is None:
        result = verdict(run(problem, free0))
        blocks = fitted_blocks(layout, problem, result)
        return FitOutcome(blocks, result, segments, cost, np.zeros((0, 0)), np.nan, None)
    fit = fit_sparse(
        run, problem, free0, layout, model, sparse or SparseOptions(0.01, True), reference
    )
    blocks = fitted_blocks(layout, problem, fit.result)
    return FitOutcome(
        blocks,
        verdict(fit.result),
        segments,
        cost,
        fit.penalty_scale,
        fit.gamma_max,
        fit.reference,
        fit.evidence,
    )


def solve(model, layout, problem, free0, *, solver, optimizer, max_iter, tol, verbose,
          lm_scaling="per-variable"):  # fmt: skip
    """Run ``solver`` (a solver object or the name of one: `resolve_solver`) from ``free0``."""
    method = resolve_solver(
        solver, lm_scaling=lm_scaling, optimizer=optimizer, problem=problem,
        n_free=free0.shape[0],
    )  # fmt: skip
    return method.run(free0, problem, model, layout, max_iter=max_iter, tol=tol, verbose=verbose)


def fitted_blocks(layout, problem, result: SolverResult) -> dict:
    """Numpy blocks of the solution (fixed entries at their base value)."""
    full = np.asarray(problem.base).copy()
    full[np.asarray(problem.free_index)] = result.free
    return layout.unflatten(full)
