"""The world frame a motion was captured in: its up axis and its length unit, found from the motion.

* **Up** (:func:`detect_up`): the signed world axis along which the head (or, without one, the
  root) lies above the feet in most frames. Confidence: the share of frames that agree.
* **Units** (:func:`detect_units`): segment lengths and standing height, not the rest pose (rest
  poses with bones along +X are common): the thigh + shank length (bone lengths, whatever the pose)
  and the head's height above the lower foot (95th percentile over the clip) give the body's size
  in file units; compared with a typical adult (leg 0.84 m, head joint 1.45 m above the floor),
  that is a metres-per-unit estimate. It snaps to m, cm, mm, inches, feet or CMU's unit when one is
  within a factor 1.3 (sure within 1.15), else it is kept as is (an unusual scale, reported).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fk import forward_kinematics
from .model import LENGTH_UNITS
from .rig import Limbs, NotBiped, bone_joints, find_limbs, floating_base, nearest_pair_tips

AXES = {"x": 0, "y": 1, "z": 2}
UNITS = {k: v for k, v in LENGTH_UNITS.items() if k != "dm"}  # the units files are written in
UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches", "ft": "feet",
              "cmu": "CMU units (1/0.45 in)"}
TYPICAL_LEG_M = 0.84  # thigh + shank of an adult (hip joint to ankle joint)
TYPICAL_HEAD_M = 1.45  # head joint above the floor, standing
SNAP_FACTOR = 1.3
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


def _sample_frames(n_frames):
    step = max(1, int(np.ceil(n_frames / MAX_FRAMES)))
    return slice(0, n_frames, step)


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
    if limbs.head is not None and stand > 0:
        cues.append(TYPICAL_HEAD_M / stand)
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
        if named is not None:
            top = named.head if named.head is not None else floating_base(sk)
            up, up_conf = detect_up(positions, top, [leg[2] for leg in named.legs.values()])
        else:
            tips = nearest_pair_tips(sk)
            if tips is not None:
                up, up_conf = detect_up(positions, floating_base(sk), tips)
            else:
                up, up_conf = "+y", 0.0
    else:
        up = parse_up(up)
    try:
        limbs = find_limbs(sk, positions, up_vector(up))
    except NotBiped as e:
        why = str(e)
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
