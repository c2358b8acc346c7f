r"""Delay embedding: the regressors of a discrete-time model of the *measured* outputs.

When only some states are measured, a black-box map cannot use the state; it uses the
recent past of what is measured instead. At time $k$ the regressor vector is

$$
w_k = \bigl[z_k, \dots, z_{k-n_z+1},\;
      \sqrt{z_k^+}, \dots, \sqrt{z_{k-n_z+1}^+},\;
      u_k, \dots, u_{k-n_u+1}\bigr],
\qquad z^+ = \max(z, 0),
$$

(the square roots only when requested: the physics-informed variant for outflows that
follow Torricelli's law) and the model predicts $z_{k+1}$ from $w_k$. The same
function builds the regressors for fitting (every row of a record) and for simulation (one
row from the simulated history), so both use exactly the same variables.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Embedding", "embed_record", "history_length", "regressor_row", "variable_names"]


class Embedding(NamedTuple):
    r"""Shape of the delay embedding.

    Attributes
    ----------
    n_output_lags : int
        $n_z \ge 1$, past outputs in the regressor (the current one included).
    n_input_lags : int
        $n_u \ge 0$, past inputs in the regressor (the current one included).
    sqrt_outputs : bool
        Append $\sqrt{\max(z, 0)}$ of every output lag.
    """

    n_output_lags: int
    n_input_lags: int
    sqrt_outputs: bool


def history_length(embedding: Embedding) -> int:
    """Number of leading samples needed before the first prediction can be made."""
    return max(embedding.n_output_lags, embedding.n_input_lags, 1)


def _lags(a: np.ndarray, n_lags: int, start: int, stop: int) -> np.ndarray:
    """Rows ``k = start .. stop-1`` of ``[a_k, a_{k-1}, ..., a_{k-n_lags+1}]``."""
    return np.hstack([a[start - j : stop - j] for j in range(n_lags)]).reshape(stop - start, -1)


def _assemble(z_lags: np.ndarray, u_lags: np.ndarray, sqrt_outputs: bool) -> np.ndarray:
    parts = [z_lags, np.sqrt(np.maximum(z_lags, 0.0))] if sqrt_outputs else [z_lags]
    return np.hstack([*parts, u_lags])


def embed_record(u: np.ndarray, z: np.ndarray, embedding: Embedding):
    """Regressors ``w_k`` and targets ``z_{k+1}`` of one contiguous record.

    Parameters
    ----------
    u : ndarray of shape (n_samples, n_inputs)
    z : ndarray of shape (n_samples, n_outputs)
    embedding : Embedding

    Returns
    -------
    regressors : ndarray of shape (n_rows, n_variables)
    targets : ndarray of shape (n_rows, n_outputs)
        With ``n_rows = n_samples - history_length(embedding)``.
    """
    start, stop = history_length(embedding) - 1, z.shape[0] - 1
    z_lags = _lags(z, embedding.n_output_lags, start, stop)
    u_lags = _lags(u, embedding.n_input_lags, start, stop)
    return _assemble(z_lags, u_lags, embedding.sqrt_outputs), z[start + 1 :]


def regressor_row(u: np.ndarray, z: np.ndarray, k: int, embedding: Embedding) -> np.ndarray:
    """The regressor ``w_k`` of a single time step (``z`` holds the simulated history)."""
    z_lags = z[k - np.arange(embedding.n_output_lags)].reshape(1, -1)
    u_lags = u[k - np.arange(embedding.n_input_lags)].reshape(1, -1)
    return _assemble(z_lags, u_lags, embedding.sqrt_outputs)[0]


def variable_names(
    output_names: list[str], input_names: list[str], embedding: Embedding
) -> list[str]:
    """Names of the regressor variables, in the order of
    [`embed_record`][sk_offwhite.baselines.embed_record]."""
    z_names = [f"{n}[k-{j}]" if j else f"{n}[k]" for j in range(embedding.n_output_lags)
               for n in output_names]  # fmt: skip
    u_names = [f"{n}[k-{j}]" if j else f"{n}[k]" for j in range(embedding.n_input_lags)
               for n in input_names]  # fmt: skip
    roots = [f"sqrt({n})" for n in z_names] if embedding.sqrt_outputs else []
    return z_names + roots + u_names
