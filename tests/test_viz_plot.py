"""Timing and speed plots, the physics region plot, contact strip and report reading."""


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


@pytest.fixture(scope="module")
def physics_report(jump):
    """A real physics report (what ``retime physics --report`` writes) of the jump's 1.9 s around the
    flight at a third of its duration, with the regions per source frame as the demo stores them."""
    from retime.method import Request, solve

    r = solve("physics", jump.frames(slice(180, 407)), Request(scale=0.35))
    data = r.report.to_json()
    regions = r.detail.regions
    data["regions"] = [np.asarray(regions.polygon(i), dtype=float).round(6).tolist() for i in range(regions.n_frames)]
    return data


def test_region_plot_and_strip(tmp_path, physics_report):
    from retime.physics.report import write_report

    path = tmp_path / "r.json"
    write_report(physics_report, path)
    report = load_report(path)
    dist = [f["distance"] for f in physics_report["frames"]]
    assert max(dist) > 0  # a third of the duration leaves frames outside their region
    assert pick_frame(report) == int(np.argmax(dist))  # the first of the frames farthest from their region
    assert report["feasible_fraction"] == physics_report["summary"]["feasible_fraction"]
    out = tmp_path / "region.png"
    assert plot_regions(report, None, out, size=(9.0, 5.0), dpi=100) == int(np.argmax(dist))
    with Image.open(out) as im:
        assert im.size == (900, 500)
    plot_contact_strip(report, tmp_path / "strip.png", size=(6.0, 2.0), dpi=100)
    with Image.open(tmp_path / "strip.png") as im:
        assert im.size == (600, 200)
    with pytest.raises(RetimeError, match="outside the report"):
        plot_regions(report, 5000, tmp_path / "no.png")
    # CLI
    assert main(["plot", "--regions", str(path), "--frame", "10", "-o", str(tmp_path / "c.png")]) == 0


def test_a_plain_physics_report_has_the_regions_to_plot(tmp_path):
    """README: `retime physics 16_06.amc --report h.json`, then `retime plot --regions h.json --frame 40`.
    The report used to hold no region (only the demo stored them: "no region stored for this frame");
    each frame's stored region now agrees with the report's own distance of its timing to the region."""
    from retime.data import bundled_path
    from retime.viz.regions import _polygon_distance

    report_path = tmp_path / "h.json"
    assert main(["physics", str(bundled_path("16_06.amc")), "-o", str(tmp_path / "h.bvh"), "--scale", "0.5",
                 "--report", str(report_path), "--quiet"]) == 0
    report = load_report(report_path)
    frames = report["frames"]
    assert all(f["region"] is not None and len(f["region"]) >= 3 for f in frames)
    distance = np.array([_polygon_distance(np.array([f["point"]]), f["region"])[0] for f in frames])
    np.testing.assert_allclose(distance, [f["distance"] for f in frames], atol=2e-2)  # 4 significant digits
    assert report_path.stat().st_size < 200 * 1024 + 400 * len(frames)  # compact: a few hundred bytes a frame
    assert main(["plot", "--regions", str(report_path), "--frame", "40", "-o", str(tmp_path / "r.png")]) == 0


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
