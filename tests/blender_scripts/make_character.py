"""A character for the format tests: ``python make_character.py MOTION.bvh OUT.fbx|.glb|.gltf ...``

The BVH through Blender's importer (the scene at its frame rate), a mesh of one box per bone weighted to
that bone with an armature modifier, and a material; exported to each OUT."""
import os
import sys

import bpy

from _addon_script import skin_boxes

bvh, outs = sys.argv[1], sys.argv[2:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=bvh, update_scene_fps=True, update_scene_duration=True)
arm = bpy.context.active_object
skin_boxes(arm, [b.name for b in arm.data.bones])
for out in outs:
    if out.endswith(".fbx"):
        bpy.ops.export_scene.fbx(filepath=out, bake_anim_simplify_factor=0.0, add_leaf_bones=False)
    else:
        bpy.ops.export_scene.gltf(filepath=out, export_format="GLB" if out.endswith(".glb") else "GLTF_SEPARATE")
    print("wrote", out)
sys.stdout.flush()
os._exit(0)
