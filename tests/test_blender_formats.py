"""FBX and glTF through Blender (the bpy wheel in its own venv): retime reads them wherever it reads
motion and writes them wherever it writes BVH, keeping the file's meshes, skins and materials; Blender's
own BVH importer reads retime's BVH output with the same joint positions; without bpy, one line."""
import json
import os

import numpy as np
import pytest

from _blender_support import (SHARED_BVH, TOLERANCE, blender_env, joint_positions_blender, load_motion_bpy,
                              max_error_over_height, require_bpy, run_bpy, run_retime)
from retime.data import bundled_path
from retime.motion import blender_io, forward_kinematics, load_motion
from retime.warp import apply_timing, scale_warp


@pytest.fixture(scope="module")
def characters(tmp_path_factory):
    """The bundled jump at 120 fps, and at 30 fps (its frames read 4 times slower), as BVH, and as
    characters (a skinned mesh, a material) in FBX, GLB and glTF."""
    require_bpy()
    tmp = tmp_path_factory.mktemp("formats")
    for name, extra in (("jump", []), ("jump30", ["--fps", "30"])):
        code, _, err = run_retime("convert", bundled_path("16_06.amc"), tmp / f"{name}.bvh", *extra)
        assert code == 0, err
    run_bpy("make_character.py", tmp / "jump.bvh", tmp / "jump.fbx", tmp / "jump.glb", env=blender_env(tmp))
    run_bpy("make_character.py", tmp / "jump30.bvh", tmp / "jump30.glb", tmp / "jump30.gltf", env=blender_env(tmp))
    return tmp


def retime(tmp, *args):
    code, out, err = run_retime(*args, env=blender_env(tmp))
    assert code == 0, err
    return out


def inspect(tmp, path, *extra):
    out = tmp / (path.name + ".json")
    run_bpy("inspect_scene.py", path, out, *extra, env=blender_env(tmp))
    return json.loads(out.read_text())


def same_poses(a, b):
    """Largest joint distance between two motions of the same skeleton, over the body height."""
    pa, _ = forward_kinematics(a)
    pb, _ = forward_kinematics(b)
    index = {n: i for i, n in enumerate(a.skeleton.names)}
    pa = pa[:, [index[n] for n in b.skeleton.names]]
    assert pa.shape == pb.shape, f"{pa.shape} against {pb.shape}"
    return float(np.linalg.norm(pa - pb, axis=-1).max() / np.ptp(pa[..., 1]))


@pytest.mark.parametrize("name, bvh, fps", [("jump.fbx", "jump.bvh", 120), ("jump.glb", "jump.bvh", 120),
                                           ("jump30.glb", "jump30.bvh", 30), ("jump30.gltf", "jump30.bvh", 30)])
def test_read_keeps_frames_rate_and_poses(characters, name, bvh, fps):
    source = load_motion(characters / bvh)
    read = load_motion_bpy(characters / name)
    assert (read.n_frames, read.fps) == (source.n_frames, fps) == (407, fps)  # a glTF at 30 Hz is not read at 24
    assert same_poses(source, read) < TOLERANCE
    assert read.skeleton.up == "+y" and read.skeleton.meters_per_unit == 1.0


@pytest.mark.parametrize("source, output", [("jump.fbx", "back.fbx"), ("jump.glb", "back.glb"),
                                            ("jump30.gltf", "back30.gltf")])
def test_convert_round_trip(characters, source, output):
    """retime convert FILE OUT: the same frames, frame rate and poses read back, meshes and materials kept."""
    tmp = characters
    retime(tmp, "convert", tmp / source, tmp / output)
    before, after = load_motion_bpy(tmp / source), load_motion_bpy(tmp / output)
    assert (after.n_frames, after.fps) == (before.n_frames, before.fps)
    assert same_poses(before, after) < TOLERANCE
    fps = str(round(before.fps))
    scene_before, scene_after = inspect(tmp, tmp / source, fps), inspect(tmp, tmp / output, fps)
    if not source.endswith(".fbx"):  # Blender's glTF exporter splits vertices at its own seams: not ours to keep
        for scene in (scene_before, scene_after):
            for mesh in scene["meshes"].values():
                del mesh["vertices"]
    assert scene_after["meshes"] == scene_before["meshes"]
    body = scene_after["meshes"]["Body"]
    assert body["deformed_by_armature"] and body["groups"] > 20 and body["polygons"] >= 6 * 31  # a box per bone (glTF: triangles)
    assert body["materials"] == ["Skin"]
    if output.endswith(".gltf"):
        assert (tmp / "back30.bin").is_file()  # the buffers beside it, written with it


@pytest.mark.parametrize("source, output", [("jump.fbx", "half.fbx"), ("jump.glb", "half.gltf"), ("jump30.glb", "half30.fbx")])
def test_retimed_file_plays_the_new_timing(characters, source, output):
    """retime linear FILE -o OUT --scale 0.5: OUT plays apply_timing of FILE's motion, and opens again in
    Blender with its mesh and the new frame range."""
    tmp = characters
    retime(tmp, "linear", tmp / source, "-o", tmp / output, "--scale", "0.5")
    before, after = load_motion_bpy(tmp / source), load_motion_bpy(tmp / output)
    expected = apply_timing(before, scale_warp(before.duration, 0.5, before.fps))
    assert (after.n_frames, after.fps) == (expected.n_frames, before.fps) == (204, before.fps)
    assert same_poses(expected, after) < TOLERANCE
    scene = inspect(tmp, tmp / output, str(round(before.fps)))
    assert scene["fps"] == pytest.approx(before.fps)
    (arm,) = scene["armatures"].values()
    assert arm["frame_range"][1] - arm["frame_range"][0] == 203
    assert scene["meshes"]["Body"]["materials"] == ["Skin"] and scene["meshes"]["Body"]["deformed_by_armature"]


def test_fbx_passes_keep_the_keys(characters):
    """A clip converted to FBX and then FBX to FBX three times: every file keys the same frames (Blender's
    importer offsets an FBX's keys one frame later by default, which each pass used to write back), plays
    the same poses, and its armature is named after the clip, not after a temporary file."""
    tmp = characters
    passes = [tmp / "clip.fbx", tmp / "clip_2.fbx", tmp / "clip_3.fbx", tmp / "clip_4.fbx"]
    retime(tmp, "convert", bundled_path("16_06.amc"), passes[0])
    for source, output in zip(passes, passes[1:]):
        retime(tmp, "convert", source, output)
    for path in passes:
        (name, arm), = inspect(tmp, path)["armatures"].items()
        assert (name, arm["frame_range"]) == ("clip", [1.0, 407.0]), path.name
    last = load_motion_bpy(passes[-1])
    assert last.n_frames == 407 and same_poses(load_motion(tmp / "jump.bvh"), last) < TOLERANCE


def test_physics_writes_fbx(characters):
    """The judged path: an FBX character retimed to half its duration with physics, its poses those of the
    BVH output of the same request."""
    tmp = characters
    retime(tmp, "physics", tmp / "jump.fbx", "-o", tmp / "phys.fbx", "--scale", "0.5", "--warp", tmp / "phys.csv", "--quiet")
    retime(tmp, "physics", tmp / "jump.fbx", "-o", tmp / "phys.bvh", "--scale", "0.5", "--quiet")
    assert same_poses(load_motion(tmp / "phys.bvh"), load_motion_bpy(tmp / "phys.fbx")) < TOLERANCE


def test_not_an_fbx_is_one_line(characters):
    bad = characters / "broken.fbx"
    bad.write_text("this is not an FBX file\n")
    code, out, err = run_retime("info", bad, env=blender_env(characters))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "broken.fbx" in err and "Traceback" not in err, err


def test_blender_reads_retime_bvh(characters):
    """Blender's BVH importer on retime's output: the same joint positions on every frame as retime's
    forward kinematics (a CMU jump retimed, and Mixamo's rig from ../shared when it is there)."""
    tmp = characters
    files = [tmp / "half.bvh"]
    retime(tmp, "linear", bundled_path("16_06.amc"), "-o", files[0], "--scale", "0.5")
    if SHARED_BVH.is_dir():
        files.append(tmp / "mixamo_half.bvh")
        retime(tmp, "linear", SHARED_BVH / "Gangnam Style.bvh", "-o", files[1], "--scale", "0.5")
    args = [a for f in files for a in (f, f.with_suffix(".npz"))]
    run_bpy("import_bvh_heads.py", *args, env=blender_env(tmp))
    for f in files:
        motion, names, expected, height = joint_positions_blender(f)
        got = np.load(f.with_suffix(".npz"))
        assert float(got["fps"]) == pytest.approx(motion.fps, rel=1e-6)
        assert max_error_over_height(list(names), expected, list(got["names"]), got["heads"], height) < TOLERANCE


def test_without_bpy_one_line(monkeypatch, tmp_path, capsys):
    """No Python with bpy anywhere: reading or writing FBX/glTF says what to install, in one line."""
    from retime.cli import main

    monkeypatch.delenv("RETIME_BPY_PYTHON", raising=False)
    monkeypatch.setattr(blender_io, "_venv_places", lambda: [])
    monkeypatch.setattr(blender_io.importlib.util, "find_spec", lambda name: None)
    monkeypatch.setattr(blender_io.shutil, "which", lambda name: None)
    blender_io.bpy_command.cache_clear()
    (tmp_path / "a.glb").write_bytes(b"glTF")
    try:
        assert main(["info", str(tmp_path / "a.glb")]) == 2
        code = main(["physics", str(bundled_path("16_06.amc")), "-o", str(tmp_path / "out.fbx")])  # before any work
    finally:
        blender_io.bpy_command.cache_clear()
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("needs Blender's bpy module" in e and "pip install 'bpy>=4.2,<6'" in e for e in err)
    assert not (tmp_path / "out.fbx").exists()


def test_python_without_bpy_one_line(monkeypatch, tmp_path, capsys):
    """RETIME_BPY_PYTHON naming a Python that has no bpy: one line saying so."""
    import sys

    from retime.cli import main

    monkeypatch.setenv("RETIME_BPY_PYTHON", sys.executable)
    blender_io.bpy_command.cache_clear()
    (tmp_path / "a.fbx").write_bytes(b"Kaydara FBX Binary  \0")
    try:
        assert main(["info", str(tmp_path / "a.fbx")]) == 2
    finally:
        blender_io.bpy_command.cache_clear()
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "has no bpy" in line and "a.fbx" in line


def test_blender_on_path_runs_the_bridge(characters, monkeypatch, tmp_path):
    """With no bpy Python found, retime runs ``blender --background ... --python bridge.py -- ARGS``: here a
    stand-in 'blender' that runs the script with the bpy venv, so the command line retime builds is used."""
    fake = tmp_path / "blender"
    fake.write_text("#!/bin/sh\n"
                    'while [ "$1" != "--python" ]; do shift; done\n'
                    'script=$2; shift 2\n'
                    f'exec {blender_env(characters)["RETIME_BPY_PYTHON"]} "$script" "$@"\n')
    fake.chmod(0o755)
    monkeypatch.delenv("RETIME_BPY_PYTHON", raising=False)
    monkeypatch.setenv("PATH", f"{tmp_path}:{os.environ['PATH']}")
    monkeypatch.setattr(blender_io, "_venv_places", lambda: [])
    monkeypatch.setattr(blender_io.importlib.util, "find_spec", lambda name: None)
    blender_io.bpy_command.cache_clear()
    try:
        command = blender_io.bpy_command()
        motion = load_motion(characters / "jump.fbx")
    finally:
        blender_io.bpy_command.cache_clear()
    assert command[0] == str(fake) and "--background" in command and command[-1] == "--"
    assert (motion.n_frames, motion.fps) == (407, 120)
