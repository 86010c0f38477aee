"""Apply a timing curve to other per-frame data: a video file, or a CSV / NPY signal.

Hsu et al. (2007, Fig. 4) warp the video taken during the capture session with the time warp
computed for the motion.  Output frame k (at output time t_k = k / fps) shows the source at time
s = curve(t_k): the nearest source frame, or with ``blend`` a linear mix of the two source frames
around s.  The video is streamed (timing curves are monotone, so the decoder only moves forward),
so memory use does not grow with the length of the clip.  Audio is not carried over: a retimed
sound track would need pitch-preserving time stretching, which is out of scope.
"""

from __future__ import annotations

import csv
import io
import math
import os
import queue
import threading
from fractions import Fraction
from tokenize import TokenError
from typing import Iterator, Sequence

import numpy as np

from retime.errors import FormatError, RetimeError

VIDEO_EXTS = {".mp4", ".mkv", ".mov", ".avi", ".webm", ".gif", ".m4v"}
TIME_COLUMNS = {"time", "t", "time_s", "seconds", "timestamp"}


def _check_curve_fits(curve, source_duration: float, frame_period: float, path: str, fit: bool):
    """Scale factor from the curve's source time to the data's time (1 unless ``fit``)."""
    S = float(curve.source_duration)
    if fit:
        if S <= 0:
            raise RetimeError(f"{path}: the timing curve has zero source duration; cannot --fit")
        return source_duration / S
    tol = max(1.5 * frame_period, 0.01 * max(source_duration, S))
    if S > source_duration + tol:
        raise RetimeError(
            f"{path}: the timing curve needs {S:.3f} s of source but the input lasts only {source_duration:.3f} s; "
            "use --fit to stretch the curve onto the input, or give the matching input"
        )
    if S < source_duration - tol:
        raise RetimeError(
            f"{path}: the timing curve covers {S:.3f} s of source but the input lasts {source_duration:.3f} s; "
            "use --fit to stretch the curve onto the input, or give the matching input"
        )
    return 1.0


# ---------------------------------------------------------------------- video
def probe_video(path: str | os.PathLike) -> dict:
    """{'fps', 'frames', 'width', 'height', 'duration'} of a video's first stream (decodes to count)."""
    import av

    path = os.fspath(path)
    try:
        with av.open(path) as container:
            if not container.streams.video:
                raise FormatError(path, "no video stream in this file")
            stream = container.streams.video[0]
            rate = stream.average_rate or stream.guessed_rate
            times = [f.time for f in container.decode(stream)]
    except _av_errors(av) as exc:
        raise FormatError(path, f"cannot read video ({exc})") from None
    if not times:
        raise FormatError(path, "the video has no frames")
    fps = float(rate) if rate else (len(times) - 1) / max(times[-1] - times[0], 1e-9)
    return {
        "fps": fps,
        "frames": len(times),
        "width": stream.codec_context.width,
        "height": stream.codec_context.height,
        "duration": (len(times) - 1) / fps,
        "times": np.asarray([t - times[0] if t is not None else i / fps for i, t in enumerate(times)]),
    }


def _av_errors(av) -> tuple:
    """PyAV's reading errors, whatever its version names them: every one derives from FFmpegError
    (and from a builtin such as ValueError or OSError; av.error.ValueError is gone in PyAV 18)."""
    return tuple(e for e in (getattr(av.error, "FFmpegError", None), ValueError, OSError, EOFError) if e is not None)


def _decode(path: str) -> Iterator[tuple[float, np.ndarray]]:
    """(time from the first frame in seconds, RGB uint8 frame) for each frame of the first video stream."""
    import av

    try:
        container = av.open(path)
    except _av_errors(av) as exc:
        raise FormatError(path, f"cannot read video ({exc})") from None
    with container:
        if not container.streams.video:
            raise FormatError(path, "no video stream in this file")
        stream = container.streams.video[0]
        stream.thread_type = "AUTO"
        rate = stream.average_rate or stream.guessed_rate
        fps = float(rate) if rate else 30.0
        t0 = None
        try:
            for i, frame in enumerate(container.decode(stream)):
                t = frame.time if frame.time is not None else i / fps
                if t0 is None:
                    t0 = t
                yield t - t0, frame.to_ndarray(format="rgb24")
        except _av_errors(av) as exc:
            raise FormatError(path, f"corrupt video data ({exc})") from None


def retime_frames(
    frames: Iterator[tuple[float, np.ndarray]],
    query_times: np.ndarray,
    blend: bool = False,
) -> Iterator[np.ndarray]:
    """For each (nondecreasing) source query time, the nearest frame or a blend of the two around it.

    ``frames`` yields (source time, image) in increasing time.  Query times before the first frame
    or after the last give the first / last frame.
    """
    it = iter(frames)
    try:
        t_a, f_a = next(it)
    except StopIteration:
        raise RetimeError("the input video has no frames") from None
    nxt = next(it, None)
    for q in np.asarray(query_times, dtype=np.float64):
        while nxt is not None and nxt[0] <= q:
            t_a, f_a = nxt
            nxt = next(it, None)
        if nxt is None or q <= t_a:
            yield f_a
            continue
        t_b, f_b = nxt
        w = (q - t_a) / (t_b - t_a)
        if blend:
            if w < 1e-6:
                yield f_a
            elif w > 1 - 1e-6:
                yield f_b
            else:
                mix = f_a.astype(np.float32) * (1.0 - w) + f_b.astype(np.float32) * w
                yield np.clip(mix + 0.5, 0, 255).astype(np.uint8)
        else:
            # nearest frame; exact halves go to the later frame (1e-9 s slack for rounding)
            yield f_b if w >= 0.5 - 1e-9 else f_a


def apply_to_video(
    curve,
    input_path: str | os.PathLike,
    output_path: str | os.PathLike,
    fps: float | None = None,
    blend: bool = False,
    fit: bool = False,
    quiet: bool = True,
) -> dict:
    """Retime a video with ``curve`` (output time -> source time in seconds from the first frame).

    Returns {'frames', 'fps', 'width', 'height', 'duration'} of the written video.
    """
    from retime.viz.progress import progress

    input_path, output_path = os.fspath(input_path), os.fspath(output_path)
    info = probe_video(input_path)
    out_fps = float(fps) if fps else info["fps"]
    if not (out_fps > 0 and math.isfinite(out_fps)):
        raise RetimeError(f"output fps must be positive, got {fps}")
    scale = _check_curve_fits(curve, info["duration"], 1.0 / info["fps"], input_path, fit)
    t_out = np.asarray(curve.frame_times(out_fps), dtype=np.float64)
    queries = np.maximum.accumulate(np.asarray(curve(t_out), dtype=np.float64) * scale)
    w, h = info["width"], info["height"]
    ext = os.path.splitext(output_path)[1].lower()
    pad = ext != ".gif" and (w % 2 or h % 2)
    ow, oh = w + (w % 2 if pad else 0), h + (h % 2 if pad else 0)
    with VideoWriter(output_path, ow, oh, out_fps) as writer, progress(len(queries), "apply", quiet, unit="frame") as bar:
        for frame in retime_frames(_decode(input_path), queries, blend=blend):
            if pad:
                frame = np.pad(frame, ((0, oh - h), (0, ow - w), (0, 0)), mode="edge")
            writer.write(frame)
            bar.update(1)
    return {"frames": len(queries), "fps": out_fps, "width": ow, "height": oh, "duration": float(curve.duration)}


# ---------------------------------------------------------------------- signals
def _read_csv(path: str) -> tuple[list[str] | None, np.ndarray]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = [r for r in csv.reader(f) if r and any(c.strip() for c in r)]
    except OSError as exc:
        raise RetimeError(f"{path}: cannot read ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise FormatError(path, "not a text CSV file") from None
    if not rows:
        raise FormatError(path, "the file is empty")
    header = None
    first = rows[0]
    try:
        [float(c) for c in first]
    except ValueError:
        header = [c.strip() for c in first]
        rows = rows[1:]
    width = len(header) if header else len(rows[0]) if rows else 0
    data = np.empty((len(rows), width))
    line0 = 2 if header else 1
    for i, row in enumerate(rows):
        if len(row) != width:
            raise FormatError(path, f"expected {width} columns, found {len(row)}", line=line0 + i)
        try:
            data[i] = [float(c) for c in row]
        except ValueError:
            bad = next(c for c in row if not _is_float(c))
            raise FormatError(path, f"not a number: {bad.strip()!r}", line=line0 + i) from None
    if len(data) < 2:
        raise FormatError(path, "need at least two rows of values")
    if not np.all(np.isfinite(data)):
        raise FormatError(path, "values must be finite (found NaN or infinity)")
    return header, data


def _is_float(s: str) -> bool:
    try:
        float(s)
        return True
    except ValueError:
        return False


def _interp_rows(src_t: np.ndarray, values: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Linear interpolation of rows of ``values`` (N, ...) sampled at increasing ``src_t`` at ``query``."""
    idx = np.clip(np.searchsorted(src_t, query, side="right") - 1, 0, len(src_t) - 2)
    t0, t1 = src_t[idx], src_t[idx + 1]
    w = np.clip((query - t0) / (t1 - t0), 0.0, 1.0)
    w = w.reshape((-1,) + (1,) * (values.ndim - 1))
    return values[idx] * (1.0 - w) + values[idx + 1] * w


def apply_to_signal(
    curve,
    input_path: str | os.PathLike,
    output_path: str | os.PathLike,
    fps: float | None = None,
    out_fps: float | None = None,
    fit: bool = False,
) -> dict:
    """Retime a per-frame signal: CSV (rows = frames, optional header, optional time column) or NPY.

    The source rate comes from a time column (CSV) or ``fps``; values are interpolated linearly at
    the source times curve(t_k), t_k = k / out_fps (out_fps defaults to the source rate).
    Returns {'frames', 'fps', 'columns'}.
    """
    from retime.io_util import atomic_write

    input_path, output_path = os.fspath(input_path), os.fspath(output_path)
    ext = os.path.splitext(input_path)[1].lower()
    out_ext = os.path.splitext(output_path)[1].lower()
    if out_ext != ext:
        raise RetimeError(f"{output_path}: write a signal to the same type as its input ({ext})")
    time_col = None
    if ext == ".csv":
        header, values = _read_csv(input_path)
        if header:
            for i, name in enumerate(header):
                if name.strip().lower() in TIME_COLUMNS:
                    time_col = i
                    break
    elif ext == ".npy":
        header = None
        try:
            values = np.load(input_path, allow_pickle=False)
        except (ValueError, OSError, EOFError, SyntaxError, TokenError) as exc:  # a bad header fails in
            # NumPy's header parser (SyntaxError, TokenError); an empty file is an EOFError
            raise FormatError(input_path, f"cannot read NumPy array ({exc or 'empty file'})") from None
        if values.ndim < 1 or values.shape[0] < 2:
            raise FormatError(input_path, f"need an array with at least two frames along axis 0, got shape {values.shape}")
        if not np.issubdtype(values.dtype, np.number) or np.issubdtype(values.dtype, np.complexfloating):
            raise FormatError(input_path, f"need real numbers, got dtype {values.dtype}")
        values = values.astype(np.float64)
        if not np.all(np.isfinite(values)):
            raise FormatError(input_path, "values must be finite (found NaN or infinity)")
    else:
        raise RetimeError(f"{input_path}: unsupported input type {ext or '(none)'}; use a video, .csv or .npy")

    if time_col is not None:
        src_t = values[:, time_col] - values[0, time_col]
        if np.any(np.diff(src_t) <= 0):
            bad = int(np.nonzero(np.diff(src_t) <= 0)[0][0]) + 3
            raise FormatError(input_path, f"the {header[time_col]!r} column must increase", line=bad)
        src_fps = (len(src_t) - 1) / src_t[-1]
    else:
        if not fps:
            raise RetimeError(f"{input_path}: give the signal's frame rate with --fps (it has no time column)")
        src_fps = float(fps)
        src_t = np.arange(len(values)) / src_fps
    o_fps = float(out_fps) if out_fps else src_fps
    scale = _check_curve_fits(curve, float(src_t[-1]), 1.0 / src_fps, input_path, fit)
    t_out = np.asarray(curve.frame_times(o_fps), dtype=np.float64)
    query = np.asarray(curve(t_out), dtype=np.float64) * scale
    out = _interp_rows(src_t, values, query)
    if time_col is not None:
        out[:, time_col] = t_out
    if ext == ".csv":
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        if header:
            writer.writerow(header)
        for row in out:
            writer.writerow([f"{v:.9g}" for v in row])
        with atomic_write(output_path, "w") as f:
            f.write(buf.getvalue())
    else:
        with atomic_write(output_path, "wb") as f:
            np.save(f, out)
    return {"frames": len(out), "fps": o_fps, "columns": out.shape[1] if out.ndim > 1 else 1}


# ---------------------------------------------------------------------- encoding (the renderer's videos too)
_ENCODERS = {".mp4": "libx264", ".mkv": "libx264", ".mov": "libx264", ".gif": "gif"}


def _fps_fraction(fps: float) -> Fraction:
    return Fraction(fps).limit_denominator(1001)


class VideoWriter:
    """Writes RGB frames to .mp4/.mkv/.mov (H.264, yuv420p) or .gif with PyAV.

    Use as a context manager; writes to a temporary file beside ``path`` and renames it on success.
    """

    def __init__(self, path: str | os.PathLike, width: int, height: int, fps: float, crf: int = 20,
                 palette_frames: Sequence[np.ndarray] | None = None):
        import av

        self.path = os.fspath(path)
        ext = os.path.splitext(self.path)[1].lower()
        if ext not in _ENCODERS:
            raise RetimeError(f"{self.path}: unsupported video type {ext or '(none)'}; use .mp4, .mkv, .mov or .gif")
        if width % 2 or height % 2:
            if ext != ".gif":
                raise RetimeError(f"{self.path}: H.264 needs an even frame size, got {width}x{height}")
        directory = os.path.dirname(os.path.abspath(self.path))
        if not os.path.isdir(directory):
            raise RetimeError(f"{self.path}: folder {directory} does not exist")
        self.ext = ext
        self.width, self.height = width, height
        base = os.path.basename(self.path)
        self.tmp = os.path.join(directory, f".{base}.tmp{os.getpid()}{ext}")
        self.container = av.open(self.tmp, mode="w")
        rate = _fps_fraction(fps)
        self._palette = None
        if ext == ".gif":
            # GIF: one 256-colour palette for the whole clip (from sample frames, else the first
            # frame), no dithering, so flat areas stay flat and the file stays small
            self.stream = self.container.add_stream("gif", rate=rate)
            self.stream.pix_fmt = "pal8"
            if palette_frames:
                self._palette = _make_palette(palette_frames)
        else:
            self.stream = self.container.add_stream("libx264", rate=rate)
            self.stream.pix_fmt = "yuv420p"
            # two x264 threads: with more, they fight the renderer for this machine's cores
            self.stream.options = {"crf": str(crf), "preset": "veryfast", "tune": "animation", "threads": "2"}
        self.stream.width, self.stream.height = width, height
        self.n = 0
        self._closed = False
        self._error: BaseException | None = None
        self._queue: queue.Queue = queue.Queue(maxsize=8)
        self._thread = threading.Thread(target=self._encode_loop, name="retime-encode", daemon=True)
        self._thread.start()

    def write(self, frame: np.ndarray) -> None:
        """Queue one (H, W, 3) uint8 RGB frame; encoding runs in a background thread."""
        if frame.shape != (self.height, self.width, 3):
            raise ValueError(f"frame shape {frame.shape} != {(self.height, self.width, 3)}")
        if self._error is not None:
            raise self._error
        self._queue.put(np.ascontiguousarray(frame, dtype=np.uint8))
        self.n += 1

    def _encode_loop(self) -> None:
        import av
        from PIL import Image  # here: writing a CSV signal needs no imaging library

        try:
            while True:
                frame = self._queue.get()
                if frame is None:
                    break
                if self.ext == ".gif":
                    if self._palette is None:
                        self._palette = _make_palette([frame])
                    img, table = self._palette
                    idx = np.asarray(Image.fromarray(frame).quantize(palette=img, dither=Image.Dither.NONE))
                    vf = av.VideoFrame.from_ndarray((idx, table), format="pal8")
                else:
                    vf = av.VideoFrame.from_ndarray(frame, format="rgb24")
                for packet in self.stream.encode(vf):
                    self.container.mux(packet)
            for packet in self.stream.encode():
                self.container.mux(packet)
        except BaseException as exc:  # reported by write()/close() in the caller's thread
            self._error = exc
            while self._queue.get() is not None:
                pass

    def close(self, ok: bool = True) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._queue.put(None)
            self._thread.join()
        finally:
            self.container.close()
        if ok and self._error is not None:
            os.remove(self.tmp)
            raise self._error
        if ok:
            os.replace(self.tmp, self.path)
        elif os.path.exists(self.tmp):
            os.remove(self.tmp)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self.close(ok=exc_type is None)
        return False


def _make_palette(frames: Sequence[np.ndarray]) -> tuple[Image.Image, np.ndarray]:
    """A 256-colour palette image and its (256, 4) ARGB table, from a mosaic of sample frames."""
    from PIL import Image

    small = [Image.fromarray(np.ascontiguousarray(f, dtype=np.uint8)).reduce(2) for f in frames]
    w = sum(im.width for im in small)
    h = max(im.height for im in small)
    mosaic = Image.new("RGB", (w, h), tuple(int(c) for c in small[0].getpixel((0, 0))))
    x = 0
    for im in small:
        mosaic.paste(im, (x, 0))
        x += im.width
    pal_img = mosaic.quantize(colors=255, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    pal = np.array(pal_img.getpalette()[: 256 * 3], dtype=np.uint8).reshape(-1, 3)
    table = np.zeros((256, 4), dtype=np.uint8)
    table[: len(pal), 1:] = pal  # PyAV takes pal8 palette entries as A, R, G, B
    table[:, 0] = 255
    return pal_img, table
