"""How physical a clip's own timing is, frame by frame (``retime check``; McCann et al. 2006, sec. 5:
"a force visualization framework that emphasizes violated constraints in a source motion").

Per source frame, from the path dynamics and feasible regions of the clip at its own timing:

* ``residual``: the wrench (body weights, weighted L1 over the root rows) that no friction-cone
  contact force can supply (``RegionSet.source_residual``);
* ``torque_excess``: the most any joint's torque of the original timing exceeds its limit (N m;
  zero with the default limits, which come from the clip itself, unless a body file sets them);
* ``com_accel``: the centre of mass's acceleration (m/s^2, of the smoothed path) and ``flight_g``:
  how fast it falls in flight against g (1 in a real flight; the parabola fitted to each flight of
  the unsmoothed frames, :mod:`.ballistic`);
* ``foot_slide``: horizontal speed (m/s) of the sole points in contact.

The verdict is :func:`retime.physics.plausibility.check_source`'s: physical, or each cause found
(a wrong up axis or frame rate, radians, a root-locked export, a treadmill, sliding feet, a body held
up off the floor, residual force with no named cause) as a code and a sentence.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .check_forces import FrameForces, frame_forces
from .plausibility import OFF_RESIDUAL, SourceCheck, check_source


@dataclass
class ClipCheck:
    fps: float
    times: np.ndarray  # (F,) s
    residual: np.ndarray  # (F,) body weights
    torque_excess: np.ndarray  # (F,) N m
    com_accel: np.ndarray  # (F, 3) m/s^2, y up
    flight: np.ndarray  # (F,) bool: no sole point in contact
    foot_slide: np.ndarray  # (F,) m/s (0 where no point is in contact)
    verdict: SourceCheck
    notes: list[str] = field(default_factory=list)
    forces: FrameForces | None = None  # per frame: the feet's contact forces, the residual force, the centre of mass

    @property
    def physical(self) -> bool:
        return self.verdict.physical

    @property
    def flight_g(self) -> float | None:
        """How fast the centre of mass falls in flight, in units of g (None: no flight to fit)."""
        f = self.verdict.flight
        return None if f is None else f.ratio

    @property
    def airborne(self) -> np.ndarray:
        """(F,) bool: both feet clear of the floor (the frames the flights are fitted on)."""
        f = self.verdict.flight
        return np.zeros(len(self.times), bool) if f is None or f.airborne is None else f.airborne

    @property
    def judged(self) -> np.ndarray:
        """(F,) bool: the frames the verdict judged by their residual (all but those near a flight
        that falls at g)."""
        judged = self.verdict.judged
        return judged if judged is not None and len(judged) == len(self.residual) else np.ones(len(self.residual), bool)

    def worst_frames(self, k: int = 5, apart: float = 0.1) -> list[int]:
        """Up to ``k`` frames of the largest residual over a quarter body weight, ``apart`` seconds
        from each other (distinct moments, not one landing's neighbouring frames), among the frames
        the verdict judged by their residual (not those next to a flight that falls at g)."""
        out = []
        gap = max(1, int(round(apart * self.fps)))
        residual = np.where(self.judged, self.residual, 0.0)
        for i in np.argsort(-residual, kind="stable"):
            if residual[i] <= OFF_RESIDUAL or len(out) == k:
                break
            if all(abs(int(i) - j) > gap for j in out):
                out.append(int(i))
        return out

    def summary(self) -> dict:
        slide = self.foot_slide[~self.flight]
        verdict = self.verdict.as_dict()
        return {
            "physical": self.physical,
            "frames": int(len(self.times)),
            "off_share": round(self.verdict.off_share, 4),
            "median_residual": round(self.verdict.median_residual, 4),
            "max_residual": round(float(self.residual.max()), 4) if len(self.residual) else 0.0,
            "max_torque_excess": round(float(self.torque_excess.max()), 3) if len(self.times) else 0.0,
            "flight_share": round(float(self.flight.mean()), 4),
            "flight_g": verdict["flight_g"],
            "flights": verdict["flights"], "time_factor": verdict["time_factor"],
            "stance_time_factor": verdict["stance_time_factor"], "stance_steps": verdict["stance_steps"],
            "median_foot_slide": round(float(np.median(slide)), 4) if slide.size else 0.0,
            "worst_frames": self.worst_frames(),
            "codes": self.verdict.codes,
            "causes": list(self.verdict.causes),
            "cautions": [c.code for c in self.verdict.cautions],
            "caution_sentences": [c.sentence for c in self.verdict.cautions],
            "notes": list(self.notes),
        }

    def report(self) -> dict:
        frames = [{"frame": i, "time": round(float(t), 6), "residual": round(float(r), 5),
                   "torque_excess": round(float(e), 4), "flight": bool(f), "airborne": bool(b),
                   "foot_slide": round(float(s), 4), "com_accel": [round(float(x), 4) for x in a]}
                  for i, (t, r, e, f, b, s, a) in enumerate(zip(self.times, self.residual, self.torque_excess,
                                                              self.flight, self.airborne, self.foot_slide,
                                                              self.com_accel))]
        if self.forces is not None:
            for i, frame in enumerate(frames):
                frame.update(self.forces.frame(i))
        return {"summary": self.summary(), "verdict": self.verdict_line(), "residual_threshold": OFF_RESIDUAL,
                "frames": frames}

    def verdict_line(self) -> str:
        s = self.summary()
        share = self.verdict.judged_share
        which = "frames" if share == 1.0 else f"the {share:.0%} of frames away from flights"
        top = self.residual[self.judged]
        numbers = (f"{s['off_share']:.0%} of {which} over {OFF_RESIDUAL:.0%} body weight of residual "
                   f"(median {s['median_residual']:.2f}, max {float(top.max()) if top.size else 0.0:.2f})")
        if self.flight_g is not None:  # formatted from the unrounded ratio, as the causes' sentences are
            numbers += f"; in flight the centre of mass falls at {self.flight_g:.2f} g"
        if self.physical and self.verdict.cautions:
            return f"physical as captured, with a caution: {numbers}. " + " ".join(
                f"[{c.code}] {c.sentence}." for c in self.verdict.cautions)
        if self.physical:
            return f"physical as captured: {numbers}"
        return f"NOT physical as captured: {numbers}. " + " ".join(f"[{c.code}] {c.sentence}."
                                                                    for c in self.verdict.found)


def _com_accel(terms) -> np.ndarray:
    """(F, 3) centre-of-mass acceleration at the frames, from the bodies' world frames."""
    c = np.asarray(terms.com)[::int(terms.samples_per_frame)]
    if len(c) < 3:
        return np.zeros_like(c)
    dt = 1.0 / float(terms.fps)
    return np.gradient(np.gradient(c, dt, axis=0), dt, axis=0)


def sole_point_velocity(terms) -> np.ndarray:
    """(F, 4, 2) horizontal velocity (m/s, x and z) of each contact point (the midpoint of its two
    sole corners) at the motion's frames."""
    corners = np.asarray(terms.corners)[::int(terms.samples_per_frame)]
    mid = 0.5 * (corners[:, 0::2] + corners[:, 1::2])
    if len(mid) < 2:
        return np.zeros(mid.shape[:2] + (2,))
    return np.gradient(mid[..., [0, 2]], axis=0) * float(terms.fps)


def _foot_slide(terms) -> np.ndarray:
    contact = np.asarray(terms.contact, dtype=bool)[::int(terms.samples_per_frame)]
    speed = np.linalg.norm(sole_point_velocity(terms), axis=-1)  # (F, 4)
    return np.where(contact, speed, 0.0).max(axis=1)


def _torque_excess(terms) -> np.ndarray:
    spf = int(terms.samples_per_frame)
    if terms.tau_ref is None or terms.tau_limit is None:
        return np.zeros(len(terms.times[::spf]))
    tau = np.abs(np.asarray(terms.tau_ref))[::spf]
    return np.maximum(tau - np.asarray(terms.tau_limit)[None], 0.0).max(axis=1)


def check_clip(motion, body=None, contacts=None) -> ClipCheck:
    """Check ``motion``'s own timing (see the module docstring); ``body`` and ``contacts`` as for
    :func:`retime.physics.api.physics_warp`."""
    from .api import prepare_regions

    terms, _, _, regions = prepare_regions(motion, body=body, contacts=contacts)  # no objective: no retiming
    spf = int(terms.samples_per_frame)
    residual = np.asarray(regions.source_residual, dtype=float)[::spf]
    contact = np.asarray(terms.contact, dtype=bool)[::spf]
    out = ClipCheck(fps=float(motion.fps), times=np.asarray(terms.times)[::spf], residual=residual,
                    torque_excess=_torque_excess(terms), com_accel=_com_accel(terms), flight=~contact.any(axis=1),
                    foot_slide=_foot_slide(terms), verdict=check_source(motion, terms, regions),
                    notes=list(getattr(terms, "conform_notes", [])),
                    forces=frame_forces(motion, terms, regions.body_weight))
    return out
