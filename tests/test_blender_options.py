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


def retime_parses(argv):
    """retime's own parser on the add-on's command line (the program's name dropped)."""
    from retime.cli.main import build_parser, parse

    return parse(build_parser(), argv[1:])


@pytest.mark.parametrize("method", ["linear", "guided", "physics"])
def test_every_flag_of_the_table_is_one_retime_takes(options, method):
    import argparse

    from retime.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices[method]
    flags = {o for a in sub._actions for o in a.option_strings}
    for name, flag, methods in options.OPTIONS:
        if method in methods:
            assert flag in flags, (method, flag)


def test_the_command_means_to_retime_what_the_panel_says(options):
    args = retime_parses(options.command("retime", "guided", "s.bvh", "o.bvh", "w.csv", duration=0.7000000012,
                                         scale=0.5, keytimes=[(0.25, 0.5)], reference="r.bvh", blend=0.25))
    assert (args.command, args.motion, args.output, args.warp) == ("guided", "s.bvh", "o.bvh", "w.csv")
    assert args.duration == 0.7 and args.scale is None  # as typed; a duration wins over a scale
    assert args.keytime == [(0.25, 0.5)] and args.reference == "r.bvh" and args.blend == 0.25
    args = retime_parses(options.command("retime", "physics", "s.bvh", "o.bvh", "w.csv", scale=0.5,
                                         gravity_scale=0.25, mass=["lfemur=10", "rfemur=2"], blend=0.5))
    assert args.scale == 0.5 and args.duration is None and args.gravity_scale == 0.25
    assert args.mass == [("lfemur", 10.0), ("rfemur", 2.0)]
    # at retime's defaults nothing is passed, and retime's own defaults apply
    argv = options.command("retime", "physics", "s.bvh", "o.bvh", "w.csv")
    assert argv == ["retime", "physics", "s.bvh", "-o", "o.bvh", "--warp", "w.csv"]
    args = retime_parses(options.command("retime", "linear", "s.bvh", "o.bvh", "w.csv", scale=0.5, blend=0.3,
                                         gravity_scale=2.0, reference="r.bvh"))
    assert args.scale == 0.5 and not hasattr(args, "blend") and not hasattr(args, "gravity_scale")
