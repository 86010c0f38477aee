"""Applying timing curves to videos (frame index drawn in each frame) and to CSV / NPY signals."""

from fractions import Fraction

import av
import numpy as np
import pytest

from retime.cli import main
from retime.errors import FormatError, RetimeError
from retime.viz.video import apply_to_signal, apply_to_video, retime_frames
from retime.warp import TimingCurve, keytime_warp, uniform_warp

W, H, BITS = 128, 64, 8


def _index_frame(k: int) -> np.ndarray:
    """Top half: the frame index as 8 black/white blocks (MSB first); bottom half: grey 20 + 3k."""
    img = np.zeros((H, W, 3), np.uint8)
    for b in range(BITS):
        if (k >> (BITS - 1 - b)) & 1:
            img[: H // 2, b * 16 : (b + 1) * 16] = 255
    img[H // 2 :] = 20 + 3 * k
    return img


def _read_index(img: np.ndarray) -> int:
    top = img[4 : H // 2 - 4].astype(float).mean(axis=(0, 2))
    bits = [top[b * 16 + 4 : (b + 1) * 16 - 4].mean() > 127 for b in range(BITS)]
    return int(sum(1 << (BITS - 1 - i) for i, bit in enumerate(bits) if bit))


def _grey(img: np.ndarray) -> float:
    return float(img[H // 2 + 6 : H - 6, 6:-6].astype(float).mean())


@pytest.fixture(scope="module")
def index_video(tmp_path_factory):
    """60 frames at 30 fps (duration 59/30 s), written independently of retime's writer."""
    path = tmp_path_factory.mktemp("video") / "index.mp4"
    with av.open(str(path), "w") as c:
        s = c.add_stream("libx264", rate=Fraction(30))
        s.width, s.height, s.pix_fmt = W, H, "yuv420p"
        s.options = {"qp": "0"}
        for k in range(60):
            for p in s.encode(av.VideoFrame.from_ndarray(_index_frame(k), format="rgb24")):
                c.mux(p)
        for p in s.encode():
            c.mux(p)
    return path


def _decode(path):
    with av.open(str(path)) as c:
        stream = c.streams.video[0]
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(stream)]
        rate = float(stream.average_rate)
    return frames, rate


def test_source_video_decodes(index_video):
    frames, rate = _decode(index_video)
    assert [_read_index(f) for f in frames] == list(range(60))
    assert rate == 30


@pytest.mark.parametrize(
    "curve",
    [
        uniform_warp(59 / 30, 1.0),  # twice as fast
        uniform_warp(59 / 30, 4.0),  # half speed: frames repeat
        keytime_warp(59 / 30, [(1.0, 0.4)], duration=1.5),  # fast, then slow
        keytime_warp(59 / 30, [(0.5, 1.0), (1.5, 1.2)], duration=1.9, smooth=True),
    ],
)
def test_nearest_frame_sequence(tmp_path, index_video, curve):
    out = tmp_path / "out.mp4"
    info = apply_to_video(curve, index_video, out)
    frames, rate = _decode(out)
    t = curve.frame_times(30)
    expected = np.floor(curve(t) * 30 + 0.5 + 1e-9).astype(int)
    assert rate == 30
    assert len(frames) == info["frames"] == len(t) == int(round(curve.duration * 30)) + 1
    assert [_read_index(f) for f in frames] == expected.tolist()


def test_output_fps_differs_from_input(tmp_path, index_video):
    curve = uniform_warp(59 / 30, 59 / 30)
    out = tmp_path / "out60.mp4"
    apply_to_video(curve, index_video, out, fps=60)
    frames, rate = _decode(out)
    assert rate == 60 and len(frames) == 119
    expected = np.floor(curve(curve.frame_times(60)) * 30 + 0.5 + 1e-9).astype(int)
    assert [_read_index(f) for f in frames] == expected.tolist()


def test_blend_mixes_neighbours(tmp_path, index_video):
    curve = uniform_warp(59 / 30, 59 / 15)  # half speed: every other output frame is halfway
    out = tmp_path / "blend.mp4"
    apply_to_video(curve, index_video, out, blend=True)
    frames, _ = _decode(out)
    u = curve(curve.frame_times(30)) * 30
    grey = np.array([_grey(f) for f in frames])
    np.testing.assert_allclose(grey, 20 + 3 * u, atol=4.0)  # H.264 at crf 20 moves flat greys a little
    # exactly, before encoding: each output frame is (1 - w) * frame[i] + w * frame[i + 1]
    source, _ = _decode(index_video)
    mixed = list(retime_frames(((k / 30, f) for k, f in enumerate(source)), u / 30, blend=True))
    for k, img in enumerate(mixed):
        i = min(int(np.floor(u[k] + 1e-9)), 58)
        w = u[k] - i
        want = source[i] * (1 - w) + source[i + 1] * w
        assert np.max(np.abs(img - want)) <= 0.5 + 1e-3  # rounded to the nearest level


def test_retime_frames_streams_in_order():
    frames = [(k / 10, np.full((2, 2, 3), k, np.uint8)) for k in range(5)]
    q = np.array([0.0, 0.04, 0.05, 0.16, 0.4, 0.9])
    got = [int(f[0, 0, 0]) for f in retime_frames(iter(frames), q)]
    assert got == [0, 0, 1, 2, 4, 4]
    blended = [float(f[0, 0, 0]) for f in retime_frames(iter(frames), np.array([0.25]), blend=True)]
    assert blended == [3.0]  # 2.5 rounds half up


def test_curve_longer_than_video_is_refused(tmp_path, index_video):
    curve = uniform_warp(3.0, 1.0)
    with pytest.raises(RetimeError, match="--fit"):
        apply_to_video(curve, index_video, tmp_path / "x.mp4")
    assert not (tmp_path / "x.mp4").exists()
    info = apply_to_video(curve, index_video, tmp_path / "fit.mp4", fit=True)
    frames, _ = _decode(tmp_path / "fit.mp4")
    assert _read_index(frames[-1]) == 59 and info["frames"] == 31


def test_signal_csv_with_time_column(tmp_path):
    src = tmp_path / "sig.csv"
    t = np.arange(121) / 120
    rows = ["time,force_x,force_y"] + [f"{a:.9f},{np.sin(a):.9f},{a * a:.9f}" for a in t]
    src.write_text("\n".join(rows) + "\n")
    curve = keytime_warp(1.0, [(0.5, 0.2)], duration=0.8)
    out = tmp_path / "sig_out.csv"
    info = apply_to_signal(curve, src, out, out_fps=100)
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    assert out.read_text().splitlines()[0] == "time,force_x,force_y"
    tt = curve.frame_times(100)
    assert info["frames"] == len(tt) == 81
    np.testing.assert_allclose(data[:, 0], tt, atol=1e-8)
    s = curve(tt)
    np.testing.assert_allclose(data[:, 1], np.interp(s, t, np.sin(t)), atol=1e-8)
    np.testing.assert_allclose(data[:, 2], np.interp(s, t, t * t), atol=1e-8)


def test_signal_npy_needs_a_rate(tmp_path):
    values = np.random.default_rng(0).normal(size=(61, 3, 2))
    src = tmp_path / "x.npy"
    np.save(src, values)
    curve = uniform_warp(1.0, 0.5)
    with pytest.raises(RetimeError, match="--fps"):
        apply_to_signal(curve, src, tmp_path / "y.npy")
    apply_to_signal(curve, src, tmp_path / "y.npy", fps=60)
    out = np.load(tmp_path / "y.npy")
    assert out.shape == (31, 3, 2)
    np.testing.assert_allclose(out, values[::2], atol=1e-12)


def test_signal_errors_name_the_line(tmp_path):
    src = tmp_path / "bad.csv"
    src.write_text("a,b\n1,2\n3,x\n")
    with pytest.raises(FormatError, match=r"bad.csv:3: not a number"):
        apply_to_signal(uniform_warp(1, 1), src, tmp_path / "o.csv", fps=1)


def test_cli_apply(tmp_path, index_video, capsys):
    warp = tmp_path / "w.csv"
    uniform_warp(59 / 30, 1.0).to_csv(warp, 30)
    out = tmp_path / "cli.mp4"
    assert main(["apply", str(warp), str(index_video), "-o", str(out), "--quiet"]) == 0
    assert "31 frames" in capsys.readouterr().out
    frames, _ = _decode(out)
    assert len(frames) == 31
    # never over an input
    assert main(["apply", str(warp), str(index_video), "-o", str(index_video)]) == 2
    assert "refusing" in capsys.readouterr().err
    # a warp file that is not one
    bad = tmp_path / "bad.csv"
    bad.write_text("hello\n")
    assert main(["apply", str(bad), str(index_video), "-o", str(tmp_path / "z.mp4")]) == 2
    assert "bad.csv" in capsys.readouterr().err


def test_timing_curve_from_csv_roundtrip_matches(tmp_path):
    # guards the assumption that warps read from CSV evaluate like the curve that wrote them
    c = keytime_warp(2.0, [(1.0, 0.5)], duration=1.5, smooth=True)
    c.to_csv(tmp_path / "c.csv", 30)
    d = TimingCurve.from_csv(tmp_path / "c.csv")
    t = c.frame_times(30)
    np.testing.assert_allclose(d(t), c(t), atol=1e-8)
