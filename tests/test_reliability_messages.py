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
