"""What the closed-loop examples share: the runtime set-up and the printed summary."""

from __future__ import annotations

import logging
from pathlib import Path

from sk_offwhite import enable_compilation_cache, enable_fused_loops
from sk_offwhite.loop import write_report


def configure_runtime(*, fused: bool = True, cache: bool = True, log: bool = True) -> None:
    """Fused simulation loops, the on-disk compilation cache and the loop's progress log."""
    if fused:
        enable_fused_loops()
    if cache:
        enable_compilation_cache()
    if log:
        logging.basicConfig(format="%(asctime)s %(message)s", datefmt="%H:%M:%S")
        logging.getLogger("sk_offwhite").setLevel(logging.INFO)


def print_rows(rows, unit: str, scale: float, digits: int, width: int) -> None:
    """The ``init_window`` rows of `score_models`, RMSE in ``unit`` (``scale`` per SI unit)."""
    for row in rows:
        if row["protocol"] != "init_window":
            continue
        score = f"RMSE {scale * row['rmse']:.{digits}f} {unit}  fit {row['fit_percent']:.1f} %"
        if row["diverged_at"] is not None:
            score = f"diverged from sample {row['diverged_at']}"
        print(f"{row['model']:30s} {row['record']:{width}s} {score}")


def print_outcome(result, unit: str, scale: float, elapsed: float) -> None:
    """The effects added, the final parameters, the CV errors, the choice and the failures."""
    print("effects added:", ", ".join(e.name for e in result.effects) or "none")
    print("final parameters:", {k: float(f"{v:.5g}") for k, v in result.final.parameters_.items()})
    cv = {k: round(scale * v, 3) for k, v in result.cv_errors.items()}
    print(f"cross-validated RMSE ({unit}):", cv)
    print(f"chosen (lowest CV error): {result.chosen}")
    if result.failures:
        print("fits that failed:", *result.failures, sep="\n  ")
    print(f"wall time: {elapsed:.0f} s")


def write_study_report(result, rows, records, out, data, *, title: str, notes) -> Path:
    """`write_report` in the units of the measured benchmark ``data`` (its ``units`` and
    ``sampling_time``); returns the report's path."""
    return write_report(
        result,
        rows,
        records,
        out,
        title=title,
        notes=notes,
        units=data.units,
        sampling_time=data.sampling_time,
    )
