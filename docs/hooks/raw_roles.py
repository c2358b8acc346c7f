r"""MkDocs hook: fail the build when a page still shows a Sphinx role or directive, or
maths that was not typeset.

Docstrings and pages are written in the Markdown that mkdocstrings renders (maths as
``$...$`` and ``$$`` blocks, cross-references as autorefs links). A role such as
``:class:`Foo``` or a ``.. math::`` directive left in a docstring is not an error for
Markdown: it shows as raw text on the page. This hook reads the HTML of every built page and
stops the build with the list of offending pages and lines. It also stops at a ``$`` left
in a page's text (outside code and typeset maths): maths that arithmatex did not take shows
as raw TeX, such as a ``$$`` block indented inside a list item by less than the list's
continuation, or a formula with ``|`` in a table row (write ``\lvert``, ``\lVert``).
"""

from __future__ import annotations

import html
import re

from mkdocs.exceptions import PluginError

ROLES = ("math", "func", "class", "meth", "mod", "data", "attr")
ROLE = re.compile(r"(?<![\w.\-]):(?:py:)?(?:" + "|".join(ROLES) + r"):(?=`|<code|<span|\w|~)")
DIRECTIVE = re.compile(r"\.\.\s+math::")
TAG = re.compile(r"<[^>]+>")
SCRIPT = re.compile(r"<script\b.*?</script>", re.DOTALL | re.IGNORECASE)
CODE = re.compile(r"<(pre|code)\b.*?</\1>", re.DOTALL | re.IGNORECASE)
MATHS = re.compile(r'<(span|div) class="arithmatex">.*?</\1>', re.DOTALL)
UNTYPESET = re.compile(r"\$")

_found: dict[str, list[str]] = {}


def offending_lines(page_html: str) -> list[str]:
    """The lines of ``page_html`` (scripts removed) that hold a raw role or directive, and
    those (code and typeset maths removed too) whose text holds a ``$``, as text without
    tags."""
    text = SCRIPT.sub("", page_html)
    raw = [line for line in text.splitlines() if ROLE.search(line) or DIRECTIVE.search(line)]
    prose = MATHS.sub("", CODE.sub("", text)).splitlines()
    raw += [line for line in prose if UNTYPESET.search(TAG.sub("", line))]
    return [html.unescape(TAG.sub("", line)).strip()[:160] or line.strip()[:160] for line in raw]


def on_pre_build(config, **kwargs):
    _found.clear()


def on_post_page(output, page, config, **kwargs):
    lines = offending_lines(output)
    if lines:
        _found[page.file.src_uri] = lines
    return output


def on_post_build(config, **kwargs):
    if not _found:
        return
    report = [f"  {page}: {line}" for page, lines in sorted(_found.items()) for line in lines[:10]]
    roles = ", ".join(f":{r}:" for r in ROLES)
    raise PluginError(
        f"raw Sphinx roles or directives ({roles}, .. math::) or untypeset maths ($) in the "
        "built pages; write them as Markdown ($...$, $$ blocks at the paragraph's indentation, "
        "[`name`][full.path] links):\n" + "\n".join(report)
    )
