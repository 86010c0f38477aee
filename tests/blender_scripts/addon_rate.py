"""The add-on and the frame rate: ``python addon_rate.py ADDON.zip MOTION.bvh RESULTS.json``.

The BVH imported with Blender's defaults (the scene at 24 fps, Update Scene FPS off); the panel drawn into a
stand-in layout that records what it shows, before and after the action's source rate is known; the panel's
offer taken; an action baked by the add-on. RESULTS.json holds what the panel showed, the rates and the
baked action's recorded rate."""
import sys
from types import SimpleNamespace

import bpy

from _addon_script import finish, install_addon


class Layout:
    """Records labels and operator buttons; everything else is accepted and ignored."""

    def __init__(self, shown):
        self.shown, self.alert = shown, False

    def label(self, text="", icon="NONE"):
        self.shown.append({"label": text, "icon": icon, "alert": self.alert})

    def operator(self, idname, text="", icon="NONE"):
        button = SimpleNamespace()
        self.shown.append({"operator": idname, "text": text, "props": button})
        return button

    def box(self):
        return Layout(self.shown)

    def __getattr__(self, name):  # prop, prop_search, row, column, ...
        return lambda *args, **kwargs: self


def panel():
    shown = []
    addon.draw_panel(Layout(shown), bpy.context)
    for item in shown:
        if "props" in item:
            item["props"] = vars(item["props"])
    return shown


zip_path, bvh, results_path = sys.argv[1:4]
addon = sys.modules[install_addon(zip_path)]
scene = bpy.context.scene
bpy.ops.import_anim.bvh(filepath=bvh)  # Blender's defaults: the scene stays at 24 fps
arm = bpy.context.active_object
action = arm.animation_data.action
out = {"scene_fps": scene.render.fps / scene.render.fps_base, "unknown": panel()}
action["retime_source_fps"] = 120.0  # what a user (or a script that knows the capture) says
out["known"] = panel()
print("retime-test: baking at 24 fps")
bpy.ops.retime.retime(method="linear", scale=0.5, apply="BAKE")
out["baked_at_24"] = arm.animation_data.action.get("retime_source_fps")
arm.animation_data.action = action
bpy.ops.retime.use_source_rate(fps=120.0)
out["scene_fps_after"] = scene.render.fps / scene.render.fps_base
out["matching"] = panel()
finish(out, results_path, indent=1)
