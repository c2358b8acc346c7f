"""pysindy baselines fitted and scored under sk_offwhite's protocol (free-run simulation).

[`DelaySINDyRegressor`][sk_offwhite.baselines.DelaySINDyRegressor] is pysindy's ``DiscreteSINDy``
(STLSQ or SR3) on a delay embedding of the measured outputs and inputs, with an optional
physics-informed square-root library, behind the ``fit(u, z)`` / ``predict(u)`` / ``score(u, z)``
contract of [`GreyBoxSparseRegressor`][sk_offwhite.GreyBoxSparseRegressor];
[`tune_delay_sindy`][sk_offwhite.baselines.tune_delay_sindy] chooses its lags and threshold by
cross-validation on the estimation record only.
"""

from ._embedding import Embedding, embed_record, history_length, variable_names
from ._regressor import DelaySINDyRegressor, make_optimizer
from ._search import DEFAULT_GRID, access_statement, tune_delay_sindy
from ._simulate import FreeRun, monomials, output_box, simulate_free_run

__all__ = [
    "DEFAULT_GRID",
    "DelaySINDyRegressor",
    "Embedding",
    "FreeRun",
    "access_statement",
    "embed_record",
    "history_length",
    "make_optimizer",
    "monomials",
    "output_box",
    "simulate_free_run",
    "tune_delay_sindy",
    "variable_names",
]
