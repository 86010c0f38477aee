"""BVH (Biovision hierarchy) reading and writing.

Accepts what the format allows and exporters write: CR, LF or CRLF line ends, tabs or spaces, any
rotation order per joint (1 to 3 rotation channels), position channels on any joint, End Sites, any
frame time. A joint's position channels replace its OFFSET (as most tools read them); a root
OFFSET is therefore ignored when the root has position channels.
"""
from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..io_util import atomic_write
from ..limits import number_problem, numbers_fine
from .fk import rest_height
from .model import POSITION_CHANNELS, ROTATION_CHANNELS, Motion, Skeleton, guess_meters_per_unit
from .quat import continuous, euler_to_quat, quat_to_euler

_CHANNEL_NAMES = {c.lower(): c for c in ROTATION_CHANNELS + POSITION_CHANNELS}


def read_text(path) -> str:
    try:
        raw = Path(path).read_bytes()  # closes the file (no ResourceWarning)
    except FileNotFoundError:
        raise FormatError(path, "file not found") from None
    except IsADirectoryError:
        raise FormatError(path, "is a folder, not a file") from None
    except OSError as e:
        raise FormatError(path, f"cannot read: {e.strerror}") from None
    if b"\0" in raw[:4096]:
        raise FormatError(path, "binary data where text was expected; is this really a text motion file?")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _lines(text):
    """(line number, stripped line) for non-empty lines; splitlines handles CR, LF and CRLF."""
    return [(i + 1, ln.strip()) for i, ln in enumerate(text.splitlines()) if ln.strip()]


class _Hierarchy:
    def __init__(self):
        self.names, self.parents, self.offsets, self.channels, self.end_sites = [], [], [], [], []


def _split_braces(lines):
    """Put every '{' and '}' on a line of its own ("JOINT Hips {", "{ OFFSET 0 0 0", "} }")."""
    out = []
    for lineno, line in lines:
        if "{" not in line and "}" not in line:
            out.append((lineno, line))
            continue
        for piece in re.split(r"([{}])", line):
            if piece.strip():
                out.append((lineno, piece.strip()))
    return out


def _parse_hierarchy(path, lines):
    """Parse up to MOTION; returns the hierarchy and the index of the MOTION line in ``lines``."""
    motion_at = next((k for k, (_, ln) in enumerate(lines) if ln.split()[0].upper() == "MOTION"), len(lines))
    h, _ = _parse_hierarchy_lines(path, _split_braces(lines[:motion_at + 1]))
    return h, motion_at


def _parse_hierarchy_lines(path, lines):
    h = _Hierarchy()
    stack = []  # joint index per open brace; -2 for an End Site block
    pending = None  # ('joint', idx) or ('end', parent) waiting for its '{'
    i = 0
    if not lines or lines[0][1].split()[0].upper() != "HIERARCHY":
        raise FormatError(path, "does not start with HIERARCHY; not a BVH file?", lines[0][0] if lines else None)
    i = 1
    while i < len(lines):
        lineno, line = lines[i]
        tokens = line.split()
        key = tokens[0].upper()
        if key == "MOTION":
            if stack or pending:
                raise FormatError(path, "MOTION before the hierarchy's braces are closed", lineno)
            return h, i
        if key in ("ROOT", "JOINT"):
            if key == "ROOT" and (stack or h.names):
                raise FormatError(path, "more than one ROOT; retime reads one skeleton per file", lineno)
            if key == "JOINT" and not stack:
                raise FormatError(path, "JOINT outside any ROOT", lineno)
            if stack and stack[-1] < 0:
                raise FormatError(path, f"{tokens[0]} inside an End Site (an End Site has no children)", lineno)
            name = line[len(tokens[0]):].strip()
            if not name:
                raise FormatError(path, f"{tokens[0]} without a name", lineno)
            if name in h.names:
                raise FormatError(path, f"joint name {name!r} used twice", lineno)
            h.names.append(name)
            h.parents.append(stack[-1] if stack else -1)
            h.offsets.append(None)
            h.channels.append([])
            pending = ("joint", len(h.names) - 1)
        elif key == "END":
            if not stack or stack[-1] < 0:
                raise FormatError(path, "End Site outside a joint", lineno)
            pending = ("end", stack[-1])
        elif key == "{":
            if pending is None:
                raise FormatError(path, "'{' without a ROOT, JOINT or End Site before it", lineno)
            if pending[0] == "joint":
                stack.append(pending[1])
            else:
                h.end_sites.append([pending[1], None])
                stack.append(-2)
            pending = None
        elif key == "}":
            if not stack:
                raise FormatError(path, "'}' without a matching '{'", lineno)
            top = stack.pop()
            if top >= 0 and h.offsets[top] is None:
                raise FormatError(path, f"joint {h.names[top]!r} has no OFFSET", lineno)
            if top == -2 and h.end_sites[-1][1] is None:
                raise FormatError(path, "End Site has no OFFSET", lineno)
        elif key == "OFFSET":
            if not stack:
                raise FormatError(path, "OFFSET outside a joint", lineno)
            vals = read_numbers(path, tokens[1:4], lineno, "OFFSET", count=3)
            if stack[-1] == -2:
                h.end_sites[-1][1] = vals
            else:
                h.offsets[stack[-1]] = vals
        elif key == "CHANNELS":
            if not stack or stack[-1] < 0:
                raise FormatError(path, "CHANNELS outside a joint", lineno)
            try:
                count = int(tokens[1])
            except (IndexError, ValueError):
                raise FormatError(path, "CHANNELS needs a count, then the channel names", lineno) from None
            names = tokens[2:]
            if len(names) != count:
                raise FormatError(path, f"CHANNELS says {count} but names {len(names)}", lineno)
            chans = []
            for c in names:
                if c.lower() not in _CHANNEL_NAMES:
                    raise FormatError(path, f"unknown channel {c!r} (expected X/Y/Z position/rotation)", lineno)
                chans.append(_CHANNEL_NAMES[c.lower()])
            h.channels[stack[-1]] = chans
        else:
            raise FormatError(path, f"unexpected {tokens[0]!r} in HIERARCHY", lineno)
        i += 1
    raise FormatError(path, "file ends before MOTION (truncated?)", lines[-1][0])


def read_numbers(path, tokens, lineno, what, count=None):
    """A line's numbers (``count`` of them, if given), each finite and within the limits, or the
    FormatError naming the line (the BVH and ASF/AMC readers' one check)."""
    try:
        vals = np.array([float(t) for t in tokens])
    except ValueError:
        raise FormatError(path, f"{what} holds a value that is not a number", lineno) from None
    if count is not None and vals.size != count:
        raise FormatError(path, f"{what} needs {count} number{'s' if count > 1 else ''}, found {vals.size}", lineno)
    problem = number_problem(vals)
    if problem:
        raise FormatError(path, f"{what} holds {problem}", lineno)
    return vals


_HEADER = re.compile(r"^(frames\s*:|frame\s*time\s*:)\s*(\S*)", re.IGNORECASE)


RADIAN_LIMIT = 2 * np.pi * 1.01


def rotation_unit(skeleton, values) -> str:
    """'rad' when every rotation channel stays within +-2 pi and some of them move by more than
    0.05 (degrees that small would be a frozen pose; some exporters, Kinect's, write radians)."""
    cols = [k for k, c in enumerate(c for chans in skeleton.channels for c in chans) if c in ROTATION_CHANNELS]
    if not cols or values.shape[0] < 2:
        return "deg"
    rot = values[:, cols]
    if np.abs(rot).max() <= RADIAN_LIMIT and np.ptp(rot, axis=0).max() > 0.05:
        return "rad"
    return "deg"


def read_bvh(path, fps=None, angles=None) -> Motion:
    """Read a BVH file. ``fps`` overrides the file's Frame Time; ``angles`` ('deg', 'rad', None:
    detected, see :func:`rotation_unit`) the rotation channels' unit (``skeleton.angles``)."""
    text = read_text(path)
    lines = _lines(text)
    h, i = _parse_hierarchy(path, lines)
    if not h.names:
        raise FormatError(path, "no ROOT joint in HIERARCHY", lines[i][0])
    header = {}
    i += 1
    while i < len(lines) and len(header) < 2:
        lineno, line = lines[i]
        m = _HEADER.match(line)
        if not m:
            raise FormatError(path, f"expected 'Frames:' and 'Frame Time:' after MOTION, found {line[:40]!r}", lineno)
        header["frames" if m.group(1).lower().startswith("frames") else "time"] = (m.group(2), lineno)
        i += 1
    if "frames" not in header or "time" not in header:
        raise FormatError(path, "file ends in the MOTION header (truncated?)", lines[-1][0])
    try:
        n_frames = int(header["frames"][0])
    except ValueError:
        raise FormatError(path, f"Frames: needs a whole number, found {header['frames'][0]!r}", header["frames"][1]) from None
    try:
        frame_time = float(header["time"][0])
    except ValueError:
        raise FormatError(path, f"Frame Time: needs a number of seconds, found {header['time'][0]!r}", header["time"][1]) from None
    if n_frames <= 0:
        raise FormatError(path, "the file has zero frames; there is nothing to retime", header["frames"][1])
    if fps is None:
        if not (np.isfinite(frame_time) and frame_time > 0 and np.isfinite(1.0 / frame_time)):
            raise FormatError(path, "Frame Time must be a positive number of seconds; or give --fps", header["time"][1])
        fps = fps_from_frame_time(header["time"][0])
    n_channels = sum(len(c) for c in h.channels)
    data_lines = lines[i:]
    if len(data_lines) < n_frames:
        last = data_lines[-1][0] if data_lines else lines[-1][0]
        raise FormatError(path, f"file ends after {len(data_lines)} of {n_frames} frames (truncated?)", last)
    extra = len(data_lines) - n_frames
    data_lines = data_lines[:n_frames]
    values = _parse_frames(path, data_lines, n_channels)
    offsets = np.array(h.offsets)
    end_sites = [(int(j), np.asarray(o)) for j, o in h.end_sites]
    skeleton = Skeleton(names=h.names, parents=np.array(h.parents), offsets=offsets, channels=h.channels,
                        end_sites=end_sites, source=str(path))
    if extra > 0:
        skeleton.notes.append(f"{path}: the file has {extra} more frame row(s) after the {n_frames} its 'Frames:' "
                              f"line declares (line {header['frames'][1]}); read {n_frames}. Correct that line to read them all")
    skeleton.meters_per_unit = guess_meters_per_unit(rest_height(skeleton))
    if angles not in (None, "deg", "rad"):
        raise FormatError(path, f"angles must be 'deg' or 'rad', got {angles!r}")
    skeleton.angles = angles or rotation_unit(skeleton, values)
    rotations, translations = channels_to_pose(skeleton, values, degrees=skeleton.angles == "deg")
    return Motion(skeleton, rotations, translations, fps)


def fps_from_frame_time(token: str) -> float:
    """1 / Frame Time, snapped to the whole frame rate the printed frame time is a rounding of.

    Exporters print 1/120 s as 0.00833333 (or 0.008333); read literally that is 120.000048 Hz. When
    1/round(1/t) rounds to the printed digits, the whole rate is meant. 29.97 Hz (0.0333667) stays."""
    frame_time = float(token)
    fps = 1.0 / frame_time
    whole = round(fps)
    mantissa = token.lower().lstrip("+")
    if whole >= 1 and "e" not in mantissa and "." in mantissa:
        rounding = 0.5 * 10.0 ** -len(mantissa.split(".", 1)[1])
        # only when printed to about five significant digits or more: "0.012" is 83.3 Hz, not 83
        if rounding < 1e-4 * frame_time and abs(frame_time - 1.0 / whole) <= rounding * (1 + 1e-9):
            return float(whole)
    return fps


def _parse_frames(path, data_lines, n_channels):
    rows = [ln.split() for _, ln in data_lines]
    for f, row in enumerate(rows):
        if len(row) != n_channels:
            raise FormatError(path, f"frame {f + 1} has {len(row)} values, the hierarchy declares {n_channels} channels",
                              data_lines[f][0])
    try:
        values = np.array(rows, dtype=float).reshape(len(rows), n_channels)
    except ValueError:
        values = None
    if values is not None and numbers_fine(values):
        return values
    for f, (lineno, line) in enumerate(data_lines):  # find and name the bad line
        read_numbers(path, line.split(), lineno, f"frame {f + 1}")
    raise FormatError(path, "cannot read the frame values", data_lines[0][0])


def channels_to_pose(skeleton, values, degrees=True):
    """Per-frame channel values (F, C) -> local rotations (F, J, 4) and translations (F, J, 3)."""
    n_frames = values.shape[0]
    n_joints = skeleton.n_joints
    rotations = np.zeros((n_frames, n_joints, 4))
    rotations[..., 3] = 1.0
    translations = np.broadcast_to(skeleton.offsets, (n_frames, n_joints, 3)).copy()
    col = 0
    groups = {}
    for j, chans in enumerate(skeleton.channels):
        rot_cols, seq = [], ""
        for c in chans:
            if c in POSITION_CHANNELS:
                translations[:, j, POSITION_CHANNELS.index(c)] = values[:, col]
            else:
                rot_cols.append(col)
                seq += c[0]
            col += 1
        if seq:
            groups.setdefault(seq, []).append((j, rot_cols))
    for seq, members in groups.items():
        joints = [j for j, _ in members]
        cols = np.array([c for _, c in members])  # (G, k)
        # BVH channels rotate about the joint's own (moving) axes in the listed order: intrinsic.
        rotations[:, joints] = euler_to_quat(seq.upper(), values[:, cols], degrees=degrees)
    return rotations, translations


def _writable_channels(chans):
    """Channels to write for a joint: its own, with the rotation completed to three axes."""
    rot = [c for c in chans if c in ROTATION_CHANNELS]
    axes = "".join(c[0] for c in rot)
    if len(rot) == 3 and len(set(axes)) == 3:
        return list(chans)
    pos = [c for c in chans if c in POSITION_CHANNELS]
    return pos + [a + "rotation" for a in "ZXY"]


def pose_to_channels(skeleton, rotations, translations):
    """Local rotations and translations -> channel values (F, C) and the channel names per joint."""
    n_frames = rotations.shape[0]
    columns, channels = [], []
    for j, chans in enumerate(skeleton.channels):
        chans = _writable_channels(chans)
        channels.append(chans)
        seq = "".join(c[0] for c in chans if c in ROTATION_CHANNELS)
        q = continuous(rotations[:, j])
        euler = quat_to_euler(seq.upper(), q, degrees=True)
        euler = np.rad2deg(np.unwrap(np.deg2rad(euler), axis=0))
        k = 0
        for c in chans:
            if c in POSITION_CHANNELS:
                columns.append(translations[:, j, POSITION_CHANNELS.index(c)])
            else:
                columns.append(euler[:, k])
                k += 1
    return np.stack(columns, axis=1) if columns else np.zeros((n_frames, 0)), channels


def bvh_text(motion) -> str:
    sk = motion.skeleton
    values, channels = pose_to_channels(sk, motion.rotations, motion.translations)
    out = io.StringIO()
    out.write("HIERARCHY\n")
    children = {j: sk.children(j) for j in range(sk.n_joints)}
    sites = {}
    for j, off in sk.end_sites:
        sites.setdefault(j, []).append(off)

    def fmt(v):  # offsets keep every digit (shortest round trip: 1.797e308 must not come back as inf)
        return " ".join(repr(float(x) + 0.0) for x in v)

    # depth first with an explicit stack: a chain of thousands of joints must not hit Python's recursion limit
    stack = [("open", 0, 0)]
    while stack:
        what, j, depth = stack.pop()
        ind = "\t" * depth
        if what == "close":
            for off in sites.get(j, []):
                out.write(f"{ind}\tEnd Site\n{ind}\t{{\n{ind}\t\tOFFSET {fmt(off)}\n{ind}\t}}\n")
            out.write(f"{ind}}}\n")
            continue
        out.write(f"{ind}{'ROOT' if sk.parents[j] < 0 else 'JOINT'} {sk.names[j]}\n{ind}{{\n")
        # A root whose position is animated gets OFFSET 0: tools differ on whether a root OFFSET adds
        # to its position channels (retime, Blender: it does not), and a zero offset reads the same in both.
        offset = np.zeros(3) if j == 0 and set(POSITION_CHANNELS) <= set(channels[j]) else sk.offsets[j]
        out.write(f"{ind}\tOFFSET {fmt(offset)}\n")
        out.write(f"{ind}\tCHANNELS {len(channels[j])} {' '.join(channels[j])}\n")
        stack.append(("close", j, depth))
        for c in reversed(children[j]):
            stack.append(("open", c, depth + 1))

    out.write(f"MOTION\nFrames: {motion.n_frames}\nFrame Time: {1.0 / motion.fps:.10g}\n")
    np.savetxt(out, values, fmt="%.6f", delimiter=" ")
    return out.getvalue()


def write_bvh(motion, path):
    """Write a motion as BVH, atomically."""
    text = bvh_text(motion)
    with atomic_write(path, "w", newline="\n") as f:
        f.write(text)
