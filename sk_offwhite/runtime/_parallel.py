"""Independent fits in worker processes, their warnings shown in the caller.

A joblib worker (the ``loky`` backend) does not show the warnings its task raises; the
helpers here record them in the task and issue them again, in order, in the process that
collects the results. With one job nothing leaves the process and the tasks run at once,
in order, exactly as a loop would run them.
"""

from __future__ import annotations

import importlib
import multiprocessing
import warnings
from collections.abc import Callable, Iterable

from joblib import Parallel, delayed, effective_n_jobs

from ._cache import release_package_programs

__all__ = ["gather", "launch", "start_workers"]


def _recording(function: Callable, release_after: bool, *args):
    """``function(*args)`` and the warnings it raised, as ``(message, category)`` pairs;
    with ``release_after``, a worker process then drops the package's compiled programs."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = function(*args)
    if release_after and multiprocessing.parent_process() is not None:
        release_package_programs()
    return value, [(str(w.message), w.category) for w in caught]


def launch(
    function: Callable, arguments: Iterable[tuple], n_jobs: int | None, release_after: bool = False
):
    """``function(*args)`` for each tuple of ``arguments``: computed now (one job), or
    started now in ``n_jobs`` worker processes (joblib's convention: ``-1`` all cores),
    whose results arrive while the caller goes on. Pass the result to `gather`.

    With ``release_after``, each worker drops the package's compiled programs
    ([`release_package_programs`][sk_offwhite.release_package_programs]) after each task: workers
    are reused, and tasks whose structures are not fitted again would otherwise pile theirs up."""
    tasks = (delayed(_recording)(function, release_after, *args) for args in arguments)
    if effective_n_jobs(n_jobs) == 1:
        return [task(*args, **kwargs) for task, args, kwargs in tasks]
    return Parallel(n_jobs=n_jobs, return_as="generator")(tasks)


def gather(jobs, labels=None, progress: Callable | None = None) -> list:
    """The values of `launch`'s tasks, in order, each task's warnings issued again
    here (prefixed with ``"{label}: "`` when ``labels`` names the tasks); ``progress(k,
    label)`` is called as the ``k``-th value (from 1) arrives."""
    values = []
    for k, (value, caught) in enumerate(jobs):
        label = None if labels is None else labels[k]
        for message, category in caught:
            warnings.warn(f"{label}: {message}" if label else message, category, stacklevel=3)
        values.append(value)
        if progress is not None:
            progress(k + 1, label)
    return values


def _ready(module: str) -> str:
    """Import ``module`` (in a worker: what its first task would otherwise wait for)."""
    importlib.import_module(module)
    return module


def start_workers(n_jobs: int | None, module: str = "sk_offwhite.loop"):
    """Start the ``n_jobs`` worker processes of `launch` now, each importing
    ``module``, and return at once: the caller goes on with its own work while they start
    (about 2 s each on a small machine, most of it importing JAX and scikit-learn). Pass
    the result to `gather` before the first `launch` that should find them
    ready. With one job there is nothing to start (an empty list)."""
    workers = effective_n_jobs(n_jobs)
    if workers == 1:
        return []
    return launch(_ready, [(module,)] * workers, n_jobs)
