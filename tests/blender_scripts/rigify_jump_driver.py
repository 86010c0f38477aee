"""Runs inside the bpy venv: the Rigify rig of RIGIFY.blend (make_rigify.py) animated as an animator would
with a motion capture: its controls (the torso and the IK feet; the arms in FK, carried by the chest)
constrained to CMU 16_06 imported from BVH, baked with visual keying and the constraints removed; then Check, the add-on's physics Retime (Bake)
and an FBX export of the baked rig. ``python rigify_jump_driver.py ADDON.zip RIGIFY.blend MOTION.bvh FOLDER
RESULTS.json``

FOLDER gets the DEF bones' world heads on every source frame (source.npz) and on every output frame of the
physics bake (physics.npz), retime's files of each run (FOLDER/check, FOLDER/physics) and the baked rig, a
mesh skinned to its DEF bones, as a game export has it: FBX of the deform bones (rigify.fbx: Blender keeps
their ORG and MCH ancestors too) and glTF (rigify.glb: the DEF bones alone, 98 roots), with the DEF bones'
world heads as Blender plays each file imported (NAME.npz); RESULTS.json says what the
operators returned, the residual curve Check keyed, and what the bake animates."""
import os
import sys

import bpy
import numpy as np
from mathutils import Matrix

from _addon_script import bake_and_record, finish, install_addon, open_rig, skin_boxes, world_heads

FPS = 60  # the scene's rate: the capture's 120 Hz halved (the BVH importer scales its keys to it)
SCALE = 0.8  # the physics retime: 0.8 of the duration
# each control follows the capture's joint that plays its part, relative to the first frame, where the rig
# stands in its rest pose: the torso the pelvis, the IK feet the ankles. The IK hands are left out: the
# capture's wrists, moved from the rig's rest hands, pass out of the rig's reach, where IK turns the elbow
# fast between frames (3.3e-3 of the height off retime's interpolation of the deform skeleton)
FOLLOW = {"torso": "root", "foot_ik.L": "lfoot", "foot_ik.R": "rfoot"}
# the torso 4 cm lower than the rig's rest, whose legs are straight but for 4 mm: the capture's straighten
# further at take-off and landing, and a leg at the end of its reach bends fast between frames
LOWER = {"torso": Matrix.Translation((0.0, 0.0, -0.04)), "foot_ik.L": Matrix(), "foot_ik.R": Matrix()}


def select_bones(rig, names):
    for bone in rig.pose.bones:
        (bone if hasattr(bone, "select") else bone.bone).select = bone.name in names  # 5.0 selects pose bones


def constrain_and_bake(rig, bvh):
    """Import ``bvh``, constrain the controls to it (Child Of, set at the first frame), bake them with visual
    keying, remove the constraints and the capture; returns the baked frame range."""
    scene = bpy.context.scene
    scene.render.fps, scene.render.fps_base = FPS, 1.0
    bpy.ops.import_anim.bvh(filepath=bvh, use_fps_scale=True, update_scene_fps=False, frame_start=1)
    capture = bpy.context.active_object
    start, end = (int(round(f)) for f in capture.animation_data.action.frame_range)
    scene.frame_start, scene.frame_end = start, end
    scene.frame_set(start)
    hips = capture.matrix_world @ capture.pose.bones["root"].head
    torso = rig.matrix_world @ rig.pose.bones["torso"].head
    capture.location.x += torso.x - hips.x  # the capture's pelvis over the rig's, so that its turns turn the rig
    capture.location.y += torso.y - hips.y  # about its own hips
    bpy.context.view_layer.update()
    for side in "LR":
        rig.pose.bones[f"thigh_parent.{side}"]["IK_Stretch"] = 0.0  # legs keep their length where the capture's reach further
        rig.pose.bones[f"upper_arm_parent.{side}"]["IK_FK"] = 1.0  # FK arms, their controls at rest
    for control, joint in FOLLOW.items():
        c = rig.pose.bones[control].constraints.new("CHILD_OF")
        c.name = "follow capture"
        c.target, c.subtarget = capture, joint
        c.inverse_matrix = (capture.matrix_world @ capture.pose.bones[joint].matrix).inverted() @ LOWER[control]
    for obj in scene.objects:
        obj.select_set(obj is rig)
    bpy.context.view_layer.objects.active = rig
    bpy.ops.object.mode_set(mode="POSE")
    select_bones(rig, FOLLOW)
    bpy.ops.nla.bake(frame_start=start, frame_end=end, only_selected=True, visual_keying=True,
                     clear_constraints=False, bake_types={"POSE"})
    for control in FOLLOW:
        bone = rig.pose.bones[control]
        bone.constraints.remove(bone.constraints["follow capture"])
    bpy.ops.object.mode_set(mode="OBJECT")
    bpy.data.objects.remove(capture)
    return start, end


def residual_curve(armature, start, end):
    helper = bpy.data.objects["Retime Check"]
    curve = next(fc for fc in armature.action_fcurves(helper.animation_data.action) if fc.data_path == '["residual"]')
    return [curve.evaluate(f) for f in range(start, end + 1)]


def main(zip_path, blend, bvh, folder, results_path):
    package = install_addon(zip_path)
    from importlib import import_module

    armature = import_module(package + ".armature")
    rig = open_rig(blend)
    start, end = constrain_and_bake(rig, bvh)
    names = [b.name for b in rig.data.bones if b.use_deform]
    np.savez(os.path.join(folder, "source.npz"), heads=world_heads(rig, names, range(start, end + 1)),
             names=np.array(names))
    original = rig.animation_data.action
    result = {"start": start, "end": end, "deform_bones": len(names), "controls": sorted(FOLLOW)}
    result["check"] = sorted(bpy.ops.retime.check(exchange_folder=os.path.join(folder, "check")))
    result["residual_curve"] = residual_curve(armature, start, end)
    body = skin_boxes(rig, names)
    body.select_set(True)
    bpy.ops.export_scene.fbx(filepath=os.path.join(folder, "rigify.fbx"), use_selection=True,
                             object_types={"ARMATURE", "MESH"}, use_armature_deform_only=True, add_leaf_bones=False,
                             bake_anim=True, bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False,
                             bake_anim_simplify_factor=0.0)
    bpy.ops.export_scene.gltf(filepath=os.path.join(folder, "rigify.glb"), use_selection=True, export_def_bones=True,
                              export_animation_mode="ACTIVE_ACTIONS", export_force_sampling=True)
    bpy.data.objects.remove(body)
    result["physics"] = bake_and_record(rig, armature, names, folder, "physics", method="physics", scale=SCALE,
                                        apply="BAKE")
    result["original_kept"] = original.name in bpy.data.actions and rig.animation_data.action is not original
    for name in ("rigify.fbx", "rigify.glb"):  # the exports as Blender plays them, imported
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.context.scene.render.fps = FPS
        path = os.path.join(folder, name)
        if name.endswith(".fbx"):
            bpy.ops.import_scene.fbx(filepath=path, anim_offset=0.0)
        else:
            bpy.ops.import_scene.gltf(filepath=path)
        imported = next(o for o in bpy.context.scene.objects if o.type == "ARMATURE")
        np.savez(os.path.join(folder, name + ".npz"), heads=world_heads(imported, names, range(start, end + 1)),
                 names=np.array(names))
    finish(result, results_path)


if __name__ == "__main__":
    main(*sys.argv[1:6])
