"""The closed-loop report in the units given to it, and its refusals of bad arguments.

The result is assembled from one short physics-only fit (no loop run): the report only
reads the result's fields.
"""

import dataclasses
import json

import numpy as np
import pysindy as ps
import pytest

from sk_offwhite import GreyBoxSparseRegressor, Leak, augment
from sk_offwhite.datasets import make_leaky_tank
from sk_offwhite.effects import DictionaryTerm
from sk_offwhite.loop import score_models, write_report
from sk_offwhite.loop._report import _Units
from sk_offwhite.loop._result import LoopResult

UNITS = {"u": "m3/s", "x": "m"}


@pytest.fixture(scope="module")
def report_inputs():
    data = make_leaky_tank(n_samples=200, random_state=0)
    est = GreyBoxSparseRegressor(data.physics, max_iter=20).fit(data.u, data.z)
    result = LoopResult(
        physics=data.physics,
        augmented_physics=data.physics,
        baseline=est,
        with_delta=None,
        final=est,
        final_with_delta=None,
        gamma_path=None,
        hypotheses=[],
        range_facts=[],
        candidates=[],
        selection=[("declared physics", 0.1)],
        set_fits={"declared physics": est},
        cv_errors={"baseline": 0.1, "final": 0.1},
        chosen="final",
    )
    records = {"estimation": (data.u, data.z), "validation": (data.u_val, data.z_val)}
    return result, score_models(result, records), records


@pytest.fixture(scope="module")
def written(report_inputs, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    result, rows, records = report_inputs
    path = write_report(
        result, rows, records, out, title="Leaky tank", units=UNITS, sampling_time=2.0
    )
    return path.read_text(), json.loads((out / "results.json").read_text())


def test_rmse_headers_name_the_output_unit(written):
    text, _ = written
    assert "| model | record | protocol | RMSE [m] | fit % |" in text
    assert "| model | cross-validated RMSE [m] (estimation record) |" in text
    assert "validation RMSE [m] (init_window=50) |" in text


def test_units_are_stated_once_with_states_and_parameters_in_the_physics_units(written):
    text, _ = written
    assert "Units: `u` in m3/s, `x` in m; time in s (sampling time 2 s)." in text
    assert text.count("States and fitted parameters are in the units of the declared") == 1
    assert "Values in the units of the declared physics; output `x` in m." in text
    assert "Effects added (parameters in the units of the declared physics; output `x` in m)" in (
        text
    )


def test_results_json_holds_the_units_and_sampling_time(written):
    _, facts = written
    assert facts["units"] == UNITS and facts["sampling_time"] == 2.0


def test_the_trail_is_scored_with_the_rows_init_window(report_inputs, tmp_path):
    """Each cross-validated set is scored on the other records as the rows are: with the
    ``init_window`` given to `score_models`; results.json holds those scores."""
    result, _, records = report_inputs
    rows = score_models(result, records, init_window=5)
    text = write_report(result, rows, records, tmp_path, title="t").read_text()
    facts = json.loads((tmp_path / "results.json").read_text())
    expected = next(
        r["rmse"]
        for r in rows
        if (r["model"], r["record"], r["protocol"]) == ("augmented physics", "validation",
                                                         "init_window")
    )  # fmt: skip
    scored = facts["set_scores"]["declared physics"]["validation"]
    assert scored["rmse"] == pytest.approx(expected) and scored["diverged_at"] is None
    assert "validation RMSE (init_window=5) |" in text
    row = next(line for line in text.splitlines() if line.startswith("| declared physics | 0.1"))
    assert float(row.split("|")[3]) == pytest.approx(expected, abs=5e-5)
    assert {r["init_window"] for r in rows} == {None, 5}
    default = score_models(result, {"validation": records["validation"]})
    assert all(r["rmse"] != pytest.approx(expected) for r in default if r["init_window"] == 50)


def test_without_units_the_report_says_so_and_headers_are_bare(report_inputs, tmp_path):
    result, rows, records = report_inputs
    text = write_report(result, rows, {"estimation": records["estimation"]}, tmp_path, title="t")
    text = text.read_text()
    assert "| RMSE | fit % |" in text and "time in samples" in text
    facts = json.loads((tmp_path / "results.json").read_text())
    assert facts["units"] == {} and facts["sampling_time"] is None


def test_the_time_axis_is_in_seconds_with_a_sampling_time():
    with_time, without = _Units({"x": "m"}, 0.5), _Units()
    assert with_time.time_label == "time [s]" and without.time_label == "sample"
    np.testing.assert_allclose(with_time.times(3), [0.0, 0.5, 1.0])
    np.testing.assert_allclose(without.times(3), [0.0, 1.0, 2.0])
    assert with_time.label("x") == "x [m]" and with_time.label("residual", "x") == "residual [m]"
    assert without.label("x") == "x"


def test_an_rmse_unit_needs_one_unit_for_every_output():
    assert _Units({"a": "V", "b": "V"}).rmse(["a", "b"]) == " [V]"
    assert _Units({"a": "V", "b": "A"}).rmse(["a", "b"]) == ""
    assert _Units({"a": "V"}).rmse(["a", "b"]) == ""


@pytest.mark.parametrize(
    ("records", "error", "match"),
    [
        (
            lambda r: {"validation": r["validation"]},
            ValueError,
            "records must hold an 'estimation'",
        ),
        (lambda r: [r["estimation"]], TypeError, "records must be a non-empty dict"),
        (lambda r: {"estimation": r["estimation"][0]}, ValueError, r"records\['estimation'\]"),
    ],
)
def test_records_without_an_estimation_pair_are_refused(
    report_inputs, tmp_path, records, error, match
):
    result, rows, good = report_inputs
    with pytest.raises(error, match=match):
        write_report(result, rows, records(good), tmp_path, title="t")
    assert not list(tmp_path.iterdir())  # refused before anything is written


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"sampling_time": 0.0}, ValueError, "sampling_time must be finite and > 0"),
        ({"sampling_time": float("nan")}, ValueError, "sampling_time"),
        ({"sampling_time": "4"}, TypeError, "sampling_time must be a number"),
        ({"sampling_time": True}, TypeError, "sampling_time"),
        ({"units": ["V"]}, TypeError, "units must be a dict"),
        ({"units": {"y": "V"}}, ValueError, r"units names \['y'\]"),
        ({"units": {"x": 1}}, TypeError, "units must map each name to a non-empty string"),
    ],
)
def test_bad_units_and_sampling_time_are_refused(report_inputs, tmp_path, kwargs, error, match):
    result, rows, records = report_inputs
    with pytest.raises(error, match=match):
        write_report(result, rows, records, tmp_path, title="t", **kwargs)
    assert not list(tmp_path.iterdir())


def test_an_added_dictionary_term_is_reported_as_a_stand_in(report_inputs, tmp_path):
    """A promoted term names no law: the report says so; a named effect is not flagged."""
    result, _, records = report_inputs
    term = DictionaryTerm(0, ps.PolynomialLibrary(degree=2), ["x", "u"], 3, name="term_x_x_2")
    effects = (Leak(0, name="leak_x"), term)
    u, z = records["estimation"]
    final = GreyBoxSparseRegressor(augment(result.physics, *effects), max_iter=5).fit(u, z)
    added = dataclasses.replace(result, final=final, effects=effects)
    text = write_report(added, [], {"estimation": records["estimation"]}, tmp_path, title="t")
    lines = [line for line in text.read_text().splitlines() if line.startswith("- `")]
    term_line = next(line for line in lines if line.startswith("- `term_x_x_2`"))
    leak_line = next(line for line in lines if line.startswith("- `leak_x`"))
    assert "names no physical law (a stand-in" in term_line
    assert "stand-in" not in leak_line and not leak_line.endswith("; ")


def test_other_estimators_are_scored_as_the_loops_models_and_reported(report_inputs, tmp_path):
    """A model of the user's own (here the declared fit itself, under another label) gets the
    rows of the loop's models, to the last digit, and the report's table shows them."""
    result, rows, records = report_inputs
    scored = score_models(result, records, others={"reference law": result.baseline})
    assert scored[: len(rows)] == rows
    declared = [{**r, "model": "reference law"} for r in rows if r["model"] == "declared physics"]
    assert scored[len(rows) :] == declared
    path = write_report(result, scored, records, tmp_path, title="Leaky tank")
    assert "| reference law | validation | init_window |" in path.read_text()


@pytest.mark.parametrize(
    "others, error, message",
    [
        ([("reference law", None)], TypeError, "others must map labels"),
        ({"declared physics": None}, ValueError, "'declared physics' is not a new label"),
        ({"reference law": GreyBoxSparseRegressor()}, TypeError, "must be a fitted"),
    ],
)
def test_score_models_refuses_bad_others(report_inputs, others, error, message):
    result, _, records = report_inputs
    with pytest.raises(error, match=message):
        score_models(result, records, others=others)
