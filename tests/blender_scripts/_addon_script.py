"""What the scripts that drive the add-on share: a fresh scene with the add-on installed as a user would,
the bones' world heads as the scene plays, and the ending (results as JSON, then an exit that skips bpy's
slow teardown)."""
import json
import os
import sys

import bpy
import numpy as np


def install_addon(zip_path):
    """An empty factory scene with the add-on zip installed and enabled; returns the add-on's module name."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    return next(a.module for a in bpy.context.preferences.addons if a.module.endswith(".retime"))


def open_rig(blend, name="rig"):
    """Open ``blend`` (the add-on stays installed: it lives in the preferences) and make the armature
    ``name`` the active and only selected object."""
    bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False)
    rig = bpy.data.objects[name]
    for obj in bpy.context.scene.objects:
        obj.select_set(obj is rig)
    bpy.context.view_layer.objects.active = rig
    return rig


def skin_boxes(arm, bones):
    """A mesh ("Body") of one box per bone of ``bones`` (names; those longer than 0.1 mm), weighted to that
    bone, deformed by ``arm`` through an Armature modifier, with a material; returns the mesh object."""
    verts, faces, groups = [], [], []
    for bone in (arm.data.bones[n] for n in bones):
        if bone.length < 1e-4:
            continue
        head, tail = bone.head_local, bone.tail_local
        axis = tail - head
        r = 0.1 * bone.length
        base = len(verts)
        side = axis.orthogonal().normalized() * r
        up = axis.normalized().cross(side)
        for p in (head, tail):
            for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
                verts.append(p + a * side + b * up)
        faces += [tuple(base + i for i in f) for f in ((0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2),
                                                       (2, 6, 7, 3), (3, 7, 4, 0))]
        groups.append((bone.name, list(range(base, base + 8))))
    mesh = bpy.data.meshes.new("Body")
    mesh.from_pydata([tuple(v) for v in verts], [], [tuple(f) for f in faces])
    body = bpy.data.objects.new("Body", mesh)
    bpy.context.scene.collection.objects.link(body)
    for name, idx in groups:
        body.vertex_groups.new(name=name).add(idx, 1.0, "REPLACE")
    body.parent = arm
    body.modifiers.new("Armature", "ARMATURE").object = arm
    material = bpy.data.materials.new("Skin")
    material.diffuse_color = (0.8, 0.3, 0.2, 1.0)
    mesh.materials.append(material)
    return body


def world_heads(arm, names, frames):
    """(frames, bones, 3): the world heads of the bones ``names`` of ``arm`` on each scene frame, as evaluated."""
    out = np.empty((len(frames), len(names), 3))
    for k, f in enumerate(frames):
        bpy.context.scene.frame_set(int(f))
        ev = arm.evaluated_get(bpy.context.evaluated_depsgraph_get())
        for j, n in enumerate(names):
            out[k, j] = ev.matrix_world @ ev.pose.bones[n].head
    return out


def bake_and_record(arm, armature, names, folder, name, **op):
    """Retime the armature's action with ``op`` (a Bake), keeping retime's files in FOLDER/NAME; the world
    heads of the bones ``names`` on every output frame go to FOLDER/NAME.npz. Returns the operator's status
    and the bones the baked action animates. ``armature``: the add-on's armature module."""
    status = sorted(bpy.ops.retime.retime(**op, exchange_folder=os.path.join(folder, name)))
    baked = arm.animation_data.action
    start, end = (int(round(f)) for f in baked.frame_range)
    frames = list(range(start, end + 1))
    np.savez(os.path.join(folder, name + ".npz"), heads=world_heads(arm, names, frames), names=np.array(names),
             frames=np.array(frames))
    return {"status": status, "animated": sorted({fc.data_path.split('"')[1] for fc in armature.action_fcurves(baked)})}


def finish(results, results_path, indent=None):
    """Write ``results`` to ``results_path`` and leave at once."""
    with open(results_path, "w") as f:
        json.dump(results, f, indent=indent)
    sys.stdout.flush()
    os._exit(0)
