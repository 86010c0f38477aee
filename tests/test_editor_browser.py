"""The editor in headless Chromium (Playwright): load a clip, drag, add, lock, export; latency.

Skips with a reason when Chromium or Playwright is missing, unless the env var CI is set (then it
fails: .ci/run installs them). Screenshots go to $RETIME_EDITOR_SHOTS (default: pytest's tmp dir).
"""
from __future__ import annotations

import os
import statistics
import time
from pathlib import Path

import numpy as np
import pytest

from _editor_support import require  # noqa: E402

require("fastapi", "pip install 'retime[editor]'")
require("uvicorn", "pip install 'retime[editor]'")

from retime.data import bundled_path  # noqa: E402

from _editor_support import CHROMIUM_ARGS, require_browser, wait_js  # noqa: E402

CLIP = "16_16.amc"  # a 510-frame walk: the "500-frame clip" of the latency target


@pytest.fixture(scope="module")
def shots(tmp_path_factory):
    d = Path(os.environ.get("RETIME_EDITOR_SHOTS") or tmp_path_factory.mktemp("shots"))
    d.mkdir(parents=True, exist_ok=True)
    return d


@pytest.fixture(scope="module")
def browser():
    path = require_browser()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=path, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    from retime.editor.server import BackgroundServer, create_app, load_clip

    outdir = tmp_path_factory.mktemp("edits")
    clip = load_clip(bundled_path(CLIP))
    with BackgroundServer(create_app(clip, outdir)) as url:
        yield url, outdir, clip


def open_page(browser, url, errors):
    page = browser.new_page(viewport={"width": 1400, "height": 900}, accept_downloads=True)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(url + "/")
    wait_js(page, "window.__retime && window.__retime.ready")
    wait_js(page, "document.querySelector('#status').classList.contains('live')")
    return page


def point_center(page, i):
    box = page.locator(f'#curve g.cp[data-index="{i}"] .knob').bounding_box()
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def drag(page, x0, y0, x1, y1, steps=25, pause=0.012):
    page.mouse.move(x0, y0)
    page.mouse.down()
    for k in range(1, steps + 1):
        page.mouse.move(x0 + (x1 - x0) * k / steps, y0 + (y1 - y0) * k / steps)
        time.sleep(pause)
    page.mouse.up()


def test_load_drag_lock_export(browser, server, shots):
    url, outdir, clip = server
    errors = []
    page = open_page(browser, url, errors)
    assert "16_16" in page.inner_text("#clipinfo") and "510 frames" in page.inner_text("#clipinfo")
    webgl = page.evaluate("window.__retime.webgl")
    assert webgl, "no WebGL in this Chromium: the 3-D view is off"
    assert page.locator("#viewer canvas").count() == 1
    page.screenshot(path=str(shots / "editor-1-loaded.png"))

    # pause at a fixed time so that the poses can be compared
    page.click("#play")
    page.evaluate("window.__retime.playing = false")
    page.locator("#scrub").fill("600")
    wait_js(page, "window.__retime.shown && Math.abs(window.__retime.shown.t - 0.6 * 4.241667) < 0.01")
    before = page.evaluate("({s: window.__retime.shown.sourceRetimed, d: document.querySelector('#curve-path').getAttribute('d'),"
                           " pose: Array.from(window.__retime.viewer.lastPoses[1].slice(0, 9))})")
    viewer_before = page.locator("#viewer").screenshot()

    # add a control point by double-clicking in the middle of the editor, then drag it up
    box = page.locator("#curve").bounding_box()
    page.mouse.dblclick(box["x"] + box["width"] * 0.45, box["y"] + box["height"] * 0.55)
    wait_js(page, "window.__retime.solution.points.length === 3")
    x, y = point_center(page, 1)
    drag(page, x, y, x - 0.12 * box["width"], y - 0.3 * box["height"])
    wait_js(page, "window.__retime.lastFinalSeq === window.__retime.seq")
    time.sleep(0.3)
    after = page.evaluate("({s: window.__retime.shown.sourceRetimed, d: document.querySelector('#curve-path').getAttribute('d'),"
                          " pose: Array.from(window.__retime.viewer.lastPoses[1].slice(0, 9)), sol: window.__retime.solution})")
    sol = after["sol"]
    p = sol["points"][1]
    # the point moved up and left: the first part now plays faster than the original
    assert p["s"] / p["t"] > 1.3, p
    speed = np.asarray(sol["speed"])
    assert speed[0] > 1.3 and speed[-1] < 0.9
    assert after["d"] != before["d"]  # the curve on screen changed
    assert after["s"] != pytest.approx(before["s"], abs=1e-3)  # the retimed character shows another pose
    assert not np.allclose(after["pose"], before["pose"], atol=1e-4)
    assert page.locator("#viewer").screenshot() != viewer_before
    # the curve drawn is the linear warp through the control points, frame by frame
    t = np.asarray(sol["curve"]["t"])
    pts = sol["points"]
    expected = np.interp(t, [q["t"] for q in pts], [q["s"] for q in pts])
    np.testing.assert_allclose(sol["curve"]["s"], expected, atol=1e-5)
    page.screenshot(path=str(shots / "editor-2-dragged.png"))

    # lock it (keyboard L on the selected point): a keytime marker appears on the scrub bar
    page.click('#curve g.cp[data-index="1"]')
    page.keyboard.press("l")
    wait_js(page, "window.__retime.solution.points[1].locked")
    assert page.locator("#scrub-marks .mark").count() == 1
    assert page.locator('#curve g.cp.locked[data-index="1"] rect.knob').count() == 1
    assert page.inner_text("#lock") == "Unlock"

    # export: files land in the output folder and are offered as downloads
    page.click("#export")
    page.wait_for_selector("#exports a")
    links = page.locator("#exports a")
    assert links.count() == 2
    with page.expect_download() as dl:
        links.nth(0).click()
    download = dl.value
    saved = Path(download.path()).read_bytes()
    name = download.suggested_filename
    assert name.endswith(".bvh") and (outdir / name).read_bytes() == saved
    assert saved.startswith(b"HIERARCHY")
    from retime.motion import load_motion
    from retime.warp import TimingCurve

    exported = load_motion(outdir / name)
    assert exported.n_frames == len(sol["curve"]["t"])
    warp = TimingCurve.from_csv(outdir / name.replace(".bvh", ".csv"))
    np.testing.assert_allclose(warp.s, sol["curve"]["s"], atol=1e-5)  # the CSV is the curve on screen
    np.testing.assert_allclose(warp.t, t, atol=1e-6)
    page.screenshot(path=str(shots / "editor-3-locked-exported.png"))
    assert not errors, errors
    page.close()


def test_errors_are_shown_and_the_page_keeps_working(browser, server, shots):
    url = server[0]
    errors = []
    page = open_page(browser, url, errors)
    page.fill("#duration", "500")  # far beyond 20x slower: the server refuses
    page.press("#duration", "Enter")
    page.wait_for_selector(".toast")
    text = page.inner_text(".toast")
    assert "outside" in text and "duration" in text
    page.screenshot(path=str(shots / "editor-4-error.png"))
    # still live: a valid duration works
    page.fill("#duration", "2")
    page.press("#duration", "Enter")
    wait_js(page, "Math.abs(window.__retime.solution.duration - 2) < 1e-9")
    assert page.evaluate("document.querySelector('#status').classList.contains('live')")
    assert not [e for e in errors if "400" not in e], errors
    page.close()


def test_guided_blend_slider(browser, server, shots):
    """Guided's reference influence is a slider; at 0 the warp is the spline through the ends (a line)."""
    url = server[0]
    errors = []
    page = open_page(browser, url, errors)
    page.click('#methods button[data-method="guided"]')
    wait_js(page, "window.__retime.solution.method === 'guided'")
    page.fill("#duration", "2.5")
    page.press("#duration", "Enter")
    wait_js(page, "Math.abs(window.__retime.solution.duration - 2.5) < 1e-9")
    straight = ("(() => { const c = window.__retime.solution.curve, n = c.t.length, r = c.s[n - 1] / c.t[n - 1];"
                " return c.t.every((t, k) => Math.abs(c.s[k] - r * t) < 1e-5); })()")  # the page gets 6 decimals
    slider = page.locator("#param-guided-blend")
    assert slider.get_attribute("type") == "range"
    slider.fill("0")  # sets the value and fires input and change
    wait_js(page, "window.__retime.solution.method === 'guided' && window.__retime.params.guided.blend === 0")
    wait_js(page, straight)
    page.screenshot(path=str(shots / "editor-5-blend.png"))
    assert not errors, errors
    page.close()


def test_guided_pace_beside_the_blend_slider(browser, tmp_path, shots):
    """Guided's pace pull is a number beside the blend slider, and the page's value reaches the solve: on
    a walk that slows in a turn, pace 0 gives the command line's pace-0 warp (the default plays it
    apart), and a negative pace is refused in one line."""
    from retime.editor.server import BackgroundServer, create_app, load_clip
    from retime.guided import guided_solve
    from retime.motion import load_motion, save_bvh
    from test_guided_steady import paced_walk

    save_bvh(paced_walk(load_motion(bundled_path("16_15.amc")), turn=True), tmp_path / "walk.bvh")
    clip = load_clip(tmp_path / "walk.bvh")
    (tmp_path / "edits").mkdir()
    with BackgroundServer(create_app(clip, tmp_path / "edits")) as url:
        errors = []
        page = open_page(browser, url, errors)
        page.click('#methods button[data-method="guided"]')
        wait_js(page, "window.__retime.solution.method === 'guided'")
        order = page.evaluate("[...document.querySelectorAll('#params input')].map(e => e.id)")
        assert order.index("param-guided-pace") == order.index("param-guided-blend") + 1
        pace = page.locator("#param-guided-pace")
        assert pace.get_attribute("type") == "number" and pace.get_attribute("min") == "0"
        duration = round(0.6 * clip.motion.n_frames / clip.motion.fps, 3)
        page.fill("#duration", str(duration))
        page.press("#duration", "Enter")
        wait_js(page, f"Math.abs(window.__retime.solution.duration - {duration}) < 1e-9")
        default = page.evaluate("window.__retime.solution.curve")
        pace.fill("0")
        pace.dispatch_event("change")
        wait_js(page, "window.__retime.params.guided.pace === 0 && window.__retime.solution.method === 'guided'")
        moved = f"window.__retime.solution.curve.s.some((s, k) => Math.abs(s - {default['s']}[k]) > 0.1)"
        wait_js(page, moved)
        curve = page.evaluate("window.__retime.solution.curve")
        cli = guided_solve(clip.motion, duration=duration, pace=0.0).curve
        np.testing.assert_allclose(curve["s"], cli(np.array(curve["t"])), atol=2e-6)  # the page gets 6 decimals
        pace.fill("-1")
        pace.dispatch_event("change")
        page.wait_for_selector(".toast")
        assert "Pace pull: -1 is outside 0 .. 100" in page.inner_text(".toast")
        page.screenshot(path=str(shots / "editor-6-pace.png"))
        assert not [e for e in errors if "400" not in e], errors
        page.close()


@pytest.mark.parametrize("method", ["physics", "guided", "linear"])
def test_drag_latency(browser, server, method, capsys, shots):
    """Drag a control point; time each input -> re-solved (reconverged) curve painted on screen."""
    url = server[0]
    errors = []
    page = open_page(browser, url, errors)
    methods = {m["name"]: m for m in page.evaluate("window.__retime.methods")}
    if not methods.get(method, {}).get("available"):
        pytest.skip(f"{method}: {methods.get(method, {}).get('reason', 'not in this build')}")
    page.click("#play")  # paused: the usual state while editing (the 3-D view still redraws each change)
    box = page.locator("#curve").bounding_box()
    settled = "window.__retime.lastFinalSeq === window.__retime.seq"
    if method != "linear":
        page.click(f'#methods button[data-method="{method}"]')
        wait_js(page, f"window.__retime.solution.method === '{method}' && {settled}", timeout=120)
    n = page.evaluate("window.__retime.solution.points.length")
    if n < 4:  # linear, guided: add two points, lock the first (a keytime)
        page.mouse.dblclick(box["x"] + box["width"] * 0.3, box["y"] + box["height"] * 0.45)
        wait_js(page, f"window.__retime.solution.points.length === {n + 1} && {settled}", timeout=30)
        page.mouse.dblclick(box["x"] + box["width"] * 0.6, box["y"] + box["height"] * 0.35)
        wait_js(page, f"window.__retime.solution.points.length === {n + 2} && {settled}", timeout=30)
    lock = 1 if n < 4 else n // 4  # physics: lock one of the spline's control points
    page.click(f'#curve g.cp[data-index="{lock}"]')
    if not page.evaluate(f"window.__retime.solution.points[{lock}].locked"):  # guided adds keytimes locked
        page.keyboard.press("l")
    wait_js(page, f"window.__retime.solution.points[{lock}].locked && {settled}", timeout=30)
    pts = page.evaluate("window.__retime.solution.points")
    i = max(range(1, len(pts) - 1), key=lambda k: (not pts[k]["locked"], -abs(pts[k]["t"] - 0.6 * pts[-1]["t"])))
    page.evaluate("window.__retime.latencies = []")
    deadline = time.monotonic() + (12 if method == "physics" else 20)
    k = 0
    while time.monotonic() < deadline and len(page.evaluate("window.__retime.latencies")) < 30:
        x, y = point_center(page, i)  # (the optimizer may have moved it after the last release)
        dy = (-1) ** k * 0.08 * box["height"]
        drag(page, x, y, x, y + dy, steps=12, pause=0.04 if method == "linear" else 0.12)
        k += 1
        wait_js(page, settled, timeout=30)
    wait_js(page, settled, timeout=30)
    time.sleep(0.2)
    page.screenshot(path=str(shots / f"editor-5-{method}.png"))
    lat = page.evaluate("window.__retime.latencies")
    ms = [x["ms"] for x in lat]
    assert len(ms) >= (8 if method == "linear" else 3), lat
    med, p90 = statistics.median(ms), float(np.percentile(ms, 90))
    solve = statistics.median([x["solve_ms"] for x in lat if x["solve_ms"] is not None])
    frames = page.evaluate("window.__retime.clip.n_frames")
    with capsys.disabled():
        print(f"\n[editor latency] {method}: {CLIP} ({frames} frames), {len(ms)} drag updates: input -> re-solved curve "
              f"on screen median {med:.0f} ms, p90 {p90:.0f} ms (server solve median {solve:.0f} ms; "
              f"headless Chromium with software WebGL on {os.cpu_count()} cores; median queued "
              f"{statistics.median(x['queued_ms'] for x in lat):.0f}, server+network "
              f"{statistics.median(x['network_ms'] for x in lat):.0f}, paint {statistics.median(x['paint_ms'] for x in lat):.0f} ms)")
    assert med < 3000
    assert not errors, errors
    page.close()


def test_a_headless_screenshot_shows_the_3d_view_and_a_rounded_rate(tmp_path):
    """As a user takes one (README): `chromium --headless --use-angle=swiftshader --screenshot`. Without
    that flag this machine's headless Chromium draws an empty 3-D view. A clip captured at
    119.87532965715656 Hz (jumping.bvh's rate) is headed "119.875 Hz", not every digit of the float."""
    import subprocess

    from PIL import Image

    from retime.editor.server import BackgroundServer, create_app, load_clip
    from retime.motion import load_motion, save_bvh

    chromium = require_browser()
    motion = load_motion(bundled_path(CLIP)).frames(slice(0, 240))
    motion.fps = 119.87532965715656
    save_bvh(motion, tmp_path / "odd_rate.bvh")
    flags = ["--headless", "--no-sandbox", "--hide-scrollbars", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
             "--window-size=1400,900", "--virtual-time-budget=8000"]
    with BackgroundServer(create_app(load_clip(tmp_path / "odd_rate.bvh"), tmp_path)) as url:
        shot = tmp_path / "editor.png"
        subprocess.run([chromium, *flags, f"--screenshot={shot}", url + "/"], capture_output=True, timeout=120)
        dom = subprocess.run([chromium, *flags, "--dump-dom", url + "/"], capture_output=True, text=True,
                             timeout=120).stdout
    assert "frames at 119.875 Hz" in dom, dom[:2000]
    with Image.open(shot) as im:
        view = np.asarray(im.convert("RGB").crop((15, 100, 1070, 400)), dtype=int)  # the 3-D view, below its labels
    r, g, b = view[..., 0], view[..., 1], view[..., 2]
    amber = np.sum((r > 170) & (g > 90) & (g < 190) & (b < 90))  # the retimed figure
    blue = np.sum((b > 150) & (r < 140) & (b - r > 50))  # the original
    assert amber > 100 and blue > 100, (amber, blue)
