"""Propagating a hand-made timing edit (Hsu et al. 2007, V7): one gait cycle of a walk is retimed by hand
with keytimes to look like a limp (the step onto one foot hurried, the other lingered on); guided time warping
with that edited cycle as the only reference gives the whole walk the same limp, at the walk's own duration.

    python3 examples/guided_limp.py [OUT_DIR] [--data DIR]

Writes OUT_DIR/limp_reference.bvh (the hand-edited cycle), OUT_DIR/limp_walk.{bvh,csv,png}; prints how long
each foot's stance lasts before and after, in the reference and in the output.
"""
from __future__ import annotations

import numpy as np
from guided_common import load, parse_args, write_result

from retime.guided import guided_solve
from retime.motion import forward_kinematics, save_bvh
from retime.warp import apply_timing, keytime_warp


def stances(motion, curve=None):
    """Mean output duration of left and right stance phases (foot below its 30th height percentile)."""
    pos, _ = forward_kinematics(motion)
    names = motion.skeleton.names
    out = []
    for foot in ("lfoot", "rfoot"):
        h = pos[:, names.index(foot), 1]
        down = h < np.percentile(h, 30)
        edges = np.flatnonzero(np.diff(down.astype(int)))
        spans = [(a + 1, b) for a, b in zip(edges[:-1], edges[1:]) if down[a + 1]]
        if not spans:
            out.append(float("nan"))
            continue
        ds = []
        for a, b in spans:
            s0, s1 = a / motion.fps, b / motion.fps
            ds.append((curve.inverse(s1) - curve.inverse(s0)) if curve is not None else s1 - s0)
        out.append(float(np.mean(ds)))
    return out


def main():
    args = parse_args(__doc__.split("\n")[0])
    walk = load("16_16.amc", args.data)
    if walk is None:
        return
    # one gait cycle, hand-edited: the first half (one step) hurried, the second lingered on
    a, b = 1.4, 2.5
    cycle = walk.frames(slice(int(a * walk.fps), int(b * walk.fps) + 1))
    L = cycle.duration
    manual = keytime_warp(L, keytimes=[(0.5 * L, 0.3 * 1.25 * L)], duration=1.25 * L)
    reference = apply_timing(cycle, manual)
    save_bvh(reference, f"{args.out}/limp_reference.bvh")
    write_result(args.out, "limp_reference_edit", cycle, manual, "the hand-made edit of one gait cycle (keytimes)",
                 retimed=reference)
    res = guided_solve(walk, reference=reference, upsample=4)
    write_result(args.out, "limp_walk", walk, res.curve, "16_16 walk with the edited cycle as reference")
    print(f"walk {walk.duration:.2f} s -> {res.curve.duration:.2f} s; grid n={res.n}, m={res.m}, r={res.r}")
    l0, r0 = stances(walk)
    print(f"stance (s)      left   right")
    print(f"original      {l0:6.3f}  {r0:6.3f}")
    lr, rr = stances(cycle, manual)
    print(f"reference     {lr:6.3f}  {rr:6.3f}   (the edited cycle)")
    lo, ro = stances(walk, res.curve)
    print(f"output        {lo:6.3f}  {ro:6.3f}")
    print(f"wrote BVH, CSV and PNG files to {args.out}")


if __name__ == "__main__":
    main()
