from ..errors import RetimeError
from ..method import Request, solve
from .common import add_duration_args, add_motion_args, add_output_args, check_output, load_input, write_outputs


def register(sub):
    p = sub.add_parser(
        "linear", help="uniform or keytime retiming (the baseline animation tools offer)",
        description="Retime uniformly to a new duration, or through keytimes, linearly or with a smooth monotone spline.",
        epilog="examples:\n  retime linear 16_06.amc -o fast.bvh --scale 0.5\n"
               "  retime linear 16_06.amc -o keyed.bvh --duration 2 --keytime 1.5=0.8 --smooth --warp keyed.csv",
        formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    add_motion_args(p)
    add_output_args(p)
    add_duration_args(p)
    p.add_argument("--smooth", action="store_true", help="smooth monotone spline through the keytimes instead of straight lines")
    p.set_defaults(func=run)


def run(args):
    from ..linear import Settings

    check_output(args)
    m = load_input(args)
    if args.duration is None and args.scale is None and not args.keytime:
        raise RetimeError("say how to retime: --duration SEC, --scale X or at least one --keytime SRC=DST")
    if m.n_frames < 2:
        raise RetimeError(f"{args.motion}: a single frame has no timing to change")
    result = solve("linear", m, Request(args.duration, args.scale, args.keytime, Settings(smooth=args.smooth)))
    write_outputs(args, "linear", m, result)
    return 0
