"""Continuation in γ: a sequence of fits, each started from the previous solution."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._estimator import GreyBoxSparseRegressor

__all__ = ["fit_gamma_path"]


def _check_gammas(gammas) -> list[float]:
    values = np.asarray(gammas, dtype=float).reshape(-1)
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"gammas must be one or more finite values >= 0, got {gammas!r}.")
    return values.tolist()


def fit_gamma_path(
    estimator: GreyBoxSparseRegressor, u, z, gammas: Sequence[float], **fit_params
) -> GreyBoxSparseRegressor:
    r"""Fit at each :math:`\gamma` of ``gammas`` in turn, each fit started from the last.

    Continuation in the sparsity weight: a large :math:`\gamma` first drives the weights of
    unneeded terms to zero (a support is chosen), then smaller values refit with less
    shrinkage, starting from that solution,

    .. math::

        (\theta, x_0, \Omega)^{(i)} = \arg\min C_T(\theta, x_0, \Omega; \gamma_i)
        \quad \text{from } (\theta, x_0, \Omega)^{(i-1)}.

    A single fit at the smallest :math:`\gamma` from the physics guess would keep terms
    that the first stage removes (on the vehicle of Section 5.1, the dictionary term
    ``x4 x6`` that duplicates a physical regressor).

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        Fitted in place. The first fit follows its own ``warm_start``; the later ones are
        warm-started.
    u, z : array-like
        Inputs and measured outputs, as for :meth:`GreyBoxSparseRegressor.fit`.
    gammas : sequence of float
        The values of :math:`\gamma`, in the order they are fitted (usually decreasing).
    **fit_params
        Passed to every ``fit`` (for example ``sample_index``).

    Returns
    -------
    estimator : GreyBoxSparseRegressor
        Fitted at ``gammas[-1]``, with ``gamma == gammas[-1]`` and its ``warm_start``
        setting as it was.

    Raises
    ------
    ValueError
        If ``gammas`` is empty, not finite or negative.
    """
    values = _check_gammas(gammas)
    warm_start = estimator.warm_start
    try:
        estimator.set_params(gamma=values[0]).fit(u, z, **fit_params)
        estimator.set_params(warm_start=True)
        for gamma in values[1:]:
            estimator.set_params(gamma=gamma).fit(u, z, **fit_params)
    finally:
        estimator.set_params(warm_start=warm_start)
    return estimator
