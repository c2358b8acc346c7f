"""The closed loop: from a poor physics-only fit to a named, added effect, before/after."""

import logging
import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from sk_offwhite import (
    Bias,
    DeadZone,
    DifferenceDeadZone,
    DivergenceWarning,
    Friction,
    GreyBoxSparseRegressor,
    InputSaturation,
    Leak,
    OutputOffset,
    OutputSaturation,
    Overflow,
    Parameter,
    PhysicsModel,
    QuadraticDrag,
    RunawayParameterWarning,
    VaryingParameter,
    augment,
)
from sk_offwhite.datasets import make_leaky_tank
from sk_offwhite.diagnose import range_violations
from sk_offwhite.loop import (
    Candidate,
    Hypothesis,
    LoopSettings,
    Term,
    _corrections,
    _fits,
    _selection,
    close_the_loop,
    held_out_rmse,
    held_out_splits,
    propose_effects,
    score_models,
    warm_physics,
    write_report,
)
from sk_offwhite.loop._candidates import DEAD_ZONE_START
from sk_offwhite.loop._fits import quick_fit as _quick_fit
from sk_offwhite.loop._hypotheses import _sign, feature_variables
from sk_offwhite.loop._progress import StageClock
from sk_offwhite.loop._proposals import capped as _capped
from sk_offwhite.loop._proposals import not_modelled
from sk_offwhite.loop._refinement import additions_and_exchanges, swap
from sk_offwhite.loop._report import _json_rows, _table
from sk_offwhite.loop._search import Search
from sk_offwhite.loop._selection import always_fitted, best_starts
from sk_offwhite.loop._sets import set_cv
from sk_offwhite.loop._switchboard import effect_sets
from sk_offwhite.loop._variants import mechanism, representatives
from sk_offwhite.model._kinds import Kinds


@pytest.fixture(scope="module")
def leaky():
    """The whole loop, every stage, on the leaky tank; the three best-ranked candidates
    fitted (the leak among them), the others marked in the trail."""
    data = make_leaky_tank(n_samples=600, random_state=0)
    settings = LoopSettings(
        gammas=(1e-3,), n_folds=2, max_iter=150, max_effects=1, max_candidates=3
    )
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    return data, result


def _validation_rmse(result, data, model):
    rows = score_models(result, {"validation": (data.u_val, data.z_val)})
    return next(r["rmse"] for r in rows if r["model"] == model and r["protocol"] == "init_window")


def test_loop_names_the_hidden_leak(leaky):
    data, result = leaky
    top = result.hypotheses[0]
    assert top.equation == "x" and top.sign == data.hidden_effect["sign"] == -1
    assert top.variables == ("x",)
    assert [effect.name for effect in result.effects] == ["leak_x"]
    assert isinstance(result.effects[0], Leak)


def test_adding_the_effect_cuts_validation_and_parameter_errors(leaky):
    data, result = leaky
    before = _validation_rmse(result, data, "declared physics")
    after = _validation_rmse(result, data, "augmented physics")
    assert after < 0.2 * before
    truth = data.true_parameters
    error_before = abs(result.baseline.parameters_["k"] - truth["k"])
    error_after = abs(result.final.parameters_["k"] - truth["k"])
    assert error_after < 0.1 * error_before
    np.testing.assert_allclose(result.final.parameters_["leak_x_rate"], 0.05, rtol=0.05)


def test_the_final_model_is_the_selections_fit_of_the_chosen_set(leaky):
    _, result = leaky
    selected = result.set_fits["leak_x"]
    assert result.final is selected  # a model of its own from the same start: not refitted
    assert result.cv_errors["final"] == dict(result.selection)["leak_x"]


def test_report_is_written_with_figures(leaky, tmp_path):
    data, result = leaky
    records = {"estimation": (data.u, data.z), "validation": (data.u_val, data.z_val)}
    rows = score_models(result, records)
    path = write_report(result, rows, records, tmp_path, title="Leaky tank")
    text = path.read_text()
    assert "leak_x" in text and "| declared physics | validation | init_window |" in text
    assert (tmp_path / "outputs_validation.png").stat().st_size > 1000
    assert (tmp_path / "correction.png").exists() and (tmp_path / "results.json").exists()
    assert "## Time per stage" in text and "| effect selection |" in text
    assert "## Correction of the output map on the augmented physics" in text


def test_results_json_holds_what_the_report_says(leaky, tmp_path):
    """Effects, parameters with standard errors and status, CV errors, the chosen model,
    failures, notes and warnings: results.json round-trips the report's facts."""
    import json

    data, result = leaky
    records = {"estimation": (data.u, data.z), "validation": (data.u_val, data.z_val)}
    text = write_report(result, score_models(result, records), records, tmp_path, title="t")
    facts = json.loads((tmp_path / "results.json").read_text())
    assert facts["chosen"] == result.chosen
    assert [e["name"] for e in facts["effects"]] == [e.name for e in result.effects]
    assert set(facts["parameters"]) == set(result.final.parameters_)
    for name, fact in facts["parameters"].items():
        assert fact["value"] == pytest.approx(float(result.final.parameters_[name]))
        assert fact["status"] in ("free", "fixed", "held", "at bound")
        assert f"| {name} | {fact['value']:.6g} |" in text.read_text()
    assert facts["cv_errors"]["final"] == pytest.approx(result.cv_errors["final"])
    assert facts["failures"] == result.failures and facts["notes"] == result.notes
    assert "## Warnings of the search's internal fits" in text.read_text()


def test_every_effect_set_of_the_trail_is_scored_on_validation(leaky, tmp_path):
    """Each structural step of the trail carries its fit on the estimation record, and the
    report scores it on the validation record next to its CV error."""
    data, result = leaky
    assert set(result.set_fits) == {name for name, _ in result.selection}
    records = {"estimation": (data.u, data.z), "validation": (data.u_val, data.z_val)}
    path = write_report(result, score_models(result, records), records, tmp_path, title="t")
    text = path.read_text()
    assert "| validation RMSE (init_window=50) |" in text
    leak = _validation_rmse(result, data, "augmented physics")
    row = next(line for line in text.splitlines() if line.startswith("| leak_x |"))
    assert float(row.split("|")[3]) == pytest.approx(leak, abs=5e-5)  # printed to 4 decimals


def test_every_stage_is_timed(leaky):
    _, result = leaky
    stages = ["declared physics", "evidence", "physics + sparse δ", "effect selection"]
    assert list(result.timings)[:4] == stages
    assert all(seconds > 0 for seconds in result.timings.values())


def test_stages_are_logged_as_they_run(caplog):
    clock = StageClock()
    with caplog.at_level(logging.INFO, logger="sk_offwhite.loop"):
        with clock.stage("fitting"):
            pass
        with clock.stage("fitting"):
            pass
    messages = [r.getMessage().split(":")[0] for r in caplog.records]
    assert messages == ["fitting ...", "fitting"] * 2
    assert set(clock.seconds) == {"fitting"} and clock.seconds["fitting"] >= 0


def test_feature_names_map_to_variables():
    names = ("x1", "x2", "u")
    assert feature_variables("x1 u", names) == ("x1", "u")
    assert feature_variables("x1^2", names) == ("x1",)
    assert feature_variables("1", names) == ()
    assert feature_variables("x12", names) == ()


def test_proposals_follow_the_sign_region_and_measured_ceiling():
    states = np.linspace(0.0, 10.0, 200)[:, None] * np.ones((1, 2))
    loss = Hypothesis("x1", 0, ("x1",), -1, ("x1", 8.0, np.inf), (), "x1 loses.")
    z = np.minimum(states[:, 1:], 9.0)
    facts = range_violations(z, states[:, 1:], ["x2"])
    proposals = propose_effects(
        [loss], facts, ("x1", "x2"), ["x2"], states, measured=(1,), outputs=states[:, 1:]
    )
    effects = [c.effect for c in proposals]
    corner = 0.025 * float(np.std(states[:, 0]))  # both states and the output alike
    assert Overflow(0, 8.0, sink=1, corner=corner, name="overflow_x1_to_x2") in effects
    assert Leak(0, name="leak_x1") in effects
    assert not any(isinstance(e, Friction) for e in effects)  # a level is not a velocity
    assert OutputSaturation(0, 9.0, corner=corner, name="saturation_x2") in effects
    assert Overflow(1, 9.0, corner=corner, name="overflow_x2") in effects
    assert not any(isinstance(e, OutputOffset) for e in effects)


def test_a_constant_term_on_a_measured_state_proposes_a_sensor_offset():
    states = np.linspace(0.0, 10.0, 200)[:, None] * np.ones((1, 2))
    bias = Term("x2", "1", 0.2, 0.2, 1.0, ())
    gain = Hypothesis("x2", 1, (), 1, None, (bias,), "x2 gains.")
    effects = [c.effect for c in propose_effects([gain], [], ("x1", "x2"), ["x2"], states, (1,))]
    assert OutputOffset(0, name="offset_x2") in effects
    level, corner = float(np.quantile(states[:, 0], 0.8)), 0.025 * float(np.std(states[:, 0]))
    overflow = Overflow(0, level, sink=1, corner=corner, name="overflow_x1_to_x2")
    assert overflow in effects


def test_an_input_term_proposes_an_actuator_saturation():
    u = np.linspace(-2.0, 2.0, 101)[:, None]
    hyp = Hypothesis("w", 0, ("u",), -1, None, (), "w lacks a term in u.")
    effects = [
        c.effect for c in propose_effects([hyp], [], ("w",), ["w"], u, u=u, input_names=("u",))
    ]
    assert InputSaturation(0, float(np.quantile(np.abs(u), 0.9)), name="actuator_u") in effects
    width = DEAD_ZONE_START * float(np.sqrt(np.mean(u**2)))  # next to the model without it
    assert DeadZone(0, width, name="dead_zone_u") in effects
    assert not any(isinstance(e, Overflow) for e in effects)  # w changes sign: not a level


def test_an_input_of_a_states_kind_proposes_a_threshold_on_their_difference():
    """A source voltage driving a capacitor's: a clearance and a diode on e - v, started at
    10 % of the RMS difference, whatever the hypotheses name (none here); not for a
    generic input or one of another kind, nor without the inputs."""
    t = np.linspace(0.0, 20.0, 300)
    u, states = 3.0 * np.sin(t)[:, None], (2.0 + np.sin(t - 0.5))[:, None]
    voltages = Kinds(("voltage",), ("voltage",), {})

    def proposed(kinds, inputs=u):
        found = propose_effects([], [], ("v",), ["v"], states, u=inputs, input_names=("e",),
                                kinds=kinds)  # fmt: skip
        return [c.effect for c in found if isinstance(c.effect, DifferenceDeadZone)]

    width = 0.1 * float(np.sqrt(np.mean((u - states) ** 2)))
    assert proposed(voltages) == [
        DifferenceDeadZone(0, 0, width, name="dead_zone_e_v"),
        DifferenceDeadZone(0, 0, width, one_sided=True, name="drop_e_v"),
    ]
    assert proposed(Kinds(("voltage",), ("generic",), {})) == []
    assert proposed(Kinds(("voltage",), ("current",), {})) == []
    assert proposed(voltages, inputs=None) == []


def test_every_level_may_overflow_whatever_the_hypotheses_say():
    # an overflow acts where the declared physics seldom takes the state, where the
    # linearised evidence is blind: each level's is proposed without a hypothesis
    levels = np.linspace(0.0, 10.0, 200)[:, None] * np.ones((1, 2))
    names = [c.effect.name for c in propose_effects([], [], ("x1", "x2"), ["x2"], levels)]
    assert names == ["overflow_x1_to_x2", "overflow_x2_to_x1"]  # fraction 0: out of it
    alone = propose_effects([], [], ("h",), ["h"], levels[:, :1])
    level, corner = float(np.quantile(levels[:, 0], 0.8)), 0.025 * float(np.std(levels[:, 0]))
    assert [c.effect for c in alone] == [Overflow(0, level, corner=corner, name="overflow_h")]
    swinging = np.sin(np.linspace(0.0, 20.0, 200))[:, None]
    assert propose_effects([], [], ("w",), ["w"], swinging) == []  # not a level


@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_hinge_corners_follow_the_units_of_the_data(scale):
    """An overflow's, a cap's and a sensor ceiling's corner are a fraction of the
    variable's spread, so levels in other units give the same effects in those units."""
    states = np.linspace(2.0, 10.0, 200)[:, None] * np.ones((1, 2))
    z = np.minimum(states[:, 1:], 9.0)

    def proposed(c):
        facts = range_violations(c * z, c * states[:, 1:], ["x2"])
        found = propose_effects([], facts, ("x1", "x2"), ["x2"], c * states, measured=(1,),
                                outputs=c * states[:, 1:])  # fmt: skip
        return {e.effect.name: e.effect for e in found if hasattr(e.effect, "corner")}

    volts, other = proposed(1.0), proposed(scale)
    assert sorted(volts) == sorted(other) and len(volts) == 4  # 3 overflows, 1 sensor ceiling
    for name, effect in volts.items():
        assert other[name].corner == pytest.approx(scale * effect.corner, rel=1e-12), name
        assert other[name].level == pytest.approx(scale * effect.level, rel=1e-12), name


def test_a_hinge_corner_must_be_positive():
    with pytest.raises(ValueError, match="corner must be a positive"):
        Overflow(0, 1.0, corner=0.0)
    with pytest.raises(ValueError, match="corner must be a positive"):
        OutputSaturation(0, 1.0, corner=float("nan"))


def test_candidates_are_unique_by_name():
    states = np.ones((10, 2))
    hyps = [
        Hypothesis("x1", 0, ("x1",), -1, None, (), "x1 loses."),
        Hypothesis("x2", 1, ("x1",), 1, None, (), "x2 gains."),
    ]
    names = [c.effect.name for c in propose_effects(hyps, [], ("x1", "x2"), ["x2"], states)]
    assert len(names) == len(set(names)) and "overflow_x1_to_x2" in names


def test_an_overflow_at_a_level_a_hypothesis_located_is_located():
    """A hypothesis that says where its state loses (its region on that state) places the
    overflow there and locates it; a region on another variable places and locates
    nothing, and of two proposals of one name the located one is kept."""
    states = np.linspace(1.0, 10.0, 200)[:, None] * np.ones((1, 2))
    names = ("x1", "x2")

    def overflows(region, hypotheses=()):
        losing = Hypothesis("x1", 0, ("x1",), -1, region, (), "x1 loses.")
        found = propose_effects([*hypotheses, losing], [], names, ["x2"], states)
        return {c.effect.name: c for c in found if isinstance(c.effect, Overflow)}

    here = overflows(("x1", 7.5, 10.0))["overflow_x1_to_x2"]
    assert here.located and here.effect.level == 7.5
    elsewhere = overflows(("u", 7.5, 10.0))["overflow_x1_to_x2"]
    assert not elsewhere.located
    assert elsewhere.effect.level == pytest.approx(float(np.quantile(states[:, 0], 0.8)))
    gaining = Hypothesis("x2", 1, ("x1",), 1, None, (), "x2 gains.")  # proposes it first
    kept = overflows(("x1", 7.5, 10.0), [gaining])["overflow_x1_to_x2"]
    assert kept.located and kept.effect.level == 7.5


def test_the_scan_fits_located_effects_laws_and_group_members_whatever_their_rank():
    overflow, bias = Overflow(0, 1.0, name="overflow_x"), Bias(0, name="bias_x")
    drag, law = QuadraticDrag(0, name="drag_x"), VaryingParameter("k", 0, "polynomial", 0.04)
    candidates = [
        Candidate(overflow, "located", located=True),
        Candidate(bias, "scanned"),
        Candidate(drag, "in a group"),
        Candidate(law, "read from the correction"),
    ]
    assert always_fitted(candidates, [((drag, bias), {})]) == {0, 1, 2, 3}
    assert always_fitted(candidates, []) == {0, 3}
    assert always_fitted(candidates[1:3], []) == set()


def test_max_candidates_caps_the_candidates_fitted(monkeypatch):
    fitted = []

    def rank_alone(search, candidates, models):
        fitted.extend(candidates)
        return []

    monkeypatch.setattr(_selection, "rank_alone", rank_alone)
    monkeypatch.setattr(_selection, "structure_cv", lambda *args: 1.0)
    physics = make_leaky_tank(n_samples=50, random_state=0).physics
    candidates = [Candidate(Leak(0, name=name), "a leak") for name in ("a", "b", "c")]
    search = Search(None, None, LoopSettings(max_candidates=2))
    effects, trail, _, warm, _ = _selection.select_effects(search, physics, candidates, 1.0)
    assert fitted == candidates[:2] and effects == () and warm == {}
    assert trail == [("declared physics", 1.0)]


def test_a_set_never_holds_two_variants_of_one_mechanism(monkeypatch):
    into_x1 = Overflow(1, 9.0, sink=0, name="overflow_x2_to_x1")
    out = Overflow(1, 9.0, name="overflow_x2")
    upper = Overflow(0, 5.0, sink=1, name="overflow_x1_to_x2")
    leak = Leak(0, name="leak_x1")
    assert mechanism(into_x1) == mechanism(out) != mechanism(upper) and mechanism(leak) == "leak_x1"
    # the variant with fewer parameters stands for its mechanism unless another is better
    # by more than the tolerance (2 %)
    ranked = [(0.5, SimpleNamespace(effect=into_x1), {}), (0.505, SimpleNamespace(effect=out), {})]
    ranked += [(0.6, SimpleNamespace(effect=upper), {}), (0.7, SimpleNamespace(effect=leak), {})]
    assert [c.effect for _, c, _ in representatives(ranked, 0.02)] == [out, upper, leak]
    clearly = [(0.4, *ranked[0][1:]), *ranked[1:]]
    assert representatives(clearly, 0.02)[0][1].effect == into_x1

    # every added effect lowers the error, a second variant most: without the rule
    # forward selection would take it
    def quick_fit(search, board, effects, warm):
        names = frozenset(e.name for e in effects)
        return 0.1 if {"overflow_x2_to_x1", "overflow_x2"} <= names else 1 / (1 + len(names)), {}

    monkeypatch.setattr(_selection, "quick_fit", quick_fit)
    settings = LoopSettings(max_effects=3, beam=3)
    steps = _selection.forward(Search(None, None, settings), None, ranked, 1.0)
    assert [[e.name for e in step[0]] for step in steps] == [
        ["overflow_x2"],
        ["overflow_x2", "overflow_x1_to_x2"],
        ["overflow_x2", "overflow_x1_to_x2", "leak_x1"],
    ]
    exchanges = additions_and_exchanges((out, upper), {}, ranked, 1.0, 1.0, settings)
    moves = [m[0] for m in exchanges]
    assert all(len({mechanism(e) for e in m}) == len(m) for m in moves)
    assert (out, upper, leak) in moves and (upper, leak) in moves


def test_settings_are_checked_and_passed_to_every_fit():
    with pytest.raises(ValueError, match="'max_candidates' parameter of LoopSettings"):
        LoopSettings(max_candidates=0)
    with pytest.raises(ValueError, match="'lm_scaling' parameter of LoopSettings"):
        LoopSettings(lm_scaling="minpack")
    settings = LoopSettings(lm_scaling="global")
    assert Search(None, None, settings).estimator(None).lm_scaling == "global"


@pytest.mark.parametrize("one_standard_error", [False, True])
def test_the_delta_path_uses_the_settings_rule_for_gamma(monkeypatch, one_standard_error):
    seen = {}

    def path(est, u, z, gammas=None, **kwargs):
        seen.update(kwargs)
        return SimpleNamespace(estimator=est)

    monkeypatch.setattr(_corrections, "fit_gamma_path", path)
    settings = LoopSettings(one_standard_error=one_standard_error)
    search = Search(np.zeros((300, 1)), np.zeros((300, 1)), settings)
    _corrections.fit_delta(search, None, None)
    assert seen["one_standard_error"] is one_standard_error
    assert seen["n_gammas"] == settings.n_gammas and len(seen["cv"]) == settings.n_folds


@pytest.mark.slow
def test_shared_programs_find_the_same_leak():
    data = make_leaky_tank(n_samples=400, random_state=1)
    settings = LoopSettings(
        gammas=(1e-3,), n_folds=2, max_iter=100, max_effects=1, max_candidates=4,
        fit_delta=False, share_programs=True,
    )  # fmt: skip
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    assert [effect.name for effect in result.effects] == ["leak_x"]
    assert "leak_x_on" not in result.final.parameters_  # the final model is the plain one
    np.testing.assert_allclose(result.final.parameters_["leak_x_rate"], 0.05, rtol=0.1)


def test_held_out_splits_are_folds_or_the_tail():
    folds = held_out_splits(LoopSettings(n_folds=3), 300)
    assert [list(test[[0, -1]]) for _, test in folds] == [[0, 99], [100, 199], [200, 299]]
    ((train, test),) = held_out_splits(LoopSettings(selection="tail"), 400)
    np.testing.assert_array_equal(train, np.arange(300))
    np.testing.assert_array_equal(test, np.arange(300, 400))


@pytest.mark.parametrize(
    "kwargs, match",
    [({"selection": "holdout"}, "selection"), ({"tail_fraction": 1.0}, "tail_fraction")],
)
def test_selection_settings_are_checked(kwargs, match):
    with pytest.raises(ValueError, match=match):
        LoopSettings(**kwargs)


def test_a_tail_no_longer_than_the_init_window_is_refused():
    with pytest.raises(ValueError, match="init_window"):
        held_out_splits(LoopSettings(selection="tail", init_window=50), 160)


@pytest.mark.slow
def test_the_tail_score_finds_the_leak():
    """Selection by the held-out last quarter of the record: the leak is added, and every
    CV figure of the trail is that single held-out block's RMSE."""
    data = make_leaky_tank(n_samples=400, random_state=1)
    settings = LoopSettings(
        gammas=(1e-3,), max_iter=100, max_effects=1, max_candidates=4, fit_delta=False,
        selection="tail",
    )  # fmt: skip
    result = close_the_loop(data.physics, data.suggested_library, data.u, data.z, settings=settings)
    assert [effect.name for effect in result.effects] == ["leak_x"]
    declared = GreyBoxSparseRegressor(
        warm_physics(data.physics, result.baseline), max_iter=100, init_window=50
    ).fit(data.u[:300], data.z[:300])
    tail = -held_out_rmse(50)(declared, data.u[300:], data.z[300:])
    assert result.selection[0][1] == pytest.approx(tail, rel=1e-6)
    assert result.selection[-1][1] < 0.5 * tail


def test_stepwise_drops_an_effect_that_adds_nothing():
    """A chosen set carrying a redundant effect (an output offset on a record without one)
    is refined to the smaller set whose CV error is within ``tolerance``, and the trail
    gets the row of the set it tried. The removal that leaves the offset alone misses the
    whole record by more than that bar, and is not cross-validated."""
    data = make_leaky_tank(n_samples=400, random_state=1)
    settings = LoopSettings(n_folds=2, max_iter=100, fit_delta=False)
    effects = (Leak(0, name="leak_x"), OutputOffset(0, name="offset_x"))
    board = effect_sets(data.physics, effects, shared=False)
    search, fits = Search(data.u, data.z, settings), {}
    cv, _ = set_cv(search, board, effects, {})
    kept, params, rows = swap(search, board, [], (effects, {}, cv), fits)
    assert [e.name for e in kept] == ["leak_x"] and search.failures == []
    assert [label for label, _ in rows] == ["leak_x"]
    assert dict(rows)["leak_x"] <= (1 + settings.tolerance) * cv
    offset_alone = _quick_fit(search, board, effects[1:], {})
    assert offset_alone[0] > (1 + settings.tolerance) * cv
    assert "offset_x_offset" not in params


def test_the_loop_on_a_physics_that_has_the_effect_adds_nothing():
    """The leak the loop finds on the leaky tank (``test_loop_names_the_hidden_leak``)
    already in the physics: the loop adds nothing, the null case of every discovery."""
    data = make_leaky_tank(n_samples=400, random_state=1)
    complete = augment(data.physics, Leak(0, name="leak_x"))
    settings = LoopSettings(n_folds=2, max_iter=100, max_candidates=4, fit_delta=False)
    result = close_the_loop(complete, data.suggested_library, data.u, data.z, settings=settings)
    assert result.effects == () and result.failures == [] and result.chosen == "baseline"


def test_no_candidate_repeats_a_mechanism_the_physics_models():
    """An augmented physics (the loop's own result, say) holding a hard limit of the input:
    the loop proposes neither that limit again, whose parameter would clash with its own
    (a failed fit before), nor a soft saturation of the same input."""
    physics = augment(
        make_leaky_tank(n_samples=50).physics,
        InputSaturation(0, 3.0, shape="clip", name="actuator_limit_u"),
    )
    proposed = [
        InputSaturation(0, 3.0, shape="clip", name="actuator_limit_u"),
        InputSaturation(0, 3.0, name="actuator_u"),
        Leak(0, name="leak_x"),
    ]
    kept = not_modelled(physics, [Candidate(e, "proposed") for e in proposed])
    assert [c.effect.name for c in kept] == ["leak_x"]


def test_a_ranking_fit_keeps_a_runaway_level_to_itself(monkeypatch):
    """A proposed effect the record never exercises runs its level off: the ranking fit
    scores the set as it is and raises no RunawayParameterWarning (the declared physics'
    fit and the final model's do)."""
    data = make_leaky_tank(n_samples=300, random_state=0)
    settings = LoopSettings(n_jobs=1, max_iter=50)
    effect = Leak(0, name="leak_x")
    board = effect_sets(data.physics, (effect,), shared=False)
    fit_set = _fits.fit_set

    def fit_set_whose_level_runs_away(*args):
        message = "Parameter 'leak_x_rate' ran from 1 to 1e9"
        warnings.warn(message, RunawayParameterWarning, stacklevel=2)
        return fit_set(*args)

    monkeypatch.setattr(_fits, "fit_set", fit_set_whose_level_runs_away)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RunawayParameterWarning)
        rmse, fitted = _quick_fit(Search(data.u, data.z, settings), board, (effect,), {})
    assert np.isfinite(rmse) and "leak_x_rate" in fitted


def _growing_model():
    """A fitted model of ``x[k+1] = a x[k] + u[k]`` with ``a`` near 2: finite on its 30
    samples, overflowing after about 1030 steps."""

    def step(x, u, theta):
        return theta["a"] * x + u

    physics = PhysicsModel(step, [0], {"a": Parameter(1.5)}, 1, 1, x0=[1.0], x0_fixed=True)
    u = np.zeros((30, 1))
    z = 2.0 ** np.arange(30.0)[:, None]
    return GreyBoxSparseRegressor(physics).fit(u, z)


def test_a_diverging_simulation_is_scored_and_reported_not_raised():
    est = _growing_model()
    models = dict(baseline=est, with_delta=None, final=est, final_with_delta=None)
    result = SimpleNamespace(**models)
    short_record = (np.zeros((30, 1)), 2.0 ** np.arange(30.0))
    records = {"short": short_record, "long": (np.zeros((1100, 1)), np.ones(1100))}
    with pytest.warns(DivergenceWarning, match="not finite from sample"):
        rows = score_models(result, records, init_window=10)
    short = [r for r in rows if r["record"] == "short"]
    long = [r for r in rows if r["record"] == "long"]
    assert all(r["diverged_at"] is None and np.isfinite(r["rmse"]) for r in short)
    assert all(r["rmse"] == np.inf and r["fit_percent"] == -np.inf for r in long)
    assert all(1000 < r["diverged_at"] < 1100 for r in long)
    table = "\n".join(_table(rows))
    assert f"| long | original | diverged from sample {long[0]['diverged_at']} |" in table
    assert all(r["rmse"] is None for r in _json_rows(long))
    assert all(isinstance(r["rmse"], float) for r in _json_rows(short))


def test_a_set_reached_from_two_starts_keeps_the_better_fit(monkeypatch):
    """Forward selection and the nested sets can reach one effect set from different
    starts: the set is fitted from each and keeps the lowest estimation RMSE; a set
    reached from one start (or the same start twice) is not fitted again."""
    leak, bias = Leak(0, rate=0.1, name="leak_x"), Bias(0, name="bias_x")
    fits = {0.1: (0.5, {"leak_x_rate": 0.1}), 0.3: (0.2, {"leak_x_rate": 0.05})}
    asked = []

    def best_of(search, board, sets):
        asked.extend(sets)
        return [min((fits[s["leak_x_rate"]] for s in starts), key=lambda f: f[0])
                for _, starts in sets]  # fmt: skip

    monkeypatch.setattr(_selection, "best_of", best_of)
    steps = [
        ((leak,), {"leak_x_rate": 0.1}, 0.5),
        ((bias, leak), {"leak_x_rate": 0.2, "bias_x_value": 1.0}, 0.4),
        ((leak,), {"leak_x_rate": 0.3}, None),
        ((leak, bias), {"leak_x_rate": 0.2, "bias_x_value": 1.0}, None),
    ]
    merged = best_starts(Search(None, None, LoopSettings()), None, steps)
    assert [len(starts) for _, starts in asked] == [2]  # only the set with two starts
    assert merged[0] == ((leak,), {"leak_x_rate": 0.05}, 0.2)  # the better start's fit
    assert merged[1:] == steps[1:]


def test_the_candidate_cap_counts_mechanisms_with_all_their_variants():
    """``max_candidates`` caps mechanisms: a saturation's two shapes or an overflow's two
    destinations take one place, so adding a variant pushes no other effect out."""
    effects = [
        Overflow(1, 9.0, 0, name="overflow_x2_to_x1"),
        InputSaturation(0, 4.0, name="actuator_u"),
        InputSaturation(0, 4.0, shape="clip", name="actuator_limit_u"),
        Leak(1, name="leak_x2"),
        Overflow(1, 9.0, name="overflow_x2"),  # a variant proposed later
        Overflow(0, 12.0, 1, name="overflow_x1_to_x2"),
    ]
    candidates = [Candidate(effect, "why") for effect in effects]
    names = [c.effect.name for c in _capped(candidates, 3)]
    assert names == ["overflow_x2_to_x1", "actuator_u", "actuator_limit_u", "leak_x2",
                     "overflow_x2"]  # fmt: skip
    assert [c.effect.name for c in _capped(candidates, 1)] == ["overflow_x2_to_x1", "overflow_x2"]
    assert _capped(candidates, None) == candidates


def test_a_hypothesis_takes_the_sign_where_its_correction_agrees_most_on_it():
    state = np.linspace(1.0, 2.0, 10)
    signals = {"s": np.arange(10.0)}
    region = ("s", 0.0, 3.0)  # the first four samples
    agreeing = np.array([-1.0, -1.0, -1.0, -1.0, 1, 1, 1, 1, 1, 1])
    assert _sign(agreeing, state, signals, region) == -1  # the region's, not the record's
    cancelling = np.array([-1.0, 1.0, -1.0, 0.8, 1, 1, 1, 1, 1, 1])  # region net < 0
    assert _sign(cancelling, state, signals, region) == 1  # the record agrees more
    assert _sign(-cancelling, state, signals, None) == -1
    assert _sign(np.zeros(10), state, signals, region) == 1
