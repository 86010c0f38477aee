"""Bad input: one clear line naming the file and the line or frame, exit code 2, no traceback, nothing
written, inputs never overwritten."""
import hashlib
import re
import shutil

import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.errors import RetimeError
from retime.io_util import atomic_write


@pytest.fixture
def clip(tmp_path):
    """Copies of the bundled 16.asf, 16_15.amc and 16_15.bvh in a fresh folder."""
    for name in ("16.asf", "16_15.amc", "16_15.bvh"):
        shutil.copy(bundled_path(name), tmp_path / name)
    return tmp_path


def lines_of(path):
    return path.read_text().splitlines()


def write_lines(path, lines):
    path.write_text("\n".join(lines) + "\n")


def frame_block(lines, number):
    """Index of the AMC line holding frame ``number``."""
    return lines.index(str(number))


def fails_cleanly(capsys, argv, *expect, out=None, line=None):
    """Run the CLI; check exit 2, a single stderr line holding every string in ``expect``, no output."""
    folder = out.parent if out is not None else None
    before = set(folder.iterdir()) if folder else set()
    try:
        rc = main([str(a) for a in argv])
    except SystemExit as e:  # argparse's own errors
        rc = e.code
    captured = capsys.readouterr()
    err = captured.err
    assert rc == 2, err
    assert "Traceback" not in err and captured.out == ""
    assert len(err.strip().splitlines()) == 1, err
    for text in expect:
        assert str(text) in err, (text, err)
    if line is not None:
        assert re.search(rf":{line}: ", err), (line, err)
    if out is not None:
        assert not out.exists()
        assert set(folder.iterdir()) == before  # no temporary file left either
    return err


def linear(src, out, *more):
    return ["linear", src, "-o", out, "--scale", "0.5", *more]


# -- motion files ---------------------------------------------------------------------------------
def test_truncated_bvh_data(capsys, clip):
    path = clip / "16_15.bvh"
    lines = lines_of(path)
    write_lines(path, lines[:-100])
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "371 of 471 frames", "truncated",
                        out=clip / "o.bvh", line=len(lines) - 100)


def test_truncated_bvh_mid_line(capsys, clip):
    path = clip / "16_15.bvh"
    text = path.read_text()
    path.write_text(text[: len(text) - 40])  # the last frame loses its last values
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 471 has", "channels",
                  out=clip / "o.bvh", line=len(lines_of(path)))


def test_truncated_bvh_hierarchy(capsys, clip):
    path = clip / "16_15.bvh"
    write_lines(path, lines_of(path)[:60])
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "truncated", out=clip / "o.bvh", line=60)


@pytest.mark.parametrize("value,what", [("nan", "not finite"), ("abc", "not a number"), ("1e999", "not finite")])
def test_bad_bvh_value(capsys, clip, value, what):
    path = clip / "16_15.bvh"
    lines = lines_of(path)
    k = lines.index("MOTION") + 3 + 9  # the 10th frame
    tokens = lines[k].split()
    tokens[5] = value
    lines[k] = " ".join(tokens)
    write_lines(path, lines)
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 10", what, out=clip / "o.bvh", line=k + 1)


def test_bvh_with_zero_frames(capsys, clip):
    path = clip / "16_15.bvh"
    lines = lines_of(path)
    k = lines.index("MOTION")
    write_lines(path, lines[:k + 1] + ["Frames: 0", "Frame Time: 0.00833333"])
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "zero frames", out=clip / "o.bvh", line=k + 2)


def test_bvh_with_bad_frame_time(capsys, clip):
    path = clip / "16_15.bvh"
    lines = lines_of(path)
    k = lines.index("MOTION")
    lines[k + 2] = "Frame Time: 0"
    write_lines(path, lines)
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "Frame Time", out=clip / "o.bvh", line=k + 3)


def test_truncated_amc(capsys, clip):
    path = clip / "16_15.amc"
    lines = lines_of(path)
    k = frame_block(lines, 300)
    write_lines(path, lines[: k + 12])  # frame 300 stops after 11 bones
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 300", "missing bone", "truncated",
                  out=clip / "o.bvh", line=k + 12)


def test_amc_frame_missing_a_bone(capsys, clip):
    path = clip / "16_15.amc"
    lines = lines_of(path)
    k = frame_block(lines, 10)
    bone = next(i for i in range(k, k + 32) if lines[i].startswith("lfemur "))
    del lines[bone]
    write_lines(path, lines)
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 10", "missing bone(s) lfemur", out=clip / "o.bvh")


def test_amc_unknown_bone(capsys, clip):
    path = clip / "16_15.amc"
    lines = lines_of(path)
    k = frame_block(lines, 5)
    bone = next(i for i in range(k, k + 32) if lines[i].startswith("rtibia "))
    lines[bone] = lines[bone].replace("rtibia", "rshin")
    write_lines(path, lines)
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 5", "unknown bone 'rshin'", "16.asf",
                  out=clip / "o.bvh", line=bone + 1)


@pytest.mark.parametrize("value,what", [("nan", "not finite"), ("NaN", "not finite"), ("x1", "not a number"),
                                        ("inf", "not finite")])
def test_bad_amc_value(capsys, clip, value, what):
    path = clip / "16_15.amc"
    lines = lines_of(path)
    k = frame_block(lines, 42)
    lines[k + 1] = lines[k + 1].rsplit(" ", 1)[0] + " " + value  # root's last value
    write_lines(path, lines)
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 42", "'root'", what, out=clip / "o.bvh", line=k + 2)


def test_amc_bone_with_too_many_values(capsys, clip):
    path = clip / "16_15.amc"
    lines = lines_of(path)
    k = frame_block(lines, 7)
    lines[k + 2] += " 1.5"
    write_lines(path, lines)
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "frame 7", "has 4 values", "3 dof",
                  out=clip / "o.bvh", line=k + 3)


def test_amc_with_zero_frames(capsys, clip):
    path = clip / "16_15.amc"
    write_lines(path, lines_of(path)[:3])
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "zero frames", out=clip / "o.bvh")


def test_missing_skeleton_file(capsys, clip):
    (clip / "16.asf").unlink()
    path = clip / "16_15.amc"
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "no skeleton file", "--asf", out=clip / "o.bvh")


def test_asf_given_but_missing(capsys, clip):
    fails_cleanly(capsys, linear(clip / "16_15.amc", clip / "o.bvh", "--asf", clip / "nope.asf"),
                  clip / "nope.asf", "not found", out=clip / "o.bvh")


def test_truncated_asf(capsys, clip):
    path = clip / "16.asf"
    lines = lines_of(path)
    write_lines(path, lines[: len(lines) // 2])
    fails_cleanly(capsys, linear(clip / "16_15.amc", clip / "o.bvh"), path, "truncated", out=clip / "o.bvh")


def test_missing_motion_file(capsys, clip):
    fails_cleanly(capsys, linear(clip / "nope.bvh", clip / "o.bvh"), clip / "nope.bvh", "not found", out=clip / "o.bvh")
    fails_cleanly(capsys, linear(clip / "16_99.amc", clip / "o.bvh"), clip / "16_99.amc", "not found", out=clip / "o.bvh")
    fails_cleanly(capsys, linear(clip, clip / "o.bvh"), "unknown motion format", out=clip / "o.bvh")
    (clip / "d.bvh").mkdir()
    fails_cleanly(capsys, linear(clip / "d.bvh", clip / "o.bvh"), "folder", out=clip / "o.bvh")


def test_not_a_motion_file(capsys, clip):
    path = clip / "notes.txt"
    path.write_text("hello")
    fails_cleanly(capsys, linear(path, clip / "o.bvh"), path, "unknown motion format", out=clip / "o.bvh")
    bvh = clip / "fake.bvh"
    bvh.write_bytes(b"\x00\x01binary")
    fails_cleanly(capsys, linear(bvh, clip / "o.bvh"), bvh, "binary", out=clip / "o.bvh")


# -- requests ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("keys,what", [
    (["--keytime", "1=2", "--keytime", "2=1"], "out of order"),
    (["--keytime", "10=1"], "outside the clip"),
    (["--keytime=-1=1"], "outside the clip"),
    (["--keytime", "1=100"], "outside the output"),
    (["--keytime", "1.5"], "SRC=DST"),
    (["--keytime", "a=b"], "SRC=DST"),
])
def test_bad_keytimes(capsys, clip, keys, what):
    out = clip / "o.bvh"
    fails_cleanly(capsys, ["linear", clip / "16_15.amc", "-o", out, "--duration", "3", *keys], what, out=out)


@pytest.mark.parametrize("flag,value", [("--duration", "0"), ("--duration", "-2"), ("--scale", "0"),
                                        ("--scale", "nan"), ("--duration", "abc"), ("--fps", "0")])
def test_bad_numbers(capsys, clip, flag, value):
    out = clip / "o.bvh"
    fails_cleanly(capsys, ["linear", clip / "16_15.amc", "-o", out, flag, value, *(["--scale", "2"] if flag == "--fps" else [])],
                  flag, out=out)


def test_never_overwrites_the_input(capsys, clip):
    path = clip / "16_15.bvh"
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    fails_cleanly(capsys, linear(path, path), "overwrite the input")
    fails_cleanly(capsys, ["convert", path, path], "overwrite the input")
    fails_cleanly(capsys, ["linear", path, "-o", clip / "o.bvh", "--scale", "2", "--warp", clip / "o.bvh"], "overwrite",
                  out=clip / "x.bvh")
    alias = clip / "sub" / ".." / "16_15.bvh"
    (clip / "sub").mkdir()
    fails_cleanly(capsys, linear(path, alias), "overwrite the input")
    assert hashlib.sha256(path.read_bytes()).hexdigest() == digest


def test_output_must_be_bvh_in_an_existing_folder(capsys, clip):
    fails_cleanly(capsys, linear(clip / "16_15.amc", clip / "o.txt"), "o.txt", ".bvh", out=clip / "o.txt")
    fails_cleanly(capsys, linear(clip / "16_15.amc", clip / "nowhere" / "o.bvh"), "does not exist")
    fails_cleanly(capsys, ["linear", clip / "16_15.amc", "-o", clip / "o.bvh", "--scale", "2", "--warp", clip / "w.txt"],
                  ".csv", out=clip / "o.bvh")
    (clip / "dir.bvh").mkdir()
    fails_cleanly(capsys, linear(clip / "16_15.amc", clip / "dir.bvh"), "folder")


def test_a_failed_write_leaves_nothing_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "out.bvh"
    with pytest.raises(RuntimeError):
        with atomic_write(target) as f:
            f.write("half a file")
            raise RuntimeError("disk full")
    assert list(tmp_path.iterdir()) == []
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as f:
            f.write("new")
            raise RuntimeError("disk full")
    assert target.read_text() == "old" and list(tmp_path.iterdir()) == [target]
    with atomic_write(target) as f:
        f.write("new")
    assert target.read_text() == "new" and list(tmp_path.iterdir()) == [target]
    with pytest.raises(RetimeError, match="does not exist"):
        with atomic_write(tmp_path / "no" / "x.bvh") as f:
            pass


@pytest.mark.parametrize("flags, message", [(["--duration", "1e9"], "at most"), (["--scale", "1e308"], "at most"),
                                            (["--fps", "1e300", "--duration", "1e10"], "outside 0.001 to 100,000 Hz")])
def test_absurd_output_lengths_are_refused(capsys, clip, flags, message):
    out = clip / "o.bvh"
    fails_cleanly(capsys, ["linear", clip / "16_15.amc", "-o", out, *flags], message, out=out)


def test_a_misspelt_option_points_to_the_command_and_suggests_the_name(capsys, clip):
    """--duraton pointed to 'retime --help' and suggested nothing."""
    out = clip / "o.bvh"
    fails_cleanly(capsys, ["linear", clip / "16_15.amc", "-o", out, "--duraton", "2"], "--duraton",
                  "did you mean --duration?", "(see 'retime linear --help')", out=out)
    fails_cleanly(capsys, ["physics", clip / "16_15.amc", "-o", out, "--gravity-scal=0.5"],
                  "did you mean --gravity-scale?", "(see 'retime physics --help')", out=out)


def test_an_abbreviated_option_is_not_taken_for_the_whole(capsys, clip):
    """--scal 0.5 was silently --scale 0.5: an option added later could change what an old command means."""
    from retime.cli.main import build_parser

    out = clip / "o.bvh"
    fails_cleanly(capsys, ["linear", clip / "16_15.amc", "-o", out, "--scal", "0.5"], "did you mean --scale?", out=out)
    parser = build_parser()
    (commands,) = [a.choices for a in parser._actions if a.choices and "linear" in a.choices]
    assert not parser.allow_abbrev and not any(p.allow_abbrev for p in commands.values())


def test_guided_free_and_fast_is_refused(capsys, clip):
    """--free --fast silently ran the exact search (and said "(exact; ...)"): the heuristic needs a fixed
    output duration, so the combination is one line, before any search."""
    out = clip / "o.bvh"
    fails_cleanly(capsys, ["guided", clip / "16_15.amc", "-o", out, "--free", "--fast"], "--fast", "drop --fast or --free",
                  out=out)


SMALL_BVH = ("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 3 Xrotation Yrotation Zrotation\n End Site\n {\n"
             "  OFFSET 0 1 0\n }\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n0 0 0\n1 1 1\n")


@pytest.mark.parametrize("old,new,line,what", [
    ("  OFFSET 0 1 0\n", "  OFFSET 0 1 0\n  JOINT b\n  {\n   OFFSET 0 1 0\n  }\n", 9, "inside an End Site"),
    ("Frame Time: 0.1", "Frame Time: 1e-320", 13, "Frame Time"),
    ("Frame Time: 0.1", "Frame Time: -0.1", 13, "Frame Time"),
    ("Frames: 2", "Frames: two", 12, "whole number"),
    ("Frame Time: 0.1", "Frame Time: fast", 13, "number of seconds"),
    (" CHANNELS 3 Xrotation Yrotation Zrotation", " CHANNELS 3 Xrotation Yrotation Wrotation", 5, "unknown channel"),
    (" CHANNELS 3 Xrotation Yrotation Zrotation", " CHANNELS 4 Xrotation Yrotation Zrotation", 5, "says 4 but names 3"),
    (" OFFSET 0 0 0\n", " OFFSET 0 0\n", 4, "OFFSET needs 3 numbers"),
    ("ROOT a\n", "ROOT a\n{\n", 4, "'{' without"),
    ("0 0 0\n1 1 1\n", "0 0 0\n1 1\n", 15, "frame 2 has 2 values"),
    ("HIERARCHY\n", "", 1, "HIERARCHY"),
])
def test_bvh_structure_errors(capsys, tmp_path, old, new, line, what):
    path = tmp_path / "s.bvh"
    assert old in SMALL_BVH
    path.write_text(SMALL_BVH.replace(old, new, 1))
    fails_cleanly(capsys, ["info", path], path, what, line=line)


def test_convert_checks_its_output_first(capsys, clip):
    fails_cleanly(capsys, ["convert", clip / "16_15.amc", clip / "o.txt"], ".bvh", out=clip / "o.txt")
    fails_cleanly(capsys, ["convert", clip / "16_15.amc", clip / "16_15.amc"], ".bvh")
    fails_cleanly(capsys, ["convert", clip / "16_15.bvh", clip / "16_15.bvh"], "overwrite the input")


@pytest.mark.parametrize("old,new,line,what", [
    ("  length 0.45", "  length 0", 7, "length unit must be a positive"),
    ("     axis 0 0 20  XYZ", "     axis 0 0 20  XYQ", 30, "permutation of XYZ"),
    ("    dof rx ry rz", "    dof rx ry rw", 31, "unknown dof 'rw'"),
    ("     length 7.78223   ", "     length -7.78223", 40, "must not be negative"),
    ("     direction 0.34202 -0.939693 0   ", "     direction 0.34202 -0.939693", 39, "direction needs 3 numbers"),
    ("     direction 0.34202 -0.939693 0   ", "     direction 0.34202 nan 0", 39, "not finite"),
    ("     length 7.78223   ", "", 36, "no length"),
    ("     name ltibia", "     name lfemur", 36, "defined twice"),
    ("    lfemur ltibia", "    lfemur lshin", None, "unknown bone 'lshin'"),
    ("   order TX TY TZ RX RY RZ", "   order TX TY TZ RX RY RQ", 13, "root order"),
])
def test_asf_errors(capsys, clip, old, new, line, what):
    path = clip / "16.asf"
    lines = path.read_text().splitlines()
    assert old in lines, old
    lines[lines.index(old)] = new
    write_lines(path, lines)
    fails_cleanly(capsys, ["info", clip / "16_15.amc"], path, what, line=line)
