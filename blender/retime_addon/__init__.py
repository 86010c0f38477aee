"""Retime for Blender: retime the active armature's action with the ``retime`` program.

The add-on exports the armature's animation as BVH, runs ``retime linear|guided|physics`` (a program of a
normal Python environment: it needs NumPy 2, SciPy and numba, which Blender's Python lacks) and puts the
timing curve it returns on the armature, baked into a new action or as an NLA strip's animated time.
Check (``retime check``) shows how physical the action is: the residual force as a curve, the worst
frames as markers, the feet's contact forces as arrows (:mod:`.check_view`).
Its panel sits in the sidebar (N) of the Dope Sheet and of the NLA editor, tab "Retime".
"""
import bpy

from . import armature, check_view, operator
from .options import DEFAULTS
from .runner import RetimeAddonError, retime_executable


class RetimePreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    retime_path: bpy.props.StringProperty(
        name="retime Program", subtype="FILE_PATH",
        description="The retime executable; empty: the RETIME_EXECUTABLE environment variable, then PATH")

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "retime_path")
        try:
            layout.label(text=f"Using {retime_executable(self.retime_path)}", icon="CHECKMARK")
        except RetimeAddonError as e:
            layout.label(text=str(e), icon="ERROR")


class RetimeSettings(bpy.types.PropertyGroup):
    """The panel's choices, kept with the scene."""

    method: bpy.props.EnumProperty(name="Method", items=operator.METHOD_ITEMS, default="physics")
    timing: bpy.props.EnumProperty(name="Timing", default="SCALE", items=[
        ("SCALE", "Scale", "The output lasts this many times as long"),
        ("DURATION", "Duration", "The output lasts this many seconds"),
        ("FREE", "Free", "The method chooses (physics: the most plausible; guided: the source's duration)"),
    ])
    duration: bpy.props.FloatProperty(name="Duration", min=0.01, default=1.0, unit="TIME_ABSOLUTE")
    scale: bpy.props.FloatProperty(name="Scale", min=0.01, default=0.5)
    apply: bpy.props.EnumProperty(name="Apply", items=operator.APPLY_MODES, default="BAKE")
    use_markers: bpy.props.BoolProperty(name="Keytimes from Markers", default=True, description=operator.MARKER_HELP)
    reference: bpy.props.StringProperty(name="Reference", description="The action whose timing to imitate (empty: the action itself)")
    blend: bpy.props.FloatProperty(name="Reference Influence", default=DEFAULTS["blend"], min=0.0, max=1.0, subtype="FACTOR",
                                   description="0: the smooth spline through the keytimes; 1: the guided warp")
    pace: bpy.props.FloatProperty(name="Pace Pull", default=DEFAULTS["pace"], min=0.0, soft_max=100.0,
                                  description="Pulls a walk or run to one steady speed (a jump's flight keeps its own); "
                                              "0: the reference's own pace")
    gravity_scale: bpy.props.FloatProperty(name="Gravity", default=DEFAULTS["gravity_scale"], min=0.01, max=100.0)
    mass: bpy.props.StringProperty(name="Mass Factors", description="BONE=FACTOR, comma separated (e.g. lfemur=10)")


def draw_panel(layout, context):
    settings = context.scene.retime
    obj = context.active_object
    if obj is None or obj.type != "ARMATURE":
        layout.label(text="Select an armature", icon="INFO")
    else:
        action = obj.animation_data.action if obj.animation_data else None
        layout.label(text=f"{obj.name}: {action.name if action else 'no action'}", icon="ARMATURE_DATA")
        draw_rate(layout, context.scene, action)
    layout.prop(settings, "method")
    layout.prop(settings, "timing", expand=True)
    if settings.timing == "SCALE":
        layout.prop(settings, "scale")
    elif settings.timing == "DURATION":
        layout.prop(settings, "duration")
    keys = sum(bool(operator.KEYTIME_MARKER.match(m.name)) for m in context.scene.timeline_markers)
    layout.prop(settings, "use_markers", text=f"Keytimes from Markers ({keys})")
    if settings.method == "guided":
        layout.prop_search(settings, "reference", bpy.data, "actions")
        layout.prop(settings, "blend", slider=True)
        layout.prop(settings, "pace")
    if settings.method == "physics":
        layout.prop(settings, "gravity_scale")
        layout.prop(settings, "mass")
    layout.prop(settings, "apply", expand=True)
    op = layout.operator(operator.RETIME_OT_retime.bl_idname, icon="TIME")
    op.method, op.apply, op.use_markers = settings.method, settings.apply, settings.use_markers
    op.scale = settings.scale if settings.timing == "SCALE" else 0.0
    op.duration = settings.duration if settings.timing == "DURATION" else 0.0
    op.reference = settings.reference if settings.method == "guided" else ""
    op.blend = settings.blend if settings.method == "guided" else DEFAULTS["blend"]
    op.pace = settings.pace if settings.method == "guided" else DEFAULTS["pace"]
    op.gravity_scale, op.mass = settings.gravity_scale, settings.mass if settings.method == "physics" else ""
    check_view.draw_rows(layout, context)


def draw_rate(layout, scene, action):
    """The rate the action is timed at (the scene's: what the scene plays), and a warning with the action's
    source rate, offered, where it is known and differs (a BVH imported at 24 fps without Update Scene FPS
    is retimed as if captured at 24 fps)."""
    fps = armature.scene_fps(scene)
    source = armature.rate_mismatch(scene, action)
    if source is None:
        layout.label(text=f"Timed at the scene's {fps:.4g} fps", icon="TIME")
        return
    box = layout.box()
    box.alert = True
    box.label(text=f"Scene plays {fps:.4g} fps; the action's source rate is {source:.4g} fps", icon="ERROR")
    box.label(text="retime times it as the scene plays it")
    op = box.operator(operator.RETIME_OT_use_source_rate.bl_idname, text=f"Use {source:.4g} fps")
    op.fps = source


class RetimePanel:
    """The panel's place in an editor's sidebar; the subclasses name the editor."""

    bl_label = "Retime"
    bl_region_type = "UI"
    bl_category = "Retime"

    def draw(self, context):
        draw_panel(self.layout, context)


class RETIME_PT_dopesheet(RetimePanel, bpy.types.Panel):
    bl_space_type = "DOPESHEET_EDITOR"


class RETIME_PT_nla(RetimePanel, bpy.types.Panel):
    bl_space_type = "NLA_EDITOR"


CLASSES = (RetimePreferences, RetimeSettings, operator.RETIME_OT_retime, operator.RETIME_OT_use_source_rate,
           *check_view.CLASSES, RETIME_PT_dopesheet, RETIME_PT_nla)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.retime = bpy.props.PointerProperty(type=RetimeSettings)


def unregister():
    del bpy.types.Scene.retime
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
