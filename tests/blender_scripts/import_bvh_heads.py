"""Blender's own BVH importer on retime's output: ``python import_bvh_heads.py BVH OUT.npz [BVH OUT.npz ...]``
writes each bone's world head position on every frame ("heads", Blender's axes), the bone "names" and the
scene's "fps" after the import."""
import os
import sys

import bpy
import numpy as np

args = sys.argv[1:]
for bvh, out in zip(args[::2], args[1::2]):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_anim.bvh(filepath=bvh, update_scene_fps=True, update_scene_duration=True)
    arm = bpy.context.active_object
    start, end = (int(round(f)) for f in arm.animation_data.action.frame_range)
    names = [b.name for b in arm.pose.bones]
    heads = np.empty((end - start + 1, len(names), 3))
    for k, frame in enumerate(range(start, end + 1)):
        bpy.context.scene.frame_set(frame)
        for j, name in enumerate(names):
            heads[k, j] = arm.matrix_world @ arm.pose.bones[name].head
    scene = bpy.context.scene
    np.savez(out, heads=heads, names=np.array(names), fps=scene.render.fps / scene.render.fps_base)
sys.stdout.flush()
os._exit(0)
