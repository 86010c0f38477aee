"""Guided time warping on steady motion: do walks and runs play at a steady speed, do jumps keep their
flight, do the ends stay within the skip limit? Issue 23.

For every walk, run and jump in the dev data (CMU and bvh-dev, classified as in their READMEs) and the
clips bundled with retime, ``retime guided`` (the input as its own reference) at --scale 0.6 and 1.5,
with the steady score (the default) and the paper's, printing:
  cv, max/min  coefficient of variation and max/min of the per-frame playback speed over the middle
               90% of the output (walks and runs)
  flights      mean playback speed over each flight (jumps: the longest; runs: all, for the record)
  first, last  playback speed of the first and last output step, and the skip limit there
  pace         (walks and runs) max/min of the clip's own travel speed (the floating base's, along the
               floor) over six equal parts of its middle 90%: above 1.3 the reference itself changes
               pace (a start from standing, a turn, stops), and guided keeps the timing of each part
Targets: walks and runs cv <= 0.05 and max/min <= 1.3; jump flights 1.00 +- 0.05; no end step above
the skip limit (max_skip / upsampling).

Usage: python3 benchmarks/guided_steady.py [--data DIR] [--json] [--score steady|paper|both]
       [--clips TEXT ...] [--kinds walk,run,...] [--scales 0.6,1.5]
--clips keeps the clips whose key (e.g. cmu/16_15.amc) contains one of the texts; --kinds and --scales
keep those kinds and scales (a subset for a quick look; the targets are judged on what ran).
Exit code 1 if a target of the steady score is missed.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from retime.guided.api import guided_solve
from retime.motion import load_motion
from retime.phases import flights, longest_flight, interval_speed

SCALES = (0.6, 1.5)
CV_TARGET = 0.05
RATIO_TARGET = 1.3
FLIGHT_TOLERANCE = 0.05
MIDDLE = 0.9

CLIPS = {  # file: kind, from the data READMEs (cmu/README.md "Index by motion type", bvh-dev/README.md)
    "cmu/16_15.amc": "walk", "cmu/16_16.amc": "walk", "cmu/16_22.amc": "walk", "cmu/16_31.amc": "walk",
    "cmu/16_17.amc": "walk", "bvh-dev/AV_8Walk_Meredith_HVHA_Rep1.bvh": "walk",
    "bvh-dev/woddy2_walk_straight_fast.bvh": "walk",
    "cmu/16_35.amc": "run", "cmu/16_45.amc": "run", "cmu/16_55.amc": "run", "bvh-dev/run.bvh": "run",
    "cmu/16_01.amc": "jump", "cmu/16_03.amc": "jump", "cmu/13_39.amc": "jump", "cmu/02_04.bvh": "jump",
    "cmu/16_05.amc": "jump", "cmu/16_06.amc": "jump", "cmu/16_09.amc": "jump", "cmu/13_11.amc": "jump",
    "cmu/118_26.amc": "jump", "bvh-dev/01_01.bvh": "jump", "bvh-dev/jumping.bvh": "jump",
    "bvh-dev/wd2_short_broad_jump.bvh": "jump",
    "bundled/16_33.amc": "other", "bundled/131_01.bvh": "other",  # walk to a stop; stand, walk, stop
}


def find_data(given):
    here = Path(__file__).resolve().parent
    for d in ([given] if given else []) + [here.parent.parent / "shared" / "data", Path("/work/shared/data")]:
        if d and (Path(d) / "cmu").is_dir():
            return Path(d)
    return None


def clip_path(data, key):
    folder, name = key.split("/", 1)
    if folder == "bundled" or data is None:
        from retime.data import bundled_path

        try:
            return Path(bundled_path(name))
        except FileNotFoundError:
            return None
    p = data / folder / name
    return p if p.exists() else None


def step_speeds(curve, fps):
    """Playback speed of every output step at the clip's rate (source s per output s)."""
    t = curve.frame_times(fps)
    return np.diff(curve(t)) / np.diff(t)


def measure(motion, kind, contact_flights, scale, score):
    t0 = time.perf_counter()
    res = guided_solve(motion, scale=scale, score=score)
    seconds = time.perf_counter() - t0
    v = step_speeds(res.curve, motion.fps)
    cut = int(round(len(v) * (1 - MIDDLE) / 2))
    mid = v[cut:len(v) - cut] if len(v) > 2 * cut + 2 else v
    limit_first = res.s / res.upsample[0]  # the skip limit the solve kept, in the clip's speed
    limit_last = res.s / res.upsample[-1]
    row = {"score": score, "scale": scale, "cv": float(mid.std() / mid.mean()), "ratio": float(mid.max() / mid.min()),
           "first": float(v[0]), "last": float(v[-1]), "limit_first": limit_first, "limit_last": limit_last,
           "seconds": seconds, "flights": [interval_speed(res.curve, a, b) for a, b in contact_flights]}
    row["ends_ok"] = bool(v[0] <= limit_first + 1e-9 and v[-1] <= limit_last + 1e-9)
    if kind in ("walk", "run"):
        row["steady_ok"] = bool(row["cv"] <= CV_TARGET and row["ratio"] <= RATIO_TARGET)
    if kind == "jump":
        row["flight_ok"] = bool(row["flights"] and abs(row["flights"][0] - 1.0) <= FLIGHT_TOLERANCE)
    return row


PACE_PARTS = 6


def pace_ratio(motion):
    """max/min of the floating base's speed along the floor over PACE_PARTS parts of the middle 90%."""
    from retime.motion import forward_kinematics
    from retime.motion.frame import up_vector
    from retime.motion.rig import floating_base

    pos, _ = forward_kinematics(motion, motion.rotations, motion.translations)
    base = pos[:, floating_base(motion.skeleton)] * float(motion.skeleton.meters_per_unit)
    up = up_vector(motion.skeleton.up)
    along_floor = base - np.outer(base @ up, up)
    speed = np.linalg.norm(np.diff(along_floor, axis=0), axis=1) * motion.fps
    cut = int(round(len(speed) * (1 - MIDDLE) / 2))
    parts = [p.mean() for p in np.array_split(speed[cut:len(speed) - cut], PACE_PARTS) if p.size]
    return float(max(parts) / min(parts)) if parts and min(parts) > 0 else float("inf")


def clip_flights(motion, kind):
    from retime.motion.feet import foot_contacts

    if kind not in ("jump", "run"):
        return []
    contact = foot_contacts(motion)
    if kind == "jump":
        f = longest_flight(contact, np.arange(motion.n_frames) / motion.fps)  # the flight the demo and reports give
        return [f] if f else []
    return flights(contact, motion.fps, min_frames=2)


def fmt_row(name, kind, r, pace):
    fl = " ".join(f"{s:.2f}" for s in r["flights"][:4]) + (" ..." if len(r["flights"]) > 4 else "")
    marks = []
    if "steady_ok" in r:
        marks.append("steady" if r["steady_ok"] else "UNSTEADY")
    if "flight_ok" in r:
        marks.append("flight" if r["flight_ok"] else "FLIGHT")
    marks.append("ends" if r["ends_ok"] else "ENDS")
    return (f"{name:36.36} {kind:5} {r['score']:6} {r['scale']:4.1f} | {r['cv']:6.3f} {r['ratio']:6.2f} | "
            f"{fl:22} | {r['first']:5.2f} {r['last']:5.2f} (<= {r['limit_first']:g}) | "
            f"{'-' if pace is None else format(pace, '.2f'):>5} | {r['seconds']:5.2f} s | {' '.join(marks)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", help="folder holding cmu/ and bvh-dev/ (default ../shared/data)")
    ap.add_argument("--json", action="store_true", help="one JSON object per clip, scale and score")
    ap.add_argument("--score", choices=("steady", "paper", "both"), default="both")
    ap.add_argument("--clips", nargs="+", help="only clips whose key contains one of these texts")
    ap.add_argument("--kinds", help="only these kinds, comma-separated (walk, run, jump, other)")
    ap.add_argument("--scales", help="only these scales, comma-separated (default 0.6,1.5)")
    args = ap.parse_args(argv)
    kinds = set(args.kinds.split(",")) if args.kinds else None
    try:
        scales = tuple(float(x) for x in args.scales.split(",")) if args.scales else SCALES
    except ValueError:
        ap.error(f"--scales takes numbers separated by commas, got {args.scales!r}")
    data = find_data(args.data)
    if data is None:
        print("dev data not found: only the bundled clips are measured", file=sys.stderr)
    scores = ("steady", "paper") if args.score == "both" else (args.score,)
    ok = True
    if not args.json:
        print(f"{'clip':36} {'kind':5} {'score':6} {'x':>4} | {'cv':>6} {'max/mn':>6} | {'flight speeds':22} | "
              f"first  last (limit) |  pace | time    | targets")
    for key, kind in CLIPS.items():
        if (kinds and kind not in kinds) or (args.clips and not any(c in key for c in args.clips)):
            continue
        path = clip_path(data, key)
        if path is None:
            print(f"{key}: not found, skipped", file=sys.stderr)
            continue
        motion = load_motion(str(path))
        fl = clip_flights(motion, kind)
        pace = pace_ratio(motion) if kind in ("walk", "run") else None
        for scale in scales:
            for score in scores:
                r = measure(motion, kind, fl, scale, score)
                if score == "steady":
                    ok &= r["ends_ok"] and r.get("steady_ok", True) and r.get("flight_ok", True)
                if args.json:
                    print(json.dumps({"clip": key, "kind": kind, "pace": pace, **r}))
                else:
                    print(fmt_row(key, kind, r, pace))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
