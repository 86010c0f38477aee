"""Is a timing feasible? The one definition the report, the demo and the editor share.

An output frame shows source time s with playback speed p' and acceleration p''. It is **in its
region** when the residual wrench (body weights, the relaxation's weighted L1 measure, found by an
LP: :func:`retime.physics.regions.frame_region.residual_at`) that (u, v) = (p'', p'^2) needs beyond the nearest
source frame's feasible region is at most :data:`IN_REGION_TOL`. Inside the region's polygon the
residual is 0 without an LP.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

IN_REGION_TOL = 1e-2  # body weights of residual wrench beyond the region (about 7 N for 70 kg)
INSIDE_DISTANCE = 1e-9  # (u, v) this close to the polygon is inside it: no LP needed


def source_frames(frame_times, s) -> np.ndarray:
    """Index of the source frame nearest to each source time ``s`` (frames at ``frame_times``)."""
    times = np.asarray(frame_times, dtype=float)
    return np.clip(np.rint(np.interp(s, times, np.arange(len(times)))).astype(int), 0, len(times) - 1)


def curve_derivatives(curve, t, fps: float):
    """(p', p'') of any timing curve at output times ``t``: its speed, and central differences of the
    speed a quarter frame apart (one-sided at the ends)."""
    speed = np.asarray(curve.speed(t), dtype=float)
    h = 0.25 / fps
    tp = np.minimum(t + h, curve.duration)
    tm = np.maximum(t - h, 0.0)
    accel = (np.asarray(curve.speed(tp)) - np.asarray(curve.speed(tm))) / np.maximum(tp - tm, 1e-12)
    return speed, accel


@dataclass
class Feasibility:
    """Per output frame: the source frame shown, the distance of (u, v) to its region's polygon and
    the residual (body weights) it needs beyond the region."""

    frames: np.ndarray
    distance: np.ndarray
    residual: np.ndarray
    tol: float = IN_REGION_TOL

    @property
    def inside(self) -> np.ndarray:
        return self.residual <= self.tol

    @property
    def fraction(self) -> float:
        return float(np.mean(self.inside))


def feasibility(dynamics, regions, s, speed, accel, tol=IN_REGION_TOL) -> Feasibility:
    """:class:`Feasibility` of output frames showing source times ``s`` at speed p' and
    acceleration p'' (arrays of one length)."""
    from .frame_region import residual_at
    from .highs_lp import HighsPool

    frames = source_frames(regions.times, s)
    u = np.asarray(accel, dtype=float)
    v = np.asarray(speed, dtype=float) ** 2
    distance = regions.distances(frames, u, v)
    residual = np.zeros(len(frames))
    pool = HighsPool()  # one set of HiGHS objects for all the frames' LPs
    for k in np.flatnonzero(distance > INSIDE_DISTANCE):
        residual[k] = residual_at(dynamics, regions, int(frames[k]), float(u[k]), float(v[k]), pool)
    return Feasibility(frames, distance, residual, tol)


def curve_feasibility(curve, dynamics, regions, fps: float, tol=IN_REGION_TOL) -> Feasibility:
    """:func:`feasibility` of any timing curve at its output frames (derivatives by differences)."""
    t = curve.frame_times(fps)
    speed, accel = curve_derivatives(curve, t, fps)
    return feasibility(dynamics, regions, curve(t), speed, accel, tol)


def spline_feasibility(spline, dynamics, regions, fps: float, tol=IN_REGION_TOL) -> Feasibility:
    """:func:`feasibility` of the physics timing spline at its output frames (exact derivatives)."""
    t = output_times(spline.duration, fps)
    return feasibility(dynamics, regions, spline(t), spline.speed(t), spline.accel(t), tol)


def output_times(duration: float, fps: float) -> np.ndarray:
    """Output frame times of a spline of ``duration`` (the last clipped to its end)."""
    return np.minimum(np.arange(int(round(duration * fps)) + 1) / fps, duration)
