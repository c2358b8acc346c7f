"""Simulation errors of the loop's models under the two scoring protocols in use.

* ``original``: the whole record is simulated from the model's fitted initial state (the
  Cascaded Tanks benchmark note states that estimation and validation records start from the
  same unknown state), every sample scored.
* ``init_window``: the first ``n`` measured samples are used to estimate the initial state
  and are excluded from the score (the ``nonlinear_benchmarks`` protocol, ``n = 50``).
"""

from __future__ import annotations

from .._path import held_out_errors
from .._validation import check_record
from ..diagnose import simulation_metrics

__all__ = ["MODEL_LABELS", "held_out_rmse", "score_models"]

MODEL_LABELS = {
    "baseline": "declared physics",
    "with_delta": "physics + sparse δ",
    "final": "augmented physics",
    "final_with_delta": "augmented physics + δ",
}


def held_out_rmse(init_window: int):
    """Scorer ``(estimator, u, z) -> -RMSE`` of a held-out block's free-run simulation.

    The block's initial state is estimated from its first ``init_window`` measured samples
    (``predict(u, z_init=...)``), which are not scored: the ``init_window`` protocol applied
    to a cross-validation block. A non-finite simulation scores ``-DIVERGED_FACTOR *
    std(z)`` (:data:`~sk_offwhite._path.DIVERGED_FACTOR`), so one diverging fold ranks a
    model last without making the mean undefined. The same function scores the held-out
    blocks of :func:`~sk_offwhite.fit_gamma_path` (``GammaPath.cv_rmse``).
    """

    def scorer(estimator, u, z) -> float:
        return -float(held_out_errors(estimator, u, z, init_window)[1])

    return scorer


def _protocol_metrics(est, u, z, protocol: str, init_window: int) -> dict:
    u, z = check_record(u, z)
    if protocol == "original":
        return simulation_metrics(z, est.simulate(u).outputs)
    z_sim = est.simulate(u, z_init=z[:init_window]).outputs
    return simulation_metrics(z, z_sim, skip=init_window)


def score_models(result, records: dict, init_window: int = 50) -> list[dict]:
    """Rows ``{model, record, protocol, rmse, fit_percent}`` for every fitted model and record.

    ``records`` maps a record name (``"estimation"``, ``"validation"``) to ``(u, z)``.
    """
    rows = []
    for key, label in MODEL_LABELS.items():
        est = getattr(result, key)
        if est is None:  # not fitted (fit_delta=False) or failed: listed in the report
            continue
        for record, (u, z) in records.items():
            for protocol in ("original", "init_window"):
                overall = _protocol_metrics(est, u, z, protocol, init_window)["overall"]
                rows.append(
                    dict(
                        model=label,
                        record=record,
                        protocol=protocol,
                        rmse=overall["rmse"],
                        fit_percent=overall["fit_percent"],
                    )
                )
    return rows
