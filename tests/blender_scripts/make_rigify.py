"""Runs inside the bpy venv: a Rigify rig generated from the human meta-rig (Blender ships Rigify), saved
alone (the meta-rig removed) for the Rigify tests to open. ``python make_rigify.py OUT.blend``"""
import os
import sys

import bpy


def main(out):
    import addon_utils  # importable once bpy is

    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon_utils.enable("rigify", default_set=True)
    bpy.ops.object.armature_human_metarig_add()
    metarig = bpy.context.active_object
    bpy.ops.pose.rigify_generate()
    rig = bpy.context.active_object
    bpy.data.objects.remove(metarig)
    rig.name = "rig"
    bpy.ops.wm.save_as_mainfile(filepath=out)
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main(sys.argv[1])
