"""The Check operator: the active armature's action -> BVH -> ``retime check --report`` -> what the report
says, shown in the scene beside the character (McCann et al. 2006, sec. 6: force visualization in
animation software). Its own collection "Retime Check" holds:

* the helper empty "Retime Check" with the custom property ``residual`` (body weights of force no
  contact can give) keyed on every frame: select it and the Graph Editor shows the curve;
* an arrow per foot, "Retime Force left" / "right", at the foot's centre of pressure, pointing along
  its contact force and as long as it (``force_length`` scene units per body weight, kept on the
  helper), and "Retime Residual Force", the force no contact gives, at the centre of mass;
* the centre of mass, "Retime Centre of Mass", and its ground projection, "Retime CoM Ground";

plus timeline markers named ``check: ...`` at the worst frames and where the residual goes over the
threshold. The character's action is never touched; a new check replaces all of this and Clear
removes it. Report frame i is the action's frame start + i; the BVH's axes are Blender's turned Y up
(:data:`armature.TO_Y_UP`) and its unit the scene's."""
import json
import os

import bpy
import numpy as np

from . import armature
from .operator import ArmatureJob, export_bvh
from .runner import BackgroundRunOperator, RetimeAddonError, Run

COLLECTION = "Retime Check"
TAG = "retime_check"  # custom property on every object, action and the collection a check made
MARKER = "check: "
FEET = ("left", "right")
HELPER, COM, GROUND, RESIDUAL_ARROW = "Retime Check", "Retime Centre of Mass", "Retime CoM Ground", "Retime Residual Force"


def arrow_name(foot):
    return f"Retime Force {foot}"


def to_blender(vectors):
    """(..., 3) vectors in the exported BVH's axes -> Blender's world axes."""
    return np.asarray(vectors, dtype=float) @ armature.TO_Y_UP


class CheckJob(ArmatureJob):
    """One check of one armature's action: export, run, show."""

    def __init__(self, context, props):
        super().__init__(context, props, "check")
        if self.end - self.start < 3:
            raise RetimeAddonError(f"the action {self.action.name!r} has {self.end - self.start + 1} frames; "
                                   "checking needs at least 4")
        self._program_and_folder("retime-check-")

    @property
    def doing(self):
        return f"checking {self.action.name!r}"

    def launch(self, context):
        source = os.path.join(self.folder, "source.bvh")
        export_bvh(context, self.obj, self.action, self.slot, (self.start, self.end), self.fps, source)
        self.report_path = os.path.join(self.folder, "check.json")
        self.run = Run([self.executable, "check", source, "--report", self.report_path], self.folder)

    def finish(self, context):
        """Read the report and show it; returns the report's type (a warning when not physical) and the
        one-line verdict."""
        self.run.result(success=(0, 1, 3))  # 1: not physical, 3: physical with a caution; the report is written all the same
        try:
            with open(self.report_path) as f:
                report = json.load(f)
        except (OSError, ValueError) as e:
            raise RetimeAddonError(f"retime check wrote no readable report {self.report_path}: {e}") from None
        length = self.props.force_length or default_force_length(context, self.obj)
        show(context, report, self.start, length, self.action.name)
        said = " ".join(f"Check {self.action.name!r}: {report['verdict']}".split())
        return {"INFO"} if report["summary"]["physical"] else {"WARNING"}, said


def default_force_length(context, obj):
    """Scene units per body weight for the arrows: half the armature's height on the current frame."""
    ev = obj.evaluated_get(context.evaluated_depsgraph_get())
    z = [(ev.matrix_world @ b.head).z for b in ev.pose.bones] + [(ev.matrix_world @ b.tail).z for b in ev.pose.bones]
    return max(0.5 * (max(z) - min(z)), 1e-3) if z else 1.0


# -- what a check leaves in the scene -------------------------------------------------------------------

def clear(scene):
    """Remove everything a check made: its objects, their actions, the collection, the markers."""
    for obj in [o for o in bpy.data.objects if o.get(TAG)]:
        action = obj.animation_data.action if obj.animation_data else None
        bpy.data.objects.remove(obj)
        if action is not None and action.get(TAG) and action.users == 0:
            bpy.data.actions.remove(action)
    for action in [a for a in bpy.data.actions if a.get(TAG) and a.users == 0]:
        bpy.data.actions.remove(action)
    for coll in [c for c in bpy.data.collections if c.get(TAG)]:
        bpy.data.collections.remove(coll)
    for marker in [m for m in scene.timeline_markers if m.name.startswith(MARKER)]:
        scene.timeline_markers.remove(marker)


def _collection(scene):
    coll = bpy.data.collections.new(COLLECTION)
    coll[TAG] = True
    scene.collection.children.link(coll)
    return coll


def _empty(coll, name, display, size):
    obj = bpy.data.objects.new(name, None)
    obj.empty_display_type, obj.empty_display_size = display, size
    obj[TAG] = True
    coll.objects.link(obj)
    return obj


def _key(obj, frames, curves):
    """A new action on ``obj`` with a linear key per frame for each (data path, index, values)."""
    action, slot, fcurves = armature.new_action(obj, f"{obj.name} (check)")
    action[TAG] = True
    for path, index, values in curves:
        armature.write_curve(fcurves, path, index, obj.name, frames, values)
    armature.assign_action(obj, action, slot)


def arrow_keys(vectors, length):
    """Per frame, the rotation (w, x, y, z) turning +Z along the vector, and the scale making an arrow
    of display size 1 as long as ``length`` times the vector; a zero vector keeps the last rotation and
    scales to nothing. Consecutive rotations keep one sign, so that Blender's blend of keys is a turn."""
    from mathutils import Vector

    up = Vector((0.0, 0.0, 1.0))
    quats, scales = np.empty((len(vectors), 4)), np.empty(len(vectors))
    last = np.array([1.0, 0.0, 0.0, 0.0])
    for k, v in enumerate(vectors):
        size = float(np.linalg.norm(v))
        if size > 1e-9:
            q = np.array(tuple(up.rotation_difference(Vector(tuple(v / size)))))
            last = -q if np.dot(q, last) < 0 else q
        quats[k], scales[k] = last, size * length
    return quats, scales


def _key_arrow(obj, frames, points, vectors, length):
    quats, scales = arrow_keys(vectors, length)
    obj.rotation_mode = "QUATERNION"
    _key(obj, frames, [("location", i, points[:, i]) for i in range(3)]
         + [("rotation_quaternion", i, quats[:, i]) for i in range(4)]
         + [("scale", i, scales) for i in range(3)])


def _marker_frames(residual, worst, threshold):
    """(frame index, label): the worst frames, then the first frame of each run over the threshold."""
    out = [(int(i), f"{MARKER}worst {residual[i]:.2f} bw") for i in worst]
    over = np.r_[False, residual > threshold, False]
    starts, ends = np.flatnonzero(over[1:] & ~over[:-1]), np.flatnonzero(~over[1:] & over[:-1])
    taken = {i for i, _ in out}
    for a, b in zip(starts, ends):
        if a not in taken:
            out.append((int(a), f"{MARKER}over {threshold:g} bw for {b - a} frames"))
    return out


def show(context, report, start, length, label):
    """Put the report in the scene (see the module docstring), replacing a previous check's."""
    scene = context.scene
    clear(scene)
    rows = report["frames"]
    frames = start + np.array([r["frame"] for r in rows], dtype=float)
    residual = np.array([r["residual"] for r in rows])
    coll = _collection(scene)
    helper = _empty(coll, HELPER, "PLAIN_AXES", 0.1 * length)
    helper["residual"] = 0.0
    helper.id_properties_ui("residual").update(description="Force no contact can give (body weights)", min=0.0)
    helper["force_length"] = float(length)
    helper["checked_action"] = label
    _key(helper, frames, [('["residual"]', 0, residual)])
    com = to_blender([r["com"] for r in rows])
    _key(_empty(coll, COM, "SPHERE", 0.05 * length), frames, [("location", i, com[:, i]) for i in range(3)])
    forces = {foot: to_blender([r["foot_force"][foot] for r in rows]) for foot in FEET}
    points = {foot: to_blender([r["foot_point"][foot] for r in rows]) for foot in FEET}
    loaded = np.concatenate([points[f][forces[f][:, 2] > 0.05, 2] for f in FEET])
    floor = float(np.median(loaded)) if loaded.size else float(com[:, 2].min() - length)
    ground = np.column_stack([com[:, 0], com[:, 1], np.full(len(com), floor)])
    _key(_empty(coll, GROUND, "CIRCLE", 0.08 * length), frames, [("location", i, ground[:, i]) for i in range(3)])
    for foot in FEET:
        _key_arrow(_empty(coll, arrow_name(foot), "SINGLE_ARROW", 1.0), frames, points[foot], forces[foot], length)
    _key_arrow(_empty(coll, RESIDUAL_ARROW, "SINGLE_ARROW", 1.0), frames, com,
               to_blender([r["residual_force"] for r in rows]), length)
    threshold = float(report["residual_threshold"])
    for i, name in _marker_frames(residual, report["summary"]["worst_frames"], threshold):
        scene.timeline_markers.new(name, frame=int(start + i))
    scene.frame_set(scene.frame_current)


# -- operators ------------------------------------------------------------------------------------------

class RETIME_OT_check(BackgroundRunOperator, bpy.types.Operator):
    """Check how physical the active armature's action is as it plays (retime check): the residual force
    as a curve, the worst frames as markers, the feet's contact forces as arrows"""

    bl_idname = "retime.check"
    bl_label = "Check"
    bl_options = {"REGISTER", "UNDO"}

    force_length: bpy.props.FloatProperty(
        name="Force Length", min=0.0, default=0.0, subtype="DISTANCE",
        description="Length of a force arrow of one body weight (0: half the character's height)")
    exchange_folder: bpy.props.StringProperty(
        name="Keep Files In", subtype="DIR_PATH",
        description="Keep the BVH and retime's report (check.json) in this folder (empty: a temporary one)")

    job_type = CheckJob
    title = "Retime check"


class RETIME_OT_clear_check(bpy.types.Operator):
    """Remove what Check put in the scene (its collection, objects, actions and markers)"""

    bl_idname = "retime.clear_check"
    bl_label = "Clear Check"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.scene is not None

    def execute(self, context):
        clear(context.scene)
        return {"FINISHED"}


def draw_rows(layout, context):
    """The panel's Check rows (below the Retime button)."""
    layout.separator()
    row = layout.row(align=True)
    row.operator(RETIME_OT_check.bl_idname, icon="PHYSICS")
    row.operator(RETIME_OT_clear_check.bl_idname, text="Clear", icon="X")
    helper = bpy.data.objects.get(HELPER)
    if helper is not None and helper.get(TAG):
        layout.label(text=f"Checked {helper.get('checked_action', '')}: residual {helper['residual']:.2f} bw",
                     icon="FORCE_FORCE")


CLASSES = (RETIME_OT_check, RETIME_OT_clear_check)
