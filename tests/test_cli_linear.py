"""The info, convert and linear commands on the bundled clips, in-process and as a real subprocess."""
import shutil
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from retime.cli import main
from retime.data import bundled_path
from retime.motion import forward_kinematics, load_motion
from retime.warp import TimingCurve


def run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def angle_between(a, b):
    return (Rotation.from_quat(a.reshape(-1, 4)).inv() * Rotation.from_quat(b.reshape(-1, 4))).magnitude().max()


def test_info(capsys):
    rc, out, err = run(capsys, "info", bundled_path("16_06.amc"))
    assert rc == 0 and err == ""
    assert "frames    407" in out and "fps       120" in out and "joints    31" in out
    assert "duration  3.3833 s" in out and "lfemur" in out and "rx ry rz" in out


def test_convert_amc_to_bvh(capsys, tmp_path, jump):
    out_path = tmp_path / "jump.bvh"
    rc, out, err = run(capsys, "convert", bundled_path("16_06.amc"), out_path)
    assert rc == 0 and err == "" and "407 frames" in out
    m = load_motion(out_path)
    assert m.n_frames == 407 and m.fps == 120.0
    np.testing.assert_allclose(forward_kinematics(m)[0], forward_kinematics(jump)[0], atol=1e-5)


def test_scale_half_gives_the_even_frames(capsys, tmp_path, jump):
    out_path, warp = tmp_path / "fast.bvh", tmp_path / "fast.csv"
    rc, out, err = run(capsys, "linear", bundled_path("16_06.amc"), "-o", out_path, "--scale", "0.5", "--warp", warp)
    assert rc == 0 and err == ""
    m = load_motion(out_path)
    assert m.n_frames == 204 and m.fps == 120.0
    assert angle_between(m.rotations, jump.rotations[::2]) < 1e-7  # 6 printed decimals of a degree
    np.testing.assert_allclose(m.translations[:, 0], jump.translations[::2, 0], atol=1e-6)
    rows = warp.read_text().splitlines()
    assert rows[0] == "output_time,source_time" and len(rows) == 205
    assert [float(x) for x in rows[1].split(",")] == [0.0, 0.0]
    t_end, s_end = (float(x) for x in rows[-1].split(","))
    assert t_end == pytest.approx(203 / 120) and s_end == pytest.approx(406 / 120)
    curve = TimingCurve.from_csv(warp)
    np.testing.assert_allclose(curve(np.arange(204) / 120), 2 * np.arange(204) / 120, atol=1e-9)


def test_scale_half_on_a_bvh(capsys, tmp_path):
    src = load_motion(bundled_path("131_01.bvh"))
    out_path = tmp_path / "fast.bvh"
    rc, _, _ = run(capsys, "linear", bundled_path("131_01.bvh"), "-o", out_path, "--scale", "0.5")
    assert rc == 0
    m = load_motion(out_path)
    assert m.n_frames == src.n_frames // 2  # 994 frames: the last (odd) one has no even partner
    assert angle_between(m.rotations, src.rotations[:-1:2]) < 1e-7
    np.testing.assert_allclose(forward_kinematics(m)[0], forward_kinematics(src.frames(slice(0, -1, 2)))[0], atol=1e-5)


def test_keytimes_land_on_their_frames(capsys, tmp_path, jump):
    out_path = tmp_path / "keyed.bvh"
    rc, out, _ = run(capsys, "linear", bundled_path("16_06.amc"), "-o", out_path, "--duration", "2.5",
                     "--keytime", "1.5=0.75", "--keytime", "2.5=2.0", "--smooth")
    assert rc == 0
    m = load_motion(out_path)
    assert m.n_frames == 301
    for src, dst in [(1.5, 0.75), (2.5, 2.0), (0.0, 0.0), (jump.duration, 2.5)]:
        i, k = int(round(src * 120)), int(round(dst * 120))
        assert angle_between(m.rotations[k], jump.rotations[i]) < 1e-7, (src, dst)


def test_duration_and_fps(capsys, tmp_path, jump):
    out_path = tmp_path / "slow.bvh"
    rc, _, _ = run(capsys, "linear", bundled_path("16_06.amc"), "--fps", "60", "-o", out_path, "--duration", "10")
    assert rc == 0
    m = load_motion(out_path)
    assert m.fps == 60.0 and m.n_frames == 601 and m.duration == pytest.approx(10.0)


@pytest.mark.parametrize("command", ["info", "convert", "linear"])
def test_help_has_an_example(command, capsys):
    with pytest.raises(SystemExit) as e:
        main([command, "--help"])
    assert e.value.code == 0
    assert "example" in capsys.readouterr().out


def test_console_script_end_to_end(tmp_path):
    exe = shutil.which("retime")
    cmd = [exe] if exe else [sys.executable, "-c", "import sys; from retime.cli import main; sys.exit(main())"]
    out_path = tmp_path / "fast.bvh"
    ok = subprocess.run(cmd + ["linear", str(bundled_path("16_33.amc")), "-o", str(out_path), "--scale", "0.5"],
                        capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert "wrote" in ok.stdout and load_motion(out_path).n_frames == 143
    bad = tmp_path / "bad.bvh"
    bad.write_text(bundled_path("16_15.bvh").read_text()[:5000])
    fail = subprocess.run(cmd + ["linear", str(bad), "-o", str(tmp_path / "x.bvh"), "--scale", "2"],
                          capture_output=True, text=True, timeout=120)
    assert fail.returncode == 2
    assert "Traceback" not in fail.stderr and len(fail.stderr.strip().splitlines()) == 1
    assert str(bad) in fail.stderr
    assert not (tmp_path / "x.bvh").exists()
