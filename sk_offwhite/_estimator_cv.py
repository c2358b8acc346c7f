r"""``GreyBoxSparseRegressorCV``: the sparsity weight $\gamma$ chosen by cross-validation.

As ``LassoCV`` is to ``Lasso``: ``fit`` runs the support path
([`fit_gamma_path`][sk_offwhite.fit_gamma_path]) over a grid of $\gamma$ relative to
$\gamma_{max}$, scores every $\gamma$ by the held-out simulation error of contiguous blocks of
the record, and leaves the estimator fitted at the chosen one.
"""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
from sklearn.utils._param_validation import Interval

from ._estimator import GreyBoxSparseRegressor
from ._estimator_checks import _check_counts
from ._path import GammaPath, fit_gamma_path
from .model import PhysicsModel

__all__ = ["GreyBoxSparseRegressorCV"]

_SHARED = tuple(name for name in GreyBoxSparseRegressor._parameter_constraints if name != "gamma")
"""The hyperparameters the CV estimator passes on to each fit of the path."""


class GreyBoxSparseRegressorCV(GreyBoxSparseRegressor):
    r"""Physics model + sparse correction, its $\gamma$ chosen by cross-validation in ``fit``.

    ``fit(u, z)`` fits the support path: for each $\gamma$ of a geometric grid from
    $\gamma_{max}$ (the smallest value at which the correction is empty) down to ``eps``
    times it, the model is fitted on the whole record (each from the previous solution) and
    on the training part of every fold, each fold scored by the free-run simulation of its
    held-out block (its initial state estimated from the block's first ``init_window``
    samples, which are not scored). The estimator is left fitted at the $\gamma$ of lowest
    mean CV error (``one_standard_error``: the largest within one standard error of it):
    ``coef_``, ``parameters_``, ``predict`` and ``score`` are those of that fit.

    Parameters
    ----------
    physics, library, lam, nu, horizon
        As [`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor]; without a
        ``library`` the physics is fitted alone (there is no weight to choose).
    gammas : array-like, default=None
        The grid of $\gamma$; ``None``: ``n_gammas`` values from $\gamma_{max}$ of the record
        down to ``eps`` times it ([`gamma_grid`][sk_offwhite.gamma_grid]).
    n_gammas : int, default=8
    eps : float, default=1e-6
    cv : int or cross-validation splitter, default=3
        Folds of contiguous blocks: an int is that many blocks, each fitted on the rest as
        separate records (``KFold`` unshuffled, or ``SequenceSplit(cv, train="rest")``);
        any splitter that keeps time order.
    one_standard_error : bool, default=False
        Choose the largest $\gamma$ (the sparsest model) whose mean CV error is within one
        standard error of the lowest, instead of the lowest.
    n_jobs : int, default=None
        Processes that fit the folds while this one fits the whole record (joblib's
        convention); the numbers are the same as with one.
    delta_states, delta_outputs, prune_tol, refit, l1_smoothing, shooting_weight, solver, \
lm_scaling, optimizer, max_iter, tol, init_window, warm_start, verbose, random_state
        As [`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor].

    Attributes
    ----------
    gamma_ : float or None
        The chosen $\gamma$ (``gamma`` reads it; ``None`` without a library).
    gammas_ : ndarray
        The grid, up to where the path ended.
    path_ : GammaPath
        The support path: supports, coefficients, estimation and CV errors per $\gamma$.
    cv_results_ : dict of ndarray
        ``gamma``, ``n_nonzero``, ``train_error``, ``mean_cv_rmse``, ``std_cv_rmse`` and
        ``split{k}_cv_rmse`` (the held-out RMSE of fold ``k`` in the output's units), one
        entry per $\gamma$; ``pandas.DataFrame(cv_results_)`` reads it.
    (every attribute of GreyBoxSparseRegressor)
        Those of the fit at ``gamma_``.
    """

    _parameter_constraints: dict = {
        **{k: v for k, v in GreyBoxSparseRegressor._parameter_constraints.items() if k != "gamma"},
        "gammas": ["array-like", None],
        "n_gammas": [Interval(Integral, 1, None, closed="left")],
        "eps": [Interval(Real, 0, 1, closed="neither")],
        "cv": ["cv_object"],
        "one_standard_error": ["boolean"],
        "n_jobs": [Integral, None],
    }

    def __init__(
        self,
        physics: PhysicsModel | None = None,
        library=None,
        gammas=None,
        lam: float = 0.0,
        nu: float = 0.0,
        horizon: int | None = None,
        *,
        n_gammas: int = 8,
        eps: float = 1e-6,
        cv=3,
        one_standard_error: bool = False,
        n_jobs: int | None = None,
        delta_states=None,
        delta_outputs=None,
        prune_tol: float = 0.01,
        refit: bool = True,
        l1_smoothing: float = 100.0,
        shooting_weight: float = 10.0,
        solver="auto",
        lm_scaling: str = "per-variable",
        optimizer=None,
        max_iter: int = 200,
        tol: float = 1e-10,
        init_window: int | None = None,
        warm_start: bool = False,
        verbose: int = 0,
        random_state=None,
    ):
        self.gammas = gammas
        self.n_gammas = n_gammas
        self.eps = eps
        self.cv = cv
        self.one_standard_error = one_standard_error
        self.n_jobs = n_jobs
        shared = {k: v for k, v in locals().items() if k in _SHARED}
        vars(self).update(shared)

    @property
    def gamma(self) -> float | None:
        """The chosen $\\gamma$ (``gamma_``), ``None`` before ``fit``."""
        return getattr(self, "gamma_", None)

    def fit(self, u, z, sample_index=None):
        """Fit the support path on ``(u, z)`` and keep the fit at the CV-chosen $\\gamma$.

        Parameters
        ----------
        u, z, sample_index
            As for [`GreyBoxSparseRegressor.fit`][sk_offwhite.GreyBoxSparseRegressor.fit].

        Returns
        -------
        self : GreyBoxSparseRegressorCV
        """
        self._validate_params()
        _check_counts(self)
        base = GreyBoxSparseRegressor(**{name: getattr(self, name) for name in _SHARED})
        if self.library is None:  # the physics alone: no weight to choose
            self._adopt(base.fit(u, z, sample_index=sample_index))
            self.path_, self.gamma_, self.gammas_, self.cv_results_ = None, None, None, {}
            return self
        path = fit_gamma_path(
            base, u, z, self.gammas, n_gammas=self.n_gammas, eps=self.eps, cv=self.cv,
            one_standard_error=self.one_standard_error, init_window=self.init_window,
            sample_index=sample_index, n_jobs=self.n_jobs,
        )  # fmt: skip
        self._adopt(base)
        self._store_path(path)
        return self

    def _adopt(self, fitted: GreyBoxSparseRegressor) -> None:
        """Take over the fitted state of ``fitted`` (its attributes and caches)."""
        state = {k: v for k, v in vars(fitted).items() if k.endswith("_") or k.startswith("_")}
        state.pop("_metadata_request", None)
        vars(self).update(state)

    def _store_path(self, path: GammaPath) -> None:
        self.path_ = path
        self.gamma_ = float(path.best_gamma)
        self.gammas_ = np.asarray(path.gammas, float)
        self.cv_results_ = _cv_results(path)


def _cv_results(path: GammaPath) -> dict:
    """``cv_results_`` of a support path, one entry per $\\gamma$."""
    results = {
        "gamma": np.asarray(path.gammas, float),
        "n_nonzero": np.asarray(path.n_nonzero),
        "train_error": np.asarray(path.train_error, float),
    }
    if path.cv_rmse is not None:
        with np.errstate(invalid="ignore"):
            results["mean_cv_rmse"] = np.mean(path.cv_rmse, axis=1)
            results["std_cv_rmse"] = np.std(path.cv_rmse, axis=1)
        for k in range(path.cv_rmse.shape[1]):
            results[f"split{k}_cv_rmse"] = path.cv_rmse[:, k]
    return results
