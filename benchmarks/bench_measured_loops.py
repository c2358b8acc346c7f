"""The closed loop on the three measured benchmarks, from their textbook physics.

Runs each example script (``examples/cascaded_tanks_loop.py``, ``examples/emps_loop.py``,
``examples/silverbox_loop.py``) as a user would, into a temporary folder, and reads the
report's ``results.json``: the effects the loop added, the declared and the augmented
physics' validation errors under the benchmark's protocol (its ``init_window`` rows; the
Cascaded Tanks also under the original protocol, the initial state fitted), the chosen
model with its validation error, and the wall time. Everything is chosen on the
estimation record; the validation records are only scored.

Run: ``python benchmarks/bench_measured_loops.py [NAME ...]`` (names: ``cascaded_tanks``,
``emps``, ``silverbox``); writes ``benchmarks/results/bench_measured_loops.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _results import table, write_results

from sk_offwhite.loop._scoring import MODEL_LABELS

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
BENCHMARKS = {
    "cascaded_tanks": ("cascaded_tanks_loop.py", "validation", "V", 1.0),
    "emps": ("emps_loop.py", "validation", "mm", 1e3),
    "silverbox": ("silverbox_loop.py", "arrow", "mV", 1e3),
}
"""Name: (example script, headline record, unit, scale from SI)."""

COLUMNS = ["benchmark", "record", "unit", "declared physics", "augmented physics",
           "chosen model", "chosen", "effects added", "functions of the kinds",
           "reference physics", "seconds"]  # fmt: skip

KIND_NOTE = "the functions of the variables' kinds explain more than the dictionary: "
"""What the report's note on the functions of the variables' kinds says before its list."""


def run_example(script: str, out: Path) -> float:
    """Run one example into ``out``; its wall time in seconds."""
    start = time.perf_counter()
    command = [sys.executable, str(EXAMPLES / script), "--out", str(out), "--quiet"]
    subprocess.run(command, check=True, cwd=EXAMPLES.parent)
    return time.perf_counter() - start


def rmse(facts: dict, model: str, record: str, protocol: str = "init_window") -> float | None:
    """The RMSE of ``model`` on ``record`` under ``protocol`` in the report's rows."""
    rows = [
        row["rmse"]
        for row in facts["rows"]
        if (row["model"], row["record"], row["protocol"]) == (model, record, protocol)
    ]
    return rows[0] if rows else None


def loop_row(name: str, facts: dict, seconds: float, protocol: str = "init_window") -> list:
    """One table row from a report's ``results.json``."""
    _, record, unit, scale = BENCHMARKS[name]
    chosen_label = MODEL_LABELS[facts["chosen"]]

    def scaled(model):
        return in_unit(rmse(facts, model, record, protocol), scale)

    effects = "; ".join(f"{e['name']}: {e['description']}" for e in facts["effects"])
    return [name + ("" if protocol == "init_window" else f" ({protocol})"), record, unit,
            scaled("declared physics"), scaled("augmented physics"), scaled(chosen_label),
            chosen_label, effects or "none", kind_findings(facts["notes"]),
            scaled(reference_label(facts)), seconds]  # fmt: skip


TRAIL_COLUMNS = ["benchmark", "unit", "effect set", "cross-validated (estimation)",
                 "validation", "set of the chosen model"]  # fmt: skip


def trail_rows(name: str, facts: dict) -> list[list]:
    """One row per effect set the loop cross-validated: its CV error on the estimation
    record and its fit's error on the headline record (the benchmark's ``init_window``),
    both in the benchmark's unit; ``yes`` on the set the augmented physics holds."""
    _, record, unit, scale = BENCHMARKS[name]
    added = {effect["name"] for effect in facts["effects"]}
    rows = []
    for label, cv in facts["selection"]:
        scored = facts["set_scores"].get(label, {}).get(record) or {}
        members = set() if label == "declared physics" else set(label.split(" + "))
        rows.append([name, unit, label, in_unit(cv, scale), in_unit(scored.get("rmse"), scale),
                     "yes" if members == added else ""])  # fmt: skip
    return rows


def in_unit(value: float | None, scale: float) -> float | None:
    """An RMSE in SI units in the benchmark's unit (``None`` stays ``None``)."""
    return None if value is None else scale * value


def reference_label(facts: dict) -> str | None:
    """The label of the report's model that is not the loop's (a reference physics the
    example scored with ``score_models(others=...)``), or ``None``."""
    others = {row["model"] for row in facts["rows"]} - set(MODEL_LABELS.values())
    return next(iter(others), None)


def kind_findings(notes: list[str]) -> str:
    """The functions of the variables' kinds that explain more than the dictionary, per
    equation, as the report's notes list them (``"none"`` where none does)."""
    found = [
        note.removeprefix("In the ").replace(f" equation {KIND_NOTE}", ": ").split(" of the")[0]
        for note in notes
        if KIND_NOTE in note
    ]
    return "; ".join(found) or "none"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", choices=[[], *BENCHMARKS], default=[])
    args = parser.parse_args()
    rows, trails, data = [], [], {}
    with tempfile.TemporaryDirectory() as folder:
        for name in args.names or BENCHMARKS:
            out = Path(folder) / name
            seconds = run_example(BENCHMARKS[name][0], out)
            facts = json.loads((out / "results.json").read_text())
            rows.append(loop_row(name, facts, seconds))
            trails += trail_rows(name, facts)
            if name == "cascaded_tanks":
                rows.append(loop_row(name, facts, seconds, protocol="original"))
            data[name] = {"effects": facts["effects"], "parameters": facts["parameters"],
                          "cv_errors": facts["cv_errors"], "rows": facts["rows"]}  # fmt: skip
            print(dict(zip(COLUMNS, rows[-1], strict=True)), flush=True)
    notes = [
        "validation RMSE in the benchmark's unit under its protocol (init_window: the initial "
        "state estimated from the record's first samples, not scored; original: the initial "
        "state fitted); chosen: the model of lowest cross-validated error on the estimation "
        "record; functions of the kinds: those a physicist tries first for each variable that "
        "explain more of the declared physics' cost than the dictionary's best term, each "
        "alone, per equation; reference physics: the benchmark's reference law (EMPS: "
        "viscous and Coulomb friction and a force offset), its parameters fitted on the "
        "estimation record and scored the same way; seconds: the example's wall time."
    ]
    trail_notes = [
        "Every effect set the loop cross-validated on the estimation record, and the same "
        "set fitted on the whole estimation record and scored on the validation record (the "
        "benchmark's init_window protocol). The loop chooses on the first column only: where "
        "the two columns rank the sets differently, the estimation record alone cannot tell "
        "those sets apart the way the validation record does."
    ]
    tables = [
        table("The closed loop on the measured benchmarks", COLUMNS, rows, notes),
        table("Every effect set the loop cross-validated", TRAIL_COLUMNS, trails, trail_notes),
    ]
    write_results("bench_measured_loops", tables, data=data)


if __name__ == "__main__":
    main()
