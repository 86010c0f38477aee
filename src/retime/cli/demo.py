"""retime demo: the README's main job, an HTML report comparing linear, guided and physics retiming."""
import argparse
import sys

from .common import positive_float

EPILOG = """examples:
  retime demo                      writes retime-demo/report.html
  retime demo -o out --scale 0.6   60% of the original duration
  retime demo --clip 16_03.amc     another bundled clip (or a path to a .amc/.bvh file)

Open DIR/report.html in a browser; it links to the video, plots, BVH and warp files beside it."""


def _frames(text):
    try:
        a, b = (int(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--frames must look like FIRST:LAST (e.g. 150:406), got {text!r}") from None
    return a, b


def register(sub):
    p = sub.add_parser(
        "demo",
        help="retime a bundled CMU jump with every method and write an HTML report",
        description="Retime a bundled CMU jump (16_06 by default) to a shorter duration with linear, guided and "
        "physics retiming; write DIR/report.html with the request, the timing plots, a side-by-side video "
        "and the numbers (durations, flight speed, feasible fraction, run times).",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("-o", "--output", default="retime-demo", metavar="DIR", help="folder to write (default: retime-demo)")
    p.add_argument("--clip", default="16_06.amc", metavar="CLIP", help="bundled clip name or motion file (default 16_06.amc)")
    p.add_argument("--scale", type=positive_float, default=0.5, metavar="X", help="output duration as a fraction of the clip's (default 0.5)")
    p.add_argument("--methods", default="linear,guided,physics", metavar="LIST", help="comma-separated methods (default: linear,guided,physics)")
    p.add_argument("--fps", type=positive_float, default=30.0, metavar="HZ", help="video frame rate (default 30)")
    p.add_argument("--frames", type=_frames, metavar="FIRST:LAST", help="use only these source frames (0-based, inclusive)")
    p.add_argument("--no-video", action="store_true", help="skip the side-by-side video")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=run)


def run(args):
    from ..report.demo import run_demo

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    result = run_demo(args.output, clip=args.clip, scale=args.scale, methods=methods, fps=args.fps,
                      video=not args.no_video, quiet=args.quiet, frames=args.frames)
    for m in result.methods:
        if m.curve is None:
            print(f"{m.name}: not run ({m.error})", file=sys.stderr)
        else:
            fs = "-" if m.flight_speed is None else f"{m.flight_speed:.2f}x"
            ff = "" if m.feasible_fraction is None else f", feasible fraction {m.feasible_fraction:.3f}"
            print(f"{m.name:8s} {m.curve.duration:.3f} s, flight speed {fs}{ff}, {m.seconds:.2f} s to compute")
    print(f"wrote {result.report_path} in {result.total_seconds:.1f} s; open {result.report_path.resolve().as_uri()} in a browser")
    return 0
