"""An armature's animation in BVH's convention, and back to keys (runs inside Blender: bpy, mathutils, NumPy).

Shared by retime's FBX/glTF bridge and the Blender add-on (which ships a copy, see ``blender/build.py``).

BVH's convention here: Y up (the inverse of Blender's BVH importer, which maps BVH's Y to Blender's Z),
the rest pose has every local rotation the identity, a joint's local rotation is expressed in
world-aligned axes rather than the bone's own, offsets and positions are in scene units. The object's
world transform at the first frame is folded in, so a scaled or rotated armature object (an FBX's
0.01) comes out at the size and orientation the viewport shows. Joints whose head moves away from
where the rest pose puts it get position channels, so translating bones survive the trip.
"""
import re

import numpy as np

# Blender's Z-up world -> BVH's Y-up: (x, y, z) -> (x, z, -y)
TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
JOINT_CHANNELS = ROOT_CHANNELS[3:]
LINEAR = 1  # the enum value of Keyframe.interpolation 'LINEAR', for foreach_set


class ArmatureError(Exception):
    """A problem with the armature or its animation, said in one line the user can act on."""


def bvh_name(name: str) -> str:
    """A bone name as a BVH joint name (BVH names cannot hold white space)."""
    return re.sub(r"\s+", "_", name.strip()) or "_"


class Hierarchy:
    """An armature's bones in depth-first order (parents before children) with their rest matrices, and
    for writing poses back, every bone of the armature with the kept bone it moves with (``leaders``)."""

    def __init__(self, obj, keep_names=None):
        """Every bone, in one tree or refused; ``keep_names``: those bones alone (:func:`skeleton`: the
        deform skeleton), each under its nearest kept ancestor, and a kept bone with none but the topmost
        hanging from the kept bone nearest its head (:func:`_adopt`)."""
        def keep(b):
            return keep_names is None or b.name in keep_names

        def parent(b):
            p = b.parent
            while p is not None and not keep(p):
                p = p.parent
            return p

        def children(b):  # the kept bones whose nearest kept ancestor is b, in Blender's order
            out = []
            for c in b.children:
                out.extend([c] if keep(c) else children(c))
            return out

        roots = [b for b in obj.data.bones if keep(b) and parent(b) is None]
        what = "bones" if keep_names is None else "deform bones"
        if not roots:
            raise ArmatureError(f"armature {obj.name!r} has no {what}")
        adopted = {}  # bone name -> the deform bone it hangs from by geometry
        if keep_names is not None and len(roots) > 1:
            roots, adopted = _adopt(roots, [b for b in obj.data.bones if keep(b)], parent)
        if len(roots) > 1:
            names = ", ".join(repr(b.name) for b in roots[:4]) + (", ..." if len(roots) > 4 else "")
            raise ArmatureError(f"armature {obj.name!r} has {len(roots)} root {what} ({names}); retime needs one "
                                "hierarchy: parent them to a single root bone")
        foster = {}
        for name, p in adopted.items():
            foster.setdefault(p.name, []).append(obj.data.bones[name])
        order, stack = [], [roots[0]]
        kids = {}
        while stack:
            bone = stack.pop()
            order.append(bone)
            kids[bone.name] = children(bone) + foster.get(bone.name, [])
            stack.extend(reversed(kids[bone.name]))
        self.names = [b.name for b in order]
        index = {n: i for i, n in enumerate(self.names)}
        ups = [adopted.get(b.name) or parent(b) for b in order]
        self.parents = np.array([index[u.name] if u is not None else -1 for u in ups], dtype=int)
        self.leaders = _leaders(obj.data.bones, index)
        self.bvh_names = _unique([bvh_name(n) for n in self.names])
        self.rest = np.array([np.array(b.matrix_local, dtype=float) for b in order])  # (J, 4, 4) armature space
        self.tails = np.array([np.array(b.tail_local, dtype=float) for b in order])
        self.leaves = [j for j, b in enumerate(order) if not kids[b.name]]


def _leaders(bones, index):
    """Every bone of the armature (its name, its parent's name or None, its rest matrix) with the kept bone
    it moves with rigidly when poses are written back (its index in ``index``, the kept bones', or -1: at
    rest): itself when kept; else the kept bone nearest below it (a Rigify export's ORG and MCH bones above
    the DEF bones, so that a DEF bone connected to one is carried along), else the nearest kept above it."""
    out = []
    for b in bones:
        lead = index.get(b.name)
        frontier = list(b.children)
        while lead is None and frontier:  # breadth first: the nearest kept descendant, Blender's order on a tie
            lead = next((index[c.name] for c in frontier if c.name in index), None)
            frontier = [g for c in frontier for g in c.children]
        up = b.parent
        while lead is None and up is not None:
            lead, up = index.get(up.name), up.parent
        out.append((b.name, b.parent.name if b.parent else None, np.array(b.matrix_local, dtype=float),
                    -1 if lead is None else lead))
    return out


def _adopt(roots, bones, parent):
    """One tree from several deform roots (Rigify parents its DEF bones to non-deform ORG bones, so the
    thighs, the shoulders and the face have no deform ancestor): the topmost root (fewest ancestors; the
    first on a tie) stays the root, and the others, each with its deform subtree, hang from the bone
    whose rest segment (head to tail) passes nearest their head, the nearest first, so that no loop can
    form. Returns ([the root], {bone name: the bone it hangs from})."""
    def depth(b):
        n = 0
        while b.parent is not None:
            b, n = b.parent, n + 1
        return n

    def root_of(b):
        while parent(b) is not None:
            b = parent(b)
        return b.name

    top = min(roots, key=depth)
    group = np.array([root_of(b) for b in bones])
    heads = np.array([b.head_local for b in bones], dtype=float)
    axis = np.array([b.tail_local for b in bones], dtype=float) - heads
    length2 = np.maximum((axis * axis).sum(axis=1), 1e-18)
    waiting = [r for r in roots if r is not top]
    in_tree = group == top.name
    adopted = {}
    while waiting:
        points = np.array([r.head_local for r in waiting], dtype=float)  # (R, 3)
        rel = points[:, None] - heads[None, in_tree]  # (R, T, 3)
        t = np.clip((rel * axis[None, in_tree]).sum(-1) / length2[None, in_tree], 0.0, 1.0)
        gap = np.linalg.norm(rel - t[..., None] * axis[None, in_tree], axis=-1)
        r, k = np.unravel_index(int(np.argmin(gap)), gap.shape)
        orphan = waiting.pop(int(r))
        adopted[orphan.name] = bones[int(np.flatnonzero(in_tree)[k])]
        in_tree |= group == orphan.name
    return [top], adopted


def _unique(names):
    seen, out = {}, []
    for n in names:
        k = seen.get(n, 0)
        seen[n] = k + 1
        out.append(n if k == 0 else f"{n}.{k}")
    return out


def drives_deform(obj) -> bool:
    """Whether an armature has control bones beside its deform bones (Rigify and most hand-made rigs):
    then its body is the deform skeleton, posed by constraints and drivers from the controls."""
    bones = obj.data.bones
    return any(b.use_deform for b in bones) and not all(b.use_deform for b in bones)


def skinning_bones(obj) -> set:
    """The bones of armature ``obj`` that weight a mesh it deforms (an Armature modifier on it)."""
    import bpy

    names = set()
    for mesh in bpy.data.objects:
        if mesh.type != "MESH" or not any(m.type == "ARMATURE" and m.object is obj for m in mesh.modifiers):
            continue
        groups = {g.index: g.name for g in mesh.vertex_groups}
        names.update(groups[g.group] for v in mesh.data.vertices for g in v.groups if g.weight > 0 and g.group in groups)
    return names & {b.name for b in obj.data.bones}


def deform_bones(obj) -> set:
    """The bones that make the body: the deform bones when the armature has others beside them (a rig built
    in Blender: :func:`drives_deform`). When every bone is deform, as Blender's FBX and glTF importers mark
    them: every bone when they form one tree (an ordinary rig, read whole as it is written), else the bones
    that weight a mesh the armature deforms, when there is one (a game export of a Rigify character holds
    its DEF bones' non-deform ancestors too: ORG and MCH bones, the torso control, several roots)."""
    bones = obj.data.bones
    if drives_deform(obj):
        return {b.name for b in bones if b.use_deform}
    if sum(b.parent is None for b in bones) > 1:
        return skinning_bones(obj) or {b.name for b in bones}
    return {b.name for b in bones}


def skeleton(obj) -> Hierarchy:
    """The skeleton retime reads from an armature, one rule for the add-on and the FBX/glTF bridge: the
    :func:`deform_bones`, each under its nearest kept ancestor, several roots joined (the topmost stays the
    root, each other hangs with its subtree from the bone nearest its head at rest: :func:`_adopt`)."""
    return Hierarchy(obj, keep_names=deform_bones(obj))


def sample_pose(context, obj, frames, hierarchy=None):
    """The evaluated pose (after constraints and drivers) at each scene frame: bone pose matrices in
    armature space (F, J, 4, 4) and the object's world matrix (F, 4, 4), of ``hierarchy``'s bones (default:
    :func:`skeleton`). Moves the scene's current frame (the caller restores it)."""
    hierarchy = hierarchy or skeleton(obj)
    poses = np.empty((len(frames), len(hierarchy.names), 4, 4))
    world = np.empty((len(frames), 4, 4))
    scene = context.scene
    for k, frame in enumerate(frames):
        scene.frame_set(int(frame))
        evaluated = obj.evaluated_get(context.evaluated_depsgraph_get())
        world[k] = np.array(evaluated.matrix_world)
        bones = evaluated.pose.bones
        for j, name in enumerate(hierarchy.names):
            poses[k, j] = np.array(bones[name].matrix)
    return hierarchy, poses, world


def _rotation(m):
    """The rotation nearest (..., 3, 3) matrices that may carry a scale: the polar factor. A bone scaled
    along some axes (Rigify's squash and stretch) shears the children that inherit its scale in full (as
    FBX and glTF import them), and normalising their columns gave no rotation: the BVH then put the feet
    of an imported Rigify rig 2 cm off."""
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    flip = np.linalg.det(r) < 0  # a mirroring scale: keep a rotation
    if np.any(flip):
        u[flip, :, -1] *= -1
        r = u @ vt
    return r


def _uniform_scale(m3):
    s = np.linalg.norm(m3, axis=0)
    if np.ptp(s) > 1e-4 * s.max():
        raise ArmatureError(f"the armature object has a non-uniform scale {tuple(round(x, 4) for x in s)}; apply it "
                            "(Object > Apply > Scale) first")
    return float(s.mean())


class BvhPose:
    """An armature's animation in BVH's convention (see the module docstring)."""

    def __init__(self, hierarchy, poses, world):
        h, c = hierarchy, TO_Y_UP
        self.hierarchy = h
        scale = _uniform_scale(world[0, :3, :3])
        r0 = _rotation(world[0, :3, :3])
        rest_rot = _rotation(h.rest[:, :3, :3])
        g_arm = _rotation(poses[..., :3, :3]) @ np.swapaxes(rest_rot, -1, -2)  # rotation from the rest pose
        r_world = _rotation(world[:, :3, :3])
        g_world = r_world[:, None] @ g_arm @ r0.T
        heads = np.einsum("fab,fjb->fja", world[:, :3, :3], poses[..., :3, 3]) + world[:, None, :3, 3]
        g = c @ g_world @ c.T  # (F, J, 3, 3) global rotations, Y up
        heads = heads @ c.T
        p = h.parents
        rest_heads = (c @ (scale * r0) @ h.rest[:, :3, 3].T).T
        self.offsets = rest_heads - np.where(p[:, None] >= 0, rest_heads[np.maximum(p, 0)], 0.0)
        self.offsets[0] = 0.0  # the root's position channels carry its position
        self.end_sites = {j: (c @ (scale * r0) @ (h.tails[j] - h.rest[j, :3, 3])) for j in h.leaves}
        parent_g = np.where(p[None, :, None, None] >= 0, g[:, np.maximum(p, 0)], np.eye(3))
        self.rotations = np.swapaxes(parent_g, -1, -2) @ g  # local rotations (F, J, 3, 3)
        parent_heads = np.where(p[None, :, None] >= 0, heads[:, np.maximum(p, 0)], 0.0)
        self.positions = np.einsum("fjba,fjb->fja", parent_g, heads - parent_heads)  # in the parent's axes
        size = max(float(np.ptp(rest_heads, axis=0).max()), 1e-9)
        drift = np.abs(self.positions - self.offsets[None]).max(axis=(0, 2))
        self.translating = drift > 1e-5 * size
        self.translating[0] = True

    def channels(self, j):
        return ROOT_CHANNELS if self.translating[j] else JOINT_CHANNELS

    def text(self, fps: float) -> str:
        """The BVH file: hierarchy, then one line of channel values per frame."""
        h = self.hierarchy
        out = ["HIERARCHY"]
        children = {j: [int(c) for c in np.nonzero(h.parents == j)[0]] for j in range(len(h.names))}
        stack = [("open", 0, 0)]
        while stack:  # depth first without recursion: long chains must not hit Python's limit
            what, j, depth = stack.pop()
            ind = "\t" * depth
            if what == "close":
                if j in self.end_sites:
                    out += [f"{ind}\tEnd Site", f"{ind}\t{{", f"{ind}\t\tOFFSET {_fmt(self.end_sites[j])}", f"{ind}\t}}"]
                out.append(f"{ind}}}")
                continue
            out.append(f"{ind}{'ROOT' if j == 0 else 'JOINT'} {h.bvh_names[j]}")
            out += [f"{ind}{{", f"{ind}\tOFFSET {_fmt(self.offsets[j])}",
                    f"{ind}\tCHANNELS {len(self.channels(j))} {' '.join(self.channels(j))}"]
            stack.append(("close", j, depth))
            stack.extend(("open", c, depth + 1) for c in reversed(children[j]))
        n_frames = self.rotations.shape[0]
        out += ["MOTION", f"Frames: {n_frames}", f"Frame Time: {1.0 / fps:.10g}"]
        columns = []
        euler = np.rad2deg(euler_zxy(self.rotations))
        for j in range(len(h.names)):
            if self.translating[j]:
                columns.append(self.positions[:, j])
            columns.append(euler[:, j])
        values = np.concatenate(columns, axis=1)
        out += [" ".join(f"{v:.9g}" for v in row) for row in values]
        return "\n".join(out) + "\n"


def _fmt(v):
    return " ".join(f"{float(x):.9g}" for x in v)


def euler_zxy(m):
    """Rotation matrices (F, J, 3, 3) -> BVH's 'Zrotation Xrotation Yrotation' angles (F, J, 3), radians,
    R = Rz Rx Ry, unwrapped along the frames so that no angle jumps by a full turn."""
    x = np.arcsin(np.clip(m[..., 2, 1], -1.0, 1.0))
    z = np.arctan2(-m[..., 0, 1], m[..., 1, 1])
    y = np.arctan2(-m[..., 2, 0], m[..., 2, 2])
    return np.unwrap(np.stack([z, x, y], axis=-1), axis=0)


def quat_xyzw_to_matrix(q):
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def bone_bases(hierarchy, world0, rotations, translations):
    """The local (basis) matrices {bone name: (F, 4, 4)} of every bone of the armature that make it, its
    object at ``world0``, play BVH-convention poses: local rotations as quaternions (F, J, 4; x y z w) and
    translations (F, J, 3; the offset or the position channels) of the joints in ``hierarchy`` order. The
    inverse of BvhPose for the kept bones; each other bone moves rigidly with its leader
    (:func:`_leaders`)."""
    h, c = hierarchy, TO_Y_UP
    local = quat_xyzw_to_matrix(np.asarray(rotations, dtype=float))
    translations = np.asarray(translations, dtype=float)
    n_frames, n_joints = local.shape[:2]
    g = np.empty_like(local)
    heads = np.empty((n_frames, n_joints, 3))
    for j, p in enumerate(h.parents):  # forward kinematics, parents first
        if p < 0:
            g[:, j], heads[:, j] = local[:, j], translations[:, j]
        else:
            g[:, j] = g[:, p] @ local[:, j]
            heads[:, j] = heads[:, p] + np.einsum("fab,fb->fa", g[:, p], translations[:, j])
    scale = _uniform_scale(world0[:3, :3])
    r0 = _rotation(world0[:3, :3])
    g_arm = r0.T @ (c.T @ g @ c) @ r0  # back to Blender's axes, then to the armature's
    heads_arm = ((heads @ c) - world0[:3, 3]) @ r0 / scale
    pose = np.zeros((n_frames, n_joints, 4, 4))
    pose[..., :3, :3] = g_arm @ _rotation(h.rest[:, :3, :3])
    pose[..., :3, 3] = heads_arm
    pose[..., 3, 3] = 1.0
    lead_from_rest = pose @ np.linalg.inv(h.rest)  # (F, J, 4, 4): a kept bone's motion from its rest
    rest = {name: m for name, _, m, _ in h.leaders}
    posed = {name: lead_from_rest[:, k] @ m if k >= 0 else np.broadcast_to(m, (n_frames, 4, 4))
             for name, _, m, k in h.leaders}
    basis = {}
    for name, parent, m, _ in h.leaders:  # relative to where the parent puts the bone at rest
        under = posed[parent] @ np.linalg.inv(rest[parent]) @ m if parent is not None else m
        basis[name] = np.linalg.inv(under) @ posed[name]
    return basis


# -- actions across Blender versions: 4.4 made actions layered (slots and channelbags); 5.0 dropped the old API

def action_fcurves(action, slot=None):
    """The F-curves an action plays on the slot (Blender 4.4+) or its F-curves (4.2, 4.3)."""
    if action is None:
        return []
    if getattr(action, "is_action_layered", False):
        from bpy_extras import anim_utils

        slot = slot or (action.slots[0] if len(action.slots) else None)
        bag = anim_utils.action_get_channelbag_for_slot(action, slot)
        return list(bag.fcurves) if bag is not None else []
    return list(action.fcurves)


def new_action(obj, name):
    """A new empty action for ``obj``: (action, slot or None, the F-curve collection to add curves to)."""
    import bpy

    from bpy_extras import anim_utils

    action = bpy.data.actions.new(name)
    if hasattr(anim_utils, "action_ensure_channelbag_for_slot"):  # 4.4+ (4.3's slots were experimental)
        slot = action.slots.new(obj.id_type, obj.name)
        return action, slot, anim_utils.action_ensure_channelbag_for_slot(action, slot).fcurves
    return action, None, action.fcurves


def assign_action(obj, action, slot):
    adt = obj.animation_data or obj.animation_data_create()
    adt.action = action
    if slot is not None:
        adt.action_slot = slot


def write_curve(fcurves, data_path, index, group, frames, values):
    """A new F-curve keyed at every frame with linear interpolation."""
    try:
        fc = fcurves.new(data_path, index=index, group_name=group)  # 4.4+ channelbags
    except TypeError:
        fc = fcurves.new(data_path, index=index, action_group=group)
    n = len(frames)
    fc.keyframe_points.add(n)
    fc.keyframe_points.foreach_set("co", np.column_stack([frames, values]).astype(np.float32).ravel())
    fc.keyframe_points.foreach_set("interpolation", np.full(n, LINEAR, dtype=np.int32))
    fc.update()
    return fc


def frame_range(action):
    """An action's first and last frames, rounded to whole frames."""
    start, end = action.frame_range
    return int(round(start)), int(round(end))


def scene_fps(scene):
    """A scene's frame rate in frames per second."""
    return scene.render.fps / scene.render.fps_base


def set_scene_fps(scene, fps):
    """Set a scene's frame rate: whole frames per second over a base (29.97 = 30 / 1.001)."""
    scene.render.fps = max(1, round(fps))
    scene.render.fps_base = scene.render.fps / fps


# the rate an action's frames were captured or keyed at, where it is known: Blender keeps no such thing
# (a BVH imported without Update Scene FPS plays its frames at the scene's rate), so the Retime add-on
# writes it on the actions it makes, and a user or a script may set it (action["retime_source_fps"] = 120)
SOURCE_FPS = "retime_source_fps"


def source_fps(action):
    """The action's source frame rate when known, else None."""
    try:
        value = float(action.get(SOURCE_FPS, 0.0))
    except (TypeError, ValueError):
        return None
    return value if value > 0 else None


def rate_mismatch(scene, action):
    """The action's source rate when it is known and not the scene's (to 0.1%), else None."""
    known = source_fps(action) if action is not None else None
    if known is None or abs(known - scene_fps(scene)) <= 1e-3 * known:
        return None
    return known


def rotation_path(mode):
    """The pose bone (or object) property a rotation mode plays."""
    return {"QUATERNION": "rotation_quaternion", "AXIS_ANGLE": "rotation_axis_angle"}.get(mode, "rotation_euler")


def quaternions_to_mode(quats, mode, previous=None):
    """Rotations given as quaternions (F, 4; w x y z) as the values of the property rotation mode ``mode``
    plays (see :func:`rotation_path`): quaternions (F, 4) kept on the hemisphere of the previous frame's,
    for Blender interpolates the components; axis-angle (F, 4; angle, axis) of those; Euler angles (F, 3)
    in the order ``mode``, each frame's the nearest to the previous frame's, the first frame's the nearest
    to ``previous`` (Euler angles) when given."""
    from mathutils import Euler, Quaternion

    q = np.array([tuple(r) for r in quats], dtype=float).reshape(-1, 4)
    for k in range(1, len(q)):  # the sign nearer the previous frame's
        if np.dot(q[k], q[k - 1]) < 0:
            q[k] = -q[k]
    if mode == "QUATERNION":
        return q
    if mode == "AXIS_ANGLE":
        out = []
        for r in q:
            axis, angle = Quaternion(r).to_axis_angle()
            out.append((angle, *axis))
        return np.array(out).reshape(-1, 4)
    out, prev = [], None if previous is None else Euler(previous, mode)
    for r in q:
        prev = Quaternion(r).to_euler(mode, prev) if prev is not None else Quaternion(r).to_euler(mode)
        out.append(tuple(prev))
    return np.array(out).reshape(-1, 3)


def key_bone(fcurves, pose_bone, frames, locations, quaternions, scales=None):
    """Key a bone at ``frames``: locations (F, 3), rotations as quaternions (F, 4; w x y z) written in the
    bone's own rotation mode (see :func:`quaternions_to_mode`; Euler angles from the nearest to zero),
    scales (F, 3)."""
    name = pose_bone.name.replace("\\", "\\\\").replace('"', '\\"')
    path = f'pose.bones["{name}"].'
    mode = pose_bone.rotation_mode
    rot_path = rotation_path(mode)
    rot = quaternions_to_mode(quaternions, mode, previous=(0.0, 0.0, 0.0))
    for i in range(3):
        write_curve(fcurves, path + "location", i, pose_bone.name, frames, locations[:, i])
    for i in range(rot.shape[1]):
        write_curve(fcurves, path + rot_path, i, pose_bone.name, frames, rot[:, i])
    if scales is not None:
        for i in range(3):
            write_curve(fcurves, path + "scale", i, pose_bone.name, frames, scales[:, i])


def decompose(basis):
    """Basis matrices (F, 4, 4) -> locations (F, 3), quaternions (F, 4; w x y z), scales (F, 3)."""
    from mathutils import Matrix

    locs, quats, scales = [], [], []
    for m in basis:
        loc, rot, scale = Matrix(m.tolist()).decompose()
        locs.append(tuple(loc))
        quats.append(tuple(rot))
        scales.append(tuple(scale))
    return np.array(locs), np.array(quats), np.array(scales)
