"""A motion as the methods see it: y up, one floating base, rigid bones (:func:`conform`).

The timing curve a method computes on the conformed motion applies unchanged to the original
(conforming keeps the frames and their times), so written poses are never touched.

* **Floating base.** A root with a single child joint (a dummy or reference root, animated or not)
  hands the floating base to that child: the child's world transform (root transform composed with
  its own) becomes the new root's, so translation on the dummy, on the child or split between
  them all give the same motion. Repeated down a chain of such roots.
* **Rigid bones.** A non-root joint's translation (6-channel joints) is replaced by its mean. A
  constant one (the OFFSET up to noise) is a fixed bone; one that really changes is a stretching
  bone (Perception Neuron, a retargeter's per-frame offsets): the largest stretch is reported, and
  above :data:`MAX_STRETCH` of the bone the motion is refused (:class:`BoneStretch`).
* **Up.** The world turns so that the skeleton's detected (or given) up axis is +y; lengths keep
  the file's unit (``meters_per_unit``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from .frame import up_rotation
from .model import Motion, Skeleton
from .quat import qmul, qrot
from .rig import floating_base, props_below

MAX_STRETCH = 0.15  # of the bone's mean length
MIN_BONE_M = 0.02  # shorter bones are judged by MAX_STRETCH_M instead
MAX_STRETCH_M = 0.03
NOISE_STRETCH = 0.005  # below this share of the bone (or 1 mm) a changing translation is capture noise


@dataclass
class Stretch:
    joint: str
    frame: int
    metres: float
    bone_m: float

    @property
    def share(self) -> float:
        return self.metres / self.bone_m if self.bone_m > 0 else float("inf")

    def describe(self) -> str:
        return (f"joint {self.joint!r} stretches by up to {self.metres * 100:.1f} cm "
                f"({self.share:.0%} of its {self.bone_m * 100:.1f} cm bone) at frame {self.frame}")


class BoneStretch(Exception):
    def __init__(self, stretch: Stretch):
        self.stretch = stretch
        super().__init__(
            f"{stretch.describe()}; physics needs rigid bones. Per-frame bone offsets like these come from "
            "Perception Neuron exports or retargeters; re-export with fixed bone lengths (or bake the offsets "
            "into the rest pose). Guided and linear retiming do not need rigid bones.")


@dataclass
class Conformed:
    motion: Motion
    rotation: np.ndarray  # (3, 3): file axes -> the conformed (y-up) world
    removed_roots: list[str] = field(default_factory=list)
    dropped_props: list[str] = field(default_factory=list)  # joints beside the body under a dummy root
    fixed_bones: list[str] = field(default_factory=list)  # 6-channel joints whose translation is constant
    stretch: Stretch | None = None  # the largest stretch above capture noise, if any

    def notes(self) -> list[str]:
        out = []
        if self.removed_roots:
            out.append(f"the floating base is {self.motion.skeleton.names[0]!r} (below the dummy root "
                       f"{', '.join(repr(n) for n in self.removed_roots)})")
        if self.dropped_props:
            out.append(f"left out of the physics: {', '.join(repr(n) for n in self.dropped_props[:6])} (props or "
                       "helpers beside the body under the dummy root)")
        if self.stretch is not None:
            out.append(f"bones made rigid at their mean length; the largest stretch: {self.stretch.describe()}")
        return out


def _drop_root(skeleton: Skeleton, rotations, translations):
    """Compose the root into its only child and remove it."""
    rot = rotations.copy()
    tr = translations.copy()
    rot[:, 1] = qmul(rotations[:, 0], rotations[:, 1])
    tr[:, 1] = translations[:, 0] + qrot(rotations[:, 0], translations[:, 1])
    parents = skeleton.parents[1:] - 1
    parents[0] = -1
    sk = dataclasses.replace(
        skeleton, names=skeleton.names[1:], parents=parents, offsets=skeleton.offsets[1:],
        channels=skeleton.channels[1:], end_sites=[(j - 1, o) for j, o in skeleton.end_sites],
        dof=skeleton.dof[1:], limits=skeleton.limits[1:] if skeleton.limits else None)
    return sk, rot[:, 1:], tr[:, 1:]


def _is_dummy_root(skeleton: Skeleton) -> bool:
    return floating_base(skeleton) > 0


def _keep(skeleton: Skeleton, rotations, translations, keep):
    """Only the joints ``keep`` (sorted, closed under parents): props dropped."""
    keep = [int(j) for j in keep]
    new_index = {j: k for k, j in enumerate(keep)}
    parents = np.array([new_index[int(skeleton.parents[j])] if skeleton.parents[j] >= 0 else -1 for j in keep])
    sk = dataclasses.replace(
        skeleton, names=[skeleton.names[j] for j in keep], parents=parents, offsets=skeleton.offsets[keep],
        channels=[skeleton.channels[j] for j in keep],
        end_sites=[(new_index[j], o) for j, o in skeleton.end_sites if j in new_index],
        dof=[skeleton.dof[j] for j in keep], limits=[skeleton.limits[j] for j in keep] if skeleton.limits else None)
    return sk, rotations[:, keep], translations[:, keep]


def _rigid(skeleton: Skeleton, translations):
    """Mean translations of the non-root joints, the fixed bones and the largest stretch."""
    mpu = skeleton.meters_per_unit
    tr = translations.copy()
    offsets = skeleton.offsets.copy()
    fixed, worst = [], None
    for j in range(1, skeleton.n_joints):
        t = translations[:, j]
        mean = t.mean(axis=0)
        dev = np.linalg.norm(t - mean, axis=1)
        has_pos = any(c.endswith("position") for c in skeleton.channels[j])
        tr[:, j] = mean
        offsets[j] = mean
        bone = float(np.linalg.norm(mean)) * mpu
        top = float(dev.max()) * mpu
        if top <= max(NOISE_STRETCH * bone, 1e-3):
            if has_pos:
                fixed.append(skeleton.names[j])
            continue
        s = Stretch(skeleton.names[j], int(np.argmax(dev)), top, bone)
        if worst is None or _severity(s) > _severity(worst):
            worst = s
    return dataclasses.replace(skeleton, offsets=offsets), tr, fixed, worst


def _severity(s: Stretch) -> float:
    return s.share / MAX_STRETCH if s.bone_m >= MIN_BONE_M else s.metres / MAX_STRETCH_M


def conform(motion: Motion, max_stretch: float = MAX_STRETCH) -> Conformed:
    """The y-up, single-floating-base, rigid-boned motion of ``motion`` (see the module docstring);
    raises :class:`BoneStretch` when a bone stretches by more than ``max_stretch``."""
    sk, rot, tr = motion.skeleton, motion.rotations, motion.translations
    removed, props = [], []
    while _is_dummy_root(sk):
        extra = props_below(sk, 0) or []
        if extra:  # IK targets or markers beside the body: physics has no use for them
            props += [sk.names[j] for j in extra]
            sk, rot, tr = _keep(sk, rot, tr, [j for j in range(sk.n_joints) if j not in set(extra)])
        removed.append(sk.names[0])
        sk, rot, tr = _drop_root(sk, rot, tr)
    sk, tr, fixed, worst = _rigid(sk, tr)
    if worst is not None and _severity(worst) * MAX_STRETCH > max_stretch:
        raise BoneStretch(worst)
    R = up_rotation(sk.up)
    if not np.array_equal(R, np.eye(3)):
        q = Rotation.from_matrix(R).as_quat()
        rot = rot.copy()
        tr = tr.copy()
        rot[:, 0] = qmul(np.broadcast_to(q, rot[:, 0].shape), rot[:, 0])
        tr[:, 0] = tr[:, 0] @ R.T
    frame = sk.frame
    sk = dataclasses.replace(sk, up="+y")
    if frame is not None:
        from .rig import NotBiped, limbs_by_name

        try:
            limbs = limbs_by_name(sk)
        except NotBiped:
            limbs = None
        if limbs is None and frame.limbs is not None:  # structural limbs: the same joints, renumbered
            where = {name: k for k, name in enumerate(sk.names)}
            old = motion.skeleton.names

            def moved(v):
                return tuple(where[old[j]] for j in v)

            limbs = dataclasses.replace(
                frame.limbs, legs={s: moved(v) for s, v in frame.limbs.legs.items()},
                arms={s: moved(v) for s, v in frame.limbs.arms.items() if all(old[j] in where for j in v)},
                head=where.get(old[frame.limbs.head]) if frame.limbs.head is not None else None)
        sk.frame = dataclasses.replace(frame, up="+y", limbs=limbs)
    out = Motion(sk, rot, tr, motion.fps)
    return Conformed(out, R, removed_roots=removed, dropped_props=props, fixed_bones=fixed,
                     stretch=worst if worst is not None and worst.share > NOISE_STRETCH else None)
