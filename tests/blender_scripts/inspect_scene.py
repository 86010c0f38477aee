"""What a file holds once Blender imports it: ``python inspect_scene.py FILE OUT.json`` writes the meshes
(vertices, polygons, vertex groups, the armature deforming them, materials), the armatures (bones, the action's
frame range, keys where the file has them: FBX imported without Blender's default one-frame offset) and
the scene's frame rate."""
import json
import os
import sys

import bpy

path, out = sys.argv[1:3]
bpy.ops.wm.read_factory_settings(use_empty=True)
if path.lower().endswith(".fbx"):
    bpy.ops.import_scene.fbx(filepath=path, anim_offset=0.0)
elif path.lower().endswith(".bvh"):
    bpy.ops.import_anim.bvh(filepath=path, update_scene_fps=True)
else:
    bpy.context.scene.render.fps = int(sys.argv[3]) if len(sys.argv) > 3 else 24
    bpy.ops.import_scene.gltf(filepath=path)
scene = bpy.context.scene
meshes, armatures = {}, {}
for obj in scene.objects:
    if obj.type == "MESH":
        deform = [m.object.name for m in obj.modifiers if m.type == "ARMATURE" and m.object]
        meshes[obj.data.name] = {"vertices": len(obj.data.vertices), "polygons": len(obj.data.polygons),
                                 "groups": len(obj.vertex_groups),
                                 "deformed_by_armature": bool(deform),
                                 "materials": sorted(m.name for m in obj.data.materials if m)}
    elif obj.type == "ARMATURE":
        action = obj.animation_data.action if obj.animation_data else None
        armatures[obj.name] = {"bones": len(obj.data.bones),
                               "frame_range": list(action.frame_range) if action else None}
json.dump({"meshes": meshes, "armatures": armatures, "fps": scene.render.fps / scene.render.fps_base},
          open(out, "w"), indent=1)
sys.stdout.flush()
os._exit(0)
