"""Choosing a baseline's lags and threshold on the estimation record only.

[`tune_delay_sindy`][sk_offwhite.baselines.tune_delay_sindy] is a plain ``GridSearchCV`` over
[`DelaySINDyRegressor`][sk_offwhite.baselines.DelaySINDyRegressor] with contiguous ``KFold`` blocks
of the estimation record (``sample_index`` keeps blocks apart, each held-out block is simulated from
its own first samples), scored by the free-run $R^2$. Validation data never enter the choice.
"""

from __future__ import annotations

import numpy as np
from sklearn.model_selection import GridSearchCV, KFold

from ._regressor import DelaySINDyRegressor

__all__ = ["DEFAULT_GRID", "access_statement", "tune_delay_sindy"]

DEFAULT_GRID: dict[str, list] = {
    "n_output_lags": [1, 2, 3],
    "n_input_lags": [1, 2, 3],
    "threshold": [1e-3, 1e-2, 1e-1],
}
"""Lags and thresholds searched by [`tune_delay_sindy`][sk_offwhite.baselines.tune_delay_sindy]
unless told otherwise."""


def tune_delay_sindy(
    u,
    z,
    *,
    optimizer: str = "stlsq",
    sqrt_outputs: bool = False,
    degree: int = 2,
    param_grid: dict | None = None,
    n_splits: int = 3,
    n_jobs: int | None = None,
) -> GridSearchCV:
    """Grid search of a [`DelaySINDyRegressor`][sk_offwhite.baselines.DelaySINDyRegressor] by
    free-run CV on one record.

    Parameters
    ----------
    u : array-like of shape (n_samples, n_inputs)
        Estimation inputs.
    z : array-like of shape (n_samples,) or (n_samples, n_outputs)
        Estimation outputs.
    optimizer : {'stlsq', 'sr3'}, default='stlsq'
    sqrt_outputs : bool, default=False
        Physics-informed square roots of the outputs in the library.
    degree : int, default=2
        Polynomial degree of the library.
    param_grid : dict, default=None
        Grid over the estimator's parameters; ``None`` uses
        [`DEFAULT_GRID`][sk_offwhite.baselines.DEFAULT_GRID].
    n_splits : int, default=3
        Contiguous folds of the record.
    n_jobs : int, default=None
        Passed to ``GridSearchCV``.

    Returns
    -------
    GridSearchCV
        Fitted (refitted on the whole record with the best parameters).
    """
    base = DelaySINDyRegressor(optimizer=optimizer, sqrt_outputs=sqrt_outputs, degree=degree)
    search = GridSearchCV(
        base,
        param_grid or DEFAULT_GRID,
        cv=KFold(n_splits),
        n_jobs=n_jobs,
        error_score=-np.inf,
    )
    return search.fit(u, z, sample_index=np.arange(len(u)))


def access_statement(estimator: DelaySINDyRegressor) -> str:
    """One sentence saying what a fitted baseline had access to (for reports)."""
    library = f"polynomial library of degree {estimator.degree}"
    if estimator.sqrt_outputs:
        library += " on the lags and their square roots (physics-informed)"
    return (
        f"Only the estimation inputs and measured outputs: {estimator.n_output_lags} output "
        f"lag(s), {estimator.n_input_lags} input lag(s), {library}, "
        f"{estimator.optimizer.upper()} with threshold {estimator.threshold:g}; no unmeasured "
        "state, physical parameter or validation sample."
    )
