"""The editor shows the clip's own physics (``retime check``): the residual strip under the scrub bar and
the contact-force arrows on the original figure, in headless Chromium (software WebGL).

The page's data is the check's report turned into the viewer's world (metres, y up); the arrows drawn
at a paused frame point along that frame's forces from its feet, one body weight half the body's
height; in flight no foot arrow shows; the strip marks the frames over the threshold."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from _editor_support import require

require("fastapi", "pip install 'retime[editor]'")
require("uvicorn", "pip install 'retime[editor]'")

from retime.data import bundled_path  # noqa: E402
from retime.motion import load_motion, save_bvh  # noqa: E402
from retime.motion.mistakes import wrong_frame_time  # noqa: E402
from retime.physics.check import check_clip  # noqa: E402

from _editor_support import CHROMIUM_ARGS, require_browser, wait_js  # noqa: E402

CLIP = "16_06.amc"  # a jump: stance, flight and a hard landing


@pytest.fixture(scope="module")
def page_and_check(tmp_path_factory):
    path = require_browser()
    from playwright.sync_api import sync_playwright

    from retime.editor.server import BackgroundServer, create_app, load_clip

    shots = Path(os.environ.get("RETIME_EDITOR_SHOTS") or tmp_path_factory.mktemp("shots"))
    # played too fast (Frame Time x0.8): the check judges its landing (a flight that falls at g and its
    # landing are left out of the verdict, so the clip as captured has no worst frame)
    bvh = tmp_path_factory.mktemp("clip") / "16_06.bvh"
    save_bvh(wrong_frame_time(load_motion(bundled_path(CLIP)), 0.8), bvh)
    clip = load_clip(bvh)
    report = check_clip(load_motion(bvh)).report()
    with BackgroundServer(create_app(clip, tmp_path_factory.mktemp("edits"))) as url, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=path, args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        errors = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url + "/")
        wait_js(page, "window.__retime && window.__retime.ready")
        wait_js(page, "window.__retime.check", timeout=180)
        yield page, report, shots, errors
        browser.close()


def show_frame(page, frame):
    fps = page.evaluate("window.__retime.clip.fps")
    page.evaluate("window.__retime.playing = false")
    page.evaluate(f"window.__retime.playT = {frame / fps}; window.__retime.dirty = true")
    wait_js(page, f"window.__retime.viewer.shownForces && window.__retime.viewer.shownForces.frame === {frame}")
    return page.evaluate("window.__retime.viewer.shownForces")


def test_the_page_gets_the_checks_report(page_and_check):
    page, report, _, errors = page_and_check
    check = page.evaluate("window.__retime.check")
    assert check["available"] and check["physical"] == report["summary"]["physical"]
    np.testing.assert_allclose(check["residual"], [f["residual"] for f in report["frames"]], atol=1e-4)
    for foot in ("left", "right"):  # 16_06 is Y up in metres: the viewer's world is the file's
        np.testing.assert_allclose(check["feet"][foot]["force"], [f["foot_force"][foot] for f in report["frames"]],
                                   atol=1e-4)
    assert f"physics of the original: {report['verdict']}" in page.inner_text("#check-info")
    assert "[frame_rate]" in report["verdict"]  # the clip plays 1.25x too fast, and the page says so
    assert not errors, errors


def test_arrows_follow_the_forces(page_and_check):
    page, report, shots, errors = page_and_check
    check = page.evaluate("window.__retime.check")
    height = page.evaluate("window.__retime.viewer.height")
    offset = np.array(page.evaluate("window.__retime.viewer.offset.toArray()"))
    frames = report["frames"]
    stance = next(i for i, f in enumerate(frames) if not f["flight"] and f["foot_force"]["left"][1] > 0.3
                  and f["foot_force"]["right"][1] > 0.3)
    shown = show_frame(page, stance)
    for foot in ("left", "right"):
        force = np.array(check["feet"][foot]["force"][stance])
        arrow = shown[foot]
        assert arrow is not None, foot
        np.testing.assert_allclose(arrow["direction"], force / np.linalg.norm(force), atol=1e-4)
        assert arrow["length"] == pytest.approx(np.linalg.norm(force) * 0.5 * height, rel=1e-4)
        np.testing.assert_allclose(arrow["origin"], np.array(check["feet"][foot]["point"][stance]) - offset, atol=1e-4)
    page.screenshot(path=str(shots / "editor-check-stance.png"))
    flight = next(i for i, f in enumerate(frames) if f["flight"] and i > stance)
    shown = show_frame(page, flight)
    assert shown["left"] is None and shown["right"] is None  # nothing pushes in the air
    worst = report["summary"]["worst_frames"][0]
    shown = show_frame(page, worst)
    assert shown["residual"] is not None and shown["residual"]["length"] > 0.5 * 0.5 * height  # the hard landing
    page.screenshot(path=str(shots / "editor-check-landing.png"))
    assert not errors, errors


def test_the_strip_marks_the_frames_over_the_threshold(page_and_check):
    page, report, _, _ = page_and_check
    residual = np.array([f["residual"] for f in report["frames"]])
    over = int((residual > report["residual_threshold"]).sum())
    assert over > 0
    widths = page.evaluate("Array.from(document.querySelectorAll('#residual-strip .res.over'))"
                           ".map(e => parseFloat(e.style.width))")
    total = page.evaluate("(() => { const s = window.__retime.solution, c = window.__retime.clip;"
                          " return Math.max(c.duration, s.duration) * c.fps; })()")
    assert sum(widths) == pytest.approx(100 * over / total, rel=0.05)
    assert json.dumps(page.evaluate("document.querySelector('#residual-strip').children.length")) != "0"
