"""Runs inside the bpy venv: install the add-on zip as a user would, then play the cases of a JSON file,
one Blender process for all of them. ``python addon_driver.py ADDON.zip CASES.json RESULTS.json``

Each case: {"name", "bvh", "op": operator keywords, "markers": [[frame, name], ...], "select": "armature" |
"none" | "mesh", "drop_action": bool, "env": {variable: value or null}, "transform": {object property:
value}, "rotate_mode", "reference_bvh", "preference": the add-on's retime path}. The result per case: "status"
(the operator's return or "RuntimeError"), "error" (the report of a failed call), and for a success an
.npz beside RESULTS.json with the bones' world head positions on every output frame ("heads", Blender's
axes), their "names", the output "frames", and for an NLA strip the strip-time keys ("strip_time").
"""
import json
import os
import sys

import bpy
import numpy as np


def clear_scene():
    for collection in (bpy.data.objects, bpy.data.armatures, bpy.data.actions, bpy.data.meshes):
        for item in list(collection):
            collection.remove(item)
    bpy.context.scene.timeline_markers.clear()


def setup(case):
    clear_scene()
    if case.get("reference_bvh"):  # an action of another take of the same skeleton, its armature deleted
        bpy.ops.import_anim.bvh(filepath=case["reference_bvh"])
        other = bpy.context.active_object
        reference = other.animation_data.action
        reference.name, reference.use_fake_user = "reference", True
        bpy.data.objects.remove(other)
    if case["bvh"].endswith(".fbx"):  # a character as FBX brings it: object transform, quaternions
        bpy.ops.import_scene.fbx(filepath=case["bvh"])
        arm = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
        bpy.context.view_layer.objects.active = arm
        arm.select_set(True)
        start, end = arm.animation_data.action.frame_range
        bpy.context.scene.frame_start, bpy.context.scene.frame_end = int(start), int(end)
    else:
        bpy.ops.import_anim.bvh(filepath=case["bvh"], update_scene_fps=True, update_scene_duration=True,
                                rotate_mode=case.get("rotate_mode", "NATIVE"))
        arm = bpy.context.active_object
    for prop, value in case.get("transform", {}).items():  # an armature object moved, turned and scaled
        setattr(arm, prop, value)
    for frame, name in case.get("markers", []):
        bpy.context.scene.timeline_markers.new(name, frame=frame)
    if case.get("drop_action"):
        arm.animation_data.action = None
    select = case.get("select", "armature")
    if select != "armature":
        arm.select_set(False)
        bpy.context.view_layer.objects.active = None
    if select == "mesh":
        mesh = bpy.data.meshes.new("Body")
        body = bpy.data.objects.new("Body", mesh)
        bpy.context.scene.collection.objects.link(body)
        bpy.context.view_layer.objects.active = body
    return arm


def heads(arm, names, frames):
    out = np.empty((len(frames), len(names), 3))
    for k, f in enumerate(frames):
        bpy.context.scene.frame_set(int(f))
        ev = arm.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mw = ev.matrix_world
        for j, n in enumerate(names):
            out[k, j] = mw @ ev.pose.bones[n].head
    return out


def play(case, folder):
    saved = {k: os.environ.get(k) for k in case.get("env", {})}
    for k, v in case.get("env", {}).items():
        os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
    prefs = bpy.context.preferences.addons[__package_name__].preferences
    prefs.retime_path = case.get("preference", "")
    try:
        arm = setup(case)
        original = arm.animation_data.action if arm.animation_data else None
        original_keys = _keys(original)
        before = _state(arm)
        try:
            status = sorted(bpy.ops.retime.retime(**case["op"]))
        except RuntimeError as e:
            return {"status": "RuntimeError", "error": str(e).strip(), "unchanged": _state(arm) == before}
        result = {"status": status}
        adt = arm.animation_data
        if adt.action is not None:
            start, end = (int(round(f)) for f in adt.action.frame_range)
            result["keys_per_curve"] = sorted({len(fc.keyframe_points) for fc in _curves(adt.action)})
        else:
            strip = adt.nla_tracks[-1].strips[0]
            start, end = int(round(strip.frame_start)), int(round(strip.frame_end))
            keys = strip.fcurves.find("strip_time").keyframe_points
            result["strip_use_animated_time"] = strip.use_animated_time
            np.save(os.path.join(folder, case["name"] + ".strip.npy"), np.array([tuple(k.co) for k in keys]))
        result["original_untouched"] = _keys(original) == original_keys
        result["action"] = adt.action.name if adt.action else None
        result["strip_plays_original"] = bool(adt.nla_tracks) and adt.nla_tracks[-1].strips[0].action == original
        frames = list(range(start, end + 1))
        names = [b.name for b in arm.pose.bones]
        positions = heads(arm, names, frames)
        np.savez(os.path.join(folder, case["name"] + ".npz"), heads=positions, names=np.array(names),
                 frames=np.array(frames))
        return result
    finally:
        for k, v in saved.items():
            os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)


def _curves(action):
    from importlib import import_module

    return import_module(__package_name__ + ".armature").action_fcurves(action)


def _keys(action):
    """Every key of an action, to check that it was left as it was."""
    if action is None:
        return None
    return [(fc.data_path, fc.array_index, tuple(tuple(k.co) for k in fc.keyframe_points)) for fc in _curves(action)]


def _state(arm):
    """What a failed retime must leave as it was."""
    adt = arm.animation_data
    return (adt.action.name if adt and adt.action else None, len(bpy.data.actions),
            len(adt.nla_tracks) if adt else 0, bpy.context.scene.frame_end)


if __name__ == "__main__":
    zip_path, cases_path, results_path = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    __package_name__ = next(a.module for a in bpy.context.preferences.addons if a.module.endswith(".retime"))
    folder = os.path.dirname(os.path.abspath(results_path))
    results = {}
    for case in json.load(open(cases_path)):
        results[case["name"]] = play(case, folder)
    op = bpy.types.RETIME_OT_retime
    results["_registered"] = {
        "bl_options": sorted(op.bl_options),
        "panels": sorted(f"{p.bl_space_type}/{p.bl_region_type}" for p in bpy.types.Panel.__subclasses__()
                         if p.__module__.startswith(__package_name__)),
        "properties": sorted(bpy.ops.retime.retime.get_rna_type().properties.keys()),
        "preferences": bpy.context.preferences.addons[__package_name__].preferences is not None,
    }
    with open(results_path, "w") as f:
        json.dump(results, f, indent=1)
    sys.stdout.flush()
    os._exit(0)
