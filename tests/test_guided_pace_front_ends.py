"""Guided's pace pull (Settings.pace, ``--pace``) is offered wherever ``--blend`` is: the editor's
panel, batch jobs and the Blender add-on (its bpy-free half here; the operator itself in
test_blender_addon.py). Each front end must hand the value on: on a walk that slows in a turn, pace 0
and the default play measurably apart, and a front end's pace 0 gives the command line's pace 0 warp."""
import numpy as np
import pytest
from _blender_support import addon_module
from test_guided_steady import paced_walk

from retime.cli import main
from retime.errors import RetimeError
from retime.guided.method import Settings
from retime.method import Request, solve
from retime.motion import save_bvh

SCALE = 0.6


@pytest.fixture(scope="module")
def slowing_walk(walk):
    """A walk that slows to 40% in a turn: the pull plays it at one speed, pace 0 keeps the slowdown."""
    return paced_walk(walk, turn=True)


def _warp(motion, pace=None):
    settings = Settings() if pace is None else Settings(pace=pace)
    return solve("guided", motion, Request(scale=SCALE, settings=settings)).curve


def _apart(a, b, duration):
    t = np.linspace(0.0, duration, 200)
    return float(np.abs(a(t) - b(t)).max())


def test_pace_zero_and_the_default_play_the_walk_apart(slowing_walk):
    """The premise of the tests below: the value matters on this clip (the warps differ by > 0.1 s)."""
    a, b = _warp(slowing_walk, 0.0), _warp(slowing_walk)
    assert _apart(a, b, min(a.duration, b.duration)) > 0.1


# ------------------------------------------------------------------------------------------ editor

def _editor_warp(motion, params):
    from retime.editor.methods import Clip, ControlPoint, GuidedMethod, Job, check_params

    clip = Clip("walk", motion)
    S = (motion.n_frames - 1) / motion.fps
    T = S * SCALE
    values = check_params("guided", params, clip)  # as the page's parameters are checked
    job = Job(points=[ControlPoint(0.0, 0.0, True), ControlPoint(T, S, True)], params=values, duration=T)
    return next(iter(GuidedMethod(clip).solve(job))).curve


def test_the_editor_passes_its_pace_on(slowing_walk):
    ours = _editor_warp(slowing_walk, {"pace": 0.0})
    cli = _warp(slowing_walk, 0.0)
    assert _apart(ours, cli, ours.duration) < 1e-9  # the editor's pace 0 is the command line's
    assert _apart(_editor_warp(slowing_walk, {}), _warp(slowing_walk), ours.duration) < 1e-9  # unset: Settings'


def test_the_editor_offers_pace_beside_blend_and_refuses_bad_values():
    from retime.editor.methods import GuidedMethod

    names = [p.name for p in GuidedMethod.params]
    assert names.index("pace") == names.index("blend") + 1
    param, = [p for p in GuidedMethod.params if p.name == "pace"]
    assert param.default == Settings.pace and param.to_json()["min"] == 0.0
    assert param.check("0") == 0.0
    with pytest.raises(RetimeError, match=r"^Pace pull: -1 is outside 0 \.\. 100$"):
        param.check(-1)
    with pytest.raises(RetimeError, match=r"^Pace pull: must be a finite number$"):
        param.check("nan")


# ------------------------------------------------------------------------------------------ batch

def test_a_batch_job_passes_its_pace_on(tmp_path, slowing_walk):
    from retime.batch.jobs import Defaults, find_clips
    from retime.batch.manifest import clip_hash
    from retime.batch.run import clip_task, run_task

    save_bvh(slowing_walk, tmp_path / "walk.bvh")
    save_bvh(slowing_walk, tmp_path / "same_walk.bvh")  # one output per motion file
    jobs = tmp_path / "jobs.csv"
    jobs.write_text(f"motion,scale,pace\nwalk.bvh,{SCALE},0\nsame_walk.bvh,{SCALE},\n")
    still, default = find_clips([str(jobs)], Defaults(), outdir=tmp_path / "out")
    assert still.pace == 0.0 and default.pace is None
    assert clip_task(default, "guided", {}).request.settings == Settings()  # unset: Settings' default
    assert clip_hash(still, "guided", {}) != clip_hash(default, "guided", {})  # a changed pace runs again
    for clip in (still, default):
        outputs = clip.outputs(tmp_path / "out", "guided")
        outputs["bvh"].parent.mkdir(parents=True, exist_ok=True)  # as the batch makes its folders
        done = run_task(clip_task(clip, "guided", outputs))
        assert done["status"] == "done", done["error"]
    assert main(["guided", str(tmp_path / "walk.bvh"), "-o", str(tmp_path / "cli.bvh"), "--scale", str(SCALE),
                 "--pace", "0", "--warp", str(tmp_path / "cli.csv"), "--quiet"]) == 0
    cli = np.loadtxt(tmp_path / "cli.csv", delimiter=",", skiprows=1)
    batch = [np.loadtxt(clip.outputs(tmp_path / "out", "guided")["warp"], delimiter=",", skiprows=1)
             for clip in (still, default)]
    np.testing.assert_array_equal(batch[0], cli)  # the job's pace 0 is the command line's
    assert np.abs(batch[0][:, 1] - batch[1][:, 1]).max() > 0.1


@pytest.mark.parametrize("value", ["-1", "nan", "inf", "fast"])
def test_a_batch_pace_must_be_a_finite_number_at_least_zero(tmp_path, value):
    from retime.batch.jobs import Defaults, find_clips

    jobs = tmp_path / "jobs.csv"
    jobs.write_text(f"motion,scale,pace\nwalk.bvh,0.6,{value}\n")
    want = "is not a number" if value == "fast" else "must be a finite number >= 0"
    with pytest.raises(RetimeError, match=rf"jobs.csv line 2: pace .*{want}") as e:
        find_clips([str(jobs)], Defaults())
    assert "\n" not in str(e.value)


def test_a_batch_pace_is_for_guided(tmp_path, capsys, walk):
    save_bvh(walk, tmp_path / "walk.bvh")
    jobs = tmp_path / "jobs.csv"
    jobs.write_text("motion,scale,pace\nwalk.bvh,0.6,2\n")
    assert main(["batch", str(jobs), "-o", str(tmp_path / "out"), "--method", "linear"]) != 0
    assert "a pace is for --method guided" in capsys.readouterr().err


# ------------------------------------------------------------------------------- Blender add-on

def test_the_add_on_asks_retime_for_its_pace():
    from retime.cli.main import build_parser, parse

    options = addon_module("options")
    assert options.DEFAULTS["pace"] == Settings.pace
    argv = options.command("retime", "guided", "s.bvh", "o.bvh", "w.csv", scale=0.5, pace=0.0)
    assert argv[argv.index("--pace") + 1] == "0"
    args = parse(build_parser(), argv[1:])
    assert args.pace == 0.0
    assert "--pace" not in options.command("retime", "guided", "s.bvh", "o.bvh", "w.csv", scale=0.5)  # default: Settings'
    assert "--pace" not in options.command("retime", "linear", "s.bvh", "o.bvh", "w.csv", scale=0.5, pace=0.0)
