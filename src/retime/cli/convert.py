from ..motion import save_motion
from .common import add_motion_args, check_output, load_input


def register(sub):
    p = sub.add_parser("convert", help="convert a motion to BVH, FBX or glTF",
                       description="Convert a motion (BVH, ASF/AMC, FBX, glTF) to BVH, or to FBX/glTF through Blender.",
                       epilog="example: retime convert 16_06.amc 16_06.bvh")
    add_motion_args(p)
    p.add_argument("output", metavar="OUT.bvh")
    p.set_defaults(func=run)


def run(args):
    check_output(args)  # a .bvh that is not one of the inputs, checked before the (slow) load
    m = load_input(args)
    save_motion(m, args.output, source=args.motion)
    print(f"wrote {args.output}: {m.n_frames} frames at {m.fps:g} fps")
    return 0
