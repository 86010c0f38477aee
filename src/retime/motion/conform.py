"""A motion as the methods see it: y up, one floating base, rigid bones (:func:`conform`).

The timing curve a method computes on the conformed motion applies unchanged to the original
(conforming keeps the frames and their times), so written poses are never touched.

* **Floating base.** A root with a single child joint (a dummy or reference root, animated or not)
  hands the floating base to that child: the child's world transform (root transform composed with
  its own) becomes the new root's, so translation on the dummy, on the child or split between
  them all give the same motion. Repeated down a chain of such roots.
* **Rigid bones.** A non-root joint's translation (6-channel joints) is replaced by its mean. A
  constant one (the OFFSET up to noise) is a fixed bone; one that really changes slides (its
  direction changes: Perception Neuron) or stretches (its length changes: a retargeter's per-frame
  offsets). The largest change is reported, its length change and direction change apart
  (:class:`Stretch`). The motion is refused (:class:`BoneStretch`) only when making the bones
  rigid moves a foot or toe joint by more than :data:`MAX_CONTACT_SHIFT_M` in a frame where it is on
  the floor (within :data:`CONTACT_HEIGHT_M` of its lowest and slower than
  :data:`CONTACT_SPEED_M_S`): there the contacts, and so the physics, would change.
* **Up.** The world turns so that the skeleton's detected (or given) up axis is +y; lengths keep
  the file's unit (``meters_per_unit``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import RetimeError
from .fk import forward_kinematics
from .frame import up_rotation, up_vector
from .model import Motion, Skeleton
from .quat import qmul, qrot
from .rig import floating_base, props_below

MAX_STRETCH = 0.15  # of the bone's mean length: ranks the changes (a short bone by MAX_STRETCH_M)
MIN_BONE_M = 0.02
MAX_STRETCH_M = 0.03
NOISE_STRETCH = 0.005  # below this share of the bone (or 1 mm) a changing translation is capture noise
MAX_CONTACT_SHIFT_M = 0.05  # rigid bones may move a foot on the floor this much ("a few centimetres")
CONTACT_HEIGHT_M = 0.05  # a foot or toe joint this close to its lowest ...
CONTACT_SPEED_M_S = 0.5  # ... and this slow is on the floor
WARN_STRETCH_M = 0.01  # a bone whose offset moves this much, made rigid, is a warning (less: a note)


@dataclass
class Stretch:
    """The largest change of a bone's offset: how far the offset vector moves from its mean
    (``metres``, at ``frame``), split into its length change and its direction change."""

    joint: str
    frame: int
    metres: float
    bone_m: float  # the mean offset's length
    shortest_m: float = float("nan")
    longest_m: float = float("nan")
    turn_deg: float = 0.0  # the offset's largest angle from its mean direction

    @property
    def share(self) -> float:
        return self.metres / self.bone_m if self.bone_m > 0 else float("inf")

    @property
    def length_change_m(self) -> float:
        return max(self.longest_m - self.bone_m, self.bone_m - self.shortest_m)

    @property
    def slides(self) -> bool:
        """Mostly a direction change: the joint slides over its parent's bone, it hardly stretches."""
        return self.length_change_m < 0.5 * self.metres

    def describe(self) -> str:
        return (f"joint {self.joint!r} {'slides' if self.slides else 'stretches'}: its offset moves by up to "
                f"{self.metres * 100:.1f} cm at frame {self.frame} ({self.share:.0%} of its {self.bone_m * 100:.1f} cm "
                f"bone); its length changes {self.shortest_m * 100:.1f} to {self.longest_m * 100:.1f} cm, "
                f"its direction by up to {self.turn_deg:.0f} degrees")


@dataclass
class ContactShift:
    """How far making the bones rigid moves a foot or toe joint in a frame where it is on the floor."""

    joint: str
    frame: int
    metres: float


class BoneStretch(Exception):
    def __init__(self, stretch: Stretch, shift: ContactShift):
        self.stretch = stretch
        self.shift = shift
        super().__init__(
            f"making the bones rigid moves {shift.joint!r} by {shift.metres * 100:.1f} cm at frame {shift.frame}, "
            f"where it is on the floor (physics allows {MAX_CONTACT_SHIFT_M * 100:.0f} cm); the largest change: "
            f"{stretch.describe()}. Physics needs rigid bones. Per-frame bone offsets like these come from "
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
    contact_shift: ContactShift | None = None  # how far the rigid bones move a foot on the floor

    def notes(self) -> list[str]:
        out = []
        if self.removed_roots:
            out.append(f"the floating base is {self.motion.skeleton.names[0]!r} (below the dummy root "
                       f"{', '.join(repr(n) for n in self.removed_roots)})")
        if self.dropped_props:
            out.append(f"left out of the physics: {', '.join(repr(n) for n in self.dropped_props[:6])} (props or "
                       "helpers beside the body under the dummy root)")
        if self.stretch is not None:
            out.append(self._rigid_sentence())
        return out

    def warnings(self) -> list[str]:
        """The notes a user must not miss: bones that slide or stretch by a centimetre or more were made rigid."""
        if self.stretch is None or self.stretch.metres < WARN_STRETCH_M:
            return []
        return [self._rigid_sentence()]

    def _rigid_sentence(self) -> str:
        feet = (f" (this moves the feet by at most {self.contact_shift.metres * 100:.1f} cm where they are on the floor)"
                if self.contact_shift is not None else "")
        return f"bones made rigid at their mean length{feet}; the largest change: {self.stretch.describe()}"


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
        length = np.linalg.norm(t, axis=1) * mpu
        cos = (t @ mean) / np.maximum(np.linalg.norm(t, axis=1) * np.linalg.norm(mean), 1e-12)
        s = Stretch(skeleton.names[j], int(np.argmax(dev)), top, bone, float(length.min()), float(length.max()),
                    float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))).max()))
        if worst is None or _severity(s) > _severity(worst):
            worst = s
    return dataclasses.replace(skeleton, offsets=offsets), tr, fixed, worst


def _severity(s: Stretch) -> float:
    return s.share / MAX_STRETCH if s.bone_m >= MIN_BONE_M else s.metres / MAX_STRETCH_M


def _contact_shift(skeleton, rotations, before, after, feet, fps) -> ContactShift:
    """The largest move of a foot or toe joint (``feet``) between the translations ``before`` and
    ``after``, over the frames where it is on the floor before (see the module docstring)."""
    mpu = skeleton.meters_per_unit
    p0 = forward_kinematics(Motion(skeleton, rotations, before, fps))[0][:, feet] * mpu
    p1 = forward_kinematics(Motion(skeleton, rotations, after, fps))[0][:, feet] * mpu
    height = p0 @ up_vector(skeleton.up)  # (F, K)
    speed = np.linalg.norm(np.gradient(p0, axis=0), axis=2) * fps if len(p0) > 1 else np.zeros(height.shape)
    down = (height - height.min(axis=0) <= CONTACT_HEIGHT_M) & (speed <= CONTACT_SPEED_M_S)
    down[np.argmin(height, axis=0), np.arange(len(feet))] = True  # every foot touches the floor somewhere
    moved = np.where(down, np.linalg.norm(p1 - p0, axis=2), 0.0)
    f, k = np.unravel_index(int(np.argmax(moved)), moved.shape)
    return ContactShift(skeleton.names[feet[k]], int(f), float(moved[f, k]))


def _limbs_after(sk: Skeleton, original: Skeleton):
    """The limbs of ``sk`` (``original`` with dummy roots and props removed): by name, else the
    original's structural limbs, renumbered (the same joints)."""
    from .rig import NotBiped, limbs_by_name

    frame = original.frame
    if frame is not None and frame.limbs is None:
        return None  # not a biped, as the reader found (four limbs on the floor, whatever the names say)
    try:
        limbs = limbs_by_name(sk)
    except NotBiped:
        limbs = None
    if limbs is None and frame is not None and frame.limbs is not None:
        where = {name: k for k, name in enumerate(sk.names)}
        old = original.names

        def moved(v):
            return tuple(where[old[j]] for j in v)

        limbs = dataclasses.replace(
            frame.limbs, legs={s: moved(v) for s, v in frame.limbs.legs.items()},
            arms={s: moved(v) for s, v in frame.limbs.arms.items() if all(old[j] in where for j in v)},
            head=where.get(old[frame.limbs.head]) if frame.limbs.head is not None else None)
    return limbs


def conform(motion: Motion, max_contact_shift: float = MAX_CONTACT_SHIFT_M) -> Conformed:
    """The y-up, single-floating-base, rigid-boned motion of ``motion`` (see the module docstring);
    raises :class:`BoneStretch` when making the bones rigid moves a foot on the floor by more than
    ``max_contact_shift`` metres."""
    sk, rot, tr = motion.skeleton, motion.rotations, motion.translations
    removed, props = [], []
    while _is_dummy_root(sk):
        extra = props_below(sk, 0) or []
        if extra:  # IK targets or markers beside the body: physics has no use for them
            props += [sk.names[j] for j in extra]
            sk, rot, tr = _keep(sk, rot, tr, [j for j in range(sk.n_joints) if j not in set(extra)])
        removed.append(sk.names[0])
        sk, rot, tr = _drop_root(sk, rot, tr)
    limbs = _limbs_after(sk, motion.skeleton)
    before = tr
    sk, tr, fixed, worst = _rigid(sk, tr)
    shift = None
    if worst is not None and limbs is not None:
        feet = sorted({j for pair in limbs.feet.values() for j in pair})
        shift = _contact_shift(sk, rot, before, tr, feet, motion.fps)
        if shift.metres > max_contact_shift:
            raise BoneStretch(worst, shift)
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
        sk.frame = dataclasses.replace(frame, up="+y", limbs=limbs)
    out = Motion(sk, rot, tr, motion.fps)
    return Conformed(out, R, removed_roots=removed, dropped_props=props, fixed_bones=fixed,
                     stretch=worst if worst is not None and worst.share > NOISE_STRETCH else None, contact_shift=shift)


def conformed(motion):
    """The motion as physics sees it (:func:`conform`: y up, one floating base, rigid bones), with a
    bone stretch too large to make rigid as a RetimeError."""
    try:
        return conform(motion)
    except BoneStretch as e:
        where = f"{motion.skeleton.source}: " if motion.skeleton.source else ""
        raise RetimeError(f"{where}{e}") from None


def bind_pose_frames(motion, rest_deg=2.0, max_seconds=0.25) -> int:
    """Leading frames of an exporter's bind pose to leave out of the dynamics (0: none).

    Some BVH exporters (e.g. the Daz-friendly CMU conversions) start with a T-pose frame, every joint
    rotation near identity (half the joints within 2 degrees), then swing into the motion within a
    few frames: 90 degrees of arm in 40 ms, which no body does and which low-passing smears over a
    tenth of a second of dynamics. When frame 0 is such a rest pose and its first step is larger than
    the 99th percentile of the steps after ``max_seconds``, the frames up to the first step no larger
    than that are counted."""
    q = np.asarray(motion.rotations, dtype=float)
    F = len(q)
    if F < 8:
        return 0
    rest = 2.0 * np.degrees(np.arccos(np.clip(np.abs(q[0, 1:, 3]), 0.0, 1.0)))
    if rest.size == 0 or np.median(rest) > rest_deg:  # fingers and toes may rest bent
        return 0
    step = 2.0 * np.degrees(np.arccos(np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=-1)), 0.0, 1.0))).max(axis=1)
    window = int(max_seconds * motion.fps)
    limit = np.percentile(step[min(F - 2, window):], 99)  # the motion's own fastest steps
    if step[0] <= limit:
        return 0
    for f in range(1, min(F - 4, window + 1)):
        if step[f] <= limit:
            return f
    return 0
