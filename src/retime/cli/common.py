"""Options and helpers shared by the commands."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..errors import RetimeError
from ..io_util import check_not_input, check_outputs
from ..motion import WRITABLE, load_motion
from ..motion.blender_io import SCENE_SUFFIXES, require_bpy


def add_motion_args(p):
    p.add_argument("motion", metavar="MOTION", help="input motion (.bvh; .amc with its .asf beside it; .fbx, .glb or .gltf with Blender's bpy)")
    p.add_argument("--asf", metavar="SKELETON.asf", help="skeleton for an .amc file (default: X.asf beside X_NN.amc)")
    p.add_argument("--fps", type=positive_float, metavar="HZ",
                   help="input frame rate (AMC files carry none: default 120 Hz; overrides a BVH's Frame Time)")
    add_frame_args(p)


def add_frame_args(p):
    p.add_argument("--up", type=up_axis, metavar="AXIS",
                   help="the file's up axis: x, y, z, -x, -y or -z (default: detected from the motion)")
    p.add_argument("--units", type=length_units, metavar="UNIT",
                   help="the file's length unit: m, cm, mm, in, ft, cmu, or metres per unit such as 0.04 "
                        "(default: detected from bone lengths and standing height)")
    p.add_argument("--angles", choices=("deg", "rad"),
                   help="unit of a BVH's rotation channels (default: detected; radians when every angle stays "
                        "within +-2 pi)")


def frame_kwargs(args) -> dict:
    return {"up": getattr(args, "up", None), "units": getattr(args, "units", None),
            "angles": getattr(args, "angles", None)}


def up_axis(text):
    from ..motion.frame import parse_up

    try:
        return parse_up(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def length_units(text):
    from ..motion.frame import parse_units

    try:
        parse_units(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


def add_output_args(p):
    p.add_argument("-o", "--output", required=True, metavar="OUT.bvh",
                   help="retimed motion to write: .bvh, or .fbx, .glb, .gltf with Blender's bpy (an FBX or glTF input "
                        "keeps its meshes and materials)")
    p.add_argument("--warp", metavar="WARP.csv", help="also write the timing curve (output_time,source_time per output frame)")


def add_duration_args(p, free=False):
    g = p.add_mutually_exclusive_group(required=False)
    g.add_argument("--duration", type=positive_float, metavar="SEC", help="output duration in seconds")
    g.add_argument("--scale", type=positive_float, metavar="X",
                   help="output lasts X times as long as the input (0.5 = twice as fast)")
    if free:
        g.add_argument("--free", action="store_true", help="let the method choose the duration")
    p.add_argument("--keytime", action="append", default=[], type=keytime, metavar="SRC=DST",
                   help="source time SRC (s) plays at output time DST (s); repeat for several")


def _number_type(convert, ok, what, kind="number"):
    """An argparse type: ``convert`` the text, then require ``ok(value)`` (saying ``what`` if not)."""
    def parse(text):
        try:
            v = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a {kind}") from None
        if not ok(v):
            raise argparse.ArgumentTypeError(f"must be {what}, got {text}")
        return v
    return parse


positive_float = _number_type(float, lambda v: 0 < v < float("inf"), "a positive number")
positive_int = _number_type(int, lambda v: v >= 1, "at least 1", kind="whole number")
nonnegative_float = _number_type(float, lambda v: 0 <= v < float("inf"), "a finite number of at least 0")
unit_float = _number_type(float, lambda v: 0 <= v <= 1, "a number from 0 to 1")


def keytime(text):
    try:
        a, b = text.split("=")
        return float(a), float(b)
    except ValueError:
        raise argparse.ArgumentTypeError(f"keytime must look like SRC=DST in seconds (e.g. 1.2=0.8), got {text!r}") from None


def load_input(args):
    motion = load_motion(args.motion, fps=args.fps, asf=args.asf, **frame_kwargs(args))
    check_found_inputs(args, motion)
    for note in motion.skeleton.notes:
        print(f"warning: {note}", file=sys.stderr)
    return motion


OUTPUT_OPTIONS = ("output", "warp", "report", "write_body")  # what a motion command may write
INPUT_OPTIONS = ("motion", "asf", "reference", "body", "contacts")  # what it may read


def check_output(args, suffixes=WRITABLE):
    """Every output of a motion command, before any work: its suffix, its folder, not an input
    given on the command line, not another output (see :func:`retime.io_util.check_outputs`)."""
    if Path(args.output).suffix.lower() not in suffixes:
        raise RetimeError(f"{args.output}: output must end in {' or '.join(suffixes)}")
    if Path(args.output).suffix.lower() in SCENE_SUFFIXES:
        require_bpy(args.output)  # before the (slow) retiming
    if getattr(args, "warp", None) and Path(args.warp).suffix.lower() != ".csv":
        raise RetimeError(f"{args.warp}: the warp file must end in .csv")
    check_outputs([getattr(args, k, None) for k in OUTPUT_OPTIONS], [getattr(args, k, None) for k in INPUT_OPTIONS])


def check_found_inputs(args, *motions):
    """Outputs against the files found while loading (an AMC's skeleton beside it, a reference's)."""
    found = [m.skeleton.source for m in motions if m is not None and m.skeleton.source]
    for k in OUTPUT_OPTIONS:
        if getattr(args, k, None):
            check_not_input(getattr(args, k), *found)


def write_outputs(args, name, motion, result, retimed=None):
    """Method ``name``'s result: the retimed motion and the warp (:func:`retime.outputs.write_retiming`)."""
    from ..outputs import write_retiming

    retimed = write_retiming(name, motion, result, args.output, args.warp, source=args.motion, retimed=retimed)
    said_written(args, motion, retimed)
    say_warnings(result.report.summary)


def say_warnings(summary):
    """The method's warnings from its report (every method's report has the list)."""
    for warning in summary.get("warnings", []):
        print(f"warning: {warning}")


def said_written(args, motion, retimed):
    print(f"wrote {args.output}: {retimed.n_frames} frames, {retimed.duration:.3f} s "
          f"(source {motion.duration:.3f} s)" + (f"; warp {args.warp}" if args.warp else ""))
