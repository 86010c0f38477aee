"""Issue 4's acceptance checks on jump clips: half duration and a quarter of gravity.

For every clip: at half its duration, the flight's playback speed (the longest stretch with no foot
down, as the demo finds it) and the report's ``feasible_fraction`` (wanted: flight 0.8-1.3x,
feasible >= 0.9); at a quarter of gravity with free duration, the same (wanted: flight 0.42-0.6x,
feasible >= 0.9); and the clip's least physical duration (:mod:`retime.physics.timing.fastest`). Both
optimizer starts can be compared with ``--start``.

    python3 benchmarks/physics_jumps.py                       # the jumps in ../shared/data/cmu
    python3 benchmarks/physics_jumps.py DIR/16_07.amc ...     # any clips (X_NN.amc finds X.asf beside it)
    python3 benchmarks/physics_jumps.py --start uniform
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from retime.motion import load_motion
from retime.physics.api import physics_warp
from retime.report.demo import flight_phase, flight_speed

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "cmu"
JUMPS = ["16_01.amc", "16_03.amc", "16_05.amc", "16_06.amc", "16_09.amc", "13_11.amc", "13_39.amc", "118_26.amc",
         "02_04.bvh"]
CASES = {"half": dict(scale=0.5), "quarter_g": dict(gravity=(0.0, -9.81 / 4, 0.0))}
WANTED = {"half": (0.8, 1.3), "quarter_g": (0.42, 0.6)}


def check(path, start="global"):
    m = load_motion(path)
    flight = flight_phase(m)
    rows = []
    for case, kw in CASES.items():
        t0 = time.perf_counter()
        r = physics_warp(m, start=start, **kw)
        s = r.report["summary"]
        fs = flight_speed(r.curve, flight)
        lo, hi = WANTED[case]
        ok = fs is not None and lo <= fs <= hi and s["feasible_fraction"] >= 0.9
        rows.append({"clip": Path(path).name, "case": case, "duration": s["duration"], "source": s["source_duration"],
                     "flight_speed": fs, "feasible": s["feasible_fraction"], "least_duration": s["least_duration"],
                     "ok": ok, "seconds": time.perf_counter() - t0})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*", help=f"motion files (default: the jumps in {SHARED})")
    ap.add_argument("--start", choices=("global", "uniform"), default="global")
    args = ap.parse_args(argv)
    clips = args.clips or [str(SHARED / c) for c in JUMPS if (SHARED / c).exists()]
    if not clips:
        print(f"no clips given and none found in {SHARED}", file=sys.stderr)
        return 2
    failed = 0
    print(f"{'clip':12s} {'case':10s} {'duration':>14s} {'flight':>7s} {'feasible':>8s} {'least':>7s}  {'s':>5s}")
    for path in clips:
        for r in check(path, args.start):
            fs = "-" if r["flight_speed"] is None else f"{r['flight_speed']:.3f}"
            least = "-" if r["least_duration"] is None else f"{r['least_duration']:.2f}"
            print(f"{r['clip']:12s} {r['case']:10s} {r['duration']:6.2f}/{r['source']:6.2f} {fs:>7s} "
                  f"{r['feasible']:8.3f} {least:>7s}  {r['seconds']:5.1f}" + ("" if r["ok"] else "  MISSED"), flush=True)
            failed += not r["ok"]
    print(f"{failed} case(s) missed" if failed else "all cases met")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
