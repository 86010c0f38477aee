"""Issue 11's acceptance table on real files from other exporters and rigs (../shared/data/bvh-dev,
or any BVH/AMC files given): what was detected, whether the clip is physical as captured, and
physics at 0.7 of the duration and at a quarter of gravity (free duration).

    python3 benchmarks/rigs.py                   # the dev set
    python3 benchmarks/rigs.py FILE.bvh ...      # any files
    python3 benchmarks/rigs.py --frames [FILE ...]   # only the detected up and units, per file and variant

Variants (issue 25): each file turned Z-up, X-up and -Z-up, rescaled to millimetres and put under a
dummy root, written and read back; the up axis must follow the turn and the metres per unit stay
the same ('kept' when both hold).

Wanted (the issue): every humanoid file retimes at --scale 0.7 and --gravity-scale 0.25; walks
>= 90% feasible at 0.7 where their least physical duration allows it; quarter-gravity flights at
0.5 +- 0.06; no clip reported feasible without a warning when its own timing is not physical; the
only refusal a non-biped.

Before this issue (main at cd9e774, the same 14 files, --scale 0.7): 5 refused (Mixamo x2 and
HumanIK x2: "cannot find the left foot"; OpenNI: "no length along the ground"), the Z-up jump read
Y-up (95% feasible, flight 1.18x), and no warning on any clip.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from retime.errors import RetimeError
from retime.motion import load_motion, save_bvh
from retime.motion import variants as V
from retime.physics.api import physics_warp

DEV = Path(__file__).resolve().parents[2] / "shared" / "data" / "bvh-dev"


def _flights(report, min_s=0.15):
    return [p["speed"] for p in report["summary"]["phases"]
            if p["state"] == "flight" and p["source_end"] - p["source_start"] >= min_s]


def row(path: Path) -> str:
    try:
        m = load_motion(path)
    except RetimeError as e:
        return f"{path.name[:28]:28s} unreadable: {e}"
    g = m.skeleton.frame
    head = f"{path.name[:28]:28s} {g.up:>3s} {g.unit[:9]:>9s} {(g.limbs.how if g.limbs else 'none'):>9s}"
    if m.n_frames < 4:
        return head + "  (a single pose: nothing to retime)"
    t0 = time.perf_counter()
    try:
        a = physics_warp(m, scale=0.7)
        down = -9.81 * 0.25 * np.eye(3)["xyz".index(m.skeleton.up[1])] * (1 if m.skeleton.up[0] == "+" else -1)
        b = physics_warp(m, gravity=down)
    except RetimeError as e:
        return head + f"  refused: {str(e)[:90]}"
    s = a.report["summary"]
    fl = ", ".join(f"{x:.2f}" for x in _flights(b.report)[:4]) or "-"
    least = s.get("least_duration")
    return (head + f" {'yes' if s['source_check']['physical'] else 'NO':>8s} {s['feasible_fraction']:6.1%}"
            f" {s['duration']:6.2f} {least if least is not None else float('nan'):6.2f}"
            f"   {fl:24s} {b.report['summary']['feasible_fraction']:6.1%} {time.perf_counter() - t0:6.1f}")


VARIANTS = {"z-up": lambda m: V.turn_up(m, "+z"), "x-up": lambda m: V.turn_up(m, "+x"),
            "-z-up": lambda m: V.turn_up(m, "-z"), "mm": lambda m: V.rescale(m, m.skeleton.meters_per_unit / 0.001),
            "dummy root": lambda m: V.add_dummy_root(m, share=0.5)}
TURNS = {"z-up": "+z", "x-up": "+x", "-z-up": "-z"}


def frame_rows(path: Path) -> list[str]:
    """Detected up and units of the file and of each variant (see the module docstring)."""
    try:
        m = load_motion(path)
    except RetimeError as e:
        return [f"{path.name[:28]:28s} unreadable: {e}"]
    g = m.skeleton.frame
    rows = [f"{path.name[:28]:28s} {'as written':>10s} {g.up:>3s} {g.up_confidence:5.0%} {g.unit[:10]:>10s} "
            f"{m.skeleton.meters_per_unit:9.4g}  {'' if g.limbs else 'not a biped: ' + g.biped[:50]}"]
    with tempfile.TemporaryDirectory() as tmp:
        for name, make in VARIANTS.items():
            out = Path(tmp) / f"{name}.bvh"
            save_bvh(make(m), out)
            v = load_motion(out)
            h = v.skeleton.frame
            factor = m.skeleton.meters_per_unit / 0.001 if name == "mm" else 1.0
            kept = (v.skeleton.up == (V.turned_up(m.skeleton.up, TURNS[name]) if name in TURNS else m.skeleton.up)
                    and abs(v.skeleton.meters_per_unit * factor / m.skeleton.meters_per_unit - 1) < 1e-3)
            rows.append(f"{'':28s} {name:>10s} {h.up:>3s} {h.up_confidence:5.0%} {h.unit[:10]:>10s} "
                        f"{v.skeleton.meters_per_unit:9.4g}  {'kept' if kept else 'CHANGED'}")
    return rows


def main(argv):
    frames_only = "--frames" in argv
    argv = [a for a in argv if a != "--frames"]
    paths = [Path(p) for p in argv] or sorted(DEV.glob("*.bvh"))
    if not paths:
        print("no files: give some, or put ../shared/data/bvh-dev beside the repository")
        return 1
    print(f"{'file':28s} {'variant':>10s} {'up':>3s} {'conf':>5s} {'unit':>10s} {'m/unit':>9s}")
    for p in paths:
        for line in frame_rows(p):
            print(line, flush=True)
    if frames_only:
        return 0
    print()
    print(f"{'file':28s} {'up':>3s} {'unit':>9s} {'limbs by':>9s} {'physical':>8s} {'@0.7':>6s} {'dur':>6s} "
          f"{'least':>6s}   {'flights at g/4 (x)':24s} {'@g/4':>6s} {'sec':>6s}")
    for p in paths:
        print(row(p), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
