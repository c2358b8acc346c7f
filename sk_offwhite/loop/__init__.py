"""The closed loop on measured data: residual, missing effect, augmented physics, before/after.

[`close_the_loop`][sk_offwhite.loop.close_the_loop] runs the whole loop on an estimation record,
[`score_models`][sk_offwhite.loop.score_models] scores its models under both protocols, and
[`write_report`][sk_offwhite.loop.write_report] writes the Markdown report with its figures. The
pieces ([`form_hypotheses`][sk_offwhite.loop.form_hypotheses],
[`propose_effects`][sk_offwhite.loop.propose_effects]) can be used on their own.
"""

from ._candidates import Candidate, promoted_terms, propose_effects
from ._hypotheses import Hypothesis, Term, evidence_hypotheses, form_hypotheses, rank_terms
from ._loop import (
    LoopResult,
    LoopSettings,
    analyse_model,
    close_the_loop,
    cross_validated_rmse,
    fit_continued,
    held_out_splits,
    hold_undetermined_directions,
    warm_physics,
)
from ._report import write_report
from ._scoring import held_out_rmse, score_models

__all__ = [
    "Candidate",
    "Hypothesis",
    "LoopResult",
    "LoopSettings",
    "Term",
    "analyse_model",
    "close_the_loop",
    "cross_validated_rmse",
    "fit_continued",
    "evidence_hypotheses",
    "form_hypotheses",
    "held_out_rmse",
    "held_out_splits",
    "hold_undetermined_directions",
    "promoted_terms",
    "propose_effects",
    "rank_terms",
    "score_models",
    "warm_physics",
    "write_report",
]
