"""What the add-on asks ``retime`` for, without bpy or retime (Blender's Python has neither SciPy nor numba,
so the add-on cannot import retime): the output's frame count, by retime's one rule
(``retime.warp.output_duration``), and the command line of a request. ``tests/test_blender_options.py``
checks both against retime itself, outside Blender."""
import math

#: retime's own defaults for the options the panel and the operator offer (retime.guided.method.Settings'
#: blend and pace; physics' standard gravity, a gravity scale of 1); tests/test_front_end_defaults.py
#: checks them against retime's Settings
DEFAULTS = {"blend": 1.0, "pace": 10.0, "gravity_scale": 1.0}


def output_frames(method, duration, scale, n_source, fps):
    """The output's frame count when the duration is set (None when the method chooses it): a scale
    floors (output frame k shows source frame k / scale exactly), a duration rounds to whole frames."""
    if scale > 0:
        return int(math.floor((n_source - 1) * scale + 1e-6)) + 1
    if duration > 0:
        return max(1, int(round(duration * fps))) + 1
    return n_source if method == "guided" else None


def _typed(value):
    """A float property as the user typed it: Blender keeps them in single precision (0.7 is 0.699999988)."""
    return f"{value:.7g}"


#: every option the add-on passes to ``retime METHOD``: (name, command-line flag, the methods that take
#: it); tests/test_blender_options.py checks each flag against retime's own parser
OPTIONS = (
    ("duration", "--duration", ("linear", "guided", "physics")),
    ("scale", "--scale", ("linear", "guided", "physics")),
    ("keytimes", "--keytime", ("linear", "guided", "physics")),
    ("reference", "--reference", ("guided",)),
    ("blend", "--blend", ("guided",)),
    ("pace", "--pace", ("guided",)),
    ("gravity_scale", "--gravity-scale", ("physics",)),
    ("mass", "--mass", ("physics",)),
)


def command(executable, method, source, output, warp, duration=0.0, scale=0.0, keytimes=(), reference=None,
            blend=DEFAULTS["blend"], pace=DEFAULTS["pace"], gravity_scale=DEFAULTS["gravity_scale"], mass=()):
    """The ``retime`` command line of a request, from :data:`OPTIONS`: ``duration`` or ``scale`` (0:
    unset; a duration wins), ``keytimes`` [(source s, output s)], a guided ``reference`` BVH,
    ``blend`` and ``pace``, a physics ``gravity_scale`` and ``mass`` ["SEGMENT=FACTOR", ...]. An option at retime's
    default is left out, so retime's own default applies."""
    given = {"duration": _typed(duration) if duration > 0 else None,
             "scale": _typed(scale) if scale > 0 and not duration > 0 else None,
             "keytimes": [f"{src!r}={dst!r}" for src, dst in keytimes],
             "reference": reference,
             "blend": _typed(blend) if blend != DEFAULTS["blend"] else None,
             "pace": _typed(pace) if pace != DEFAULTS["pace"] else None,
             "gravity_scale": _typed(gravity_scale) if abs(gravity_scale - DEFAULTS["gravity_scale"]) > 1e-9 else None,
             "mass": list(mass)}
    argv = [executable, method, source, "-o", output, "--warp", warp]
    for name, flag, methods in OPTIONS:
        if method not in methods:
            continue
        value = given[name]
        for item in value if isinstance(value, list) else [value]:
            if item is not None:
                argv += [flag, item]
    return argv
