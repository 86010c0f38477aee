"""retime's bridge to Blender's FBX and glTF importers and exporters. Runs in a Python with ``bpy``
(``python bridge.py ARGS``) or in Blender (``blender --background --python bridge.py -- ARGS``):

    read SOURCE OUT.bvh OUT.json        the animated armature of SOURCE as a BVH, and what retime needs
                                        to know about it (frame rate, metres per unit) as JSON
    write SOURCE POSES.npz OUT          SOURCE imported, its armature playing the poses in POSES.npz
                                        (written by retime.motion.blender_io), exported to OUT (.fbx,
                                        .glb or .gltf, by suffix). A .bvh or .amc SOURCE has no scene:
                                        POSES.npz then holds the BVH text, read with Blender's importer.

Errors are one line on stderr, ``retime-bridge: error: ...``, and exit code 2.
"""
import json
import os
import struct
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import armature  # noqa: E402  (beside this script; Blender runs it as a file, not as a package)

SCENE_SUFFIXES = (".fbx", ".glb", ".gltf")


class BridgeError(Exception):
    pass


def main(argv):
    if len(argv) == 4 and argv[0] == "read":
        return read(*argv[1:])
    if len(argv) == 4 and argv[0] == "write":
        return write(*argv[1:])
    raise BridgeError("usage: bridge.py read SOURCE OUT.bvh OUT.json | write SOURCE POSES.npz OUT")


def empty_scene():
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def import_scene(path):
    """Import an FBX or glTF file into an empty scene whose frame rate is the file's."""
    import bpy

    scene = empty_scene()
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".fbx":
        # sets the scene's rate from the file's time mode; no offset (the default shifts the keys one frame
        # later, and written back each pass, the file's animation drifted a frame per round trip)
        _run_operator("importer", bpy.ops.import_scene.fbx, filepath=path, anim_offset=0.0)
    else:
        # glTF keeps times in seconds and the importer turns them into frames at the scene's rate (a glTF
        # sampled at 30 Hz imported at Blender's default 24 fps lands between frames): use the file's rate
        rate = gltf_rate(path)
        if rate is not None:
            scene.render.fps, scene.render.fps_base = max(1, round(rate)), 1.0  # the importer ignores fps_base
        _run_operator("importer", bpy.ops.import_scene.gltf, filepath=path)
    return scene


def _run_operator(kind, op, failed="", **kwargs):
    """Run Blender's ``kind`` ("importer", "exporter") operator; its failure becomes a BridgeError: the last
    line of its report after ``failed``, or that it gave up."""
    try:
        result = op(**kwargs)
    except RuntimeError as e:  # the operator's report, e.g. an unsupported FBX version
        raise BridgeError(failed + str(e).strip().splitlines()[-1]) from None
    if "FINISHED" not in result:
        raise BridgeError(f"Blender's {kind} gave up ({', '.join(result)})")


def gltf_json(path):
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] == b"glTF":  # binary glTF: 12-byte header, then the JSON chunk
        length, kind = struct.unpack_from("<I4s", data, 12)
        if kind != b"JSON":
            raise BridgeError("binary glTF without a JSON chunk first")
        return json.loads(data[20:20 + length])
    return json.loads(data)


def gltf_rate(path):
    """The sampling rate of the file's first animation (samplers' input accessors must give min and max)."""
    try:
        doc = gltf_json(path)
    except (OSError, ValueError, struct.error) as e:
        raise BridgeError(f"not a glTF file: {e}") from None
    accessors = doc.get("accessors", [])
    for anim in doc.get("animations", []):
        for sampler in anim.get("samplers", []):
            acc = accessors[sampler["input"]]
            if acc.get("count", 0) > 1 and acc.get("max") and acc.get("min"):
                span = acc["max"][0] - acc["min"][0]
                if span > 0:
                    return (acc["count"] - 1) / span
    return None


def animated_armature(scene):
    """The one armature with an action in the scene."""
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    animated = [o for o in armatures if o.animation_data and o.animation_data.action]
    if not armatures:
        raise BridgeError("no armature in the file; retime retimes skeletal animation")
    if not animated:
        raise BridgeError(f"the armature {armatures[0].name!r} has no animation")
    if len(animated) > 1:
        raise BridgeError(f"{len(animated)} animated armatures ({', '.join(o.name for o in animated)}); retime reads "
                          "files with one")
    return animated[0]


def read(source, out_bvh, out_json):
    import bpy

    scene = import_scene(source)
    obj = animated_armature(scene)
    action = obj.animation_data.action
    start, end = armature.frame_range(action)
    if end <= start:
        raise BridgeError(f"the action {action.name!r} has a single frame; there is no timing to change")
    try:
        pose = armature.BvhPose(*armature.sample_pose(bpy.context, obj, range(start, end + 1)))
    except armature.ArmatureError as e:
        raise BridgeError(str(e)) from None
    fps = armature.scene_fps(scene)
    with open(out_bvh, "w", newline="\n") as f:
        f.write(pose.text(fps))
    with open(out_json, "w") as f:
        json.dump({"fps": fps, "meters_per_unit": scene.unit_settings.scale_length}, f)
    return 0


def write(source, poses_npz, out):
    import bpy

    poses = np.load(poses_npz, allow_pickle=False)
    fps = float(poses["fps"])
    if os.path.splitext(source)[1].lower() in SCENE_SUFFIXES:
        scene = import_scene(source)
        obj = animated_armature(scene)
        start = armature.frame_range(obj.animation_data.action)[0]
        n_frames = put_poses(bpy.context, obj, poses, start)
    else:
        scene = empty_scene()
        # Blender names the armature after the BVH file: after the clip written, not a temporary name
        bvh = os.path.join(os.path.dirname(out), os.path.splitext(os.path.basename(out))[0] + ".bvh")
        with open(bvh, "w") as f:
            f.write(str(poses["bvh_text"]))
        try:
            _run_operator("importer", bpy.ops.import_anim.bvh, filepath=bvh, update_scene_fps=True, frame_start=1)
        finally:
            os.unlink(bvh)
        start, n_frames = 1, int(poses["frames"])
    armature.set_scene_fps(scene, fps)
    scene.frame_start, scene.frame_end = start, start + n_frames - 1
    export(out)
    return 0


def put_poses(context, obj, poses, start):
    """Replace the armature's action by a new one playing ``poses`` from frame ``start``; return the frame count."""
    import bpy

    h = armature.skeleton(obj)  # the bones read (armature.sample_pose): the deform skeleton, one hierarchy
    names = [str(n) for n in poses["names"]]
    if names != h.bvh_names:
        raise BridgeError(f"the armature {obj.name!r} has other bones than the motion retime wrote")
    context.scene.frame_set(start)
    world0 = np.array(obj.evaluated_get(context.evaluated_depsgraph_get()).matrix_world)
    basis = armature.bone_bases(h, world0, poses["rotations"], poses["translations"])
    n_frames = len(poses["rotations"])
    frames = np.arange(start, start + n_frames, dtype=float)
    old = obj.animation_data.action
    action, slot, fcurves = armature.new_action(obj, old.name)
    for name, local in basis.items():  # every bone: those not read move with the bones read
        loc, quat, scale = armature.decompose(local)
        armature.key_bone(fcurves, obj.pose.bones[name], frames, loc, quat, scale)
    armature.assign_action(obj, action, slot)
    for track in list(obj.animation_data.nla_tracks):  # other takes of the file: the retimed one is exported alone
        obj.animation_data.nla_tracks.remove(track)
    name = old.name
    bpy.data.actions.remove(old)
    action.name = name
    return n_frames


def export(out):
    import bpy

    suffix = os.path.splitext(out)[1].lower()
    failed = "Blender's exporter failed: "
    if suffix == ".fbx":
        # every frame kept (no curve simplification), no leaf bones added, the one action alone
        _run_operator("exporter", bpy.ops.export_scene.fbx, failed, filepath=out, bake_anim=True,
                      bake_anim_simplify_factor=0.0, bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False,
                      bake_anim_force_startend_keying=True, add_leaf_bones=False)
    else:
        _run_operator("exporter", bpy.ops.export_scene.gltf, failed, filepath=out,
                      export_format="GLB" if suffix == ".glb" else "GLTF_SEPARATE",
                      export_animation_mode="ACTIVE_ACTIONS", export_force_sampling=True, export_frame_range=True,
                      export_optimize_animation_size=False)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    try:
        code = main(argv)
    except (BridgeError, armature.ArmatureError) as e:
        print(f"retime-bridge: error: {e}", file=sys.stderr)
        code = 2
    sys.stdout.flush()
    os._exit(code)  # bpy's atexit handlers are slow and chatty; everything is written and closed
