"""Issue 24: Newton after a short L-BFGS warm-up, against the default (L-BFGS to Settings.max_iter, then Newton).

For every clip the problem is built once (regions, baked objective, grid start, at ``--scale``) and each
variant ``L:N`` (at most L L-BFGS iterations, then at most N Newton iterations,
:func:`retime.physics.timing.optimize.solve`) runs from the same start. Prints per variant: the
iterations (L-BFGS + Newton), the objective and its change against the first variant's (the default
first), the KKT residual, whether it converged, the seconds, how far its timing lies from the first
variant's (source frames) and why Newton stopped. ``--float32`` also builds the clip's float32 copy
(every channel rounded, as benchmarks/physics_converge.py; the original is then its BVH copy, as
there: BVH text rounds an AMC) and prints how far each variant's two answers lie apart.
``--diagnose L`` also runs Newton alone from L L-BFGS iterations and counts, over its iterations, how
well its quadratic model predicted the gain (actual / predicted), and how often a
speed bound shortened the accepted step.

    python3 benchmarks/physics_warmup.py                       # bundled clips + ../shared/data/cmu 131_03, 02_04
    python3 benchmarks/physics_warmup.py CLIP ... --variants 3000:300,300:1000 --float32 --diagnose 300
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from longclip import SHARED
from physics_converge import BUNDLED, float32_copy
from physics_optimizer import build_problem
from retime.motion import load_motion
from retime.motion.files import save_motion
from retime.physics.method import Settings
from retime.physics.timing.newton import BandedCoordinates, BandedObjective, newton_inner
from retime.physics.timing.optimize import solve

CLIPS = [BUNDLED / n for n in ("16_16.amc", "16_06.amc", "16_15.amc", "16_33.amc", "131_01.bvh")] \
    + [SHARED / n for n in ("131_03.bvh", "02_04.bvh")]


def run_variants(problem, variants, times):
    """[(info, seconds, timing curve at ``times``)] per variant, each from the problem's start."""
    w0 = problem.spline.w.copy()
    out = []
    for lbfgs, newton in variants:
        t0 = time.perf_counter()
        w, info = solve(problem, w0.copy(), method="newton", max_iter=lbfgs, tol=1e-9, newton_iter=newton)
        out.append((info, time.perf_counter() - t0, problem.spline(times, w)))
    return out


def diagnose(problem, lbfgs, max_iter=300):
    """Newton from ``lbfgs`` L-BFGS iterations: (iterations, its stop, the accepted steps' actual /
    predicted gain split at 0.25 and 0.75, how many steps a speed bound shortened)."""
    w, _ = solve(problem, problem.spline.w.copy(), method="lbfgs", max_iter=lbfgs, tol=1e-9)
    coords = BandedCoordinates(problem)
    z, c0 = coords.from_w(w)
    ratios, shortened = [], [0]

    def log(it, fn, predicted, gain, sigma, t):
        ratios.append(gain / max(predicted, 1e-300))
        shortened[0] += t < 1.0

    _, _, it, _, msg = newton_inner(BandedObjective(coords, c0), z, (problem.w_min, problem.w_max),
                                    max_iter=max_iter, log=log)
    r = np.array(ratios)
    return it, msg, int(np.sum(r < 0.25)), int(np.sum((r >= 0.25) & (r <= 0.75))), int(np.sum(r > 0.75)), shortened[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--variants", default=f"{Settings().max_iter}:300,100:300,300:300,100:1000,300:1000",
                    help="L:N pairs, comma separated; the first is the reference")
    ap.add_argument("--float32", action="store_true", help="also each variant's move under float32 rounding")
    ap.add_argument("--diagnose", type=int, default=0, help="also Newton's model quality from this many L-BFGS iterations")
    args = ap.parse_args(argv)
    variants = [tuple(int(x) for x in v.split(":")) for v in args.variants.split(",")]
    clips = [Path(c) for c in args.clips] or [c for c in CLIPS if c.exists()]
    for clip in clips:
        with tempfile.TemporaryDirectory() as tmp:
            m = load_motion(clip)
            f32 = None
            if args.float32:  # both copies as BVH, as benchmarks/physics_converge.py (the BVH text rounds too)
                src, cp = Path(tmp) / "orig.bvh", Path(tmp) / "f32.bvh"
                save_motion(m, src)
                float32_copy(src, cp)
                m = load_motion(src)
            pr = build_problem(m, args.scale)[0]
            times = np.arange(0.0, args.scale * m.duration, 1.0 / m.fps)
            runs = run_variants(pr, variants, times)
            if args.float32:
                f32 = run_variants(build_problem(load_motion(cp), args.scale)[0], variants, times)
        ref_obj, ref_curve = runs[0][0].objective, runs[0][2]
        for k, ((lb, nw), (info, sec, curve)) in enumerate(zip(variants, runs)):
            moved = "" if f32 is None else f" f32 move {float(np.max(np.abs(curve - f32[k][2]))) * m.fps:6.3f}"
            print(f"{clip.stem:8s} {lb:5d}:{nw:<5d} iterations {info.iterations - info.newton_iterations:5d}"
                  f"+{info.newton_iterations:<4d} objective {info.objective:.10g} ({100 * (info.objective / ref_obj - 1):+.4f}%) "
                  f"kkt {info.kkt_residual:.1e} converged {info.converged:d} {sec:6.2f} s "
                  f"from first {float(np.max(np.abs(curve - ref_curve))) * m.fps:6.3f} fr{moved} | {info.message}", flush=True)
        if args.diagnose:
            it, msg, low, mid, high, short = diagnose(pr, args.diagnose)
            print(f"{clip.stem:8s} Newton from {args.diagnose} L-BFGS iterations: {it} iterations ({msg}); actual / "
                  f"predicted gain < 0.25 on {low}, 0.25-0.75 on {mid}, > 0.75 on {high}; a speed bound shortened "
                  f"{short} steps", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
