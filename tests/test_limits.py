"""Bounded memory and no silently wrong output (issue 12: 4 and 6): refused up front, in one line."""
from __future__ import annotations

import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.errors import FormatError
from retime.motion import load_motion, save_bvh

CLIP = bundled_path("16_06.amc")


def _err(args, capsys):
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.err


def _bvh(tmp_path, frame_time="0.0083333", frames=None, extra_rows=0):
    m = load_motion(CLIP).frames(slice(0, 40))
    path = tmp_path / "a.bvh"
    save_bvh(m, path)
    lines = path.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("Frame Time"))
    lines[k] = f"Frame Time: {frame_time}"
    if frames is not None:
        lines[k - 1] = f"Frames: {frames}"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_an_output_too_big_for_memory_is_refused_before_it_is_made(tmp_path, capsys):
    code, err = _err(["linear", CLIP, "-o", tmp_path / "o.bvh", "--duration", "8e4"], capsys)
    assert code == 2 and "would need about" in err and "RETIME_MAX_MEMORY" in err and "Traceback" not in err
    assert not (tmp_path / "o.bvh").exists()


def test_the_memory_limit_can_be_set(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("RETIME_MAX_MEMORY", "1M")
    code, err = _err(["linear", CLIP, "-o", tmp_path / "o.bvh", "--scale", "0.5"], capsys)
    assert code == 2 and "limit of" in err
    monkeypatch.setenv("RETIME_MAX_MEMORY", "2G")
    assert _err(["linear", CLIP, "-o", tmp_path / "o.bvh", "--scale", "0.5"], capsys)[0] == 0


@pytest.mark.parametrize("frame_time", ["1000000", "1e-300", "1e308"])
def test_frame_rates_outside_a_sane_range_are_refused(tmp_path, capsys, frame_time):
    path = _bvh(tmp_path, frame_time)
    code, err = _err(["guided", path, "-o", tmp_path / "o.bvh", "--scale", "0.5"], capsys)
    assert code == 2 and "outside 0.001 to 100,000 Hz" in err and str(path) in err


def test_a_tiny_fps_option_is_refused(tmp_path, capsys):
    code, err = _err(["linear", CLIP, "-o", tmp_path / "o.bvh", "--scale", "1", "--fps", "1e-320"], capsys)
    assert code == 2 and "outside" in err and not (tmp_path / "o.bvh").exists()


def test_rows_beyond_the_declared_frames_are_said(tmp_path, capsys):
    path = _bvh(tmp_path, frames=2)
    code, err = _err(["linear", path, "-o", tmp_path / "o.bvh", "--scale", "1"], capsys)
    assert code == 0 and "38 more frame row(s) after the 2" in err


def test_offsets_that_read_back_are_written(tmp_path):
    """Every bit of an offset survives the writer, up to the reader's limit (1e12, beyond any length)."""
    m = load_motion(CLIP).frames(slice(0, 5))
    m.skeleton.offsets[3] = [999999999999.9999, 1e-320, -0.1]
    path = tmp_path / "big.bvh"
    save_bvh(m, path)
    back = load_motion(path, units="m")
    assert np.array_equal(back.skeleton.offsets[3], m.skeleton.offsets[3])


def test_an_offset_beyond_any_length_is_refused_on_its_line(tmp_path):
    m = load_motion(CLIP).frames(slice(0, 5))
    m.skeleton.offsets[3] = [1.7976931348623157e308, 0.0, -0.1]
    path = tmp_path / "big.bvh"
    save_bvh(m, path)
    line = 1 + next(i for i, text in enumerate(path.read_text().splitlines()) if "1.7976931348623157e+308" in text)
    with pytest.raises(FormatError, match=rf"^{path}:{line}: OFFSET holds the value 1.79769e\+308"):
        load_motion(path, units="m")


@pytest.mark.parametrize("option", [["--approx", "nan"], ["--smoothing", "-7"], ["--approx", "inf"]])
def test_bad_guided_numbers_are_refused(tmp_path, capsys, option):
    with pytest.raises(SystemExit) as e:
        main(["guided", str(CLIP), "-o", str(tmp_path / "o.bvh"), *option])
    assert e.value.code == 2
    assert option[0] in capsys.readouterr().err


def test_physics_is_refused_before_it_would_exhaust_memory(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("RETIME_MAX_MEMORY", "8M")  # 16_06: planned as 12.6 MB (1,000 bytes a frame and joint)
    code, err = _err(["physics", CLIP, "-o", tmp_path / "o.bvh", "--scale", "0.5"], capsys)
    assert code == 2 and "physics on 407 frames would need about" in err and not (tmp_path / "o.bvh").exists()
