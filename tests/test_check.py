"""``retime check`` against known answers: the bundled jumps are physical as captured; the same jump
with the wrong up axis, scaled by 2.54 or played at double speed is not (exit 1); bad input is 2."""
from __future__ import annotations

import json

import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.motion import load_motion, save_bvh
from retime.motion import variants as V
from retime.warp import apply_timing, scale_warp


def _check(capsys, *args):
    code = main(["check", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out + out.err


@pytest.mark.parametrize("clip", ["16_03.amc", "16_06.amc", "16_15.amc"])
def test_bundled_captures_are_physical(capsys, clip):
    code, out = _check(capsys, bundled_path(clip))
    assert code == 0 and "physical as captured" in out and "NOT" not in out


@pytest.fixture(scope="module")
def jump_bvh(tmp_path_factory):
    path = tmp_path_factory.mktemp("check") / "jump.bvh"
    save_bvh(load_motion(bundled_path("16_06.amc")), path)
    return path


def test_the_wrong_up_axis_is_not_physical(capsys, jump_bvh):
    code, out = _check(capsys, jump_bvh, "--up", "x", "--units", "m")
    assert code == 1 and "NOT physical" in out and "up axis is wrong" in out


def test_scaled_by_2_54_is_not_physical(capsys, jump_bvh, tmp_path):
    big = tmp_path / "big.bvh"
    save_bvh(V.rescale(load_motion(jump_bvh), 2.54), big)  # metres read as if 2.54 times the size
    code, out = _check(capsys, big, "--units", "m")
    assert code == 1 and "NOT physical" in out
    assert _check(capsys, big)[0] == 0  # detected as inches, it is physical again


def test_double_speed_is_not_physical(capsys, jump_bvh, tmp_path):
    m = load_motion(jump_bvh)
    fast = tmp_path / "fast.bvh"
    save_bvh(apply_timing(m, scale_warp(m.duration, 0.5, m.fps)), fast)
    code, out = _check(capsys, fast, "--report", tmp_path / "r.json", "--plot", tmp_path / "p.png")
    assert code == 1 and "NOT physical" in out and "worst frames" in out
    report = json.loads((tmp_path / "r.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    s = report["summary"]
    assert not s["physical"] and s["flight_g"] > 1.4 and len(report["frames"]) == load_motion(fast).n_frames
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_the_plot_shows_the_worst_frame_and_names_the_file(capsys, tmp_path, monkeypatch):
    """16_06's landing was 2.24 body weights: the plot's 99th-percentile scale (1.59) cut it off
    unlabelled, and its title was the whole absolute path. The check now leaves a flight at g and its
    landing out of the verdict, so the clip here is 16_06 played at the wrong rate (Frame Time x0.8),
    whose every frame is judged and whose landing peaks at 3.2 body weights."""
    import numpy as np

    from retime.motion.mistakes import wrong_frame_time
    from retime.viz import check as check_plot

    jump_bvh = tmp_path / "jump.bvh"
    save_bvh(wrong_frame_time(load_motion(bundled_path("16_06.amc")), 0.8), jump_bvh)

    figures = []
    real = check_plot.check_figure
    monkeypatch.setattr(check_plot, "check_figure", lambda c, title="": figures.append((c, real(c, title))) or figures[-1][1])
    assert _check(capsys, jump_bvh.resolve(), "--plot", tmp_path / "p.png")[0] == 1
    (result, fig), = figures
    ax = fig.axes[0]
    worst = int(np.argmax(result.residual))
    assert result.residual[worst] > np.percentile(result.residual, 99) * 1.15  # what the old scale cut off
    assert ax.get_ylim()[1] > result.residual[worst]
    labels = [t.get_text() for t in ax.texts]
    assert f"frame {worst}: {result.residual[worst]:.2f}" in labels
    title = ax.get_title(loc="left")
    assert title.startswith("jump.bvh: ") and str(jump_bvh.parent) not in title
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_bad_input_is_exit_2(capsys, tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT a\n{\n")
    code, out = _check(capsys, bad)
    assert code == 2 and "bad.bvh" in out and "Traceback" not in out


def test_the_documented_imports_work():
    from retime.physics import check_clip, physics_warp  # the README's names

    assert callable(physics_warp) and callable(check_clip)
