"""One-line refusals instead of silent garbage or tracebacks (issue 22): numbers too large to retime,
a Blender bridge that exits 0 without its output, and messages that name the file."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from retime.errors import RetimeError
from retime.motion import load_motion, save_motion
from test_batch import short_bvh  # noqa: F401 (a fixture)
from test_batch_safety import one_line_error, run


def _with_values(source: Path, target: Path, changes) -> Path:
    """``source`` with frame values replaced: {(frame, channel): text}."""
    lines = source.read_text().split("\n")
    first = next(i for i, ln in enumerate(lines) if ln.startswith("Frame Time")) + 1
    for (frame, channel), text in changes.items():
        values = lines[first + frame].split()
        values[channel] = text
        lines[first + frame] = " ".join(values)
    target.write_text("\n".join(lines))
    return target


@pytest.mark.parametrize("command", [["linear", "--scale", "0.7"], ["guided", "--scale", "0.7", "--fast", "--quiet"]])
def test_channel_values_of_1e308_are_refused_naming_the_line(tmp_path, short_bvh, command):
    huge = _with_values(short_bvh, tmp_path / "huge.bvh", {(0, 0): "1e308", (1, 0): "-1e308"})
    out = tmp_path / "o.bvh"
    code, _, err = run([command[0], str(huge), "-o", str(out), *command[1:]])
    assert code == 2 and not out.exists()
    line = one_line_error(err)
    assert f"{huge}:" in line and "frame 1 holds the value 1e+308" in line, line


def test_an_offset_of_1e20_is_refused_naming_the_file(tmp_path, short_bvh):
    text = short_bvh.read_text()
    first = text.index("OFFSET")
    huge = tmp_path / "offset.bvh"
    huge.write_text(text[:first] + "OFFSET 1e20 0 0" + text[text.index("\n", first):])
    code, _, err = run(["check", str(huge)])
    assert code == 2 and f"{huge}:" in one_line_error(err) and "1e+20" in err


def test_a_motion_with_nan_is_never_written(tmp_path, short_bvh):
    motion = load_motion(short_bvh)
    rotations = motion.rotations.copy()
    rotations[3, 2, 0] = np.nan
    with pytest.raises(RetimeError, match="not finite"):
        save_motion(motion.replace(rotations=rotations), tmp_path / "o.bvh")
    assert not (tmp_path / "o.bvh").exists()


def test_a_bridge_that_exits_0_without_output_is_an_error(tmp_path, short_bvh, monkeypatch):
    monkeypatch.setenv("RETIME_BPY_PYTHON", "/bin/true")
    out = tmp_path / "out.glb"
    code, stdout, err = run(["convert", str(short_bvh), str(out)])
    assert code == 2 and "wrote nothing" in one_line_error(err) and "wrote" not in stdout
    assert not out.exists()
    fbx = tmp_path / "in.fbx"
    fbx.write_bytes(b"not read by /bin/true")
    code, _, err = run(["info", str(fbx)])
    assert code == 2 and f"{fbx}: /bin/true exited without error but wrote nothing" in one_line_error(err)


def test_check_refuses_a_plot_suffix_before_any_work(tmp_path, short_bvh, monkeypatch):
    import retime.physics.check as physics_check

    monkeypatch.setattr(physics_check, "check_clip", lambda *a, **k: pytest.fail("the check ran"))
    code, _, err = run(["check", str(short_bvh), "--plot", str(tmp_path / "p.txt")])
    assert code == 2 and f"{tmp_path / 'p.txt'}: unsupported plot type .txt" in one_line_error(err)


def _chain_bvh(path: Path, joints: int, frames: int = 12) -> Path:
    """A single chain of ``joints`` joints (no legs), swaying."""
    lines = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for i in range(1, joints):
        lines += [f"JOINT j{i}", "{", "OFFSET 0 1 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    lines += ["End Site", "{", "OFFSET 0 1 0", "}"] + ["}"] * joints
    lines += ["MOTION", f"Frames: {frames}", "Frame Time: 0.0333333"]
    for f in range(frames):
        lines.append(" ".join(["0", "10", "0", f"{5 * np.sin(f / 10):.4f}", "0", "0"] + ["1", "0", "0"] * (joints - 1)))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize("command", ["check", "physics"])
def test_a_skeleton_without_legs_is_refused_before_the_dynamics(tmp_path, monkeypatch, command):
    """H2: a 3,000-joint chain took 5 min 48 s and 2.9 GB to be refused by check (physics still took 81 s
    at 2,000 joints: the conform's dummy-root walk); U1: the refusal names the file. Every door to the
    dynamics refuses it before the conform."""
    import retime.physics.model.dynamics as dynamics

    monkeypatch.setattr(dynamics, "conformed", lambda *a, **k: pytest.fail("the conform ran"))
    chain = _chain_bvh(tmp_path / "chain.bvh", 6)
    argv = [command, str(chain)] + (["-o", str(tmp_path / "out.bvh"), "--scale", "0.5"] if command == "physics" else [])
    code, _, err = run(argv)
    assert code == 2 and one_line_error(err).startswith(f"retime {command}: error: {chain}: physics-based retiming "
                                                        "needs a two-legged character")
    assert not (tmp_path / "out.bvh").exists()


def test_check_clip_refuses_a_skeleton_without_legs_before_the_dynamics(tmp_path, monkeypatch):
    import retime.physics.model.dynamics as dynamics
    from retime.physics.check import check_clip

    monkeypatch.setattr(dynamics, "conformed", lambda *a, **k: pytest.fail("the conform ran"))
    chain = _chain_bvh(tmp_path / "chain.bvh", 6)
    with pytest.raises(RetimeError, match=rf"^{chain}: physics-based retiming needs a two-legged character"):
        check_clip(load_motion(chain))


def test_subtree_sizes_match_the_descendants(short_bvh):
    from retime.motion.rig import _subtree_sizes, descendants

    rng = np.random.default_rng(3)
    parents = [-1] + [int(rng.integers(0, k)) for k in range(1, 200)]  # a random tree, parents first
    assert _subtree_sizes(parents) == [len(descendants(parents, j)) for j in range(200)]
    skeleton = load_motion(short_bvh).skeleton
    assert _subtree_sizes(skeleton.parents) == [len(descendants(skeleton.parents, j)) for j in range(skeleton.n_joints)]


def test_a_bone_stretch_names_the_file(short_bvh):
    from retime.physics.model.dynamics import conformed

    motion = load_motion(short_bvh)
    stretched = motion.replace(translations=motion.translations.copy())
    # a leg bone growing to 60 % longer over the clip: made rigid, it moves the foot where it stands
    knee = motion.skeleton.names.index("ltibia")  # its offset is the thigh
    stretched.translations[:, knee] *= np.linspace(1.0, 1.6, motion.n_frames)[:, None]
    with pytest.raises(RetimeError, match=rf"^{short_bvh}: making the bones rigid moves '\w+' by"):
        conformed(stretched)
