"""Style from another clip (Hsu et al. 2007, V6): a weak boxing passage takes the timing of an aggressive one.

Both passages come from CMU 13_17 (boxing): the 10-second window with the slowest hands is the input, the one
with the fastest hands the reference. The output keeps the input's duration; the input is upsampled so that
the warp may slow down as well as speed up.

    python3 examples/guided_style.py [OUT_DIR] [--data DIR]

Writes OUT_DIR/style_boxing.{bvh,csv,png} (and the input and reference passages as BVH); prints the playback
speed during the input's punches and between them.
"""
from __future__ import annotations

import numpy as np
from guided_common import load, parse_args, speed_where, write_result

from retime.guided import guided_solve
from retime.guided.features import root_frame_poses
from retime.motion import save_bvh

WINDOW = 10.0


def hand_speed(motion):
    names = motion.skeleton.names
    hands = [names.index(h) for h in ("lhand", "rhand") if h in names] or [len(names) - 1]
    p = root_frame_poses(motion)[:, hands]
    return np.linalg.norm(np.diff(p, axis=0), axis=2).max(axis=1) * motion.fps


def main():
    args = parse_args(__doc__.split("\n")[0])
    box = load("13_17.amc", args.data)
    if box is None:
        print("13_17.amc (boxing) is needed for this example: give --data with the CMU clips")
        return
    speed = hand_speed(box)
    w = int(WINDOW * box.fps)
    starts = np.arange(0, len(speed) - w, int(box.fps))
    mean = np.array([speed[a:a + w].mean() for a in starts])
    weak, strong = int(starts[np.argmin(mean)]), int(starts[np.argmax(mean)])
    if abs(weak - strong) < w:  # keep the passages apart
        strong = int(starts[np.argmax(np.where(np.abs(starts - weak) >= w, mean, -1))])
    src = box.frames(slice(weak, weak + w + 1))
    ref = box.frames(slice(strong, strong + w + 1))
    save_bvh(src, f"{args.out}/style_input.bvh")
    save_bvh(ref, f"{args.out}/style_reference.bvh")
    res = guided_solve(src, reference=ref)
    curve = res.curve
    hs = hand_speed(src)
    t = (np.arange(len(hs)) + 0.5) / src.fps
    thr = np.percentile(hs, 70)
    punch = speed_where(curve, lambda s: np.interp(s, t, hs) >= thr)
    rest = speed_where(curve, lambda s: np.interp(s, t, hs) < thr)
    write_result(args.out, "style_boxing", src, curve,
                 f"13_17 boxing {weak / box.fps:.0f}-{weak / box.fps + WINDOW:.0f} s timed like "
                 f"{strong / box.fps:.0f}-{strong / box.fps + WINDOW:.0f} s")
    print(f"input passage {weak / box.fps:.1f} s (mean hand speed {mean.min():.2f} m/s), reference "
          f"{strong / box.fps:.1f} s ({mean.max():.2f} m/s)")
    print(f"output {curve.duration:.2f} s (input {src.duration:.2f} s), upsampling {res.upsample}, objective "
          f"{res.objective:.3g}")
    print(f"playback speed during punches {punch:.2f}, between punches {rest:.2f}")
    print(f"wrote BVH, CSV and PNG files to {args.out}")


if __name__ == "__main__":
    main()
