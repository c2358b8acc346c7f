"""The closed loop on measured data: residual, missing effect, augmented physics, before/after.

[`EffectSearchCV`][sk_offwhite.loop.EffectSearchCV] runs the whole loop as a scikit-learn
meta-estimator and [`close_the_loop`][sk_offwhite.loop.close_the_loop] as a function;
[`score_models`][sk_offwhite.loop.score_models] scores its models under both protocols and
[`write_report`][sk_offwhite.loop.write_report] writes the Markdown report with its figures.
The pieces ([`form_hypotheses`][sk_offwhite.loop.form_hypotheses],
[`propose_effects`][sk_offwhite.loop.propose_effects],
[`read_varying_parameters`][sk_offwhite.loop.read_varying_parameters]) can be used on their
own.
"""

from ..model_selection import held_out_rmse
from ._candidates import Candidate, promoted_terms, propose_effects
from ._cv import cross_validated_rmse, held_out_splits, held_out_splitter
from ._effect_search import EffectSearchCV, close_the_loop
from ._evidence import analyse_model
from ._final import hold_undetermined_directions
from ._fits import fit_continued, warm_physics
from ._hypotheses import Hypothesis, Term, evidence_hypotheses, form_hypotheses, rank_terms
from ._reading import VaryingReading, read_varying_parameters
from ._report import write_report
from ._result import LoopResult
from ._scoring import score_models
from ._settings import LoopSettings

__all__ = [
    "Candidate",
    "EffectSearchCV",
    "Hypothesis",
    "LoopResult",
    "LoopSettings",
    "Term",
    "VaryingReading",
    "analyse_model",
    "close_the_loop",
    "cross_validated_rmse",
    "evidence_hypotheses",
    "fit_continued",
    "form_hypotheses",
    "held_out_rmse",
    "held_out_splits",
    "held_out_splitter",
    "hold_undetermined_directions",
    "promoted_terms",
    "propose_effects",
    "rank_terms",
    "read_varying_parameters",
    "score_models",
    "warm_physics",
    "write_report",
]
