"""One rule for the output's frame count (retime.warp.output_duration), whatever door a request comes
through: the Python wrappers, retime.method.solve, the command line, the editor and batch give the same
number of frames for a scale, a duration and a free duration.

The clips and factors are chosen so that rounding and flooring the frame count disagree: a door that
rounds a scale (as physics_warp once did: 16_06 at 0.6 gave 245 frames against the command's 244)
fails here."""
import csv
import math
import shutil

import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.method import Request, solve
from retime.motion import load_motion, save_bvh
from retime.warp import output_duration

# (clip, first frame, last frame + 1): short pieces, so that physics runs in a few seconds each
PIECES = [("16_06.amc", 180, 407), ("16_33.amc", 0, 213), ("16_03.amc", 120, 303)]
SCALES = (0.6, 0.55, 0.7, 0.65, 0.45, 0.35, 0.4)


def discriminating_scale(n_frames):
    """A scale whose frame count floor and round disagree on (n_frames - 1) * scale."""
    for scale in SCALES:
        exact = (n_frames - 1) * scale
        if 0.55 < exact - math.floor(exact) < 0.95:
            return scale
    raise AssertionError(f"no scale in {SCALES} discriminates {n_frames} frames")


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pieces")
    out = []
    for name, a, b in PIECES:
        path = folder / f"{name.split('.')[0]}_{a}.bvh"
        save_bvh(load_motion(bundled_path(name)).frames(slice(a, b)), path)
        motion = load_motion(path)
        n = motion.n_frames
        scale = discriminating_scale(n)
        # a duration 0.7 of a frame past a whole frame: rounding goes up, flooring down
        duration = (round(0.8 * (n - 1)) + 0.7) / motion.fps
        out.append((path, motion, scale, duration))
    return out


def warp_rows(path):
    with open(path) as f:
        return sum(1 for _ in csv.reader(f)) - 1  # the header


def cli_frames(tmp_path, method, path, *extra):
    warp = tmp_path / f"{method}-{path.stem}-{'_'.join(extra)}.csv"
    argv = [method, str(path), "-o", str(warp.with_suffix(".bvh")), "--warp", str(warp), *extra]
    if method != "linear":
        argv.append("--quiet")
    assert main(argv) == 0
    return warp_rows(warp)


def batch_frames(tmp_path, method, rows):
    """Frames of each row's output through ``retime batch`` (one local worker)."""
    pytest.importorskip("distributed")
    jobs = tmp_path / f"jobs-{method}.csv"
    inputs = tmp_path / f"inputs-{method}"
    inputs.mkdir()
    names = []
    with open(jobs, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["motion", "duration", "scale", "keytimes", "reference", "blend"])
        for k, (path, duration, scale) in enumerate(rows):
            copy = inputs / f"{path.stem}_{k}.bvh"  # one output name per row
            shutil.copyfile(path, copy)
            names.append(copy.stem)
            w.writerow([str(copy), "" if duration is None else repr(duration), "" if scale is None else repr(scale),
                        "", "", ""])
    out = tmp_path / f"batch-{method}"
    assert main(["batch", str(jobs), "-o", str(out), "--method", method, "--workers", "1", "--quiet"]) == 0
    return [warp_rows(out / inputs.name / f"{name}.csv") for name in names]  # mirrored below OUTDIR


def editor_frames(tmp_path, method, motion, duration):
    from retime.editor.methods import Clip
    from retime.editor.sessions import Session

    session = Session("s", Clip("piece", motion), tmp_path, motion.fps)
    session.apply([{"op": "method", "method": method}, {"op": "duration", "duration": duration}])
    return session.export()["frames"]


def test_the_rule(clips):
    for path, motion, scale, duration in clips:
        S, fps = motion.duration, motion.fps
        assert output_duration(S, fps, scale=scale) * fps == pytest.approx(math.floor(S * fps * scale))
        assert output_duration(S, fps, duration=duration) * fps == pytest.approx(round(duration * fps))
        assert output_duration(S, fps) is None


@pytest.mark.parametrize("method", ["linear", "guided"])
def test_linear_and_guided_doors_agree(tmp_path, clips, method):
    from retime.guided import guided_warp
    from retime.guided.method import Settings as GuidedSettings
    from retime.warp import keytime_warp, scale_warp

    def wrapper(motion, duration=None, scale=None, free=False):
        if method == "guided":
            return guided_warp(motion, duration=duration, scale=scale, free=free)
        if scale is not None:
            return scale_warp(motion.duration, scale, motion.fps)
        return keytime_warp(motion.duration, (), output_duration(motion.duration, motion.fps, duration))

    rows = []
    for path, motion, scale, duration in clips:
        fps = motion.fps
        for kind, value in (("scale", scale), ("duration", duration)):
            want = round(output_duration(motion.duration, fps, **{kind: value}) * fps) + 1
            got = {"wrapper": wrapper(motion, **{kind: value}).n_frames(fps),
                   "solve": solve(method, motion, Request(**{kind: value})).curve.n_frames(fps),
                   "cli": cli_frames(tmp_path, method, path, f"--{kind}", repr(value))}
            if kind == "duration":
                got["editor"] = editor_frames(tmp_path, method, motion, value)
            assert got == dict.fromkeys(got, want), (path.name, kind, value)
        rows += [(path, None, scale), (path, duration, None)]
        if method == "guided":  # a free duration: the search's, the same through every door
            free = {"wrapper": wrapper(motion, free=True).n_frames(fps),
                    "solve": solve(method, motion, Request(settings=GuidedSettings(free=True))).curve.n_frames(fps),
                    "cli": cli_frames(tmp_path, method, path, "--free")}
            assert len(set(free.values())) == 1, (path.name, free)
    want = [round(output_duration(load_motion(p).duration, 120.0, d, s) * 120.0) + 1 for p, d, s in rows]
    assert batch_frames(tmp_path, method, rows) == want


def test_physics_doors_agree(tmp_path, clips):
    from retime.physics import physics_warp

    rows, free_counts = [], []
    for path, motion, scale, duration in clips[:2]:
        fps = motion.fps
        for kind, value in (("scale", scale), ("duration", duration)):
            want = round(output_duration(motion.duration, fps, **{kind: value}) * fps) + 1
            got = {"wrapper": physics_warp(motion, **{kind: value}).curve.n_frames(fps),
                   "solve": solve("physics", motion, Request(**{kind: value})).curve.n_frames(fps),
                   "cli": cli_frames(tmp_path, "physics", path, f"--{kind}", repr(value))}
            if kind == "duration":
                got["editor"] = editor_frames(tmp_path, "physics", motion, value)
            assert got == dict.fromkeys(got, want), (path.name, kind, value)
        free = {"wrapper": physics_warp(motion).curve.n_frames(fps),
                "solve": solve("physics", motion, Request()).curve.n_frames(fps),
                "cli": cli_frames(tmp_path, "physics", path)}
        assert len(set(free.values())) == 1, (path.name, free)
        free_counts.append(free["cli"])
        rows += [(path, None, scale), (path, None, None)]
    want = []
    for (path, _, scale), free in zip(rows[::2], free_counts):
        m = load_motion(path)
        want += [round(output_duration(m.duration, m.fps, scale=scale) * m.fps) + 1, free]
    assert batch_frames(tmp_path, "physics", rows) == want
