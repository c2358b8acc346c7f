r"""The support path: fits over a grid of $\gamma$ relative to $\gamma_{max}$.

For each $\gamma$ of a geometric grid from $\gamma_{max}$ (the smallest value for
which the correction is empty) down to $\epsilon\,\gamma_{max}$, the estimator is
fitted on the whole record and, with ``cv``, on the training part of every fold; each fold's
fit is scored by simulating its held-out block. The result holds, per $\gamma$, the
support, the coefficients, the estimation and cross-validated errors: what a person plots
to choose, and what [`fit_gamma_path`][sk_offwhite.fit_gamma_path] chooses from (lowest mean CV
error, or the sparsest model within one standard error of it).
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from numbers import Integral, Real

import numpy as np
from joblib import effective_n_jobs
from sklearn.base import clone
from sklearn.model_selection import KFold, check_cv
from sklearn.utils._param_validation import (
    Interval,
    InvalidParameterError,
    validate_parameter_constraints,
)

from ._estimator import GreyBoxSparseRegressor
from ._validation import check_pair, is_experiment_list
from .model._equations import correction_rows
from .model_selection._scoring import held_out_errors
from .model_selection._split import check_sample_index
from .runtime._parallel import gather, launch

__all__ = ["GammaPath", "fit_gamma_path", "gamma_grid"]


def gamma_grid(gamma_max: float, n_gammas: int = 8, eps: float = 1e-6) -> np.ndarray:
    r"""Geometric grid $\gamma_{max}\,\epsilon^{k/(n-1)}$, $k = 0, \dots, n-1$.

    As scikit-learn's ``lasso_path`` grid of $\alpha$: decreasing, from the value at
    which the correction is empty to ``eps`` times it.
    """
    if not np.isfinite(gamma_max) or gamma_max <= 0:
        raise ValueError(
            f"gamma_max must be finite and > 0, got {gamma_max!r}: the physics explains the "
            "data exactly or its fit failed, so there is no correction to search for."
        )
    if int(n_gammas) < 1 or not 0 < eps < 1:
        raise ValueError(f"need n_gammas >= 1 and 0 < eps < 1, got {n_gammas!r}, {eps!r}.")
    return gamma_max * np.logspace(0.0, np.log10(eps), int(n_gammas))


def _check_gammas(gammas) -> np.ndarray:
    values = np.asarray(gammas, dtype=float).reshape(-1)
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(f"gammas must be one or more finite values >= 0, got {gammas!r}.")
    return values


@dataclass
class GammaPath:
    r"""Fits along a grid of $\gamma$ (see [`fit_gamma_path`][sk_offwhite.fit_gamma_path]).

    Attributes
    ----------
    gammas : ndarray of shape (n_gammas,)
        The grid, up to where the path ended (see [`fit_gamma_path`][sk_offwhite.fit_gamma_path]).
    gamma_max : float
        $\gamma_{max}$ of the whole record (``nan`` when ``gammas`` were given).
    coefs : ndarray of shape (n_gammas, n_delta_states, n_features)
        ``coef_`` of the whole-record fit at each $\gamma$ (``nan`` where that fit
        failed: a warning names it and the path goes on).
    train_error : ndarray of shape (n_gammas,)
        RMS free-run simulation error on the whole record from the fitted initial state, in
        output standard deviations (``nan`` with ``sample_index``).
    cv_error : ndarray of shape (n_gammas, n_folds) or None
        RMS simulation error of each fold's held-out block (initial state estimated from
        its first ``init_window`` samples, which are not scored), in output standard
        deviations; ``inf`` where the simulation diverged, and (``stop_at_divergence``)
        at every smaller $\gamma$ of that fold and every fold's after the first
        $\gamma$ at which one diverged (unless that is the grid's first), which are
        not fitted.
    best_index : int or None
        The chosen $\gamma$ (``None`` without ``cv``).
    feature_names : list of str
    estimator : GreyBoxSparseRegressor
        The estimator passed in, fitted at the chosen $\gamma$ (without ``cv``: at
        the last one).
    cv_rmse : ndarray of shape (n_gammas, n_folds) or None
        The same held-out errors in the output's units (RMS over outputs and samples, as
        [`held_out_rmse`][sk_offwhite.loop.held_out_rmse] scores a block); a diverged simulation
        scores `DIVERGED_FACTOR` standard deviations of its block, a failed fit
        ``inf``.
    start : {'continuation', 'reference'}
        Where the returned fit started: the path's continuation from the larger
        $\gamma$, or (with ``cv`` only) the physics reference, as every fold's fit
        starts (see [`fit_gamma_path`][sk_offwhite.fit_gamma_path]); ``coefs`` and ``train_error``
        at the chosen $\gamma$ are those of the returned fit.
    """

    gammas: np.ndarray
    gamma_max: float
    coefs: np.ndarray
    train_error: np.ndarray
    cv_error: np.ndarray | None
    best_index: int | None
    feature_names: list
    estimator: GreyBoxSparseRegressor = field(repr=False)
    cv_rmse: np.ndarray | None = None
    start: str = "continuation"

    @property
    def supports(self) -> np.ndarray:
        """Boolean supports, shape ``(n_gammas, n_delta_states, n_features)``."""
        return np.isfinite(self.coefs) & (self.coefs != 0)

    @property
    def n_nonzero(self) -> np.ndarray:
        """Number of terms kept at each $\\gamma$."""
        return self.supports.reshape(len(self.gammas), -1).sum(axis=1)

    @property
    def cv_mean(self) -> np.ndarray | None:
        return None if self.cv_error is None else _fold_statistics(self.cv_error)[0]

    @property
    def cv_std(self) -> np.ndarray | None:
        return None if self.cv_error is None else _fold_statistics(self.cv_error)[1]

    @property
    def best_gamma(self) -> float | None:
        return None if self.best_index is None else float(self.gammas[self.best_index])

    def selected(self, index: int | None = None) -> list[str]:
        """``"equation: term"`` names of the support at ``index`` (default: the chosen one)."""
        if index is None:
            index = len(self.gammas) - 1 if self.best_index is None else self.best_index
        names = correction_rows(self.estimator)
        return [
            f"{names[i]}: {self.feature_names[j]}"
            for i, j in zip(*np.nonzero(self.coefs[index]), strict=True)
        ]

    def summary(self) -> str:
        """One line per $\\gamma$: terms kept, estimation and CV error, the choice."""
        lines = [f"{'gamma':>10s} {'terms':>5s} {'train':>9s} {'cv mean':>9s} {'cv std':>9s}"]
        for k, gamma in enumerate(self.gammas):
            cv = "" if self.cv_error is None else f" {self.cv_mean[k]:9.4g} {self.cv_std[k]:9.4g}"
            mark = "  <- chosen" if k == self.best_index else ""
            line = f"{gamma:10.3g} {self.n_nonzero[k]:5d} {self.train_error[k]:9.4g}{cv}{mark}"
            lines.append(line)
        return "\n".join(lines)


def _normalised_rmse(est: GreyBoxSparseRegressor, u, z, init_window: int) -> float:
    """RMS free-run error of one block after ``init_window`` samples, in output stds."""
    return float(held_out_errors(est, u, z, init_window)[0])


def _blocks(index: np.ndarray) -> list[np.ndarray]:
    """``index`` cut into runs of consecutive integers."""
    return np.split(index, np.flatnonzero(np.diff(index) != 1) + 1)


def _fold_errors(
    est, u, z, train, test, gammas, init_window, min_improvement, stop_at_divergence=False
) -> np.ndarray:
    r"""Held-out errors at every $\gamma$ of one fold (fits on ``train`` only), shape
    ``(n_gammas, 2)``: in output standard deviations and in the output's units; ``inf``
    where the fold's fit failed (with a warning that names the error). The fold's own path
    ends as the whole record's does (`_changes`); the $\gamma$ after its end
    keep its last model's errors. With ``stop_at_divergence`` it also ends at its first
    ``inf`` (a failed fit or a diverged held-out simulation), the rest ``inf`` unfitted."""
    fold = _FoldPath(est, u, z, train, test, init_window, min_improvement, stop_at_divergence)
    return np.asarray([fold.step(gamma) for gamma in gammas])


class _FoldPath:
    r"""One fold's path, a $\gamma$ at a time (`step`), so that the folds can
    advance together (`_folds_together`); arguments as `_fold_errors`."""

    def __init__(self, est, u, z, train, test, init_window, min_improvement, stop):
        self.est, self.u, self.z, self.train, self.test = est, u, z, train, test
        self.init_window, self.min_improvement, self.stop = init_window, min_improvement, stop
        self.errors = self.last = self.previous = None

    def step(self, gamma: float) -> np.ndarray:
        """The held-out errors at ``gamma`` (the next, smaller value of the grid)."""
        if self.stop and self.errors is not None and not np.all(np.isfinite(self.errors)):
            self.errors = np.array([np.inf, np.inf])
        elif self.previous is None and self.last is not None:  # the fold's path has ended
            self.errors = self.last
        else:
            self.errors = self._fit(gamma)
        return self.errors

    def _fit(self, gamma: float) -> np.ndarray:
        est = self.est.set_params(gamma=gamma)
        try:
            est.fit(self.u[self.train], self.z[self.train], sample_index=self.train)
        except ValueError as error:
            message = f"fit_gamma_path: a fold's fit at gamma={gamma:.3g} failed ({error})"
            warnings.warn(message, stacklevel=4)
            return np.array([np.inf, np.inf])
        if self.last is not None and not _changes(
            est.fit_error_, self.previous, self.min_improvement
        ):
            self.previous = None
            return self.last
        blocks = _blocks(self.test)
        scores = [_block_errors(est, self.u, self.z, b, self.init_window) for b in blocks]
        self.last, self.previous = np.sqrt(np.mean(np.square(scores), axis=0)), est.fit_error_
        return self.last


def _folds_together(arguments, stop_at_divergence: bool) -> np.ndarray:
    r"""Every fold's `_fold_errors` (``arguments``: one tuple of its arguments per
    fold), shape ``(n_folds, n_gammas, 2)``, the folds advanced together one
    $\gamma$ at a time. With ``stop_at_divergence`` none is fitted after
    `_divergence` (`_choose` cannot choose there): those errors are ``inf``."""
    gammas = arguments[0][5]
    folds = [_FoldPath(*args[:5], *args[6:8], stop_at_divergence) for args in arguments]
    errors = np.full((len(folds), len(gammas), 2), np.inf)
    for k, gamma in enumerate(gammas):
        errors[:, k] = [fold.step(gamma) for fold in folds]
        if stop_at_divergence and _divergence(errors[:, : k + 1]) is not None:
            break
    return errors


def _divergence(errors: np.ndarray) -> int | None:
    r"""Index of the first $\gamma$ at which a fold's error is not finite (``errors``
    of shape ``(n_folds, n_gammas, 2)``), when every fold's first is finite; ``None``
    otherwise. With ``stop_at_divergence`` `_choose` chooses before it."""
    finite = np.all(np.isfinite(errors[..., 0]), axis=0)
    if not finite[0] or np.all(finite):
        return None
    return int(np.flatnonzero(~finite)[0])


def _cut_at_divergence(errors: np.ndarray) -> np.ndarray:
    """``errors`` (as `_folds_together`'s) ``inf`` after `_divergence`: folds
    fitted apart report what folds fitted together do."""
    index = _divergence(errors)
    if index is not None:
        errors = errors.copy()
        errors[:, index + 1 :] = np.inf
    return errors


def _changes(fit_error: float, previous: float, min_improvement: float) -> bool:
    r"""Whether a smaller $\gamma$ changed the fit: the fit error moved by more than
    ``min_improvement`` of its previous value (always, with ``min_improvement=0``). A fit
    that got worse has moved to another minimum (the vehicle's path goes from a wrong
    4-term support to Δ's 3 terms that way): the path goes on."""
    return min_improvement <= 0 or abs(fit_error - previous) > min_improvement * previous


def _block_errors(est, u, z, block, init_window) -> np.ndarray:
    window = min(init_window, len(block) // 2)
    return held_out_errors(est, u[block], z[block], window)


def _choose(
    cv_error: np.ndarray, gammas: np.ndarray, one_standard_error: bool, stop_at_divergence: bool
) -> int:
    """Lowest mean CV error, or the largest $\\gamma$ within one standard error; with
    ``stop_at_divergence``, among the $\\gamma$ before the first whose mean is not
    finite (all of them if that is the first)."""
    mean, std = _fold_statistics(cv_error)
    if not np.any(np.isfinite(mean)):
        raise ValueError("every fit of the path diverged on its held-out blocks.")
    if stop_at_divergence and np.isfinite(mean[0]):
        mean = np.where(np.arange(len(mean)) < _first_divergence(mean), mean, np.inf)
    best = int(np.nanargmin(np.where(np.isfinite(mean), mean, np.nan)))
    if not one_standard_error:
        return best
    limit = mean[best] + std[best] / np.sqrt(cv_error.shape[1])
    within = np.flatnonzero((mean <= limit) & (gammas >= gammas[best]))
    return int(within[np.argmax(gammas[within])])


def _fold_statistics(cv_error: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation over the folds (``nan`` std where a fold diverged)."""
    with np.errstate(invalid="ignore"):
        return np.mean(cv_error, axis=1), np.std(cv_error, axis=1)


def _first_divergence(errors: np.ndarray) -> int:
    """Index of the first non-finite entry of ``errors`` (``len(errors)`` if none)."""
    diverged = np.flatnonzero(~np.isfinite(errors))
    return int(diverged[0]) if diverged.size else len(errors)


def _splits(cv, n_samples: int) -> list[tuple[np.ndarray, np.ndarray]]:
    splitter = check_cv(cv)
    if isinstance(splitter, KFold) and splitter.shuffle:
        raise ValueError("cv must keep time order: KFold(shuffle=True) mixes the samples.")
    try:
        return list(splitter.split(np.zeros((n_samples, 1))))
    except ValueError as error:
        raise ValueError(f"cv: {error}") from error


def _whole_record_path(est, u, z, gammas, sample_index, min_improvement):
    r"""Fit at every $\gamma$ on the whole record until a smaller one no longer changes
    the fit (`_changes`); snapshots of the fitted estimator (``None`` where a fit
    failed) and their estimation errors."""
    snapshots, errors, previous = [], [], None
    for gamma in gammas:
        try:
            est.set_params(gamma=gamma).fit(u, z, sample_index=sample_index)
        except ValueError as error:  # the path goes on from the last fit that worked
            warnings.warn(
                f"fit_gamma_path: the fit at gamma={gamma:.3g} failed ({error})", stacklevel=3
            )
            snapshots.append(None)
            errors.append(np.inf)
            continue
        if previous is not None and not _changes(est.fit_error_, previous, min_improvement):
            break
        previous = est.fit_error_
        est.set_params(warm_start=True)
        snapshots.append(copy.copy(est))
        errors.append(_normalised_rmse(est, u, z, 0) if sample_index is None else np.nan)
    if all(snap is None for snap in snapshots):
        raise ValueError("fit_gamma_path: the fit failed at every gamma of the path.")
    return snapshots, np.asarray(errors)


def penalised_objective(est: GreyBoxSparseRegressor) -> float:
    r"""$F + \gamma\sum_{ij} s_{ij}|\Omega_{ij}|$ of a fitted estimator: the objective
    every fit of the path minimises (``fit_error_`` squared, ``penalty_scale_``), with exact
    absolute values."""
    penalty = np.sum(np.asarray(est.penalty_scale_) * np.abs(np.asarray(est.coef_)))
    return float(est.fit_error_**2 + est.gamma * penalty)


def _better_start(snapshot: GreyBoxSparseRegressor, u, z, sample_index, reference=None):
    r"""``(fit, start)``: ``snapshot`` (the path's continuation at its $\gamma$) or the
    same $\gamma$ fitted from the physics reference, whichever reaches the lower
    `penalised_objective` (by more than `RESTART_MARGIN` of it); why, in
    [`fit_gamma_path`][sk_offwhite.fit_gamma_path]. ``reference`` is the path's cached physics-only
    stage (the estimator's ``_reference``), which the fit from the reference then does not redo; the
    copy shares the snapshot's physics and library, so no program is traced again."""
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fresh = copy.copy(snapshot).set_params(warm_start=False)
            fresh._reference = reference
            fresh.fit(u, z, sample_index=sample_index)
    except ValueError:
        return snapshot, "continuation"
    kept, other = penalised_objective(snapshot), penalised_objective(fresh)
    if not (np.isfinite(other) and other < kept - RESTART_MARGIN * abs(kept)):
        return snapshot, "continuation"
    for warning in caught:  # what the adopted fit warned of (not converged, ...)
        warnings.warn_explicit(warning.message, warning.category, warning.filename, warning.lineno)
    return fresh, "reference"


RESTART_MARGIN = 1e-9
"""Relative decrease of `penalised_objective` a fit from the physics reference must
bring to replace the continuation's (below it the two are the same optimum up to rounding)."""


def fit_gamma_path(
    estimator: GreyBoxSparseRegressor,
    u,
    z,
    gammas=None,
    *,
    n_gammas: int = 8,
    eps: float = 1e-6,
    cv=None,
    one_standard_error: bool = False,
    init_window: int | None = None,
    sample_index=None,
    n_jobs: int | None = None,
    min_improvement: float = 0.0,
    stop_at_divergence: bool = True,
    restart: bool | None = None,
) -> GammaPath:
    r"""Fit ``estimator`` along a grid of $\gamma$ and (with ``cv``) choose one.

    The grid is fitted in order, each $\gamma$ from the previous one's solution
    (continuation; the first from the physics-only fit, which is computed once per record,
    see `sk_offwhite.fitting._sparsity`). Continuation matters: a correction whose terms
    partly cancel (large weights, small sum) costs much $\ell_1$ norm, and a fit
    started from $\Omega = 0$ at a small $\gamma$ can settle in another local
    minimum, while a path that grows the support term by term reaches it.

    With ``min_improvement > 0`` the path ends early, as glmnet's does, at the first
    $\gamma_{k+1}$ whose fit error $e_{k+1}$ (``fit_error_``, the RMS
    multi-step fit residual in output standard deviations) is within
    $\text{min\_improvement}\,e_k$ of $e_k$: a weaker penalty that changes no
    fit only loosens the correction. Below that point the
    fits differ by where the solver stops in directions the data do not determine, so a
    change of units or of rounding picks another model, and the CV errors there are as
    erratic.
    $\gamma_{k+1}$ and the smaller values are left out of the result; each CV fold
    ends its own path by the same rule and keeps its last model's held-out errors.

    With ``cv``, the fit returned at the chosen $\gamma$ has two starts: the path's
    continuation and the physics reference, from which every fold's fit starts (the kind
    of fit the CV scored); the one with the lower penalised objective
    $F + \gamma\sum s|\Omega|$ is kept (``GammaPath.start`` says which).
    Continuation can carry a support from a larger $\gamma$ into a basin the data no
    longer support, where the fit from the reference reaches the right one. Without
    ``cv`` the last $\gamma$'s continuation is returned (``restart=None``): nothing has
    scored a fit from the reference there, and at a tiny $\gamma$ on noisy data its
    lower objective can be a fit of the noise, with parameters farther from the truth
    than the continuation's. On noise-free data ``restart=True`` asks for the two starts
    there too: which basin the continuation ends in can depend on rounding, and so on
    the processor, while the fit from the reference does not depend on the path before it.

    Parameters
    ----------
    estimator : GreyBoxSparseRegressor
        With a ``library``; fitted in place, left at the chosen $\gamma$.
    u, z : array-like
        One record, as for [`GreyBoxSparseRegressor.fit`][sk_offwhite.GreyBoxSparseRegressor.fit].
    gammas : array-like, default=None
        The grid. ``None``: [`gamma_grid`][sk_offwhite.gamma_grid] (``n_gammas`` values from
        $\gamma_{max}$ of the record down to ``eps`` times it).
    n_gammas : int, default=8
    eps : float, default=1e-6
    cv : int or cross-validation splitter, default=None
        Folds of contiguous blocks (an int means ``KFold(cv)``, unshuffled). ``None``: no
        selection, the estimator is left at the last $\gamma$.
    one_standard_error : bool, default=False
        Choose the largest $\gamma$ (the sparsest model) whose mean CV error is
        within one standard error of the lowest, instead of the lowest.
    init_window : int, default=None
        Samples that estimate each held-out block's initial state (not scored); ``None``
        uses the estimator's rule (``init_window`` or ``min(50, n // 5)``).
    sample_index : array-like, default=None
        As for ``fit`` (a jump starts a new record).
    n_jobs : int, default=None
        Processes that fit the CV folds (joblib's convention: ``None`` one, ``-1`` all
        cores) while this one fits the whole record. The numbers are the same as with one
        (each fold is the same computation); the workers compile their own programs unless
        the persistent cache is on
        ([`enable_compilation_cache`][sk_offwhite.enable_compilation_cache]).
    min_improvement : float, default=0.0
        Relative change of the fit error a smaller $\gamma$ must bring for the path to
        go on (dimensionless, e.g. 1e-3); 0 fits the whole grid, as does a grid that is not
        decreasing. Off by default: a non-convex path can stay flat on a wrong support for
        several $\gamma$ and then reach the right one (the noise-free vehicle of Section
        5.1 does), which an early end would miss.
    stop_at_divergence : bool, default=True
        Choose only among the $\gamma$ before the first one whose mean CV error is
        not finite (a fold's held-out simulation diverged, or a fold's or the whole
        record's fit failed), and fit no fold below its own first divergence, nor any
        below the first $\gamma$ at which one diverged (when each fold's first
        $\gamma$ is finite; their errors there are ``inf``). There the
        penalty no longer keeps the correction stable off the data it was fitted on, and
        a smaller $\gamma$ only loosens it further: a finite CV error below that
        point is the luck of where each fold's fit stopped (the folds can diverge at one
        $\gamma$, not at the next, and again below it, and a choice there can change
        with the units of the data). ``False`` chooses among every finite mean.
    restart : bool, default=None
        Fit the returned $\gamma$ from the physics reference too and keep the lower
        penalised objective (see above). ``None``: only with ``cv``.

    Returns
    -------
    GammaPath
    """
    _check_path_arguments(
        estimator, gammas=gammas, n_gammas=n_gammas, eps=eps, cv=cv,
        one_standard_error=one_standard_error, init_window=init_window, n_jobs=n_jobs,
        min_improvement=min_improvement, stop_at_divergence=stop_at_divergence,
        restart=restart,
    )  # fmt: skip
    u_arr, z_arr = check_pair(u, z) if not _records_given(u, z) else _refuse_records()
    sample_index = check_sample_index(sample_index)
    if cv is not None:  # a splitter that cannot cut the record fails before any fit
        _check_window_fits(estimator, init_window, _splits(cv, len(u_arr)))
    values, gamma_max, min_improvement = _path_grid(
        estimator, u_arr, z_arr, gammas, n_gammas, eps, sample_index, min_improvement
    )
    fold_errors = None
    if cv is not None:
        window = _init_window(estimator, init_window, len(u_arr))
        shared = (values, window, min_improvement, stop_at_divergence)
        fold_errors = _start_folds(estimator, u_arr, z_arr, cv, shared, n_jobs)
    warm_start = estimator.warm_start
    try:
        snapshots, train_error = _whole_record_path(
            estimator, u_arr, z_arr, values, sample_index, min_improvement
        )
    finally:
        estimator.set_params(warm_start=warm_start)
    values = values[: len(snapshots)]
    failed = np.array([snap is None for snap in snapshots])
    cv_error = cv_rmse = best = None
    if fold_errors is not None:
        cv_error, cv_rmse = _fold_scores(fold_errors(), failed)
        best = _choose(cv_error, values, one_standard_error, stop_at_divergence)
    chosen = int(np.flatnonzero(~failed)[-1]) if best is None else best
    two_starts = best is not None if restart is None else bool(restart)
    start = _keep_chosen(
        estimator, snapshots, train_error, chosen, two_starts, u_arr, z_arr, sample_index
    )
    estimator.set_params(warm_start=warm_start)
    shape = estimator.coef_.shape
    coefs = np.stack([np.full(shape, np.nan) if s is None else s.coef_ for s in snapshots])
    return GammaPath(
        values,
        gamma_max,
        coefs,
        train_error,
        cv_error,
        best,
        estimator.feature_names_,
        estimator,
        cv_rmse,
        start,
    )


def _path_grid(estimator, u, z, gammas, n_gammas, eps, sample_index, min_improvement):
    r"""``(values, gamma_max, min_improvement)``: the given grid (``gamma_max`` nan, and no
    early end on a grid that is not decreasing, since the end compares each $\gamma$ with a
    larger one) or [`gamma_grid`][sk_offwhite.gamma_grid] of the record."""
    if gammas is None:
        return (*_grid(estimator, u, z, n_gammas, eps, sample_index), min_improvement)
    values = _check_gammas(gammas)
    return values, np.nan, 0.0 if np.any(np.diff(values) >= 0) else min_improvement


def _start_folds(estimator, u, z, cv, shared: tuple, n_jobs) -> Callable[[], np.ndarray]:
    """Start each fold's path (``shared``: the grid, the window, the early end, the stop at
    divergence) and return the function that gives their held-out errors: the folds are
    fitted here at once with one process, else launched now on ``n_jobs`` workers and
    gathered (cut at their first divergence) when the function is called, after the whole
    record's path."""
    stop_at_divergence = shared[-1]
    arguments = [
        (clone(estimator), u, z, train, test, *shared) for train, test in _splits(cv, len(u))
    ]
    if effective_n_jobs(n_jobs) == 1:
        errors = _folds_together(arguments, stop_at_divergence)
        return lambda: errors
    jobs = launch(_fold_errors, arguments, n_jobs)

    def gathered() -> np.ndarray:
        errors = np.stack(gather(jobs))
        return _cut_at_divergence(errors) if stop_at_divergence else errors

    return gathered


def _keep_chosen(estimator, snapshots, train_error, chosen, two_starts, u, z, sample_index):
    """Leave ``estimator`` at the fit of ``snapshots[chosen]``, the better of its two starts
    with ``two_starts`` (its training error updated when the reference wins on one record);
    return which start it is."""
    start = "continuation"
    if two_starts:
        reference = getattr(estimator, "_reference", None)
        snapshots[chosen], start = _better_start(snapshots[chosen], u, z, sample_index, reference)
    if start == "reference" and sample_index is None:
        train_error[chosen] = _normalised_rmse(snapshots[chosen], u, z, 0)
    vars(estimator).update(vars(snapshots[chosen]))
    return start


PATH_CONSTRAINTS: dict = {
    "gammas": ["array-like", None],
    "n_gammas": [Interval(Integral, 1, None, closed="left")],
    "eps": [Interval(Real, 0, 1, closed="neither")],
    "cv": ["cv_object", None],
    "one_standard_error": ["boolean"],
    "init_window": [Interval(Integral, 0, None, closed="left"), None],
    "n_jobs": [Integral, None],
    "min_improvement": [Interval(Real, 0, 1, closed="left")],
    "stop_at_divergence": ["boolean"],
    "restart": ["boolean", None],
}
"""What each argument of [`fit_gamma_path`][sk_offwhite.fit_gamma_path] may be."""


def _check_path_arguments(estimator, **arguments) -> None:
    """Every argument of the path checked before its first fit, each error naming it."""
    if not isinstance(estimator, GreyBoxSparseRegressor):
        raise TypeError(
            f"estimator must be a GreyBoxSparseRegressor, got {type(estimator).__name__}."
        )
    if estimator.library is None:
        raise ValueError("fit_gamma_path needs an estimator with a library (a correction).")
    estimator._validate_params()
    validate_parameter_constraints(PATH_CONSTRAINTS, arguments, "fit_gamma_path")
    for name in ("n_gammas", "init_window", "n_jobs"):
        if isinstance(arguments[name], bool | np.bool_):
            raise InvalidParameterError(
                f"The {name!r} parameter of fit_gamma_path must be an integer, got "
                f"{arguments[name]!r}."
            )
    if arguments["gammas"] is not None:
        try:
            _check_gammas(arguments["gammas"])
        except (TypeError, ValueError) as error:
            raise InvalidParameterError(f"gammas: {error}") from error


def _grid(estimator, u, z, n_gammas: int, eps: float, sample_index) -> tuple[np.ndarray, float]:
    """``(grid, gamma_max)``: the [`gamma_grid`][sk_offwhite.gamma_grid] of ``n_gammas`` values
    below the record's $\\gamma_{max}$ (the physics-only fit's, which is computed for it)."""
    estimator._fit(u, z, sample_index, reference_only=True)
    return gamma_grid(estimator.gamma_max_, n_gammas, eps), estimator.gamma_max_


def _fold_scores(folds: np.ndarray, failed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(cv_error, cv_rmse)`` of shape ``(n_gammas, n_folds)`` from the folds' errors
    (`_folds_together`'s shape, cut to the whole record's ``len(failed)`` γ):
    ``inf`` at the γ whose fit on the whole record ``failed``."""
    cv_error, cv_rmse = np.moveaxis(folds, (2, 0), (0, 2))[:, : len(failed)]
    cv_error[failed], cv_rmse[failed] = np.inf, np.inf
    return cv_error, cv_rmse


def _records_given(u, z) -> bool:
    return is_experiment_list(u) or is_experiment_list(z)


def _refuse_records():
    raise ValueError(
        "u and z must be one record (2-D arrays) for fit_gamma_path, not lists of records: "
        "run the path on each record, or join records that follow each other."
    )


def _check_window_fits(estimator, init_window, splits) -> None:
    """Refuse a declared ``init_window`` that leaves fewer than 2 samples to score in the
    shortest held-out block (the default rule is cut to half a block instead)."""
    window = init_window if init_window is not None else estimator.init_window
    shortest = min(len(test) for _, test in splits)
    if window is not None and int(window) > shortest - 2:
        raise ValueError(
            f"init_window={window} leaves fewer than 2 samples to score in the held-out "
            f"blocks of {shortest} samples: use fewer folds or a shorter init_window."
        )


def _init_window(estimator, init_window, n_samples: int) -> int:
    if init_window is not None:
        return int(init_window)
    if estimator.init_window is not None:
        return int(estimator.init_window)
    return min(50, n_samples // 5)
