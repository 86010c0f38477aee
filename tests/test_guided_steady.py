"""Guided's steady objective (issue 23): steady motion plays steadily, the ends keep the skip limit,
--blend runs from the keytime spline warp to the guided warp."""
import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.guided import guided_solve
from retime.guided.steady import points_per_step, speed_costs
from retime.motion import Motion, load_motion
from retime.phases import interval_speed
from retime.warp import keytime_warp

BUNDLED = ["16_03.amc", "16_06.amc", "16_15.amc", "16_15.bvh", "16_16.amc", "16_33.amc", "131_01.bvh"]


def step_speeds(curve, fps):
    t = curve.frame_times(fps)
    return np.diff(curve(t)) / np.diff(t)


def sine_walk(base: Motion, seconds=4.0, hz=1.1):
    """A periodic "walk": every joint swings about x as a sine of its own phase, the root moves on."""
    fps = base.fps
    t = np.arange(int(seconds * fps)) / fps
    J = base.skeleton.n_joints
    amp = np.linspace(0.2, 0.6, J)
    phase = np.linspace(0.0, 2 * np.pi, J, endpoint=False)
    theta = amp * np.sin(2 * np.pi * hz * t[:, None] + phase)
    rot = np.zeros((len(t), J, 4))
    rot[..., 0] = np.sin(theta / 2)
    rot[..., 3] = np.cos(theta / 2)
    tr = np.repeat(base.translations[:1], len(t), axis=0).copy()
    tr[:, 0, 0] = base.translations[0, 0, 0] + 20.0 * t  # forward at a constant pace (file units)
    tr[:, 0, 1] = base.translations[0, 0, 1] + 0.5 * np.sin(4 * np.pi * hz * t)  # bounce, twice a cycle
    return Motion(base.skeleton, rot, tr, fps)


@pytest.fixture(scope="module")
def periodic(walk):
    return sine_walk(walk)


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_periodic_motion_plays_at_a_steady_speed(periodic, scale):
    res = guided_solve(periodic, scale=scale)
    v = step_speeds(res.curve, periodic.fps)
    cut = len(v) // 20
    mid = v[cut:len(v) - cut]
    assert mid.std() / mid.mean() < 0.02
    assert mid.max() / mid.min() < 1.05
    assert np.median(mid) == pytest.approx(1 / scale, rel=0.02)


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_paper_score_plays_the_periodic_motion_in_blocks(periodic, scale):
    """The defect the steady score removes: whole-frame steps and a linear score give blocks of speed."""
    res = guided_solve(periodic, scale=scale, score="paper")
    v = step_speeds(res.curve, periodic.fps)
    cut = len(v) // 20
    mid = v[cut:len(v) - cut]
    assert mid.max() / mid.min() > 1.5


@pytest.mark.parametrize("scale", [0.6, 1.5])
@pytest.mark.parametrize("clip", BUNDLED)
def test_ends_keep_the_skip_limit(clip, scale):
    motion = load_motion(bundled_path(clip))
    res = guided_solve(motion, scale=scale)
    v = step_speeds(res.curve, motion.fps)
    assert v[0] <= res.s / res.upsample[0] + 1e-9
    assert v[-1] <= res.s / res.upsample[-1] + 1e-9
    # no pop: the first and last steps are within a factor of 1.5 of their neighbours' mean
    for end, near in ((v[0], v[1:6]), (v[-1], v[-6:-1])):
        assert 1 / 1.5 <= end / near.mean() <= 1.5


def test_blend_zero_is_the_spline_warp(jump):
    keys = [(1.2, 0.8)]
    res = guided_solve(jump, scale=0.6, keytimes=keys, blend=0.0)
    spline = keytime_warp(jump.duration, keys, res.curve.duration, smooth=True)
    t = res.curve.frame_times(jump.fps)
    assert np.array_equal(res.curve(t), spline(t))


def test_blend_moves_the_flight_speed_monotonically(jump):
    from retime.physics.contacts import foot_contacts
    from retime.phases import longest_flight

    a, b = longest_flight(foot_contacts(jump), np.arange(jump.n_frames) / jump.fps)
    speeds = [interval_speed(guided_solve(jump, scale=0.6, blend=w).curve, a, b) for w in (0.0, 0.25, 0.5, 0.75, 1.0)]
    assert speeds[0] == pytest.approx(1 / 0.6, rel=0.02)  # the spline plays the flight like the rest
    assert speeds[-1] == pytest.approx(1.0, abs=0.05)  # guided at its natural speed
    assert all(x > y for x, y in zip(speeds, speeds[1:]))


def test_blend_keeps_keytimes_and_range(jump):
    res = guided_solve(jump, duration=2.0, keytimes=[(1.5, 0.9)], blend=0.4)
    assert float(res.curve(0.9)) == pytest.approx(1.5, abs=1e-9)
    assert float(res.curve(0.0)) == 0.0 and float(res.curve(2.0)) == pytest.approx(jump.duration)


def test_blend_keeps_a_keytime_between_frames(jump):
    """A keytime whose output time falls between frames (0.9042 s at 120 Hz) holds in the mix too."""
    res = guided_solve(jump, duration=2.0, keytimes=[(1.5, 0.9042)], blend=0.4)
    assert float(res.curve(0.9042)) == pytest.approx(1.5, abs=1e-9)


def test_blend_and_score_errors(jump):
    from retime.errors import RetimeError

    with pytest.raises(RetimeError, match="blend"):
        guided_solve(jump, scale=0.6, blend=1.5)
    with pytest.raises(RetimeError, match="unknown score"):
        guided_solve(jump, scale=0.6, score="fancy")


def test_natural_and_mean_speed_both_on_the_fine_grid():
    # --scale 0.6 on a self-referenced compression: 5 grid frames per 3 output frames, 1x = 1 grid frame
    L = points_per_step(5, 3, 1.0)
    assert (1.0 * 3 * L / 5) == pytest.approx(round(3 * L / 5))
    # --scale 1.5 on the upsampled grid (2 grid frames per analysis frame): 4 per 3, 1x = 2
    L = points_per_step(4, 3, 2.0)
    assert (2.0 * 3 * L / 4) == pytest.approx(round(2.0 * 3 * L / 4))


def test_speed_costs_fill_the_ends_from_their_neighbours():
    F = np.full((6, 2, 8), np.inf)
    F[1:5, 0, 0] = [1.0, 2.0, 3.0, 4.0]
    F[2:4, 1, 1] = [5.0, 6.0]
    D = speed_costs(F)
    assert D[:, 0].tolist() == [1.0, 1.0, 2.0, 3.0, 4.0, 4.0]
    assert D[:, 1].tolist() == [5.0, 5.0, 5.0, 6.0, 6.0, 6.0]


def test_cli_blend_and_score(tmp_path, capsys):
    src = str(bundled_path("16_06.amc"))
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["guided", src, "-o", str(tmp_path / "a.bvh"), "--scale", "0.6", "--blend", "0", "--warp", str(a),
                 "--quiet"]) == 0
    assert main(["linear", src, "-o", str(tmp_path / "b.bvh"), "--scale", "0.6", "--warp", str(b)]) == 0
    ours = np.loadtxt(a, delimiter=",", skiprows=1)
    line = np.loadtxt(b, delimiter=",", skiprows=1)
    # no keytimes: the spline through the ends is the uniform warp (to the last frame's rounding)
    np.testing.assert_allclose(ours[:, 1], ours[:, 0] * ours[-1, 1] / ours[-1, 0], atol=1e-9)
    assert ours.shape == line.shape
    assert main(["guided", src, "-o", str(tmp_path / "c.bvh"), "--scale", "0.6", "--score", "paper", "--quiet"]) == 0
    with pytest.raises(SystemExit):
        main(["guided", src, "-o", str(tmp_path / "d.bvh"), "--scale", "0.6", "--blend", "2"])
    assert "from 0 to 1" in capsys.readouterr().err


def test_batch_blend_column(tmp_path):
    from retime.batch.jobs import Defaults, find_clips
    from retime.batch.run import clip_task
    from retime.guided.method import Settings
    from retime.errors import RetimeError

    jobs = tmp_path / "jobs.csv"
    jobs.write_text(f"motion,scale,blend\n{bundled_path('16_06.amc')},0.6,0.25\n{bundled_path('16_03.amc')},0.6,\n")
    a, b = find_clips([str(jobs)], Defaults())
    assert a.blend == 0.25 and b.blend is None
    assert clip_task(a, "guided", a.outputs(tmp_path, "guided")).request.settings.blend == 0.25
    assert clip_task(b, "guided", b.outputs(tmp_path, "guided")).request.settings == Settings()
    jobs.write_text(f"motion,scale,blend\n{bundled_path('16_06.amc')},0.6,1.5\n")
    with pytest.raises(RetimeError, match=r"jobs.csv line 2: blend must be a number from 0 to 1"):
        find_clips([str(jobs)], Defaults())


def test_batch_blend_is_for_guided(tmp_path, capsys):
    jobs = tmp_path / "jobs.csv"
    jobs.write_text(f"motion,scale,blend\n{bundled_path('16_06.amc')},0.6,0.5\n")
    assert main(["batch", str(jobs), "-o", str(tmp_path / "out"), "--method", "linear"]) != 0
    assert "a blend is for --method guided" in capsys.readouterr().err


def test_editor_offers_blend_as_a_slider():
    from retime.editor.methods import GuidedMethod
    from retime.errors import RetimeError

    param, = [p for p in GuidedMethod.params if p.name == "blend"]
    d = param.to_json()
    assert d["kind"] == "slider" and (d["min"], d["max"]) == (0.0, 1.0)
    assert param.check("0.3") == 0.3
    with pytest.raises(RetimeError, match="outside 0 .. 1"):
        param.check(1.2)


def test_front_ends_leave_the_defaults_to_settings():
    """Settings holds the defaults of score, steadiness and blend: the command line passes only what is
    given and names Settings' values in its help, the editor's slider starts at Settings.blend."""
    import argparse

    from retime.cli.main import build_parser
    from retime.editor.methods import GuidedMethod
    from retime.guided.api import SCORES
    from retime.guided.method import Settings

    guided = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices["guided"]
    options = {a.dest: a for a in guided._actions}
    assert all(options[name].default is None for name in ("score", "steadiness", "blend"))
    assert tuple(options["score"].choices) == SCORES and f"{Settings.score} (default" in options["score"].help
    assert f"default {Settings.steadiness:g}" in options["steadiness"].help
    param, = [p for p in GuidedMethod.params if p.name == "blend"]
    assert param.default == Settings.blend == 1.0 and "default" in options["blend"].help
