"""Metamorphic variants of a motion: the same performance as another exporter or rig would write it.

Each function returns a new motion that shows exactly the same movement, so every timing method must
give it the same timing curve (the tests check this on real files):

* :func:`turn_up` - the world turned so that the body's up is another axis (Z-up, -Y-up, X-up);
* :func:`rescale` - lengths in another unit (mm, inches, m, ...);
* :func:`rename` - joint names in another convention (Mixamo, Unreal, Rigify, 3ds Max Biped, Kinect,
  Second Life, Xsens, CMU);
* :func:`add_dummy_root` - a reference joint above the hips, holding all, none or part of the travel;
* :func:`six_channels` - position channels on every joint, holding the bone offset.

A variant stands for a file: write it out and read it back (or pass it to
:func:`retime.motion.files.with_detected_frame`) before retiming it, so that its up axis, units and limbs
are detected as a reader would.
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from .model import POSITION_CHANNELS, Motion
from .quat import qmul, qrot
from .rig import _SIDE_WORDS, name_words, part_of, side_and_part

_TURNS = {"+y": np.eye(3), "+z": Rotation.from_euler("x", 90, degrees=True).as_matrix().round(),
          "-z": Rotation.from_euler("x", -90, degrees=True).as_matrix().round(),
          "-y": np.diag([1.0, -1.0, -1.0]),
          "+x": Rotation.from_euler("z", -90, degrees=True).as_matrix().round(),
          "-x": Rotation.from_euler("z", 90, degrees=True).as_matrix().round()}


def turn_up(motion: Motion, up: str = "+z") -> Motion:
    """The motion of a y-up file with the world turned so that y goes to ``up`` (the rest pose
    stays in the skeleton's own frame, as exporters write it)."""
    R = _TURNS[up]
    q = Rotation.from_matrix(R).as_quat()
    rot = motion.rotations.copy()
    tr = motion.translations.copy()
    rot[:, 0] = qmul(np.broadcast_to(q, rot[:, 0].shape), rot[:, 0])
    tr[:, 0] = tr[:, 0] @ R.T
    return motion.replace(rotations=rot, translations=tr)


def turned_up(up: str, turn: str) -> str:
    """The up axis of a file whose up is ``up`` after :func:`turn_up` with ``turn`` (which turns +y
    to ``turn``): the signed axis the turn takes ``up`` to."""
    from .frame import up_vector

    v = _TURNS[turn] @ up_vector(up)
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "xyz"[k]


def rescale(motion: Motion, factor: float) -> Motion:
    """Every length times ``factor`` (a cm file as mm: 10)."""
    sk = motion.skeleton
    new = dataclasses.replace(sk, offsets=sk.offsets * factor, end_sites=[(j, np.asarray(o) * factor)
                                                                          for j, o in sk.end_sites],
                              meters_per_unit=sk.meters_per_unit / factor)
    return Motion(new, motion.rotations.copy(), motion.translations * factor, motion.fps)


_CONVENTIONS = {
    "mixamo": {"side": {"left": "Left", "right": "Right"}, "fmt": "mixamorig:{side}{part}",
               "parts": {"thigh": "UpLeg", "shank": "Leg", "foot": "Foot", "toe": "ToeBase", "upperarm": "Arm",
                         "forearm": "ForeArm", "hand": "Hand", "clavicle": "Shoulder", "head": "Head", "neck": "Neck"},
               "other": "mixamorig:{name}"},
    "unreal": {"side": {"left": "l", "right": "r"}, "fmt": "{part}_{side}",
               "parts": {"thigh": "thigh", "shank": "calf", "foot": "foot", "toe": "ball", "upperarm": "upperarm",
                         "forearm": "lowerarm", "hand": "hand", "clavicle": "clavicle", "head": "head", "neck": "neck_01"},
               "other": "{name}"},
    "rigify": {"side": {"left": "L", "right": "R"}, "fmt": "DEF-{part}.{side}",
               "parts": {"thigh": "thigh", "shank": "shin", "foot": "foot", "toe": "toe", "upperarm": "upper_arm",
                         "forearm": "forearm", "hand": "hand", "clavicle": "shoulder", "head": "head", "neck": "neck"},
               "other": "DEF-{name}"},
    "kinect": {"side": {"left": "Left", "right": "Right"}, "fmt": "{part}{side}",
               "parts": {"thigh": "Hip", "shank": "Knee", "foot": "Ankle", "toe": "Foot", "upperarm": "Shoulder",
                         "forearm": "Elbow", "hand": "Wrist", "clavicle": "Collar", "head": "Head", "neck": "Neck"},
               "other": "{name}"},
    "xsens": {"side": {"left": "Left", "right": "Right"}, "fmt": "{side}{part}",
              "parts": {"thigh": "UpperLeg", "shank": "LowerLeg", "foot": "Foot", "toe": "Toe", "upperarm": "UpperArm",
                        "forearm": "ForeArm", "hand": "Hand", "clavicle": "Shoulder", "head": "Head", "neck": "Neck"},
              "other": "{name}"},
    "biped": {"side": {"left": "L", "right": "R"}, "fmt": "Bip01 {side} {part}",
              "parts": {"thigh": "Thigh", "shank": "Calf", "foot": "Foot", "toe": "Toe0", "upperarm": "UpperArm",
                        "forearm": "Forearm", "hand": "Hand", "clavicle": "Clavicle", "head": "Head", "neck": "Neck"},
              "other": "Bip01 {name}"},
    "cmu": {"side": {"left": "l", "right": "r"}, "fmt": "{side}{part}",
            "parts": {"thigh": "femur", "shank": "tibia", "foot": "foot", "toe": "toes", "upperarm": "humerus",
                      "forearm": "radius", "hand": "wrist", "clavicle": "clavicle", "head": "head", "neck": "lowerneck"},
            "other": "{name}"},
}


# Second Life names are Kinect's with an "m" before them (mHipLeft, mKneeLeft, ...)
_CONVENTIONS["secondlife"] = dict(_CONVENTIONS["kinect"], fmt="m{part}{side}", other="m{name}")


def rename(motion: Motion, convention: str = "mixamo") -> Motion:
    """Joint names in another rig's convention: limbs by their role (found afresh on this motion),
    other joints prefixed as that convention prefixes them."""
    from .frame import detect_frame

    conv = _CONVENTIONS[convention]
    sk = motion.skeleton
    roles = {}
    limbs = detect_frame(motion).limbs  # found afresh: a frame recorded before another variant is stale
    if limbs is not None:
        for side, (thigh, shank, foot, toe) in limbs.legs.items():
            roles.update({thigh: (side, "thigh"), shank: (side, "shank"), foot: (side, "foot")})
            if toe != foot:
                roles[toe] = (side, "toe")
        for side, (upper, fore, hand) in limbs.arms.items():
            roles.update({upper: (side, "upperarm"), fore: (side, "forearm"), hand: (side, "hand")})
        if limbs.head is not None:
            roles[limbs.head] = (None, "head")
    for j, name in enumerate(sk.names):  # the other joints named like a part (necks, clavicles)
        part = part_of(name)
        if j not in roles and part in conv["parts"] and part not in ("foot", "toe", "hand"):
            roles[j] = (side_and_part(name)[0], part)
    names, seen = [], {}
    for j, name in enumerate(sk.names):
        if j in roles:
            side, part = roles[j]
            new = (conv["fmt"].format(side=conv["side"][side], part=conv["parts"][part]) if side else
                   conv["other"].format(name=conv["parts"][part]))
            seen[new] = seen.get(new, 0) + 1
            if seen[new] > 1:
                new += str(seen[new] - 1)
        else:
            # keep the joint's words, but never a limb's: a renamed "LeftFoot" must not be a second foot
            word = "".join(w.capitalize() for w in _neutral_words(name)) or f"Joint{j}"
            new = conv["other"].format(name=f"{word}{j}")
        names.append(new)
    new_sk = dataclasses.replace(sk, names=names)
    return Motion(new_sk, motion.rotations, motion.translations, motion.fps)


def _neutral_words(name):
    """The words of a joint name that is no limb, without its side and numbers (kept apart, so a
    helper stays a helper: L_Talus_RIGMESH -> TalusRigmesh)."""
    if part_of(name) is not None:
        return ["bone"]
    side = side_and_part(name)[0]
    words = [w for w in name_words(name) if not w.isdigit()]
    if side is not None and words and _SIDE_WORDS.get(words[0]) == side:
        words = words[1:]
    return words


def add_dummy_root(motion: Motion, name: str = "Reference", share: float = 1.0, props: int = 0) -> Motion:
    """A root above the current one. It holds ``share`` of the horizontal travel (1: all of it,
    0: none) and a constant quarter turn about the vertical; the old root keeps the rest, so the
    world motion is unchanged. ``props``: that many IK-target joints beside the body under it."""
    sk = motion.skeleton
    up = np.zeros(3)
    up[1] = 1.0
    turn = Rotation.from_rotvec(0.5 * np.pi * up).as_quat()
    root_tr = motion.translations[:, 0]
    moved = share * (root_tr - (root_tr @ up)[:, None] * up)
    F = motion.n_frames
    dummy_rot = np.broadcast_to(turn, (F, 4))
    inv = Rotation.from_quat(turn).inv().as_quat()
    child_rot = qmul(np.broadcast_to(inv, (F, 4)), motion.rotations[:, 0])
    child_tr = qrot(np.broadcast_to(inv, (F, 4)), root_tr - moved)
    rot = np.concatenate([dummy_rot[:, None], child_rot[:, None], motion.rotations[:, 1:]], axis=1)
    tr = np.concatenate([moved[:, None], child_tr[:, None], motion.translations[:, 1:]], axis=1)
    parents = np.concatenate([[-1], sk.parents + 1])
    parents[1] = 0
    six = list(POSITION_CHANNELS) + ["Zrotation", "Xrotation", "Yrotation"]
    new = dataclasses.replace(
        sk, names=[name] + list(sk.names), parents=parents, offsets=np.vstack([np.zeros(3), sk.offsets]),
        channels=[six] + [six] + [list(c) for c in sk.channels[1:]], end_sites=[(j + 1, o) for j, o in sk.end_sites],
        dof=None, limits=None)
    out = Motion(new, rot, tr, motion.fps)
    for k in range(props):
        out = _add_prop(out, f"IK_Target{k}")
    return out


def _add_prop(motion: Motion, name: str) -> Motion:
    """A 6-channel leaf under the root, wandering about (an IK target exported with the rig)."""
    sk = motion.skeleton
    F = motion.n_frames
    scale = float(np.abs(sk.offsets).max()) or 1.0
    t = np.arange(F) / motion.fps
    path = np.stack([np.sin(t), 0.5 + 0.1 * np.cos(2 * t), np.cos(0.7 * t)], axis=1) * scale
    six = list(POSITION_CHANNELS) + ["Zrotation", "Xrotation", "Yrotation"]
    rot = np.concatenate([motion.rotations, np.broadcast_to([0.0, 0.0, 0.0, 1.0], (F, 1, 4))], axis=1)
    tr = np.concatenate([motion.translations, path[:, None]], axis=1)
    new = dataclasses.replace(sk, names=list(sk.names) + [name], parents=np.append(sk.parents, 0),
                              offsets=np.vstack([sk.offsets, path[0]]), channels=[list(c) for c in sk.channels] + [six],
                              dof=None, limits=None)
    return Motion(new, rot, tr, motion.fps)


def six_channels(motion: Motion, noise: float = 0.0, seed: int = 0) -> Motion:
    """Position channels on every joint, holding its offset (plus ``noise`` file units of jitter)."""
    sk = motion.skeleton
    rng = np.random.default_rng(seed)
    channels = [list(POSITION_CHANNELS) + [c for c in chans if c.endswith("rotation")] for chans in sk.channels]
    tr = motion.translations.copy()
    if noise:
        tr[:, 1:] += rng.normal(scale=noise, size=tr[:, 1:].shape)
    new = dataclasses.replace(sk, channels=channels, dof=None)
    return Motion(new, motion.rotations.copy(), tr, motion.fps)
