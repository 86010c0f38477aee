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
    g = sk.frame
    if g is not None:
        up_how = "given" if g.up_given else f"detected, {g.up_confidence:.0%} of frames agree"
        print(f"up        {g.up} ({up_how})")
        from ..motion.frame import UNIT_NAMES

        print(f"units     {UNIT_NAMES.get(g.unit, g.unit)} (1 unit = {sk.meters_per_unit:.6g} m; {g.unit_confidence})")
        if g.limbs is not None:
            top = "head" if g.limbs.head is not None else "root"
            print(f"size      {top} {g.height_m:.2f} m above the feet, legs {g.leg_m:.2f} m (limbs found by {g.limbs.how})")
        else:
            print(f"size      rest pose {rest_height(sk) * sk.meters_per_unit:.2f} m tall; not a biped ({g.biped})")
    print(f"angles    {'radians (detected)' if sk.angles == 'rad' and not getattr(args, 'angles', None) else sk.angles}")
    from ..motion.conform import BoneStretch, conform

    try:
        conformed = conform(m)
    except BoneStretch as e:
        print(f"bones     {e}")
    else:
        for note in conformed.notes():
            print(f"physics   {note}")
        if conformed.fixed_bones:
            print(f"physics   {len(conformed.fixed_bones)} joint(s) with constant position channels read as fixed bones")
    for j, name in enumerate(sk.names):
        parent = sk.names[sk.parents[j]] if sk.parents[j] >= 0 else "-"
        print(f"  {name:<16} parent {parent:<16} dof {' '.join(sk.dof[j]) or '-'}")
    return 0
