"""Emphasis with a free duration (Hsu et al. 2007, V8): a jump whose flight was slowed down by hand is the
reference; the unconstrained search (no target duration) slows down the flight of other jumps the same way.

    python3 examples/guided_emphasis.py [OUT_DIR] [--data DIR]

The reference is 16_06 around its jump, its flight played at a third of its speed with keytimes. Velocity
and acceleration weigh more here than by default (1 s and 0.1 s^2 instead of 0.1 s and 0.01 s^2): the free
search pays for every output frame, so it slows down only where playing faster would look clearly wrong
against the reference; with the defaults it keeps speeding through. Writes OUT_DIR/emphasis_reference.bvh
and OUT_DIR/emphasis_<clip>.{bvh,csv,png}; prints each output's flight speed (below 1 = slow motion).
"""
from __future__ import annotations

from guided_common import load, parse_args, write_result

from retime.guided import FeatureWeights, guided_solve
from retime.guided.evaluate import flight_phases, interval_speed
from retime.motion import save_bvh
from retime.warp import apply_timing, keytime_warp

INPUTS = ["16_03.amc", "16_05.amc", "16_01.amc", "13_11.amc"]
SLOW = 3.0
WEIGHTS = FeatureWeights(pose=1.0, velocity=1.0, acceleration=0.1)


def main():
    args = parse_args(__doc__.split("\n")[0])
    jump = load("16_06.amc", args.data)
    if jump is None:
        return
    (fa, fb), = flight_phases(jump)[:1]
    a, b = max(0.0, fa - 0.6), min(jump.duration, fb + 0.6)  # a brief portion around the jump
    part = jump.frames(slice(int(a * jump.fps), int(b * jump.fps) + 1))
    fa, fb = fa - int(a * jump.fps) / jump.fps, fb - int(a * jump.fps) / jump.fps
    T = part.duration + (SLOW - 1) * (fb - fa)
    manual = keytime_warp(part.duration, keytimes=[(fa, fa), (fb, fa + SLOW * (fb - fa))], duration=T)
    reference = apply_timing(part, manual)
    save_bvh(reference, f"{args.out}/emphasis_reference.bvh")
    print(f"reference: 16_06 {a:.2f}-{b:.2f} s, flight slowed {SLOW:g}x by hand ({reference.duration:.2f} s)")
    print(f"{'clip':12}{'input':>8}{'output':>8}{'flight speed':>14}")
    for name in INPUTS:
        motion = load(name, args.data)
        if motion is None:
            continue
        res = guided_solve(motion, reference=reference, free=True, weights=WEIGHTS)
        curve = res.curve
        flights = flight_phases(motion)
        write_result(args.out, f"emphasis_{name.split('.')[0]}", motion, curve,
                     f"{name}: free duration, slowed-down jump as reference",
                     spans=[(x, y, "flight") for x, y in flights])
        fl = " ".join(f"{interval_speed(curve, x, y):.2f}" for x, y in flights) or "-"
        print(f"{name:12}{motion.duration:7.2f}s{curve.duration:7.2f}s{fl:>14}")
    print(f"wrote BVH, CSV and PNG files to {args.out}")


if __name__ == "__main__":
    main()
