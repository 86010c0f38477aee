"""Capture glitches (issue 23): a few frames that jump away from the motion and back are played as a
gap, so a steady walk with one glitch still plays at one speed; smooth fast motion is left alone."""
import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.guided import guided_solve
from retime.guided import api as guided_api
from retime.guided.features import pose_pair
from retime.guided.glitches import fill_glitches, find_glitches
from retime.method import Request, solve
from retime.guided.method import Settings
from retime.phases import interval_speed, longest_flight

from test_guided_steady import sine_walk, step_speeds

FPS = 120.0


def smooth_poses(frames=600, dims=12, seed=0):
    """A smooth, periodic pose signal (F, D) at FPS."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / FPS
    return np.sin(2 * np.pi * rng.uniform(0.5, 2.0, dims) * t + rng.uniform(0, 2 * np.pi, dims))


def middle_cv(curve, fps):
    v = step_speeds(curve, fps)
    cut = len(v) // 20
    mid = v[cut:len(v) - cut]
    return mid.std() / mid.mean()


@pytest.fixture
def no_glitch_filling(monkeypatch):
    monkeypatch.setattr(guided_api, "find_glitches", lambda poses, fps: [])


def test_a_single_frame_spike_is_found_and_filled_on_the_line_through_its_neighbours():
    x = smooth_poses()
    x[300] += 3.0
    glitches = find_glitches(x, FPS)
    assert [(g.first, g.last) for g in glitches] == [(300, 300)]
    filled = fill_glitches(x, glitches)
    assert np.allclose(filled[300], 0.5 * (x[299] + x[301]))
    assert np.array_equal(np.delete(filled, 300, axis=0), np.delete(x, 300, axis=0))


def test_a_glitch_at_the_start_is_continued_from_the_frames_after_it():
    x = smooth_poses()
    x[:2] += 3.0  # the clip starts in a pose it leaves in one jump (CMU 16_15)
    glitches = find_glitches(x, FPS)
    assert [(g.first, g.last) for g in glitches] == [(0, 1)]
    filled = fill_glitches(x, glitches)
    assert np.allclose(filled[:2], x[2] + np.arange(-2, 0)[:, None] * (x[3] - x[2]))


@pytest.mark.parametrize("case", ["step", "fast", "long run", "float32 and rescaled"])
def test_what_is_not_a_glitch(case):
    x = smooth_poses()
    if case == "step":  # a jump that persists
        x[300:] += 3.0
    elif case == "fast":  # 20 frames of movement 40x faster than the rest, smooth frame to frame
        x[300:320] += np.linspace(0, 1, 20)[:, None] * 40 * np.abs(np.diff(x, axis=0)).mean() * 20
        x[320:] = x[320:] + (x[319] - x[320])
    elif case == "long run":  # 0.1 s away and back: longer than a glitch
        x[300:312] += 3.0
    else:
        x[300] += 3.0
        got = find_glitches((x * 100.0).astype(np.float32), FPS)
        assert [(g.first, g.last) for g in got] == [(300, 300)]
        return
    assert find_glitches(x, FPS) == []


def glitched_walk(walk, first, last):
    """The sine walk with frames first..last-1 turned far away (every joint below the root 106 degrees)."""
    motion = sine_walk(walk)
    rot = motion.rotations.copy()
    rot[first:last, 1:] = [0.0, 0.8, 0.0, 0.6]
    return type(motion)(motion.skeleton, rot, motion.translations, motion.fps)


@pytest.mark.parametrize("where", ["start", "end"])
def test_a_walk_with_a_glitch_at_an_end_plays_at_a_steady_speed(walk, where, no_glitch_filling, monkeypatch):
    n = sine_walk(walk).n_frames
    motion = glitched_walk(walk, *((0, 2) if where == "start" else (n - 2, n)))
    # without the pace pull (which alone now plays this walk steadily) the glitch's effect shows
    unfilled = middle_cv(guided_solve(motion, scale=0.6, pace=0.0).curve, motion.fps)
    monkeypatch.undo()
    res = guided_solve(motion, scale=0.6)
    assert unfilled > 0.05  # played at 1x, the glitch makes the rest of the warp drift
    assert middle_cv(guided_solve(motion, scale=0.6, pace=0.0).curve, motion.fps) < 0.02
    assert middle_cv(res.curve, motion.fps) < 0.02
    assert np.median(step_speeds(res.curve, motion.fps)) == pytest.approx(1 / 0.6, rel=0.02)


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_a_walk_with_one_glitch_frame_plays_at_a_steady_speed(walk, scale):
    motion = glitched_walk(walk, 160, 161)
    res = guided_solve(motion, scale=scale)
    assert middle_cv(res.curve, motion.fps) < 0.02
    assert np.median(step_speeds(res.curve, motion.fps)) == pytest.approx(1 / scale, rel=0.02)


def test_16_15_plays_steadily_and_says_why(walk):
    answer = solve("guided", walk, Request(None, 0.6, (), Settings()))
    assert middle_cv(answer.curve, walk.fps) < 0.05
    (warning,) = answer.report.summary["warnings"]
    assert "frames 0-1" in warning and "capture glitch" in warning


def test_a_glitch_in_another_reference_is_filled_and_named(walk):
    clean = sine_walk(walk)
    answer = solve("guided", clean, Request(None, 0.6, (), Settings(reference=glitched_walk(walk, 0, 2))))
    assert middle_cv(answer.curve, clean.fps) < 0.02
    (warning,) = answer.report.summary["warnings"]
    assert warning.startswith("reference frames 0-1")


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_a_real_flight_is_not_a_glitch(jump, scale, monkeypatch):
    from retime.motion.feet import foot_contacts

    x, _ = pose_pair(jump, jump, 1.0)
    assert find_glitches(x, jump.fps) == []
    a, b = longest_flight(foot_contacts(jump), np.arange(jump.n_frames) / jump.fps)
    speed = interval_speed(guided_solve(jump, scale=scale).curve, a, b)
    assert speed == pytest.approx(1.0, abs=0.05)


def test_cli_prints_the_glitch_warning(tmp_path, capsys):
    out = tmp_path / "w.bvh"
    assert main(["guided", str(bundled_path("16_15.amc")), "--scale", "0.6", "-o", str(out), "--quiet"]) == 0
    assert "warning: source frames 0-1" in capsys.readouterr().out
