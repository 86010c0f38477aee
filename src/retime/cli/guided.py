"""``retime guided``: guided time warping (Hsu, da Silva, Popović 2007)."""
from __future__ import annotations

import argparse

from ..errors import RetimeError
from ..guided.limits import MAX_SKIP_LIMIT
from ..guided.features import FeatureWeights
from ..guided.method import SCORES, Settings
from ..method import Request, solve
from ..motion import load_motion
from .common import check_found_inputs, frame_kwargs, add_duration_args, add_motion_args, add_output_args, check_output, load_input, nonnegative_float, positive_float, positive_int, unit_float, write_outputs


def register(sub):
    p = sub.add_parser(
        "guided", help="retime so that local velocities and accelerations match a reference (Hsu et al. 2007)",
        description=(
            "Guided time warping: the warp through the keytimes whose local velocities and accelerations "
            "best match a reference motion, found exactly by dynamic programming. The default reference is the "
            "input itself: a jump's flight keeps its natural speed while the rest plays at one steady speed "
            "(with --pace 0, or --score paper, idle stretches are sped through, or slowed down when lengthening)."),
        epilog=(
            "examples:\n"
            "  retime guided 16_06.amc -o short.bvh --scale 0.6 --warp short.csv\n"
            "  retime guided 16_06.amc -o long.bvh --duration 5 --fast\n"
            "  retime guided weak.bvh -o strong.bvh --reference aggressive.bvh\n"
            "  retime guided jumps.bvh -o slowmo.bvh --reference slowmo_jump.bvh --free\n"
            "  retime guided walk.amc -o keyed.bvh --duration 3 --keytime 1.2=0.9 --keytime 2.5=2.2"),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_motion_args(p)
    add_output_args(p)
    add_duration_args(p, free=True)
    p.add_argument("--reference", metavar="REF", help="motion whose timing to imitate (same skeleton; default: the input)")
    p.add_argument("--reference-fps", type=positive_float, metavar="HZ", help="frame rate of an .amc reference (default 120)")
    d = Settings()  # every default below is Settings', passed on only when given
    p.add_argument("--max-skip", type=int, metavar="S",
                   help="skip limit: an output frame advances at most S grid frames, so playback is at most S times "
                        f"the original speed (S/U when the grid is upsampled U times; default {d.max_skip}, "
                        f"at most {MAX_SKIP_LIMIT})")
    p.add_argument("--neighbors", type=int, metavar="K",
                   help=f"nearest reference features per score (default {d.neighbors})")
    p.add_argument("--fast", action="store_true", help="coarse-to-fine heuristic instead of the exact search (not with --free)")
    w = FeatureWeights()
    p.add_argument("--weights", type=weights_arg, metavar="P,V,A[,H]",
                   help="feature weights: pose, velocity (s), acceleration (s^2) and root height "
                        f"(default {w.pose:g},{w.velocity:g},{w.acceleration:g},{w.root_height:g}; "
                        "H=0 gives the paper's torso-frame features only)")
    p.add_argument("--analysis-fps", type=positive_float, metavar="HZ",
                   help=f"rate of the search (default {d.analysis_fps:g} Hz, as in the paper)")
    p.add_argument("--upsample", type=int, metavar="U",
                   help="grid frames per analysis frame (default: automatic; more lets the warp slow down further)")
    p.add_argument("--smoothing", type=positive_int, metavar="W",
                   help=f"moving-average window of the warp in analysis frames (default {d.smoothing}; 1 = none)")
    p.add_argument("--adaptive-smoothing", action="store_true",
                   help="average each output frame over the source time it covers (window = local compression)")
    p.add_argument("--approx", type=nonnegative_float, metavar="EPS",
                   help="approximate nearest neighbours (KD-tree) with relative error EPS, for long references")
    p.add_argument("--score", choices=SCORES,
                   help=f"local score: steady{' (default' if d.score == 'steady' else ''}; sub-frame steps and a convex "
                        "penalty on speed changes, so a steady motion plays at a steady speed) or "
                        f"paper{' (default)' if d.score == 'paper' else ''} (Hsu et al.'s eq. 2 on whole grid frames)")
    p.add_argument("--steadiness", type=nonnegative_float, metavar="L",
                   help=f"steady score: weight of the speed-change penalty (default {d.steadiness:g}; lower keeps short "
                        "flights at their speed, higher plays more evenly)")
    p.add_argument("--pace", type=nonnegative_float, metavar="P",
                   help=f"steady score: pull of every step to one steady speed, and of a jump's flight to its natural "
                        f"speed, in units of the speed-change penalty (default {d.pace:g}; 0 keeps the reference's "
                        "changes of pace, as a walk slowing in a turn)")
    p.add_argument("--blend", type=unit_float, metavar="W",
                   help="the reference's influence from 0 (the keytime spline warp, as linear --smooth) to 1 "
                        f"(the guided warp; default {d.blend:g})")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=run)


def weights_arg(text):
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"weights must be 3 or 4 numbers like 1,0.1,0.01, got {text!r}") from None
    if len(vals) not in (3, 4):
        raise argparse.ArgumentTypeError(f"weights must be 3 or 4 numbers like 1,0.1,0.01, got {text!r}")
    try:
        return FeatureWeights(*vals)
    except RetimeError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def run(args):
    check_output(args)
    motion = load_input(args)
    if motion.n_frames < 2:
        raise RetimeError(f"{args.motion}: a single frame has no timing to change")
    reference = None
    if args.reference:
        reference = load_motion(args.reference, fps=args.reference_fps, **frame_kwargs(args))
        check_found_inputs(args, reference)
    from ..guided import adaptive_smooth

    options = ("max_skip", "neighbors", "analysis_fps", "weights", "upsample", "smoothing", "score", "steadiness", "pace", "blend")
    given = {k: getattr(args, k) for k in options if getattr(args, k) is not None}
    if args.approx is not None:
        given.update(knn="approx", eps=args.approx)
    settings = Settings(reference=reference, free=bool(getattr(args, "free", False)), fast=args.fast,
                        progress=not args.quiet, **given)
    answer = solve("guided", motion, Request(args.duration, args.scale, args.keytime, settings))
    retimed = adaptive_smooth(motion, answer.curve) if args.adaptive_smoothing else None  # None: through the curve
    write_outputs(args, "guided", motion, answer, retimed)
    if not args.quiet:
        i, t = answer.info, answer.report.summary["timings"]
        kind = "exact" if i["exact"] else "heuristic"
        print(f"objective {i['objective']:.4g} ({kind}; n={i['n']}, m={i['m']}, r={i['r']}, s={i['s']}, "
              f"k={i['k']}); scores {t['scores']:.3f} s, search {t['search']:.3f} s")
    return 0
