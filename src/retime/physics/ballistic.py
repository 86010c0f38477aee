"""Flight gravity: how fast a clip's centre of mass falls while both feet are off the floor.

In flight nothing but gravity acts on the body, so its centre of mass follows a parabola whose
curvature is g whatever the limbs do. A parabola is fitted to the centre of mass's height over each
flight, from the clip's own frames (no low-pass: a 0.05 s smoothing of a run's 0.1 s flight mixes in
the stance forces around it, which read as 0.25-0.88 g); the flights' estimates are combined by
their median weighted by duration, so one short or noisy flight does not decide.

A frame is airborne when neither foot bears on the floor (:attr:`FootPoints.airborne`), and
:data:`TRIM_FRAMES` are left out at each end of a flight: the contact transitions, where the sole
is off the floor but the foot still pushes or already lands.

Played ``s`` times too slow (a wrong Frame Time or --fps), every acceleration is ``1/s^2`` of the
real one: a flight at ``g_est`` says the clip's time runs ``sqrt(G / g_est)`` times too slow.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..motion.feet import above_own_floor
from ..phases import runs
from .constants import G
from .model.contacts import corner_positions

CLEAR_M = 0.03  # a foot point this close to its floor bears on it ...
NEAR_M = 0.05  # ... and one this close that is nearly still (a foot rolling onto its tip)
STILL_M_S = 0.5
TRIM_FRAMES = 1  # left out at each end of a flight (take-off and landing)
MIN_FIT_FRAMES = 5  # a parabola through fewer frames says little about its curvature
MIN_FIT_S = 0.04  # nor through a shorter stretch


@dataclass
class Flight:
    first: int  # first frame of the fit
    last: int  # last frame of the fit (inclusive)
    g: float  # m/s^2, downward curvature of the fitted parabola
    rms: float  # m, the fit's residual

    def seconds(self, fps: float) -> float:
        return (self.last - self.first) / fps


@dataclass
class FlightGravity:
    fps: float
    flights: list[Flight] = field(default_factory=list)
    airborne: np.ndarray | None = None  # (F,) bool: both feet clear of the floor

    @property
    def seconds(self) -> float:
        """Total duration of the fitted flights."""
        return float(sum(f.seconds(self.fps) for f in self.flights))

    @property
    def g(self) -> float | None:
        """Median of the flights' gravities weighted by their durations (m/s^2; None: no flight)."""
        if not self.flights:
            return None
        g = np.array([f.g for f in self.flights])
        w = np.array([f.seconds(self.fps) for f in self.flights])
        order = np.argsort(g)
        cum = np.cumsum(w[order])
        return float(g[order][np.searchsorted(cum, 0.5 * cum[-1])])

    @property
    def ratio(self) -> float | None:
        """Flight gravity in units of g (1 in a real flight)."""
        return None if self.g is None else self.g / G

    @property
    def time_factor(self) -> float | None:
        """How many times too slow the clip plays (below 1: too fast); None without a usable flight."""
        g = self.g
        return None if g is None or g <= 0 else float(np.sqrt(G / g))


@dataclass
class FootPoints:
    """A motion's centre of mass and the points its feet can stand on, at its own frames, unsmoothed
    (y up, metres): each foot's four sole corners and its toe tip (a pushing-off foot pivots on the
    tip with its sole already up). Points 0-3 and 8 are the left foot's, 4-7 and 9 the right's."""

    com: np.ndarray  # (F, 3)
    height: np.ndarray  # (F, 10): above the point's own floor
    velocity: np.ndarray  # (F, 10, 3) m/s

    @property
    def bears(self) -> np.ndarray:
        """(F, 10) bool: the point bears on the floor: within :data:`CLEAR_M` of it, or within
        :data:`NEAR_M` and nearly still (:data:`STILL_M_S`; a foot rolling onto its tip, whose height
        the floor estimate knows only to a centimetre or two)."""
        speed = np.linalg.norm(self.velocity, axis=-1)
        return (self.height < CLEAR_M) | ((self.height < NEAR_M) & (speed < STILL_M_S))

    @property
    def airborne(self) -> np.ndarray:
        """(F,) bool: no point of either foot bears on the floor."""
        return ~self.bears.any(axis=1)


def foot_points(motion, body) -> FootPoints:
    """The :class:`FootPoints` of ``motion`` (y up, as physics sees it) with ``body``'s masses and
    soles. Heights are above each point's own floor, as contact detection takes them
    (:func:`retime.motion.feet.above_own_floor`)."""
    from ..motion.feet import bone_ends, feet_in_order
    from .model.body import centre_of_mass, world_frames

    pos, R = world_frames(motion)
    com = centre_of_mass(body, R, pos)
    corners = corner_positions(body, motion.skeleton, R, pos)  # (F, 8, 3): 4 per foot, left first
    ends = bone_ends(motion.skeleton)
    tips = [motion.skeleton.index(f.toe_joint) for f in feet_in_order(body.feet)]
    tip = np.stack([pos[:, j] + np.einsum("fab,b->fa", R[:, j], ends[j]) for j in tips], axis=1)  # (F, 2, 3)
    points = np.concatenate([corners, tip], axis=1)  # (F, 10, 3)
    height = above_own_floor(points[..., 1], motion.fps)
    velocity = np.gradient(points, axis=0) * motion.fps if len(points) > 1 else np.zeros(points.shape)
    return FootPoints(com, height, velocity)


def fit_flights(height, air, fps: float, trim: int = TRIM_FRAMES) -> FlightGravity:
    """A parabola through ``height`` (F,) over each airborne run of ``air`` (F,), ``trim`` frames in
    from its ends; runs too short to fit (:data:`MIN_FIT_FRAMES`, :data:`MIN_FIT_S`) are skipped."""
    out = FlightGravity(fps=float(fps))
    height = np.asarray(height, dtype=float)
    for up, a, b in runs(air):
        a, b = a + trim, b - trim
        if not up or b - a + 1 < MIN_FIT_FRAMES or (b - a) / fps < MIN_FIT_S:
            continue
        t = (np.arange(a, b + 1) - 0.5 * (a + b)) / fps
        coef, res, *_ = np.polyfit(t, height[a:b + 1], 2, full=True)
        rms = float(np.sqrt(res[0] / (b - a + 1))) if len(res) else 0.0
        out.flights.append(Flight(int(a), int(b), float(-2.0 * coef[0]), rms))
    return out


def flight_gravity(points: FootPoints, fps: float) -> FlightGravity:
    """The flight gravity of a motion from its :class:`FootPoints` (see the module docstring)."""
    air = points.airborne
    out = fit_flights(points.com[:, 1], air, fps)
    out.airborne = air
    return out
