"""What the add-on asks ``retime`` for, without bpy or retime (Blender's Python has neither SciPy nor numba,
so the add-on cannot import retime): the output's frame count, by retime's one rule
(``retime.warp.output_duration``), and the command line of a request. ``tests/test_blender_options.py``
checks both against retime itself, outside Blender."""
import math

#: retime's own defaults for the options the panel and the operator offer (retime.guided.method.Settings'
#: blend; physics' standard gravity, a gravity scale of 1)
DEFAULTS = {"blend": 1.0, "gravity_scale": 1.0}


def output_frames(method, duration, scale, n_source, fps):
    """The output's frame count when the duration is set (None when the method chooses it): a scale
    floors (output frame k shows source frame k / scale exactly), a duration rounds to whole frames."""
    if scale > 0:
        return int(math.floor((n_source - 1) * scale + 1e-6)) + 1
    if duration > 0:
        return max(1, int(round(duration * fps))) + 1
    return n_source if method == "guided" else None
