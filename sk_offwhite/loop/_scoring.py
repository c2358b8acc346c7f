"""Simulation errors of the loop's models under the two scoring protocols in use.

* ``original``: the whole record is simulated from the model's fitted initial state (the
  Cascaded Tanks benchmark note states that estimation and validation records start from the
  same unknown state), every sample scored.
* ``init_window``: the first ``n`` measured samples are used to estimate the initial state
  and are excluded from the score (the ``nonlinear_benchmarks`` protocol, ``n = 50``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .._validation import check_record
from ..diagnose import simulation_metrics
from ..model_selection import held_out_rmse

__all__ = [
    "MODEL_LABELS",
    "checked_records",
    "held_out_rmse",
    "score_models",
]  # held_out_rmse: re-exported

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


def score_models(
    result, records: dict, init_window: int = 50, others: Mapping | None = None
) -> list[dict]:
    """Rows ``{model, record, protocol, init_window, rmse, fit_percent, diverged_at}`` for
    every fitted model and record (``init_window`` ``None`` in the ``original`` rows).

    ``records`` maps a record name (``"estimation"``, ``"validation"``) to ``(u, z)``. A
    model whose simulation of a record diverges is scored, not dropped: ``rmse`` ``inf``,
    ``fit_percent`` ``-inf`` and ``diverged_at`` the first sample that is not finite
    (``None`` for a finite simulation), with a
    [`DivergenceWarning`][sk_offwhite.DivergenceWarning] from the simulation. ``others``
    maps a label to a fitted estimator of your own (a reference physics, a baseline),
    scored the same way after the loop's models; `write_report` shows its rows with theirs.
    """
    records = checked_records(records)
    _check_scoring(result, records, init_window)
    models = {label: getattr(result, key, None) for key, label in MODEL_LABELS.items()}
    models |= _checked_others(others, models)
    rows = []
    for label, est in models.items():
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
                        init_window=None if protocol == "original" else init_window,
                        rmse=overall["rmse"],
                        fit_percent=overall["fit_percent"],
                        diverged_at=overall["diverged_at"],
                    )
                )
    return rows


def _checked_others(others, models: dict) -> dict:
    """``others`` as a dict of new labels to fitted estimators, or an error naming it."""
    if others is None:
        return {}
    if not isinstance(others, Mapping):
        raise TypeError(
            f"others must map labels to fitted estimators, got {type(others).__name__}."
        )
    for label, est in others.items():
        if not isinstance(label, str) or label in models:
            raise ValueError(f"others: {label!r} is not a new label (the loop's: {list(models)}).")
        if not hasattr(est, "simulate") or not hasattr(est, "n_outputs_"):
            raise TypeError(f"others[{label!r}] must be a fitted GreyBoxSparseRegressor.")
    return dict(others)


def checked_records(records) -> dict:
    """``records`` as a dict of name to a validated ``(u, z)`` pair, or an error naming
    ``records`` (a list, a record that is no pair, arrays of unequal lengths)."""
    if not isinstance(records, dict) or not records:
        raise TypeError(
            "records must be a non-empty dict of record names to (u, z) pairs, for example "
            f"{{'estimation': (u_est, z_est)}}, got {type(records).__name__}."
        )
    checked = {}
    for name, pair in records.items():
        if not isinstance(pair, tuple | list) or len(pair) != 2:
            raise ValueError(f"records[{name!r}] must be a (u, z) pair of arrays.")
        try:
            checked[name] = check_record(*pair)
        except (TypeError, ValueError) as error:
            raise type(error)(f"records[{name!r}]: {error}") from error
    return checked


def _check_scoring(result, records: dict, init_window) -> None:
    """Refuse a ``result`` that is no loop result and an ``init_window`` that is not an
    integer leaving at least 2 samples of every record to score."""
    if not hasattr(result, "baseline"):
        raise TypeError(
            "result must be the LoopResult of close_the_loop (or EffectSearchCV.result_), "
            f"got {type(result).__name__}."
        )
    if isinstance(init_window, bool) or not isinstance(init_window, int | np.integer):
        raise TypeError(f"init_window must be an integer, got {init_window!r}.")
    shortest = min(len(u) for u, _ in records.values())
    if not 0 <= init_window <= shortest - 2:
        raise ValueError(
            f"init_window must be in [0, {shortest - 2}] (at least 2 samples of the shortest "
            f"record, {shortest} samples, must be scored), got {init_window}."
        )
