"""Reading and writing motion files by suffix: BVH, ASF/AMC, and FBX/glTF through Blender; the up
axis and units detected on every read."""
import contextlib
from pathlib import Path

import numpy as np

from ..errors import FormatError, RetimeError
from ..limits import check_fps, check_memory
from .asf import read_amc
from .blender_io import SCENE_SUFFIXES, read_scene, write_scene
from .bvh import read_bvh, write_bvh
from .frame import detect_frame
from .model import Motion

READABLE = (".bvh", ".amc", *SCENE_SUFFIXES)
WRITABLE = (".bvh", *SCENE_SUFFIXES)


def load_motion(path, fps=None, asf=None, up=None, units=None, angles=None) -> Motion:
    """Load a BVH, AMC, FBX or glTF file (the last two through Blender, :mod:`.blender_io`). AMC files find ``X.asf`` beside ``X_NN.amc`` unless ``asf`` is given;
    they carry no frame rate, so ``fps`` defaults to CMU's 120 Hz.

    The up axis and length unit are detected from the motion (:mod:`.frame`) and recorded on the
    skeleton (``up``, ``meters_per_unit``, ``frame``); ``up`` ('y', '-z', ...) and ``units`` ('cm',
    'in', ... or metres per unit) override the detection, ``angles`` ('deg' or 'rad') a BVH's
    rotation unit (default: detected)."""
    path = Path(path)
    if fps is not None:
        _check_rate(path, fps, "the given frame rate")
    with contextlib.suppress(OSError):  # the readers hold about 14 times the file in memory at their peak
        check_memory(14 * path.stat().st_size, f"reading {path}")
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return with_detected_frame(path, read_bvh(path, fps=fps, angles=angles), up, units, None)
    if suffix == ".amc":
        return with_detected_frame(path, read_amc(path, asf=asf, fps=fps), up, units, 1.0)
    if suffix in SCENE_SUFFIXES:
        motion, metres_per_unit = read_scene(path)
        if fps is not None:
            motion = motion.replace(fps=fps)
        return with_detected_frame(path, motion, up or "+y", units, metres_per_unit)
    if suffix == ".asf":
        raise FormatError(path, "is a skeleton without motion; load the .amc file (it finds this .asf)")
    raise FormatError(path, f"unknown motion format {suffix or '(no extension)'!r}; retime reads .bvh, .amc, .fbx, .glb and .gltf")


def _check_rate(path, fps, what="the file's frame rate"):
    try:
        check_fps(float(fps), what)
    except RetimeError as e:
        hint = "give another" if what == "the given frame rate" else "check Frame Time, or give --fps"
        raise FormatError(path, f"{e}; {hint}") from None


def with_detected_frame(path, motion, up=None, units=None, declared=None):
    """``motion`` with its up axis and units detected (:mod:`.frame`) and recorded on its skeleton
    (``up``, ``meters_per_unit``, ``frame``); ``up``/``units`` override; errors name ``path``."""
    _check_rate(path, motion.fps)
    try:
        guess = detect_frame(motion, up=up, units=units, declared_units=declared)
    except ValueError as e:
        raise FormatError(path, str(e)) from None
    sk = motion.skeleton
    if guess.unit_confidence == "unknown":  # not a biped: keep the rest-pose guess
        guess.meters_per_unit = sk.meters_per_unit
    sk.up, sk.meters_per_unit, sk.frame = guess.up, guess.meters_per_unit, guess
    return motion


def save_bvh(motion: Motion, path) -> None:
    """Write ``motion`` as BVH, atomically."""
    if Path(path).suffix.lower() != ".bvh":
        raise FormatError(path, "output must be a .bvh file")
    write_bvh(motion, path)


def save_motion(motion: Motion, path, source=None) -> None:
    """Write ``motion`` as BVH, FBX or glTF by ``path``'s suffix, atomically. FBX and glTF go through
    Blender (:func:`.blender_io.write_scene`): an FBX or glTF ``source`` keeps its meshes, skins and materials."""
    suffix = Path(path).suffix.lower()
    if not (np.all(np.isfinite(motion.rotations)) and np.all(np.isfinite(motion.translations))):
        raise RetimeError(f"{path}: the motion to write holds values that are not finite (NaN or inf), from "
                          f"overflow on its input's numbers ({source or 'the input'}); nothing written")
    if suffix == ".bvh":
        return write_bvh(motion, path)
    if suffix in SCENE_SUFFIXES:
        return write_scene(motion, path, source)
    raise FormatError(path, f"cannot write {suffix or '(no extension)'!r}; retime writes {', '.join(WRITABLE)}")
