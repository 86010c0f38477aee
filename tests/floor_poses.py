"""Clips whose head is not above their feet: a kneeling bow and a standing elephant (3ds Max Biped
names on four legs), built joint by joint in metres, y up, facing +x (rotations about z bend in the
sagittal plane). The issue's real files (a kneeling clip in inches, an elephant in metres) are not
in ../shared; these have the same geometry: the head ahead of the feet by more than it is above."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from retime.motion import Motion, Skeleton
from synthetic_figure import NAMES, OFFSETS, PARENTS

SIX = ["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]
THREE = ["Zrotation", "Xrotation", "Yrotation"]


def _quat_z(deg):
    return Rotation.from_euler("z", np.asarray(deg, dtype=float)[:, None], degrees=True).as_quat()


def _motion(names, parents, offsets, angles_deg, root, fps):
    F = len(root)
    rot = np.zeros((F, len(names), 4))
    rot[..., 3] = 1.0
    for j, a in angles_deg.items():
        rot[:, j] = _quat_z(np.broadcast_to(a, (F,)))
    tr = np.broadcast_to(np.asarray(offsets, dtype=float), (F, len(names), 3)).copy()
    tr[:, 0] = root
    sk = Skeleton(list(names), np.asarray(parents), np.asarray(offsets, dtype=float),
                  [SIX] + [THREE] * (len(names) - 1), meters_per_unit=1.0)
    return Motion(sk, rot, tr, fps)


# the figure's joints by where they sit (its CMU names are one joint off: its 'lfemur' is at the knee)
_AT = {"root": "Hips", "lowerback": "Spine", "upperback": "Spine1", "thorax": "Spine2", "lowerneck": "Neck",
       "upperneck": "Neck1", "head": "Head"}
for _s, _side in (("l", "Left"), ("r", "Right")):
    _AT.update({f"{_s}hipjoint": f"{_side}UpLeg", f"{_s}femur": f"{_side}Leg", f"{_s}tibia": f"{_side}Foot",
                f"{_s}foot": f"{_side}ToeBase", f"{_s}toes": f"{_side}Toe_End", f"{_s}clavicle": f"{_side}Arm",
                f"{_s}humerus": f"{_side}ForeArm", f"{_s}radius": f"{_side}Hand", f"{_s}wrist": f"{_side}HandIndex1",
                f"{_s}hand": f"{_side}HandIndex2", f"{_s}fingers": f"{_side}HandIndex3",
                f"{_s}thumb": f"{_side}HandThumb1"})


def kneeling_bow(seconds=6.0, fps=60.0, least=0.0) -> Motion:
    """The 31-joint CMU-layout figure kneeling (knees, shins and insteps on the floor) and bowing
    deeply twice, sitting back towards its heels as it bows (so its weight stays over the knees);
    deep in the bow for most of the clip, and never less than ``least`` (1: deepest throughout)."""
    t = np.arange(int(seconds * fps)) / fps
    bow = np.clip(3.0 * np.sin(np.pi * t / (seconds / 2)) ** 2, 0, 1)  # 0 upright .. 1 deepest, twice
    bow = least + (1.0 - least) * bow
    idx = {n: k for k, n in enumerate(NAMES)}
    sit_back = 0.3 * bow  # hips move back over the heels
    thigh = 0.42 + 0.05
    tilt = np.degrees(np.arcsin(sit_back / thigh))
    angles = {}
    for s in "lr":
        angles[idx[f"{s}hipjoint"]] = tilt  # thighs lean back, knees stay put
        angles[idx[f"{s}femur"]] = -90 - tilt  # shanks flat on the floor, pointing back
        angles[idx[f"{s}tibia"]] = -90  # insteps flat, toes back
        angles[idx[f"{s}humerus"]] = -60 * bow  # arms forward as it bows
    angles[idx["lowerback"]] = -60 * bow
    angles[idx["upperback"]] = -30 * bow
    angles[idx["thorax"]] = -15 * bow
    root = np.zeros((len(t), 3))
    knee_height = 0.05
    root[:, 0] = -sit_back
    root[:, 1] = knee_height + thigh * np.cos(np.radians(tilt))
    return _motion([_AT[n] for n in NAMES], PARENTS, OFFSETS, angles, root, fps)


def elephant(seconds=4.0, fps=30.0) -> Motion:
    """An elephant standing on four legs (3ds Max Biped names: the front legs are the arms), nodding
    its head and swinging its tail; its head is 3.2 m ahead of the hind feet and 2.2 m above them."""
    joints = [("Bip01 Pelvis", -1, (0, 0, 0)), ("Bip01 Spine", 0, (0.5, 0.1, 0)), ("Bip01 Spine1", 1, (0.8, 0, 0)),
              ("Bip01 Spine2", 2, (0.8, 0, 0)), ("Bip01 Neck", 3, (0.5, 0.1, 0)), ("Bip01 Head", 4, (0.6, 0, 0)),
              ("Bip01 Tail", 0, (-0.5, -0.2, 0)), ("Bip01 Tail1", 6, (-0.1, -0.6, 0))]
    for s, z in (("L", 0.35), ("R", -0.35)):
        k = len(joints)
        joints += [(f"Bip01 {s} Thigh", 0, (0, -0.1, z)), (f"Bip01 {s} Calf", k, (0, -0.9, 0)),
                   (f"Bip01 {s} Foot", k + 1, (0, -0.9, 0)), (f"Bip01 {s} Toe0", k + 2, (0.15, -0.08, 0))]
        k = len(joints)
        joints += [(f"Bip01 {s} Clavicle", 3, (0, -0.1, z)), (f"Bip01 {s} UpperArm", k, (0, -0.2, 0)),
                   (f"Bip01 {s} Forearm", k + 1, (0, -0.85, 0)), (f"Bip01 {s} Hand", k + 2, (0, -0.85, 0)),
                   (f"Bip01 {s} Finger0", k + 3, (0.15, -0.08, 0))]
    names = [j[0] for j in joints]
    t = np.arange(int(seconds * fps)) / fps
    angles = {names.index("Bip01 Neck"): -15 * np.sin(2 * np.pi * 0.5 * t),
              names.index("Bip01 Tail"): 20 * np.sin(2 * np.pi * 0.8 * t)}
    root = np.zeros((len(t), 3))
    root[:, 1] = 2.0
    return _motion(names, [j[1] for j in joints], [j[2] for j in joints], angles, root, fps)


def lying(seconds=4.0, fps=30.0) -> Motion:
    """The figure lying on its back along x (head at -x), raising and lowering its arms and one
    knee: its head is level with its feet, so only the floor under its back says where up is."""
    t = np.arange(int(seconds * fps)) / fps
    idx = {n: k for k, n in enumerate(NAMES)}
    wave = np.sin(2 * np.pi * 0.5 * t) ** 2
    angles = {idx["root"]: 90.0 + 0 * t,  # the body's up (+y) turned to -x: lying on its back
              idx["lclavicle"]: 150 * wave, idx["rclavicle"]: 150 * wave,  # arms raised over the chest and down
              idx["lhipjoint"]: 60 * wave, idx["lfemur"]: -100 * wave}  # one knee drawn up
    root = np.zeros((len(t), 3))
    root[:, 1] = 0.1
    return _motion([_AT[n] for n in NAMES], PARENTS, OFFSETS, angles, root, fps)
