"""Write a benchmark's results as JSON, with the machine, the versions, the date and the command.

Every script under ``benchmarks/`` that the documentation cites calls ``write_results`` at
the end of its run: ``benchmarks/results/<name>.json`` by default, or the path given by the
script's ``--json`` option. The documentation's benchmarks page renders those files into
tables (``docs/hooks/benchmark_tables.py``); a file that is missing shows as not measured yet.

The file holds ``tables``, each ``{"title", "columns", "rows"}`` with rows as lists of
numbers, strings or ``None`` in the order of ``columns``, an optional ``"notes"`` list of
strings per table, and ``data``, whatever else the script wants to keep (the raw results).
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import shlex
import sys
from importlib import metadata
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"
PACKAGES = ("sk_offwhite", "jax", "jaxlib", "numpy", "scipy", "scikit-learn", "pysindy", "cvxpy")


def default_path(name: str) -> Path:
    """``benchmarks/results/<name>.json``."""
    return RESULTS / f"{name}.json"


def cpu_model() -> str:
    """The CPU's model name (``/proc/cpuinfo`` on Linux, ``platform`` elsewhere)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict:
    """CPU model, cores available to this process, the load average when the results were
    written (other work on the machine slows every timing), OS and Python."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:
        cores = os.cpu_count()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    return {
        "cpu": cpu_model(),
        "cores": cores,
        "load_average": load,
        "system": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
    }


def versions() -> dict:
    """Installed versions of the packages a benchmark depends on (absent ones left out)."""
    found = {}
    for name in PACKAGES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
    return found


def command(argv=None) -> str:
    """The command line that ran the script, relative to the repository root."""
    script = Path(sys.argv[0])
    try:
        script = script.resolve().relative_to(RESULTS.parents[1])
    except ValueError:
        pass
    args = sys.argv[1:] if argv is None else list(argv)
    return shlex.join(["python", script.as_posix(), *args])


def table(title: str, columns, rows, notes=()) -> dict:
    """One table of the results page: rows are sequences in the order of ``columns``."""
    return {
        "title": title,
        "columns": list(columns),
        "rows": [[_plain(value) for value in row] for row in rows],
        "notes": list(notes),
    }


def records_table(title: str, records, notes=()) -> dict:
    """One table from a list of dicts with the same keys (the keys are the columns)."""
    records = list(records)
    columns = list(records[0]) if records else []
    return table(title, columns, [[r.get(c) for c in columns] for r in records], notes)


def markdown_tables(title: str, text: str) -> list:
    """The pipe tables of a Markdown ``text`` a script prints, as tables titled ``title``
    (numbered when there are several); the lines around them become their notes."""
    found, notes, block = [], [], []
    for line in [*text.splitlines(), ""]:
        if line.strip().startswith("|"):
            block.append(line)
            continue
        if block:
            found.append((block, notes))
            block, notes = [], []
        if line.strip():
            notes.append(line.strip())
    out = []
    for number, (lines, before) in enumerate(found, 1):
        cells = [[c.strip() for c in line.strip().strip("|").split("|")] for line in lines]
        rows = [row for row in cells[1:] if not all(set(c) <= set("-: ") for c in row)]
        name = title if len(found) == 1 else f"{title} ({number})"
        out.append(table(name, cells[0], [[_number(c) for c in row] for row in rows], before))
    if out and notes:
        out[-1]["notes"] += notes
    return out


def _number(text: str):
    """A cell of a Markdown table: a number where it reads as one, else its text."""
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def _plain(value):
    """Numbers, strings, booleans and None as they are; anything else as its text."""
    if value is None or isinstance(value, bool | int | str):
        return value
    try:
        return float(value)
    except (TypeError, ValueError):
        return str(value)


def write_results(name: str, tables, *, path=None, argv=None, data=None) -> Path:
    """Write ``tables`` and the run's context to ``path`` (default ``results/<name>.json``)."""
    path = Path(path) if path is not None else default_path(name)
    payload = {
        "benchmark": name,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": command(argv),
        "machine": machine(),
        "versions": versions(),
        "tables": list(tables),
        "data": data,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(payload, indent=1, default=_plain) + "\n", encoding="utf-8")
    print(f"results written to {path}")
    return path
