"""retime apply: play a video or a per-frame signal through a timing curve (Hsu et al. Fig. 4)."""
import argparse
from pathlib import Path

from ..errors import RetimeError
from ..io_util import check_outputs
from .common import positive_float

EPILOG = """examples:
  retime apply guided.csv session.mp4 -o session_guided.mp4 --blend
  retime apply guided.csv forces.csv -o forces_guided.csv            (CSV with a 'time' column)
  retime apply guided.csv emg.npy -o emg_guided.npy --input-fps 1000

WARP.csv maps output time to source time in seconds (header output_time,source_time), as written
by --warp of the retiming commands. Output frame k shows the input at source time p(k / fps)."""


def register(sub):
    p = sub.add_parser(
        "apply",
        help="apply a timing curve to a video or a per-frame CSV/NPY signal",
        description="Resample a video (nearest frame, or --blend between the two neighbouring frames) "
        "or a per-frame signal (linear interpolation) at the source times of a timing curve.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("warp", metavar="WARP.csv", help="timing curve (output_time,source_time)")
    p.add_argument("input", metavar="INPUT", help="video (.mp4 .mov .mkv .avi .webm .gif) or signal (.csv .npy)")
    p.add_argument("-o", "--output", required=True, metavar="OUTPUT", help="retimed video (.mp4 .mkv .mov .gif) or signal (same type as INPUT)")
    p.add_argument("--fps", type=positive_float, metavar="HZ", help="output frame rate (default: the input's)")
    p.add_argument("--input-fps", type=positive_float, metavar="HZ", help="sample rate of a signal without a time column")
    p.add_argument("--blend", action="store_true", help="video: blend the two source frames around each source time instead of taking the nearest")
    p.add_argument("--fit", action="store_true", help="stretch the curve's source time onto the input's duration when they differ")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args):
    from ..viz.video import VIDEO_EXTS, apply_to_signal, apply_to_video
    from ..warp import TimingCurve

    check_outputs([args.output], [args.input, args.warp])
    if not Path(args.input).exists():
        raise RetimeError(f"{args.input}: file not found")
    curve = TimingCurve.from_csv(args.warp)
    ext = Path(args.input).suffix.lower()
    if ext in VIDEO_EXTS:
        if Path(args.output).suffix.lower() not in {".mp4", ".mkv", ".mov", ".gif"}:
            raise RetimeError(f"{args.output}: write a video as .mp4, .mkv, .mov or .gif")
        info = apply_to_video(curve, args.input, args.output, fps=args.fps, blend=args.blend, fit=args.fit, quiet=args.quiet)
        print(f"wrote {args.output}: {info['frames']} frames at {info['fps']:g} fps, {info['duration']:.3f} s, "
              f"{info['width']}x{info['height']}")
    else:
        info = apply_to_signal(curve, args.input, args.output, fps=args.input_fps, out_fps=args.fps, fit=args.fit)
        print(f"wrote {args.output}: {info['frames']} frames at {info['fps']:g} Hz, {info['columns']} column(s)")
    return 0
