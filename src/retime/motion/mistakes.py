"""A good capture as a broken export or a wrong reading would give it: what ``retime check`` must
catch (tests and ``benchmarks/check_verdicts.py``; compare :mod:`.variants`, which keep the
movement and must keep the timing).

* :func:`wrong_frame_time` - the Frame Time multiplied by a factor (the clip plays that much too slow);
* :func:`radians_as_degrees` - rotations written in radians, read as degrees;
* :func:`up_read_as` - the world turned so that up is another axis, then read with the old one;
* :func:`root_locked` - the root pinned where it starts (an in-place export);
* :func:`treadmill` - the root's travel taken out, its sway kept: the feet are carried back while planted.

Each returns a motion with its frame detected again (:func:`.files.with_detected_frame`), as a
reader would see the file, unless the mistake is a reading given by hand (``up_read_as``).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from .files import with_detected_frame
from .model import Motion
from .variants import turn_up

TREADMILL_TRAVEL_S = 0.5  # the travel taken out is the root's path low-passed at this width (s)


def _detected(motion: Motion, **kw) -> Motion:
    """``motion`` on its own copy of the skeleton with its frame detected again; a unit its source
    declared (an ASF's) stays declared."""
    sk = motion.skeleton
    frame = getattr(sk, "frame", None)
    declared = sk.meters_per_unit if frame is not None and frame.unit_confidence == "declared" else None
    motion = motion.replace(skeleton=dataclasses.replace(sk, notes=list(sk.notes)))
    return with_detected_frame("(variant)", motion, declared=declared, **kw)


def wrong_frame_time(motion: Motion, factor: float) -> Motion:
    """The Frame Time times ``factor``: the same frames, played ``factor`` times too slow."""
    return _detected(motion.replace(fps=motion.fps / float(factor)))


def radians_as_degrees(motion: Motion) -> Motion:
    """Every joint's rotation angle read as degrees where radians were written (about its own axis:
    as Euler channels are, for the small angles that come out)."""
    q = motion.rotations.reshape(-1, 4)
    small = Rotation.from_rotvec(Rotation.from_quat(q).as_rotvec() * (np.pi / 180.0)).as_quat()
    return _detected(motion.replace(rotations=small.reshape(motion.rotations.shape)))


def up_read_as(motion: Motion, up: str = "+z", read: str = "+y") -> Motion:
    """A ``read``-up file's world turned so that its up goes to ``up``, then read with ``read`` as up
    (``--up``): a Z-up file read as Y-up. A file whose up is not ``read`` already is just read so."""
    turned = turn_up(motion, up) if motion.skeleton.up == read else motion
    return _detected(turned, up=read, units=motion.skeleton.meters_per_unit)


def _horizontal(motion: Motion) -> list[int]:
    axis = "xyz".index(motion.skeleton.up[-1])
    return [a for a in range(3) if a != axis]


def root_locked(motion: Motion) -> Motion:
    """The root pinned at its first position: the body hangs where it started."""
    tr = motion.translations.copy()
    tr[:, 0] = tr[0, 0]
    return _detected(motion.replace(translations=tr))


def treadmill(motion: Motion) -> Motion:
    """The root's horizontal travel taken out, its sway kept: the capture a treadmill gives. The
    travel is the straight line from the first frame to the last and what remains of the path,
    low-passed over :data:`TREADMILL_TRAVEL_S`."""
    tr = motion.translations.copy()
    h = _horizontal(motion)
    path = tr[:, 0][:, h]
    line = path[0] + np.linspace(0.0, 1.0, len(path))[:, None] * (path[-1] - path[0])
    rest = path - line
    tr[:, 0, h] = path[0] + rest - gaussian_filter1d(rest, TREADMILL_TRAVEL_S * motion.fps, axis=0, mode="nearest")
    return _detected(motion.replace(translations=tr))
