"""How the loop scores a structure: the held-out simulation error over contiguous blocks.

The folds are those of [`SequenceSplit`][sk_offwhite.SequenceSplit] (``n_folds`` blocks, each
fitted on the rest as separate records, or the record's tail held out) and each held-out
block is scored by [`held_out_rmse`][sk_offwhite.model_selection.held_out_rmse], the scorer a
``GridSearchCV`` of the estimator uses: its initial state estimated from its first
``init_window`` samples, which are not scored. The folds run in worker processes whose
warnings are issued again here (`sk_offwhite.runtime._parallel`).
"""

from __future__ import annotations

import warnings

import numpy as np
from sklearn.base import clone

from ..model_selection import SequenceSplit, held_out_rmse
from ..runtime._parallel import gather, launch
from ._search import Search
from ._settings import LoopSettings

__all__ = ["cross_validated_rmse", "held_out_splits", "held_out_splitter"]


def held_out_splitter(settings: LoopSettings) -> SequenceSplit:
    """The folds of ``settings.selection``: ``n_folds`` contiguous blocks, each fitted on
    the rest, or the last ``tail_fraction`` of the record held out."""
    if settings.selection == "cv":
        return SequenceSplit(settings.n_folds, train="rest")
    return SequenceSplit(1, train="forward", test_size=settings.tail_fraction)


def held_out_splits(settings: LoopSettings, n_samples: int) -> list:
    """``(train, test)`` index pairs of [`held_out_splitter`][sk_offwhite.loop.held_out_splitter]
    on a record of ``n_samples``; every held-out block must leave two scored samples after
    ``init_window``, and a held-out tail's past must be longer than ``init_window``."""
    where = (
        f"n_folds={settings.n_folds}"
        if settings.selection == "cv"
        else f"tail_fraction={settings.tail_fraction}"
    )
    try:
        splits = list(held_out_splitter(settings).split(np.zeros((n_samples, 1))))
    except ValueError as error:
        raise ValueError(f"{where}: {error}") from error
    shortest = min(len(test) for _, test in splits)
    if shortest < settings.init_window + 2:
        raise ValueError(
            f"init_window={settings.init_window} leaves fewer than 2 scored samples in a "
            f"held-out block of {shortest} samples ({n_samples} samples, {where}): use a "
            "smaller init_window, fewer folds or a longer record."
        )
    if settings.selection == "tail" and len(splits[0][0]) <= settings.init_window:
        raise ValueError(
            f"tail_fraction={settings.tail_fraction} of {n_samples} samples leaves a past "
            f"no longer than init_window={settings.init_window}."
        )
    return splits


def cross_validated_rmse(physics, u, z, settings: LoopSettings | None = None) -> float:
    """The loop's score of a structure: the mean held-out free-run RMSE of ``physics``
    (started from its parameter values) over the folds of
    [`held_out_splits`][sk_offwhite.loop.held_out_splits], each fold fitted with ``settings``
    (its ``cv_horizon``, ``max_iter``, ``init_window``, ``lm_scaling``); a fold whose fit
    fails scores ``inf``."""
    search = Search(u, z, LoopSettings() if settings is None else settings)
    return structure_cv(search, physics)


def structure_cv(search: Search, physics) -> float:
    """[`cross_validated_rmse`][sk_offwhite.loop.cross_validated_rmse] of ``physics`` on the
    search's record."""
    return estimator_cv(search, search.estimator(physics, cv=True))


def estimator_cv(search: Search, est) -> float:
    """Mean held-out simulation RMSE of ``est`` (cloned for each fold) over the folds, the
    folds fitted by ``n_jobs`` processes."""
    u, z, window = search.u, search.z, search.settings.init_window
    splits = held_out_splits(search.settings, len(u))
    arguments = [(clone(est), u, z, train, test, window) for train, test in splits]
    return float(np.mean(gather(launch(_fold_rmse, arguments, *search.processes()))))


def _fold_rmse(est, u, z, train, test, init_window: int) -> float:
    """Held-out RMSE of ``test`` (one block) after fitting ``train`` (its gaps start new
    records); ``inf`` and a warning naming the error when the fit raises anything, as
    ``cross_validate`` scores a failed fold with ``error_score``."""
    try:
        est.fit(u[train], z[train], sample_index=train)
    except Exception as error:  # any failure of one fold ranks the model last
        warnings.warn(
            f"a fold's fit failed and scores inf: {type(error).__name__}: {error}",
            UserWarning,
            stacklevel=2,
        )
        return np.inf
    return -held_out_rmse(init_window)(est, u[test], z[test])
