"""Preservation (Hsu et al. 2007, V1-V5): shorten jumps and walks to 60% and lengthen them to 150%
with the clip as its own reference. Ballistic flight should keep its natural speed while the rest of
the clip absorbs the change; a linear warp speeds everything up alike.

    python3 examples/guided_preservation.py [OUT_DIR] [--data DIR]

Writes OUT_DIR/preserve_<clip>_<percent>.{bvh,csv,png} and prints, for each jump, the playback speed of
its flight phase (1.0 = natural) next to the clip's overall speed.
"""
from __future__ import annotations

from guided_common import load, parse_args, speed_where, write_result

from retime.guided import guided_solve
from retime.guided.evaluate import flight_phases, interval_speed
from retime.warp import scale_warp

JUMPS = ["16_06.amc", "16_03.amc", "13_11.amc", "118_26.amc", "16_05.amc"]
WALKS = ["16_15.amc", "16_16.amc"]


def main():
    args = parse_args(__doc__.split("\n")[0])
    print(f"{'clip':12}{'scale':>7}{'duration':>10}{'overall':>9}{'flight':>9}  (speeds: 1.00 = natural)")
    for name in JUMPS + WALKS:
        motion = load(name, args.data)
        if motion is None:
            continue
        flights = flight_phases(motion) if name in JUMPS else []
        for scale in (0.6, 1.5):
            res = guided_solve(motion, scale=scale)
            curve = res.curve
            linear = scale_warp(motion.duration, scale, motion.fps)
            stem = f"preserve_{name.split('.')[0]}_{int(round(scale * 100))}"
            spans = [(a, b, "flight") for a, b in flights]
            write_result(args.out, stem, motion, curve,
                         f"{name}: {int(round(scale * 100))}% duration, itself as reference",
                         others=[("linear", linear)], spans=spans)
            overall = motion.duration / curve.duration
            fl = " ".join(f"{interval_speed(curve, a, b):.2f}" for a, b in flights) or "-"
            print(f"{name:12}{scale:7.2f}{curve.duration:9.3f}s{overall:9.2f}{fl:>9}")
            if not flights:  # walks: the gait plays at a nearly even speed
                even = speed_where(curve, lambda s: s >= 0)
                print(f"{'':12}{'':7}{'':10} mean speed {even:.2f} (log-average)")
    print(f"wrote BVH, CSV and PNG files to {args.out}")


if __name__ == "__main__":
    main()
