"""Foot contacts: when each heel and toe touches the ground, and the friction cones (Eq. 7-11).

Contact points, in this order everywhere (``CONTACT_POINTS``)::

    0 left_heel   1 left_toe   2 right_heel   3 right_toe

Each point is a pair of sole corners (see :class:`retime.motion.feet.Foot`): the heel's two
corners ride on the foot joint's body, the toe's two on the toe joint's body.

**Detection** (:func:`detect_contacts`): :func:`retime.motion.feet.contact_states` on the body's
sole corners along the path (one detector for every method; thresholds and smoothing there).

**Contact file** (:func:`read_contacts`, CSV, overrides detection entirely)::

    # point, first frame, last frame (0-based, inclusive); '#' starts a comment
    point,first,last
    left_heel,0,120
    left,200,406        # 'left' / 'right' = heel and toe of that foot; 'both' = all four points

A point not listed is never in contact.

**Friction cones**: Coulomb cones of coefficient ``mu`` about the world up axis (+y; the ground does
not tilt when gravity does) are approximated by inscribed pyramids with 4 unit edges
``(+-mu, 1, 0)/sqrt(1+mu^2)`` and ``(0, 1, +-mu)/sqrt(1+mu^2)`` at each of the 4 sole corners of a
foot: 16 basis forces per foot (Fig. 3). ``N = J^T P`` (Eq. 11) has columns ordered
``16*foot + 4*corner + edge`` with foot 0 = left, 1 = right and corners
``heel_a, heel_b, toe_a, toe_b``; the columns of a point not in contact are zero.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
from numba import njit

from ...errors import FormatError, RetimeError
from ...io_util import atomic_write
from ...motion.feet import CONTACT_POINTS, contact_states, sole_corners, sole_positions
from .tree import points_jacobian_transpose, support_rows

ALIASES = {"left": (0, 1), "right": (2, 3), "both": (0, 1, 2, 3)}
EDGES_PER_CORNER = 4
CORNERS_PER_FOOT = 4
BASIS_PER_FOOT = EDGES_PER_CORNER * CORNERS_PER_FOOT


def corner_bodies(body):
    """(8,) joint names and (8, 3) local positions of the sole corners, in column order."""
    return sole_corners(body.feet)


def corner_positions(body, skeleton, R, o):
    """World positions (n, 8, 3) of the sole corners given world joint frames R (n, J, 3, 3), o (n, J, 3)."""
    return sole_positions(body.feet, skeleton, R, o)


def friction_edges(mu: float) -> np.ndarray:
    """(4, 3) unit edges of the pyramid inscribed in the friction cone of coefficient ``mu`` (y up)."""
    if not (mu >= 0):
        raise RetimeError(f"friction coefficient must not be negative, got {mu}")
    e = np.array([[mu, 1.0, 0.0], [-mu, 1.0, 0.0], [0.0, 1.0, mu], [0.0, 1.0, -mu]])
    return e / np.sqrt(1.0 + mu * mu)


def corner_rows(tree, body, skeleton) -> np.ndarray:
    """The velocity rows (sorted) a force at a sole corner shows up on: the legs' and the root's."""
    return support_rows(tree, [skeleton.index(n) for n in corner_bodies(body)[0]])


def corner_jacobians(tree, body, skeleton, R, o):
    """J^T of unit world forces along x, y, z at each sole corner, on the rows that can feel them
    (:func:`corner_rows`): (rows (R,), jt (n, R, 8, 3))."""
    names, _ = corner_bodies(body)
    x = corner_positions(body, skeleton, R, o)
    bodies = [skeleton.index(n) for n in names]
    rows = corner_rows(tree, body, skeleton)
    jt = points_jacobian_transpose(tree, R, o, bodies, x, np.eye(3)[None], rows=rows)
    return rows, jt.reshape(jt.shape[0], jt.shape[1], 8, 3)


def compact_contact_basis(corner_jt, edges, contact):
    """N = J^T P on the rows of the corner Jacobians (n, R, 8, 3): (n, R, 32) for friction-pyramid
    ``edges`` (4, 3) (:func:`friction_edges`) and contact states (n, 4); columns of points not in
    contact are zero (see :class:`.contact_basis.ContactBasis` for the rows)."""
    n, R = corner_jt.shape[:2]
    out = np.zeros((n, R, 8 * EDGES_PER_CORNER))
    _edges(np.ascontiguousarray(corner_jt), np.ascontiguousarray(edges, dtype=float),
           np.ascontiguousarray(contact, dtype=np.bool_), out)
    return out


@njit(cache=True)
def _edges(jt, E, contact, out):
    n, nr, nc, _ = jt.shape
    ne = E.shape[0]
    for i in range(n):
        for r in range(nr):
            for c in range(nc):
                if contact[i, c // 2]:
                    j0, j1, j2 = jt[i, r, c, 0], jt[i, r, c, 1], jt[i, r, c, 2]
                    for e in range(ne):
                        out[i, r, c * ne + e] = j0 * E[e, 0] + j1 * E[e, 1] + j2 * E[e, 2]


# ---------------------------------------------------------------------------------------------
# detection


def detect_contacts(motion, body, h_on=0.03, h_off=0.05, v_on=1.0, v_off=2.0, min_frames=3,
                    frames=None) -> np.ndarray:
    """Contact states (F, 4) of the heel and toe of each foot of ``body`` at the motion's frames
    (:func:`retime.motion.feet.contact_states`); ``frames``: the motion's world frames if known (see
    :func:`retime.physics.model.body.world_frames`)."""
    from .body import world_frames

    pos, R = world_frames(motion) if frames is None else frames
    return contact_states(corner_positions(body, motion.skeleton, R, pos), motion.fps, h_on=h_on, h_off=h_off,
                          v_on=v_on, v_off=v_off, min_frames=min_frames)


def read_contacts(path, n_frames: int) -> np.ndarray:
    """Contact states (n_frames, 4) from a contact CSV file (format in the module docstring)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise FormatError(path, "no such contact file") from None
    except IsADirectoryError:
        raise FormatError(path, "is a folder, not a contact file") from None
    except UnicodeDecodeError as e:
        line = path.read_bytes()[:e.start].count(b"\n") + 1
        raise FormatError(path, "is not UTF-8 text; a contact file is a CSV of point,first,last", line=line) from None
    out = np.zeros((n_frames, 4), dtype=bool)
    rows = 0
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        fields = [f.strip() for f in next(csv.reader(io.StringIO(line)))]
        if fields[:1] == ["point"]:
            continue
        if len(fields) != 3:
            raise FormatError(path, "expected 'point,first,last'", line=lineno)
        name, first, last = fields
        if name in CONTACT_POINTS:
            points = (CONTACT_POINTS.index(name),)
        elif name in ALIASES:
            points = ALIASES[name]
        else:
            raise FormatError(path, f"unknown contact point {name!r}; use one of "
                                    f"{', '.join(CONTACT_POINTS + tuple(ALIASES))}", line=lineno)
        try:
            a, b = int(first), int(last)
        except ValueError:
            raise FormatError(path, f"frames must be whole numbers, got {first!r}, {last!r}", line=lineno) from None
        if not (0 <= a <= b < n_frames):
            raise FormatError(path, f"frames {a}..{b} are outside the motion's 0..{n_frames - 1} "
                                    "(0-based, first <= last)", line=lineno)
        out[a:b + 1, list(points)] = True
        rows += 1
    if rows == 0:
        raise FormatError(path, "no contact ranges; write lines 'point,first,last' (or detect contacts instead)")
    return out


def write_contacts(path, contact) -> None:
    """Write contact states (F, 4) as a contact CSV file (one line per run of contact)."""
    lines = ["# point, first frame, last frame (0-based, inclusive)", "point,first,last"]
    contact = np.asarray(contact, dtype=bool)
    for p, name in enumerate(CONTACT_POINTS):
        s = np.concatenate([[False], contact[:, p], [False]])
        starts = np.nonzero(~s[:-1] & s[1:])[0]
        ends = np.nonzero(s[:-1] & ~s[1:])[0] - 1
        lines += [f"{name},{a},{b}" for a, b in zip(starts, ends)]
    with atomic_write(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def load_contacts(contacts, motion, body, frames=None) -> np.ndarray:
    """Contact states (F, 4) from None (detect), a contact file path or an (F, 4) bool array."""
    if contacts is None:
        return detect_contacts(motion, body, frames=frames)
    if isinstance(contacts, (str, Path)):
        return read_contacts(contacts, motion.n_frames)
    arr = np.asarray(contacts, dtype=bool)
    if arr.shape != (motion.n_frames, 4):
        raise RetimeError(f"contact states must have shape ({motion.n_frames}, 4), got {arr.shape}")
    return arr


def at_samples(contact, fps, times) -> np.ndarray:
    """Contact states at sample times: those of the nearest frame (halfway goes to the later one)."""
    idx = np.clip(np.floor(np.asarray(times) * fps + 0.5 + 1e-9).astype(int), 0, len(contact) - 1)
    return np.asarray(contact)[idx]
