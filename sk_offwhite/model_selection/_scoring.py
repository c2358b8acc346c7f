"""The one score of a held-out block of a sequence: its free-run simulation error.

A block's initial state is unknown to the model, so it is estimated from the block's first
``init_window`` measured samples (as MATLAB's ``compare`` does), which are then not scored.
[`held_out_rmse`][sk_offwhite.model_selection.held_out_rmse] is that score as a scikit-learn
scorer; the closed loop's cross-validation and the support path score their blocks with it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DIVERGED_FACTOR", "held_out_errors", "held_out_rmse", "unit_free"]

DIVERGED_FACTOR = 10.0
"""A held-out simulation that is not finite scores, in the output's units, this many
standard deviations of the measured block (ten times worse than predicting its mean)."""


def held_out_errors(est, u, z, init_window: int) -> np.ndarray:
    """Errors of the free run of one block after ``init_window`` samples (its initial state
    estimated from them): the RMS error in output standard deviations (``inf`` if the run
    diverged), and the unit-free RMSE (`unit_free`; `DIVERGED_FACTOR` standard deviations
    of ``z`` if the run diverged), which
    [`held_out_rmse`][sk_offwhite.model_selection.held_out_rmse] scores."""
    z = np.asarray(z, float).reshape(len(u), -1)
    scale = np.asarray(est.output_scale_, float).reshape(-1)
    with np.errstate(over="ignore", invalid="ignore"):
        z_init = z[:init_window] if init_window else None
        simulated = np.asarray(est.predict(u, z_init=z_init)).reshape(z.shape)
        error = (simulated - z)[init_window:]
        values = np.array([np.sqrt(np.mean((error / scale) ** 2)), unit_free(error, scale)])
    if np.all(np.isfinite(values)):
        return values
    return np.array([np.inf, DIVERGED_FACTOR * float(np.std(z))])


def unit_free(error: np.ndarray, scale: np.ndarray) -> float:
    r"""The RMSE of ``error`` (samples by outputs) with every output weighed by its
    ``scale``: $\sqrt{\tfrac{1}{n_z}\sum_o \overline{e_o^2}/\sigma_o^2}\,
    \sqrt{\tfrac{1}{n_z}\sum_o \sigma_o^2}$. For one output it is the plain RMSE; with
    several, rescaling one output (other units) rescales its error and its scale alike and
    leaves every comparison of models as it was, so no output dominates by its units."""
    if error.shape[1] == 1:
        return float(np.sqrt(np.mean(error**2)))
    relative = np.mean(np.mean(error**2, axis=0) / scale**2)
    return float(np.sqrt(relative) * np.sqrt(np.mean(scale**2)))


def held_out_rmse(init_window: int):
    """Scorer ``(estimator, u, z) -> -RMSE`` of a held-out block's free-run simulation.

    The block's initial state is estimated from its first ``init_window`` measured samples
    (``predict(u, z_init=...)``), which are not scored. With several outputs the RMSE is
    unit-free (`unit_free`): each output weighed by the scale of its training data. A non-finite
    simulation scores ``-DIVERGED_FACTOR * std(z)``, so that one diverging fold ranks a model last
    without making the mean undefined. Pass it as ``scoring=`` to ``GridSearchCV`` or
    ``cross_validate``.
    """

    def scorer(estimator, u, z) -> float:
        return -float(held_out_errors(estimator, u, z, init_window)[1])

    return scorer
