"""retime render: stick-figure videos of motions side by side, in sync."""
import argparse
from pathlib import Path

from ..errors import RetimeError
from ..io_util import check_outputs
from .common import add_frame_args, frame_kwargs, positive_float

EPILOG = """examples:
  retime render 16_06.amc -o 16_06.mp4
  retime render 16_06.amc --warp linear.csv --warp guided.csv --warp physics.csv -o compare.mp4
  retime render 16_06.amc fast.bvh --label original --label fast -o side_by_side.gif --fps 25
  retime render 16_06.amc -o frame.png --at 1.5

Each MOTION is a panel; each --warp adds a panel with the first MOTION played through that timing
curve (its playback speed is shown). All panels share one clock; the video lasts as long as the
longest panel, and shorter panels hold their last pose."""


def _size(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must look like WIDTHxHEIGHT (e.g. 480x540), got {text!r}") from None
    if w < 64 or h < 64 or w > 4096 or h > 4096:
        raise argparse.ArgumentTypeError(f"panel size must be between 64 and 4096 pixels, got {text}")
    return w, h


def register(sub):
    p = sub.add_parser(
        "render",
        help="render motions as stick figures to a video (mp4, gif) side by side",
        description="Render one or more motions as stick figures with a ground grid and a camera that "
        "follows the root, side by side and in sync, with time and playback speed shown.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("motions", nargs="+", metavar="MOTION", help="motion files (.bvh, or .amc with its .asf beside it)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.mp4", help="video to write (.mp4, .mkv, .mov or .gif), or .png with --at")
    p.add_argument("--fps", type=positive_float, default=None, metavar="HZ", help="video frame rate (default 30; 25 for GIF)")
    p.add_argument("--warp", action="append", default=[], metavar="WARP.csv", help="add a panel: the first MOTION played through this curve")
    p.add_argument("--label", action="append", default=[], metavar="NAME", help="panel label, once per panel in order (default: file names)")
    p.add_argument("--report", metavar="REPORT.json", help="physics report: highlight the feet in contact in the panel it belongs to")
    p.add_argument("--size", type=_size, default=(480, 540), metavar="WxH", help="size of one panel in pixels (default 480x540)")
    p.add_argument("--columns", type=int, metavar="N", help="panels per row (default: all in one row)")
    p.add_argument("--at", type=float, metavar="SEC", help="write a single frame at this time as PNG")
    p.add_argument("--asf", metavar="SKELETON.asf", help="skeleton for .amc files (default: X.asf beside X_NN.amc)")
    p.add_argument("--input-fps", type=positive_float, metavar="HZ", help="frame rate of the motions (AMC: default 120)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    add_frame_args(p)
    p.set_defaults(func=run)


def run(args):
    from ..motion import load_motion
    from ..viz.render import render_still, render_video, track_from_motion
    from ..warp import TimingCurve, apply_timing

    out_ext = Path(args.output).suffix.lower()
    if args.at is not None and out_ext != ".png":
        raise RetimeError(f"{args.output}: --at writes a single frame; name a .png file")
    if args.at is None and out_ext not in {".mp4", ".mkv", ".mov", ".gif"}:
        raise RetimeError(f"{args.output}: write a video as .mp4, .mkv, .mov or .gif (or a .png with --at SEC)")
    check_outputs([args.output], [*args.motions, *args.warp, args.report, args.asf])
    motions = [load_motion(m, fps=args.input_fps, asf=args.asf, **frame_kwargs(args)) for m in args.motions]
    panels = []  # (default label, motion, curve)
    for path, m in zip(args.motions, motions):
        panels.append((Path(path).stem, m, None))
    for w in args.warp:
        curve = TimingCurve.from_csv(w)
        panels.append((Path(w).stem, apply_timing(motions[0], curve), curve))
    if args.label and len(args.label) != len(panels):
        raise RetimeError(f"{len(args.label)} --label for {len(panels)} panels; give one per panel or none")
    labels = args.label or [p[0] for p in panels]
    contacts = [None] * len(panels)
    if args.report:
        contacts = _contacts(args, panels, motions)
    tracks = [track_from_motion(m, label, curve=c, contacts=ct) for (_, m, c), label, ct in zip(panels, labels, contacts)]
    if args.at is not None:
        render_still(tracks, args.output, args.at, fps=args.fps or 30.0, panel_size=args.size, columns=args.columns)
        print(f"wrote {args.output}: frame at {args.at:g} s")
        return 0
    fps = args.fps or (25.0 if out_ext == ".gif" else 30.0)
    if args.columns is not None and args.columns < 1:
        raise RetimeError(f"--columns must be at least 1, got {args.columns}")
    info = render_video(tracks, args.output, fps=fps, panel_size=args.size, quiet=args.quiet, columns=args.columns)
    print(f"wrote {args.output}: {info['frames']} frames at {fps:g} fps, {info['duration']:.3f} s, "
          f"{info['width']}x{info['height']}, {len(tracks)} panel(s)")
    return 0


def _contacts(args, panels, motions):
    """Contacts per panel from a physics report: on every panel showing the first motion (itself or
    through a --warp) when the report names its source frames, else on the panel it was written for."""
    from ..viz.regions import contacts_through_curve, load_report, report_contacts, report_source_contacts

    report = load_report(args.report)
    first = motions[0]
    if all(f["source_frame"] is not None for f in report["frames"]):
        src = report_source_contacts(report, first.skeleton, first.n_frames, args.report)
        out = []
        for i, (_, m, curve) in enumerate(panels):
            if curve is not None:
                out.append(contacts_through_curve(src, first.fps, curve, m.n_frames, m.fps))
            elif i == 0:
                out.append(src)
            else:
                out.append(None)
        return out
    index = _report_panel(report, panels, args.report)
    out = [None] * len(panels)
    out[index] = report_contacts(report, panels[index][1].skeleton, panels[index][1].n_frames, args.report)
    return out


def _report_panel(report, panels, path) -> int:
    """The panel whose frame count matches the report's per-frame records (the last one that does)."""
    n = len(report["frames"])
    matches = [i for i, (_, m, _) in enumerate(panels) if m.n_frames == n]
    if not matches:
        counts = ", ".join(str(m.n_frames) for _, m, _ in panels)
        raise RetimeError(f"{path}: the report has {n} frames but the panels have {counts}; "
                          "give the motion the report was written for")
    return matches[-1]
