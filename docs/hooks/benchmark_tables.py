"""MkDocs hook: render the benchmarks' JSON results into the pages that cite them.

A page line of the form

    <!-- results: NAME | COMMAND -->

is replaced by the tables of ``benchmarks/results/NAME.json`` (written by the benchmark
scripts, see ``benchmarks/_results.py``), headed by the machine, the package versions, the
date and the command that produced them. When the file is missing the line becomes a note
that the benchmark has not been measured yet, with ``COMMAND`` to produce it: the build does
not fail.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

MARKER = re.compile(r"^<!--\s*results:\s*(?P<name>[\w.-]+)\s*(?:\|\s*(?P<command>.*?))?\s*-->\s*$")
SHOWN_VERSIONS = ("sk_offwhite", "jax", "numpy", "scipy", "scikit-learn", "pysindy", "cvxpy")


def _results_dir(config) -> Path:
    return Path(config.config_file_path).resolve().parent / "benchmarks" / "results"


def cell(value) -> str:
    """One table cell: numbers to four significant digits, booleans as yes / no."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "—"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        return f"{value:.4g}"
    return str(value).replace("|", "\\|").replace("\n", " ")


def render_table(table: dict) -> list[str]:
    """A results table as Markdown lines: its title, the pipe table, its notes."""
    columns = table.get("columns") or []
    lines = [f"**{table.get('title', '')}**", ""]
    if not columns:
        return lines + ["(no rows)", ""]
    lines.append("| " + " | ".join(cell(c) for c in columns) + " |")
    lines.append("|" + "---|" * len(columns))
    for row in table.get("rows", []):
        padded = list(row) + [None] * (len(columns) - len(row))
        lines.append("| " + " | ".join(cell(v) for v in padded[: len(columns)]) + " |")
    lines.append("")
    for note in table.get("notes", []):
        lines += [f"*{cell(note)}*", ""]
    return lines


def context_line(results: dict) -> str:
    """Where, when and how the results were measured."""
    machine = results.get("machine", {})
    versions = results.get("versions", {})
    shown = ", ".join(f"{k} {versions[k]}" for k in SHOWN_VERSIONS if k in versions)
    date = str(results.get("date", "unknown date"))[:10]
    load = machine.get("load_average")
    load = f", load average {load:.1f} at the end" if isinstance(load, int | float) else ""
    return (
        f"Measured on {date} on {machine.get('cpu', 'an unknown CPU')}, "
        f"{machine.get('cores', '?')} cores{load} (Python {machine.get('python', '?')}; "
        f"{shown}), by `{results.get('command', '?')}`."
    )


def render(name: str, command: str | None, folder: Path) -> list[str]:
    """The Markdown that replaces one marker."""
    path = folder / f"{name}.json"
    run = f"`{command}`" if command else f"the script that writes `{name}.json`"
    if not path.exists():
        return [
            '!!! note "Not measured yet"',
            f"    `benchmarks/results/{name}.json` is not there: run {run} to produce it.",
            "",
        ]
    try:
        results = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        return [
            '!!! warning "Results unreadable"',
            f"    `benchmarks/results/{name}.json` could not be read ({error}); run {run} again.",
            "",
        ]
    lines = [context_line(results), ""]
    for table in results.get("tables", []):
        lines += render_table(table)
    return lines


def on_page_markdown(markdown, page, config, files, **kwargs):
    if "<!-- results:" not in markdown:
        return markdown
    folder = _results_dir(config)
    out = []
    for line in markdown.splitlines():
        match = MARKER.match(line.strip())
        if match:
            out += render(match["name"], match["command"], folder)
        else:
            out.append(line)
    return "\n".join(out) + "\n"


def on_serve(server, config, builder, **kwargs):
    folder = _results_dir(config)
    if folder.exists():
        server.watch(str(folder))
    return server
