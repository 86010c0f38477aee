"""Phases of a motion (runs of one state over its frames: in contact or in flight) and how fast a
timing curve plays each: the one place retime finds flights and phase speeds.

Plain arrays in, plain lists out: ``contact`` is a (F,) or (F, points) bool array of a detector's
contact states (:func:`retime.motion.feet.foot_contacts`), ``times`` the frames' source times.
"""
from __future__ import annotations

import numpy as np

from .warp import TimingCurve


def runs(state) -> list[tuple[bool, int, int]]:
    """Runs of equal values of a bool array: [(value, first, last)], ``last`` inclusive."""
    state = np.asarray(state, dtype=bool)
    if state.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(state.astype(np.int8))) + 1
    starts = np.r_[0, cuts]
    ends = np.r_[cuts - 1, state.size - 1]
    return [(bool(state[a]), int(a), int(b)) for a, b in zip(starts, ends)]


def any_contact(contact) -> np.ndarray:
    contact = np.asarray(contact, dtype=bool)
    return contact.any(axis=1) if contact.ndim == 2 else contact


def flights(contact, fps: float, min_frames: int = 3) -> list[tuple[float, float]]:
    """(start s, end s) of every stretch of at least ``min_frames`` frames with no contact."""
    return [(a / fps, b / fps) for in_contact, a, b in runs(any_contact(contact))
            if not in_contact and b - a + 1 >= min_frames]


def longest_flight(contact, times) -> tuple[float, float] | None:
    """(start, end) source times of the longest flight phase (the first of equal ones) as
    :func:`contact_phases` gives it to every method's report (from its first frame in the air to the
    first frame back on the ground), or None."""
    found = [(p["source_start"], p["source_end"]) for p in contact_phases(contact, times, lambda s: s)
             if p["state"] == "flight"]
    return max(found, key=lambda f: f[1] - f[0]) if found else None


def interval_speed(curve: TimingCurve, s0: float, s1: float) -> float:
    """Mean playback speed over the source interval [s0, s1]: its length over the output time it
    takes (infinite when it takes none)."""
    t0, t1 = (float(v) for v in curve.inverse(np.array([s0, s1], dtype=float)))
    if t1 <= t0:
        return float("inf")
    return (s1 - s0) / (t1 - t0)


def phase_record(state: str, s0: float, s1: float, t0: float, t1: float) -> dict:
    return {"state": state, "source_start": round(float(s0), 6), "source_end": round(float(s1), 6),
            "output_start": round(float(t0), 6), "output_end": round(float(t1), 6),
            "speed": round(float((s1 - s0) / (t1 - t0)), 4)}


def contact_phases(contact, times, inverse) -> list[dict]:
    """Stance and flight phases of the frames at source ``times`` with their output spans under
    ``inverse`` (source times -> output times); a phase a curve plays in no time (a one-sample
    phase at the clip's end) is left out."""
    times = np.asarray(times, dtype=float)
    out = []
    for in_contact, a, b in runs(any_contact(contact)):
        s0, s1 = times[a], times[min(b + 1, len(times) - 1)]
        t0, t1 = inverse(np.array([s0, s1]))
        if s1 <= s0 or t1 <= t0:
            continue
        out.append(phase_record("stance" if in_contact else "flight", s0, s1, t0, t1))
    return out


def keytime_phases(curve: TimingCurve, keytimes=()) -> list[dict]:
    """The stretches between keytimes (the whole clip without them), each with its speed."""
    src = [0.0] + sorted(float(s) for s, _ in keytimes) + [curve.source_duration]
    out = []
    t = curve.inverse(np.asarray(src, dtype=float))
    for k in range(len(src) - 1):
        if src[k + 1] > src[k] and t[k + 1] > t[k]:
            out.append(phase_record("segment", src[k], src[k + 1], t[k], t[k + 1]))
    return out
