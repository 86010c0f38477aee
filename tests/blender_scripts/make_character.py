"""A character for the format tests: ``python make_character.py MOTION.bvh OUT.fbx|.glb|.gltf ...``

The BVH through Blender's importer (the scene at its frame rate), a mesh of one box per bone weighted to
that bone with an armature modifier, and a material; exported to each OUT."""
import os
import sys

import bpy

bvh, outs = sys.argv[1], sys.argv[2:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_anim.bvh(filepath=bvh, update_scene_fps=True, update_scene_duration=True)
arm = bpy.context.active_object
verts, faces, groups = [], [], []
for bone in arm.data.bones:
    if bone.length < 1e-4:
        continue
    head, tail = bone.head_local, bone.tail_local
    axis = (tail - head)
    r = 0.1 * bone.length
    base = len(verts)
    side = axis.orthogonal().normalized() * r
    up = axis.normalized().cross(side)
    for p in (head, tail):
        for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
            verts.append(p + a * side + b * up)
    faces += [tuple(base + i for i in f) for f in ((0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 4, 0))]
    groups.append((bone.name, list(range(base, base + 8))))
mesh = bpy.data.meshes.new("Body")
mesh.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
body = bpy.data.objects.new("Body", mesh)
bpy.context.scene.collection.objects.link(body)
for name, idx in groups:
    body.vertex_groups.new(name=name).add(idx, 1.0, "REPLACE")
body.parent = arm
mod = body.modifiers.new("Armature", "ARMATURE")
mod.object = arm
mat = bpy.data.materials.new("Skin")
mat.diffuse_color = (0.8, 0.3, 0.2, 1.0)
mesh.materials.append(mat)
for out in outs:
    if out.endswith(".fbx"):
        bpy.ops.export_scene.fbx(filepath=out, bake_anim_simplify_factor=0.0, add_leaf_bones=False)
    else:
        bpy.ops.export_scene.gltf(filepath=out, export_format="GLB" if out.endswith(".glb") else "GLTF_SEPARATE")
    print("wrote", out)
sys.stdout.flush()
os._exit(0)
