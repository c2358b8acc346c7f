"""Residual analysis: metrics, correlation tests, residual regions, range facts, report."""

import json

import numpy as np
import pytest
from scipy.stats import chi2, norm

from sk_offwhite.diagnose import (
    analyse_residuals,
    cross_correlation_test,
    range_violations,
    residual_regions,
    simulation_metrics,
    whiteness_test,
)

N_SAMPLES = 1000


def _ar1(coefficient, n_samples, rng):
    shocks = rng.standard_normal(n_samples)
    series = np.zeros(n_samples)
    for k in range(1, n_samples):
        series[k] = coefficient * series[k - 1] + shocks[k]
    return series


# --- simulation metrics -------------------------------------------------------------------


def test_perfect_simulation_has_fit_100_and_zero_error():
    z = np.sin(np.arange(50.0))
    metrics = simulation_metrics(z, z.copy())["per_output"]["z1"]
    assert metrics["fit_percent"] == pytest.approx(100.0)
    assert metrics["r2"] == pytest.approx(1.0)
    assert metrics["rmse"] == metrics["nrmse"] == metrics["max_abs_error"] == 0.0


def test_metrics_match_hand_computation():
    # e = (0, 0, 0, -2): rmse 1, ||z - mean|| = sqrt(5), std(z) = sqrt(5 / 4)
    metrics = simulation_metrics([1.0, 2, 3, 4], [1.0, 2, 3, 6])["per_output"]["z1"]
    assert metrics["rmse"] == pytest.approx(1.0)
    assert metrics["nrmse"] == pytest.approx(1.0 / np.sqrt(1.25))
    assert metrics["fit_percent"] == pytest.approx(100.0 * (1.0 - 2.0 / np.sqrt(5.0)))
    assert metrics["r2"] == pytest.approx(0.2)
    assert metrics["max_abs_error"] == pytest.approx(2.0)
    assert metrics["n_scored"] == 4


def test_skip_excludes_the_first_samples():
    with_transient = simulation_metrics([100.0, 1, 2, 3, 4], [0.0, 1, 2, 3, 6], skip=1)
    without = simulation_metrics([1.0, 2, 3, 4], [1.0, 2, 3, 6])
    assert with_transient == without
    assert with_transient["overall"]["n_scored"] == 4


def test_overall_pools_rmse_and_averages_fit_over_named_outputs():
    z = np.array([[1.0, 10.0], [2.0, 20.0], [3.0, 30.0], [4.0, 40.0]])
    z_sim = z + np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0], [-2.0, 2.0]])
    metrics = simulation_metrics(z, z_sim, output_names=["a", "b"])
    assert set(metrics["per_output"]) == {"a", "b"}
    assert metrics["overall"]["rmse"] == pytest.approx(1.0)
    fits = [metrics["per_output"][name]["fit_percent"] for name in "ab"]
    assert metrics["overall"]["fit_percent"] == pytest.approx(np.mean(fits))


def test_constant_measurement_has_undefined_normalised_metrics():
    metrics = simulation_metrics(np.ones(10), np.zeros(10))["per_output"]["z1"]
    assert metrics["rmse"] == pytest.approx(1.0)
    assert np.isnan(metrics["nrmse"]) and np.isnan(metrics["fit_percent"])


# --- whiteness and cross-correlation ----------------------------------------------------


def test_whiteness_matches_hand_computed_autocorrelation_and_ljung_box():
    result = whiteness_test([1.0, -1.0, 1.0, -1.0], max_lag=2)
    np.testing.assert_allclose(result.autocorrelation, [1.0, -0.75, 0.5])
    q_statistic = 4 * 6 * (0.75**2 / 3 + 0.5**2 / 2)
    assert result.q_statistic == pytest.approx(q_statistic)
    assert result.p_value == pytest.approx(chi2.sf(q_statistic, 2))
    assert result.band == pytest.approx(norm.ppf(0.995) / 2.0)


def test_white_noise_passes_the_whiteness_test():
    result = whiteness_test(np.random.default_rng(0).standard_normal(N_SAMPLES))
    assert result.white
    assert result.p_value > 0.01
    assert result.fraction_outside <= 0.08
    np.testing.assert_array_equal(result.lags, np.arange(26))


def test_ar1_residual_fails_the_whiteness_test():
    result = whiteness_test(_ar1(0.8, N_SAMPLES, np.random.default_rng(1)))
    assert not result.white
    assert result.p_value < 1e-10
    assert result.autocorrelation[1] == pytest.approx(0.8, abs=0.06)
    assert result.fraction_outside > 0.3


def test_cross_correlation_lags_follow_the_documented_convention():
    rng = np.random.default_rng(2)
    residual, u = rng.standard_normal(30), rng.standard_normal(30)
    result = cross_correlation_test(residual, u, max_lag=4)
    e, v = residual - residual.mean(), u - u.mean()
    scale = np.sqrt((e @ e) * (v @ v))
    for lag, value in zip(result.lags, result.correlation[0], strict=True):
        direct = sum(e[k + lag] * v[k] for k in range(30) if 0 <= k + lag < 30)
        assert value == pytest.approx(direct / scale)


def test_residual_driven_by_a_lagged_input_fails_the_cross_correlation_test():
    rng = np.random.default_rng(3)
    u = rng.standard_normal((N_SAMPLES, 2))
    residual = 0.5 * np.roll(u[:, 0], 3) + 0.3 * rng.standard_normal(N_SAMPLES)
    result = cross_correlation_test(residual, u)
    assert not result.independent
    assert result.p_value[0] < 1e-10 and result.p_value[1] > 0.01
    assert result.lags[np.argmax(np.abs(result.correlation[0]))] == 3
    assert result.correlation.shape == (2, 51)


def test_white_residual_is_independent_of_a_coloured_input():
    rng = np.random.default_rng(4)
    u = _ar1(0.9, N_SAMPLES, rng)
    result = cross_correlation_test(rng.standard_normal(N_SAMPLES), u)
    assert result.independent
    assert result.band[0] >= norm.ppf(0.995) / np.sqrt(N_SAMPLES)


def test_coloured_residual_is_independent_of_a_coloured_input():
    # both AR(0.9): the white-noise band would flag them; the Bartlett factor widens it
    rng = np.random.default_rng(0)
    u, residual = _ar1(0.9, N_SAMPLES, rng), _ar1(0.9, N_SAMPLES, rng)
    result = cross_correlation_test(residual, u)
    assert result.independent
    assert result.band[0] > 2.0 * norm.ppf(0.995) / np.sqrt(N_SAMPLES)


def test_constant_input_column_is_not_tested():
    rng = np.random.default_rng(5)
    u = np.column_stack([np.ones(200), rng.standard_normal(200)])
    result = cross_correlation_test(rng.standard_normal(200), u, max_lag=5)
    assert np.all(np.isnan(result.correlation[0])) and np.isnan(result.p_value[0])
    assert np.all(np.isfinite(result.correlation[1]))
    assert result.independent


# --- residual regions ---------------------------------------------------------------------


def _threshold_case(sign):
    rng = np.random.default_rng(6)
    x1 = rng.uniform(0.0, 10.0, N_SAMPLES)
    other = rng.uniform(-1.0, 1.0, N_SAMPLES)
    residual = sign * np.where(x1 > 7.0, 0.4, 0.0) + 0.02 * rng.standard_normal(N_SAMPLES)
    return residual, {"other": other, "x1 (simulated)": x1}


def test_region_starts_at_the_threshold_and_names_variable_and_sign():
    residual, variables = _threshold_case(+1.0)
    regions = residual_regions(residual, variables)
    top = regions[0]
    assert top.variable == "x1 (simulated)"
    assert top.low == pytest.approx(7.0, abs=0.4) and top.high == np.inf
    assert top.error_share > 0.9 and top.sample_share == pytest.approx(0.3, abs=0.05)
    assert top.notable and top.p_value <= 0.05
    assert "large only when x1 (simulated) is above" in top.sentence
    assert "under-predicts" in top.sentence
    assert [region.variable for region in regions] == ["x1 (simulated)", "other"]
    assert not regions[1].notable


def test_negative_residual_means_the_model_over_predicts():
    residual, variables = _threshold_case(-1.0)
    top = residual_regions(residual, variables)[0]
    assert top.mean_inside < 0.0
    assert "over-predicts" in top.sentence


def test_bins_respect_min_count_with_tied_values():
    # 100 ties at 0.55 make quantile edges coincide; the bin left below them is merged
    rng = np.random.default_rng(7)
    tied = np.r_[rng.uniform(0.0, 1.0, 100), np.full(100, 0.55)]
    regions = residual_regions(rng.standard_normal(200), {"v": tied}, n_bins=8, min_count=25)
    (region,) = regions
    np.testing.assert_array_equal(region.bin_count, [25, 32, 118, 25])
    assert np.all(np.diff(region.bin_edges) > 0)


def test_zero_residual_or_constant_variable_gives_no_region():
    values = np.linspace(0.0, 1.0, 100)
    assert residual_regions(np.zeros(100), {"v": values}) == []
    assert residual_regions(np.sin(values), {"flat": np.ones(100)}) == []


# --- range facts -------------------------------------------------------------------------


def _saturated_case():
    model = 12.0 * np.sin(np.linspace(0.0, 20.0, N_SAMPLES))
    return np.clip(model, None, 10.0), model


def test_range_violations_report_a_ceiling_and_the_model_excursions():
    measured, model = _saturated_case()
    (fact,) = range_violations(measured, model, ["x2"])
    n_beyond = int(np.sum(model > 10.0 + 1e-6 * np.ptp(measured)))
    assert (fact.output, fact.side, fact.saturated) == ("x2", "upper", True)
    assert fact.measured_limit == 10.0
    assert fact.n_at_limit == int(np.sum(measured == 10.0))
    assert fact.n_model_beyond == n_beyond > 0
    assert fact.model_extreme == pytest.approx(model.max())
    assert "never exceeds 10 " in fact.sentence
    assert f"exceeds it in {n_beyond} samples" in fact.sentence


def test_floor_and_excursion_without_saturation_are_reported():
    measured, model = _saturated_case()
    facts = range_violations(-measured, -model)
    assert [(f.side, f.saturated) for f in facts] == [("lower", True)]
    assert "never goes below -10" in facts[0].sentence
    smooth = np.sin(np.linspace(0.0, 3.0, 200))  # minimum 0 at the start, matched
    (fact,) = range_violations(smooth, 1.1 * smooth)
    assert not fact.saturated and fact.n_model_beyond > 3
    assert fact.sentence.startswith("the model exceeds the measured maximum of z1")


def test_model_matching_a_saturated_measurement_stays_within_it():
    measured, _ = _saturated_case()
    (fact,) = range_violations(measured, measured)
    assert fact.saturated and fact.n_model_beyond == 0
    assert fact.sentence.endswith("the model stays within it")


def test_unsaturated_perfect_model_has_no_range_facts():
    smooth = np.sin(np.linspace(0.0, 6.0, 200))
    assert range_violations(smooth, smooth) == []


# --- report --------------------------------------------------------------------------------


def _report_data():
    rng = np.random.default_rng(8)
    x_sim = np.column_stack([rng.uniform(0.0, 10.0, N_SAMPLES), rng.uniform(-1, 1, N_SAMPLES)])
    u = rng.standard_normal(N_SAMPLES)
    saturated_measured, saturated_model = _saturated_case()
    z_sim = np.column_stack([saturated_model, x_sim[:, 0]])
    residual = np.where(x_sim[:, 0] > 7.0, 0.4, 0.0) + 0.02 * rng.standard_normal(N_SAMPLES)
    z = np.column_stack([saturated_measured, x_sim[:, 0] + residual])
    return z, z_sim, u, x_sim


def test_report_bundles_every_diagnostic_without_touching_inputs():
    data = _report_data()
    copies = [array.copy() for array in data]
    for array in data:
        array.setflags(write=False)
    report = analyse_residuals(
        *data,
        state_names=["h1", "h2"],
        input_names=["pump"],
        output_names=["y", "level"],
        skip=50,
    )
    for array, copy in zip(data, copies, strict=True):
        np.testing.assert_array_equal(array, copy)
    assert report.n_scored == N_SAMPLES - 50
    assert report.metrics["overall"]["n_scored"] == N_SAMPLES - 50
    assert report.regions["level"][0].variable in {"h1 (simulated)", "level (simulated)"}
    assert report.range_violations[0].output == "y"
    summary = report.summary()
    assert "the first 50 skipped" in summary
    assert "**level**: the residual is large only when h1 (simulated) is above" in summary
    assert "the measured y never exceeds 10" in summary
    assert "**y**: the residual is not white" in summary
    assert json.loads(json.dumps(report.to_dict(), allow_nan=False))["skip"] == 50


def test_report_handles_constant_residual_and_no_inputs():
    z = np.sin(np.linspace(0.0, 10.0, 300))
    report = analyse_residuals(z, z, None)
    assert report.whiteness["z1"] is None and report.cross_correlation["z1"] is None
    assert report.regions["z1"] == []
    assert "constant; correlation tests skipped" in report.summary()
    json.dumps(report.to_dict(), allow_nan=False)


# --- bad input -----------------------------------------------------------------------------

_Z = np.linspace(0.0, 1.0, 40)
_RESIDUAL = np.random.default_rng(9).standard_normal(40)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda: simulation_metrics(_Z, _Z[:-1]), ValueError, "z_sim must have the shape"),
        (lambda: simulation_metrics(np.r_[_Z[:-1], np.nan], _Z), ValueError, "z contains 1 NaN"),
        (lambda: simulation_metrics(_Z, np.r_[np.inf, _Z[1:]]), ValueError, "z_sim contains"),
        (lambda: simulation_metrics(np.zeros((4, 2, 2)), _Z), ValueError, "z must be 1-D or 2-D"),
        (lambda: simulation_metrics(["a"] * 40, _Z), ValueError, "z must be a numeric array"),
        (lambda: simulation_metrics(_Z, _Z, skip=39), ValueError, "skip must be in"),
        (lambda: simulation_metrics(_Z, _Z, skip=1.0), TypeError, "skip must be an integer"),
        (lambda: simulation_metrics(_Z, _Z, output_names="z"), TypeError, "output_names"),
        (lambda: simulation_metrics(_Z, _Z, output_names=["a", "b"]), ValueError, "output_name"),
        (lambda: whiteness_test(_RESIDUAL, max_lag=40), ValueError, "max_lag must be in"),
        (lambda: whiteness_test(_RESIDUAL, confidence=1.0), ValueError, "confidence"),
        (lambda: whiteness_test(np.ones(40)), ValueError, "residual is constant"),
        (lambda: whiteness_test(np.ones((40, 2))), ValueError, "residual must be one signal"),
        (lambda: cross_correlation_test(_RESIDUAL, _Z[:-1]), ValueError, "u has 39 samples"),
        (lambda: residual_regions(_RESIDUAL, {"x": _Z[:-1]}), ValueError, r"variables\['x'\]"),
        (lambda: residual_regions(_RESIDUAL, [_Z]), TypeError, "variables must be a mapping"),
        (lambda: residual_regions(_RESIDUAL, {"x": _Z}, n_bins=1), ValueError, "n_bins"),
        (lambda: range_violations(_Z, _Z, ["a", "b"]), ValueError, "names must have 1"),
        (lambda: analyse_residuals(_Z, _Z, _Z[:-1]), ValueError, "u has 39 samples but z"),
        (lambda: analyse_residuals(_Z, _Z, _Z, _Z[:5]), ValueError, "x_sim has 5 samples"),
        (
            lambda: analyse_residuals(_Z, _Z, _Z, input_names=["z1"]),
            ValueError,
            "names must all differ",
        ),
        (lambda: analyse_residuals(_Z, _Z, None, input_names=["p"]), ValueError, "u is None"),
        (lambda: analyse_residuals(_Z, _Z, _Z, skip=10, max_lag=30), ValueError, "max_lag"),
    ],
)
def test_bad_input_raises_an_error_naming_the_argument(call, error, match):
    with pytest.raises(error, match=match):
        call()
