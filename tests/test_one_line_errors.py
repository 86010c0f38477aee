"""One-line errors where there were tracebacks (issue 12: 5), each reproduced."""
from __future__ import annotations

import json
import shutil

import pytest

from test_cli_errors import fails_cleanly
from retime.data import bundled_path
from retime.motion import load_motion

CLIP = bundled_path("16_33.amc")


def test_a_chain_of_thousands_of_joints_is_written(tmp_path, capsys):
    n = 3000
    text = ["HIERARCHY", "ROOT j0", "{", "OFFSET 0 0 0", "CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation"]
    for k in range(1, n):
        text += [f"JOINT j{k}", "{", "OFFSET 0 0.01 0", "CHANNELS 3 Zrotation Xrotation Yrotation"]
    text += ["End Site", "{", "OFFSET 0 0.01 0", "}"] + ["}"] * n
    text += ["MOTION", "Frames: 2", "Frame Time: 0.1", " ".join(["0"] * (6 + 3 * (n - 1)))] * 1
    text += [" ".join(["0.5"] * (6 + 3 * (n - 1)))]
    path = tmp_path / "deep.bvh"
    path.write_text("\n".join(text) + "\n")
    from retime.cli import main

    assert main(["convert", str(path), str(tmp_path / "out.bvh"), "--units", "m"]) == 0
    assert load_motion(tmp_path / "out.bvh", units="m").skeleton.n_joints == n


def test_an_empty_npy_is_one_line(tmp_path, capsys):
    warp = tmp_path / "w.csv"
    warp.write_text("output_time,source_time\n0,0\n1,1\n")
    empty = tmp_path / "x.npy"
    empty.write_bytes(b"")
    fails_cleanly(capsys, ["apply", warp, empty, "-o", tmp_path / "y.npy"], "x.npy", out=tmp_path / "y.npy")


def test_a_corrupt_video_is_one_line(tmp_path, capsys):
    warp = tmp_path / "w.csv"
    warp.write_text("output_time,source_time\n0,0\n1,1\n")
    video = tmp_path / "v.mp4"
    video.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(range(256)) * 20)
    fails_cleanly(capsys, ["apply", warp, video, "-o", tmp_path / "o.mp4"], "v.mp4", out=tmp_path / "o.mp4")


def test_a_contact_file_that_is_not_utf8_is_one_line(tmp_path, capsys):
    contacts = tmp_path / "c.csv"
    contacts.write_bytes(b"point,first,last\nleft,0,\xff\xfe10\n")
    fails_cleanly(capsys, ["physics", CLIP, "-o", tmp_path / "o.bvh", "--contacts", contacts], "not UTF-8",
                  out=tmp_path / "o.bvh", line=2)


def test_an_amc_frame_number_that_is_no_number_is_one_line(tmp_path, capsys):
    for name in ("16_33.amc", "16.asf"):
        shutil.copy(bundled_path(name), tmp_path / name)
    amc = tmp_path / "16_33.amc"
    text = amc.read_text().replace("\n2\n", "\n\u00b2\n", 1)
    amc.write_text(text)
    fails_cleanly(capsys, ["info", amc], "16_33.amc")


def test_a_report_holding_nan_is_one_line(tmp_path, capsys):
    from retime.physics.api import physics_warp
    from retime.physics.report import write_report

    r = physics_warp(load_motion(CLIP).frames(slice(0, 60)), scale=0.7)
    path = tmp_path / "r.json"
    write_report(r.report, path)
    data = json.loads(path.read_text())
    data["frames"][3]["p_ddot"] = float("nan")
    path.write_text(json.dumps(data))
    fails_cleanly(capsys, ["plot", "--regions", path, "--frame", "3", "-o", tmp_path / "p.png"], "not finite",
                  out=tmp_path / "p.png")


@pytest.mark.parametrize("length", ["1e-308", "1e-320"])
def test_an_absurd_asf_length_unit_is_one_line(tmp_path, capsys, length):
    asf = tmp_path / "16.asf"
    asf.write_text(bundled_path("16.asf").read_text().replace("length 0.45", f"length {length}"))
    shutil.copy(bundled_path("16_33.amc"), tmp_path / "16_33.amc")
    fails_cleanly(capsys, ["convert", tmp_path / "16_33.amc", tmp_path / "o.bvh"], "length", out=tmp_path / "o.bvh")


@pytest.mark.parametrize("flags", [["--gravity", "1e308,0,0"], ["--gravity", "inf,0,0"], ["--gravity-scale", "1e300"],
                                   ["--mass", "lfemur=1e300"]])
def test_huge_physics_settings_are_one_line(tmp_path, capsys, flags):
    fails_cleanly(capsys, ["physics", CLIP, "-o", tmp_path / "o.bvh", *flags], flags[0], out=tmp_path / "o.bvh")
