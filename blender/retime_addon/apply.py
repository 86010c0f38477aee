"""Putting a timing curve (output frame -> source time, retime's warp CSV) on an armature: a baked action,
or an NLA strip whose animated strip time is the curve."""
import csv

import numpy as np

from . import armature
from .runner import RetimeAddonError

KEY_GAP = 0.02  # frames; F-Curve.update() merges keys closer than 0.01
ROTATIONS = {"rotation_quaternion": 4, "rotation_axis_angle": 4, "rotation_euler": 3}


def read_warp(path):
    """(output times, source times) in seconds, one per output frame."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or [h.strip() for h in rows[0][:2]] != ["output_time", "source_time"]:
        raise RetimeAddonError(f"{path}: not a retime warp file")
    values = np.array([[float(a), float(b)] for a, b, *_ in rows[1:]])
    return values[:, 0], values[:, 1]


def source_positions(source_times, fps, n_source):
    """Each output frame's source frame index i0, the next one, and the weight between them (as
    retime.warp.apply_timing: snapped when within 1e-6 of a frame)."""
    u = np.maximum.accumulate(np.asarray(source_times) * fps)
    r = np.round(u)
    u = np.clip(np.where(np.abs(u - r) < 1e-6, r, u), 0.0, n_source - 1)
    i0 = np.minimum(np.floor(u).astype(int), max(n_source - 2, 0))
    w = u - i0
    i1 = np.minimum(i0 + 1, n_source - 1)
    last = w >= 1.0
    return np.where(last, i1, i0), i1, np.where(last, 0.0, w)


def _owner(obj, data_path):
    """The struct an F-curve's property belongs to, and the property's name."""
    owner_path, _, prop = data_path.rpartition(".")
    try:
        return (obj.path_resolve(owner_path) if owner_path else obj), prop
    except ValueError:
        return None, prop


def _to_quaternions(prop, values, order):
    from mathutils import Euler, Quaternion

    if prop == "rotation_quaternion":
        return [Quaternion(v) for v in values]
    if prop == "rotation_axis_angle":
        return [Quaternion(v[1:], v[0]) for v in values]
    return [Euler(v, order).to_quaternion() for v in values]


def resample(obj, action, slot, source_frames, positions, key_frames, name):
    """A new action keyed at ``key_frames`` with the source played at ``positions`` (i0, i1, w: between
    source frames i0 and i1 at weight w, as retime.warp.apply_timing): rotations slerped (quaternion bones
    as quaternions, Euler bones as continuous Euler angles), every other animated property interpolated
    linearly. The source action is not changed. Returns (the new action, its slot or None)."""
    curves = armature.action_fcurves(action, slot)
    if not curves:
        raise RetimeAddonError(f"the action {action.name!r} has no F-curves to retime")
    i0, i1, w = positions
    new, new_slot, new_curves = armature.new_action(obj, name)
    by_path = {}
    for fc in curves:
        by_path.setdefault(fc.data_path, {})[fc.array_index] = fc
    for path, comps in by_path.items():
        group = next((fc.group.name for fc in comps.values() if fc.group), "")
        owner, prop = _owner(obj, path)
        sampled = {i: np.array([fc.evaluate(f) for f in source_frames]) for i, fc in comps.items()}
        if prop in ROTATIONS and owner is not None:
            size = ROTATIONS[prop]
            current = list(getattr(owner, prop))
            values = np.column_stack([sampled.get(i, np.full(len(source_frames), current[i])) for i in range(size)])
            order = owner.rotation_mode if owner.rotation_mode not in ("QUATERNION", "AXIS_ANGLE") else "XYZ"
            mode = {"rotation_quaternion": "QUATERNION", "rotation_axis_angle": "AXIS_ANGLE"}.get(prop, order)
            quats = _to_quaternions(prop, values, order)
            out = armature.quaternions_to_mode([quats[a].slerp(quats[b], t) for a, b, t in zip(i0, i1, w)], mode)
            for i in range(size):
                armature.write_curve(new_curves, path, i, group, key_frames, out[:, i])
        else:
            for i, v in sampled.items():
                armature.write_curve(new_curves, path, i, group, key_frames, v[i0] + w * (v[i1] - v[i0]))
    return new, new_slot


def bake(obj, action, slot, source_frames, warp_source_times, fps, name):
    """A new action with a key at every output frame, playing the source at the warp's source times."""
    positions = source_positions(warp_source_times, fps, len(source_frames))
    out_frames = source_frames[0] + np.arange(len(positions[0]), dtype=float)
    return resample(obj, action, slot, source_frames, positions, out_frames, name)


def _plays(owner, prop):
    """Whether a rotation property is the one its owner's rotation mode uses."""
    mode = getattr(owner, "rotation_mode", "XYZ")
    return {"rotation_quaternion": mode == "QUATERNION", "rotation_axis_angle": mode == "AXIS_ANGLE"}.get(
        prop, mode not in ("QUATERNION", "AXIS_ANGLE"))


def interpolates_like_retime(obj, action, slot):
    """Whether Blender's own evaluation of ``action`` between frames plays retime's poses: keys on whole
    frames, linear, the rotations that play as quaternions (Blender normalizes their linear blend: within
    1e-6 of a slerp at mocap rates). Euler angles blended linearly are another rotation than the slerp,
    unless a single one of them varies (a turn about one fixed axis)."""
    varying = {}
    for fc in armature.action_fcurves(action, slot):
        owner, prop = _owner(obj, fc.data_path)
        if prop in ("rotation_euler", "rotation_axis_angle") and (owner is None or _plays(owner, prop)):
            values = [k.co[1] for k in fc.keyframe_points]
            if values and max(values) - min(values) > 1e-9:
                varying[fc.data_path] = varying.get(fc.data_path, 0) + 1
                if varying[fc.data_path] > 1:
                    return False
        for key in fc.keyframe_points:
            if key.interpolation != "LINEAR" or abs(key.co[0] - round(key.co[0])) > 1e-4:
                return False
    return True


def strip_action(obj, action, slot, source_frames, warp_source_times, fps):
    """The action an NLA strip must play so that its animated time gives retime's poses: the action
    itself when Blender interpolates it as retime does, else a copy keyed on every source frame and on
    every in-between source frame the timing curve visits. Returns (action, slot, whether a copy)."""
    if interpolates_like_retime(obj, action, slot):
        return action, slot, False
    n = len(source_frames)
    i0, _, w = source_positions(warp_source_times, fps, n)
    visited = []  # Blender merges keys closer than 0.01 frames: keep the visited frames that far apart
    for u in np.unique(i0 + w):
        if not visited or u - visited[-1] >= KEY_GAP:
            visited.append(u)
    whole = np.arange(n, dtype=float)
    nearest = np.abs(whole[:, None] - np.array(visited)[None]).min(axis=1)
    at = np.sort(np.concatenate([visited, whole[nearest >= KEY_GAP]]))
    k0 = np.minimum(np.floor(at).astype(int), n - 1)
    positions = (k0, np.minimum(k0 + 1, n - 1), at - k0)
    copy, copy_slot = resample(obj, action, slot, source_frames, positions, source_frames[0] + at,
                               f"{action.name} (retime keys)")
    return copy, copy_slot, True


def nla_strip(obj, action, slot, source_frames, warp_source_times, fps, name):
    """Push ``action`` into a new NLA track as a strip that plays it through the warp: ``use_animated_time``
    with the ``strip_time`` F-curve keyed at every output frame (linear keys the animator can reshape in
    the Graph Editor). ``action`` is the one to play (see :func:`strip_action`); the active action is taken
    off the object so that the strip plays. Returns the strip."""
    adt = obj.animation_data
    start, end = float(source_frames[0]), float(source_frames[-1])
    n_out = len(warp_source_times)
    track = adt.nla_tracks.new()
    track.name = name
    strip = track.strips.new(name, int(start), action)
    if slot is not None and hasattr(strip, "action_slot"):
        strip.action_slot = slot
    strip.action_frame_start, strip.action_frame_end = start, end
    strip.use_sync_length = False
    strip.scale = (n_out - 1) / (end - start)  # spans the output frames; the animated time decides the pose
    strip.extrapolation = "HOLD_FORWARD"
    strip.use_animated_time = True
    curve = strip.fcurves.find("strip_time")
    keys = curve.keyframe_points
    while len(keys):
        keys.remove(keys[0], fast=True)
    keys.add(n_out)
    frames = start + np.arange(n_out, dtype=float)
    i0, _, w = source_positions(warp_source_times, fps, len(source_frames))  # the frames strip_action keyed
    keys.foreach_set("co", np.column_stack([frames, start + i0 + w]).astype(np.float32).ravel())
    keys.foreach_set("interpolation", np.full(n_out, armature.LINEAR, dtype=np.int32))
    curve.update()
    adt.action = None
    return strip
