r"""Scan many, fit few: candidates ranked by the gain of one Gauss-Newton step.

At the declared fit, a candidate effect switched on at its start gives the simulated outputs
$\hat z(p)$ over the free variables $p$ (the declared parameters, the effect's own and the
initial states), with residual $r = (\hat z - z)/\sigma$ in output standard deviations
($\sigma$ per output: the score is unit-free) and Jacobian $J = \partial r / \partial p$.
One Gauss-Newton step from there leaves

$$
e_{\mathrm{GN}} = \sqrt{\tfrac{1}{N n_z}\,\min_{\Delta p} \lVert r - J\,\Delta p \rVert^2},
$$

the candidate's *scan score*: the error a first step of its fit would reach, were the model
linear in $p$. It costs one simulation and its forward derivatives, where a fit costs tens of
them; the candidates that share a switchboard share one compiled program for it.

The scan ranks; it does not decide. The `fit_top` best scanned candidates are fitted
(`sk_offwhite.loop._selection.rank_alone`) with every law read from δ and every candidate
the scan cannot judge: one with memory of its own or a relaxed law, on a model of its own,
one whose start does not simulate, and one that acts beyond a level a hypothesis located
(an overflow where the correction says the state loses above a level: one linear step from
the level's start cannot tell how far moving the level would take the fit). The loop's
note says how many were scanned and how many fitted.
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np

from ..fitting._problem import build_model
from ..fitting._sparsity import output_scale
from ..simulation._rollout import simulate
from ._switchboard import Switchboard
from ._variants import mechanism

__all__ = ["scan_note", "scan_scores", "scanned_pairs", "to_fit"]

RCOND = 1e-10
"""Relative singular value below which a direction of $J$ (columns scaled to unit norm)
counts as absent from the Gauss-Newton step."""


@partial(jax.jit, static_argnums=0)
def _outputs_and_jacobians(model, theta, x0, u):
    """Simulated outputs and their forward derivatives by ``theta`` and ``x0``."""

    def outputs(theta, x0):
        return simulate(model, {"theta": theta}, x0, u)[1]

    return outputs(theta, x0), *jax.jacfwd(outputs, argnums=(0, 1))(theta, x0)


def step_error(residual: np.ndarray, jacobian: np.ndarray) -> float:
    r"""$\sqrt{\min_{\Delta p}\lVert r - J\Delta p\rVert^2 / n}$ for ``residual`` of ``n``
    entries, with the columns of ``jacobian`` scaled to unit norm (zero columns dropped)."""
    norms = np.linalg.norm(jacobian, axis=0)
    columns = jacobian[:, norms > 0] / norms[norms > 0]
    if columns.shape[1] == 0:
        return float(np.sqrt(np.mean(residual**2)))
    step = np.linalg.lstsq(columns, residual, rcond=RCOND)[0]
    return float(np.sqrt(np.mean((residual - columns @ step) ** 2)))


def candidate_score(model_physics, u: np.ndarray, z: np.ndarray) -> float:
    """The scan score of ``model_physics`` (a switchboard's model with one effect on) on the
    record; ``nan`` where its start does not simulate to finite outputs."""
    model = build_model(model_physics, None, ())
    free = ~np.array([p.fixed for p in model_physics.parameters.values()], bool)
    free_states = ~np.broadcast_to(
        np.asarray(model_physics.x0_fixed, bool), (model_physics.n_states,)
    )
    with jax.enable_x64(True):
        outputs, by_theta, by_x0 = _outputs_and_jacobians(
            model,
            jnp.asarray(model_physics.parameter_values(), jnp.float64),
            jnp.asarray(model_physics.x0, jnp.float64),
            jnp.asarray(u, jnp.float64),
        )
    scale = output_scale([(None, z)])
    outputs = np.asarray(outputs).reshape(z.shape)
    jacobian = np.concatenate(
        [np.asarray(by_theta)[..., free], np.asarray(by_x0)[..., free_states]], axis=-1
    )
    jacobian = (jacobian / scale[None, :, None]).reshape(z.size, -1)
    residual = ((outputs - z) / scale).reshape(-1)
    if not (np.all(np.isfinite(residual)) and np.all(np.isfinite(jacobian))):
        return np.nan
    return step_error(residual, jacobian)


def scan_scores(search, models, candidates) -> list[float]:
    """The scan score of each candidate on a `Switchboard` in ``models`` (its model for
    the single fit), ``nan`` for the others and where the scan fails."""
    scores = []
    for model, candidate in zip(models, candidates, strict=True):
        if not isinstance(model, Switchboard):
            scores.append(np.nan)
            continue
        try:
            physics = model.model((candidate.effect,), {})
            scores.append(candidate_score(physics, search.u, search.z))
        except (ValueError, TypeError, FloatingPointError, np.linalg.LinAlgError):
            scores.append(np.nan)
    return scores


def to_fit(scores, fit_top: int | None) -> list[bool]:
    """Which candidates are fitted: the ``fit_top`` best scores and every ``nan`` one
    (all of them when ``fit_top`` is ``None``)."""
    scores = np.asarray(scores, float)
    if fit_top is None:
        return [True] * scores.size
    judged = np.flatnonzero(np.isfinite(scores))
    best = set(judged[np.argsort(scores[judged], kind="stable")][:fit_top].tolist())
    return [bool(not np.isfinite(s) or k in best) for k, s in enumerate(scores)]


def scan_note(candidates, scores, fitted) -> str:
    """The report's line: how many candidates were scanned and fitted, and which were not."""
    scanned = int(np.sum(np.isfinite(np.asarray(scores, float))))
    skipped = [
        f"{c.effect.name} ({s:.3g})"
        for c, s, f in zip(candidates, scores, fitted, strict=True)
        if not f
    ]
    line = (
        f"Candidates: {len(candidates)} proposed, {scanned} scanned by the error one "
        f"Gauss-Newton step would reach (in output standard deviations), {sum(fitted)} fitted"
    )
    return line + (f"; not fitted: {', '.join(skipped)}." if skipped else ".")


def scanned_pairs(search, models, candidates, scores, n_pairs: int) -> list[tuple]:
    """The ``n_pairs`` pairs of candidates on one `Switchboard` that one Gauss-Newton step
    takes furthest below what their better member reaches alone, by ``(i, j, score)``:
    effects that only help together (a Coulomb friction and a force offset, each of which
    the declared parameters partly absorb). A pair qualifies where its score is below
    ``1 - min_gain`` times its better member's."""
    bar = 1.0 - search.settings.min_gain
    pairs = []
    for i, j in _board_pairs(models, candidates, scores):
        physics = models[i].model((candidates[i].effect, candidates[j].effect), {})
        try:
            score = candidate_score(physics, search.u, search.z)
        except (ValueError, TypeError, FloatingPointError, np.linalg.LinAlgError):
            continue
        if np.isfinite(score) and score < bar * min(scores[i], scores[j]):
            pairs.append((i, j, score))
    return sorted(pairs, key=lambda pair: pair[2])[:n_pairs]


def _board_pairs(models, candidates, scores):
    """Index pairs of scanned candidates on one board, of different mechanisms."""
    scanned = [k for k, s in enumerate(scores) if np.isfinite(s)]
    for a, i in enumerate(scanned):
        for j in scanned[a + 1 :]:
            same_board = models[i] is models[j]
            kinds = mechanism(candidates[i].effect), mechanism(candidates[j].effect)
            if same_board and kinds[0] != kinds[1]:
                yield i, j
