"""The batch's index.html in headless Chromium: it renders its curves, fetches nothing, and sorts by
a column when its header is clicked."""
from __future__ import annotations

from pathlib import Path

from _editor_support import CHROMIUM_ARGS
from test_demo import CHROMIUM, _browser_or_skip
from retime.batch.summary import COLUMNS, write_index_html


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
            col = COLUMNS.index("seconds")
            names = "() => [...document.querySelectorAll('tbody tr')].map(r => r.cells[0].textContent)"
            page.click(f"th:nth-child({col + 1})")
            ascending = page.evaluate(names)
            page.click(f"th:nth-child({col + 1})")
            descending = page.evaluate(names)
            drawn = page.evaluate("() => [...document.querySelectorAll('polyline')].filter(p => p.getBBox().width > 0).length")
        finally:
            browser.close()
    assert not errors and not external
    assert ascending[:3] == ["a.bvh", "b.bvh", "c.bvh"]  # numbers sort as numbers (10 after 2.5)
    assert descending[1:] == ["c.bvh", "b.bvh", "a.bvh"] or descending[:3] == ["c.bvh", "b.bvh", "a.bvh"]
    assert drawn == 3
