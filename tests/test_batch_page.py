"""The batch's index.html in headless Chromium: it renders its curves, fetches nothing, and sorts by
a column when its header is clicked."""
from __future__ import annotations

from pathlib import Path

from _editor_support import CHROMIUM_ARGS
from test_demo import CHROMIUM, _browser_or_skip
from retime.batch.summary import COLUMNS, write_index_html


def _headers(html):
    import re

    return re.findall(r"<th>(.*?)</th>", html)


def _row(name, seconds, status="done"):
    row = dict.fromkeys(COLUMNS, "")
    row.update(input=name, status=status, seconds=seconds, source_duration="2", output_duration="1")
    return row


def test_index_sorts_and_renders_in_chromium(tmp_path):
    _browser_or_skip()
    from playwright.sync_api import sync_playwright

    rows = [_row("b.bvh", "2.50"), _row("a.bvh", "0.75"), _row("c.bvh", "10.0"), _row("bad.bvh", "", "failed")]
    curve = [(0.0, 0.0), (0.5, 1.2), (1.0, 2.0)]
    path = tmp_path / "index.html"
    write_index_html(rows, [curve, curve, curve, None], path, title="retime batch: linear")
    external, errors = [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page()
            page.on("request", lambda r: None if r.url.startswith(("file://", "data:")) else external.append(r.url))
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(Path(path).resolve().as_uri(), wait_until="load")
            names = "() => [...document.querySelectorAll('tbody tr')].map(r => r.cells[0].textContent)"
            page.click("th:text-is('seconds')")
            ascending = page.evaluate(names)
            page.click("th:text-is('seconds')")
            descending = page.evaluate(names)
            drawn = page.evaluate("() => [...document.querySelectorAll('polyline')].filter(p => p.getBBox().width > 0).length")
        finally:
            browser.close()
    assert not errors and not external
    assert ascending[:3] == ["a.bvh", "b.bvh", "c.bvh"]  # numbers sort as numbers (10 after 2.5)
    assert descending[1:] == ["c.bvh", "b.bvh", "a.bvh"] or descending[:3] == ["c.bvh", "b.bvh", "a.bvh"]
    assert drawn == 3


def _physics_row(name, output, least, feasible, speeds):
    row = _row(name, "3.0")
    row.update(output_duration=output, least_duration=least, feasible_fraction=feasible, flight_speeds=speeds,
               source_physical="true", off_share="0.04")
    return row


def test_physics_page_summarises_flights_and_shows_the_duration_warning(tmp_path):
    """A clip with 12 flights put 12 speeds in one cell (the curves went off-screen at 1400 px); a clip retimed
    below its least physical duration (the command line says so) showed "done" like the rest."""
    _browser_or_skip()
    from playwright.sync_api import sync_playwright

    twelve = ";".join(f"{1 + k / 100:.4f}" for k in range(12))
    frames = lambda n, T: [(k * T / (n - 1), k * T / (n - 1)) for k in range(n)]  # a warp row per output frame
    rows = [_physics_row("/data/a-very-long-folder-name/of/clips/hops_and_skips_0001.bvh", "4", "3.5", "1", twelve),
            _physics_row("16_03.amc", "0.675", "1.4796", "0.2073", "3.9044"),
            _physics_row("at_its_least.bvh", "1.5", "1.503", "0.99", "1.05")]  # within half a frame: no warning
    curves = [frames(481, 4.0), frames(82, 0.675), frames(181, 1.5)]
    path = tmp_path / "index.html"
    write_index_html(rows, curves, path, title="retime batch: physics", method="physics")
    html = path.read_text()
    assert "12 flights: 1-1.11 (median 1.06)" in html and "1.0000;1.0100" not in html
    assert html.count("below its least physical duration") == 1
    assert "below its least physical duration 1.480 s; 21% of frames feasible" in html
    assert "error" not in _headers(html)  # no clip failed: no empty column
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 900})
            page.goto(path.resolve().as_uri(), wait_until="load")
            right = page.evaluate("() => Math.max(...[...document.querySelectorAll('svg')].map(s => s.getBoundingClientRect().right))")
            tip = page.evaluate("() => document.querySelector('tbody tr td[title]').title")
        finally:
            browser.close()
    assert right <= 1400  # every curve on screen
    assert tip.split(", ") == [f"{1 + k / 100:.3g}" for k in range(12)]  # the speeds themselves on hover
