"""Silence removal (Hsu et al. 2007, V1-V3): shorten clips with still or slow stretches to 60% with the clip
as its own reference. The warp should speed through the low-activity parts and leave the active parts near
their own speed; no threshold decides what "still" is.

    python3 examples/guided_silence.py [OUT_DIR] [--data DIR]

Writes OUT_DIR/silence_<clip>.{bvh,csv,png}; prints the log-average playback speed over the calmest and the
busiest quarter of the clip (by joint speed in the root frame).
"""
from __future__ import annotations

import numpy as np
from guided_common import load, parse_args, speed_where, write_result

from retime.guided import guided_solve
from retime.guided.features import analysis_poses
from retime.warp import scale_warp

CLIPS = ["131_01.bvh", "16_33.amc", "131_03.bvh", "13_29.amc"]


def activity(motion, fps=30.0):
    """(times, mean joint speed in m/s) of a clip, root-frame joints plus the root's travel."""
    x = analysis_poses(motion, fps)
    v = np.linalg.norm(np.diff(x.reshape(len(x), -1, 3), axis=0), axis=2).mean(axis=1) * fps
    root = motion.root_positions * motion.skeleton.meters_per_unit
    t = np.arange(len(v)) / fps + 0.5 / fps
    rv = np.linalg.norm(np.diff(root, axis=0), axis=1) * motion.fps
    return t, v + np.interp(t, np.arange(len(rv)) / motion.fps, rv)


def main():
    args = parse_args(__doc__.split("\n")[0])
    print(f"{'clip':12}{'length':>9}{'output':>9}{'overall':>9}{'calm':>8}{'busy':>8}   (playback speeds)")
    for name in CLIPS:
        motion = load(name, args.data)
        if motion is None:
            continue
        if name == "13_29.amc":  # the paper's V1 shape: 16.4 s of exercises and pauses
            motion = motion.frames(slice(0, int(16.4 * motion.fps) + 1))
        t, act = activity(motion)
        calm_thr, busy_thr = np.percentile(act, [25, 75])
        res = guided_solve(motion, scale=0.6)
        curve = res.curve
        calm = speed_where(curve, lambda s: np.interp(s, t, act) <= calm_thr)
        busy = speed_where(curve, lambda s: np.interp(s, t, act) >= busy_thr)
        stem = f"silence_{name.split('.')[0]}"
        write_result(args.out, stem, motion, curve, f"{name}: 60% duration, itself as reference",
                     others=[("linear", scale_warp(motion.duration, 0.6, motion.fps))])
        print(f"{name:12}{motion.duration:8.2f}s{curve.duration:8.2f}s{motion.duration / curve.duration:9.2f}"
              f"{calm:8.2f}{busy:8.2f}")
    print(f"wrote BVH, CSV and PNG files to {args.out}")


if __name__ == "__main__":
    main()
