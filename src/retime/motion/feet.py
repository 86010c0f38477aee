"""The feet of a motion: their soles, and when each heel and toe touches the ground.

One detector serves every method and report (physics' dynamics, guided's pace pull, the demo's
flight), so they all find the same contacts.

**Soles** (:func:`default_foot`): one rectangle per foot, with "up" the world's y axis as the foot
sees it when most planted in the motion (averaged over the 5 % most planted frames; the rest pose
without a motion): the sole plane lies ``SOLE_PAD`` = 2 cm below the lower of the toe joint and the
toe tip; heel corners (on the foot joint's body) are 0.3 foot-lengths behind the ankle, 0.26
foot-lengths apart; toe corners (on the toe joint's body, or the foot's if there is none) are
halfway from the toe joint to the tip, 0.38 foot-lengths apart (foot length = heel to tip).

Contact points, in this order everywhere (``CONTACT_POINTS``)::

    0 left_heel   1 left_toe   2 right_heel   3 right_toe

each a pair of sole corners (heel: ``heel_a, heel_b``; toe: ``toe_a, toe_b``; left foot first).

**Detection** (:func:`contact_states`), per point, from the corners' world positions at the
motion's frames: its height is the lower of its two corners' heights above that point's floor, and
its speed is the speed of the corners' midpoint. Heights are first taken above the local floor
(:func:`local_floor`: the lowest point within +-0.75 s, so a platform or a drifting floor stays a
floor). A point's floor is then the 5th percentile of that height over the clip, but at most 3 cm
above the lowest such floor of all points (a point that never touches the ground is not made to).
A point enters contact when it is below ``h_on`` (3 cm) and slower than ``v_on`` (1 m/s) and leaves
it when it is above ``h_off`` (5 cm) or faster than ``v_off`` (2 m/s) (hysteresis; a swinging foot
that skims the floor is much faster, a foot pushing off or landing is slower). Contacts and gaps
shorter than ``min_frames`` (3) are then removed, in that order.

**A motion's contacts** (:func:`foot_contacts`) are detected on the motion as physics sees it
(:func:`retime.motion.conform.conformed`: y up, one floating base, rigid bones; leading bind-pose
frames held at the first real pose), low-passed by a Gaussian of ``PATH_SMOOTHING_S`` (the path
physics differentiates), with the default soles: only the legs' forward kinematics, none of the
dynamics, so a guided solve pays little for it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d, minimum_filter1d, uniform_filter1d

from ..errors import RetimeError
from .conform import bind_pose_frames, conformed
from .quat import continuous, quat_to_matrix
from .rig import Limbs, NotBiped, limbs_by_name

CONTACT_POINTS = ("left_heel", "left_toe", "right_heel", "right_toe")
SOLE_PAD = 0.02
SIDES = ("left", "right")
# seconds: the Gaussian low-pass of the path before physics differentiates it (physics.api says why);
# contacts are detected on the same path
PATH_SMOOTHING_S = 0.05
MIN_FRAMES = 4  # the path's not-a-knot spline needs four frames; so does detection on it


@dataclass
class Foot:
    """A rectangular sole: two heel corners on ``joint``'s body and two toe corners on
    ``toe_joint``'s body, each in that joint's frame (metres)."""

    side: str
    joint: str
    toe_joint: str
    heel: np.ndarray  # (2, 3)
    toe: np.ndarray  # (2, 3)

    def __post_init__(self):
        self.heel = np.asarray(self.heel, dtype=float).reshape(2, 3)
        self.toe = np.asarray(self.toe, dtype=float).reshape(2, 3)

def bone_ends(skeleton) -> np.ndarray:
    """(J, 3) end of each joint's bone in its frame: the mean of its children's offsets (ignoring
    children at the joint itself) and end sites; zero if there are none."""
    off = skeleton.offsets * skeleton.meters_per_unit
    ends = [[] for _ in range(skeleton.n_joints)]
    for j, p in enumerate(skeleton.parents):
        if p >= 0:
            ends[p].append(off[j])
    for j, o in skeleton.end_sites:
        ends[j].append(np.asarray(o, dtype=float) * skeleton.meters_per_unit)
    out = np.zeros((skeleton.n_joints, 3))
    for j, e in enumerate(ends):
        e = [v for v in e if np.linalg.norm(v) > 1e-6]
        if e:
            out[j] = np.mean(e, axis=0)
    return out

BIPED_SENTENCE = ("physics-based retiming needs a two-legged character (two legs ending in feet on the ground), "
                  "and this skeleton is not one")


class NotTwoLegged(RetimeError):
    """The skeleton has no two legs ending in feet. ``where`` (``"FILE: "`` or empty) and ``why`` are kept
    apart from the message so that a method that works on any skeleton can say it in its own words."""

    def __init__(self, where: str, why: str, message: str):
        self.where, self.why = where, why
        super().__init__(message)


def skeleton_limbs(skeleton) -> Limbs:
    """The skeleton's limbs: those found when it was loaded (:mod:`retime.motion.frame`), else by name."""
    frame = getattr(skeleton, "frame", None)
    why = getattr(frame, "biped", "")
    try:
        limbs = frame.limbs if frame is not None else limbs_by_name(skeleton)
    except NotBiped as e:
        limbs, why = None, str(e)
    if limbs is None:
        why = why or "no joints named like feet"
        where = f"{skeleton.source}: " if skeleton.source else ""
        raise NotTwoLegged(where, why, f"{where}{BIPED_SENTENCE} ({why}; joints: {', '.join(skeleton.names[:12])}"
                           f"{', ...' if skeleton.n_joints > 12 else ''}). If it is one, name its feet in a body file "
                           "([feet.left] joint = ...). Guided and linear retiming work on any skeleton.")
    return limbs


def find_feet(skeleton, feet_names=None) -> dict[str, tuple[int, int]]:
    """{side: (foot joint, toe joint)} of the skeleton's limbs (:func:`skeleton_limbs`); the toe
    joint is the foot itself when there is none. ``feet_names`` {side: (foot, toe)} overrides."""
    if feet_names and all(s in feet_names for s in SIDES):
        limbs_feet = {}
    else:
        limbs_feet = skeleton_limbs(skeleton).feet
    out = {}
    for side in SIDES:
        if feet_names and side in feet_names:
            foot_name, toe_name = feet_names[side]
            foot = skeleton.index(foot_name)
            out[side] = (foot, skeleton.index(toe_name) if toe_name else foot)
        else:
            out[side] = limbs_feet[side]
    return out

def stance_frames(frames, fps, foot: int, toe: int, share=0.05) -> np.ndarray:
    """Indices of the frames where a foot looks most planted: the ``share`` (5 %, at least one) with
    the lowest score = ankle height + toe-joint height above their clip minimums + 0.05 s x their
    speed (averaged over 0.2 s). ``frames`` are world frames (positions (F, J, 3), rotations)."""
    pos = frames[0]
    F = len(pos)
    score = np.zeros(F)
    width = max(1, min(F, int(round(0.2 * fps))))
    kernel = np.ones(width) / width
    for j in {foot, toe}:
        x = pos[:, j]
        speed = np.linalg.norm(np.gradient(x, axis=0), axis=1) * fps if F > 1 else np.zeros(F)
        score += x[:, 1] - x[:, 1].min() + 0.05 * np.convolve(speed, kernel, mode="same")
    k = max(1, int(round(share * F)))
    return np.argsort(score, kind="stable")[:k]


def _mean_rotation(Rs):
    U, _, Vt = np.linalg.svd(np.mean(Rs, axis=0))
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Vt
    return R


SYNTHETIC_FOOT = 0.45  # ankle-to-toe reach of a foot the rig lacks, in shank lengths (about 0.19 m)
SYNTHETIC_ANKLE = 0.17  # ankle joint above the sole, in shank lengths (about 0.07 m)


def _shank_length(skeleton, foot) -> float:
    return float(np.linalg.norm(skeleton.offsets[foot])) * skeleton.meters_per_unit


def _body_forward(skeleton, positions) -> np.ndarray:
    """Where the body faces in the y-up world, from the thighs: up x forward = left."""
    legs = skeleton_limbs(skeleton).legs
    left = np.mean(positions[:, legs["left"][0]] - positions[:, legs["right"][0]], axis=0)
    fwd = np.cross(left, [0.0, 1.0, 0.0])
    n = np.linalg.norm(fwd)
    return fwd / n if n > 0 else np.array([0.0, 0.0, 1.0])


def default_foot(skeleton, side, foot, toe, frames=None, fps=None) -> Foot:
    """Sole corners of one foot (see the module docstring), built in the foot joint's frame. "Up"
    is the world y axis seen from the foot in the rest pose or, given the motion's world frames (see
    :func:`world_frames`) and frame rate, averaged over the frames where the foot is most planted
    (:func:`stance_frames`), so skeletons whose rest pose points the feet down still get a sole
    under the foot; the toe joint's rotation relative to the foot is averaged the same way."""
    ends = bone_ends(skeleton)
    off = skeleton.offsets * skeleton.meters_per_unit
    if frames is None:
        up, R_rel = np.array([0.0, 1.0, 0.0]), np.eye(3)
    else:
        idx = stance_frames(frames, fps, foot, toe)
        R = frames[1]
        up = np.mean(R[idx, foot, 1, :], axis=0)  # world y in the foot frame = row 1 of R
        up /= np.linalg.norm(up)
        R_rel = np.eye(3) if toe == foot else _mean_rotation(np.einsum("nji,njk->nik", R[idx, foot], R[idx, toe]))
    # in the foot frame: ankle A at the origin, toe joint B, toe tip T
    A = np.zeros(3)
    B = off[toe] if toe != foot else ends[foot]
    T = B + R_rel @ ends[toe] if toe != foot else B
    if np.linalg.norm(T - B) < 1e-6:  # no toe bone: extend the foot by 40 %
        T = B + 0.4 * (B - A)
    fwd = T - A - np.dot(T - A, up) * up
    reach = float(np.linalg.norm(fwd))
    if reach < 0.2 * _shank_length(skeleton, foot) and frames is not None:
        # no foot bone along the ground (a rig that ends at the ankle): a foot of typical size,
        # pointing where the body faces, its sole at a typical ankle height below the joint
        fwd_world = _body_forward(skeleton, frames[0][idx])
        fwd = np.mean(np.einsum("nji,j->ni", R[idx, foot], fwd_world), axis=0)
        fwd -= np.dot(fwd, up) * up
        if np.linalg.norm(fwd) > 1e-6:
            shank = _shank_length(skeleton, foot)
            reach = SYNTHETIC_FOOT * shank
            B = T = reach * fwd / np.linalg.norm(fwd) - SYNTHETIC_ANKLE * shank * up
            toe = foot
            R_rel = np.eye(3)
            fwd = T - A - np.dot(T - A, up) * up
    if reach < 1e-3:
        raise RetimeError(f"the {side} foot ({skeleton.names[foot]}) has no length along the ground; "
                          "give its sole corners in a body file")
    fwd /= reach
    lat = np.cross(fwd, up)
    heel_back = 0.3 * reach
    length = reach + heel_back
    sole = min(np.dot(B, up), np.dot(T, up)) - SOLE_PAD  # height of the sole plane along up

    def on_sole(x):
        return x + (sole - np.dot(x, up)) * up

    heel_c = on_sole(A - heel_back * fwd)
    toe_c = on_sole(B + 0.5 * (T - B))
    heel = np.array([heel_c + s * 0.13 * length * lat for s in (1, -1)])
    toes = np.array([toe_c + s * 0.19 * length * lat for s in (1, -1)])
    if toe != foot:
        toes = (toes - B) @ R_rel  # into the toe joint's frame
    return Foot(side=side, joint=skeleton.names[foot], toe_joint=skeleton.names[toe], heel=heel, toe=toes)


def feet_in_order(feet) -> list[Foot]:
    """The left and the right foot of ``feet`` (a body's soles), in that order."""
    by_side = {f.side: f for f in feet}
    missing = [s for s in SIDES if s not in by_side]
    if missing:
        raise RetimeError(f"the body model has no {' and '.join(missing)} foot")
    return [by_side[s] for s in SIDES]


def sole_corners(feet):
    """(8,) joint names and (8, 3) local positions of the sole corners of ``feet``, in point order
    (left heel_a, heel_b, toe_a, toe_b, then the right's)."""
    names, local = [], []
    for foot in feet_in_order(feet):
        names += [foot.joint, foot.joint, foot.toe_joint, foot.toe_joint]
        local += [foot.heel[0], foot.heel[1], foot.toe[0], foot.toe[1]]
    return names, np.array(local)


def sole_positions(feet, skeleton, R, o):
    """World positions (n, 8, 3) of the sole corners of ``feet`` given world joint frames
    R (n, J, 3, 3), o (n, J, 3)."""
    names, local = sole_corners(feet)
    idx = [skeleton.index(n) for n in names]
    return o[:, idx] + np.einsum("npij,pj->npi", R[:, idx], local)


# ---------------------------------------------------------------------------------------------
# detection


def _runs(state, value):
    """(starts, ends) of the runs of ``value`` in a bool array, ends exclusive."""
    s = np.concatenate([[False], state == value, [False]])
    d = np.diff(s.astype(np.int8))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _clean(state, min_frames):
    """Drop runs of contact shorter than min_frames, then fill gaps shorter than min_frames
    (except gaps at either end of the clip)."""
    state = np.array(state, dtype=bool)
    for a, b in zip(*_runs(state, True)):
        if b - a < min_frames:
            state[a:b] = False
    for a, b in zip(*_runs(state, False)):
        if b - a < min_frames and a > 0 and b < len(state):
            state[a:b] = True
    return state


def point_tracks(corners, fps):
    """Height above its own floor (F, 4) and speed (F, 4) of each contact point, in metres and m/s,
    from the sole corners' world positions ``corners`` (F, 8, 3) (y up, metres) at ``fps``."""
    low = np.minimum(corners[:, 0::2, 1], corners[:, 1::2, 1])  # (F, 4)
    mid = 0.5 * (corners[:, 0::2] + corners[:, 1::2])
    speed = np.linalg.norm(np.gradient(mid, axis=0), axis=-1) * fps
    return above_own_floor(low, fps), speed


def above_own_floor(low, fps):
    """(F, P) height of each point above its own floor, from its height ``low`` (F, P): above the
    local floor (:func:`local_floor`), less where the point stands (its 5th percentile, at most 3 cm
    above the lowest point's: a point that never touches the ground is not made to)."""
    low = low - local_floor(low, fps)[:, None]
    floors = np.percentile(low, 5, axis=0)
    floors = np.minimum(floors, floors.min() + 0.03)
    return low - floors


LOCAL_FLOOR_S = 0.75  # half width of the window the floor is the lowest point of


def local_floor(low, fps, half_width=LOCAL_FLOOR_S):
    """(F,) floor height under the body: the lower envelope of the lowest contact point over windows
    of +-``half_width`` seconds, so a platform, a slope or a drifting capture floor is still the
    floor (a jump's flight is far shorter than the window, so its floor is the stance around it)."""
    lowest = np.min(low, axis=1)
    size = 2 * max(1, int(round(half_width * fps))) + 1
    # a morphological opening: the lower envelope, which follows a slope exactly and drops
    # the raised stretches (flights, steps) shorter than the window
    floor = maximum_filter1d(minimum_filter1d(lowest, size=size, mode="nearest"), size=size, mode="nearest")
    return uniform_filter1d(floor, size=max(1, size // 4), mode="nearest")


def contact_states(corners, fps, h_on=0.03, h_off=0.05, v_on=1.0, v_off=2.0, min_frames=3) -> np.ndarray:
    """Contact states (F, 4) of the heel and toe of each foot from the sole corners' world positions
    ``corners`` (F, 8, 3) at the motion's frames (see the module docstring)."""
    height, speed = point_tracks(corners, fps)
    out = hysteresis((height < h_on) & (speed < v_on), (height > h_off) | (speed > v_off))
    for p in range(out.shape[1]):
        out[:, p] = _clean(out[:, p], min_frames)
    return out


def hysteresis(enter, leave) -> np.ndarray:
    """States (F, P) that turn on where ``enter`` (F, P) and off where ``leave`` and hold otherwise,
    starting off; ``enter`` and ``leave`` never both hold (the thresholds do not overlap), so a state
    is on exactly when its latest event is an entry."""
    F = len(enter)
    frame = np.arange(F)[:, None]
    last_enter = np.maximum.accumulate(np.where(enter, frame, -1), axis=0)
    last_leave = np.maximum.accumulate(np.where(leave & ~enter, frame, -1), axis=0)
    return last_enter > last_leave


# ---------------------------------------------------------------------------------------------
# a motion's contacts, from its legs alone


def lowpass(x, sigma_frames):
    """Gaussian filter along axis 0 with odd reflection about the end samples (a constant velocity
    passes unchanged)."""
    if sigma_frames <= 0:
        return x
    pad = min(int(np.ceil(4 * sigma_frames)) + 1, len(x) - 1)
    head = 2 * x[:1] - x[pad:0:-1]
    tail = 2 * x[-1:] - x[-2:-pad - 2:-1]
    padded = np.concatenate([head, x, tail])
    return gaussian_filter1d(padded, sigma_frames, axis=0, mode="nearest", truncate=4.0)[pad:pad + len(x)]


def _with_ancestors(parents, joints) -> list[int]:
    keep = set()
    for j in joints:
        j = int(j)
        while j >= 0 and j not in keep:
            keep.add(j)
            j = int(parents[j])
    return sorted(keep)


def leg_frames(motion, joints, smoothing=PATH_SMOOTHING_S):
    """World positions (F, J, 3) in metres and rotation matrices (F, J, 3, 3) of ``joints`` (and
    their ancestors; NaN elsewhere) along the motion's path low-passed at ``smoothing`` seconds, as
    physics samples it at the frames: root position and sign-continuous quaternions filtered, the
    quaternions normalized, leading bind-pose frames held (:func:`~.conform.bind_pose_frames`)."""
    sk = motion.skeleton
    F, J = motion.n_frames, sk.n_joints
    chain = _with_ancestors(sk.parents, joints)
    root = motion.root_positions * sk.meters_per_unit
    quats = np.asarray(motion.rotations, dtype=float)[:, chain]
    held = bind_pose_frames(motion)
    if held:
        root, quats = root.copy(), quats.copy()
        root[:held], quats[:held] = root[held], quats[held]
    X = lowpass(np.concatenate([root, continuous(quats).reshape(F, -1)], axis=1), smoothing * motion.fps)
    q = X[:, 3:].reshape(F, len(chain), 4)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    local = quat_to_matrix(q)  # (F, chain, 3, 3)
    offsets = sk.offsets * sk.meters_per_unit
    pos = np.full((F, J, 3), np.nan)
    R = np.full((F, J, 3, 3), np.nan)
    for k, j in enumerate(chain):  # parents come before their children
        p = sk.parents[j]
        if p < 0:
            pos[:, j], R[:, j] = X[:, :3], local[:, k]
        else:
            pos[:, j] = pos[:, p] + R[:, p] @ offsets[j]
            R[:, j] = R[:, p] @ local[:, k]
    return pos, R


def foot_contacts(motion) -> np.ndarray:
    """Contact states (F, 4) of the motion's frames exactly as physics detects them with its default
    body (see the module docstring): what guided's pace pull and the demo call a flight
    (:func:`retime.phases.longest_flight`). Detected on the raw motion, a Z-up file's flight came
    out seconds away from the one physics reports. Raises RetimeError for a rig without two legs
    (:func:`skeleton_limbs`) or a motion physics would not conform."""
    skeleton_limbs(motion.skeleton)  # no legs is refused before the conform, slow on a long chain
    motion = conformed(motion).motion
    if motion.n_frames < MIN_FRAMES:
        raise RetimeError(f"foot contacts need at least {MIN_FRAMES} frames, the motion has {motion.n_frames}")
    sk = motion.skeleton
    feet = find_feet(sk)
    legs = skeleton_limbs(sk).legs
    thighs = [leg[0] for leg in legs.values() if leg[0] is not None]  # where the body faces (a rig without feet)
    frames = leg_frames(motion, [j for pair in feet.values() for j in pair] + thighs)
    soles = [default_foot(sk, side, foot, toe, frames, motion.fps) for side, (foot, toe) in feet.items()]
    return contact_states(sole_positions(soles, sk, frames[1], frames[0]), motion.fps)
