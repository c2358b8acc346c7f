r"""Cross-validation folds of one sequence, and the ``sample_index`` they hand to ``fit``.

The rows of ``u`` and ``z`` are consecutive samples of one trajectory. A scikit-learn
search indexes them with each fold's training indices and calls ``fit`` on the selected
rows, which the estimator simulates as one record unless it also receives their
``sample_index``. [`SequenceSplit`][sk_offwhite.SequenceSplit] makes folds whose training rows are
one contiguous run by default, so no fit ever simulates through the hole left by a held-out block.
`check_sample_index` and `warn_if_fragmented` validate the ``sample_index``
that ``fit`` and ``score`` receive.
"""

from __future__ import annotations

import sys
import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.model_selection import BaseCrossValidator
from sklearn.utils._param_validation import (
    Interval,
    InvalidParameterError,
    StrOptions,
    validate_parameter_constraints,
)
from sklearn.utils.validation import _num_samples

__all__ = [
    "SequenceSplit",
    "SequenceWarning",
    "check_fold_rows",
    "check_sample_index",
    "warn_if_fragmented",
]

_MIN_RUN = 2  # rows a record needs to hold one transition


class SequenceWarning(UserWarning):
    """The rows of a fit or score are not whole sequences (shuffled or one-by-one folds)."""


class SequenceSplit(BaseCrossValidator):
    r"""Folds of contiguous blocks of one sequence, for cross-validating on time series.

    The ``n_samples`` rows are cut into consecutive blocks $B_j = [s_j, s_{j+1})$
    and each fold holds out one block as its test rows. The training rows of the fold
    that tests $B_j$, with $g$ = ``gap`` rows left out on each side of it, are

    - ``train="longer"`` (default): the longer of the runs $[0, s_j - g)$ and
      $[s_{j+1} + g, n)$ (the earlier one on a tie). Every block is tested once, as
      with ``KFold``, and every training set is **one contiguous run**, so the estimator
      fits it as one record without being told where the rows came from. Folds with an
      inner test block train on about half of the other rows.
    - ``train="rest"``: both runs, $[0, s_j - g) \cup [s_{j+1} + g, n)$ (with
      ``gap=0``, the folds of ``KFold(n_splits)``). An inner test block leaves a hole
      between the two runs: the estimator fits them as two records, with their own
      initial states, **only if it receives** ``sample_index`` (for example
      ``search.fit(u, z, sample_index=np.arange(len(u)))``, or with metadata routing
      ``set_fit_request(sample_index=True)``); without it the two runs are simulated as
      if the last row of the first were followed by the first row of the second.
    - ``train="forward"`` (forward chaining): the rows are cut into ``n_splits + 1``
      blocks, the last ``n_splits`` of ``n_samples // (n_splits + 1)`` rows each, and
      fold $j$ trains on $[0, s_j - g)$: the folds of
      ``TimeSeriesSplit(n_splits, gap=gap)``. The training rows are contiguous and
      always precede the test block, but the first block is never tested and the early
      folds train on little data. With ``test_size`` (a fraction of the rows, or a number
      of rows) the test blocks are the last ``n_splits`` blocks of that size instead, and
      ``n_splits=1`` holds out the record's tail: fitted on the past, run into the future.

    With ``"longer"`` and ``"rest"`` the first ``n_samples % n_splits`` blocks have one
    row more than the others, as in ``KFold``. The estimator's ``score`` estimates each
    test block's initial state from its first ``init_window`` rows, which it does not
    score.

    Parameters
    ----------
    n_splits : int, default=5
        Number of folds, at least 2.
    train : {"longer", "rest", "forward"}, default="longer"
        Which rows each fold trains on (see above).
    gap : int, default=0
        Rows left out of the training set on each side of the test block (the samples
        next to it, whose states are the most correlated with the test block's).
    test_size : float or int, default=None
        With ``train="forward"`` only: the size of each test block, a fraction of the rows
        in (0, 1) or a number of rows (``n_splits`` may then be 1).

    See Also
    --------
    sklearn.model_selection.TimeSeriesSplit : Forward chaining only (``train="forward"``),
        which never tests the first block; it also offers ``max_train_size`` and
        ``test_size``.
    sklearn.model_selection.KFold : Unshuffled, the folds of ``train="rest"``; with
        ``shuffle=True`` every fold is a scatter of rows with no dynamics left in it.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_offwhite import SequenceSplit
    >>> for train, test in SequenceSplit(3).split(np.zeros((9, 1))):
    ...     print(train, test)
    [3 4 5 6 7 8] [0 1 2]
    [0 1 2] [3 4 5]
    [0 1 2 3 4 5] [6 7 8]
    """

    _parameter_constraints: dict = {
        "n_splits": [Interval(Integral, 1, None, closed="left")],
        "train": [StrOptions({"longer", "rest", "forward"})],
        "gap": [Interval(Integral, 0, None, closed="left")],
        "test_size": [
            Interval(Real, 0, 1, closed="neither"),
            Interval(Integral, 1, None, closed="left"),
            None,
        ],
    }

    def __init__(
        self,
        n_splits: int = 5,
        *,
        train: str = "longer",
        gap: int = 0,
        test_size: float | int | None = None,
    ):
        params = {"n_splits": n_splits, "train": train, "gap": gap, "test_size": test_size}
        validate_parameter_constraints(self._parameter_constraints, params, type(self).__name__)
        _reject_booleans(params)
        _check_test_size(n_splits, train, test_size)
        self.n_splits = n_splits
        self.train = train
        self.gap = gap
        self.test_size = test_size

    def get_n_splits(self, X=None, y=None, groups=None) -> int:
        """Number of folds, ``n_splits`` (``X``, ``y`` and ``groups`` are ignored)."""
        return self.n_splits

    def split(self, X, y=None, groups=None):
        """Training and test row indices of each fold, in time order.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_inputs)
            Only its number of rows is used.
        y, groups : ignored
            Present for compatibility with scikit-learn's splitters.

        Yields
        ------
        train : ndarray of int
            Training rows of the fold, increasing.
        test : ndarray of int
            Its test block, increasing and contiguous.
        """
        for runs, test in self._folds(_num_samples(X)):
            train = np.concatenate([np.arange(start, stop) for start, stop in runs])
            yield train, np.arange(*test)

    def _folds(self, n_samples: int) -> list[tuple[list, tuple[int, int]]]:
        """``(training runs, test block)`` of every fold, as ``(start, stop)`` pairs."""
        if self.test_size is None:
            bounds = _block_bounds(n_samples, self.n_splits, self.train == "forward")
        else:
            bounds = _tail_bounds(n_samples, self.n_splits, self.test_size)
        tests = list(zip(bounds[:-1], bounds[1:], strict=True))
        tests = tests[1:] if self.train == "forward" else tests
        folds = [(self._training_runs(test, n_samples), test) for test in tests]
        for k, (runs, _) in enumerate(folds):
            self._check_runs(runs, k, n_samples)
        return folds

    def _training_runs(self, test: tuple[int, int], n_samples: int) -> list[tuple[int, int]]:
        before = (0, max(test[0] - self.gap, 0))
        after = (min(test[1] + self.gap, n_samples), n_samples)
        if self.train == "forward":
            return [before]
        if self.train == "rest":
            return [run for run in (before, after) if run[1] > run[0]]
        return [before if before[1] - before[0] >= after[1] - after[0] else after]

    def _check_runs(self, runs, fold: int, n_samples: int) -> None:
        lengths = [stop - start for start, stop in runs]
        if sum(lengths) == 0 or min(lengths) < _MIN_RUN:
            raise ValueError(
                f"{self!r} on {n_samples} samples leaves fold {fold} a training run of "
                f"{min(lengths, default=0)} row(s) (at least {_MIN_RUN} needed): use a "
                "smaller n_splits or gap, or more samples."
            )


def _check_test_size(n_splits: int, train: str, test_size) -> None:
    """``test_size`` belongs to forward chaining; without it there are two folds at least."""
    if test_size is not None and train != "forward":
        raise InvalidParameterError(
            f"The 'test_size' parameter of SequenceSplit needs train='forward', got {train!r}."
        )
    if test_size is None and n_splits < 2:
        raise InvalidParameterError(
            "The 'n_splits' parameter of SequenceSplit must be at least 2 (1 only with "
            f"train='forward' and a test_size), got {n_splits!r}."
        )


def _tail_bounds(n_samples: int, n_splits: int, test_size) -> np.ndarray:
    """Starts of the first training run (0) and of the last ``n_splits`` test blocks of
    ``test_size`` rows (a fraction of ``n_samples``, at least one row), and ``n_samples``."""
    size = test_size if isinstance(test_size, Integral) else round(test_size * n_samples)
    size = max(int(size), 1)
    first = n_samples - n_splits * size
    if first < _MIN_RUN:
        raise ValueError(
            f"test_size={test_size!r} x {n_splits} fold(s) leaves {max(first, 0)} of "
            f"{n_samples} samples to train on (at least {_MIN_RUN} needed)."
        )
    return np.concatenate([[0], first + size * np.arange(n_splits + 1)])


def _reject_booleans(params: dict) -> None:
    """``True`` passes as the integer 1; a count must not be a boolean."""
    for name in ("n_splits", "gap", "test_size"):
        if isinstance(params[name], bool | np.bool_):
            raise InvalidParameterError(
                f"The {name!r} parameter of SequenceSplit must be an int, got {params[name]!r}."
            )


def _block_bounds(n_samples: int, n_splits: int, forward: bool) -> np.ndarray:
    """Start of every block and ``n_samples``: ``KFold``'s blocks, or with ``forward``
    ``TimeSeriesSplit``'s (``n_splits + 1`` blocks, the first taking the remainder)."""
    n_blocks = n_splits + 1 if forward else n_splits
    if n_samples < _MIN_RUN * n_blocks:
        raise ValueError(
            f"n_splits={n_splits} cuts {n_samples} samples into {n_blocks} blocks, some of "
            f"fewer than {_MIN_RUN} rows: use a smaller n_splits or more samples."
        )
    if forward:
        size = n_samples // n_blocks
        sizes = [n_samples - n_splits * size] + [size] * n_splits
    else:
        sizes = [n_samples // n_blocks + (k < n_samples % n_blocks) for k in range(n_blocks)]
    return np.concatenate([[0], np.cumsum(sizes)])


def check_sample_index(sample_index) -> np.ndarray | None:
    """``sample_index`` as a 1-D integer array (``None`` stays ``None``).

    Raises
    ------
    ValueError
        If it holds anything but integers (integral floats are accepted): strings,
        booleans, dates, NaN or fractions.
    """
    if sample_index is None:
        return None
    index = np.asarray(sample_index).reshape(-1)
    if index.dtype.kind in "iu":
        return index
    values = _as_floats(index)
    if values is None or not np.all(np.isfinite(values)) or np.any(values != np.round(values)):
        shown = np.array2string(index, threshold=6)
        raise ValueError(
            "sample_index must hold the integer position of every row in the original "
            f"sequence (for example np.arange(n_samples)), got {shown} (dtype {index.dtype})."
        )
    return values.astype(np.int64)


def _as_floats(index: np.ndarray) -> np.ndarray | None:
    """Float values of a numeric or object array; ``None`` for booleans, text and dates."""
    if index.dtype.kind not in "fO":
        return None
    try:
        return index.astype(np.float64)
    except (TypeError, ValueError):
        return None


def warn_if_fragmented(records: list[tuple], stacklevel: int = 2) -> None:
    """Warn ([`SequenceWarning`][sk_offwhite.SequenceWarning]) when some records hold a single row.

    A record is a run of rows whose ``sample_index`` steps by one. A record of one row has
    no transition to fit or simulate; several of them are the mark of rows taken out of
    order or one by one, as shuffled folds take them.
    """
    lengths = np.array([len(u) for u, _ in records])
    single = int(np.sum(lengths < _MIN_RUN))
    if single == 0:
        return
    warnings.warn(
        f"sample_index breaks the rows into {len(lengths)} records, {single} of them a "
        "single row: every place where it does not step by +1 starts a new record with its "
        "own initial state. Shuffled folds (KFold(shuffle=True), ShuffleSplit) break the "
        "sequences this way; use sk_offwhite.SequenceSplit, or KFold without shuffle.",
        SequenceWarning,
        stacklevel=stacklevel + 1,
    )


_SEARCH_FRAMES = ("_fit_and_score", "_fit_and_predict")
"""scikit-learn's functions that fit one fold of a search or a cross-validation (their
``train`` and ``fit_params`` say which rows the estimator receives and with what)."""


def check_fold_rows(max_depth: int = 40) -> None:
    """Refuse a fit that is a fold of a scikit-learn search or cross-validation whose
    training rows are not one contiguous run and that receives no ``sample_index``: the
    estimator would simulate through the hole left by the held-out block, and the search
    would rank its models by that error. Read from the caller's frames, so it works for any
    splitter; outside such a fold it does nothing."""
    frame = sys._getframe(1)
    for _ in range(max_depth):
        if frame is None:
            return
        if frame.f_code.co_name in _SEARCH_FRAMES and "train" in frame.f_locals:
            _check_fold(frame.f_locals["train"], frame.f_locals.get("fit_params") or {})
            return
        frame = frame.f_back


def _check_fold(train, fit_params: dict) -> None:
    rows = np.asarray(train).reshape(-1)
    if "sample_index" in fit_params or rows.size < 2 or np.all(np.diff(rows) == 1):
        return
    runs = int(np.sum(np.diff(rows) != 1)) + 1
    raise ValueError(
        f"this cross-validation fold trains on {runs} separate runs of rows, but fit got no "
        "sample_index: the runs would be simulated as one record. Pass "
        "sample_index=np.arange(n_samples) to the search's fit (it is cut with the rows), or "
        "use sk_offwhite.SequenceSplit(n_splits), whose training rows are one run."
    )
