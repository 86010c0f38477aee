"""Runs inside the bpy venv: install the add-on zip, import a BVH, and play Check twice, then Clear.
``python check_driver.py ADDON.zip MOTION.bvh FOLDER RESULTS.json``

RESULTS.json: the operator's status and report, the first frame, the residual curve evaluated on every
frame, the timeline markers, each check object's world matrix column 3 (an arrow's +Z, its length the
force) and location on every frame (read back by playing the scene), the force length, what the second
run and Clear left, and whether the character's action kept every key."""
import os
import sys

import bpy

from _addon_script import finish, install_addon

ARROWS = ("Retime Force left", "Retime Force right", "Retime Residual Force")
POINTS = ("Retime Centre of Mass", "Retime CoM Ground")


def keys(action, package):
    from importlib import import_module

    curves = import_module(package + ".armature").action_fcurves(action)
    return [(fc.data_path, fc.array_index, [tuple(k.co) for k in fc.keyframe_points]) for fc in curves]


def made():
    """What a check made, by name: objects, collections, actions, markers."""
    return {"objects": sorted(o.name for o in bpy.data.objects if o.get("retime_check")),
            "collections": sorted(c.name for c in bpy.data.collections if c.get("retime_check")),
            "actions": sorted(a.name for a in bpy.data.actions if a.get("retime_check")),
            "markers": sorted((m.name, m.frame) for m in bpy.context.scene.timeline_markers)}


def played(start, end):
    """Every check object's world matrix on every frame, as the scene plays it."""
    scene = bpy.context.scene
    out = {name: {"z": [], "location": []} for name in ARROWS + POINTS}
    for frame in range(start, end + 1):
        scene.frame_set(frame)
        for name in out:
            m = bpy.data.objects[name].matrix_world
            out[name]["z"].append(list(m.col[2][:3]))
            out[name]["location"].append(list(m.translation))
    return out


def main(zip_path, bvh, folder, results_path):
    package = install_addon(zip_path)
    bpy.ops.import_anim.bvh(filepath=bvh, update_scene_fps=True, update_scene_duration=True)
    arm = bpy.context.active_object
    action = arm.animation_data.action
    before = keys(action, package)
    bpy.context.scene.timeline_markers.new("96", frame=150)  # a keytime marker of the user's stays
    start, end = (int(round(f)) for f in action.frame_range)
    result = {"start": start, "end": end}
    result["status"] = sorted(bpy.ops.retime.check(exchange_folder=os.path.join(folder, "first")))
    helper = bpy.data.objects["Retime Check"]
    curve = helper.animation_data.action
    from importlib import import_module

    fcurves = import_module(package + ".armature").action_fcurves(curve)
    residual = next(fc for fc in fcurves if fc.data_path == '["residual"]')
    result["residual_curve"] = [residual.evaluate(f) for f in range(start, end + 1)]
    bpy.context.scene.frame_set(start + 10)
    result["residual_played"] = [start + 10, helper["residual"]]
    result["force_length"] = helper["force_length"]
    result["first"] = made()
    result["played"] = played(start, end)
    result["in_collection"] = sorted(o.name for o in bpy.data.collections["Retime Check"].objects)
    result["status_again"] = sorted(bpy.ops.retime.check(force_length=2.0))
    result["again"] = made()
    result["force_length_again"] = bpy.data.objects["Retime Check"]["force_length"]
    bpy.ops.retime.clear_check()
    result["cleared"] = made()
    result["action_untouched"] = arm.animation_data.action == action and keys(action, package) == before
    arm.select_set(False)
    bpy.context.view_layer.objects.active = None
    try:
        bpy.ops.retime.check()
        result["no_armature"] = "ran"
    except RuntimeError as e:
        result["no_armature"] = str(e).strip()
    result["registered"] = sorted(bpy.ops.retime.check.get_rna_type().properties.keys())
    finish(result, results_path)


if __name__ == "__main__":
    main(*sys.argv[1:5])
