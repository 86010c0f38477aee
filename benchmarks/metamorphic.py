"""Metamorphic check of the timing methods on real clips: the same performance written another way
must get the same timing curve (issues 24 and 25).

Clips: the bundled CMU clips, a handful of ../shared/data/cmu clips and the dev set
(../shared/data/bvh-dev). Each clip is first written as BVH and read back (the original: both sides
see the writer's 6-decimal rounding); each variant is made from that, written and read back:

* ``float32``: every channel of the motion section rounded to float32 (how DCC tools store keys);
* ``mixamo`` ... ``cmu``: joint names in that rig's convention (:func:`retime.motion.variants.rename`);
* ``z-up``: the whole clip turned so that the file's +y goes to +z (root rotation and translation;
  :func:`retime.motion.variants.turn_up`; a Z-up file comes out -Y-up);
* ``cm``, ``mm``: every length in that unit (offsets and translations times metres-per-unit / unit;
  a file already in that unit is only written and read again).

Methods, through :func:`retime.method.solve` at ``--scale 0.6``: linear, guided (default score),
physics (clips it refuses are recorded with the reason) and ``retime check`` (verdict codes, flight g).
Per method, clip and variant: the largest difference of the variant's timing curve from the
original's (source time at each output frame, in source frames); for check whether the codes agree.

Tolerances (the issues): physics float32 <= 0.1 source frame (issue 24), renames unchanged up to the
optimizer's tolerance (issue 25); guided essentially exact under renames, turns and rescales.

    python3 benchmarks/metamorphic.py                          # everything (physics on --physics-clips)
    python3 benchmarks/metamorphic.py --methods guided,check   # some methods
    python3 benchmarks/metamorphic.py --table                  # only print the stored results
    python3 benchmarks/metamorphic.py --physics-all            # physics on every clip too

Raw results: one JSON per clip, variant and method in benchmarks/out/metamorphic/ (kept: a rerun
only computes what is missing, ``--fresh`` recomputes; a variant run by other code than its original
(another retime source) is stale and left out of the tables).
"""
from __future__ import annotations

import argparse
import functools
import json
import multiprocessing
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from physics_converge import float32_copy  # noqa: E402  (the issue-24 benchmark's float32 file)

DATA = HERE.parents[1] / "shared" / "data"
BUNDLED = HERE.parent / "src" / "retime" / "data" / "cmu"
OUT = HERE / "out" / "metamorphic"
# CMU clips beside the bundled ones: two named in issue 24, jumps, a run and a long idle (not the 40 s ones)
CMU_EXTRA = ["13_11.amc", "02_04.bvh", "16_01.amc", "13_39.amc", "16_35.amc", "118_26.amc", "131_03.bvh"]
# dev clips for physics (slow): a Z-up jump, a sprint, a broad jump in metres, a cartwheel, an idle, a walk
PHYSICS_DEV = ["jumping.bvh", "run.bvh", "wd2_short_broad_jump.bvh", "cart.bvh", "ZombieIdel.bvh",
               "AV_8Walk_Meredith_HVHA_Rep1.bvh"]
SCALE = 0.6
BENCHMARKED = ("linear", "guided", "check", "physics")
RENAMES = ("mixamo", "unreal", "rigify", "biped", "kinect", "cmu")
VARIANTS = ("float32",) + RENAMES + ("z-up", "cm", "mm")
UNIT_M = {"cm": 0.01, "mm": 0.001}
# what each method must meet (source frames); None: no stated tolerance, only reported
TOLERANCE = {("physics", "float32"): 0.1, ("guided", "float32"): 0.5}
EXACT = 1e-3  # "essentially exact": a thousandth of a source frame


def clip_paths() -> list[Path]:
    bundled = sorted(p for p in BUNDLED.iterdir() if p.suffix in (".amc", ".bvh"))
    extra = [DATA / "cmu" / n for n in CMU_EXTRA if (DATA / "cmu" / n).exists()]
    dev = sorted((DATA / "bvh-dev").glob("*.bvh"))
    return bundled + extra + dev


PHYSICS_ALL = False  # --physics-all: physics on every clip


def physics_clips(paths) -> list[Path]:
    if PHYSICS_ALL:
        return list(paths)
    return [p for p in paths if p.parent == BUNDLED or p.name in ("13_11.amc", "02_04.bvh") or p.name in PHYSICS_DEV]


def clip_name(path: Path) -> str:
    return path.name if path.parent != BUNDLED else f"{path.name}*"  # * bundled


def _read_back(motion, path: Path):
    from retime.motion import load_motion, save_bvh

    save_bvh(motion, path)
    return load_motion(path)


def make_variant(path: Path, variant: str, tmp: Path):
    """The clip as written and read back (``variant`` None: the original) or its variant, with the
    scale factor used (rescales) for the record."""
    from retime.motion import load_motion
    from retime.motion import variants as V

    original = _read_back(load_motion(path), tmp / "orig.bvh")
    if variant is None:
        return original, None
    if variant == "float32":
        float32_copy(tmp / "orig.bvh", tmp / "f32.bvh")
        return load_motion(tmp / "f32.bvh"), None
    if variant in RENAMES:
        return _read_back(V.rename(original, variant), tmp / "v.bvh"), None
    if variant == "z-up":
        return _read_back(V.turn_up(original, "+z"), tmp / "v.bvh"), None
    factor = original.skeleton.meters_per_unit / UNIT_M[variant]
    return _read_back(V.rescale(original, factor), tmp / "v.bvh"), factor


def _frame_record(motion) -> dict:
    g = motion.skeleton.frame
    return {"up": motion.skeleton.up, "meters_per_unit": float(motion.skeleton.meters_per_unit),
            "unit": getattr(g, "unit", None), "limbs": (g.limbs.how if g is not None and g.limbs else None),
            "fps": float(motion.fps), "frames": int(motion.n_frames)}


def _curve_record(curve, fps) -> dict:
    t = curve.frame_times(fps)
    return {"duration": float(curve.duration), "source": [float(x) for x in curve(t)]}


def run_method(method: str, motion) -> dict:
    """One method on one motion: its curve at the output frames (or check's verdict), or why it refused."""
    from retime.errors import RetimeError
    from retime.method import Request, solve

    if motion.n_frames < 4:
        return {"refused": f"{motion.n_frames} frame(s): nothing to retime"}
    try:
        if method == "check":
            from retime.motion.feet import skeleton_limbs
            from retime.physics.check import check_clip

            skeleton_limbs(motion.skeleton)  # as `retime check` does: no legs is refused first
            s = check_clip(motion).summary()
            return {"physical": s["physical"], "codes": sorted(s["codes"]), "flight_g": s["flight_g"],
                    "time_factor": s["time_factor"], "off_share": s["off_share"]}
        r = solve(method, motion, Request(scale=SCALE))
    except RetimeError as e:
        return {"refused": str(e).splitlines()[0]}
    out = _curve_record(r.curve, motion.fps)
    if method == "physics":
        s = r.report.summary
        out.update(feasible=s.get("feasible_fraction"), info={k: v for k, v in r.info.items()
                                                               if isinstance(v, (int, float, str, bool, type(None)))})
        terms = r.detail.terms
        if terms is not None and getattr(terms, "body", None) is not None:
            out["masses"] = [float(x) for x in terms.body.mass]
    elif method == "guided":
        out["objective"] = r.info.get("objective")
    return out


def result_path(path: Path, variant: str | None, method: str) -> Path:
    return OUT / f"{path.stem}.{path.suffix[1:]}__{variant or 'original'}__{method}.json"


@functools.lru_cache(maxsize=None)
def code_version() -> str:
    """A hash of retime's source files: two runs compare only if the same code made them."""
    import hashlib
    import retime

    h = hashlib.sha1()
    for f in sorted(Path(retime.__file__).parent.rglob("*.py")):
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def job(args):
    path, variant, method = args
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            motion, factor = make_variant(path, variant, Path(tmp))
            rec = {"frame": _frame_record(motion), "factor": factor, **run_method(method, motion)}
        except Exception as e:  # a traceback is a finding: keep it, go on with the other runs
            rec = {"error": f"{type(e).__name__}: {e}", "traceback": traceback.format_exc()}
    rec.update(clip=str(path), variant=variant or "original", method=method, code=code_version(),
               seconds=round(time.perf_counter() - t0, 2),
               warnings=sorted({f"{w.category.__name__}: {w.message}" for w in caught})[:5])
    out = result_path(path, variant, method)
    tmp_out = out.with_suffix(".tmp")
    tmp_out.write_text(json.dumps(rec))
    tmp_out.replace(out)
    return rec


# -- comparison and tables ------------------------------------------------------------------------

def load(path, variant, method):
    p = result_path(path, variant, method)
    return json.loads(p.read_text()) if p.exists() else None


def curve_diff(a: dict, b: dict) -> float:
    """Largest |source time| difference over the output frames, in source frames (inf: other durations)."""
    if abs(a["duration"] - b["duration"]) > 1e-9 or len(a["source"]) != len(b["source"]):
        return float("inf")
    return float(np.max(np.abs(np.subtract(a["source"], b["source"])))) * a["fps"]


def compare(path, variant, method) -> dict | None:
    """The variant's run against the original's (None: either not run yet, or the two were run by
    different code, :func:`code_version`: the variant is stale)."""
    a, b = load(path, None, method), load(path, variant, method)
    if a is None or b is None:
        return None
    if a.get("code") is None or b.get("code") != a.get("code"):  # no hash: stored before it was kept
        return None
    row = {"clip": clip_name(path), "variant": variant, "frame": b.get("frame"), "orig_frame": a.get("frame")}
    for which, rec in (("orig", a), ("var", b)):
        if "error" in rec:
            row["error"] = f"{which}: {rec['error']}"
        elif "refused" in rec:
            row.setdefault("refused", {})[which] = rec["refused"]
    if "error" in row or "refused" in row:
        return row
    if method == "check":
        row.update(codes_agree=a["codes"] == b["codes"], codes=(a["codes"], b["codes"]),
                   flight_g=(a["flight_g"], b["flight_g"]), physical=(a["physical"], b["physical"]))
        return row
    row["diff"] = curve_diff(dict(a, fps=a["frame"]["fps"]), b)
    if method == "physics":
        row["feasible"] = (a.get("feasible"), b.get("feasible"))
        row["iterations"] = (a["info"].get("iterations"), b["info"].get("iterations"))
        row["objective"] = (a["info"].get("objective"), b["info"].get("objective"))
        ma, mb = a.get("masses"), b.get("masses")
        row["mass_diff"] = (float(np.max(np.abs(np.subtract(ma, mb)))) if ma and mb and len(ma) == len(mb)
                            else None)
    return row


def over_tolerance(method, variant, diff) -> bool:
    tol = TOLERANCE.get((method, variant))
    if tol is None:
        tol = EXACT if method in ("linear", "guided") else 1.0  # physics renames/turns: "optimizer's tolerance"
    return diff > tol


def _fmt_refusal(row) -> str:
    r = row["refused"]
    if set(r) == {"orig", "var"} and r["orig"] == r["var"]:
        return f"both refused: {r['orig'][:90]}"
    return "; ".join(f"{k} refused: {v[:80]}" for k, v in r.items()) + ("  <- CHANGED" if len(r) == 1 else "")


def print_tables(paths, methods):
    flagged = []
    for method in methods:
        print(f"\n== {method} (--scale {SCALE}) " + ("codes agree / flight g orig -> variant" if method == "check"
                                                    else "max |source time diff| over output frames, source frames"))
        largest = {}
        for path in (physics_clips(paths) if method == "physics" else paths):
            cells = []
            for variant in VARIANTS:
                row = compare(path, variant, method)
                if row is None:
                    cells.append(f"{variant}:-")
                    continue
                if "error" in row:
                    cells.append(f"{variant}:ERROR")
                    flagged.append((method, row["clip"], variant, row["error"][:160]))
                    continue
                if "refused" in row:
                    if len(row["refused"]) == 1:
                        flagged.append((method, row["clip"], variant, _fmt_refusal(row)))
                    cells.append(f"{variant}:refused" if len(row["refused"]) == 1 else None)
                    continue
                if method == "check":
                    ok = row["codes_agree"]
                    g0, g1 = row["flight_g"]
                    gtxt = "" if g0 is None and g1 is None else f"({g0}->{g1})"
                    cells.append(f"{variant}:{'=' if ok else 'DIFF'}{gtxt}")
                    if not ok:
                        flagged.append((method, row["clip"], variant, f"codes {row['codes'][0]} -> {row['codes'][1]}"))
                    key = variant
                    dg = abs(g1 - g0) if g0 is not None and g1 is not None else 0.0
                    largest[key] = max(largest.get(key, (0.0, "")), (dg, row["clip"]))
                    continue
                d = row["diff"]
                largest[variant] = max(largest.get(variant, (-1.0, "")), (d, row["clip"]))
                extra = ""
                if method == "physics" and row.get("mass_diff") is not None and row["mass_diff"] > 1e-3:
                    extra = f"[m{row['mass_diff']:.2f}kg]"
                cells.append(f"{variant}:{d:.3g}{extra}")
                if over_tolerance(method, variant, d):
                    up = row["frame"]["up"] if row["frame"] else "?"
                    why = f"up {row['orig_frame']['up']}->{up}, m/unit {row['orig_frame']['meters_per_unit']:.4g}->" \
                          f"{row['frame']['meters_per_unit']:.4g}, limbs {row['orig_frame']['limbs']}->{row['frame']['limbs']}"
                    if method == "physics":
                        why += (f", feasible {row['feasible'][0]}->{row['feasible'][1]}, iterations {row['iterations']}, "
                                f"objective {row['objective'][0]:.6g}->{row['objective'][1]:.6g}, "
                                f"mass diff {row['mass_diff']}")
                    flagged.append((method, row["clip"], variant, f"{d:.3g} source frames ({why})"))
            orig = load(path, None, method)
            head = f"{clip_name(path)[:30]:30s}"
            if method == "check" and orig is not None and "codes" in orig:
                head += f" {'physical' if orig['physical'] else ','.join(orig['codes']) or 'NOT'}:"
            if orig is not None and "refused" in orig and all(c is None for c in cells):
                print(f"{head} refused (all variants too): {orig['refused'][:100]}")
                continue
            print(f"{head} " + " ".join(c for c in cells if c is not None), flush=True)
        print(f"largest per variant ({'|flight g diff|' if method == 'check' else 'source frames'}): " +
              ", ".join(f"{v} {d:.3g} ({c})" for v, (d, c) in largest.items()))
    print("\n== beyond tolerance, refusals that changed, errors")
    for f in flagged:
        print("  " + " | ".join(f))
    if not flagged:
        print("  none")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--methods", default=",".join(BENCHMARKED))
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--clips", default="", help="comma-separated file names (default: all)")
    ap.add_argument("--jobs", type=int, default=2, help="processes (at most 2: the machine is shared)")
    ap.add_argument("--physics-all", action="store_true", help="physics on every clip, not only the bundled "
                    "clips, 13_11, 02_04 and PHYSICS_DEV")
    ap.add_argument("--table", action="store_true", help="only print the stored results")
    ap.add_argument("--fresh", action="store_true", help="recompute stored results")
    args = ap.parse_args(argv)
    global PHYSICS_ALL
    PHYSICS_ALL = args.physics_all
    methods = [m for m in args.methods.split(",") if m]
    variants = [v for v in args.variants.split(",") if v]
    paths = clip_paths()
    if args.clips:
        wanted = set(args.clips.split(","))
        paths = [p for p in paths if p.name in wanted]
    OUT.mkdir(parents=True, exist_ok=True)
    if not args.table:
        todo = []
        # physics' originals and float32 copies (issue 24) first, then the fast methods, then the rest of physics
        first = [v for v in variants if v == "float32"]
        order = ([("physics", [None] + first)] if "physics" in methods else []) + \
            [(m, [None] + variants) for m in methods if m != "physics"] + \
            ([("physics", [v for v in variants if v not in first])] if "physics" in methods else [])
        for method, vs in order:
            clips = physics_clips(paths) if method == "physics" else paths
            for variant in vs:
                for p in clips:
                    if args.fresh or not result_path(p, variant, method).exists():
                        todo.append((p, variant, method))
        print(f"{len(todo)} runs to do", flush=True)
        with multiprocessing.get_context("spawn").Pool(min(2, max(1, args.jobs))) as pool:
            for k, rec in enumerate(pool.imap_unordered(job, todo), 1):
                what = rec.get("error") or rec.get("refused") or ""
                print(f"[{k}/{len(todo)}] {Path(rec['clip']).name} {rec['variant']} {rec['method']} "
                      f"{rec['seconds']:.1f} s {what[:80]}", flush=True)
    print_tables(paths, methods)
    return 0


if __name__ == "__main__":
    sys.exit(main())
