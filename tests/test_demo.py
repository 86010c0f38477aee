"""`retime demo`: it finishes, writes a report whose links all resolve, and the report loads in a
real headless browser (Chromium) without broken images or external requests."""

import os
import re
import shutil
from pathlib import Path

import av
import pytest

from retime.cli import main
from retime.report.demo import flight_phase, flight_speed, run_demo

CHROMIUM = os.environ.get("RETIME_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


# the jump of 16_06 (crouch, flight, landing) without most of the standing start: a faster
# configuration of the real demo (all methods, small panels, 10 fps video)
FRAMES = (180, 406)


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    return run_demo(out, fps=10, panel_size=(240, 200), quiet=True, frames=FRAMES)


def test_demo_writes_report_and_files(demo):
    html = demo.report_path.read_text()
    assert html.startswith("<!doctype html>")
    links = re.findall(r'(?:src|href)="([^"]+)"', html)
    assert links, "the report links nothing"
    for link in links:
        assert not re.match(r"^[a-z]+:", link), f"not a relative link: {link}"
        assert (demo.out_dir / link).is_file(), f"missing file {link}"
    assert "timing.png" in links and "compare.mp4" in links
    # the numbers are in the report
    lin = next(m for m in demo.methods if m.name == "linear")
    assert f"{lin.curve.duration:.3f} s" in html
    assert "flight speed" in html.lower() and "feasible fraction" in html.lower()
    # every method either ran to the same duration or says why not
    for m in demo.methods:
        if m.curve is None:
            assert m.error and m.error.split(" (")[0] in html
        else:
            assert abs(m.curve.duration - demo.duration) < 1e-9
            assert m.motion.n_frames == round(demo.duration * demo.fps) + 1


def test_demo_video_has_the_longest_duration(demo):
    with av.open(str(demo.out_dir / "compare.mp4")) as c:
        frames = list(c.decode(video=0))
    n_panels = 1 + sum(m.curve is not None for m in demo.methods)
    assert len(frames) == round(demo.source_duration * 10) + 1
    cols = 2 if n_panels == 4 else n_panels
    assert (frames[0].width, frames[0].height) == (240 * cols, 200 * (-(-n_panels // cols)))


def test_linear_flight_speed_is_the_uniform_speed(demo):
    lin = next(m for m in demo.methods if m.name == "linear")
    assert demo.flight is not None, "16_06 is a jump: a flight phase must be found"
    s0, s1 = demo.flight
    assert 0.15 < s1 - s0 < 0.8
    assert lin.flight_speed == pytest.approx(demo.source_duration / demo.duration, rel=1e-6)


def test_all_three_methods_ran(demo):
    """guided and physics are part of the package: the demo must run them, not skip them."""
    errors = {m.name: m.error for m in demo.methods if m.curve is None}
    assert not errors, errors
    assert [m.name for m in demo.methods] == ["linear", "guided", "physics"]
    assert (demo.out_dir / "region.png").is_file()


def test_feasible_fraction_agrees_with_the_physics_report(demo):
    """Feasibility of the physics curve as any curve (p', p'' by differences of its samples) gives the
    report's number (p', p'' of the spline itself): two computations of the derivatives, one test."""
    from retime.physics.regions.feasibility import curve_feasibility

    phys = next(m for m in demo.methods if m.name == "physics")
    if phys.physics is None:
        pytest.skip("the physics method returned no regions")
    mine = curve_feasibility(phys.curve, phys.physics.dynamics, phys.physics.regions, demo.fps).fraction
    assert mine == pytest.approx(phys.feasible_fraction, abs=0.05)
    for m in demo.methods:
        assert 0.0 <= m.feasible_fraction <= 1.0


def test_flight_speed_of_a_curve_that_keeps_the_flight():
    from retime.warp import TimingCurve

    # source 0..3 s into 2 s: flight 1.2..1.6 s plays at 1x, the rest faster
    c = TimingCurve([0.0, 0.6, 1.0, 2.0], [0.0, 1.2, 1.6, 3.0])
    assert flight_speed(c, (1.2, 1.6)) == pytest.approx(1.0)
    assert flight_speed(c, None) is None


def test_flight_phase_of_a_standing_clip_is_none():
    from retime.data import bundled_path
    from retime.motion import load_motion

    m = load_motion(bundled_path("16_06.amc")).frames(slice(0, 100))  # standing still before the jump
    assert flight_phase(m) is None


def test_cli_demo_quick(tmp_path, capsys):
    out = tmp_path / "quick"
    assert main(["demo", "-o", str(out), "--methods", "linear", "--no-video", "--quiet"]) == 0
    assert (out / "report.html").is_file()
    assert "wrote" in capsys.readouterr().out
    assert main(["demo", "-o", str(out), "--methods", "linear,warp9", "--no-video", "--quiet"]) == 2
    assert "unknown method" in capsys.readouterr().err


def _browser_or_skip():
    """Chromium and Playwright, or skip with a reason (fail instead when CI is set)."""
    reason = None
    if not (shutil.which(CHROMIUM) or Path(CHROMIUM).is_file()):
        reason = f"Chromium not found at {CHROMIUM} (apt-get install chromium)"
    else:
        try:
            import playwright.sync_api  # noqa: F401
        except ImportError:
            reason = "Playwright for Python is not installed (pip install playwright)"
    if reason:
        if os.environ.get("CI"):
            pytest.fail(f"CI is set but the browser check cannot run: {reason}")
        pytest.skip(reason)


def test_report_in_headless_chromium(demo):
    _browser_or_skip()
    from playwright.sync_api import sync_playwright

    url = demo.report_path.resolve().as_uri()
    external, failed, errors = [], [], []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.on("request", lambda r: None if r.url.startswith(("file://", "data:")) else external.append(r.url))
            page.on("requestfailed", lambda r: failed.append(r.url))
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(url, wait_until="load")
            images = page.evaluate(
                "() => Array.from(document.images).map(i => ({src: i.getAttribute('src'), ok: i.complete && i.naturalWidth > 0}))"
            )
            video = page.evaluate(
                """() => new Promise(resolve => {
                    const v = document.querySelector('video');
                    if (!v) return resolve(null);
                    const done = () => resolve({ready: v.readyState, error: v.error && v.error.code,
                                                width: v.videoWidth, duration: v.duration});
                    if (v.readyState >= 1) return done();
                    v.addEventListener('loadedmetadata', done);
                    v.addEventListener('error', done, true);
                    setTimeout(done, 10000);
                })"""
            )
            title = page.title()
        finally:
            browser.close()
    assert images, "the report shows no images"
    broken = [i["src"] for i in images if not i["ok"]]
    assert not broken, f"broken images: {broken}"
    assert not failed, f"failed requests: {failed}"
    assert not external, f"the report fetched from outside: {external}"
    assert not errors, errors
    assert "retime demo" in title
    assert video is not None and video["error"] is None and video["ready"] >= 1, video
    assert video["width"] > 0
    assert video["duration"] == pytest.approx(demo.source_duration, abs=0.15)


def _commands(html):
    block = re.search(r'<pre class="commands">(.*?)</pre>', html, re.S).group(1)
    import html as html_module

    return [html_module.unescape(c) for c in re.findall(r"<span>(.*?)</span>", block)]


def test_commands_name_real_paths(demo):
    """The "same from the command line" block: its clip is a file that exists, its outputs the demo's."""
    import shlex

    html = demo.report_path.read_text()
    cmds = _commands(html)
    assert cmds[0] == f"cd {shlex.quote(str(demo.out_dir.resolve()))}"
    for cmd in cmds[1:]:
        if cmd.startswith("#"):
            continue
        files = [w for w in shlex.split(cmd) if re.search(r"\.[a-z]+$", w)]
        assert files and all((demo.out_dir / w).is_file() for w in files), cmd  # the clip's path is absolute
    assert "Retiming CMU 16_06" in html and "mocap.cs.cmu.edu" in html


JUMPING = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "bvh-dev" / "jumping.bvh"


@pytest.mark.skipif(not JUMPING.is_file(), reason="the dev set's jumping.bvh (../shared) is not here")
def test_demo_on_a_z_up_clip_finds_the_flight_physics_finds(tmp_path):
    """jumping.bvh (Z-up, not CMU's): the demo found its flight at 3.44-5.45 s on the raw motion, where
    physics finds 2.44-2.85 s, and so printed flight speeds of 4.25x (guided) and 2.63x (physics);
    titled it "CMU motion capture"; and named src/retime/data/cmu/jumping.bvh in its commands."""
    demo = run_demo(tmp_path, clip=str(JUMPING), video=False, quiet=True)
    phys = next(m for m in demo.methods if m.name == "physics")
    assert phys.curve is not None, phys.error
    flights = [p for p in phys.raw_report["summary"]["phases"] if p["state"] == "flight"]
    longest = max(flights, key=lambda p: p["source_end"] - p["source_start"])
    frame = 1.0 / demo.fps
    assert demo.flight[0] == pytest.approx(longest["source_start"], abs=2 * frame)
    assert demo.flight[1] == pytest.approx(longest["source_end"], abs=2 * frame)
    assert phys.flight_speed == pytest.approx(longest["speed"], rel=0.05)
    html = demo.report_path.read_text()
    assert "CMU" not in html
    assert Path(_commands(html)[1].split()[2]) == JUMPING
