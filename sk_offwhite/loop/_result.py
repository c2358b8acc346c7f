"""What the loop found: every fitted model, the evidence, the trail of choices, the notes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._estimator import GreyBoxSparseRegressor
from .._path import GammaPath
from ._scoring import MODEL_LABELS

__all__ = ["LoopResult"]


@dataclass
class LoopResult:
    """Everything the loop found; the report is written from it.

    ``augmented_physics`` is the declared physics with the added effects (their parameters
    at their declared and proposed values), with the parameters the final model holds on the
    directions its fit leaves undetermined fixed at their fitted values
    ([`hold_undetermined_directions`][sk_offwhite.loop.hold_undetermined_directions]). ``selection``
    holds ``(label, cross-validated RMSE)`` of the declared physics and of every nested effect set
    tried; ``single_fits`` ``(effect name, estimation RMSE)`` of each candidate fitted alone;
    ``gamma_path`` and ``final_gamma_path`` the support paths ([`GammaPath`][sk_offwhite.GammaPath],
    ``None`` for a single γ) of the two fits with δ (``with_delta`` and ``final_with_delta`` are
    ``None`` without ``fit_delta`` or when they failed). ``range_facts`` holds what the declared
    physics' simulation says of the measured outputs: their ceilings and floors
    ([`RangeViolation`][sk_offwhite.diagnose.RangeViolation]) and their repeated one-sample jumps
    ([`OutputJump`][sk_offwhite.diagnose.OutputJump]). ``evidence`` is the physics-only fit with
    the dictionary the hypotheses come from; ``final_with_output_delta`` the augmented
    physics with a sparse correction of its output map and ``output_gamma_path`` its path
    (``None`` without ``fit_output_delta``, when the outputs do not read states, or when it
    failed); ``cv_errors`` maps each fitted model's key (``"baseline"``, ``"with_delta"``,
    ``"final"``, ``"final_with_delta"``, ``"final_with_output_delta"``) to its
    cross-validated RMSE, ``chosen`` is the key of the lowest (a fit with δ that kept no
    term excepted: it is the physics it corrects); ``failures`` one line per fit that
    failed; ``notes`` what the loop decided not to use and why; ``timings`` the wall time of
    each stage in seconds (the stages are logged as they run, see
    `_progress`); ``warnings`` how many warnings of each kind the search's internal fits
    raised (counted here instead of shown: see `warning_counts`); ``set_fits`` each model of the
    ``selection`` trail fitted on the whole estimation record, by its label (``None`` where that fit
    failed), so that every structural step can be scored on validation data (the report does)."""

    physics: object
    augmented_physics: object
    baseline: GreyBoxSparseRegressor
    with_delta: GreyBoxSparseRegressor
    final: GreyBoxSparseRegressor
    final_with_delta: GreyBoxSparseRegressor
    gamma_path: GammaPath | None
    hypotheses: list
    range_facts: list
    candidates: list
    selection: list = field(default_factory=list)
    effects: tuple = ()
    single_fits: list = field(default_factory=list)
    final_gamma_path: GammaPath | None = None
    evidence: GreyBoxSparseRegressor | None = None
    cv_errors: dict = field(default_factory=dict)
    chosen: str = "baseline"
    failures: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    timings: dict = field(default_factory=dict)
    set_fits: dict = field(default_factory=dict)
    final_with_output_delta: GreyBoxSparseRegressor | None = None
    output_gamma_path: GammaPath | None = None
    warnings: dict = field(default_factory=dict)

    @property
    def best(self) -> GreyBoxSparseRegressor:
        """The model with the lowest cross-validated error (``chosen``)."""
        return getattr(self, self.chosen)


def loop_result(physics, augmented_physics, fits: dict, found: dict) -> LoopResult:
    """The [`LoopResult`][sk_offwhite.loop.LoopResult] of ``fits`` (``{key: (estimator,
    path, CV RMSE)}``, the models of `MODEL_LABELS` that were fitted) and of what else the
    loop ``found`` (the other fields, by name); the CV-best model is chosen here."""
    models = {key: fit[0] for key, fit in fits.items()}
    paths = {key: fit[1] for key, fit in fits.items()}
    cv_errors = {key: fit[2] for key, fit in fits.items() if fit[0] is not None}
    chosen = choose(cv_errors, models, found["notes"])
    return LoopResult(
        physics=physics, augmented_physics=augmented_physics, baseline=models["baseline"],
        with_delta=models.get("with_delta"), final=models["final"],
        final_with_delta=models.get("final_with_delta"), gamma_path=paths.get("with_delta"),
        final_gamma_path=paths.get("final_with_delta"), cv_errors=cv_errors, chosen=chosen,
        final_with_output_delta=models.get("final_with_output_delta"),
        output_gamma_path=paths.get("final_with_output_delta"), **found,
    )  # fmt: skip


def choose(cv_errors: dict, models: dict, notes: list) -> str:
    """Key of the lowest finite CV error (``"baseline"`` when none is finite) among the
    ``models`` that are models of their own: a fit with δ that kept no term is the physics
    it corrects, refitted, and its score (from other fold fits) does not stand for a
    different model; a note says so."""
    empty = [k for k, est in models.items() if est is not None and empty_delta(est)]
    for key in empty:
        notes.append(
            f"{MODEL_LABELS[key]} kept no term (it is the physics it corrects): not chosen "
            f"on its own score ({cv_errors.get(key, np.inf):.4g})."
        )
    finite = {k: v for k, v in cv_errors.items() if np.isfinite(v) and k not in empty}
    return min(finite, key=finite.get) if finite else "baseline"


def empty_delta(est) -> bool:
    """Whether ``est`` was fitted with a dictionary and kept none of its terms."""
    return est.library is not None and est.n_nonzero_ == 0


WARNING_KINDS = (
    ("max_iter reached", "fits stopped at max_iter"),
    ("did not converge", "fits that did not converge"),
    ("ran from", "parameters that ran far from their start"),
    ("diverged", "simulations that diverged"),
    ("fold's fit failed", "folds whose fit failed"),
)
"""How `warning_counts` names a warning, by a phrase of its message (first match)."""


def warning_counts(caught) -> dict[str, int]:
    """``{kind: count}`` of the recorded warnings ``caught``, by `WARNING_KINDS` (others by
    their category's name)."""
    counts: dict[str, int] = {}
    for record in caught:
        text = str(record.message)
        kind = next((k for phrase, k in WARNING_KINDS if phrase in text), None)
        kind = kind or record.category.__name__
        counts[kind] = counts.get(kind, 0) + 1
    return counts
