"""Simulation errors of the loop's models under the two scoring protocols in use.

* ``original``: the whole record is simulated from the model's fitted initial state (the
  Cascaded Tanks benchmark note states that estimation and validation records start from the
  same unknown state), every sample scored.
* ``init_window``: the first ``n`` measured samples are used to estimate the initial state
  and are excluded from the score (the ``nonlinear_benchmarks`` protocol, ``n = 50``).
"""

from __future__ import annotations

import numpy as np

from .._validation import check_record
from ..diagnose import simulation_metrics
from ..model_selection import held_out_rmse

__all__ = ["MODEL_LABELS", "held_out_rmse", "score_models"]  # held_out_rmse: re-exported

MODEL_LABELS = {
    "baseline": "declared physics",
    "with_delta": "physics + sparse δ",
    "final": "augmented physics",
    "final_with_delta": "augmented physics + δ",
    "final_with_output_delta": "augmented physics + output δ",
}


def _protocol_metrics(est, u, z, protocol: str, init_window: int) -> dict:
    """[`simulation_metrics`][sk_offwhite.diagnose.simulation_metrics] of one protocol, or, when the
    simulation diverges, ``overall`` with ``rmse`` ``inf``, ``fit_percent`` ``-inf`` and
    ``diverged_at`` (the first non-finite sample; the simulation has warned)."""
    u, z = check_record(u, z)
    skip = 0 if protocol == "original" else init_window
    z_init = None if protocol == "original" else z[:init_window]
    z_sim = np.asarray(est.simulate(u, z_init=z_init).outputs)
    finite = np.all(np.isfinite(z_sim), axis=1)
    if np.all(finite):
        metrics = simulation_metrics(z, z_sim, skip=skip)
        metrics["overall"]["diverged_at"] = None
        return metrics
    overall = dict(rmse=np.inf, fit_percent=-np.inf, diverged_at=int(np.argmin(finite)))
    return {"per_output": {}, "overall": overall}


def score_models(result, records: dict, init_window: int = 50) -> list[dict]:
    """Rows ``{model, record, protocol, rmse, fit_percent, diverged_at}`` for every fitted
    model and record.

    ``records`` maps a record name (``"estimation"``, ``"validation"``) to ``(u, z)``. A
    model whose simulation of a record diverges is scored, not dropped: ``rmse`` ``inf``,
    ``fit_percent`` ``-inf`` and ``diverged_at`` the first sample that is not finite
    (``None`` for a finite simulation), with a
    [`DivergenceWarning`][sk_offwhite.DivergenceWarning] from the simulation.
    """
    rows = []
    for key, label in MODEL_LABELS.items():
        est = getattr(result, key, None)
        if est is None:  # not fitted (fit_delta=False), failed (listed in the report) or older
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
                        diverged_at=overall["diverged_at"],
                    )
                )
    return rows
