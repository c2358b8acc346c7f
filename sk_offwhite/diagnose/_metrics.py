r"""Simulation error metrics: how far a model's free-run simulation is from the measurement.

With the error $e_k = z_k - \hat z_k$ over the ``n`` scored samples
$k = \text{skip}, \dots, N-1$ and $\bar z$ the mean measurement there, each
output gets

$$
\text{rmse} = \sqrt{\tfrac1n \textstyle\sum_k e_k^2}, \qquad
\text{nrmse} = \text{rmse} / \operatorname{std}(z), \qquad
\text{fit} = 100 \left(1 - \frac{\lVert e \rVert}{\lVert z - \bar z \rVert}\right),
$$

$$
R^2 = 1 - \frac{\sum_k e_k^2}{\sum_k (z_k - \bar z)^2}, \qquad
\text{max\_abs\_error} = \max_k |e_k|,
$$

where ``std`` is the population standard deviation and ``fit`` is MATLAB ``compare``'s
fit. They are related: $\text{nrmse} = \sqrt{1 - R^2}$ and
$\text{fit} = 100\,(1 - \text{nrmse})$. A constant measured output has no spread to
normalise by, so its ``nrmse``, ``fit_percent`` and ``r2`` are NaN.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ._arrays import as_columns, check_integer, column_names

__all__ = ["scored_pair", "simulation_metrics"]


def simulation_metrics(
    z, z_sim, skip: int = 0, *, output_names: Sequence[str] | None = None
) -> dict:
    """Simulation error metrics per output and overall.

    Parameters
    ----------
    z : array of shape (n_samples, n_outputs) or (n_samples,)
        Measured outputs.
    z_sim : array of the same shape
        The model's simulated outputs.
    skip : int, default 0
        Number of leading samples left out of the score (the nonlinear_benchmarks protocol
        leaves out the 50 samples used to estimate the initial state). At least two samples
        must remain.
    output_names : sequence of str, optional
        One name per output; defaults to ``z1, z2, ...``.

    Returns
    -------
    dict
        ``{"per_output": {name: metrics}, "overall": metrics}`` where ``metrics`` has the
        keys ``rmse``, ``nrmse``, ``fit_percent``, ``r2``, ``max_abs_error`` and
        ``n_scored`` (see the module docstring for the formulas). ``overall["rmse"]`` and
        ``overall["max_abs_error"]`` pool every output's errors (mixing their units);
        ``nrmse``, ``fit_percent`` and ``r2`` are the mean over outputs.
    """
    measured, simulated = scored_pair(z, z_sim, skip)
    names = column_names(output_names, measured.shape[1], "output_names", "z")
    error = measured - simulated
    per_output = {
        name: _column_metrics(measured[:, j], error[:, j]) for j, name in enumerate(names)
    }
    return {"per_output": per_output, "overall": _overall_metrics(per_output, error)}


def scored_pair(z, z_sim, skip: int) -> tuple[np.ndarray, np.ndarray]:
    """Validated copies of ``z`` and ``z_sim`` (2-D, same shape) without the first ``skip``."""
    measured = as_columns(z, "z")
    simulated = as_columns(z_sim, "z_sim")
    if simulated.shape != measured.shape:
        raise ValueError(f"z_sim must have the shape of z {measured.shape}, got {simulated.shape}.")
    n_samples = measured.shape[0]
    if n_samples < 2:
        raise ValueError(f"z has {n_samples} sample; at least 2 are needed.")
    skip = check_integer(skip, "skip", 0, n_samples - 2, "at least 2 samples must be scored")
    return measured[skip:], simulated[skip:]


def _column_metrics(measured: np.ndarray, error: np.ndarray) -> dict[str, float]:
    squared_error = float(error @ error)
    deviation = measured - measured.mean()
    squared_deviation = float(deviation @ deviation)
    rmse = math.sqrt(squared_error / error.size)
    return {
        "rmse": rmse,
        "nrmse": _ratio(rmse, math.sqrt(squared_deviation / error.size)),
        "fit_percent": 100.0
        * (1.0 - _ratio(math.sqrt(squared_error), math.sqrt(squared_deviation))),
        "r2": 1.0 - _ratio(squared_error, squared_deviation),
        "max_abs_error": float(np.max(np.abs(error))),
        "n_scored": int(error.size),
    }


def _ratio(numerator: float, denominator: float) -> float:
    return numerator / denominator if denominator > 0.0 else math.nan


def _overall_metrics(per_output: dict, error: np.ndarray) -> dict[str, float]:
    def average(key: str) -> float:
        return float(np.mean([metrics[key] for metrics in per_output.values()]))

    return {
        "rmse": float(np.sqrt(np.mean(error**2))),
        "nrmse": average("nrmse"),
        "fit_percent": average("fit_percent"),
        "r2": average("r2"),
        "max_abs_error": float(np.max(np.abs(error))),
        "n_scored": int(error.shape[0]),
    }
