"""The world frame a motion was captured in: its up axis and its length unit, found from the motion.

* **Up** (:func:`up_from_contacts`): gravity holds a body on the floor, so along the up axis the
  lowest points rest on one plane: in most frames some joints lie on the floor level, slow, with the
  centre of mass over them. This works standing, kneeling, lying, crawling and for animals. Each
  signed world axis is scored by its frames at rest this way (weighted by how many joints rest, up
  to :data:`REST_JOINTS`); when the scores leave it open (a clip at rest, nothing moving) the axis
  along which the head (or the root) lies above the feet in most frames decides (:func:`detect_up`).
  Confidence: the share of frames whose head is above the feet along it, or, when the contacts
  overrule that axis, the share of frames at rest on the new one. A floor that never holds a foot
  does not overrule a head-above-feet axis the feet stand on (a jump whose still IK hands are the
  lowest points sideways).
* **Four limbs.** A skeleton named like a biped (3ds Max Biped animals) whose hands rest on the floor
  in at least :data:`FOUR_LIMB_SHARE` of the frames its feet do bears weight on four limbs: not a
  biped.
* **Units** (:func:`detect_units`): segment lengths and standing height, not the rest pose (rest
  poses with bones along +X are common): the thigh + shank length (bone lengths, whatever the pose)
  and the head's height above the lower foot (95th percentile over the clip) give the body's size
  in file units; compared with a typical adult (leg 0.84 m, head joint 1.45 m above the floor),
  that is a metres-per-unit estimate (the head's height only when the clip stands up at some time:
  at least :data:`STANDING_RATIO` leg lengths). It snaps to m, cm, mm, inches, feet or CMU's unit when one is
  within a factor 1.3 (sure within 1.15), else it is kept as is (an unusual scale, reported).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fk import forward_kinematics
from .model import LENGTH_UNITS
from .rig import Limbs, NotBiped, bone_joints, descendants, find_limbs, floating_base, nearest_pair_tips

AXES = {"x": 0, "y": 1, "z": 2}
UNITS = {k: v for k, v in LENGTH_UNITS.items() if k != "dm"}  # the units files are written in
UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches", "ft": "feet",
              "cmu": "CMU units (1/0.45 in)"}
TYPICAL_LEG_M = 0.84  # thigh + shank of an adult (hip joint to ankle joint)
TYPICAL_HEAD_M = 1.45  # head joint above the floor, standing
SNAP_FACTOR = 1.3
STANDING_RATIO = 1.3  # head height / leg length of a body standing up (typically 1.45 / 0.84 = 1.73)
SURE_FACTOR = 1.15
MAX_FRAMES = 2000  # detection looks at this many frames at most (evenly spread)


def parse_up(text: str) -> str:
    """'y', '+Z', '-x' -> '+y', '+z', '-x'."""
    t = str(text).strip().lower()
    sign = "-" if t.startswith("-") else "+"
    axis = t.lstrip("+-")
    if axis not in AXES:
        raise ValueError(f"up axis must be one of x, y, z, -x, -y, -z, got {text!r}")
    return sign + axis


def up_vector(up: str) -> np.ndarray:
    up = parse_up(up)
    v = np.zeros(3)
    v[AXES[up[1]]] = -1.0 if up[0] == "-" else 1.0
    return v


def up_rotation(up: str) -> np.ndarray:
    """The rotation taking the axis ``up`` to +y (a quarter or half turn about x or z)."""
    from scipy.spatial.transform import Rotation

    u = up_vector(up)
    if u[1] == 1:
        return np.eye(3)
    if u[1] == -1:
        return np.diag([1.0, -1.0, -1.0])
    if u[2] != 0:  # about x
        return Rotation.from_euler("x", -90 * u[2], degrees=True).as_matrix().round()
    return Rotation.from_euler("z", 90 * u[0], degrees=True).as_matrix().round()


def to_y_up(positions, skeleton):
    """World positions (..., 3) of a skeleton's motion turned so that its up axis is +y (for
    drawing: renderers and the editor show every file standing up)."""
    R = up_rotation(skeleton.up)
    return positions if np.array_equal(R, np.eye(3)) else positions @ R.T


def parse_units(text) -> tuple[str, float]:
    """'cm' -> ('cm', 0.01); '0.04' -> ('0.04 m', 0.04) (metres per unit)."""
    t = str(text).strip().lower()
    if t in UNITS:
        return t, UNITS[t]
    try:
        v = float(t)
    except ValueError:
        v = float("nan")
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"units must be one of {', '.join(u for u in UNITS if u != 'cmu')} or metres per unit "
                         f"(e.g. 0.04), got {text!r}")
    return f"{v:g} m", v


@dataclass
class FrameGuess:
    """What :func:`detect_frame` found (or was told)."""

    up: str  # '+y', '-z', ...
    up_confidence: float  # share of frames that agree (1.0 when given)
    meters_per_unit: float
    unit: str  # 'cm', 'in', ... or '0.0376 m' for an unusual scale
    unit_confidence: str  # 'given', 'declared', 'sure', 'likely', 'unusual scale', 'unknown'
    height_m: float  # head (or root) above the lower foot, 95th percentile, metres (nan if unknown)
    leg_m: float  # thigh + shank, metres (nan if unknown)
    limbs: Limbs | None = None
    biped: str = ""
    up_given: bool = False  # why the skeleton is not a biped ('' if it is one)


def _sample_step(n_frames) -> int:
    return max(1, int(np.ceil(n_frames / MAX_FRAMES)))


def _sample_frames(n_frames):
    return slice(0, n_frames, _sample_step(n_frames))


def detect_up(positions, top: int, feet) -> tuple[str, float]:
    """Signed axis along which joint ``top`` is above the mean of ``feet`` in most frames."""
    v = positions[:, top] - positions[:, list(feet)].mean(axis=1)  # (F, 3)
    a = np.abs(v)
    axis = np.argmax(a, axis=1)
    sign = np.sign(v[np.arange(len(v)), axis])
    votes = {}
    for ax, sg in zip(axis, sign):
        key = ("-" if sg < 0 else "+") + "xyz"[ax]
        votes[key] = votes.get(key, 0) + 1
    if not votes:
        return "+y", 0.0
    best = max(votes, key=votes.get)
    return best, votes[best] / len(v)


REST_TOL = 0.03  # of the body's size: a joint this close to the floor level is on it
REST_SPEED = 0.25  # body sizes per second: a joint on the floor this slow is at rest
BALANCE_MARGIN = 0.1  # of the body's size: the centre of mass lies over its support, give or take
REST_JOINTS = 8  # a frame at rest counts its resting joints up to this many
FLAT_FLOOR = 0.1  # of the body's size: the lowest point stays this close to one level (P5 to P80 of frames)
MIN_REST = 0.25  # share of frames at rest an axis needs to overrule the head-above-feet axis ...
OVERRULE = 2.0  # ... and this many times its score
HEAD_ABOVE_ALWAYS = 0.95  # a head above the feet in this share of frames ...
MIN_REST_SURE = 0.75  # ... is overruled only by an axis at rest in this share: a body resting on a
# floor rests in nearly every frame (a kneeling bow, an elephant, a body lying down: 100 %), while a
# root-locked export hangs and its swinging hand rests on a 'wall' at its turning points (CMU walks
# and a jump, locked: 33-54 %)
FOUR_LIMB_SHARE = 0.5
FEET_STAND = 0.25  # feet resting on the head-above-feet floor in this share of frames: the body stands there ...
FEET_ELSEWHERE = 0.05  # ... and a floor that holds a foot in fewer frames than this is no floor of its: a still
# hand (a Rigify IK hand left unkeyed, its fingers the lowest points sideways) or a prop the body touches.
# Kneeling, lying and four-legged bodies have their feet on their floor too (insteps, heels, hind feet).


def _mass_centre(positions, parents):
    """(F, 3): the bones' midpoints weighted by their lengths (a body's mass lies along its bones)."""
    child = np.arange(1, positions.shape[1])
    a, b = positions[:, child], positions[:, parents[child]]
    w = np.linalg.norm(a - b, axis=2)[..., None]
    return (0.5 * (a + b) * w).sum(axis=1) / np.maximum(w.sum(axis=1), 1e-12)


@dataclass
class Rest:
    """Where the body rests on the floor along one signed axis, per frame."""

    on_floor: np.ndarray  # (F, J) joints on the floor level and slow
    balanced: np.ndarray  # (F,) some joints rest, with the centre of mass over them
    flatness: float  # how far the lowest point strays from one level (P5 to P80 of frames), in body sizes

    def score(self) -> float:
        """Frames at rest, each counting its resting joints (up to REST_JOINTS); 0 off a flat floor."""
        if self.flatness > FLAT_FLOOR:
            return 0.0
        return float(np.mean(self.balanced * np.minimum(self.on_floor.sum(axis=1), REST_JOINTS)))


def rest_on(positions, parents, fps, up: str) -> Rest:
    """How the body rests on a floor whose normal is ``up`` (see :func:`up_from_contacts`);
    ``positions`` (F, J, 3) world joint positions at ``fps`` frames per second."""
    lo, hi = positions.min(axis=1), positions.max(axis=1)
    size = float(np.median(np.linalg.norm(hi - lo, axis=1))) or 1.0
    k = AXES[up[1]]
    h = positions[..., k] * (-1.0 if up[0] == "-" else 1.0)
    lowest = h.min(axis=1)
    floor = float(np.percentile(lowest, 5))
    speed = (np.linalg.norm(np.gradient(positions, axis=0), axis=2) * fps if len(positions) > 1
             else np.zeros(h.shape))
    on = (h - floor <= REST_TOL * size) & (speed <= REST_SPEED * size)
    plane = [a for a in range(3) if a != k]
    q = positions[..., plane]  # (F, J, 2)
    com = _mass_centre(positions, parents)[:, plane]
    lo_q = np.where(on[..., None], q, np.inf).min(axis=1)
    hi_q = np.where(on[..., None], q, -np.inf).max(axis=1)
    margin = BALANCE_MARGIN * size
    balanced = on.any(axis=1) & np.all((com >= lo_q - margin) & (com <= hi_q + margin), axis=1)
    return Rest(on, balanced, (float(np.percentile(lowest, 80)) - floor) / size)


def _feet_rest(rest: Rest, parents, feet) -> float:
    """The share of frames in which a foot (or a joint below it: a toe) rests on the floor."""
    below = sorted({k for f in feet for k in descendants(parents, f)})
    return float(rest.on_floor[:, below].any(axis=1).mean()) if below else 0.0


def up_from_contacts(positions, parents, fps, prior: str | None = None, head_lift=None,
                     prior_confidence: float = 0.0, feet=()) -> tuple[str, float]:
    """The signed axis along which the body rests on the floor best (see the module docstring), and
    its confidence: the share of frames at rest on it, or ``prior_confidence`` (the share of frames
    whose head is above the feet) when ``prior`` stands. ``prior`` (the head-above-feet axis) stands unless another
    axis is at rest in :data:`MIN_REST` of the frames (:data:`MIN_REST_SURE` when the head is above
    the feet in :data:`HEAD_ABOVE_ALWAYS` of them) and scores :data:`OVERRULE` times as much (a
    clip at rest throughout, against a wall or on a floor, looks alike). The sign of a new axis is
    the side the head is on (``head_lift``, the median head-minus-feet vector), when it is clear;
    an upside-down reading is never taken from the contacts alone (a still head rests like a foot).
    When the ``feet`` (joint indices) rest on the prior's floor in :data:`FEET_STAND` of the frames, an
    axis whose floor holds a foot in fewer than :data:`FEET_ELSEWHERE` of them does not overrule it."""
    rests = {sign + axis: rest_on(positions, parents, fps, sign + axis) for axis in "xyz" for sign in "+-"}
    scores = {up: r.score() for up, r in rests.items()}
    if prior is None:
        best = max(scores, key=scores.get)
        return best, float(rests[best].balanced.mean())
    size = float(np.median(np.linalg.norm(positions.max(axis=1) - positions.min(axis=1), axis=1))) or 1.0
    lift = np.zeros(3) if head_lift is None else np.asarray(head_lift, dtype=float)

    def signed(up):  # the side the head is on, when it is clear
        k = AXES[up[1]]
        return ("+" if lift[k] > 0 else "-") + up[1] if abs(lift[k]) > BALANCE_MARGIN * size else up

    need = MIN_REST_SURE if prior_confidence >= HEAD_ABOVE_ALWAYS else MIN_REST
    standing = len(feet) > 0 and _feet_rest(rests[prior], parents, feet) >= FEET_STAND
    floors = {signed(up) for up in rests if up[1] != prior[1] and scores[up] > 0
              and scores[up] >= OVERRULE * scores[prior] and rests[up].balanced.mean() >= need
              and not (standing and _feet_rest(rests[up], parents, feet) < FEET_ELSEWHERE)}
    if not floors:
        return prior, float(prior_confidence)
    # floors alike (a body at rest lies on its side as well as it stands): the one the head is highest above
    best = max(floors, key=lambda up: (round(float(lift[AXES[up[1]]]) * (1 if up[0] == "+" else -1) / size, 1),
                                       scores[up]))
    return best, float(rests[best].balanced.mean())


def four_limbed(positions, parents, fps, up: str, limbs: Limbs) -> str:
    """Why the skeleton bears weight on four limbs ('' when it does not): its hands rest on the floor
    in at least :data:`FOUR_LIMB_SHARE` of the frames its feet do."""
    if len(limbs.arms) < 2:
        return ""
    on = rest_on(positions, parents, fps, up).on_floor

    def resting(ends):
        return np.any([on[:, descendants(parents, j)].any(axis=1) for j in ends], axis=0)

    feet = resting([leg[2] for leg in limbs.legs.values()])
    hands = resting([arm[2] for arm in limbs.arms.values()])
    if not feet.any() or (hands & feet).sum() < FOUR_LIMB_SHARE * feet.sum():
        return ""
    return (f"it bears weight on four limbs: its hands rest on the floor in {(hands & feet).sum() / feet.sum():.0%} "
            "of the frames its feet do")


def _leg_length(motion, positions, limbs):
    """Hip to ankle along the bones (the thigh's twist joints included, whatever their names)."""
    sk = motion.skeleton
    lengths = []
    feet = [leg[2] for leg in limbs.legs.values()]
    for _, shank, foot, _ in limbs.legs.values():
        top = bone_joints(sk, positions, shank, stop=[f for f in feet if f != foot])[-1]
        j, total = foot, 0.0
        while j != top and j > 0:
            total += float(np.median(np.linalg.norm(motion.translations[:, j], axis=1)))
            j = int(sk.parents[j])
        lengths.append(total)
    return float(np.mean(lengths)) if lengths else float("nan")


def detect_units(motion, positions, limbs, up: str):
    """(unit, metres per unit, confidence, height in units, leg length in units)."""
    u = up_vector(up)
    height = positions @ u
    feet = [leg[2] for leg in limbs.legs.values()]
    top = limbs.head if limbs.head is not None else floating_base(motion.skeleton)
    stand = float(np.percentile(height[:, top] - height[:, feet].min(axis=1), 95))
    leg = _leg_length(motion, positions, limbs)
    cues = []
    if np.isfinite(leg) and leg > 0:
        cues.append(TYPICAL_LEG_M / leg)
    if limbs.head is not None and stand > 0 and not (cues and stand < STANDING_RATIO * leg):
        cues.append(TYPICAL_HEAD_M / stand)  # only from a clip that stands up at some time (not kneeling, lying)
    if not cues:
        return "unknown", 1.0, "unknown", stand, leg
    estimate = float(np.exp(np.mean(np.log(cues))))
    name = min(UNITS, key=lambda k: abs(np.log(UNITS[k] / estimate)))
    factor = float(np.exp(abs(np.log(UNITS[name] / estimate))))
    if factor <= SURE_FACTOR:
        return name, UNITS[name], "sure", stand, leg
    if factor <= SNAP_FACTOR:
        return name, UNITS[name], "likely", stand, leg
    return f"{estimate:.4g} m", estimate, "unusual scale", stand, leg


def detect_frame(motion, up: str | None = None, units=None, declared_units: float | None = None) -> FrameGuess:
    """Up axis and units of ``motion`` (see the module docstring). ``up`` / ``units`` override the
    detection; ``declared_units`` (metres per unit, e.g. an ASF file's) is used unless overridden."""
    sub = motion.frames(_sample_frames(motion.n_frames))
    positions, _ = forward_kinematics(sub)
    sk = motion.skeleton
    limbs, why = None, ""
    up_conf = 1.0
    given_up = up is not None
    if up is None:
        from .rig import limbs_by_name

        try:
            named = limbs_by_name(sk)
        except NotBiped:
            named = None
        prior = lift = None
        prior_conf = 0.0
        if named is not None:
            top, feet = (named.head if named.head is not None else floating_base(sk)), [l[2] for l in named.legs.values()]
        else:
            top, feet = floating_base(sk), nearest_pair_tips(sk)
        if feet is not None:
            prior, prior_conf = detect_up(positions, top, feet)
            lift = np.median(positions[:, top] - positions[:, list(feet)].mean(axis=1), axis=0)
        body = descendants(sk.parents, floating_base(sk))  # a dummy root and its props are no part of the body
        where = {j: k for k, j in enumerate(body)}
        body_parents = np.array([where.get(int(sk.parents[j]), -1) for j in body])
        up, up_conf = up_from_contacts(positions[:, body], body_parents, motion.fps / _sample_step(motion.n_frames),
                                       prior, lift, prior_conf, [where[f] for f in (feet or ()) if f in where])
    else:
        up = parse_up(up)
    try:
        limbs = find_limbs(sk, positions, up_vector(up))
        why = four_limbed(positions, sk.parents, motion.fps / _sample_step(motion.n_frames), up, limbs)
        if why:
            raise NotBiped(why)
    except NotBiped as e:
        limbs, why = None, str(e)
    if units is not None:
        unit, mpu = parse_units(units)
        conf = "given"
        stand = leg = float("nan")
        if limbs is not None:
            _, _, _, stand, leg = detect_units(sub, positions, limbs, up)
    elif declared_units is not None:
        unit, mpu, conf = ("m" if declared_units == 1.0 else f"{declared_units:g} m"), declared_units, "declared"
        stand = leg = float("nan")
        if limbs is not None:
            _, _, _, stand, leg = detect_units(sub, positions, limbs, up)
    elif limbs is not None:
        unit, mpu, conf, stand, leg = detect_units(sub, positions, limbs, up)
    else:
        unit, mpu, conf, stand, leg = "unknown", 1.0, "unknown", float("nan"), float("nan")
    return FrameGuess(up=up, up_confidence=float(up_conf), meters_per_unit=float(mpu), unit=unit, unit_confidence=conf,
                      height_m=stand * mpu, leg_m=leg * mpu, limbs=limbs, biped=why, up_given=given_up)
