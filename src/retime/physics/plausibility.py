"""Is the clip physical as captured? Said before retiming, with the number and the likely causes.

The regions (:mod:`.regions`) measure, per source frame, the residual force the clip's *own*
timing needs beyond what the body and its foot contacts can give (``source_residual``, in body
weights). Captured motion of a real person needs little (the CMU jumps: 2-7 % of frames above a
quarter of body weight). A clip read with the wrong up axis needs about one body weight on every
frame; a root-locked, treadmill or keyframed clip needs a lot on many. Regions are widened by that
residual, so a retiming of such a clip can look "100 % feasible" while its physics means little:
:func:`check_source` says so, and why it is likely to be.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

OFF_RESIDUAL = 0.25  # body weights: a source frame needing more is not physical as captured
MAX_OFF_SHARE = 0.1  # a clip with more such frames is not physical as captured
# (real captures on CMU and the dev set: 2-7 %; a Kinect standing clip 16 %, root-locked dance 18 %)
SLIDE_SPEED = 0.45  # m/s: median horizontal speed of the feet at floor height above this is sliding
# (real captures on the dev set and CMU: 0.00-0.30 m/s; a walk with its travel removed: 0.64)
STILL_ROOT_M = 1e-3  # the root moving less than this (std, metres) is locked in place
FROZEN_DEG = 2.0  # every joint within this of its mean pose: a frozen clip


@dataclass
class SourceCheck:
    physical: bool
    off_share: float  # share of source frames needing more than OFF_RESIDUAL
    median_residual: float  # body weights
    causes: list[str] = field(default_factory=list)

    def message(self) -> str:
        if self.physical:
            return ""
        causes = "; ".join(self.causes) if self.causes else (
            "hand or knee contacts (cartwheels, crawls), props, noisy tracking, or keyframed motion that was never "
            "physical")
        if self.off_share > MAX_OFF_SHARE:
            what = (f"{self.off_share:.0%} of its frames need more than {OFF_RESIDUAL:.0%} of body weight of extra "
                    f"force at their own timing (median {self.median_residual:.2f}). Likely: {causes}")
        else:
            what = causes
        return (f"this clip is not physical as captured: {what}. Feasibility is measured against regions widened "
                "to the clip's own residual, so it means less than usual")

    def as_dict(self) -> dict:
        return {"physical": self.physical, "off_share": round(self.off_share, 4),
                "median_residual": round(self.median_residual, 4), "causes": list(self.causes)}


def sole_point_velocity(terms) -> np.ndarray:
    """(F, 4, 2) horizontal velocity (m/s, x and z) of each contact point (the midpoint of its two
    sole corners) at the motion's frames."""
    corners = np.asarray(terms.corners)[::int(terms.samples_per_frame)]
    mid = 0.5 * (corners[:, 0::2] + corners[:, 1::2])
    if len(mid) < 2:
        return np.zeros(mid.shape[:2] + (2,))
    return np.gradient(mid[..., [0, 2]], axis=0) * float(terms.fps)


def floor_slide(terms) -> tuple[float, float]:
    """(median horizontal speed m/s, steadiness 0-1) of the sole points while they are at floor
    height (within 3 cm of the local floor, :func:`.contacts.local_floor`), whether or not contact
    detection called them planted. Steadiness is |mean velocity| / mean speed: near 1 when the
    feet are carried one way, as on a treadmill; near 0 for skating back and forth."""
    from .contacts import local_floor

    corners = np.asarray(terms.corners)[::int(terms.samples_per_frame)]  # (F, 8, 3), y up
    if len(corners) < 3:
        return 0.0, 0.0
    low = np.minimum(corners[:, 0::2, 1], corners[:, 1::2, 1])  # (F, 4)
    height = low - local_floor(low, terms.fps)[:, None]
    v = sole_point_velocity(terms)
    on_floor = height < 0.03
    if not on_floor.any():
        return 0.0, 0.0
    vf = v[on_floor]
    speed = np.linalg.norm(vf, axis=-1)
    steady = float(np.linalg.norm(vf.mean(axis=0)) / max(speed.mean(), 1e-9))
    return float(np.median(speed)), steady


def _frozen(motion) -> bool:
    q = np.asarray(motion.rotations)
    if len(q) < 3:
        return False
    mean = q.mean(axis=0)
    mean /= np.maximum(np.linalg.norm(mean, axis=-1, keepdims=True), 1e-12)
    dot = np.clip(np.abs(np.sum(q * mean, axis=-1)), 0, 1)
    return bool(np.degrees(2 * np.arccos(dot)).max() < FROZEN_DEG)


def check_source(motion, terms, regions) -> SourceCheck:
    """How physical ``motion`` (the conformed motion physics saw, or the original) is at its own
    timing, from the ``terms`` and ``regions`` of its dynamics; the likely causes when it is not."""
    res = np.asarray(regions.source_residual, dtype=float)
    spf = int(terms.samples_per_frame)
    res = res[::spf] if len(res) > motion.n_frames else res
    off = float(np.mean(res > OFF_RESIDUAL)) if res.size else 0.0
    med = float(np.median(res)) if res.size else 0.0
    causes = []
    slide, steady = floor_slide(terms)
    if slide > SLIDE_SPEED:  # kinematic: the dynamics of a treadmill walk are an overground walk's
        how = "steadily one way: a treadmill or an in-place loop" if steady > 0.5 else \
            "a treadmill, an in-place loop, foot skating or noisy tracking"
        causes.append(f"the feet move while at floor height (median {slide:.2f} m/s, {how}); physics assumes a "
                      "static floor and feet that stay where they land")
    root = np.asarray(terms.root_origin)[::spf]
    if len(root) > 2 and float(np.max(np.std(root, axis=0))) < STILL_ROOT_M and not _frozen(motion):
        causes.append("the root never moves: an in-place (root-locked) export, which has no travel or "
                      "balance to keep; physics needs the character's own root motion")
    physical = off <= MAX_OFF_SHARE and not causes
    frame = getattr(motion.skeleton, "frame", None)
    if off > MAX_OFF_SHARE:
        up_given = frame is not None and frame.up_given
        if med > 0.6 and off > 0.8 and (frame is None or frame.up_confidence < 0.9 or up_given):
            conf = (", as given" if up_given else f", {frame.up_confidence:.0%} of frames agree") if frame is not None else ""
            causes.append(f"the up axis is wrong (read as {motion.skeleton.up if frame is None else frame.up}"
                          f"{conf}; give --up)")
        if frame is not None and frame.unit_confidence not in ("sure", "declared", "given"):
            causes.append(f"the length unit is uncertain (read as 1 unit = {frame.meters_per_unit:.4g} m, "
                          f"{frame.unit_confidence}; give --units)")
        if _frozen(motion):
            causes.append(f"the pose barely changes (every joint within {FROZEN_DEG:g} deg): rotations written "
                          "in radians but read as degrees? give --angles rad")
        contact = np.asarray(terms.contact, dtype=bool)[::spf]
        air = float(np.mean(~contact.any(axis=1))) if contact.size else 0.0
        if air > 0.4:
            causes.append(f"no foot is on the floor in {air:.0%} of the frames (a floating capture floor, a "
                          "platform, hands on the floor, or feet tracked badly)")
    return SourceCheck(physical, off, med, causes)
