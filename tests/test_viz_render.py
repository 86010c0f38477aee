"""Skeleton rendering: sizes, frame counts, durations (decoded with PyAV), sync, speed."""


import av
import numpy as np
import pytest

from retime.errors import RetimeError
from retime.viz.render import (
    CONTACT_COLOR,
    Renderer,
    Track,
    _sample,
    frame_count,
    render_video,
    track_from_motion,
)
from retime.viz.video import VideoWriter
from synthetic_figure import synthetic_figure


def _decode(path):
    with av.open(str(path)) as c:
        stream = c.streams.video[0]
        frames = [f for f in c.decode(stream)]
        rate = stream.average_rate
    return frames, rate


@pytest.fixture(scope="module")
def figure():
    return synthetic_figure(241, 120.0)  # 2.0 s


def test_mp4_has_requested_size_frames_and_duration(tmp_path, figure):
    pos, parents, names = figure
    track = Track(pos, parents, 120.0, label="original", names=names)
    out = tmp_path / "one.mp4"
    info = render_video([track], out, fps=30, panel_size=(320, 360))
    frames, rate = _decode(out)
    assert info["frames"] == len(frames) == frame_count(2.0, 30) == 61
    assert (frames[0].width, frames[0].height) == (320, 360)
    assert float(rate) == 30
    # frame k is shown at k / fps: the last frame starts at the motion's duration
    assert frames[-1].time == pytest.approx(2.0, abs=1e-6)


def test_side_by_side_panels_share_the_clock(tmp_path, figure):
    pos, parents, names = figure
    long = Track(pos, parents, 120.0, label="original", names=names)
    short = Track(pos[::2], parents, 120.0, label="linear", names=names, speed=np.full(121, 2.0))
    out = tmp_path / "two.mp4"
    info = render_video([long, short], out, fps=25, panel_size=(240, 270))
    frames, _ = _decode(out)
    assert len(frames) == info["frames"] == 51  # the longest panel: 2.0 s at 25 fps
    assert (frames[0].width, frames[0].height) == (480, 270)


def test_gif_frame_count_and_timing(tmp_path, figure):
    pos, parents, names = figure
    track = Track(pos[:121], parents, 120.0, names=names)  # 1.0 s
    out = tmp_path / "clip.gif"
    render_video([track], out, fps=25, panel_size=(200, 220))
    frames, _ = _decode(out)
    assert len(frames) == 26
    assert (frames[0].width, frames[0].height) == (200, 220)
    assert frames[-1].time == pytest.approx(1.0, abs=0.011)
    # colours survive the palette (the background is light grey, not a hue-shifted one)
    rgb = frames[0].to_ndarray(format="rgb24")
    r, g, b = rgb[5, 100].astype(int)
    assert abs(r - g) < 12 and abs(g - b) < 12 and r > 200


def test_sample_interpolates_linearly(figure):
    pos, parents, names = figure
    speed = np.linspace(0.5, 3.0, pos.shape[0])
    track = Track(pos, parents, 120.0, speed=speed)
    times = np.array([0.0, 0.5 / 120, 1.0, 1.9999, 2.0, 5.0])
    out = _sample(track, times)
    u = np.clip(times * 120, 0, pos.shape[0] - 1)
    for k, uk in enumerate(u):
        expected = np.array([np.interp(uk, np.arange(pos.shape[0]), pos[:, j, 0]) for j in range(pos.shape[1])])
        np.testing.assert_allclose(out["positions"][k, :, 0], expected, atol=1e-12)
    np.testing.assert_allclose(out["speed"], np.interp(u, np.arange(len(speed)), speed))


def test_contacts_are_highlighted(figure):
    pos, parents, names = figure
    contacts = np.zeros(pos.shape[:2], dtype=bool)
    contacts[:, names.index("ltoes")] = True
    plain = Renderer([Track(pos, parents, 120.0, names=names)], fps=10, panel_size=(240, 270)).frame(3)
    marked = Renderer([Track(pos, parents, 120.0, names=names, contacts=contacts)], fps=10, panel_size=(240, 270)).frame(3)

    def n_contact_pixels(img):
        return int(np.sum(np.all(np.abs(img.astype(int) - CONTACT_COLOR) < 30, axis=-1)))

    assert n_contact_pixels(plain) == 0
    assert n_contact_pixels(marked) > 20


def test_camera_follows_the_root(figure):
    pos, parents, names = figure  # walks 2.2 m along +x
    r = Renderer([Track(pos, parents, 120.0, names=names)], fps=10, panel_size=(240, 270))
    panel = r.panels[0]
    root_x = panel.xy[:, 0, 0] / 2  # supersampled pixels -> output pixels
    assert np.all(np.abs(root_x - 120) < 60)  # stays near the middle of the panel
    # ...while the world moves: the (world-fixed) grid lines move across the screen
    _, segs, visible = panel.grid[0]
    both = visible[0] & visible[15]
    assert both.sum() > 5
    assert np.abs(segs[0][both] - segs[15][both]).max() > 20


def test_travel_goes_left_to_right(figure):
    pos, parents, names = figure
    r = Renderer([Track(pos, parents, 120.0, names=names)], fps=10, panel_size=(240, 270), follow_sigma=None)
    panel = r.panels[0]
    # with a (nearly) fixed camera the root moves to the right of the screen
    assert panel.xy[-1, 0, 0] > panel.xy[0, 0, 0]


def test_bad_tracks_are_rejected(figure):
    pos, parents, names = figure
    with pytest.raises(RetimeError, match="parent"):
        Track(pos, parents[:-1], 120.0)
    with pytest.raises(RetimeError, match="NaN"):
        bad = pos.copy()
        bad[3, 2, 1] = np.nan
        Track(bad, parents, 120.0)
    with pytest.raises(RetimeError, match="nothing to render"):
        Renderer([])
    with pytest.raises(RetimeError, match="unsupported video type"):
        VideoWriter("x.avi2", 64, 64, 30)


def test_failed_render_leaves_no_file(tmp_path, figure):
    pos, parents, names = figure
    out = tmp_path / "broken.mp4"
    with pytest.raises(ValueError):
        with VideoWriter(out, 64, 64, 30) as w:
            w.write(np.zeros((64, 64, 3), np.uint8))
            w.write(np.zeros((32, 32, 3), np.uint8))
    assert list(tmp_path.iterdir()) == []


def test_track_from_bundled_motion_is_in_metres():
    from retime.data import bundled_path
    from retime.motion import load_motion
    from retime.warp import apply_timing, uniform_warp

    m = load_motion(bundled_path("16_06.amc"))
    m = m.frames(slice(0, 121))
    track = track_from_motion(m, "original")
    # joints plus end sites (toe tips, finger tips, head top)
    assert track.positions.shape[1] == m.skeleton.n_joints + len(m.skeleton.end_sites)
    height = np.ptp(track.positions[0, :, 1])
    assert 1.4 < height < 2.1
    curve = uniform_warp(m.duration, m.duration / 2)
    fast = apply_timing(m, curve)
    t2 = track_from_motion(fast, "linear", curve=curve)
    np.testing.assert_allclose(t2.speed, 2.0)
    np.testing.assert_allclose(t2.source_time, np.minimum(np.arange(fast.n_frames) / fast.fps * 2, m.duration), atol=1e-9)


def test_report_contacts_follow_the_source_frames(tmp_path):
    """Contacts are per source frame: a panel played through a curve shows those of the frame it shows."""
    import json

    from retime.cli import main
    from retime.data import bundled_path
    from retime.motion import load_motion
    from retime.viz.regions import contacts_through_curve, normalise_report, report_source_contacts
    from retime.warp import uniform_warp

    m = load_motion(bundled_path("16_06.amc")).frames(slice(0, 121))  # 1 s
    curve = uniform_warp(m.duration, 0.5)  # 61 frames at 120 Hz, each showing source frame 2k
    frames = [{"output_time": k / 120, "source_frame": 2 * k,
               "contact": ["left_heel", "left_toe"] if k < 30 else ["right_toe"]} for k in range(61)]
    report = normalise_report({"frames": frames})
    src = report_source_contacts(report, m.skeleton, m.n_frames)
    lfoot, ltoes, rtoes = (m.skeleton.index(n) for n in ("lfoot", "ltoes", "rtoes"))
    assert src[58, lfoot] and src[58, ltoes] and not src[58, rtoes]
    assert src[59, lfoot]  # not shown: nearest shown frame is 58
    assert src[61, rtoes] and not src[61, lfoot]  # nearest shown frame is 60
    played = contacts_through_curve(src, m.fps, curve, 61, 120.0)
    np.testing.assert_array_equal(played, src[::2])
    # the CLI draws them (the report beside the warp)
    path = tmp_path / "report.json"
    path.write_text(json.dumps({"frames": frames}))
    warp = tmp_path / "half.csv"
    curve.to_csv(warp, 120.0)
    out = tmp_path / "c.png"
    assert main(["render", str(bundled_path("16_06.amc")), "--warp", str(warp), "--report", str(path),
                 "--at", "0.1", "-o", str(out), "--size", "240x270"]) == 0
    from PIL import Image

    img = np.asarray(Image.open(out).convert("RGB")).astype(int)
    assert np.sum(np.all(np.abs(img - CONTACT_COLOR) < 30, axis=-1)) > 20
