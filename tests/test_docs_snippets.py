"""Every Python block of the README and of the documentation's pages runs as printed.

The ```` ```python ```` blocks of ``README.md`` and ``docs/*.md`` are run file by file, in
order, in one namespace per file, as a reader pasting them one after the other would. A block
opts out only with a marker on the line before its fence (blank lines between are allowed):

- ``<!-- no-run: REASON -->``: never run (for a block that needs data the package does not
  ship; the reason is required);
- ``<!-- requires: MODULE -->``: run only where ``MODULE`` can be imported (an optional
  extra), skipped otherwise.

Each file is one test class (so that pytest-xdist spreads the files over its workers), run
in a temporary working directory; it runs every block even after one fails and reports
every failure with its line and exception.
"""

from __future__ import annotations

import importlib.util
import re
import textwrap
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>```+|~~~+)\s*(?P<lang>[\w+-]*)")
NO_RUN = re.compile(r"<!--\s*no-run:\s*(?P<reason>\S.*?)\s*-->")
REQUIRES = re.compile(r"<!--\s*requires:\s*(?P<module>[\w.]+)\s*-->")


@dataclass(frozen=True)
class Block:
    """One fenced block: where it starts (1-based line of its fence), its code, its marker."""

    line: int
    code: str
    no_run: str | None = None
    requires: str | None = None


def _marker(lines: list[str], index: int) -> tuple[str | None, str | None]:
    """The opt-out marker on the last non-blank line before ``lines[index]``, if any."""
    for previous in reversed(lines[:index]):
        if previous.strip():
            no_run, requires = NO_RUN.search(previous), REQUIRES.search(previous)
            return (
                no_run["reason"] if no_run else None,
                requires["module"] if requires else None,
            )
    return None, None


def python_blocks(text: str) -> list[Block]:
    """The ```` ```python ```` blocks of a Markdown text, dedented (tabbed content too)."""
    lines, blocks, index = text.splitlines(), [], 0
    while index < len(lines):
        match = FENCE.match(lines[index])
        if not match:
            index += 1
            continue
        indent, fence = match["indent"], match["fence"]
        end = index + 1
        while end < len(lines) and not lines[end].strip().startswith(fence):
            end += 1
        if match["lang"].lower() in ("python", "py"):
            body = [line[len(indent) :] if line.startswith(indent) else line
                    for line in lines[index + 1 : end]]  # fmt: skip
            no_run, requires = _marker(lines, index)
            blocks.append(Block(index + 1, textwrap.dedent("\n".join(body)), no_run, requires))
        index = end + 1
    return blocks


def test_blocks_are_found_with_their_markers():
    text = (
        "Text\n\n```python\nx = 1\n```\n\n<!-- no-run: needs a plant -->\n\n```python\n"
        "plant()\n```\n\n<!-- requires: ray -->\n```python\nimport ray\n```\n\n"
        '=== "tab"\n\n    ```python\n    y = x + 1\n    ```\n\n```bash\nls\n```\n'
    )
    blocks = python_blocks(text)
    assert [b.code.strip() for b in blocks] == ["x = 1", "plant()", "import ray", "y = x + 1"]
    assert [b.no_run for b in blocks] == [None, "needs a plant", None, None]
    assert [b.requires for b in blocks] == [None, None, "ray", None]
    assert [b.line for b in blocks] == [3, 9, 14, 20]


def _ids(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def run_blocks(path: Path, tmp_path, monkeypatch) -> None:
    """Run the Python blocks of ``path`` in order in one namespace; fail listing every block
    that raised."""
    blocks = python_blocks(path.read_text(encoding="utf-8"))
    if not blocks:
        pytest.skip("no Python block")
    import matplotlib

    matplotlib.use("Agg")
    monkeypatch.chdir(tmp_path)  # blocks that write reports write them here
    namespace = {"__name__": "__main__"}
    failures, skipped, timings = [], [], []
    for block in blocks:
        where = f"{_ids(path)}:{block.line}"
        if block.no_run is not None:
            skipped.append(f"{where} (no-run: {block.no_run})")
            continue
        if block.requires and importlib.util.find_spec(block.requires.split(".")[0]) is None:
            skipped.append(f"{where} (requires {block.requires})")
            continue
        start = time.perf_counter()
        try:
            exec(compile(block.code, where, "exec"), namespace)
        except Exception as error:  # every failure of every block is reported
            last = traceback.extract_tb(error.__traceback__)[-1]
            failures.append(
                f"{where}: {type(error).__name__}: {error} (at {last.filename}:{last.lineno})"
            )
        timings.append(f"{where} {time.perf_counter() - start:.1f} s")
    print("\n".join(timings + [f"skipped {s}" for s in skipped]))
    assert not failures, "blocks that do not run as printed:\n" + "\n".join(failures)


def _file_class(path: Path) -> type:
    """A test class for one file: pytest-xdist's ``--dist loadscope`` sends each class to a
    worker of its own, so the files' blocks run in parallel across workers."""

    def test_python_blocks_run_as_printed(self, tmp_path, monkeypatch):
        run_blocks(path, tmp_path, monkeypatch)

    name = "TestBlocks_" + re.sub(r"\W", "_", _ids(path).removesuffix(".md"))
    return type(name, (), {"test_python_blocks_run_as_printed": test_python_blocks_run_as_printed})


for _path in FILES:
    _class = _file_class(_path)
    globals()[_class.__name__] = _class
