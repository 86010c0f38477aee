"""The fastest physical timing of a motion through its feasible regions (Bobrow; TOPP-RA).

Along the source path the timing is a speed profile v(s) = p'^2 with dv/ds = 2 p'' (since
d(p'^2)/dp = 2 p''), and it is physical where (p'', v) lies in the frame's region (:mod:`retime.physics.regions`).
Between two frames p'' is taken constant, so v changes linearly: v_{i+1} = v_i + 2 ds_i p''_i. The
sets of speeds from which the end of the clip can still be reached physically (the *controllable*
sets, intervals because the regions are convex) are found backwards frame by frame by clipping each
polygon with the strip ``K_lo(i+1) <= v + 2 ds u <= K_hi(i+1)`` (the regions' own half-plane clip); then the greedy forward pass, as fast as
each region and the next controllable set allow, is the time-optimal timing (Bobrow 1985, the
reachability analysis of Pham & Pham's TOPP-RA 2018). Its duration is the **least physical
duration** of the clip: asking for less leaves some frames outside their regions, whatever the
timing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..regions.polygon import clip_halfplanes


@dataclass
class FastestTiming:
    duration: float  # output seconds (inf if no physical timing passes the whole clip)
    speed: np.ndarray  # (n,) playback speed p' at every frame (empty if none)
    blocked_frame: int  # -1, or the frame where no physical timing gets through


@njit(cache=True)
def _u_range(px, py, v):
    """Smallest and largest u of the polygon at height v (v clamped into its v-range)."""
    lo_v, hi_v = py.min(), py.max()
    v = min(max(v, lo_v), hi_v)
    ulo, uhi = math.inf, -math.inf
    m = len(px)
    for i in range(m):
        j = i + 1 if i + 1 < m else 0
        if (py[i] - v) * (py[j] - v) <= 0.0:
            if abs(py[j] - py[i]) < 1e-15:
                ulo, uhi = min(ulo, px[i], px[j]), max(uhi, px[i], px[j])
            else:
                u = px[i] + (v - py[i]) / (py[j] - py[i]) * (px[j] - px[i])
                ulo, uhi = min(ulo, u), max(uhi, u)
    return ulo, uhi


@njit(cache=True)
def _fastest(offsets, vx, vy, times, speed):
    n = len(offsets) - 1
    klo = np.empty(n)
    khi = np.empty(n)
    a, b = offsets[n - 1], offsets[n]
    klo[n - 1], khi[n - 1] = max(vy[a:b].min(), 0.0), vy[a:b].max()
    none = np.zeros((int(np.max(np.diff(offsets))), 0))
    strip = np.empty((2, 3))
    for i in range(n - 2, -1, -1):
        ds = times[i + 1] - times[i]
        a, b = offsets[i], offsets[i + 1]
        nrm = math.hypot(2.0 * ds, 1.0)  # the strip klo <= v + 2 ds u <= khi as normalized half-planes
        strip[0, 0], strip[0, 1], strip[0, 2] = 2.0 * ds / nrm, 1.0 / nrm, khi[i + 1] / nrm
        strip[1, 0], strip[1, 1], strip[1, 2] = -2.0 * ds / nrm, -1.0 / nrm, -klo[i + 1] / nrm
        _, qy, _, ok = clip_halfplanes(vx[a:b].copy(), vy[a:b].copy(), none[:b - a], strip, 0.0)
        if not ok or len(qy) == 0:
            return math.inf, i
        klo[i], khi[i] = max(qy.min(), 0.0), qy.max()
    v = khi[0]
    speed[0] = math.sqrt(v)
    T = 0.0
    for i in range(n - 1):
        ds = times[i + 1] - times[i]
        a, b = offsets[i], offsets[i + 1]
        _, uhi = _u_range(vx[a:b], vy[a:b], v)
        vn = min(max(v + 2.0 * ds * uhi, klo[i + 1]), khi[i + 1])
        vn = max(vn, 0.0)
        s0, s1 = math.sqrt(v), math.sqrt(vn)
        T += 2.0 * ds / (s0 + s1) if s0 + s1 > 0.0 else math.inf
        speed[i + 1] = s1
        v = vn
    return T, -1


def fastest_timing(regions) -> FastestTiming:
    """The time-optimal physical timing through ``regions`` (a :class:`~retime.physics.regions.RegionSet`)."""
    offsets = np.asarray(regions.offsets, dtype=np.int64)
    verts = np.asarray(regions.verts, dtype=float)
    times = np.asarray(regions.times, dtype=float)
    speed = np.zeros(len(times))
    T, blocked = _fastest(offsets, np.ascontiguousarray(verts[:, 0]), np.ascontiguousarray(verts[:, 1]), times, speed)
    if not np.isfinite(T):
        return FastestTiming(math.inf, np.zeros(0), int(blocked))
    return FastestTiming(float(T), speed, -1)
