"""``retime check``'s verdicts on real captures and on the mistakes made from them (issue 25):
per file and variant, the detected up axis and unit, the verdict and its cause codes, the flight
gravity (g) and the time factor it gives, the stance time factor (:mod:`retime.physics.stance_rate`,
measured only on a gait without a flight), and (``--physics``, slow) physics' feasible fraction at
0.7 of the duration.

    python3 benchmarks/check_verdicts.py                 # ../shared/data: CMU and the dev set
    python3 benchmarks/check_verdicts.py FILE ...        # any files (taken as real overground captures)
    python3 benchmarks/check_verdicts.py --variants orig,fps0.8 --physics

Variants (:mod:`retime.motion.mistakes`) and the cause each must give: ``fps0.8`` / ``fps1.25``
(Frame Time x0.8 / x1.25: ``frame_rate``, from the flights or a gait's single support; ``fps0.9`` /
``fps1.1``, shown only when asked, are the detection limit), ``rad``
(radians read as degrees: ``radians``), ``zup`` (Z-up read as Y-up: ``up_axis``), ``locked`` (the
root pinned: ``root_locked``), ``treadmill`` (the root's travel taken out, on clips that travel:
``treadmill``). Targets: >= 95 % of the real overground captures physical; every variant not
physical, with its cause.
"""
from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from retime.errors import RetimeError
from retime.motion import load_motion
from retime.motion import mistakes as M
from retime.physics.check import check_clip

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
# real captures that move over a floor on their feet (the READMEs' descriptions); the rest of the
# dev set (dances, an idle, a cartwheel, an in-place video estimate, a Kinect standing clip) is shown apart
OVERGROUND_DEV = {"01_01.bvh", "AV_8Walk_Meredith_HVHA_Rep1.bvh", "jumping.bvh", "run.bvh",
                  "wd2_short_broad_jump.bvh", "woddy2_walk_straight_fast.bvh"}
LONG = {"13_17.amc", "13_29.amc"}  # 40 s each: with --long
LIMIT_VARIANTS = ("fps0.9", "fps1.1")  # +-10 %: what the check can still tell, shown on request
TRAVELS_M_S = 0.5  # a clip whose root travels steadily faster gets the treadmill variant

VARIANTS = {
    "orig": (lambda m: m, None),
    "fps0.8": (lambda m: M.wrong_frame_time(m, 0.8), "frame_rate"),
    "fps1.25": (lambda m: M.wrong_frame_time(m, 1.25), "frame_rate"),
    "fps0.9": (lambda m: M.wrong_frame_time(m, 0.9), "frame_rate"),  # the detection limit: not in the defaults
    "fps1.1": (lambda m: M.wrong_frame_time(m, 1.1), "frame_rate"),
    "rad": (M.radians_as_degrees, "radians"),
    "zup": (M.up_read_as, "up_axis"),
    "locked": (M.root_locked, "root_locked"),
    "treadmill": (M.treadmill, "treadmill"),
}


def default_files(long: bool) -> list[tuple[Path, bool]]:
    cmu = sorted((DATA / "cmu").glob("*.amc")) + sorted((DATA / "cmu").glob("*.bvh"))
    dev = sorted((DATA / "bvh-dev").glob("*.bvh"))
    return ([(p, True) for p in cmu if long or p.name not in LONG] +
            [(p, p.name in OVERGROUND_DEV) for p in dev if p.name != "DAZ3D.bvh"])


def row(name, variant, m, physics: bool) -> dict:
    t0 = time.perf_counter()
    c = check_clip(m)
    s = c.summary()
    out = {"file": name, "variant": variant, "up": m.skeleton.up, "unit": m.skeleton.frame.unit,
           "physical": s["physical"], "codes": s["codes"], "flight_g": s["flight_g"], "flights": s["flights"],
           "time_factor": s["time_factor"], "stance": s["stance_time_factor"], "off": s["off_share"],
           "causes": s["causes"] + s["caution_sentences"], "cautions": s["cautions"], "feasible": None}
    if physics:
        from retime.physics.api import physics_warp

        try:
            out["feasible"] = physics_warp(m, scale=0.7).report["summary"]["feasible_fraction"]
        except RetimeError as e:
            out["feasible"] = f"refused: {str(e)[:40]}"
    out["sec"] = time.perf_counter() - t0
    return out


def fmt(r) -> str:
    g = "-" if r["flight_g"] is None else f"{r['flight_g']:.2f}"
    k = "-" if r["time_factor"] is None else f"{r['time_factor']:.2f}"
    st = "-" if r["stance"] is None else f"{r['stance']:.2f}"
    f = "" if r["feasible"] is None else (f" {r['feasible']:6.1%}" if isinstance(r["feasible"], float) else f" {r['feasible']}")
    return (f"{r['file'][:26]:26s} {r['variant']:9s} {r['up']:>3s} {r['unit'][:9]:>9s} "
            f"{('caution' if r['cautions'] else 'physical') if r['physical'] else 'NOT':8s} {','.join(r['codes'] + r['cautions']) or '-':24s} {g:>5s} ({r['flights']:2d}) "
            f"{k:>5s} {st:>6s} {r['off']:5.2f}{f} {r['sec']:5.1f}s")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--variants", default=",".join(v for v in VARIANTS if v not in LIMIT_VARIANTS),
                    help="comma-separated, of: " + ", ".join(VARIANTS))
    ap.add_argument("--physics", action="store_true", help="also physics' feasible fraction at 0.7 (slow)")
    ap.add_argument("--long", action="store_true", help="also the 40 s CMU clips")
    ap.add_argument("--causes", action="store_true", help="print each verdict's sentences")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", RuntimeWarning)
    files = [(p, True) for p in args.files] or default_files(args.long)
    if not files:
        print("no files: give some, or put ../shared/data beside the repository")
        return 1
    wanted = args.variants.split(",")
    print(f"{'file':26s} {'variant':9s} {'up':>3s} {'unit':>9s} {'verdict':8s} {'causes':24s} {'g':>5s} (fl) "
          f"{'time':>5s} {'stance':>6s} {'off':>5s}{' feas' if args.physics else ''}")
    rows = []
    for path, overground in files:
        try:
            base = load_motion(path)
        except RetimeError as e:
            print(f"{path.name[:26]:26s} unreadable: {e}")
            continue
        for v in wanted:
            make, expect = VARIANTS[v]
            if v != "orig" and not overground:
                continue
            if v == "treadmill" and steady_travel(base) < TRAVELS_M_S:
                continue
            try:
                r = row(path.name, v, make(base), args.physics)
            except RetimeError as e:
                print(f"{path.name[:26]:26s} {v:9s} refused: {str(e)[:100]}")
                continue
            r["overground"], r["expect"] = overground, expect
            rows.append(r)
            print(fmt(r), flush=True)
            if args.causes and r["causes"]:
                print("    " + "\n    ".join(r["causes"]))
    score(rows)
    return 0


def steady_travel(m) -> float:
    """The horizontal speed (m/s) of the root over 1 s windows that three quarters of them exceed: a
    walk or a run travels all the time; a standing jump only while it jumps (a treadmill variant of
    it would be a standing jump)."""
    up = "xyz".index(m.skeleton.up[-1])
    root = (m.root_positions * m.skeleton.meters_per_unit)[:, [a for a in range(3) if a != up]]
    k = min(len(root) - 1, int(round(m.fps)))
    return float(np.percentile(np.linalg.norm(root[k:] - root[:-k], axis=1), 25) * m.fps / k) if k > 0 else 0.0


def score(rows):
    real = [r for r in rows if r["variant"] == "orig" and r["overground"]]
    # the stance cue's spread (measured on gaits without a flight): where real clips and variants meet
    for v in VARIANTS:
        st = sorted(r["stance"] for r in rows if r["variant"] == v and r["overground"] and r["stance"] is not None)
        if st:
            print(f"stance time factor, {v:9s}: {st[0]:.2f}-{st[-1]:.2f} on {len(st)} clips "
                  f"(median {st[len(st) // 2]:.2f})")
    if real:
        ok = sum(r["physical"] for r in real)
        print(f"\nreal overground captures physical: {ok}/{len(real)} ({ok / len(real):.0%}); not: "
              + (", ".join(f"{r['file']} ({','.join(r['codes'])})" for r in real if not r["physical"]) or "none"))
        cautioned = [r["file"] for r in real if r["physical"] and r["cautions"]]
        print(f"real overground captures physical with a caution: {len(cautioned)}/{len(real)}"
              + (f" ({', '.join(cautioned)})" if cautioned else ""))
    for v in VARIANTS:
        vs = [r for r in rows if r["variant"] == v and r["expect"]]
        if not vs:
            continue
        flagged = sum(not r["physical"] for r in vs)
        right = sum(r["expect"] in r["codes"] for r in vs)
        missed = [r["file"] for r in vs if r["expect"] not in r["codes"]]
        cautioned = [r["file"] for r in vs if r["physical"] and r["cautions"]]
        print(f"{v:9s}: not physical {flagged}/{len(vs)}, with the cause {vs[0]['expect']} {right}/{len(vs)}"
              + (f"; without it: {', '.join(missed)}" if missed else "")
              + (f"; of those with a caution: {', '.join(cautioned)}" if cautioned else ""))


if __name__ == "__main__":
    sys.exit(main())
