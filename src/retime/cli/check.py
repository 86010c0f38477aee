"""``retime check``: is a clip physical as captured? A linter's exit code: 0 yes, 1 no, 2 bad input,
3 physical with a caution (the frame rate or the length unit could not be confirmed)."""
from __future__ import annotations

import argparse

from ..errors import RetimeError
from ..io_util import check_outputs
from .common import add_motion_args, load_input

EPILOG = """examples:
  retime check 16_06.amc                       physical: exit 0
  retime check walk.bvh --report walk.json --plot walk.png
  retime check jump.bvh --up x                 the wrong up axis: not physical, exit 1

Per frame: the residual force no contact can give, torques over their limits, the centre of mass's
acceleration in flight against g and foot sliding in stance; the verdict and its likely causes."""


def register(sub):
    p = sub.add_parser("check", help="is a motion physical as captured? (exit 0 yes, 1 no, 2 bad input, 3 yes with a caution)",
                       description="Check the physical plausibility of a motion's own timing, frame by frame.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_motion_args(p)
    p.add_argument("--report", metavar="REPORT.json", help="per-frame numbers and the summary as JSON")
    p.add_argument("--plot", metavar="PLOT.png", help="the residual over time with the stance/flight strip (.png/.svg/.pdf)")
    p.add_argument("--body", metavar="BODY.toml", help="body model (as for retime physics)")
    p.add_argument("--contacts", metavar="CONTACTS.csv", help="foot contact states (default: detected)")
    p.set_defaults(func=run)


def run(args):
    from ..physics.check import check_clip
    from ..viz.plot import check_plot_path

    if args.plot:
        check_plot_path(args.plot)  # before the check's minutes of work
    check_outputs([args.report, args.plot], [args.motion, args.asf, args.body, args.contacts])
    motion = load_input(args)
    if motion.n_frames < 4:
        raise RetimeError(f"{args.motion}: checking needs at least 4 frames, the motion has {motion.n_frames}")
    result = check_clip(motion, body=args.body, contacts=args.contacts)
    for note in result.notes:
        print(f"note: {note}")
    print(f"{args.motion}: {result.verdict_line()}")
    worst = result.worst_frames()
    if worst:
        print("worst frames: " + ", ".join(f"{i} ({result.times[i]:.2f} s, {result.residual[i]:.2f} body weights)"
                                           for i in worst))
    from ..outputs import write_check

    write_check(result, args.report, args.plot, title=args.motion)
    if not result.physical:
        return 1
    return 3 if result.verdict.cautions else 0
