r"""Levenberg-Marquardt for multiple shooting with many windows: a coloured Jacobian and
sparse normal equations.

With a horizon $T$ over $N$ samples the free variables are $G$ global
ones (physical parameters, $\Omega$, inner parameters) and the initial state of every
window, $\lceil N/T \rceil n_x$ of them. A window's initial state touches only the
rows of its own window (fit and constraint residuals) and the continuity rows of the links
on either side, so the Jacobian is an arrow: $G$ dense columns and a block-banded
rest. Two windows two apart share no row, so the columns of state $i$ of all even
windows can be pushed as one tangent, and those of all odd windows as another:
$K = G + 2 n_x$ forward tangents give the whole Jacobian, however many windows
(Curtis-Powell-Reid column compression). The normal equations
$(J^TJ + \mu D)s = -J^Tr$ are then sparse (block tridiagonal with a dense border) and
are solved by a sparse LU. Memory and time per iteration grow linearly with $N$;
the dense formulation grows as $N^2$ and $N^3$.
"""

from __future__ import annotations

from functools import partial
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..simulation._objective import ResidualParts, residual_parts
from ._core import SolverResult, _omega, free_residuals, pushed_forward
from ._dense import _anchored, _penalised, majorised_cost
from ._host import lm_loop
from ._rules import damped_diagonal, held_at_bound

__all__ = ["Colouring", "colouring", "structured_levenberg_marquardt"]


class Colouring(NamedTuple):
    """Seeds of the compressed Jacobian and where its entries go.

    ``seeds`` (free x colours) are the tangents; the Jacobian entry at ``(rows[e],
    cols[e])`` is entry ``(rows[e], colours[e])`` of the compressed Jacobian. ``glob`` and
    ``local`` are the positions of the global variables and of the window starts in the
    free vector.
    """

    seeds: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    colours: np.ndarray
    n_rows: int
    glob: np.ndarray
    local: np.ndarray


def _x0_offset(layout) -> int:
    """Position of the ``x0`` block in the flat vector of all entries."""
    offset = 0
    for name, shape in layout.blocks:
        if name == "x0":
            return offset
        offset += int(np.prod(shape))
    raise ValueError("the layout has no x0 block")


def _free_roles(layout, free_index, n_segments, n_states):
    """Window of each free variable (-1 for a global one) and its colour."""
    local = np.asarray(free_index) - _x0_offset(layout)
    is_local = (local >= 0) & (local < n_segments * n_states)
    window = np.where(is_local, local // n_states, -1)
    n_global = int(np.sum(~is_local))
    colour = np.empty(local.shape[0], int)
    colour[~is_local] = np.arange(n_global)
    state = local[is_local] % n_states
    colour[is_local] = n_global + 2 * state + window[is_local] % 2
    return window, colour, n_global + 2 * n_states


def _segment_rows(offset: int, size: int, n_segments: int):
    """Rows of a segment-major part and the segment of each."""
    rows = offset + np.arange(size)
    return rows, np.arange(size) // max(size // n_segments, 1)


_SEGMENT_MAJOR = tuple(ResidualParts._fields.index(n) for n in ("fit", "inequality", "equality"))
_SHOOTING = ResidualParts._fields.index("shooting")


def _touching(part_sizes, n_segments, n_states):
    """``(row, window)`` pairs where the row depends on the window's initial state: the
    window's own fit and constraint rows, and the continuity rows of the links on either
    side (link ``k`` joins windows ``k`` and ``k + 1``)."""
    offsets = np.concatenate([[0], np.cumsum(part_sizes)])
    pairs = []
    for part in _SEGMENT_MAJOR:
        pairs.append(_segment_rows(offsets[part], part_sizes[part], n_segments))
    link_rows = offsets[_SHOOTING] + np.arange(part_sizes[_SHOOTING])
    link = np.arange(part_sizes[_SHOOTING]) // n_states
    pairs += [(link_rows, link), (link_rows, link + 1)]
    return np.concatenate([p[0] for p in pairs]), np.concatenate([p[1] for p in pairs])


def colouring(layout, free_index, segments, part_sizes) -> Colouring:
    """`Colouring` of the free variables for the residual parts of ``part_sizes``
    (the sizes of `ResidualParts`)."""
    n_segments, n_states = np.shape(segments.mask)[0], _n_states(layout)
    window, colour, n_colours = _free_roles(layout, free_index, n_segments, n_states)
    seeds = np.zeros((window.shape[0], n_colours))
    seeds[np.arange(window.shape[0]), colour] = 1.0
    n_rows = int(sum(part_sizes))
    glob = np.flatnonzero(window < 0)
    rows = [np.repeat(np.arange(n_rows), glob.shape[0])]
    cols = [np.tile(glob, n_rows)]
    touch_rows, touch_window = _touching(part_sizes, n_segments, n_states)
    by_window = _free_by_window(window, n_segments)
    for free_of_window in by_window.T:
        present = free_of_window[touch_window] >= 0
        rows.append(touch_rows[present])
        cols.append(free_of_window[touch_window][present])
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    local = np.flatnonzero(window >= 0)
    return Colouring(seeds, rows, cols, colour[cols], n_rows, glob, local)


def _n_states(layout) -> int:
    return dict(layout.blocks)["x0"][1]


def _free_by_window(window, n_segments):
    """``(n_segments, max per window)`` table of free-variable indices, -1 padded."""
    local = np.flatnonzero(window >= 0)
    counts = np.bincount(window[local], minlength=n_segments)
    table = -np.ones((n_segments, max(int(counts.max(initial=0)), 1)), int)
    slot = np.arange(local.shape[0]) - np.repeat(np.cumsum(counts) - counts, counts)
    table[window[local], slot] = local
    return table


class _State(NamedTuple):
    """Linearisation on the host: the normal matrix in blocks (globals ``g``, window starts
    ``l``) and the gradient $J^Tr$."""

    free: np.ndarray
    residual: np.ndarray
    normal_gg: np.ndarray
    normal_gl: np.ndarray
    normal_ll: sp.csc_matrix
    gradient: np.ndarray
    cost: float
    anchor: jax.Array
    diag: np.ndarray


@partial(jax.jit, static_argnames=("model", "layout"))
def _compressed(free, seeds, problem, *, model, layout):
    """Residual, compressed Jacobian (one column per colour), cost and L1 anchor."""
    anchor = _omega(free, problem, layout)
    anchored = _anchored(problem, anchor)
    fun = partial(free_residuals, problem=anchored, model=model, layout=layout)
    r, jac = pushed_forward(fun, free, seeds.T)
    return r, jac, _penalised(r, anchored), anchor


_cost = jax.jit(majorised_cost, static_argnums=(3, 4))


def _linearise(free, problem, model, layout, plan: Colouring) -> _State:
    """Host state at ``free``: residual, normal matrix $J^TJ$ in blocks, gradient."""
    r, compressed, cost, anchor = _compressed(
        jnp.asarray(free), jnp.asarray(plan.seeds), problem, model=model, layout=layout
    )
    r, compressed = np.asarray(r), np.asarray(compressed)
    values = compressed[plan.rows, plan.colours]
    shape = (plan.n_rows, plan.seeds.shape[0])
    jac = sp.csr_matrix((values, (plan.rows, plan.cols)), shape=shape)
    jac_g, jac_l = jac[:, plan.glob].toarray(), jac[:, plan.local].tocsc()
    diag = np.asarray(jac.multiply(jac).sum(axis=0)).ravel()
    return _State(
        np.asarray(free),
        r,
        jac_g.T @ jac_g,
        np.asarray((jac_l.T @ jac_g).T),
        (jac_l.T @ jac_l).tocsc(),
        jac.T @ r,
        float(cost),
        anchor,
        diag,
    )


def _damped_step(state: _State, damping: float, scale, plan: Colouring, moving) -> np.ndarray:
    r"""Solution of $(J^TJ + \mu D)s = -J^Tr$ (variables not ``moving`` stay; see
    `damped_diagonal`) by eliminating the window starts: their
    block is banded (one window couples only to its neighbours), its LU has no fill, and
    the globals solve the dense Schur complement."""
    keep_g, keep_l = moving[plan.glob].astype(float), moving[plan.local].astype(float)
    normal_gg = state.normal_gg * np.outer(keep_g, keep_g)
    normal_gl = state.normal_gl * np.outer(keep_g, keep_l)
    normal_ll = sp.diags(keep_l) @ state.normal_ll @ sp.diags(keep_l)
    diag = np.empty(state.free.shape[0])
    diag[plan.glob], diag[plan.local] = np.diag(normal_gg), normal_ll.diagonal()
    damped = damped_diagonal(diag, damping, moving, np, scale)
    a_gg = normal_gg + np.diag(damped[plan.glob])
    a_ll = (normal_ll + sp.diags(damped[plan.local])).tocsc()
    rhs = np.where(moving, -state.gradient, 0.0)
    lu = splu(a_ll, permc_spec="NATURAL")
    coupled, alone = lu.solve(np.ascontiguousarray(normal_gl.T)), lu.solve(rhs[plan.local])
    schur = a_gg - normal_gl @ coupled
    step_g = np.linalg.solve(schur, rhs[plan.glob] - normal_gl @ alone)
    step = np.empty(state.free.shape[0])
    step[plan.glob], step[plan.local] = step_g, alone - coupled @ step_g
    return step


def _solved_step(state: _State, damping, scale, plan: Colouring, moving) -> np.ndarray | None:
    """`_damped_step`, or ``None`` where the damped normal equations cannot be solved (a
    non-finite Jacobian, as a square root of a negative level gives, or an exactly singular
    factor): the trial is then rejected and Levenberg-Marquardt raises the damping."""
    if not (np.all(np.isfinite(state.gradient)) and np.all(np.isfinite(state.normal_gg))):
        return None
    try:
        step = _damped_step(state, damping, scale, plan, moving)
    except (RuntimeError, np.linalg.LinAlgError):  # splu: "Factor is exactly singular"
        return None
    return step if np.all(np.isfinite(step)) else None


def _trial(state: _State, damping, scale, problem, model, layout, plan: Colouring):
    """Damped step (``scale``: see `damped_diagonal`), projected
    on the box, and its cost (the state there is formed only if the step is accepted)."""
    lower, upper = np.asarray(problem.lower), np.asarray(problem.upper)
    moving = ~held_at_bound(state.free, state.gradient, lower, upper)
    step = _solved_step(state, damping, scale, plan, moving)
    if step is None:  # no step at this damping: rejected, so the damping grows
        return state.free, np.inf, None
    candidate = np.clip(state.free + step, lower, upper)
    cost = _cost(jnp.asarray(candidate), state.anchor, problem, model, layout)
    return candidate, float(cost), None


def structured_levenberg_marquardt(
    free0, problem, model, layout, *, max_iter: int, tol: float, verbose: int = 0,
    scaling: str = "per-variable",
) -> SolverResult:  # fmt: skip
    """Levenberg-Marquardt (`lm_loop`) with the coloured
    Jacobian and sparse normal equations (module docstring)."""
    parts = jax.eval_shape(
        lambda f: residual_parts(
            model,
            layout.unflatten(problem.base.at[problem.free_index].set(f)),
            problem.segments,
            problem.omega_free,
            problem.weights,
        ),
        free0,
    )
    sizes = [int(np.prod(part.shape)) for part in parts]
    plan = colouring(layout, np.asarray(problem.free_index), problem.segments, sizes)

    def linearise(free):
        return _linearise(free, problem, model, layout, plan)

    def trial(state, damping, scale):
        return _trial(state, damping, scale, problem, model, layout, plan)

    return lm_loop(
        linearise, trial, np.asarray(free0), problem, max_iter=max_iter, tol=tol, verbose=verbose,
        scaling=scaling,
    )  # fmt: skip
