"""Post-processing of guided time warps (Hsu et al. 2007, section 3.4).

* :func:`moving_average`: smooth the discrete warp (source time per output frame) with a
  moving average, keeping the first and last frame and every keytime exactly. The window
  shrinks symmetrically near a fixed frame, which keeps the warp increasing: a moving average
  of an increasing sequence is increasing.
* :func:`adaptive_smooth`: play a motion through a timing curve, each output frame being the
  average of the source over the interval of source time that the frame covers, i.e. a window
  as wide as the local compression (one source frame or less: plain slerp). Quaternions are
  averaged in a hemisphere-aligned, normalised form (accurate for the small spreads inside one
  window); translations are averaged exactly.
"""

from __future__ import annotations

import numpy as np

from retime.errors import RetimeError
from retime.motion import Motion
from retime.motion.quat import continuous
from retime.warp import TimingCurve, apply_timing


def moving_average(values, window: int, fixed=()) -> np.ndarray:
    """Centred moving average of ``values`` (axis 0) over ``window`` samples (odd).

    Indices in ``fixed`` (and both ends) keep their values; around them the window shrinks so
    that it never reaches across a fixed index.
    """
    v = np.asarray(values, dtype=float)
    n = v.shape[0]
    w = int(window)
    if w <= 1 or n < 3:
        return v.copy()
    half = w // 2
    cuts = sorted({0, n - 1, *[int(f) for f in fixed if 0 <= int(f) < n]})
    out = v.copy()
    csum = np.concatenate([np.zeros((1,) + v.shape[1:]), np.cumsum(v, axis=0)])
    for a, b in zip(cuts, cuts[1:]):
        idx = np.arange(a + 1, b)
        if idx.size == 0:
            continue
        h = np.minimum(half, np.minimum(idx - a, b - idx))
        lo, hi = idx - h, idx + h + 1
        shape = (-1,) + (1,) * (v.ndim - 1)
        out[idx] = (csum[hi] - csum[lo]) / (hi - lo).reshape(shape)
    return out


def _running_integral(values):
    """Integral from frame 0 of the linear interpolant of ``values`` (axis 0), at each frame."""
    mid = 0.5 * (values[1:] + values[:-1])
    return np.concatenate([np.zeros((1,) + values.shape[1:]), np.cumsum(mid, axis=0)])


def _interval_mean(values, cum, fps, a, b):
    """Mean of the linear interpolant of ``values`` over source time intervals [a, b] (b > a)."""
    n = values.shape[0]

    def integral(t):
        u = np.clip(t * fps, 0.0, n - 1)
        i0 = np.minimum(np.floor(u).astype(np.int64), max(n - 2, 0))
        f = (u - i0).reshape((-1,) + (1,) * (values.ndim - 1))
        v0 = values[i0]
        v1 = values[np.minimum(i0 + 1, n - 1)]
        # integral from frame i0 to i0 + f of the linear segment v0 -> v1
        return cum[i0] + f * v0 + 0.5 * f * f * (v1 - v0)

    width = ((b - a) * fps).reshape((-1,) + (1,) * (values.ndim - 1))
    return (integral(b) - integral(a)) / width


def adaptive_smooth(motion: Motion, curve: TimingCurve, fps: float | None = None) -> Motion:
    """``motion`` played through ``curve`` with local averaging over each frame's source interval."""
    fps = motion.fps if fps is None else float(fps)
    out = apply_timing(motion, curve, fps)
    n = motion.n_frames
    if n < 2:
        return out
    t = curve.frame_times(fps)
    dt = 1.0 / fps
    a = curve(np.clip(t - 0.5 * dt, 0.0, curve.duration))
    b = curve(np.clip(t + 0.5 * dt, 0.0, curve.duration))
    wide = (b - a) * motion.fps > 1.0  # the frame covers more than one source frame
    if not np.any(wide):
        return out
    rot = continuous(motion.rotations, axis=0)
    aw, bw = a[wide], b[wide]
    q = _interval_mean(rot, _running_integral(rot), motion.fps, aw, bw)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-8):
        raise RetimeError("adaptive smoothing: a joint turns by half a revolution within one output frame")
    q = q / norm
    # keep the sign of the plain resampled rotation (same rotation, continuous signal)
    sign = np.sign(np.sum(q * out.rotations[wide], axis=-1, keepdims=True))
    sign[sign == 0] = 1.0
    rotations = out.rotations.copy()
    rotations[wide] = q * sign
    tr = motion.translations
    translations = out.translations.copy()
    translations[wide] = _interval_mean(tr, _running_integral(tr), motion.fps, aw, bw)
    return Motion(motion.skeleton, rotations, translations, fps)
