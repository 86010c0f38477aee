"""The character's body: segment masses and inertias, foot soles, friction and torque limits.

Defaults (every value can be overridden by a TOML body file, see :func:`read_body`):

* **Total mass**: 70 kg unless given. (Scaling every mass scales the dynamics and the default
  torque limits, which come from the same dynamics, alike; so the feasible timings barely depend
  on it.)
* **Segment masses**: de Leva (1996, J. Biomech. 29:1223, male table) fractions of the total:
  head+neck 6.94 %, trunk 43.46 % (pelvis 11.17 %, the rest of the trunk 32.29 %), and per side
  upper arm 2.71 %, forearm 1.62 %, hand 0.61 %, thigh 14.16 %, shank 4.33 %, foot 1.37 %.
  Skeleton joints are assigned to these segments from the skeleton's limbs
  (:mod:`retime.motion.rig`: by name on any naming convention, else by structure) and their
  geometry, never their names: foot joint and its descendants = foot, the joints up to the knee (the
  shank joint) = shank, the bone from the hip to the knee (the knee's parent and the joints above it
  in line with it, such as twist or bend joints: :func:`~retime.motion.rig.bone_joints`) = thigh,
  joints between the thigh and the root = pelvis (with the root; CMU's hip joints, which bend away
  from the thigh); hand joint and descendants = hand, up to the elbow = forearm, the bone ending at
  the elbow = upper arm;
  joints named like head/neck (and descendants) = head; the rest = trunk. A segment made of several joints shares its mass in proportion to bone length (side
  branches of the trunk, such as clavicles, count 0.3 of their length). Missing segments give their
  share to the others proportionally.
* **Centres of mass and inertias**: each joint's body is the bone from the joint to the mean of its
  children (or its end site); the centre of mass lies along it at de Leva's fraction (e.g. thigh
  0.41, shank 0.45) and the inertia is that of a rod with de Leva's radii of gyration (transverse,
  longitudinal; e.g. thigh 0.329, 0.149 of the bone length). A bone of zero length gets a sphere of
  radius 0.1 m.
* **Soles**: one rectangle per foot (:func:`retime.motion.feet.default_foot`, shared with the
  contact detection every method uses).
* **Friction** 0.5; **torque limits** estimated from the original motion (see
  :mod:`retime.physics.model.dynamics`): ``torque_margin`` (1.5) times the largest |torque| of each joint
  axis over the clip, plus ``torque_floor`` (2 N m), but never below the joint's **strength**:
  ``strength_scale`` (1) times :data:`STRENGTH` (N m for 70 kg, scaled by the body mass). McCann et
  al. took their limits from the torques of *several* actions; one clip alone understates what its
  performer can do at joints it barely used (a standing jump hardly loads the shoulders, yet played
  twice as fast its arm swing needs four times the torque). ``strength_scale = 0`` gives the clip's
  limits alone.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import FormatError, RetimeError
from ...io_util import atomic_write
from ...motion.feet import SIDES, Foot, bone_ends, default_foot, find_feet, skeleton_limbs
from ...motion.rig import bone_joints, descendants, part_of
from .tree import FIXED, FREE, SPHERICAL, TreeModel

BODY_MASS = 70.0
FRICTION = 0.5
TORQUE_MARGIN = 1.5
TORQUE_FLOOR = 2.0
# Peak joint torque (N m, about any axis) of a 70 kg adult, by the segment a joint moves: rounded
# maximal voluntary torques of healthy adult men, e.g. Anderson, Madigan & Nussbaum 2007 (J. Biomech.
# 40:3105; hip, knee, ankle) and Winter's Biomechanics (trunk, neck, arm). Deliberately modest: the
# weaker direction of each joint.
STRENGTH = {"pelvis": 150.0, "thigh": 150.0, "shank": 150.0, "foot": 100.0, "toe": 30.0, "trunk": 150.0,
            "head": 40.0, "upperarm": 60.0, "forearm": 40.0, "hand": 10.0}
STRENGTH_MASS = 70.0
ZERO_BONE_RADIUS = 0.1

# segment: (mass fraction per side or whole, COM fraction from the proximal joint,
#           radius of gyration transverse, longitudinal) -- de Leva 1996, male
DE_LEVA = {
    "head": (0.0694, 0.50, 0.309, 0.261),
    "pelvis": (0.1117, 0.50, 0.30, 0.30),
    "trunk": (0.3229, 0.50, 0.317, 0.169),
    "upperarm": (0.0271, 0.5772, 0.277, 0.158),
    "forearm": (0.0162, 0.4574, 0.270, 0.121),
    "hand": (0.0061, 0.50, 0.40, 0.30),
    "thigh": (0.1416, 0.4095, 0.329, 0.149),
    "shank": (0.0433, 0.4459, 0.252, 0.103),
    "foot": (0.0137, 0.4415, 0.251, 0.124),
}
SIDED = ("upperarm", "forearm", "hand", "thigh", "shank", "foot")
TOE_RE = re.compile(r"toe|ball|metatars", re.I)


@dataclass
class Body:
    """Inertial model of a skeleton: one rigid body per joint (the bone from the joint onwards)."""

    names: list[str]
    mass: np.ndarray  # (J,) kg
    com: np.ndarray  # (J, 3) joint frame, metres
    inertia: np.ndarray  # (J, 3, 3) about the COM, joint frame, kg m^2
    feet: list[Foot]
    friction: float = FRICTION
    torque_margin: float = TORQUE_MARGIN
    torque_floor: float = TORQUE_FLOOR
    strength_scale: float = 1.0
    torque_limits: dict[str, np.ndarray] = field(default_factory=dict)  # joint -> (3,) N m, symmetric
    segments: dict[str, str] = field(default_factory=dict)  # joint -> de Leva segment (informational)
    toes: set[str] = field(default_factory=set)  # the joints from each toe joint down (toe strength), by the limbs

    def __post_init__(self):
        self.mass = np.asarray(self.mass, dtype=float)
        self.com = np.asarray(self.com, dtype=float).reshape(-1, 3)
        self.inertia = np.asarray(self.inertia, dtype=float).reshape(-1, 3, 3)
        self.torque_limits = {k: np.broadcast_to(np.asarray(v, dtype=float), (3,)).copy()
                              for k, v in self.torque_limits.items()}

    @property
    def total_mass(self) -> float:
        return float(self.mass.sum())

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise RetimeError(f"no segment named {name!r}; segments: {', '.join(self.names)}") from None

    def mass_factor_array(self, mass_factors) -> np.ndarray:
        """(J,) factors from None, a {segment: factor} mapping or an array."""
        out = np.ones(len(self.names))
        if mass_factors is None:
            return out
        if isinstance(mass_factors, dict):
            for name, f in mass_factors.items():
                if not (float(f) > 0):
                    raise RetimeError(f"mass factor of {name!r} must be positive, got {f}")
                out[self.index(name)] = float(f)
            return out
        arr = np.asarray(mass_factors, dtype=float)
        if arr.shape != out.shape or np.any(arr <= 0):
            raise RetimeError(f"mass factors must be {len(out)} positive numbers")
        return arr

    def strength(self) -> np.ndarray:
        """(J,) default strength (N m) of each joint: :data:`STRENGTH` of its segment, scaled by the
        body mass and ``strength_scale``; 0 for a joint of unknown segment."""
        out = np.zeros(len(self.names))
        for j, name in enumerate(self.names):
            kind = self.segments.get(name)
            if kind == "foot" and (name in self.toes or TOE_RE.search(name)):  # a Kinect toe is FootLeft
                kind = "toe"
            out[j] = STRENGTH.get(kind, 0.0)
        return out * self.strength_scale * self.total_mass / STRENGTH_MASS

    def tree(self, skeleton) -> TreeModel:
        """The rigid-body tree of this body on ``skeleton`` (see :func:`skeleton_tree`)."""
        check_skeleton(self, skeleton)
        return skeleton_tree(skeleton, self)


def skeleton_tree(skeleton, body: Body | None = None) -> TreeModel:
    """A free-floating root, ball joints where the skeleton has rotation DOFs and fixed joints where
    it has none; offsets in metres; the body's inertial parameters (zero without a body)."""
    J = skeleton.n_joints
    jtype = [FREE] + [SPHERICAL if any(d.startswith("r") for d in dofs) else FIXED for dofs in skeleton.dof[1:]]
    if body is None:
        mass, com, inertia = np.zeros(J), np.zeros((J, 3)), np.zeros((J, 3, 3))
    else:
        mass, com, inertia = body.mass, body.com, body.inertia
    return TreeModel(list(skeleton.names), skeleton.parents, jtype, skeleton.offsets * skeleton.meters_per_unit,
                     mass, com, inertia)


def check_skeleton(body: Body, skeleton) -> None:
    if list(body.names) != list(skeleton.names):
        missing = sorted(set(skeleton.names) - set(body.names))
        extra = sorted(set(body.names) - set(skeleton.names))
        raise RetimeError("the body model does not match the skeleton"
                          + (f"; missing segments: {', '.join(missing)}" if missing else "")
                          + (f"; unknown segments: {', '.join(extra)}" if extra else ""))


# ---------------------------------------------------------------------------------------------
# defaults from the skeleton


def rest_positions(skeleton) -> np.ndarray:
    """World joint positions (J, 3) in metres in the rest pose (all local rotations identity)."""
    pos = np.zeros((skeleton.n_joints, 3))
    off = skeleton.offsets * skeleton.meters_per_unit
    for j, p in enumerate(skeleton.parents):
        pos[j] = off[j] + (pos[p] if p >= 0 else 0.0)
    return pos


def _path_up(parents, start, stop):
    """Joints from ``start`` up to and including ``stop`` (or to the root if stop is not above)."""
    out = []
    j = start
    while j > 0:
        out.append(j)
        if j == stop:
            break
        j = int(parents[j])
    return out


def limb_segments(skeleton, feet=None, positions=None) -> tuple[dict[int, str], dict[int, str]]:
    """({joint: de Leva segment}, {joint: side} of the sided ones) from the limbs' geometry: the
    thigh is the bone from the hip to the knee (:func:`~retime.motion.rig.bone_joints` on the world
    ``positions`` (F, J, 3), default the rest pose), the shank the joints from the knee to the ankle,
    and so on, whatever the joints are named."""
    parents = skeleton.parents
    feet = feet or find_feet(skeleton)
    if positions is None:
        positions = rest_positions(skeleton)[None]
    try:
        limbs = skeleton_limbs(skeleton)
    except RetimeError:
        limbs = None
    arms = limbs.arms if limbs is not None else {}
    ends = [f for f, _ in feet.values()] + [hand for _, _, hand in arms.values()]
    if limbs is not None and limbs.head is not None:
        ends.append(limbs.head)
    seg: dict[int, str] = {0: "pelvis"}
    side_of: dict[int, str] = {}

    def put(joints, segment, side):
        for j in joints:
            if j not in seg:
                seg[j] = segment
                side_of[j] = side

    for side, (foot, _) in feet.items():
        put(descendants(parents, foot), "foot", side)
        leg = limbs.legs.get(side) if limbs is not None else None
        shank = leg[1] if leg is not None and leg[2] == foot else int(parents[foot])
        put(_path_up(parents, int(parents[foot]), shank), "shank", side)
        thigh = bone_joints(skeleton, positions, shank, stop=[e for e in ends if e != foot])
        put(thigh, "thigh", side)
        j = int(parents[thigh[-1]]) if thigh and thigh[-1] > 0 else 0
        while j > 0 and j not in seg:
            seg[j] = "pelvis"
            j = int(parents[j])
    for side, (upper, fore, hand) in arms.items():
        if hand in seg:
            continue
        put(descendants(parents, hand), "hand", side)
        put(_path_up(parents, int(parents[hand]), fore), "forearm", side)
        put(bone_joints(skeleton, positions, fore, stop=[e for e in ends if e != hand]), "upperarm", side)
    heads = [j for j, n in enumerate(skeleton.names) if j not in seg and part_of(n) in ("head", "neck")]
    if limbs is not None and limbs.head is not None and limbs.head not in seg:
        heads.append(limbs.head)
    for j in heads:
        for k in descendants(parents, j):
            seg.setdefault(k, "head")
    for j in range(skeleton.n_joints):
        seg.setdefault(j, "trunk")
    return seg, side_of


def _rod_inertia(mass, vec, kt, kl):
    L = float(np.linalg.norm(vec))
    if L < 1e-6:
        return np.eye(3) * 0.4 * mass * ZERO_BONE_RADIUS ** 2
    u = vec / L
    uu = np.outer(u, u)
    return mass * L * L * (kt * kt * (np.eye(3) - uu) + kl * kl * uu)


def default_body(skeleton, mass=None, feet_names=None, motion=None, frames=None) -> Body:
    """The documented default body for ``skeleton`` (total ``mass`` in kg, default 70); ``motion``
    (or its world ``frames``, see :func:`world_frames`, with the motion) places the soles (see
    :func:`default_foot`)."""
    if mass is None:
        mass = BODY_MASS
    if not (mass > 0):
        raise RetimeError(f"body mass must be positive, got {mass}")
    feet_idx = find_feet(skeleton, feet_names)
    if motion is not None and frames is None:
        frames = world_frames(motion)
    seg, side_of = limb_segments(skeleton, feet_idx, frames[0] if frames is not None else None)
    ends = bone_ends(skeleton)
    length = np.linalg.norm(ends, axis=1)
    # ancestors of head joints are spine; other trunk joints are side branches
    spine = set()
    for j, s in seg.items():
        if s == "head":
            k = j
            while k >= 0:
                spine.add(k)
                k = int(skeleton.parents[k])
    groups: dict[tuple[str, str | None], list[int]] = {}
    for j, s in seg.items():
        groups.setdefault((s, side_of.get(j) if s in SIDED else None), []).append(j)
    share = {g: DE_LEVA[g[0]][0] for g in groups}
    scale = mass / sum(share.values())
    m = np.zeros(skeleton.n_joints)
    com = np.zeros((skeleton.n_joints, 3))
    inertia = np.zeros((skeleton.n_joints, 3, 3))
    for g, joints in groups.items():
        w = np.array([length[j] * (0.3 if g[0] == "trunk" and j not in spine else 1.0) for j in joints])
        w = np.maximum(w, 0.1 * w.max()) if w.max() > 0 else np.ones(len(joints))
        w = w / w.sum()
        _, frac, kt, kl = DE_LEVA[g[0]]
        for j, wj in zip(joints, w):
            m[j] = share[g] * scale * wj
            com[j] = frac * ends[j]
            inertia[j] = _rod_inertia(m[j], ends[j], kt, kl)
    fps = motion.fps if motion is not None else None
    feet = [default_foot(skeleton, side, foot, toe, frames if motion is not None else None, fps)
            for side, (foot, toe) in feet_idx.items()]
    toes = {skeleton.names[j] for foot, toe in feet_idx.values() if toe != foot
            for j in descendants(skeleton.parents, toe)}
    return Body(names=list(skeleton.names), mass=m, com=com, inertia=inertia, feet=feet,
                segments={skeleton.names[j]: s for j, s in sorted(seg.items())}, toes=toes)


def world_frames(motion):
    """World joint positions (F, J, 3) in metres and rotation matrices (F, J, 3, 3) of a motion."""
    from ...motion import forward_kinematics
    from ...motion.quat import quat_to_matrix

    pos, rot = forward_kinematics(motion)
    return pos * motion.skeleton.meters_per_unit, quat_to_matrix(rot)


def centre_of_mass(body: Body, R, o) -> np.ndarray:
    """(n, 3) world centre of mass of ``body`` given its world joint frames R (n, J, 3, 3), o (n, J, 3)."""
    mass = np.asarray(body.mass, dtype=float)
    world_com = np.einsum("fjab,jb->fja", R, np.asarray(body.com, dtype=float)) + o
    return np.einsum("fja,j->fa", world_com, mass) / max(mass.sum(), 1e-12)


# ---------------------------------------------------------------------------------------------
# TOML body files

def _fmt(x) -> str:
    return repr(float(x))


def _vec(v) -> str:
    return "[" + ", ".join(_fmt(x) for x in np.ravel(v)) + "]"


def write_body(body: Body, path, torque_limits=None, note: str = "") -> None:
    """Write ``body`` as an editable TOML file (atomically). ``torque_limits`` {joint: (3,)} are
    written instead of the body's own (e.g. the limits estimated from a motion)."""
    limits = body.torque_limits if torque_limits is None else torque_limits
    lines = [
        "# retime body model: edit, then pass with --body. Units: kg, metres, N m.",
        "# Vectors are in each joint's frame in the rest pose (all rotations identity, y up).",
        "# inertia = [Ixx, Iyy, Izz, Ixy, Ixz, Iyz] about the segment's centre of mass.",
    ]
    if note:
        lines += [f"# {line}" for line in note.splitlines()]
    lines += [
        f"mass = {_fmt(body.total_mass)}  # total; informational when every segment is listed",
        f"friction = {_fmt(body.friction)}",
        f"torque_margin = {_fmt(body.torque_margin)}  # default limits: margin * max |torque| of the motion + floor",
        f"torque_floor = {_fmt(body.torque_floor)}",
        f"strength_scale = {_fmt(body.strength_scale)}  # default limits never fall below this times the strength table",
        "",
    ]
    for foot in body.feet:
        lines += [f"[feet.{foot.side}]", f'joint = "{foot.joint}"', f'toe_joint = "{foot.toe_joint}"',
                  f"heel = [{_vec(foot.heel[0])}, {_vec(foot.heel[1])}]  # corners in {foot.joint}'s frame",
                  f"toe = [{_vec(foot.toe[0])}, {_vec(foot.toe[1])}]  # corners in {foot.toe_joint}'s frame", ""]
    if limits:
        lines.append("[torque_limits]  # symmetric limits about the joint's x, y, z axes")
        for name, v in limits.items():
            lines.append(f"{_key(name)} = {_vec(v)}")
        lines.append("")
    for j, name in enumerate(body.names):
        I = body.inertia[j]
        lines += [f"[segments.{_key(name)}]"]
        if name in body.segments:
            lines.append(f'kind = "{body.segments[name]}"')
        lines += [f"mass = {_fmt(body.mass[j])}", f"com = {_vec(body.com[j])}",
                  f"inertia = {_vec([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]])}", ""]
    with atomic_write(path, "w") as f:
        f.write("\n".join(lines))


def _key(name: str) -> str:
    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else '"' + name.replace('"', '\\"') + '"'


MAX_BODY_VALUE = 1e4  # kg, m, N m: larger values in a body file are typing errors, not bodies


def _number(path, where, value, positive=False, nonneg=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise FormatError(path, f"{where} must be a number, got {value!r}")
    if abs(value) > MAX_BODY_VALUE:
        raise FormatError(path, f"{where} is {value:g}; body files hold values up to {MAX_BODY_VALUE:g} (kg, m, N m)")
    if positive and value <= 0:
        raise FormatError(path, f"{where} must be positive, got {value}")
    if nonneg and value < 0:
        raise FormatError(path, f"{where} must not be negative, got {value}")
    return float(value)


def _vector(path, where, value, n):
    if not isinstance(value, list) or len(value) != n:
        raise FormatError(path, f"{where} must be a list of {n} numbers, got {value!r}")
    return np.array([_number(path, where, v) for v in value])


def read_body(path, skeleton, motion=None, frames=None) -> Body:
    """Read a TOML body file for ``skeleton``. Anything it leaves out takes the default; a segment
    given a mass but no inertia keeps the default inertia scaled by the mass ratio."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FormatError(path, "no such body file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise FormatError(path, f"not a valid TOML body file: {e}") from None
    known = {"mass", "friction", "torque_margin", "torque_floor", "strength_scale", "feet", "segments", "torque_limits"}
    for key in data:
        if key not in known:
            raise FormatError(path, f"unknown setting {key!r}; known: {', '.join(sorted(known))}")
    feet_names = {}
    for side, f in (data.get("feet") or {}).items():
        if side not in SIDES or not isinstance(f, dict) or not isinstance(f.get("joint"), str):
            raise FormatError(path, f"[feet.{side}] must be [feet.left] or [feet.right] with joint = \"NAME\"")
        for key in ("joint", "toe_joint"):
            if f.get(key) and f[key] not in skeleton.names:
                raise FormatError(path, f"[feet.{side}] {key} {f[key]!r} is not a joint of the skeleton")
        feet_names[side] = (f["joint"], f.get("toe_joint") or f["joint"])
    segments = data.get("segments") or {}
    total = data.get("mass")
    body = default_body(skeleton, mass=None if total is None else _number(path, "mass", total, positive=True),
                        feet_names=feet_names or None, motion=motion, frames=frames)
    if total is not None and segments and set(segments) >= set(skeleton.names):
        total = None  # every segment listed: the total is informational
    for name, s in segments.items():
        if name not in skeleton.names:
            raise FormatError(path, f"[segments.{name}] is not a joint of the skeleton "
                                    f"(joints: {', '.join(skeleton.names)})")
        j = skeleton.index(name)
        if not isinstance(s, dict):
            raise FormatError(path, f"[segments.{name}] must be a table")
        if "mass" in s:
            new = _number(path, f"[segments.{name}] mass", s["mass"], nonneg=True)
            if "inertia" not in s and body.mass[j] > 0:
                body.inertia[j] *= new / body.mass[j]
            body.mass[j] = new
        if "com" in s:
            body.com[j] = _vector(path, f"[segments.{name}] com", s["com"], 3)
        if "inertia" in s:
            v = _vector(path, f"[segments.{name}] inertia", s["inertia"], 6)
            I = np.array([[v[0], v[3], v[4]], [v[3], v[1], v[5]], [v[4], v[5], v[2]]])
            if np.linalg.eigvalsh(I).min() < -1e-12:
                raise FormatError(path, f"[segments.{name}] inertia is not positive semi-definite")
            body.inertia[j] = I
        if "kind" in s:
            body.segments[name] = str(s["kind"])
    for foot in body.feet:
        f = (data.get("feet") or {}).get(foot.side) or {}
        for key in ("heel", "toe"):
            if key in f:
                pts = f[key]
                if not isinstance(pts, list) or len(pts) != 2:
                    raise FormatError(path, f"[feet.{foot.side}] {key} must be two [x, y, z] corners")
                setattr(foot, key, np.array([_vector(path, f"[feet.{foot.side}] {key}", p, 3) for p in pts]))
    for key in ("friction", "torque_margin", "torque_floor", "strength_scale"):
        if key in data:
            setattr(body, key, _number(path, key, data[key], positive=key == "friction", nonneg=True))
    for name, v in (data.get("torque_limits") or {}).items():
        if name not in skeleton.names:
            raise FormatError(path, f"[torque_limits] {name!r} is not a joint of the skeleton")
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            v = [v, v, v]
        vec = _vector(path, f"[torque_limits] {name}", v, 3)
        if np.any(vec < 0):
            raise FormatError(path, f"[torque_limits] {name} must not be negative")
        body.torque_limits[name] = vec
    return body


def load_body(body, skeleton, motion=None, frames=None) -> Body:
    """A Body from None (defaults), a Body (checked) or a path to a TOML body file; ``motion`` (and
    optionally its world ``frames``) places default soles (see :func:`default_foot`)."""
    if body is None:
        return default_body(skeleton, motion=motion, frames=frames)
    if isinstance(body, Body):
        check_skeleton(body, skeleton)
        return body
    return read_body(body, skeleton, motion=motion, frames=frames)
