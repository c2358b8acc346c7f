r"""Free-run simulation of a fitted delay-embedding model, with a divergence guard.

The model feeds back its own predictions: $\hat z_{k+1} = \Xi\,\varphi(\hat w_k)$,
where $\hat w_k$ holds *simulated* outputs (measured ones only for the initial
history). Black-box maps fitted on one-step errors often are unstable in free run. Every
simulated value is therefore kept inside the box ``[lo, hi]`` (the fitting records' output
range widened on each side by ``clip_margin`` times its span); a run that reaches the box
or produces a non-finite value is flagged as diverged instead of overflowing.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ._embedding import Embedding, history_length, regressor_row

__all__ = ["FreeRun", "monomials", "output_box", "simulate_free_run"]


class FreeRun(NamedTuple):
    """Result of [`simulate_free_run`][sk_offwhite.baselines.simulate_free_run].

    Attributes
    ----------
    outputs : ndarray of shape (n_samples, n_outputs)
        Simulated outputs (the given history first), clipped to the box.
    diverged : bool
        The run left the box or produced a non-finite value.
    first_divergence : int
        Index of the first sample outside the box (``-1`` if none).
    """

    outputs: np.ndarray
    diverged: bool
    first_divergence: int


def monomials(w: np.ndarray, powers: np.ndarray) -> np.ndarray:
    r"""Polynomial features $\prod_v w_v^{p_{jv}}$ of one row or many rows.

    ``powers`` is a pysindy ``PolynomialLibrary``'s ``powers_`` (one row per feature), so
    the result equals ``library.transform(w)`` without pysindy's per-call overhead.
    """
    return np.prod(np.asarray(w)[..., None, :] ** powers, axis=-1)


def output_box(z: np.ndarray, clip_margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-output bounds ``[min - m * span, max + m * span]`` of the measured outputs."""
    lo, hi = np.min(z, axis=0), np.max(z, axis=0)
    span = np.maximum(hi - lo, 1e-12)
    return lo - clip_margin * span, hi + clip_margin * span


def _step(u, z, k, embedding, coef, powers) -> np.ndarray:
    return coef @ monomials(regressor_row(u, z, k, embedding), powers)


def simulate_free_run(
    u: np.ndarray,
    history: np.ndarray,
    embedding: Embedding,
    coef: np.ndarray,
    powers: np.ndarray,
    box: tuple[np.ndarray, np.ndarray],
) -> FreeRun:
    """Simulate ``len(u)`` samples, the first ``len(history)`` taken from ``history``.

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs)
    history : ndarray of shape (n_history, n_outputs)
        Known outputs at the start; at least ``history_length(embedding)`` rows.
    embedding : Embedding
    coef : ndarray of shape (n_outputs, n_features)
    powers : ndarray of shape (n_features, n_variables)
    box : (lo, hi)
        Bounds from [`output_box`][sk_offwhite.baselines.output_box].

    Returns
    -------
    FreeRun
    """
    n, start = u.shape[0], min(history.shape[0], u.shape[0])
    z = np.empty((n, history.shape[1]))
    z[:start] = history[:start]
    first = -1
    for k in range(max(start, history_length(embedding)) - 1, n - 1):
        raw = _step(u, z, k, embedding, coef, powers)
        z[k + 1] = np.clip(np.nan_to_num(raw, nan=np.inf), *box)
        if first < 0 and not np.all((raw > box[0]) & (raw < box[1])):
            first = k + 1
    return FreeRun(z, first >= 0, first)
