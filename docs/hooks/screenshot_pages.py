"""Screenshots of the built documentation, to check the rendered pages by eye.

Build the site first (``mkdocs build --strict``, into ``build/site``), then run::

    python docs/hooks/screenshot_pages.py [--site build/site] [--out build/screenshots]
        [--browser /usr/bin/chromium] [PAGE ...]

Each page (by default those below, paths inside the site) is opened in headless Chromium
through Playwright (``pip install playwright``; the browser is the one given by
``--browser``, for example Debian's ``chromium`` package, or Playwright's own), MathJax is
waited for until it has typeset the page, and a full-page PNG is written to ``--out``, with
``--tiles`` screen-sized PNGs centred on formulas spread over the page (``NAME_mathK.png``,
display formulas first: a full page is too tall to read at once).

Look at each PNG: the maths must show as formulas, not as ``$...$``, ``\\(...\\)`` or raw
TeX, and no Sphinx role (``:math:``, ``:func:``, ``:class:``) or ``.. math::`` may show.
The script also prints, per page, how many formulas MathJax typeset and how many
``.arithmatex`` elements it left untypeset (0 is right).

This file is not an MkDocs hook: ``mkdocs.yml`` lists its hooks by name, and this folder is
excluded from the pages.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

PAGES = (
    "api/estimator/index.html",
    "theory/index.html",
    "api/certify/index.html",
    "benchmarks/index.html",
)
"""Pages shot by default: the most maths, the API pages with the most docstrings, tables."""

WIDTH, HEIGHT = 1280, 900
MATHJAX_TIMEOUT_MS = 60_000

COUNT_SCRIPT = """() => ({
    typeset: document.querySelectorAll("mjx-container").length,
    untypeset: [...document.querySelectorAll(".arithmatex")]
        .filter((e) => !e.querySelector("mjx-container")).length,
})"""


def _parse(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("pages", nargs="*", default=list(PAGES), help="paths inside the site")
    parser.add_argument("--site", type=Path, default=Path("build/site"))
    parser.add_argument("--out", type=Path, default=Path("build/screenshots"))
    parser.add_argument("--tiles", type=int, default=3, help="screens on formulas per page")
    parser.add_argument(
        "--browser",
        default=shutil.which("chromium") or shutil.which("chromium-browser"),
        help="Chromium executable (default: chromium on the PATH; none: Playwright's own)",
    )
    return parser.parse_args(argv)


def _shoot(browser, site: Path, page_path: str, out: Path, tiles: int) -> dict:
    """Open one page, wait for MathJax, write its PNG; the formula counts."""
    page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
    page.goto((site / page_path).resolve().as_uri())
    page.wait_for_function(
        "() => window.MathJax && window.MathJax.startup && window.MathJax.startup.promise",
        timeout=MATHJAX_TIMEOUT_MS,
    )
    page.evaluate("() => window.MathJax.startup.promise")
    page.evaluate("() => window.MathJax.typesetPromise ? window.MathJax.typesetPromise() : 0")
    png = out / (page_path.replace("/index.html", "").replace("/", "_") + ".png")
    page.screenshot(path=str(png), full_page=True)
    counts = page.evaluate(COUNT_SCRIPT)
    _tiles(page, png, tiles)
    page.close()
    return {"png": png, **counts}


def _tiles(page, png: Path, tiles: int) -> None:
    """Screen-sized PNGs beside ``png``, each centred on one of ``tiles`` formulas evenly
    spread over the page (display formulas if the page has any, else inline ones)."""
    formulas = page.locator("div.arithmatex")
    if formulas.count() == 0:
        formulas = page.locator(".arithmatex")
    n = formulas.count()
    picks = sorted({round(i * (n - 1) / max(tiles - 1, 1)) for i in range(tiles)}) if n else []
    for k, index in enumerate(picks):
        formulas.nth(index).evaluate("(e) => e.scrollIntoView({block: 'center'})")
        page.screenshot(path=str(png.with_name(f"{png.stem}_math{k}.png")))


def main(argv=None) -> None:
    from playwright.sync_api import sync_playwright

    args = _parse(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=args.browser)
        for page_path in args.pages:
            shot = _shoot(browser, args.site, page_path, args.out, args.tiles)
            print(f"{shot['png']}: {shot['typeset']} formulas, {shot['untypeset']} untypeset")
        browser.close()


if __name__ == "__main__":
    main()
