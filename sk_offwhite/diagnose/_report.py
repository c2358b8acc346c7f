"""One report bundling every residual diagnostic of a simulated model.

The residual is ``z - z_sim`` (measured minus simulated) over the scored samples. For each
output the report holds the simulation metrics, the whiteness and input cross-correlation
tests, and the ranges of the simulated states, the inputs and the simulated outputs in which
the residual concentrates; for all outputs, the measured ceilings/floors the model crosses.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ._arrays import (
    as_columns,
    check_confidence,
    check_integer,
    check_rows,
    column_names,
    is_constant,
)
from ._correlation import (
    CrossCorrelationResult,
    WhitenessResult,
    cross_correlation_test,
    whiteness_test,
)
from ._metrics import scored_pair, simulation_metrics
from ._ranges import RangeViolation, range_violations
from ._regions import ResidualRegion, residual_regions

__all__ = ["ResidualReport", "analyse_residuals"]


@dataclass(frozen=True)
class ResidualReport:
    """Every residual diagnostic of one simulation; build it with
    [`analyse_residuals`][sk_offwhite.diagnose.analyse_residuals].

    Attributes
    ----------
    output_names, input_names, state_names : tuple of str
    skip, n_scored : int
        Leading samples left out, and samples scored.
    confidence : float
        Confidence level of the correlation tests.
    metrics : dict
        [`simulation_metrics`][sk_offwhite.diagnose.simulation_metrics] of the scored samples.
    whiteness : dict of str to WhitenessResult or None
        Per output; None when its residual is constant.
    cross_correlation : dict of str to CrossCorrelationResult or None
        Per output; None when its residual is constant or there are no inputs.
    regions : dict of str to list of ResidualRegion
        Per output, most concentrated first.
    range_violations : list of RangeViolation
    """

    output_names: tuple[str, ...]
    input_names: tuple[str, ...]
    state_names: tuple[str, ...]
    skip: int
    n_scored: int
    confidence: float
    metrics: dict
    whiteness: dict[str, WhitenessResult | None]
    cross_correlation: dict[str, CrossCorrelationResult | None]
    regions: dict[str, list[ResidualRegion]]
    range_violations: list[RangeViolation]

    def summary(self, max_regions: int = 3) -> str:
        """The findings as Markdown lines: a heading, then one bullet per finding.

        Per output: the metrics, the whiteness verdict, the input correlations, and up to
        ``max_regions`` notable regions; then the range facts.
        """
        lines = [_heading(self)]
        for name in self.output_names:
            lines.append(_metrics_line(name, self.metrics["per_output"][name]))
            lines.extend(_correlation_lines(self, name))
            lines.extend(_region_lines(name, self.regions[name], max_regions))
        lines.extend(f"- {fact.sentence}" for fact in self.range_violations)
        return "\n".join(lines)

    def to_dict(self) -> dict:
        """JSON-serialisable copy: arrays become lists, NaN and infinities become None."""
        return _jsonable(self)


def analyse_residuals(
    z,
    z_sim,
    u=None,
    x_sim=None,
    *,
    state_names: Sequence[str] | None = None,
    input_names: Sequence[str] | None = None,
    output_names: Sequence[str] | None = None,
    skip: int = 0,
    max_lag: int = 25,
    confidence: float = 0.99,
    n_bins: int = 10,
) -> ResidualReport:
    """Run every residual diagnostic on a model's simulation.

    Parameters
    ----------
    z, z_sim : arrays of shape (n_samples, n_outputs) or (n_samples,)
        Measured and simulated outputs.
    u : array of shape (n_samples, n_inputs) or (n_samples,), optional
        Inputs; None for an autonomous system (no cross-correlation test).
    x_sim : array of shape (n_samples, n_states) or (n_samples,), optional
        Simulated states.
    state_names, input_names, output_names : sequence of str, optional
        Column names; default ``x1, ...``, ``u1, ...``, ``z1, ...``. All must differ.
    skip : int, default 0
        Leading samples left out of every diagnostic (e.g. 50 used for the initial state).
    max_lag : int, default 25
        Largest lag of the correlation tests.
    confidence : float, default 0.99
        Confidence level of the correlation tests.
    n_bins : int, default 10
        Quantile bins per variable for the residual regions.

    Returns
    -------
    ResidualReport
    """
    measured, simulated = scored_pair(z, z_sim, skip)
    n_samples, n_scored = measured.shape[0] + skip, measured.shape[0]
    outputs = column_names(output_names, measured.shape[1], "output_names", "z")
    inputs, inputs_named = _named_columns(u, "u", input_names, "input_names", n_samples)
    states, states_named = _named_columns(x_sim, "x_sim", state_names, "state_names", n_samples)
    _check_distinct(outputs, inputs_named, states_named)
    confidence = check_confidence(confidence)
    max_lag = check_integer(max_lag, "max_lag", 1, n_scored - 1, "lags within the scored samples")
    inputs, states, residual = inputs[skip:], states[skip:], measured - simulated
    variables = {
        **_simulated(states_named, states),
        **dict(zip(inputs_named, inputs.T, strict=True)),
        **_simulated(outputs, simulated),
    }
    tests = {
        name: _output_tests(residual[:, j], inputs, max_lag, confidence)
        for j, name in enumerate(outputs)
    }
    return ResidualReport(
        output_names=outputs,
        input_names=inputs_named,
        state_names=states_named,
        skip=int(skip),
        n_scored=int(n_scored),
        confidence=float(confidence),
        metrics=simulation_metrics(measured, simulated, output_names=outputs),
        whiteness={name: whiteness for name, (whiteness, _) in tests.items()},
        cross_correlation={name: cross for name, (_, cross) in tests.items()},
        regions={
            name: residual_regions(residual[:, j], variables, n_bins)
            for j, name in enumerate(outputs)
        },
        range_violations=range_violations(measured, simulated, outputs),
    )


def _named_columns(values, argument, names, names_argument, n_samples):
    """Validated optional columns and their names; no columns when ``values`` is None."""
    if values is None:
        if names:
            raise ValueError(f"{names_argument} is given but {argument} is None.")
        return np.empty((n_samples, 0)), ()
    columns = as_columns(values, argument)
    check_rows(argument, columns, n_samples, "z")
    prefix = argument.removesuffix("_sim")
    return columns, column_names(names, columns.shape[1], names_argument, prefix)


def _simulated(names: tuple[str, ...], columns: np.ndarray) -> dict[str, np.ndarray]:
    """Simulated columns keyed ``"<name> (simulated)"``."""
    return {f"{name} (simulated)": column for name, column in zip(names, columns.T, strict=True)}


def _check_distinct(*name_groups: tuple[str, ...]) -> None:
    names = [name for group in name_groups for name in group]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise ValueError(f"output, input and state names must all differ; repeated: {repeated}.")


def _output_tests(residual, inputs, max_lag, confidence):
    """Whiteness and cross-correlation results for one output (None where undefined)."""
    if is_constant(residual):
        return None, None
    whiteness = whiteness_test(residual, max_lag, confidence)
    if inputs.shape[1] == 0:
        return whiteness, None
    return whiteness, cross_correlation_test(residual, inputs, max_lag, confidence)


def _heading(report: ResidualReport) -> str:
    skipped = f", the first {report.skip} skipped" if report.skip else ""
    return (
        f"### Residual analysis ({report.n_scored} samples scored{skipped}; "
        "residual = measured - simulated)"
    )


def _metrics_line(name: str, metrics: dict) -> str:
    return (
        f"- **{name}**: fit {metrics['fit_percent']:.1f}%, RMSE {metrics['rmse']:.3g}, "
        f"NRMSE {metrics['nrmse']:.3g}, R² {metrics['r2']:.3f}, "
        f"max |error| {metrics['max_abs_error']:.3g}"
    )


def _p(p_value: float) -> str:
    return "p < 1e-16" if p_value < 1e-16 else f"p = {p_value:.2g}"


def _correlation_lines(report: ResidualReport, name: str) -> list[str]:
    whiteness = report.whiteness[name]
    if whiteness is None:
        return [f"- **{name}**: the residual is constant; correlation tests skipped"]
    lines = [f"- **{name}**: {_whiteness_phrase(whiteness)}"]
    cross = report.cross_correlation[name]
    if cross is not None:
        lines.extend(f"- **{name}**: {phrase}" for phrase in _cross_phrases(cross, report))
    return lines


def _whiteness_phrase(result: WhitenessResult) -> str:
    test = f"Ljung-Box Q = {result.q_statistic:.3g} over lags 1-{result.lags[-1]}, "
    test += _p(result.p_value)
    if result.white:
        return f"the residual is white ({test})"
    return (
        f"the residual is not white ({test}; {result.fraction_outside:.0%} of the lags "
        f"outside the {result.confidence:.0%} band): unmodelled dynamics or coloured noise"
    )


def _cross_phrases(result: CrossCorrelationResult, report: ResidualReport) -> list[str]:
    alpha = 1.0 - result.confidence
    phrases = [
        _correlated_phrase(result, j, input_name)
        for j, input_name in enumerate(report.input_names)
        if result.p_value[j] < alpha
    ]
    if phrases:
        return phrases
    tested = result.p_value[np.isfinite(result.p_value)]
    smallest = f" (smallest {_p(float(tested.min()))})" if tested.size else ""
    return [f"the residual is independent of the inputs{smallest}"]


def _correlated_phrase(result: CrossCorrelationResult, j: int, input_name: str) -> str:
    peak = int(np.argmax(np.abs(result.correlation[j])))
    lag = int(result.lags[peak])
    timing = {1: "the input leading", 0: "no delay", -1: "the residual leading: feedback?"}
    return (
        f"the residual is correlated with {input_name} (peak r = "
        f"{result.correlation[j, peak]:+.2f} at lag {lag:+d}, {timing[int(np.sign(lag))]}; "
        f"{_p(float(result.p_value[j]))}): part of its effect is missing from the model"
    )


def _region_lines(name: str, regions: list[ResidualRegion], max_regions: int) -> list[str]:
    notable = [region for region in regions if region.notable][:max_regions]
    if notable:
        return [f"- **{name}**: {region.sentence}" for region in notable]
    if not regions:
        return []
    return [f"- **{name}**: no range of any variable concentrates the residual"]


def _jsonable(value):
    """``value`` with dataclasses as dicts, arrays as lists and non-finite floats as None."""
    if dataclasses.is_dataclass(value):
        return {f.name: _jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(key): _jsonable(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(item) for item in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
