"""Timing curves: the one idea that runs through retime.

A timing curve maps output time t (seconds, 0..T) to source time s = p(t) (seconds, 0..S) and never
runs backwards. Methods (linear, guided, physics) compute one; ``apply_timing`` plays a motion through
it. Durations live on the output frame grid: an output of m frames at fps lasts (m - 1) / fps.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from .errors import FormatError, RetimeError
from .io_util import atomic_write
from .limits import check_memory
from .motion.model import Motion
from .motion.quat import slerp

CSV_HEADER = ("output_time", "source_time")
MAX_OUTPUT_FRAMES = 10_000_000  # about 23 hours at 120 fps
_TOL = 1e-9


class TimingCurve:
    """A monotone map from output time to source time, through samples (t_k, s_k).

    ``kind="linear"`` interpolates the samples linearly; ``kind="pchip"`` uses a monotone cubic
    (Fritsch-Carlson), smooth and never overshooting. ``compose`` gives ``kind="composed"``: evaluated
    exactly as outer(inner(t)), with ``t``/``s`` holding dense samples of it (for plots and files).
    """

    def __init__(self, output_times, source_times, kind="linear"):
        t = np.asarray(output_times, dtype=float).ravel()
        s = np.asarray(source_times, dtype=float).ravel()
        if t.size != s.size or t.size < 2:
            raise RetimeError("a timing curve needs at least two (output time, source time) samples")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(s))):
            raise RetimeError("a timing curve's times must be finite numbers")
        if np.any(np.diff(t) <= 0):
            k = int(np.argmax(np.diff(t) <= 0))
            raise RetimeError(f"timing curve output times must increase (sample {k + 1} -> {k + 2})")
        if np.any(np.diff(s) < -_TOL):
            k = int(np.argmax(np.diff(s) < -_TOL))
            raise RetimeError(f"timing curve source times must not decrease (sample {k + 1} -> {k + 2})")
        if kind not in ("linear", "pchip"):
            raise ValueError(f"unknown kind {kind!r}")
        self.t = t - t[0]
        self.s = np.maximum.accumulate(s)
        self.kind = kind
        self._pchip = None
        if kind == "pchip":
            from scipy.interpolate import PchipInterpolator  # here: importing SciPy is slow

            self._pchip = PchipInterpolator(self.t, self.s)
        self._parts = None  # (outer, inner) of a composed curve

    # -- evaluation ---------------------------------------------------------------------------
    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def source_start(self) -> float:
        return float(self.s[0])

    @property
    def source_duration(self) -> float:
        return float(self.s[-1])

    def __call__(self, t):
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if self._parts is not None:
            outer, inner = self._parts
            return outer(inner(t))
        if self._pchip is None:
            return np.interp(t, self.t, self.s)
        return np.clip(self._pchip(t), self.s[0], self.s[-1])

    def speed(self, t):
        """Playback speed ds/dt (1 = original speed, 2 = twice as fast)."""
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if self._parts is not None:
            outer, inner = self._parts
            return outer.speed(inner(t)) * inner.speed(t)
        if self._pchip is not None:
            return self._pchip.derivative()(t)
        slopes = np.diff(self.s) / np.diff(self.t)
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(slopes) - 1)
        return slopes[k]

    def inverse(self, s):
        """Output time at which source time s plays (the first such time where the curve holds)."""
        s = np.clip(np.asarray(s, dtype=float), self.s[0], self.s[-1])
        if self._parts is not None:
            outer, inner = self._parts
            return inner.inverse(outer.inverse(s))
        if self._pchip is None:
            ts, ss = self.t, self.s
        else:
            ts = self._dense_times()
            ss = self(ts)
        # first index with ss >= s (to rounding: a rise of 1e-38 over a second is a hold, and a time
        # inside it inverts to the hold's start), then interpolate inside that segment
        if self._pchip is not None:
            k = np.clip(np.searchsorted(ss, s, side="left"), 1, len(ss) - 1)
            return self._bisect(ts[k - 1], ts[k], s)
        eps = 1e-12 * max(1.0, float(abs(ss[-1])))
        k = np.clip(np.searchsorted(ss, s - eps, side="left"), 1, len(ss) - 1)
        s0, s1, t0, t1 = ss[k - 1], ss[k], ts[k - 1], ts[k]
        # a hold (s1 - s0 within eps) plays s from its start
        w = np.where(s1 - s0 > eps, (s - s0) / np.where(s1 - s0 > eps, s1 - s0, 1.0), 0.0)
        return t0 + np.clip(w, 0.0, 1.0) * (t1 - t0)

    def _dense_times(self):
        sub = np.linspace(0.0, 1.0, 33)[:-1]
        inner = (self.t[:-1, None] + sub[None] * np.diff(self.t)[:, None]).ravel()
        return np.append(inner, self.t[-1])

    def _bisect(self, lo, hi, s):
        """The first t in [lo, hi] with curve(t) >= s (curve(lo) < s <= curve(hi)), to rounding."""
        lo, hi = np.array(lo, dtype=float), np.array(hi, dtype=float)
        below = self(lo) >= s  # s at or before the bracket's start (s == curve(0))
        hi = np.where(below, lo, hi)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if np.all((mid == lo) | (mid == hi)):
                break
            up = self(mid) >= s
            hi = np.where(up, mid, hi)
            lo = np.where(up, lo, mid)
        return hi

    def compose(self, inner: "TimingCurve") -> "TimingCurve":
        """The curve t -> self(inner(t)): play ``inner``'s output through ``self``."""
        inside = self.t[(self.t >= inner.s[0]) & (self.t <= inner.s[-1])]
        knots = np.union1d(inner.t, inner.inverse(inside))
        if self.kind == "linear" and inner.kind == "linear":  # piecewise linear with these kinks: exact
            return TimingCurve(knots, self(inner(knots)), kind="linear")
        dense = np.union1d(knots, inner._dense_times() if inner.kind != "linear"
                           else np.linspace(0.0, inner.duration, 32 * len(inner.t)))
        out = TimingCurve(dense, self(inner(dense)), kind="linear")
        out.kind = "composed"
        out._parts = (self, inner)
        return out

    # -- frames and files -------------------------------------------------------------------
    def n_frames(self, fps: float) -> int:
        """Output frames at ``fps``: at least two (the first plays the curve's start, the last its end)."""
        return max(2, int(round(self.duration * fps)) + 1)

    def frame_times(self, fps: float) -> np.ndarray:
        """Output frame times 0, 1/fps, ...; the last frame plays the end of the curve.

        Methods build curves whose duration is a whole number of frames (``snap_duration``); for any
        other curve the last frame interval is shortened or stretched to end exactly at T."""
        times = np.arange(self.n_frames(fps)) / fps
        times[-1] = self.duration
        return times

    def to_csv(self, path, fps: float) -> None:
        """One row per output frame: ``output_time,source_time`` in seconds."""
        t = self.frame_times(fps)
        s = np.maximum.accumulate(self(t))
        s[-1] = self.s[-1]
        with atomic_write(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(CSV_HEADER)
            for a, b in zip(t, s):
                w.writerow((f"{a:.9f}", f"{b:.9f}"))

    @classmethod
    def from_csv(cls, path) -> "TimingCurve":
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8-sig")
        except FileNotFoundError:
            raise FormatError(path, "file not found") from None
        except (OSError, UnicodeDecodeError) as e:
            raise FormatError(path, f"cannot read: {e}") from None
        rows = [(i + 1, r) for i, r in enumerate(csv.reader(text.splitlines())) if r and any(x.strip() for x in r)]
        if not rows:
            raise FormatError(path, "empty warp file; expected a header 'output_time,source_time' and rows")
        lineno, header = rows[0]
        if tuple(h.strip().lower() for h in header[:2]) != CSV_HEADER:
            raise FormatError(path, f"header must be 'output_time,source_time', found {','.join(header)!r}", lineno)
        t, s = [], []
        for lineno, row in rows[1:]:
            if len(row) < 2:
                raise FormatError(path, "row needs two numbers: output_time,source_time", lineno)
            try:
                a, b = float(row[0]), float(row[1])
            except ValueError:
                raise FormatError(path, f"not a number in {','.join(row)!r}", lineno) from None
            if not (np.isfinite(a) and np.isfinite(b)):
                raise FormatError(path, "times must be finite numbers", lineno)
            if t and a <= t[-1]:
                raise FormatError(path, "output_time must increase from row to row", lineno)
            if s and b < s[-1] - 1e-7:
                raise FormatError(path, "source_time must not decrease (time cannot run backwards)", lineno)
            t.append(a)
            s.append(b)
        if len(t) < 2:
            raise FormatError(path, "a warp needs at least two rows")
        if abs(t[0]) > 1e-7:
            raise FormatError(path, f"the first row must start at output time 0, found {t[0]}", rows[1][0])
        return cls(t, s, kind="linear")

    def __repr__(self):
        return f"TimingCurve(T={self.duration:.4g}s -> S={self.source_duration:.4g}s, {len(self.t)} samples, {self.kind})"


# -- building curves ------------------------------------------------------------------------------
def snap_duration(duration: float, fps: float) -> float:
    """The output duration on the frame grid closest to ``duration`` (at least one frame)."""
    frames = duration * fps
    if not np.isfinite(frames) or frames > MAX_OUTPUT_FRAMES:
        raise RetimeError(f"the output would have {frames:.3g} frames ({duration:.4g} s at {fps:g} fps); "
                          f"retime writes at most {MAX_OUTPUT_FRAMES:,}: check the duration and frame rate")
    return max(1, int(round(frames))) / fps


def uniform_warp(source_duration: float, duration: float) -> TimingCurve:
    """Play the whole source uniformly faster or slower so that it lasts ``duration``."""
    if not (duration > 0):
        raise RetimeError(f"duration must be positive, got {duration}")
    return TimingCurve([0.0, duration], [0.0, source_duration])


def scale_warp(source_duration: float, scale: float, fps: float) -> TimingCurve:
    """Play the source at exactly 1/scale of its speed (scale 0.5 = twice as fast), for as long as
    :func:`output_duration` gives: output frame k shows source time k / (fps * scale) exactly (with
    scale 0.5, the source's even frames). When the source is not a whole number of output frames
    long, the final fraction of an output frame (under 1/fps) is not played."""
    duration = output_duration(source_duration, fps, scale=scale)
    return TimingCurve([0.0, duration], [0.0, min(duration / scale, source_duration)])


def output_duration(source_duration: float, fps: float, duration: float | None = None,
                    scale: float | None = None) -> float | None:
    """The output's length on its frame grid, the one rule every door (the Python wrappers,
    :func:`retime.method.solve`, the command line, the editor, batch, the Blender add-on) follows;
    an output of m frames lasts (m - 1) / fps.

    * ``duration`` (s): the nearest whole number of output frames (:func:`snap_duration`);
    * ``scale``: floor(S * scale * fps) output frames after the first (to 1e-6 of a frame), so that
      output frame k shows source time k / (fps * scale) exactly and none plays past the source's end;
    * neither: None, a free duration, which the method chooses and then puts on the grid with
      :func:`snap_duration`."""
    if duration is not None and scale is not None:
        raise RetimeError("give a duration or a scale, not both")
    if duration is not None:
        if not (duration > 0):
            raise RetimeError(f"duration must be positive, got {duration}")
        return snap_duration(float(duration), fps)
    if scale is None:
        return None
    scale = float(scale)
    if not (scale > 0) or not np.isfinite(scale):
        raise RetimeError(f"--scale must be a positive number, got {scale}")
    exact = source_duration * scale * fps
    if not np.isfinite(exact) or exact > MAX_OUTPUT_FRAMES:
        raise RetimeError(f"--scale {scale:g} would make {exact:.3g} output frames; retime writes at most "
                          f"{MAX_OUTPUT_FRAMES:,}")
    frames = int(np.floor(exact + 1e-6))
    if frames < 1:
        raise RetimeError(f"--scale {scale:g} leaves less than two frames of output")
    return frames / fps


def keytime_warp(source_duration: float, keytimes=(), duration=None, smooth=False) -> TimingCurve:
    """Source time ``src`` plays at output time ``dst`` for each keytime (src, dst); the ends map to
    each other. Linear between keytimes, or a smooth monotone cubic (PCHIP) with ``smooth``."""
    duration = source_duration if duration is None else duration
    if not (duration > 0):
        raise RetimeError(f"duration must be positive, got {duration}")
    keys = check_keytimes(keytimes, source_duration, duration)
    src = [0.0] + [k[0] for k in keys] + [source_duration]
    dst = [0.0] + [k[1] for k in keys] + [duration]
    return TimingCurve(dst, src, kind="pchip" if smooth and len(src) > 2 else "linear")


def check_keytimes(keytimes, source_duration, duration=None):
    """Keytimes sorted by source time, checked to be inside the clip and in the same order in both
    (``duration`` None: a free duration, any positive output time)."""
    keys = sorted((float(a), float(b)) for a, b in keytimes)
    for src, dst in keys:
        if not (0.0 < src < source_duration):
            raise RetimeError(f"keytime {src:g}={dst:g}: source time {src:g}s is outside the clip (0, {source_duration:g}s)")
        if not (0.0 < dst < (np.inf if duration is None else duration)):
            end = "end" if duration is None else f"{duration:g}s"
            raise RetimeError(f"keytime {src:g}={dst:g}: output time {dst:g}s is outside the output (0, {end})")
    for (s0, d0), (s1, d1) in zip(keys, keys[1:]):
        if s1 == s0 or d1 <= d0:
            raise RetimeError(f"keytimes {s0:g}={d0:g} and {s1:g}={d1:g} are out of order or collide: "
                              "later source times must play at later output times")
    return keys


# -- applying curves ----------------------------------------------------------------------------
def _source_positions(curve, src_fps, n_src, out_fps):
    """Fractional source frame index for each output frame (snapped when within 1e-6 of a frame)."""
    u = np.maximum.accumulate(curve(curve.frame_times(out_fps))) * src_fps  # no rounding wobble backwards
    r = np.round(u)
    u = np.where(np.abs(u - r) < 1e-6, r, u)
    return np.clip(u, 0.0, n_src - 1)


def frame_bracket(u, n):
    """The frames around fractional frame indices ``u`` (in 0..n-1) and the weight of the later:
    (i0, i1, w); a frame itself has w = 0 (the last one too)."""
    i0 = np.minimum(np.floor(u).astype(np.int64), max(n - 2, 0))
    w = u - i0
    i1 = np.minimum(i0 + 1, n - 1)
    last = w >= 1.0  # the source's last frame: take it as it is
    i0 = np.where(last, i1, i0)
    w = np.where(last, 0.0, w)
    return i0, i1, w


def check_frame_count(curve: TimingCurve, fps: float) -> None:
    """Refuse outputs too long to hold in memory (a duration or frame rate typed wrong)."""
    frames = curve.duration * fps + 1
    if not frames <= MAX_OUTPUT_FRAMES:
        raise RetimeError(f"the output would have {frames:.3g} frames ({curve.duration:.4g} s at {fps:g} fps); "
                          f"retime writes at most {MAX_OUTPUT_FRAMES:,}: check the duration and frame rate")


def apply_timing(motion: Motion, curve: TimingCurve, fps: float | None = None) -> Motion:
    """Resample ``motion`` at source times curve(t) for each output frame t (slerp for rotations,
    linear for translations). The result keeps the skeleton and (unless given) the frame rate."""
    fps = motion.fps if fps is None else float(fps)
    check_frame_count(curve, fps)
    # rotations, translations and the slerp's temporaries, then the written text (about 11 bytes a value)
    n_out = curve.n_frames(fps)
    per_frame = motion.skeleton.n_joints * (7 * 8 * 4) + 11 * sum(len(c) for c in motion.skeleton.channels)
    check_memory(n_out * per_frame, f"an output of {n_out:,} frames")
    if curve.source_duration > motion.duration + 1e-6:
        raise RetimeError(f"the timing curve reaches source time {curve.source_duration:.4g}s, "
                          f"past the end of the motion ({motion.duration:.4g}s)")
    u = _source_positions(curve, motion.fps, motion.n_frames, fps)
    i0, i1, w = frame_bracket(u, motion.n_frames)
    rot = slerp(motion.rotations[i0], motion.rotations[i1], w[:, None])
    exact = w == 0.0  # output frames that land on a source frame copy it bit for bit
    rot[exact] = motion.rotations[i0[exact]]
    tr = lerp_frames(motion.translations, i0, i1, w)
    return Motion(motion.skeleton, rot, tr, fps)


def resample_array(values, src_fps: float, curve: TimingCurve, out_fps: float | None = None):
    """Any per-frame array (frames on axis 0) played through ``curve``, linearly interpolated."""
    values = np.asarray(values)
    out_fps = src_fps if out_fps is None else out_fps
    check_frame_count(curve, out_fps)
    u = _source_positions(curve, src_fps, values.shape[0], out_fps)
    return lerp_frames(values, *frame_bracket(u, values.shape[0]))


def lerp_frames(values, i0, i1, w):
    """Per-frame values (frames on axis 0) linearly between frames i0 and i1 with weight w of i1."""
    w = np.asarray(w).reshape((-1,) + (1,) * (values.ndim - 1))
    return values[i0] + w * (values[i1].astype(float) - values[i0])
