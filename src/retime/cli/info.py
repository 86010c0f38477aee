from ..motion.fk import rest_height
from .common import add_motion_args, load_input


def register(sub):
    p = sub.add_parser("info", help="describe a motion file", description="Print a motion's joints, DOFs, frames, rate and duration.",
                       epilog="example: retime info 16_06.amc")
    add_motion_args(p)
    p.set_defaults(func=run)


def run(args):
    m = load_input(args)
    sk = m.skeleton
    print(f"file      {args.motion}")
    print(f"joints    {sk.n_joints} ({len(sk.end_sites)} end sites)")
    print(f"dofs      {sk.n_dofs}")
    print(f"frames    {m.n_frames}")
    print(f"fps       {m.fps:g}")
    print(f"duration  {m.duration:.4f} s")
    print(f"height    {rest_height(sk) * sk.meters_per_unit:.2f} m (1 unit = {sk.meters_per_unit:g} m)")
    for j, name in enumerate(sk.names):
        parent = sk.names[sk.parents[j]] if sk.parents[j] >= 0 else "-"
        print(f"  {name:<16} parent {parent:<16} dof {' '.join(sk.dof[j]) or '-'}")
    return 0
