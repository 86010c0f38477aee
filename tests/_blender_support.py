"""Driving Blender from the tests: the bpy wheel's own virtual environment (created by .ci/run), scripts
run in it as subprocesses, the add-on built and installed as a user would, and retime's command line as
the add-on calls it."""
import functools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPTS = Path(__file__).resolve().parent / "blender_scripts"
SRC = REPO / "src"
SHARED_BVH = REPO.parent / "shared" / "data" / "bvh-dev"
TOLERANCE = 1e-4  # of the body's height: the bound for "the same poses"
ADDON = REPO / "blender" / "retime_addon"


def addon_module(name: str):
    """One of the add-on's modules that need no bpy (runner.py, options.py), imported outside Blender."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"retime_addon_{name}", ADDON / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@functools.lru_cache(maxsize=1)
def bpy_python():
    """The Python with bpy (RETIME_BPY_PYTHON, else the repo's .venv-bpy), or None."""
    given = os.environ.get("RETIME_BPY_PYTHON")
    candidate = Path(given) if given else REPO / ".venv-bpy" / "bin" / "python"
    if not candidate.is_file():
        return None
    done = subprocess.run([str(candidate), "-c", "import bpy"], capture_output=True)
    return str(candidate) if done.returncode == 0 else None


def require_bpy():
    if bpy_python() is None:
        pytest.skip("no Python with Blender's bpy: .ci/run creates .venv-bpy (python3 -m venv .venv-bpy && "
                    ".venv-bpy/bin/pip install 'bpy>=4.2,<6'), or set RETIME_BPY_PYTHON")
    return bpy_python()


def retime_wrapper(folder: Path) -> Path:
    """An executable ``retime`` that runs this tree's command line (what `pip install` would put on PATH)."""
    path = folder / "retime"
    path.write_text(f"#!/bin/sh\nPYTHONPATH={SRC} exec {sys.executable} -c "
                    "'import sys; from retime.cli import main; sys.exit(main())' \"$@\"\n")
    path.chmod(0o755)
    return path


def blender_env(folder: Path, **extra):
    """The environment for a Blender subprocess: its user folder (where extensions install) kept in
    ``folder``, this tree's retime for the FBX/glTF bridge."""
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(folder / "blender-user"), PYTHONPATH=str(SRC))
    env["RETIME_BPY_PYTHON"] = bpy_python()
    env.update({k: v for k, v in extra.items() if v is not None})
    return env


def run_bpy(script, *args, env=None, timeout=900):
    done = subprocess.run([bpy_python(), str(SCRIPTS / script), *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=timeout)
    assert done.returncode == 0, f"{script} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done


def run_retime(*args, env=None):
    """retime's command line in a subprocess (as the add-on runs it): (exit code, stdout, stderr)."""
    done = subprocess.run([sys.executable, "-c", "import sys; from retime.cli import main; sys.exit(main())",
                           *map(str, args)], capture_output=True, text=True,
                          env=dict(env or os.environ, PYTHONPATH=str(SRC)))
    return done.returncode, done.stdout, done.stderr


def build_addon(folder: Path) -> Path:
    sys.path.insert(0, str(REPO / "blender"))
    try:
        import build
    finally:
        sys.path.pop(0)
    return build.build(folder)


def load_motion_bpy(path):
    """load_motion in this process, an FBX or glTF through the tests' bpy Python."""
    from retime.motion import blender_io, load_motion

    old = os.environ.get("RETIME_BPY_PYTHON")
    os.environ["RETIME_BPY_PYTHON"] = bpy_python() or ""
    blender_io.bpy_command.cache_clear()
    try:
        return load_motion(path)
    finally:
        os.environ.pop("RETIME_BPY_PYTHON") if old is None else os.environ.__setitem__("RETIME_BPY_PYTHON", old)
        blender_io.bpy_command.cache_clear()


def joint_positions_blender(path):
    """retime's forward kinematics of a motion file (or a Motion), in Blender's axes (the BVH importer's Y
    up -> Z up), with the joint names and the body height (extent along the up axis)."""
    from retime.motion import Motion, forward_kinematics

    motion = path if isinstance(path, Motion) else load_motion_bpy(path)
    positions, _ = forward_kinematics(motion)
    height = float(np.ptp(positions[..., 1]))
    return motion, motion.skeleton.names, np.stack([positions[..., 0], -positions[..., 2], positions[..., 1]], -1), height


def max_error_over_height(names_a, a, names_b, b, height):
    """Largest distance between the same-named joints of two (F, J, 3) position arrays, over ``height``."""
    index = {n: i for i, n in enumerate(names_b)}
    common = [n for n in names_a if n in index]
    assert len(common) == len(names_a), f"joints missing: {sorted(set(names_a) - set(index))}"
    ia = [list(names_a).index(n) for n in common]
    ib = [index[n] for n in common]
    assert a.shape[0] == b.shape[0], f"{a.shape[0]} frames against {b.shape[0]}"
    return float(np.linalg.norm(a[:, ia] - b[:, ib], axis=-1).max() / height)


def play_addon_script(folder: Path, script: str, frame_time_factor: float = 1.0):
    """CMU 16_06 as BVH in ``folder`` (its Frame Time times ``frame_time_factor``), the add-on built, and
    ``script`` run in bpy on them as ``script ADDON.zip 16_06.bvh FOLDER RESULTS.json`` against this
    tree's retime: (its run, its results)."""
    import json

    from retime.data import bundled_path

    if frame_time_factor == 1.0:
        code, _, err = run_retime("convert", bundled_path("16_06.amc"), folder / "16_06.bvh")
        assert code == 0, err
    else:
        from retime.motion import load_motion, save_bvh
        from retime.motion.mistakes import wrong_frame_time

        save_bvh(wrong_frame_time(load_motion(bundled_path("16_06.amc")), frame_time_factor), folder / "16_06.bvh")
    exe = retime_wrapper(folder)
    done = run_bpy(script, build_addon(folder / "dist"), folder / "16_06.bvh", folder, folder / "results.json",
                   env=blender_env(folder, RETIME_EXECUTABLE=str(exe)))
    return done, json.loads((folder / "results.json").read_text())
