"""Fits in worker processes: the same numbers as in one process, warnings and failures shown."""

import math
import sys
import warnings

import numpy as np
import pysindy as ps
import pytest

from sk_offwhite import GreyBoxSparseRegressor, fit_gamma_path
from sk_offwhite.datasets import make_leaky_tank
from sk_offwhite.effects import Bias, Leak
from sk_offwhite.loop import LoopSettings, _cv, _sets, close_the_loop
from sk_offwhite.loop._cv import _fold_rmse
from sk_offwhite.loop._search import Search
from sk_offwhite.loop._selection import board_search
from sk_offwhite.loop._switchboard import effect_sets
from sk_offwhite.runtime._parallel import gather, launch, start_workers


@pytest.mark.parametrize("n_jobs", [None, 2])
def test_tasks_come_back_in_order_with_their_warnings_and_progress(n_jobs):
    arguments = [(f"careful {k}",) for k in range(4)]
    seen = []
    with pytest.warns(UserWarning) as caught:
        values = gather(
            launch(warnings.warn, arguments, n_jobs),
            labels=list("abcd"),
            progress=lambda k, label: seen.append((k, label)),
        )
    assert values == [None] * 4
    assert [str(w.message) for w in caught] == [f"{x}: careful {k}" for k, x in enumerate("abcd")]
    assert seen == [(1, "a"), (2, "b"), (3, "c"), (4, "d")]


def test_started_workers_import_the_module_and_answer_in_order():
    """Whether the next tasks find them is joblib's reusable executor (measured in
    docs/benchmarks.md); here, that they start, import and report back."""
    assert start_workers(None) == [] and start_workers(1) == []
    module = "wave"  # imported by nothing else here
    assert gather(start_workers(2, module=module)) == [module, module]
    assert module not in sys.modules
    with pytest.raises(ModuleNotFoundError):
        gather(start_workers(2, module="sk_offwhite_no_such_module"))


def test_a_failing_call_in_a_worker_is_a_line_of_the_failures_and_the_others_go_on():
    search = Search(None, None, LoopSettings(n_jobs=2))
    calls = [("root of 4", math.sqrt, 4.0), ("root of -1", math.sqrt, -1.0)]
    values = search.attempt_all(calls)
    assert values == [2.0, None]
    assert search.failures == ["root of -1: math domain error"]


def test_calls_split_between_this_process_and_workers_come_back_in_order(caplog):
    search = Search(None, None, LoopSettings(n_jobs=2))
    roots = [4.0, 9.0, -1.0, 16.0, 25.0]
    calls = [(f"root of {x:g}", math.sqrt, x) for x in roots]
    here = [True, False, False, True, False]
    with caplog.at_level("INFO", logger="sk_offwhite.loop"):
        values = search.attempt_split(calls, here)
    assert values == [2.0, 3.0, None, 4.0, 5.0]
    assert search.failures == ["root of -1: math domain error"]
    counted = [message.rsplit("(", 1)[1] for message in caplog.messages]
    assert counted == [f"{k} of 5)" for k in range(1, 6)]


@pytest.mark.parametrize("in_worker", [False, True])
def test_a_worker_drops_the_package_programs_after_a_task_when_asked(monkeypatch, in_worker):
    from sk_offwhite.runtime import _parallel

    released = []
    monkeypatch.setattr(_parallel, "release_package_programs", lambda: released.append(1))
    monkeypatch.setattr(
        _parallel.multiprocessing, "parent_process", lambda: object() if in_worker else None
    )
    for release_after in (False, True):
        assert _parallel._recording(math.sqrt, release_after, 4.0) == (2.0, [])
    assert len(released) == int(in_worker)  # only in a worker, only when asked


@pytest.fixture(scope="module")
def tank():
    return make_leaky_tank(n_samples=300, random_state=1)


def test_the_path_with_worker_folds_is_the_path_in_one_process(tank):
    def path(n_jobs):
        est = GreyBoxSparseRegressor(tank.physics, ps.PolynomialLibrary(degree=2), max_iter=40)
        return fit_gamma_path(est, tank.u, tank.z, n_gammas=3, cv=2, n_jobs=n_jobs)

    one, two = path(None), path(2)
    np.testing.assert_array_equal(one.cv_error, two.cv_error)
    np.testing.assert_array_equal(one.cv_rmse, two.cv_rmse)
    np.testing.assert_array_equal(one.coefs, two.coefs)
    assert one.best_index == two.best_index


@pytest.mark.slow
def test_the_loop_with_workers_chooses_and_scores_as_in_one_process(tank):
    def loop(n_jobs, share_programs):
        settings = LoopSettings(
            n_folds=2, max_iter=40, max_effects=1, max_candidates=4, fit_delta=False,
            n_jobs=n_jobs, share_programs=share_programs,
        )  # fmt: skip
        return close_the_loop(tank.physics, None, tank.u, tank.z, settings=settings)

    one, two = loop(None, False), loop(2, False)
    assert [e.name for e in one.effects] == [e.name for e in two.effects]
    assert one.selection == two.selection and one.single_fits == two.single_fits
    assert one.cv_errors == two.cv_errors and one.failures == two.failures
    # the effect sets on one switchboard: the same up to rounding
    board = loop(None, True)
    assert [e.name for e in board.effects] == [e.name for e in one.effects]
    assert [label for label, _ in board.selection] == [label for label, _ in one.selection]
    scores = [[score for _, score in result.selection] for result in (board, one)]
    np.testing.assert_allclose(*scores, rtol=1e-6)  # fits stopped at max_iter=40


def test_the_sets_on_a_switchboard_and_their_folds_are_fitted_in_this_process(tank, monkeypatch):
    """Every worker would trace and compile the board's programs again for itself."""
    asked = []

    def spying(module):
        real = module.launch

        def launch(function, arguments, n_jobs=None, release_after=False):
            asked.append(n_jobs)
            return real(function, arguments, n_jobs, release_after)

        monkeypatch.setattr(module, "launch", launch)

    for module in (_sets, _cv):
        spying(module)
    settings = LoopSettings(n_folds=2, max_iter=5, n_jobs=2)
    steps = [((Leak(0), Bias(0)), {}, None)]
    shared, separate = (effect_sets(tank.physics, [Leak(0), Bias(0)], s) for s in (True, False))
    search = Search(tank.u, tank.z, settings)
    view = board_search(search, shared)
    assert board_search(search, separate) is search
    assert view.failures is search.failures and view.notes is search.notes
    here = _sets.sets_cv(view, shared, steps)
    assert asked and set(asked) == {None}  # the sets and their folds, here
    alone = _sets.sets_cv(Search(tank.u, tank.z, settings.replace(n_jobs=None)), shared, steps)
    assert [row[:2] for row in here] == [row[:2] for row in alone]


class _Broken:
    def fit(self, u, z, sample_index=None):
        raise RuntimeError("the solver ran out of memory")


def test_a_fold_that_fails_with_any_error_scores_inf_and_says_why():
    u, z = np.zeros((20, 1)), np.zeros((20, 1))
    with pytest.warns(UserWarning, match="RuntimeError: the solver ran out of memory"):
        score = _fold_rmse(_Broken(), u, z, np.arange(10), np.arange(10, 20), 2)
    assert score == np.inf
