"""Runs inside the bpy venv: a Rigify rig generated from the human meta-rig (RIGIFY.blend, made by
make_rigify.py), its controls keyed (the torso crouching and turning, the IK feet shuffling, the chest and
the head turning), then Check and Retime on it. ``python rigify_driver.py ADDON.zip RIGIFY.blend FOLDER
RESULTS.json``

Rigify parents its deform (DEF) bones to non-deform ORG bones, so most have no deform ancestor. FOLDER gets
the DEF bones' world heads on every source frame (source.npz) and on every output frame of linear bakes at
scale 0.5 and 0.7 (NAME.npz, NAME in SCALES); RESULTS.json says what the operators returned and what each bake
animates."""
import os
import sys

import bpy
import numpy as np

from _addon_script import bake_and_record, finish, install_addon, open_rig, world_heads

FRAMES = (1, 41)
SCALES = {"rigify_linear": 0.5, "rigify_between": 0.7}  # output frames on source frames; between them


def key_controls(rig):
    """Keys every 10 frames on a few controls: the IK legs, the spine and the neck follow."""
    pose = rig.pose.bones
    for k, frame in enumerate(range(FRAMES[0], FRAMES[1] + 1, 10)):
        s = np.sin(0.8 * k)
        pose["torso"].location = (0.03 * s, 0.0, -0.12 * abs(s))  # a crouch: the IK legs bend, never stretch
        pose["torso"].rotation_mode = "XYZ"
        pose["torso"].rotation_euler = (0.0, 0.0, 0.1 * s)
        pose["foot_ik.L"].location = (0.0, 0.02 * s, 0.0)
        pose["foot_ik.R"].location = (0.0, -0.02 * s, 0.0)
        pose["chest"].rotation_mode = pose["head"].rotation_mode = "XYZ"
        pose["chest"].rotation_euler = (0.05 * s, 0.0, -0.05 * s)
        pose["head"].rotation_euler = (0.0, 0.0, 0.3 * s)
        for name, path in [("torso", "location"), ("torso", "rotation_euler"), ("foot_ik.L", "location"),
                           ("foot_ik.R", "location"), ("chest", "rotation_euler"), ("head", "rotation_euler")]:
            pose[name].keyframe_insert(path, frame=frame)
    scene = bpy.context.scene
    scene.frame_start, scene.frame_end = FRAMES
    scene.render.fps, scene.render.fps_base = 30, 1.0


def main(zip_path, blend, folder, results_path):
    package = install_addon(zip_path)
    from importlib import import_module

    armature = import_module(package + ".armature")
    rig = open_rig(blend)
    key_controls(rig)
    names = [b.name for b in rig.data.bones if b.use_deform]
    original, slot = rig.animation_data.action, getattr(rig.animation_data, "action_slot", None)
    result = {"deform_bones": len(names), "bones": len(rig.data.bones), "drives_deform": armature.drives_deform(rig)}
    np.savez(os.path.join(folder, "source.npz"), heads=world_heads(rig, names, range(FRAMES[0], FRAMES[1] + 1)),
             names=np.array(names))
    try:
        result["check"] = sorted(bpy.ops.retime.check(exchange_folder=os.path.join(folder, "rigify_check")))
    except RuntimeError as e:  # the keyed motion is no physical one: what matters is that the rig is read
        result["check"] = str(e).strip()
    for name, scale in SCALES.items():
        armature.assign_action(rig, original, slot)
        result[name] = bake_and_record(rig, armature, names, folder, name, method="linear", scale=scale, apply="BAKE")
    finish(result, results_path)


if __name__ == "__main__":
    main(*sys.argv[1:5])
