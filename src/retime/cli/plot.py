"""retime plot: timing curves and playback speed (Hsu Fig. 5), or a physics frame's feasible region."""
import argparse
from pathlib import Path

from ..errors import RetimeError
from ..io_util import check_outputs

EPILOG = """examples:
  retime plot linear.csv guided.csv physics.csv -o speeds.png
  retime plot guided.csv -o guided.svg --title "16_06 at 60%"
  retime plot --regions report.json --frame 143 -o region_143.png

Labels come from the file names (use --label to override, once per curve)."""


def register(sub):
    p = sub.add_parser(
        "plot",
        help="plot timing curves and playback speed, or a physics feasible region",
        description="Plot timing curves over the identity with their playback speed on a log scale "
        "(1x line, 10x limits), or, with --regions, one frame's feasible region and objective "
        "from a physics report plus the per-frame contact and feasibility strip.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("warps", nargs="*", metavar="WARP.csv", help="timing curves (output_time,source_time)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.png", help="image to write (.png, .svg or .pdf)")
    p.add_argument("--label", action="append", default=[], metavar="NAME", help="legend label, once per WARP in order")
    p.add_argument("--title", help="figure title")
    p.add_argument("--regions", metavar="REPORT.json", help="physics report: plot a frame's feasible region instead")
    p.add_argument("--frame", type=int, metavar="N", help="with --regions: the frame to show (default: the least feasible one)")
    p.set_defaults(func=run)


def run(args):
    from ..viz import plot

    inputs = list(args.warps) + ([args.regions] if args.regions else [])
    check_outputs([args.output], inputs)
    if Path(args.output).suffix.lower() not in plot.FORMATS:
        raise RetimeError(f"{args.output}: write a plot as .png, .svg or .pdf")
    if args.regions:
        if args.warps:
            raise RetimeError("give either WARP.csv files or --regions REPORT.json, not both")
        from ..viz.regions import load_report, plot_regions

        report = load_report(args.regions)
        frame = plot_regions(report, args.frame, args.output, title=args.title)
        print(f"wrote {args.output}: frame {frame} of {args.regions}")
        return 0
    if args.frame is not None:
        raise RetimeError("--frame goes with --regions REPORT.json")
    if not args.warps:
        raise RetimeError("give at least one WARP.csv (or --regions REPORT.json)")
    if args.label and len(args.label) != len(args.warps):
        raise RetimeError(f"{len(args.label)} --label for {len(args.warps)} warp files; give one per file or none")
    from ..warp import TimingCurve

    labels = args.label or [plot.label_from_path(w) for w in args.warps]
    curves = [(label, TimingCurve.from_csv(w)) for label, w in zip(labels, args.warps)]
    plot.plot_timing(curves, args.output, title=args.title)
    print(f"wrote {args.output}: {len(curves)} timing curve(s)")
    return 0
