"""The Retime operator: the active armature's action -> BVH -> ``retime METHOD`` -> warp CSV -> a baked
action or an NLA strip. Scripts call it directly (``bpy.ops.retime.retime(method='physics', scale=0.5,
apply='BAKE')``, runs to the end); from the panel it runs modally, retime working in the background while
the status bar shows the stage, Esc cancelling."""
import os
import re
import shutil
import tempfile

import bpy
import numpy as np

from . import apply, armature
from .options import DEFAULTS, command, output_frames as _output_frames
from .runner import BackgroundRunOperator, RetimeAddonError, Run, retime_executable

METHOD_ITEMS = [
    ("linear", "Linear", "Uniform, or piecewise linear through the keytimes"),
    ("guided", "Guided", "Keep the local velocities of a reference action (Hsu et al. 2007; default: the action itself)"),
    ("physics", "Physics", "Keep the motion physically plausible (McCann et al. 2006)"),
]
APPLY_MODES = [
    ("BAKE", "Bake", "A new action with keys at every output frame; the original action is kept untouched"),
    ("NLA", "NLA Strip", "A strip whose animated strip time follows the timing curve, editable in the Graph Editor"),
]
MARKER_HELP = ("A marker at a source frame named with an output frame (e.g. '96') makes that source frame play "
               "at that output frame")
KEYTIME_MARKER = re.compile(r"^\s*(?:->|=|@|\u2192)?\s*(-?\d+(?:\.\d+)?)\s*$")  # "96", "->96", "@96"


def preferences(context):
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


def marker_keytimes(scene, start, end, fps):
    """(source s, output s) for each marker named with an output frame: a marker at source frame F named
    "N" says that frame F must play at output frame N (frames counted from the action's first frame)."""
    keys = []
    for marker in sorted(scene.timeline_markers, key=lambda m: m.frame):
        match = KEYTIME_MARKER.match(marker.name)
        if not match:
            continue
        target = float(match.group(1))
        if not start < marker.frame < end:
            raise RetimeAddonError(f"marker {marker.name!r} at frame {marker.frame} is outside the action's frames "
                                   f"{start}-{end}; move it inside (the first and last frames are fixed)")
        if target <= start:
            raise RetimeAddonError(f"marker {marker.name!r} at frame {marker.frame} names output frame {target:g}, "
                                   f"not after the first frame {start}")
        keys.append(((marker.frame - start) / fps, (target - start) / fps))
    return keys


def animated_armature(context, verb):
    """The active armature, its action and the action's slot (None before Blender 4.4), or the one-line
    reason there is nothing to ``verb``."""
    obj = context.active_object
    if obj is None:
        raise RetimeAddonError(f"no active object: select the armature to {verb}")
    if obj.type != "ARMATURE":
        raise RetimeAddonError(f"the active object {obj.name!r} is a {obj.type.lower()}, not an armature: "
                               f"select the armature to {verb}")
    adt = obj.animation_data
    if adt is not None and adt.use_tweak_mode:
        raise RetimeAddonError(f"{obj.name!r} is in NLA tweak mode: leave it (Tab in the NLA editor) first")
    if adt is None or adt.action is None:
        raise RetimeAddonError(f"the armature {obj.name!r} has no action to {verb}: assign one in the Action Editor")
    return obj, adt.action, getattr(adt, "action_slot", None)


def export_bvh(context, obj, action, slot, frames, fps, path):
    """The armature ``obj`` playing ``action`` alone (NLA muted) sampled at every frame of ``frames``
    (first, last), written as BVH to ``path``; returns its hierarchy. A rig with control bones is
    exported as its evaluated deform skeleton (what physics must judge), while Bake and NLA retime
    the action's own curves (the controls). The armature is left as it was."""
    adt, scene = obj.animation_data, context.scene
    saved = adt.action, getattr(adt, "action_slot", None), adt.use_nla, scene.frame_current
    try:
        adt.use_nla = False
        if action is not adt.action:
            armature.assign_action(obj, action, slot)
        hierarchy, poses, world = armature.sample_pose(context, obj, range(frames[0], frames[1] + 1))
        text = armature.BvhPose(hierarchy, poses, world).text(fps)
    except armature.ArmatureError as e:
        raise RetimeAddonError(str(e)) from None
    finally:
        if adt.action is not saved[0]:
            armature.assign_action(obj, saved[0], saved[1])
        adt.use_nla = saved[2]
        scene.frame_set(saved[3])
    with open(path, "w", newline="\n") as f:
        f.write(text)
    return hierarchy


def exchange_folder(given, prefix):
    """(folder, whether to keep it): the folder the user gave for retime's files, made if need be, else a
    new temporary one (removed when the job ends)."""
    if not given.strip():
        return tempfile.mkdtemp(prefix=prefix), False
    folder = bpy.path.abspath(given.strip())
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as e:
        raise RetimeAddonError(f"cannot use the folder {folder} for retime's files: {e.strerror}") from None
    return folder, True


class ArmatureJob:
    """What a job on the active armature's action starts from: the armature, its action, slot, rate and
    frames (``start``, ``end``); ``cleanup`` stops ``retime`` and removes a temporary folder."""

    def __init__(self, context, props, verb):
        self.props = props
        self.obj, self.action, self.slot = animated_armature(context, verb)
        self.fps = armature.scene_fps(context.scene)
        self.start, self.end = armature.frame_range(self.action)
        self.run = None

    def _program_and_folder(self, prefix):
        """The ``retime`` program and the folder of its files (``self.executable``, ``self.folder``, ``self.keep``)."""
        prefs = preferences(bpy.context)
        self.executable = retime_executable(prefs.retime_path if prefs else "")
        self.folder, self.keep = exchange_folder(self.props.exchange_folder, prefix)

    def cleanup(self):
        if self.run is not None:
            self.run.cancel()
        if not self.keep:
            shutil.rmtree(self.folder, ignore_errors=True)


class Job(ArmatureJob):
    """One retime of one armature: export, run, apply; all state restored or cleaned on failure."""

    def __init__(self, context, props):
        super().__init__(context, props, "retime")
        scene = context.scene
        if self.end - self.start < 1:
            raise RetimeAddonError(f"the action {self.action.name!r} has a single frame: there is no timing to change")
        if props.duration > 0 and props.scale > 0:
            raise RetimeAddonError("give a duration or a scale, not both (set the other to 0)")
        self.n_source = self.end - self.start + 1
        self.keytimes = marker_keytimes(scene, self.start, self.end, self.fps) if props.use_markers else []
        n_out = _output_frames(props.method, props.duration, props.scale, self.n_source, self.fps)
        for src, dst in self.keytimes:
            if n_out is not None and not dst * self.fps < n_out - 1:
                raise RetimeAddonError(f"a keytime marker names output frame {self.start + dst * self.fps:g}, past the "
                                       f"output's last frame {self.start + n_out - 1}")
        self.reference = None
        if props.method == "guided" and props.reference:
            self.reference = bpy.data.actions.get(props.reference)
            if self.reference is None:
                raise RetimeAddonError(f"no action named {props.reference!r} for the reference")
        self._program_and_folder("retime-blender-")

    @property
    def doing(self):
        return f"{self.props.method} running on {self.action.name!r}"

    # -- the stages ---------------------------------------------------------------------------------
    def launch(self, context):
        """Export the action (and the reference) as BVH and start ``retime``."""
        source = os.path.join(self.folder, "source.bvh")
        self.hierarchy = self._export(context, self.action, self.slot, (self.start, self.end), source)
        p = self.props
        reference = None
        if self.reference is not None:
            ref_slot = self._slot_for(self.reference)
            frames = armature.frame_range(self.reference)
            reference = os.path.join(self.folder, "reference.bvh")
            self._export(context, self.reference, ref_slot, frames, reference)
        argv = command(self.executable, p.method, source, os.path.join(self.folder, "retimed.bvh"),
                       os.path.join(self.folder, "warp.csv"), duration=p.duration, scale=p.scale,
                       keytimes=self.keytimes, reference=reference, blend=p.blend, pace=p.pace,
                       gravity_scale=p.gravity_scale, mass=self._mass_factors() if p.method == "physics" else ())
        self.run = Run(argv, self.folder)

    def finish(self, context):
        """Read the warp and apply it; returns the report's type and the one-line summary."""
        said = self.run.result()
        _, source_times = apply.read_warp(os.path.join(self.folder, "warp.csv"))
        frames = np.arange(self.start, self.end + 1, dtype=float)
        label = f"{self.action.name} ({self.props.method})"
        n_out = len(source_times)
        mismatch = armature.rate_mismatch(context.scene, self.action)
        if self.props.apply == "BAKE":
            new, slot = apply.bake(self.obj, self.action, self.slot, frames, source_times, self.fps, label)
            new[armature.SOURCE_FPS] = self.fps  # keyed at the scene's rate
            self.action.use_fake_user = True  # kept when the file is saved, though nothing plays it now
            armature.assign_action(self.obj, new, slot)
            where = f"baked to action {new.name!r}"
        else:
            action, slot, copied = apply.strip_action(self.obj, self.action, self.slot, frames, source_times, self.fps)
            strip = apply.nla_strip(self.obj, action, slot, frames, source_times, self.fps, label)
            self.action.use_fake_user = True
            where = f"NLA strip {strip.name!r} (strip time keyed from the timing curve)"
            if copied:
                action[armature.SOURCE_FPS] = self.fps
                where += (f" playing {action.name!r}, the action keyed also between frames (its Euler or "
                          "non-linear keys blend otherwise than retime's slerp)")
        scene = context.scene
        if scene.frame_start == self.start and self.end <= scene.frame_end <= self.end + 1:  # the clip's range
            scene.frame_end = self.start + n_out - 1
        scene.frame_set(scene.frame_current)
        summary = f"retimed {self.action.name!r} with {self.props.method}: {self.n_source} -> {n_out} frames, {where}"
        if mismatch is not None:
            summary += (f"; timed at the scene's {self.fps:.4g} fps, not the action's source rate {mismatch:.4g} fps "
                        "(the Retime panel offers it)")
        return {"INFO"}, summary + (f"; {said}" if said and not said.startswith("wrote ") else "")

    # -- helpers -------------------------------------------------------------------------------------
    def _export(self, context, action, slot, frames, path):
        return export_bvh(context, self.obj, action, slot, frames, self.fps, path)

    def _slot_for(self, action):
        slots = getattr(action, "slots", None)
        if not slots:
            return None
        return next((s for s in slots if s.target_id_type == "OBJECT"), slots[0])

    def _mass_factors(self):
        """'lfemur=10, rfemur=2' -> ['lfemur=10', 'rfemur=2'] with bone names as retime's BVH names them."""
        out = []
        names = dict(zip(self.hierarchy.names, self.hierarchy.bvh_names))
        for item in filter(None, (s.strip() for s in self.props.mass.replace(";", ",").split(","))):
            bone, sep, factor = item.rpartition("=")
            if not sep or not bone.strip():
                raise RetimeAddonError(f"mass factor {item!r} must look like BONE=FACTOR (e.g. lfemur=10)")
            if bone.strip() not in names:
                raise RetimeAddonError(f"mass factor {item!r}: the armature has no bone named {bone.strip()!r}")
            out.append(f"{names[bone.strip()]}={factor.strip()}")
        return out


class RETIME_OT_retime(BackgroundRunOperator, bpy.types.Operator):
    """Retime the active armature's action with the retime program"""

    bl_idname = "retime.retime"
    bl_label = "Retime"
    bl_options = {"REGISTER", "UNDO"}

    method: bpy.props.EnumProperty(name="Method", items=METHOD_ITEMS, default="linear")
    duration: bpy.props.FloatProperty(name="Duration", description="Output duration in seconds (0: not set)",
                                      min=0.0, default=0.0, unit="TIME_ABSOLUTE")
    scale: bpy.props.FloatProperty(name="Scale", description="Output lasts this many times as long (0.5: twice as "
                                   "fast; 0: not set)", min=0.0, default=0.0)
    apply: bpy.props.EnumProperty(name="Apply", items=APPLY_MODES, default="BAKE")
    use_markers: bpy.props.BoolProperty(name="Keytimes from Markers", default=True, description=MARKER_HELP)
    reference: bpy.props.StringProperty(name="Reference", description="Guided: the action whose timing to imitate "
                                        "(empty: the action itself)")
    blend: bpy.props.FloatProperty(name="Reference Influence", description="Guided: 0 plays the smooth spline "
                                   "through the keytimes, 1 the guided warp (Hsu et al. sec. 5)", default=DEFAULTS["blend"],
                                   min=0.0, max=1.0, subtype="FACTOR")
    pace: bpy.props.FloatProperty(name="Pace Pull", description="Guided: pulls a walk or run to one steady speed (a "
                                  "jump's flight keeps its own); 0: the reference's own pace", default=DEFAULTS["pace"],
                                  min=0.0, soft_max=100.0)
    gravity_scale: bpy.props.FloatProperty(name="Gravity", description="Physics: gravity times this",
                                           default=DEFAULTS["gravity_scale"], min=0.01, max=100.0)
    mass: bpy.props.StringProperty(name="Mass Factors", description="Physics: BONE=FACTOR, comma separated "
                                   "(e.g. lfemur=10)")

    exchange_folder: bpy.props.StringProperty(
        name="Keep Files In", subtype="DIR_PATH",
        description="Keep the BVH, retime's output and the timing curve (warp.csv) in this folder, to rerun or "
                    "inspect them (empty: a temporary folder, removed afterwards)")

    job_type = Job


class RETIME_OT_use_source_rate(bpy.types.Operator):
    """Set the scene's frame rate to the action's source rate, so that the action plays (and is retimed) at
    the speed it was captured at"""

    bl_idname = "retime.use_source_rate"
    bl_label = "Use the Source Rate"
    bl_options = {"REGISTER", "UNDO"}

    fps: bpy.props.FloatProperty(name="Frame Rate", min=0.001, default=24.0)

    def execute(self, context):
        armature.set_scene_fps(context.scene, self.fps)
        self.report({"INFO"}, f"scene frame rate set to {armature.scene_fps(context.scene):.4g} fps")
        return {"FINISHED"}
