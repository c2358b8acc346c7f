"""The bad-input audit (``benchmarks/audit_bad_inputs.py``) classifies what it measures right.

Toy cases whose outcome is known by construction go through the script's own ``execute`` and
``classify``; two real cases of its table run in this process and one in a worker process.
"""

import importlib.util
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "audit_bad_inputs.py"


@pytest.fixture(scope="module")
def audit():
    spec = importlib.util.spec_from_file_location("audit_bad_inputs", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


def _toy(audit, run, **kwargs):
    kwargs.setdefault("names", ("gamma",))
    return audit.audit_cases.Case("toy", "toy", "a toy", run, **kwargs)


def _verdict(audit, case, limit=5.0):
    outcome = audit.execute(case, None, limit)
    return audit.classify(case, outcome)


def _raise(error):
    def run(ctx):
        raise error

    return run


def test_a_value_error_naming_the_argument_is_clear(audit):
    case = _toy(audit, _raise(ValueError("gamma must be >= 0, got -1.")))
    assert _verdict(audit, case).outcome == "clear"


def test_errors_that_do_not_name_it_or_are_of_another_type_are_obscure(audit):
    unnamed = _toy(audit, _raise(ValueError("could not convert string to float: 'abc'")))
    key = _toy(audit, _raise(KeyError("gamma")))
    attribute = _toy(audit, _raise(AttributeError("'dict' object has no attribute 'gamma'")))
    assert [_verdict(audit, c).subclass for c in (unnamed, key, attribute)] == [
        "unnamed",
        "type",
        "type",
    ]
    assert {_verdict(audit, c).outcome for c in (unnamed, key, attribute)} == {"obscure"}


def test_an_error_raised_inside_numpy_is_obscure_even_if_it_names_the_word(audit):
    case = _toy(audit, lambda ctx: np.linalg.inv(np.zeros((2, 2))), names=("matrix",))
    verdict = _verdict(audit, case)
    assert (verdict.outcome, verdict.subclass) == ("obscure", "deep")


def test_a_deliberately_silent_function_is_silent(audit):
    def finite(value, ctx):
        return bool(np.isfinite(value)), f"value {value}"

    case = _toy(audit, lambda ctx: math.nan, check=finite)
    verdict = _verdict(audit, case)
    assert (verdict.outcome, verdict.subclass) == ("silent", "accepted")
    refusal_expected = _toy(audit, lambda ctx: 1.0)  # no check: it should have refused
    assert _verdict(audit, refusal_expected).outcome == "silent"


def test_a_warning_that_names_the_problem_makes_it_clear(audit):
    def warns(ctx):
        warnings.warn("sample_index breaks the rows into 300 records", UserWarning, stacklevel=1)
        return math.nan

    def unrelated(ctx):
        warnings.warn("The fit did not converge", UserWarning, stacklevel=1)
        return math.nan

    failing = dict(check=lambda value, ctx: (False, "wrong"), names=("sample_index",))
    assert _verdict(audit, _toy(audit, warns, **failing)).subclass == "warned"
    assert _verdict(audit, _toy(audit, unrelated, **failing)).outcome == "silent"


def test_right_results_are_correct_or_harmless(audit):
    right = dict(check=lambda value, ctx: (value == 2, "two"))
    assert _verdict(audit, _toy(audit, lambda ctx: 2, **right)).outcome == "correct"
    harmless = _toy(audit, lambda ctx: 2, accept_class="harmless", **right)
    assert _verdict(audit, harmless).outcome == "harmless"
    assert _verdict(audit, _toy(audit, lambda ctx: 3, **right)).outcome == "silent"


def test_a_refusal_after_fitting_started_is_late(audit):
    def late(ctx):
        audit.WATCH.started = True  # as the watched fitting core does
        raise ValueError("gamma must be >= 0")

    assert _verdict(audit, _toy(audit, late)).subclass == "late"
    assert _verdict(audit, _toy(audit, late, early=False)).outcome == "clear"


def test_time_limits_make_hangs_and_slow_accepts(audit):
    def sleep(ctx):
        time.sleep(3.0)

    started = time.perf_counter()
    assert _verdict(audit, _toy(audit, sleep), limit=0.3).outcome == "hang"
    slow = _verdict(audit, _toy(audit, sleep, on_timeout="silent"), limit=0.3)
    assert (slow.outcome, slow.subclass) == ("silent", "slow-accept")
    assert time.perf_counter() - started < 2.0


def test_a_dead_worker_is_a_crash(audit):
    outcome = audit.Outcome(crashed=True, returncode=-11)
    assert audit.classify(_toy(audit, None), outcome).outcome == "crash"


def test_names_are_matched_as_words(audit):
    assert audit.names_any(["u"], "Input u contains NaN.")
    assert not audit.names_any(["u"], "the input is wrong")
    assert not audit.names_any(["x0"], "x0_fixed must be a bool")
    assert audit.names_any(["diverg"], "The simulation diverged", prefix=True)


def test_the_table_is_large_and_reviewable(audit):
    cases = audit.audit_cases.build_cases()
    assert len(cases) >= 320
    assert len({case.id for case in cases}) == len(cases)
    assert all(case.what and case.expected for case in cases)
    assert all(case.check is not None or case.names for case in cases)


def test_real_cases_of_the_table(audit):
    cases = {case.id: case for case in audit.audit_cases.build_cases()}
    context = audit.audit_cases.Context()
    audit.WATCH.install()
    try:
        rows = [
            audit.run_in_process(cases[i], context, 60.0, 6.0)
            for i in ("fit.gamma.negative", "fit.z.1d", "Parameter.bounds.reversed")
        ]
    finally:
        audit.WATCH.uninstall()
    assert [row["outcome"] for row in rows] == ["clear", "correct", "clear"]
    assert rows[0]["exception"] == "InvalidParameterError" and not rows[0]["fit_started"]


def test_a_case_runs_in_a_worker_process(audit):
    cases = [c for c in audit.audit_cases.build_cases() if c.id == "fit.lam.negative"]
    (row,) = audit.run_cases(cases, jobs=1, limit=60.0, loop_limit=6.0)
    assert row["outcome"] == "clear" and "lam" in row["message"]


def test_the_classes_being_added_get_cases_once_they_exist(audit, monkeypatch):
    import sk_offwhite
    import sk_offwhite.loop

    class FakeRegressorCV:
        def __init__(self, physics=None, library=None, gammas=None, n_gammas=8, cv=None):
            pass

    class FakeSearch:
        def __init__(self, estimator, cv=None, n_jobs=None, settings=None):
            pass

    monkeypatch.setattr(sk_offwhite, "GreyBoxSparseRegressorCV", FakeRegressorCV, raising=False)
    monkeypatch.setattr(sk_offwhite.loop, "EffectSearchCV", FakeSearch, raising=False)
    ids = [case.id for case in audit.audit_cases.new_class_cases()]
    assert {"regressor-cv.n_gammas.zero", "effect-search.cv.str", "effect-search.u.nan"} <= set(ids)
    assert not any(i.startswith(("regressor-cv.eps", "effect-search.beam")) for i in ids)
