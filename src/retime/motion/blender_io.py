"""FBX and glTF (.fbx, .glb, .gltf) through Blender's own importers and exporters.

retime's environment does not hold Blender: the ``bpy`` wheel pins NumPy below 2, so it usually lives in
a virtual environment of its own. retime runs :mod:`.inside_blender.bridge` there as a subprocess,
which imports the file and writes the animated armature as a BVH plus JSON (frame rate, metres per
unit); writing imports the source file again, puts the retimed poses on its armature as a new
action and exports, so the file's meshes, skins and materials stay. The Python that has ``bpy`` is,
in this order (:func:`bpy_command`):

1. ``RETIME_BPY_PYTHON``, a Python executable with ``bpy`` installed;
2. ``.venv-bpy`` in the current folder or beside retime's source tree (a development checkout), when
   its Python can import ``bpy``;
3. the Python running retime, when it can import ``bpy`` (``pip install 'retime[blender]'``);
4. ``blender`` on PATH, run as ``blender --background --python bridge.py``.
"""
from __future__ import annotations

import functools
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from ..errors import FormatError, RetimeError
from ..io_util import atomic_write

SCENE_SUFFIXES = (".fbx", ".glb", ".gltf")
BRIDGE = Path(__file__).with_name("inside_blender") / "bridge.py"
INSTALL_HINT = ("needs Blender's bpy module: python3 -m venv .venv-bpy && .venv-bpy/bin/pip install 'bpy>=4.2,<6' "
                "(then run retime from that folder or set RETIME_BPY_PYTHON=.venv-bpy/bin/python), "
                "or put blender 4.2+ on PATH")
_ERROR_PREFIX = "retime-bridge: error: "


def _venv_python(venv: Path) -> Path:
    return venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def _imports_bpy(python: Path) -> bool:
    """Whether ``python`` runs and can import ``bpy``."""
    try:
        return subprocess.run([str(python), "-c", "import bpy"], capture_output=True, check=False).returncode == 0
    except OSError:
        return False


def _venv_places():
    return [Path.cwd() / ".venv-bpy", Path(__file__).resolve().parents[3] / ".venv-bpy"]


@functools.lru_cache(maxsize=1)
def bpy_command() -> tuple[str, ...] | None:
    """The command that runs the bridge script with ``bpy`` (arguments follow), or None (see the module
    docstring for the order)."""
    given = os.environ.get("RETIME_BPY_PYTHON")
    if given:
        if not Path(given).is_file():
            raise RetimeError(f"RETIME_BPY_PYTHON={given}: no such file; point it at a Python with bpy installed")
        return (given, str(BRIDGE))
    for venv in _venv_places():
        if _venv_python(venv).is_file() and _imports_bpy(_venv_python(venv)):
            return (str(_venv_python(venv)), str(BRIDGE))
    if importlib.util.find_spec("bpy") is not None:
        return (sys.executable, str(BRIDGE))
    blender = shutil.which("blender")
    if blender:
        return (blender, "--background", "--factory-startup", "--python-exit-code", "2", "--python", str(BRIDGE), "--")
    return None


def require_bpy(path):
    """The bridge's command, or the one line saying what to install (before any work is done)."""
    command = bpy_command()
    if command is None:
        raise FormatError(path, f"reading and writing {Path(path).suffix.lower()} files {INSTALL_HINT}")
    return command


def _run_bridge(path, *args, produces=()):
    """Run the bridge on ``args``; it must exit 0 and leave every file in ``produces``."""
    command = require_bpy(path)
    try:
        done = subprocess.run([*command, *map(str, args)], capture_output=True, text=True, errors="replace")
    except OSError as e:
        raise RetimeError(f"cannot run {command[0]}: {e.strerror}; check RETIME_BPY_PYTHON or your Blender") from None
    if done.returncode == 0:
        if not all(Path(p).is_file() for p in produces):  # exit 0 is not proof: e.g. RETIME_BPY_PYTHON=/bin/true
            raise FormatError(path, f"{command[0]} exited without error but wrote nothing; "
                                    "is it Blender or a Python with bpy (RETIME_BPY_PYTHON)?")
        return
    lines = done.stderr.strip().splitlines()
    said = [ln[len(_ERROR_PREFIX):] for ln in lines if ln.startswith(_ERROR_PREFIX)]
    if said:
        raise FormatError(path, said[-1])
    if any("No module named 'bpy'" in ln for ln in lines):
        raise FormatError(path, f"{command[0]} has no bpy; reading {Path(path).suffix.lower()} files {INSTALL_HINT}")
    last = lines[-1] if lines else f"exit code {done.returncode}"
    raise FormatError(path, f"Blender failed ({command[0]}): {last}")


def read_scene(path):
    """The animated armature of an FBX or glTF file: (its motion, the scene's metres per unit). The
    motion's ``skeleton.source`` is the file; its up axis is +y (the bridge's BVH is Blender's Z-up turned Y-up)."""
    from .bvh import read_bvh

    path = Path(path)
    if not path.is_file():
        raise FormatError(path, "file not found" if not path.exists() else "is not a file")
    with tempfile.TemporaryDirectory(prefix="retime-bpy-") as tmp:
        bvh, meta_path = Path(tmp) / "motion.bvh", Path(tmp) / "motion.json"
        _run_bridge(path, "read", path.resolve(), bvh, meta_path, produces=(bvh, meta_path))
        meta = json.loads(meta_path.read_text())
        motion = read_bvh(bvh, fps=meta["fps"], angles="deg")
    motion.skeleton.source = str(path)
    return motion, float(meta["meters_per_unit"])


def write_scene(motion, path, source=None):
    """Write ``motion`` as FBX or glTF (by ``path``'s suffix), atomically. An FBX or glTF ``source`` is
    imported and its armature's animation replaced, keeping its meshes, skins and materials; any other
    source (a BVH, an AMC) becomes a bare armature through Blender's BVH importer."""
    from .bvh import bvh_text

    path = Path(path)
    suffix = path.suffix.lower()
    scene_source = source is not None and Path(source).suffix.lower() in SCENE_SUFFIXES
    with tempfile.TemporaryDirectory(prefix="retime-bpy-") as tmp:
        poses = Path(tmp) / "poses.npz"
        np.savez(poses, names=np.array(motion.skeleton.names), rotations=motion.rotations,
                 translations=motion.translations, fps=motion.fps, frames=motion.n_frames,
                 bvh_text=np.array("" if scene_source else bvh_text(motion)))
        out_dir = Path(tmp) / "out"
        out_dir.mkdir()
        staged = out_dir / f"{path.stem}{suffix}"
        _run_bridge(path, "write", Path(source).resolve() if scene_source else "motion.bvh", poses, staged,
                    produces=(staged,))
        for produced in sorted(out_dir.iterdir()):  # a .gltf comes with its .bin (and any textures)
            name = path.name if produced == staged else produced.name
            with atomic_write(path.with_name(name), "wb") as f:
                f.write(produced.read_bytes())
