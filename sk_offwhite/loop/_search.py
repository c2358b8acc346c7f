"""What every stage of the loop works with: the estimation record, the settings and the
failures so far, on one object.

A stage takes a `Search` and returns what it found; a fit that fails becomes a line of
``search.failures`` and the loop goes on. Fits that run in worker processes receive a
`Search.detached` copy (the record and the settings, no failures) and return their own
failures.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from .._estimator import GreyBoxSparseRegressor
from ..runtime._cache import release_package_programs
from ..runtime._parallel import gather, launch
from ._progress import StageClock, logger
from ._settings import LoopSettings

__all__ = ["FIT_ERRORS", "Search"]

FIT_ERRORS = (ValueError, TypeError, FloatingPointError, np.linalg.LinAlgError)
"""What a failing fit raises: `Search.attempt` turns these into lines of the report."""


def _trying(function, *args):
    """``(function(*args), None)``, or ``(None, message)`` when it raises a fit error."""
    try:
        return function(*args), None
    except FIT_ERRORS as error:
        return None, str(error)


@dataclass
class Search:
    """The estimation record ``(u, z)``, the loop's settings, and the failures and notes
    so far."""

    u: np.ndarray
    z: np.ndarray
    settings: LoopSettings
    failures: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    clock: StageClock = field(default_factory=StageClock, repr=False)

    def detached(self) -> Search:
        """A copy for a worker process: the record and the settings, one process, nothing
        released (the caller releases per task), failures of its own."""
        return Search(self.u, self.z, self._one_process())

    def here(self) -> Search:
        """A view of this search whose fits all run in this process, nothing released
        between them (the stage releases at its end); failures and notes are this
        search's. For fits that share compiled programs (a switchboard's): each worker
        would trace and compile them again for itself."""
        return dataclasses.replace(self, settings=self._one_process())

    def _one_process(self) -> LoopSettings:
        """The settings of fits that all run in one process, nothing released."""
        return self.settings.replace(n_jobs=None, release_programs=False)

    def estimator(self, physics, *, cv: bool = False, **params) -> GreyBoxSparseRegressor:
        """An estimator of ``physics`` with the loop's fit settings (its ``cv_horizon`` for
        the fits inside cross-validation)."""
        settings = self.settings
        return GreyBoxSparseRegressor(
            physics,
            horizon=settings.cv_horizon if cv else settings.horizon,
            max_iter=settings.max_iter,
            init_window=settings.init_window,
            lm_scaling=settings.lm_scaling,
            **params,
        )

    def processes(self) -> tuple:
        """``(n_jobs, release_after)`` of `launch`."""
        return self.settings.n_jobs, self.settings.release_programs

    def released(self, value):
        """``value``, once the package's compiled programs are dropped (with
        ``release_programs``): what a phase of the loop fitted is done with."""
        if self.settings.release_programs:
            release_package_programs()
        return value

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """A stage of the loop: logged and timed, its programs released at its end."""
        with self.clock.stage(name):
            yield
        self.released(None)

    def attempt(self, label: str, function, *args):
        """``function(*args)``; a failure becomes a line of ``failures`` (and ``None``), and
        warnings are re-issued prefixed with ``label``."""
        return self.attempt_all([(label, function, *args)], parallel=False)[0]

    def attempt_all(self, calls, parallel: bool = True, first: int = 1, total=None) -> list:
        """`attempt` of each ``(label, function, *args)`` of ``calls``, run by ``n_jobs``
        processes (this one when not ``parallel``); the values in order (``None`` where a
        call failed). Each value is logged as it arrives when there are several, as the
        ``first``-th, ... of ``total`` (default: of ``calls``)."""
        if not calls:
            return []  # no worker started for nothing
        labels = [call[0] for call in calls]
        total = len(calls) if total is None else total

        def progress(k, label):
            logger.info("  %s (%d of %d)", label, first + k - 1, total)

        processes = self.processes() if parallel else (None, False)
        jobs = launch(_trying, [call[1:] for call in calls], *processes)
        outcomes = gather(jobs, labels, progress if total > 1 else None)
        for label, (_, error) in zip(labels, outcomes, strict=True):
            if error is not None:
                self.failures.append(f"{label}: {error}")
        return [value for value, _ in outcomes]

    def attempt_split(self, calls, here) -> list:
        """`attempt_all` of ``calls``, those where ``here`` is true in this process and the
        others by ``n_jobs`` processes; values in the order of ``calls``."""
        local = [call for call, flag in zip(calls, here, strict=True) if flag]
        remote = [call for call, flag in zip(calls, here, strict=True) if not flag]
        total = len(calls)
        mine = iter(self.attempt_all(local, parallel=False, total=total))
        theirs = iter(self.attempt_all(remote, first=len(local) + 1, total=total))
        return [next(mine) if flag else next(theirs) for flag in here]
