"""Runs inside the bpy venv: a rig whose controls drive its deform skeleton through constraints, then Check
and Retime on it. ``python rig_driver.py ADDON.zip MOTION.bvh FOLDER RESULTS.json``

The rig: the BVH's armature (its bones deform) with a non-deform control bone "CTRL-X" beside every bone
X (same rest, the controls' own hierarchy), X copying CTRL-X's world transform, and the action moved onto
the controls, so that only constraints pose the deform bones (Rigify's layout, small). Per case, the deform
bones' world heads on every output frame go to FOLDER/NAME.npz; RESULTS.json says what the baked actions
animate."""
import os
import sys

import bpy

from _addon_script import bake_and_record, finish, install_addon

CASES = {"linear_rig": {"method": "linear", "scale": 0.5, "apply": "BAKE"},
         "physics_rig": {"method": "physics", "scale": 0.5, "apply": "BAKE"}}


def controlled_rig(bvh, fcurves_of):
    bpy.ops.import_anim.bvh(filepath=bvh, update_scene_fps=True, update_scene_duration=True)
    arm = bpy.context.active_object
    names = [b.name for b in arm.data.bones]
    bpy.ops.object.mode_set(mode="EDIT")
    edit = arm.data.edit_bones
    for name in names:
        b = edit[name]
        c = edit.new("CTRL-" + name)
        c.head, c.tail, c.roll, c.use_deform = b.head, b.tail, b.roll, False
    for name in names:
        if edit[name].parent is not None:
            edit["CTRL-" + name].parent = edit["CTRL-" + edit[name].parent.name]
    bpy.ops.object.mode_set(mode="OBJECT")
    for name in names:
        bone, ctrl = arm.pose.bones[name], arm.pose.bones["CTRL-" + name]
        ctrl.rotation_mode = bone.rotation_mode
        con = bone.constraints.new("COPY_TRANSFORMS")
        con.target, con.subtarget = arm, ctrl.name
    action = arm.animation_data.action
    for fc in fcurves_of(action):
        bone = fc.data_path.split('"')[1]
        fc.data_path = fc.data_path.replace(f'pose.bones["{bone}"]', f'pose.bones["CTRL-{bone}"]')
    bpy.context.scene.frame_set(bpy.context.scene.frame_current)
    return arm, names


def main(zip_path, bvh, folder, results_path):
    package = install_addon(zip_path)
    from importlib import import_module

    armature = import_module(package + ".armature")
    arm, names = controlled_rig(bvh, armature.action_fcurves)
    original, original_slot = arm.animation_data.action, getattr(arm.animation_data, "action_slot", None)
    result = {"drives_deform": armature.drives_deform(arm)}
    try:
        armature.Hierarchy(arm)  # every bone: two roots, the deform one and the controls'
        result["all_bones"] = "ok"
    except armature.ArmatureError as e:
        result["all_bones"] = str(e)
    result["check"] = sorted(bpy.ops.retime.check(exchange_folder=os.path.join(folder, "rig_check")))
    for name, op in CASES.items():
        armature.assign_action(arm, original, original_slot)
        result[name] = bake_and_record(arm, armature, names, folder, name, **op)
    finish(result, results_path)


if __name__ == "__main__":
    main(*sys.argv[1:5])
