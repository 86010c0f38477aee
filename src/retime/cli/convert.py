from ..motion import save_bvh
from .common import add_motion_args, check_output, load_input


def register(sub):
    p = sub.add_parser("convert", help="convert a motion to BVH", description="Convert a motion (BVH or ASF/AMC) to BVH.",
                       epilog="example: retime convert 16_06.amc 16_06.bvh")
    add_motion_args(p)
    p.add_argument("output", metavar="OUT.bvh")
    p.set_defaults(func=run)


def run(args):
    check_output(args)  # a .bvh that is not one of the inputs, checked before the (slow) load
    m = load_input(args)
    save_bvh(m, args.output)
    print(f"wrote {args.output}: {m.n_frames} frames at {m.fps:g} fps")
    return 0
