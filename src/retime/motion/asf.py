"""Acclaim ASF (skeleton) and AMC (motion) reading, as CMU writes them.

ASF conventions handled: ``:units`` (``length 0.45`` means one unit is 1/0.45 inch; retime works in
metres), ``angle deg|rad``, bone ``axis`` angles with their order, per-bone ``dof`` subsets and
``limits``, root ``order``/``axis``/``position``/``orientation``. AMC: ``:FULLY-SPECIFIED``,
``:DEGREES``/``:RADIANS``, one block per frame. AMC files carry no frame rate: 120 Hz (CMU's) unless
given.

Conversion to retime's model: a joint sits at the start of its bone; its rest offset is the parent
bone's vector (direction * length); its local rotation, expressed in the world-aligned rest frame, is
C M C^-1, with C the bone's ``axis`` rotation and M the AMC dof rotation (applied in dof order).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..limits import numbers_fine
from .bvh import read_numbers, read_text
from .model import Motion, Skeleton
from .quat import euler_to_quat, qconj, qmul

INCH = 0.0254
CMU_FPS = 120.0
_DOF_NAMES = ("rx", "ry", "rz", "tx", "ty", "tz", "l")


class AsfBone:
    def __init__(self, lineno):
        self.lineno = lineno
        self.name = None
        self.direction = None
        self.length = None
        self.axis = np.zeros(3)
        self.axis_order = "XYZ"
        self.dof = []
        self.limits = []


class Asf:
    """A parsed ASF file: the skeleton in metres plus what AMC reading needs."""

    def __init__(self, path, skeleton, bones, root_order, angle_scale, length_scale, c_rot):
        self.path = path
        self.skeleton = skeleton
        self.bones = bones  # name -> AsfBone (root included as a pseudo bone)
        self.root_order = root_order
        self.angle_scale = angle_scale  # multiply file angles by this to get radians
        self.length_scale = length_scale  # multiply file lengths by this to get metres
        self.c_quat = c_rot  # joint index -> quaternion (x, y, z, w) of the bone's axis frame


def _section_lines(text):
    return [(i + 1, ln.strip()) for i, ln in enumerate(text.splitlines())
            if ln.strip() and not ln.strip().startswith("#")]


def read_asf(path) -> Asf:
    text = read_text(path)
    lines = _section_lines(text)
    if not any(ln.startswith(":bonedata") for _, ln in lines):
        raise FormatError(path, "no :bonedata section; not an ASF skeleton file?")
    length_unit = 1.0
    angle_scale = np.pi / 180.0
    root_order, root_axis = ["TX", "TY", "TZ", "RX", "RY", "RZ"], "XYZ"
    root_position = np.zeros(3)
    root_orientation = np.zeros(3)
    bones = {}
    hierarchy = []
    section = None
    bone = None
    in_limits = False
    for lineno, line in lines:
        tokens = line.split()
        if line.startswith(":"):
            section = tokens[0].lower()
            if section == ":name" or section == ":version":
                section = None
            in_limits = False
            continue
        try:
            if section == ":units":
                key = tokens[0].lower()
                if key == "length":
                    length_unit = float(tokens[1])
                    if not (np.isfinite(length_unit) and length_unit > 0):
                        raise FormatError(path, f"length unit must be a positive number, got {tokens[1]}", lineno)
                    if not 1e-9 <= INCH / length_unit <= 1e6:
                        raise FormatError(path, f"length {tokens[1]} makes one unit {INCH / length_unit:.3g} m; retime "
                                                "reads units of 1 nm to 1000 km (CMU's files say 0.45)", lineno)
                elif key == "angle":
                    angle_scale = 1.0 if tokens[1].lower().startswith("rad") else np.pi / 180.0
            elif section == ":root":
                key = tokens[0].lower()
                if key == "order":
                    root_order = [t.upper() for t in tokens[1:]]
                    bad = [t for t in root_order if t not in ("TX", "TY", "TZ", "RX", "RY", "RZ")]
                    if bad or len(set(root_order)) != len(root_order):
                        raise FormatError(path, "root order must list distinct TX TY TZ RX RY RZ", lineno)
                elif key == "axis":
                    root_axis = _axis_order(path, tokens[1], lineno)
                elif key == "position":
                    root_position = read_numbers(path, tokens[1:4], lineno, "position", count=3)
                elif key == "orientation":
                    root_orientation = read_numbers(path, tokens[1:4], lineno, "orientation", count=3)
            elif section == ":bonedata":
                key = tokens[0].lower()
                if key == "begin":
                    bone = AsfBone(lineno)
                    in_limits = False
                elif key == "end":
                    if bone is None:
                        raise FormatError(path, "'end' without 'begin' in :bonedata", lineno)
                    for attr in ("name", "direction", "length"):
                        if getattr(bone, attr) is None:
                            raise FormatError(path, f"bone starting here has no {attr}", bone.lineno)
                    if bone.name in bones:
                        raise FormatError(path, f"bone {bone.name!r} defined twice", bone.lineno)
                    bones[bone.name] = bone
                    bone = None
                elif bone is None:
                    raise FormatError(path, f"{tokens[0]!r} outside a begin/end bone block", lineno)
                elif key == "id":
                    pass
                elif key == "name":
                    bone.name = tokens[1]
                elif key == "direction":
                    bone.direction = read_numbers(path, tokens[1:4], lineno, "direction", count=3)
                    norm = np.linalg.norm(bone.direction)
                    if norm > 0:  # a unit vector, printed to a few digits: make it one again
                        bone.direction = bone.direction / norm
                elif key == "length":
                    bone.length = read_numbers(path, tokens[1:2], lineno, "length", count=1)[0]
                    if bone.length < 0:
                        raise FormatError(path, f"bone length must not be negative, got {tokens[1]}", lineno)
                elif key == "axis":
                    bone.axis = read_numbers(path, tokens[1:4], lineno, "axis", count=3)
                    bone.axis_order = _axis_order(path, tokens[4], lineno) if len(tokens) > 4 else "XYZ"
                elif key == "dof":
                    bone.dof = [t.lower() for t in tokens[1:]]
                    bad = [d for d in bone.dof if d not in _DOF_NAMES]
                    if bad:
                        raise FormatError(path, f"unknown dof {bad[0]!r} (expected rx ry rz tx ty tz l)", lineno)
                    in_limits = False
                elif key == "limits" or (in_limits and line.startswith("(")):
                    nums = re.findall(r"[-+]?(?:inf|[0-9.]+(?:e[-+]?\d+)?)", line.lower())
                    bone.limits.append((float(nums[0]), float(nums[1])))
                    in_limits = True
                elif key in ("bodymass", "cofmass"):
                    pass
                else:
                    raise FormatError(path, f"unexpected {tokens[0]!r} in bone {bone.name or ''}", lineno)
            elif section == ":hierarchy":
                key = tokens[0].lower()
                if key in ("begin", "end"):
                    continue
                hierarchy.append((lineno, tokens[0], tokens[1:]))
        except (ValueError, IndexError):
            raise FormatError(path, f"cannot read {line[:60]!r}", lineno) from None
    if bone is not None:
        raise FormatError(path, "file ends inside a bone block (truncated?)", bone.lineno)
    if not hierarchy:
        raise FormatError(path, "no :hierarchy section (truncated?)")
    return _build_skeleton(path, bones, hierarchy, length_unit, angle_scale, root_order, root_axis,
                           root_position, root_orientation)


def _axis_order(path, token, lineno):
    order = token.upper()
    if not re.fullmatch(r"[XYZ]{3}", order) or len(set(order)) != 3:
        raise FormatError(path, f"axis order must be a permutation of XYZ, got {token!r}", lineno)
    return order


def _build_skeleton(path, bones, hierarchy, length_unit, angle_scale, root_order, root_axis,
                    root_position, root_orientation):
    length_scale = INCH / length_unit  # metres per file unit
    children = {}
    for lineno, parent, kids in hierarchy:
        if parent != "root" and parent not in bones:
            raise FormatError(path, f"hierarchy names unknown bone {parent!r}", lineno)
        for k in kids:
            if k not in bones:
                raise FormatError(path, f"hierarchy names unknown bone {k!r}", lineno)
        children.setdefault(parent, []).extend(kids)
    names, parents, offsets, channels, dofs, limits = ["root"], [-1], [np.zeros(3)], [], [], []
    root_chans = []
    for d in root_order:
        axis = d[1].upper()
        root_chans.append(f"{axis}position" if d[0] == "T" else f"{axis}rotation")
    channels.append(root_chans)
    dofs.append([d.lower() for d in root_order])
    limits.append([])
    # axis angles rotate about fixed axes in the given order (extrinsic), as Acclaim's C = Rz Ry Rx for XYZ
    c_rot = {0: euler_to_quat(root_axis.lower(), root_orientation * angle_scale)}
    end_sites = []
    queue = [("root", 0)]
    while queue:
        parent_name, parent_idx = queue.pop(0)
        for kid in children.get(parent_name, []):
            if kid in names:
                raise FormatError(path, f"bone {kid!r} appears twice in the hierarchy")
            b = bones[kid]
            names.append(kid)
            parents.append(parent_idx)
            if parent_name == "root":
                offsets.append(root_position * 0.0)
            else:
                pb = bones[parent_name]
                offsets.append(pb.direction * pb.length * length_scale)
            channels.append(["Zrotation", "Xrotation", "Yrotation"] if b.dof else [])
            dofs.append(list(b.dof))
            limits.append(list(b.limits))
            c_rot[len(names) - 1] = euler_to_quat(b.axis_order.lower(), b.axis * angle_scale)
            if not children.get(kid):
                end_sites.append((len(names) - 1, b.direction * b.length * length_scale))
            queue.append((kid, len(names) - 1))
    # Depth-first order keeps parents before children and groups limbs, as BVH files do.
    order = _depth_first(parents)
    remap = {old: new for new, old in enumerate(order)}
    skeleton = Skeleton(
        names=[names[i] for i in order],
        parents=np.array([remap[parents[i]] if parents[i] >= 0 else -1 for i in order]),
        offsets=np.array([offsets[i] for i in order]),
        channels=[channels[i] for i in order],
        end_sites=sorted(((remap[j], o) for j, o in end_sites), key=lambda e: e[0]),
        meters_per_unit=1.0,
        dof=[dofs[i] for i in order],
        limits=[limits[i] for i in order],
        source=str(path),
    )
    c_rot = {remap[k]: v for k, v in c_rot.items()}
    root_bone = AsfBone(0)
    root_bone.name, root_bone.dof = "root", [d.lower() for d in root_order]
    all_bones = dict(bones)
    all_bones["root"] = root_bone
    return Asf(path, skeleton, all_bones, root_order, angle_scale, length_scale, c_rot)


def _depth_first(parents):
    kids = {}
    for i, p in enumerate(parents):
        kids.setdefault(p, []).append(i)
    order, stack = [], [0]
    while stack:
        j = stack.pop()
        order.append(j)
        stack.extend(reversed(kids.get(j, [])))
    return order


def find_asf(amc_path) -> Path:
    """``X_NN.amc`` -> ``X.asf`` beside it (or the only .asf there)."""
    amc_path = Path(amc_path)
    stem = amc_path.stem
    candidates = []
    if "_" in stem:
        candidates.append(amc_path.with_name(stem.rsplit("_", 1)[0] + ".asf"))
    candidates.append(amc_path.with_suffix(".asf"))
    for c in candidates:
        for variant in (c, c.with_suffix(".ASF")):
            if variant.exists():
                return variant
    asfs = sorted(amc_path.parent.glob("*.asf")) + sorted(amc_path.parent.glob("*.ASF"))
    if len(asfs) == 1:
        return asfs[0]
    tried = ", ".join(str(c) for c in candidates)
    raise FormatError(amc_path, f"no skeleton file found (looked for {tried}); give one with --asf SKELETON.asf")


def read_amc(path, asf=None, fps=None) -> Motion:
    """Read an AMC motion with its ASF skeleton (found beside it unless given)."""
    text = read_text(path)  # first, so that a missing motion file is named as such
    asf_path = Path(asf) if asf is not None else find_asf(path)
    skel_info = read_asf(asf_path)
    frames_dof = _parse_amc(path, text, skel_info)
    motion = amc_to_motion(skel_info, frames_dof, CMU_FPS if fps is None else fps)
    return motion


def _amc_header(path, text):
    """(offset where the frame data starts, angles in degrees?) after the ':' and '#' header lines."""
    degrees = True
    pos = 0
    n = len(text)
    while pos < n:
        nl = text.find("\n", pos)
        nl = n if nl < 0 else nl
        line = text[pos:nl].strip()
        if line and not line.startswith("#"):
            if not line.startswith(":"):
                return pos, degrees
            if line.upper().startswith(":RADIANS"):
                degrees = False
        pos = nl + 1
    raise FormatError(path, "the file has zero frames; there is nothing to retime")


def _parse_amc(path, text, info):
    """Return {bone name: (F, n_dof) float array} in radians and metres."""
    if "\r" in text and text.count("\r") != text.count("\r\n"):  # CR-only (old Mac) or mixed line ends
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    start, degrees = _amc_header(path, text)
    names = set(info.skeleton.names)
    dof_count = {name: len(b.dof) for name, b in info.bones.items() if name in names}
    expected = [name for name in info.skeleton.names if dof_count.get(name, 0) > 0]
    body_text = text[start:]
    fast = _parse_amc_fast(body_text, dof_count, expected)
    if fast is not None:
        return _to_radians(fast, degrees, info)
    first_line = text.count("\n", 0, start) + 1
    body = [(i + first_line, ln.strip()) for i, ln in enumerate(body_text.splitlines())
            if ln.strip() and not ln.lstrip().startswith("#")]
    frame_starts = [k for k, (_, ln) in enumerate(body) if ln.isdecimal()]  # "²" is a digit to Python, not a number
    if not frame_starts or frame_starts[0] != 0:
        raise FormatError(path, "expected a frame number to start the motion data", body[0][0] if body else first_line)
    bounds = frame_starts + [len(body)]
    return _to_radians(_parse_amc_slow(path, body, bounds, dof_count, expected, info), degrees, info)


def _parse_amc_fast(body_text, dof_count, expected):
    """Every frame: its number, then the same bones in the same order (as CMU writes them).

    Splits the whole text into tokens once and reads the values column-wise; returns None when the
    file does not have that regular layout or holds a bad value (the slow path then names the line)."""
    tokens = body_text.split()
    if not tokens or not tokens[0].isdecimal():
        return None
    layout = []  # (bone name, value count) of the first frame
    k = 1
    while k < len(tokens) and not (tokens[k].isdecimal() and tokens[k] not in dof_count):
        name = tokens[k]
        if name not in dof_count:
            return None
        layout.append((name, dof_count[name]))
        k += 1 + dof_count[name]
    width = k
    names0 = [n for n, c in layout if c > 0]
    if sorted(names0) != sorted(expected) or len(tokens) % width:
        return None
    table = np.array(tokens, dtype=object).reshape(-1, width)
    name_cols, value_cols, col = [], [], 1
    for name, c in layout:
        name_cols.append(col)
        value_cols.extend(range(col + 1, col + 1 + c))
        col += 1 + c
    if not all(map(str.isdecimal, table[:, 0])):
        return None
    if not np.all(table[:, name_cols] == np.array([n for n, _ in layout], dtype=object)):
        return None
    try:
        vals = np.array(table[:, value_cols].ravel().tolist(), dtype=float).reshape(len(table), len(value_cols))
    except ValueError:
        return None
    if not numbers_fine(vals):
        return None
    out, col = {}, 0
    for name, c in layout:
        if c:
            out[name] = vals[:, col:col + c]
        col += c
    return out


def _parse_amc_slow(path, body, bounds, dof_count, expected, info):
    n_frames = len(bounds) - 1
    out = {n: np.zeros((n_frames, dof_count[n])) for n in expected}
    for f in range(n_frames):
        seen = set()
        frame_line = body[bounds[f]][0]
        number = int(body[bounds[f]][1])
        for lineno, ln in body[bounds[f] + 1:bounds[f + 1]]:
            tokens = ln.split()
            name = tokens[0]
            if name not in dof_count:
                raise FormatError(path, f"frame {number}: unknown bone {name!r} (not in {Path(info.path).name})", lineno)
            if len(tokens) - 1 != dof_count[name]:
                raise FormatError(
                    path, f"frame {number}: bone {name!r} has {len(tokens) - 1} values, the skeleton declares "
                    f"{dof_count[name]} dof ({' '.join(info.bones[name].dof) or 'none'})", lineno)
            if name in seen:
                raise FormatError(path, f"frame {number}: bone {name!r} appears twice", lineno)
            vals = read_numbers(path, tokens[1:], lineno, f"frame {number}: bone {name!r}")
            if dof_count[name]:
                out[name][f] = vals
            seen.add(name)
        missing = [n for n in expected if n not in seen]
        if missing:
            last = body[bounds[f + 1] - 1][0]
            hint = " (truncated?)" if f == n_frames - 1 else ""
            raise FormatError(path, f"frame {number} (line {frame_line}) is missing bone(s) {', '.join(missing)}{hint}", last)
    return out


def _to_radians(values, degrees, info):
    out = {}
    for name, v in values.items():
        dof = info.bones[name].dof
        v = v.copy()
        for k, d in enumerate(dof):
            if d.startswith("r"):
                v[:, k] *= (np.pi / 180.0) if degrees else 1.0
            elif d.startswith("t") or d == "l":
                v[:, k] *= info.length_scale
        out[name] = v
    return out


def amc_to_motion(info, values, fps) -> Motion:
    sk = info.skeleton
    n_frames = next(iter(values.values())).shape[0]
    rotations = np.zeros((n_frames, sk.n_joints, 4))
    rotations[..., 3] = 1.0
    translations = np.broadcast_to(sk.offsets, (n_frames, sk.n_joints, 3)).copy()
    for j, name in enumerate(sk.names):
        if name not in values:
            continue
        dof = info.bones[name].dof
        v = values[name]
        rot_axes = "".join(d[1] for d in dof if d.startswith("r"))
        rot_cols = [k for k, d in enumerate(dof) if d.startswith("r")]
        if j == 0:
            for k, d in enumerate(dof):
                if d.startswith("t"):
                    translations[:, j, "xyz".index(d[1])] = v[:, k]
        if rot_axes:
            # dof rotations apply in the listed order about fixed axes of the bone frame (extrinsic).
            m = euler_to_quat(rot_axes, v[:, rot_cols])
            c = info.c_quat[j]
            rotations[:, j] = qmul(qmul(c, m), qconj(c))
    return Motion(sk, rotations, translations, fps)
