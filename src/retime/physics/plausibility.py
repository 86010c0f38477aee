"""Is the clip physical as captured? Said before retiming: physical, or each cause found as a code
(:data:`CAUSES`) and a sentence with its numbers and what to do.

* **Flights** (:mod:`.ballistic`): in flight the centre of mass falls at g. A clip whose flights
  fall at another rate plays at the wrong frame rate (``frame_rate``, named with its factor and the
  Frame Time that fits); one whose body barely falls with both feet off the floor is held up by
  something physics does not see (``held_up``).
* **Stance** (:mod:`.stance_rate`), for a gait without a measured flight (walks, a run's short
  flights): on one foot the contact forces must explain the body's wrench through the sole corners
  on the floor; the uniform rate at which they do so best, the median over the steps, says how many
  times too slow the clip plays (``frame_rate``), when it is clearly away from 1.
* **Floor and root**: feet that move at floor height while the root goes nowhere are on a
  treadmill (``treadmill``), or skate (``foot_slide``); a root that never moves is an in-place
  export (``root_locked``); a pose that never changes while the root moves was written in radians
  (``radians``).
* **Residual**: the regions (:mod:`.regions`) measure, per source frame, the force the clip's own
  timing needs beyond what the body and its foot contacts can give (``source_residual``, in body
  weights). Real captures need little on most frames; a clip read with the wrong up axis needs
  about one body weight on every frame (``up_axis``). Frames within two smoothing widths of a
  flight that falls at g are left to the flight's parabola: the path's low-pass smears the stance
  forces around a run's 0.1 s flights into them (a run's frames would otherwise read 17-70 %
  over). Residual left with no named cause is ``unexplained`` (hands, props, keyframed motion).

**Cautions** (:data:`CAUTIONS`) are doubts that leave a clip physical: a stance rate outside its
band on one step or on disagreeing steps (``frame_rate_unconfirmed``), and flights at g under a
guessed, unusual length unit, which g cannot tell from a wrong rate (``units_unconfirmed``).

**Unit or rate.** Flights and stance forces measure only the length unit times the frame rate
squared: a body s times larger moving sqrt(s) times slower is the same to physics (dynamic
similarity; on jumping.bvh the stance residual's least rate moves with the unit exactly as the
flight's factor does). What tells a wrong unit from a wrong rate is the body's size: a unit that
would give legs no human has (:data:`HUMAN_LEG_M`) is not the cause; where both readings give a
human, the check does not choose for the user, and names both with their numbers.

Regions are widened by the residual, so a retiming of such a clip can look "100 % feasible" while
its physics means little: :func:`check_source` says so, and why.

Calibrated on ../shared/data (CMU and the dev set) and their metamorphic variants
(``benchmarks/check_verdicts.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import binary_dilation

from ..motion.frame import UNIT_NAMES, UNITS
from .ballistic import FlightGravity, FootPoints, flight_gravity, foot_points
from .stance_rate import StanceRate, stance_rate

OFF_RESIDUAL = 0.25  # body weights: a source frame needing more is not physical as captured
MAX_OFF_SHARE = 0.1  # a clip with more such frames is not physical as captured
# (real captures on CMU and the dev set: 2-7 %; a Kinect standing clip 16 %, root-locked dance 18 %)
SLIDE_SPEED = 0.45  # m/s: median horizontal speed of the feet at floor height above this is sliding
# (real captures on the dev set and CMU: 0.00-0.30 m/s; a walk with its travel removed: 0.64)
STILL_ROOT_M = 1e-3  # the root moving less than this (std, metres) is locked in place
FROZEN_DEG = 6.5  # every joint but the root within this of its rest pose on every frame: a frozen clip
FLIGHT_G = (0.8, 1.3)  # flights falling in this range (units of g) play at their true rate
# (real flights on CMU and the dev set, with the default body's masses: 0.91-1.19 g; Frame Time
# x1.25 gives 0.59-0.76 g, x0.8 1.43-1.86 g)
MIN_FLIGHT_S = 0.1  # fitted flight (s) below this says nothing about the frame rate
STANCE_RATE = (0.92, 1.11)  # without a flight, a single-support rate (:mod:`.stance_rate`) in this range is the clip's own
# (real walks and a run on CMU and the dev set: 0.94-1.08; Frame Time x0.8 gives 0.73-0.90, x1.25 1.13-1.39:
# the edges sit between those, a few per cent from each, so a rate off by 10 % is mostly not named)
STANCE_MIN_STEPS = 2  # ... measured on at least this many steps (a median of one step is that step's noise)
# ... and further from 1 than its steps' spread allows (one standard error of the median): a real
# run whose steps read 0.54-1.26 (131_03, median 0.91 +- 16 %; its flight decides it) would not be named
LOCOMOTION_M_S = 0.35  # ... and only on a clip whose root travels this fast: a gait (walks 0.42-2.0 m/s; a samba 0.24)
HELD_G = 0.2  # flights falling slower than this are held up, not slowed down (a rate 2.2x off)
TREADMILL_TRAVEL = 0.3  # the root travelling less than this share of the feet's floor speed: a treadmill
TRAVEL_WINDOW_S = 1.0  # the root's travel is measured over this, so a stance's sway does not count
BODY_HEIGHT_M = (1.0, 2.3)  # a body outside this (metres) may be read in the wrong unit
HUMAN_LEG_M = (0.35, 1.2)  # thigh + shank (m) of any human, a small child to a very tall adult: a unit
# that gives a leg outside this is not the file's, whatever its flights say (:func:`_human_in`)
KNOWN_UNIT = ("sure", "declared", "given")  # unit confidences at which the length unit is not doubted
COMMON_RATES = (24, 25, 30, 48, 50, 60, 90, 100, 120, 240)  # fps a fitted rate is snapped to ...
UNIT_SNAP = 0.05  # a guessed unit this close to a common one that gives 1 g flights is that one
RATE_SNAP = 0.1  # ... when this close (relative; flights measure a clip's rate to about 8 %)
CAPTURE_RATE_TOL = 0.005  # a written rate this close to a common one is that rate (119.88 = 120/1.001 is;
# every real file in ../shared/data is within 0.11 % of one)


@dataclass
class Cause:
    """One reason a clip is not physical as captured: ``code`` (one of :data:`CAUSES`) and a sentence
    with the numbers and what to do."""

    code: str
    sentence: str

    def __post_init__(self):
        assert self.code in CAUSES or self.code in CAUTIONS, self.code


CAUSES = {  # code: what it means (the sentence gives the numbers)
    "up_axis": "the up axis is wrong",
    "frame_rate": "the clip plays at the wrong frame rate",
    "radians": "rotations written in radians were read as degrees",
    "root_locked": "an in-place (root-locked) export",
    "treadmill": "a treadmill capture",
    "foot_slide": "the feet slide on the floor",
    "held_up": "the body is held up with both feet off the floor",
    "units": "the length unit is wrong",
    "unexplained": "more residual force than a real capture needs, for no named reason",
}


CAUTIONS = {  # code: what it means; a clip with only these is physical, but the check could not confirm it
    "frame_rate_unconfirmed": "with no flight to measure, the single support fits another rate, but its steps disagree",
    "units_unconfirmed": "the flights fall at g under a guessed, unusual length unit: in the nearest common unit "
                         "the clip would play at another rate",
}


@dataclass
class SourceCheck:
    physical: bool
    off_share: float  # share of the judged source frames needing more than OFF_RESIDUAL
    median_residual: float  # body weights
    found: list[Cause] = field(default_factory=list)
    flight: FlightGravity | None = None  # the flights' parabolas (None: not measured)
    travel: float = 0.0  # m/s, the root's mean horizontal travel over 1 s
    slide: float = 0.0  # m/s, median horizontal speed of the foot points bearing on the floor
    judged: np.ndarray | None = None  # (F,) bool: the frames the residual judged (None: all; the rest are near flights)
    stance: StanceRate | None = None  # the single-support rate (None: not measured, as where a flight is)
    cautions: list[Cause] = field(default_factory=list)  # doubts that leave the clip physical (:data:`CAUTIONS`)

    @property
    def judged_share(self) -> float:
        return 1.0 if self.judged is None or not self.judged.size else float(self.judged.mean())

    @property
    def causes(self) -> list[str]:
        return [c.sentence for c in self.found]

    @property
    def codes(self) -> list[str]:
        return [c.code for c in self.found]

    def message(self) -> str:
        if self.physical:  # physics' warning: a caution is said too, as check says it
            return "; ".join(c.sentence for c in self.cautions)
        return (f"this clip is not physical as captured: {'; '.join(self.causes)}. Feasibility is measured "
                "against regions widened to the clip's own residual, so it means less than usual")

    def as_dict(self) -> dict:
        f = self.flight
        return {"physical": self.physical, "off_share": round(self.off_share, 4),
                "median_residual": round(self.median_residual, 4), "codes": self.codes, "causes": self.causes,
                "flight_g": None if f is None or f.ratio is None else round(f.ratio, 4),
                "flights": 0 if f is None else len(f.flights),
                "flight_seconds": 0.0 if f is None else round(f.seconds, 4),
                "time_factor": None if f is None or f.time_factor is None else round(f.time_factor, 4),
                "stance_time_factor": None if self.stance is None or self.stance.time_factor is None
                else round(self.stance.time_factor, 4),
                "stance_steps": 0 if self.stance is None else len(self.stance.steps),
                "cautions": [c.code for c in self.cautions], "caution_sentences": [c.sentence for c in self.cautions],
                "root_travel": round(self.travel, 4), "floor_slide": round(self.slide, 4), "judged_share": round(self.judged_share, 4)}


def floor_slide(points: FootPoints) -> tuple[float, float]:
    """(median horizontal speed m/s, steadiness 0-1) of the foot points while they bear on the
    floor (:attr:`.ballistic.FootPoints.bears`), whether or not contact detection called them
    planted. Steadiness is |mean velocity| / mean speed: near 1 when the feet are carried one way,
    as on a treadmill; near 0 for skating back and forth."""
    on_floor = points.bears
    if not on_floor.any():
        return 0.0, 0.0
    vf = points.velocity[on_floor][:, [0, 2]]
    speed = np.linalg.norm(vf, axis=-1)
    steady = float(np.linalg.norm(vf.mean(axis=0)) / max(speed.mean(), 1e-9))
    return float(np.median(speed)), steady


def _frozen(motion) -> bool:
    """Every joint but the root stays within :data:`FROZEN_DEG` of its rest pose on every frame: a
    pose no capture holds, and what radians read as degrees give (2 pi rad read as 6.3 deg). The
    root's own rotation is left out: it is the heading, anything."""
    q = np.asarray(motion.rotations)[:, 1:]
    if len(q) < 3 or q.shape[1] == 0:
        return False
    angle = np.degrees(2 * np.arccos(np.clip(np.abs(q[..., 3]), 0, 1)))
    return bool(angle.max() < FROZEN_DEG)


def root_travel(root, fps) -> float:
    """Mean horizontal distance (m) the root covers in :data:`TRAVEL_WINDOW_S`, per second: its
    travel, not its sway (a treadmill's root sways a few centimetres and goes nowhere)."""
    root = np.asarray(root, dtype=float)
    k = max(1, min(len(root) - 1, int(round(TRAVEL_WINDOW_S * fps))))
    if len(root) < 2:
        return 0.0
    step = root[k:, [0, 2]] - root[:-k, [0, 2]]
    return float(np.mean(np.linalg.norm(step, axis=1)) * fps / k)


def _common_rate(fps: float) -> float | None:
    near = min(COMMON_RATES, key=lambda r: abs(r - fps))
    return float(near) if abs(near - fps) <= RATE_SNAP * near else None


def _unit_that_fits(flight: FlightGravity, frame) -> tuple[str, float] | None:
    """(name, metres per unit) of the common length unit under which the flights fall at 1 g, when
    the unit was only guessed (an unusual scale) and one is within :data:`UNIT_SNAP`: a scale is as
    likely wrong as a rate."""
    if frame is None or frame.unit_confidence in KNOWN_UNIT:
        return None
    fit = frame.meters_per_unit / flight.ratio
    name, mpu = min(UNITS.items(), key=lambda u: abs(np.log(u[1] / fit)))
    return (name, mpu) if abs(mpu / fit - 1.0) <= UNIT_SNAP else None


def _leg_in(frame, mpu: float) -> float:
    """The skeleton's leg (thigh + shank, m) were 1 unit ``mpu`` metres (nan: not measured)."""
    return float(frame.leg_m) * mpu / frame.meters_per_unit


def _human_in(frame, mpu: float) -> bool:
    """Whether the body is of a human's size (:data:`HUMAN_LEG_M`, or of unknown size) in the unit
    ``mpu``. Flights and stance forces measure only the unit times the frame rate squared (a body
    scaled by s moving sqrt(s) times slower is dynamically the same), so the body's size is what
    tells a wrong unit from a wrong rate: only when one reading is no human's."""
    leg = _leg_in(frame, mpu)
    return not np.isfinite(leg) or HUMAN_LEG_M[0] <= leg <= HUMAN_LEG_M[1]


def _legs(frame, mpu: float) -> str:
    leg = _leg_in(frame, mpu)
    return f"legs {leg:.2f} m hip to ankle" if np.isfinite(leg) else "legs of unknown length"


def _capture_rate(fps: float) -> bool:
    """Whether ``fps`` is a common capture rate as written (:data:`CAPTURE_RATE_TOL`)."""
    return any(abs(fps / r - 1.0) <= CAPTURE_RATE_TOL for r in COMMON_RATES)


def _rate_parts(k: float, fps: float) -> tuple[str, str, str]:
    """(how: "1.25x too slow", the Frame Times: "Frame Time 0.0104 s; 0.0083 s fits", the fix:
    "96 fps: give --fps 96") for a clip that plays ``k`` times too slow at ``fps``."""
    ft, fit = 1.0 / fps, 1.0 / (fps * k)
    how = f"{k:.2f}x too slow" if k > 1 else f"{1 / k:.2f}x too fast"
    rate = _common_rate(1.0 / fit)
    rate_fix = f"{1.0 / fit:.0f} fps: likely {rate:g}, give --fps {rate:g}" if rate else f"give --fps {1.0 / fit:.0f}"
    return how, f"Frame Time {ft:.4f} s; {fit:.4f} s fits", rate_fix


def flight_cause(flight: FlightGravity, fps: float, frame) -> Cause:
    """Flights that fall at the wrong rate: the wrong frame rate, named by its factor and the Frame
    Time that fits, or (a guessed scale, :func:`_unit_that_fits`) the wrong unit; ``frame``: the
    skeleton's FrameGuess."""
    how, times, rate_fix = _rate_parts(flight.time_factor, fps)
    falls = (f"in {len(flight.flights)} flight{'s' if len(flight.flights) > 1 else ''} ({flight.seconds:.2f} s) the "
             f"centre of mass falls at {flight.ratio:.2f} g, not 1 g")
    fits = _unit_that_fits(flight, frame)
    if fits is not None and _human_in(frame, fits[1]):
        unit, mpu = fits
        return Cause("units", f"the length unit is likely {unit}, not {frame.meters_per_unit:.4g} m "
                              f"({frame.unit_confidence}): {falls} (give --units {unit}; {_legs(frame, mpu)}); or "
                              f"it plays {how} ({times}: {rate_fix}; {_legs(frame, frame.meters_per_unit)} as read)")
    s = f"plays {how}: {times} ({rate_fix}); {falls}"
    if fits is not None:  # a common unit would put the flights at g, but no human is that size
        s += (f"; in {UNIT_NAMES.get(fits[0], fits[0])} they would fall at 1 g, but with {_legs(frame, fits[1])} "
              "the body would be no human's")
    if frame is not None and not (BODY_HEIGHT_M[0] <= frame.height_m <= BODY_HEIGHT_M[1]):
        s += (f"; or the length unit is off (1 unit = {frame.meters_per_unit:.4g} m, {frame.unit_confidence}, "
              f"the body {frame.height_m:.2f} m tall: give --units)")
    return Cause("frame_rate", s)


def _stance_steps(stance: StanceRate) -> str:
    k, n = stance.time_factor, len(stance.steps)
    steps = (f"the median of {n} steps, +-{np.expm1(stance.uncertainty):.0%}; {stance.steps_beyond(k)} of them "
             f"{'above' if k > 1 else 'below'} 1") if n > 1 else "one step"
    return (f"on one foot ({stance.seconds:.2f} s of single support) the contact forces explain the motion best "
            f"with its time scaled by {k:.2f} ({steps})")


def stance_cause(stance: StanceRate, fps: float) -> Cause:
    """A clip without a measured flight whose single-support frames fit another rate
    (:mod:`.stance_rate`): the wrong frame rate, named as :func:`flight_cause` names it."""
    how, times, rate_fix = _rate_parts(stance.time_factor, fps)
    return Cause("frame_rate", f"plays {how}: {times} ({rate_fix}); with no flight to measure, {_stance_steps(stance)}")


def stance_caution(stance: StanceRate, fps: float) -> Cause:
    """A stance rate outside :data:`STANCE_RATE` on too few steps, or on steps too spread to tell it
    from 1: the clip may play at the wrong rate; said as a caution, not a cause."""
    how, times, _ = _rate_parts(stance.time_factor, fps)
    return Cause("frame_rate_unconfirmed", f"frame rate unconfirmed: {_stance_steps(stance)}, too few or too spread "
                                           f"to tell from its own rate; no flight to measure (if it plays {how}: {times})")


def stance_finding(stance: StanceRate | None, fps: float) -> tuple[Cause | None, Cause | None]:
    """(cause, caution) of a stance rate: ``frame_rate`` when it lies outside :data:`STANCE_RATE` on
    :data:`STANCE_MIN_STEPS` steps or more and further from 1 than their median's uncertainty; a
    ``frame_rate_unconfirmed`` caution when it lies outside on fewer or disagreeing steps."""
    if stance is None or stance.time_factor is None or STANCE_RATE[0] <= stance.time_factor <= STANCE_RATE[1]:
        return None, None
    if len(stance.steps) >= STANCE_MIN_STEPS and abs(np.log(stance.time_factor)) > stance.uncertainty:
        return stance_cause(stance, fps), None
    return None, stance_caution(stance, fps)


def unit_caution(flight: FlightGravity, fps: float, frame) -> Cause | None:
    """Flights falling at g under a guessed length unit that is no common one confirm the unit only if
    the frame rate is right (g scales with the unit and with the rate squared, and so does every force
    at the feet): when the nearest common unit would make them fall outside :data:`FLIGHT_G` and gives
    a human-sized body (:func:`_human_in`), a caution naming both readings with their numbers."""
    if frame is None or frame.unit_confidence in KNOWN_UNIT or flight.ratio is None:
        return None
    name, mpu = min(UNITS.items(), key=lambda u: abs(np.log(u[1] / frame.meters_per_unit)))
    ratio = flight.ratio * mpu / frame.meters_per_unit  # the flights' g in that unit
    if abs(mpu / frame.meters_per_unit - 1.0) <= UNIT_SNAP or FLIGHT_G[0] <= ratio <= FLIGHT_G[1] \
            or not _human_in(frame, mpu):
        return None
    how, times, rate_fix = _rate_parts(1.0 / np.sqrt(ratio), fps)
    written = f"the file's {fps:.1f} fps" + ("" if _capture_rate(fps) else ", no common capture rate")
    return Cause("units_unconfirmed", "length unit unconfirmed: two readings fit, and neither flights nor stance forces "
                                      "can tell them apart (they measure the unit times the frame rate squared): as read, "
                                      f"1 unit = {frame.meters_per_unit:.4g} m ({frame.unit_confidence}), "
                                      f"{_legs(frame, frame.meters_per_unit)}, the flights fall at {flight.ratio:.2f} g at "
                                      f"{written}; in {UNIT_NAMES.get(name, name)}, the nearest common unit, "
                                      f"{_legs(frame, mpu)}, they would fall at {ratio:.2f} g and the clip would play "
                                      f"{how} ({times}: {rate_fix}). Give --units {name} or --units "
                                      f"{frame.meters_per_unit:.4g} to decide")


def _near(mask, frames: int) -> np.ndarray:
    return binary_dilation(mask, iterations=frames) if frames > 0 and mask.any() else mask


def _up_axis_cause(motion, frame, off_all: float, med_all: float) -> Cause | None:
    """About one body weight of residual on nearly every frame, with the up axis read unsurely (or
    given): the up axis is wrong."""
    up_given = frame is not None and frame.up_given
    if not (med_all > 0.6 and off_all > 0.8 and (frame is None or frame.up_confidence < 0.9 or up_given)):
        return None
    conf = (", as given" if up_given else f", {frame.up_confidence:.0%} of frames agree") if frame is not None else ""
    return Cause("up_axis", f"the up axis is wrong (read as {motion.skeleton.up if frame is None else frame.up}"
                            f"{conf}; give --up)")


def _pose_cause(frozen: bool, still: bool) -> Cause | None:
    """A pose that never changes while the root moves (radians), or a root that never moves (locked)."""
    if frozen and not still:
        return Cause("radians", f"the pose barely changes (every joint within {FROZEN_DEG:g} deg of its rest "
                                "pose) while the root moves: rotations written in radians but read as degrees? give --angles rad")
    if still and not frozen:
        return Cause("root_locked", "the root never moves: an in-place (root-locked) export, which has no "
                                    "travel or balance to keep; physics needs the character's own root motion")
    return None


def _floor_cause(slide: float, steady: float, travel: float) -> Cause | None:
    """Feet that move at floor height (:func:`floor_slide`): a treadmill when the root goes nowhere
    meanwhile (:func:`root_travel`), else sliding feet."""
    if slide <= SLIDE_SPEED:
        return None
    if travel < TREADMILL_TRAVEL * slide:
        how = "steadily one way" if steady > 0.5 else "back and forth"
        return Cause("treadmill", f"a treadmill or an in-place loop: the feet move while at floor height "
                                  f"(median {slide:.2f} m/s, {how}) while the root travels {travel:.2f} m/s; "
                                  "physics assumes a static floor and feet that stay where they land")
    return Cause("foot_slide", f"the feet move while at floor height (median {slide:.2f} m/s; the root "
                               f"travels {travel:.2f} m/s): foot skating or noisy tracking; physics "
                               "assumes a static floor and feet that stay where they land")


def _held_up_in_flight(flight: FlightGravity) -> Cause:
    return Cause("held_up", f"with both feet off the floor ({flight.seconds:.2f} s fitted) the centre "
                            f"of mass falls at {flight.ratio:.2f} g: something else holds the body up "
                            "(hands or knees on the floor, a prop, a floor the feet do not reach, or "
                            "feet tracked badly)")


def _residual_cause(off: float, med: float, frame, air, ballistic: bool) -> Cause:
    """What more residual than a real capture needs, with no other cause found, most likely means: a
    guessed unit, a body that floats with its feet off the floor, or nothing named."""
    if frame is not None and frame.unit_confidence not in KNOWN_UNIT:
        return Cause("units", f"the length unit is uncertain (read as 1 unit = {frame.meters_per_unit:.4g} m, "
                              f"{frame.unit_confidence}; give --units)")
    if float(air.mean()) > 0.4 and not ballistic:
        return Cause("held_up", f"both feet are off the floor in {air.mean():.0%} of the frames, yet the body "
                                "does not fall as in a flight (a floating capture floor, a platform, hands "
                                "on the floor, or feet tracked badly)")
    return Cause("unexplained", f"{off:.0%} of its frames need more than {OFF_RESIDUAL:.0%} of body "
                                f"weight of extra force at their own timing (median {med:.2f}): hand or "
                                "knee contacts (cartwheels, crawls), props, noisy tracking, or keyframed "
                                "motion that was never physical")


def _over(res) -> tuple[float, float]:
    """(share over :data:`OFF_RESIDUAL`, median) of residuals ``res``."""
    return (float(np.mean(res > OFF_RESIDUAL)), float(np.median(res))) if res.size else (0.0, 0.0)


def check_source(motion, terms, regions) -> SourceCheck:
    """How physical ``motion`` (the conformed motion physics saw, or the original) is at its own
    timing, from the ``terms`` and ``regions`` of its dynamics; the causes when it is not (see the
    module docstring)."""
    from .model.dynamics import conformed

    res = np.asarray(regions.source_residual, dtype=float)
    spf = int(terms.samples_per_frame)
    res = res[::spf] if len(res) > motion.n_frames else res
    fps = float(terms.fps)
    frame = getattr(motion.skeleton, "frame", None)
    points = foot_points(conformed(motion).motion, terms.body)
    flight = flight_gravity(points, fps)
    air = flight.airborne if flight.airborne is not None and len(flight.airborne) == len(res) else np.zeros(len(res), bool)
    off_all, med_all = _over(res)
    frozen = _frozen(motion)
    root = np.asarray(terms.root_origin)[::spf]
    still = len(root) > 2 and float(np.max(np.std(root, axis=0))) < STILL_ROOT_M
    up = _up_axis_cause(motion, frame, off_all, med_all)
    if up is not None:
        # the floor, the feet and the flights are all measured along the wrong axis: nothing else to say
        return SourceCheck(False, off_all, med_all, [up], flight)
    found = [c for c in [_pose_cause(frozen, still)] if c is not None]
    travel = root_travel(root, fps)
    slide, steady = floor_slide(points)
    if not still and not frozen:
        found += [c for c in [_floor_cause(slide, steady, travel)] if c is not None]
    measured = flight.ratio is not None and flight.seconds >= MIN_FLIGHT_S
    ballistic = measured and FLIGHT_G[0] <= flight.ratio <= FLIGHT_G[1]
    # a frozen pose, a pinned root or a moving floor make the flights meaningless
    if not found and measured and not ballistic:
        found.append(_held_up_in_flight(flight) if flight.ratio < HELD_G else flight_cause(flight, fps, frame))
    # without a flight the single-support frames are the rate's only measure (flights stay primary)
    # (calibrated on walks and runs, where the body vaults over one foot at a time: not on dances)
    stance = stance_rate(terms) if not found and not measured and travel >= LOCOMOTION_M_S else None
    cause, caution = stance_finding(stance, fps)
    found += [cause] if cause is not None else []
    cautions = [caution] if caution is not None else []
    if not found and ballistic:
        cautions += [c for c in [unit_caution(flight, fps, frame)] if c is not None]
    # frames within two smoothing widths of a flight get the stance forces around it smeared into them:
    # there the flight's parabola judges the clip, not the residual
    # (flights too short to fit, as a run's may be, are not contradicted either)
    judged = ~_near(air, int(round(2 * terms.smoothing * fps))) if ballistic or not measured else np.ones(len(res), bool)
    off, med = _over(res[judged])
    if off > MAX_OFF_SHARE and not found:
        found.append(_residual_cause(off, med, frame, air, ballistic))
    return SourceCheck(not found, off, med, found, flight, travel, slide, judged, stance, cautions)
