"""Residual analysis: what a physics model's simulation gets wrong, and where.

Given measured outputs ``z``, a model's simulated outputs ``z_sim``, the inputs ``u`` and
the simulated states ``x_sim``, with the residual ``z - z_sim``:

- [`simulation_metrics`][sk_offwhite.diagnose.simulation_metrics]: RMSE, NRMSE, fit %, R² and
  largest error per output;
- [`whiteness_test`][sk_offwhite.diagnose.whiteness_test]: is the residual white (autocorrelation,
  Ljung-Box)?
- [`cross_correlation_test`][sk_offwhite.diagnose.cross_correlation_test]: is it independent of past
  inputs? ([`correlated_inputs`][sk_offwhite.diagnose.correlated_inputs]: the inputs it is not
  independent of; [`lagging_outputs`][sk_offwhite.diagnose.lagging_outputs]: the outputs whose
  residual runs against their simulated rate, a slow sensor?);
- [`residual_regions`][sk_offwhite.diagnose.residual_regions]: in which range of a state or input
  does it concentrate, with which sign?
- [`range_violations`][sk_offwhite.diagnose.range_violations]: measured ceilings/floors
  (saturations?) the model crosses;
- [`output_jumps`][sk_offwhite.diagnose.output_jumps]: one-sample jumps of a measured output,
  repeated at one level, that the model does not make (a discontinuous sensor?);
- [`analyse_residuals`][sk_offwhite.diagnose.analyse_residuals]: all of the above as a
  [`ResidualReport`][sk_offwhite.diagnose.ResidualReport] with ``summary()`` and ``to_dict()``.

Pure NumPy/SciPy; the inputs are never modified.
"""

from ._correlation import (
    CrossCorrelationResult,
    WhitenessResult,
    correlated_inputs,
    cross_correlation_test,
    lagging_outputs,
    whiteness_test,
)
from ._jumps import OutputJump, output_jumps
from ._metrics import simulation_metrics
from ._ranges import RangeViolation, range_violations
from ._regions import ResidualRegion, residual_regions
from ._report import ResidualReport, analyse_residuals

__all__ = [
    "CrossCorrelationResult",
    "OutputJump",
    "RangeViolation",
    "ResidualRegion",
    "ResidualReport",
    "WhitenessResult",
    "analyse_residuals",
    "correlated_inputs",
    "cross_correlation_test",
    "lagging_outputs",
    "output_jumps",
    "range_violations",
    "residual_regions",
    "simulation_metrics",
    "whiteness_test",
]
