"""Timing and speed plots, the physics region plot, contact strip and report reading."""

import json

import numpy as np
import pytest
from PIL import Image

from retime.cli import main
from retime.errors import FormatError, RetimeError
from retime.viz.plot import label_from_path, plot_timing, speed_samples
from retime.viz.regions import (
    load_report,
    pick_frame,
    plot_contact_strip,
    plot_regions,
    report_contacts,
)
from retime.warp import TimingCurve, keytime_warp, uniform_warp


def test_timing_plot_has_requested_size(tmp_path):
    curves = [("linear", uniform_warp(3.0, 1.5)), ("smooth", keytime_warp(3.0, [(1.0, 0.2)], 1.5, smooth=True))]
    out = tmp_path / "t.png"
    plot_timing(curves, out, size=(8.0, 3.5), dpi=100)
    with Image.open(out) as im:
        assert im.size == (800, 350)
    svg = tmp_path / "t.svg"
    plot_timing(curves, svg)
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text
    assert "linear" in text and "smooth" in text  # legend labels (text kept as glyph ids or text)


def test_speed_samples_are_the_segment_slopes():
    c = TimingCurve([0, 1, 2, 4], [0, 0.5, 2.5, 3.0])
    t, v = speed_samples(c)
    np.testing.assert_allclose(t, [0, 1, 2, 4])
    np.testing.assert_allclose(v, [0.5, 2.0, 0.25, 0.25])
    smooth = keytime_warp(3.0, [(1.0, 0.5)], 2.0, smooth=True)
    t, v = speed_samples(smooth, n=50)
    np.testing.assert_allclose(v, smooth.speed(t))


def test_cli_plot_labels_from_file_names(tmp_path, capsys):
    a = tmp_path / "16_06_linear.csv"
    b = tmp_path / "16_06_guided.csv"
    uniform_warp(3.0, 1.5).to_csv(a, 30)
    keytime_warp(3.0, [(1.0, 0.3)], 1.5).to_csv(b, 30)
    out = tmp_path / "speeds.svg"
    assert main(["plot", str(a), str(b), "-o", str(out)]) == 0
    assert "2 timing curve(s)" in capsys.readouterr().out
    assert label_from_path(a) == "16_06_linear"
    assert "16_06_guided" in out.read_text()
    assert main(["plot", str(a), "-o", str(tmp_path / "x.jpg")]) == 2
    assert ".png, .svg or .pdf" in capsys.readouterr().err
    assert main(["plot", str(a), "--label", "one", "--label", "two", "-o", str(tmp_path / "y.png")]) == 2


def _fake_report(n=120):
    frames = []
    for k in range(n):
        flight = 40 <= k < 70
        poly = [[-0.1, 0.9], [0.1, 0.9], [0.1, 1.1], [-0.1, 1.1]] if flight else [[-2, 0], [3, 0], [4, 2.5], [0.5, 3.2], [-3, 1.8]]
        frames.append({
            "t": k / 60, "s": k / 30, "pdd": 0.1, "pd2": 4.0 if flight else 1.5,
            "feasible": not flight, "distance": 2.9 if flight else 0.0, "torque_norm": 50.0 + k,
            "contacts": [] if flight else ["lfoot", "ltoes", "rfoot"],
            "region": poly,
        })
    return {"feasible_fraction": 0.75, "frames": frames}


def test_region_plot_and_strip(tmp_path):
    path = tmp_path / "r.json"
    path.write_text(json.dumps(_fake_report()))
    report = load_report(path)
    assert pick_frame(report) == 40  # the first of the frames farthest from their region
    out = tmp_path / "region.png"
    assert plot_regions(report, None, out, size=(9.0, 5.0), dpi=100) == 40
    with Image.open(out) as im:
        assert im.size == (900, 500)
    plot_contact_strip(report, tmp_path / "strip.png", size=(6.0, 2.0), dpi=100)
    with Image.open(tmp_path / "strip.png") as im:
        assert im.size == (600, 200)
    with pytest.raises(RetimeError, match="outside the report"):
        plot_regions(report, 500, tmp_path / "no.png")
    # CLI
    assert main(["plot", "--regions", str(path), "--frame", "10", "-o", str(tmp_path / "c.png")]) == 0


def test_report_contacts_map_to_joints():
    from retime.data import bundled_path
    from retime.motion import load_motion

    sk = load_motion(bundled_path("16_06.amc")).skeleton
    report = {"frames": [{"contacts": ["left_heel", "ltoe"]}, {"contacts": {"rfoot": True, "rtoes": False}}, {"contacts": []}]}
    from retime.viz.regions import normalise_report

    c = report_contacts(normalise_report(report), sk, 3)
    assert c.shape == (3, sk.n_joints)
    assert set(np.nonzero(c[0])[0]) == {sk.index("lfoot"), sk.index("ltoes")}
    assert set(np.nonzero(c[1])[0]) == {sk.index("rfoot")}
    assert not c[2].any()


def test_bad_reports_are_format_errors(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{"frames": [\n{"t": 0,}\n]}')
    with pytest.raises(FormatError, match=r"bad.json:2: not valid JSON"):
        load_report(p)
    p.write_text('{"something": 1}')
    with pytest.raises(FormatError, match="not a physics report"):
        load_report(p)
