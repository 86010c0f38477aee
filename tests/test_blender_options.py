"""The Blender add-on's bpy-free half (blender/retime_addon/options.py), checked against retime itself:
the add-on cannot import retime, so what it restates must agree with it."""
import pytest
from _blender_support import addon_module

from retime.warp import output_duration


@pytest.fixture(scope="module")
def options():
    return addon_module("options")


@pytest.mark.parametrize("n_source", [227, 213, 407, 410, 285])
@pytest.mark.parametrize("fps", [24.0, 30.0, 120.0])
def test_the_output_frame_count_is_retimes(options, n_source, fps):
    S = (n_source - 1) / fps
    for scale in (0.5, 0.55, 0.6, 0.7, 1.5, 2.0):
        assert options.output_frames("physics", 0.0, scale, n_source, fps) == round(
            output_duration(S, fps, scale=scale) * fps) + 1
    for duration in (0.5, 1.0 + 0.7 / fps, 2.0 + 0.3 / fps, 3.3):
        assert options.output_frames("guided", duration, 0.0, n_source, fps) == round(
            output_duration(S, fps, duration=duration) * fps) + 1
    assert options.output_frames("guided", 0.0, 0.0, n_source, fps) == n_source
    assert options.output_frames("physics", 0.0, 0.0, n_source, fps) is None
