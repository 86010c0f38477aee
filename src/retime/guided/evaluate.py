"""Measurements for the paper's evaluations: flight phases and how fast a warp plays them."""

from __future__ import annotations

import numpy as np

from retime.motion import Motion, forward_kinematics
from retime.warp import TimingCurve

FOOT_WORDS = ("foot", "toe", "ankle")


def foot_joints(motion: Motion) -> list[int]:
    """Indices of the feet and toes (the limbs found on load, :mod:`retime.motion.rig`, else the
    joints named like feet or toes)."""
    frame = motion.skeleton.frame
    if frame is not None and frame.limbs is not None:
        return sorted({j for foot, toe in frame.limbs.feet.values() for j in (foot, toe)})
    idx = [i for i, nm in enumerate(motion.skeleton.names) if any(w in nm.lower() for w in FOOT_WORDS)]
    if not idx:
        raise ValueError("no foot or toe joints found by name")
    return idx


def flight_phases(motion: Motion, clearance: float = 0.04, min_duration: float = 0.1):
    """Intervals [(start s, end s)] during which every foot joint is above the ground.

    Heights are along the skeleton's up axis (detected or given, :mod:`retime.motion.frame`);
    "above" means higher than ``clearance`` metres over the lowest height that joint itself reaches.
    """
    from retime.motion.frame import up_vector

    pos, _ = forward_kinematics(motion)
    feet = foot_joints(motion)
    h = (pos[:, feet] @ up_vector(motion.skeleton.up)) * motion.skeleton.meters_per_unit
    base = np.percentile(h, 2, axis=0)
    air = np.all(h > base + clearance, axis=1)
    out = []
    f = 0
    n = len(air)
    while f < n:
        if air[f]:
            g = f
            while g + 1 < n and air[g + 1]:
                g += 1
            t0, t1 = f / motion.fps, g / motion.fps
            if t1 - t0 >= min_duration:
                out.append((t0, t1))
            f = g + 1
        else:
            f += 1
    return out


def interval_speed(curve: TimingCurve, s0: float, s1: float) -> float:
    """Average playback speed over the source interval [s0, s1]: (s1 - s0) / output time it takes."""
    t0, t1 = float(curve.inverse(s0)), float(curve.inverse(s1))
    if t1 <= t0:
        return float("inf")
    return (s1 - s0) / (t1 - t0)
