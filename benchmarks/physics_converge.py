"""Issue 24: is the physics timing a function of the motion, not of float noise?

For every clip: a BVH of it as converted, and a float32 copy (every channel of the motion section
rounded to float32, written, read back); both retimed at ``--scale`` (default 0.5). Prints how far the
two timing curves differ (source frames, over the output frames), the optimizer's iterations,
whether its stopping test was met, the KKT residual (:func:`retime.physics.timing.optimize.kkt_residual`),
both final objectives, how much the float32 copy's objective differs from the original's at the same
timing (the original's answer; when the two problems' splines match), and how many spline
coefficients the answer sits on a **kink** of the objective for (the one-sided derivatives along the
coefficient differ, and keep differing as the step shrinks): a minimum on a kink has no vanishing
gradient, and which kink wins can be decided by noise.
``--starts N`` also re-runs the optimizer on the original from N starts that differ from its own by
1e-6 (relative, random) and prints how far their answers spread: nearby minima, or stops, that
noise picks between.

With the default optimizer (``newton``: L-BFGS, then Newton's method from its answer) it also prints
the L-BFGS answer's objective next to Newton's (the polish keeps Newton's only when it is no worse),
and **today's** pipeline for comparison (``--no-today`` skips it): the objective without the fan
smoothing (``fan_blend=0``), started and optimized by L-BFGS as before issue 24, against the new
answer's value on that same objective: the new answer is no worse an optimum when its value there
is not above today's.

    python3 benchmarks/physics_converge.py                      # the bundled CMU clips
    python3 benchmarks/physics_converge.py CLIP.amc ... --method lbfgs
    python3 benchmarks/physics_converge.py CLIP.amc ... --unique-vertex-forces  # RegionOptions.unique_vertex_forces
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from retime.motion import load_motion
from retime.motion.files import save_motion
from retime.errors import RetimeError
from retime.physics.api import make_problem, physics_warp
from retime.physics.regions import RegionOptions
from retime.physics.timing.objective import evaluate_c
from retime.physics.timing.optimize import solve

BUNDLED = Path(__file__).resolve().parents[1] / "src" / "retime" / "data" / "cmu"


def float32_copy(bvh_in: Path, bvh_out: Path) -> None:
    """The BVH with every number after MOTION's Frame Time line rounded to float32."""
    lines = bvh_in.read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.strip().lower().startswith("frame time"))
    body = [" ".join(repr(float(np.float32(x))) for x in ln.split()) for ln in lines[k + 1:] if ln.strip()]
    bvh_out.write_text("\n".join(lines[:k + 1] + body) + "\n")


def kinks(problem, w):
    """Coefficients c_k at whose value the objective has a kink: the jump between the one-sided
    derivatives at steps h and 10 h is the same (a smooth function's grows tenfold)."""
    sp = problem.spline
    c, T = sp.coefficients(w), sp.duration_of(w)
    idx, _ = sp.pieces()
    h0 = 1e-9 * float(np.mean(np.diff(c)))
    _, g, _ = evaluate_c(problem.obj, sp, c, T, grad=True, workspace=problem.workspace)
    scale = float(np.max(np.abs(g))) or 1.0
    count = 0
    for k in sorted(set(range(sp.n_c)) - set(idx)):
        jumps = []
        for h in (h0, 10 * h0):
            side = []
            for sign in (-1, 1):
                cc = c.copy()
                cc[k] += sign * h
                side.append(evaluate_c(problem.obj, sp, cc, T, grad=True, workspace=problem.workspace)[1][k])
            jumps.append(abs(side[1] - side[0]))
        count += jumps[0] > 1e-4 * scale and jumps[0] > 0.5 * jumps[1]
    return count


def spread_of_starts(result, motion, duration, n, seed=0):
    """(largest distance between the answers' timing curves in source frames, objectives' range) of n
    runs from the start perturbed by 1e-6 (relative)."""
    rng = np.random.default_rng(seed)
    pr = make_problem(result.objective, motion.duration, duration)
    w0 = pr.spline.w.copy()
    t = np.arange(0.0, duration, 1.0 / motion.fps)
    curves, vals = [], []
    for _ in range(n):
        w, info = solve(pr, w0 * (1 + 1e-6 * rng.standard_normal(len(w0))), max_iter=3000, tol=1e-9)
        curves.append(pr.spline(t, w))
        vals.append(info.objective)
    far = max(float(np.max(np.abs(a - b))) for a in curves for b in curves) * motion.fps
    return far, min(vals), max(vals)


def today(result, motion, duration):
    """(today's answer, the new answer) valued on today's objective: the baked objective without the
    fan smoothing (``blend=0``, and without softening the frames a grid start gives up, so that both
    are measured alike), today's answer by L-BFGS from its own grid start (before issue 24)."""
    import dataclasses

    from retime.physics.timing.objective import evaluate

    old = dataclasses.replace(result.objective, arrays=result.objective.arrays._replace(blend=0.0))
    pr = make_problem(old, motion.duration, duration)
    w, _ = solve(pr, method="lbfgs", max_iter=3000, tol=1e-9)
    return evaluate(old, pr.spline, w), evaluate(old, result.spline, result.spline.w)


def force_change(a, b):
    """(centre, vertex) contact forces of the float32 copy's regions against the original's: the
    largest change of one basis force, in body weights (vertices only on frames whose polygons have
    as many vertices)."""
    ra, rb = a.regions, b.regions
    centre = float(np.max(np.abs(ra.center_lam - rb.center_lam), initial=0.0))
    vertex = 0.0
    for i in range(min(ra.n_frames, rb.n_frames)):
        la, lb = ra.polygon_lam(i), rb.polygon_lam(i)
        if la.shape == lb.shape and la.size:
            vertex = max(vertex, float(np.max(np.abs(la - lb))))
    return centre / ra.body_weight, vertex / ra.body_weight


def run(path, scale, kw, tmp, unique_vertex_forces=False):
    src = Path(tmp) / "orig.bvh"
    save_motion(load_motion(path), src)
    f32 = Path(tmp) / "f32.bvh"
    float32_copy(src, f32)
    out = []
    for p in (src, f32):
        m = load_motion(p)
        t0 = time.perf_counter()
        r = physics_warp(m, scale=scale, region_options=RegionOptions(unique_vertex_forces=unique_vertex_forces), **kw)
        out.append((m, r, time.perf_counter() - t0))
    (m, a, ta), (_, b, tb) = out
    T = min(a.spline.duration, b.spline.duration)
    t = np.arange(0.0, T, 1.0 / m.fps)
    moved = float(np.max(np.abs(a.curve(t) - b.curve(t)))) * m.fps
    same = None  # the copy's objective at the original's answer, relative to the original's there
    if b.spline.n_c == a.spline.n_c and b.spline.free == a.spline.free:
        same = b.session.problem.value(a.spline.w) / a.session.problem.value(a.spline.w) - 1.0
    forces = force_change(a, b) if a.regions.n_frames == b.regions.n_frames else None
    return moved, a.info, b.info, ta + tb, kinks(a.session.problem, a.spline.w), (m, a), same, forces


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--method", default=None, help="optimizer (default: physics' own)")
    ap.add_argument("--starts", type=int, default=0, help="also this many runs from perturbed starts")
    ap.add_argument("--no-today", action="store_true", help="skip the comparison with the pipeline before issue 24")
    ap.add_argument("--unique-vertex-forces", action="store_true",
                    help="the regions' vertex forces made unique (RegionOptions.unique_vertex_forces)")
    args = ap.parse_args(argv)
    clips = args.clips or sorted(str(p) for p in BUNDLED.glob("*") if p.suffix in (".amc", ".bvh"))
    kw = {} if args.method is None else {"optimizer": args.method}
    print(f"{'clip':14s} {'moved':>6s} {'iterations':>11s} {'stop':>4s} {'KKT residual':>17s} {'kinks':>5s} "
          f"{'objective orig / f32':>25s} {'same timing':>11s}  why it stopped")
    for c in clips:
        with tempfile.TemporaryDirectory() as tmp:
            try:
                moved, ia, ib, sec, nk, (m, a), same, forces = run(c, args.scale, kw, tmp, args.unique_vertex_forces)
            except RetimeError as e:  # a clip physics refuses: say so, go on
                print(f"{Path(c).name:14s} refused: {str(e).splitlines()[0][:80]}")
                continue
        print(f"{Path(c).name:14s} {moved:6.3f} {ia.iterations:5d}/{ib.iterations:5d} {ia.converged:d}/{ib.converged:d} "
              f"{ia.kkt_residual:8.2g}/{ib.kkt_residual:8.2g} {nk:5d} {ia.objective:12.7g}/{ib.objective:12.7g} "
              f"{'-' if same is None else f'{100 * same:+.2g}%':>11s}  "
              f"{ia.message} | {ib.message}  ({sec:.0f} s)", flush=True)
        if forces is not None:
            print(f"{'':14s} contact forces of the f32 copy's regions move by up to {forces[0]:.2g} body weights "
                  f"at the fan centres, {forces[1]:.2g} at the polygon vertices", flush=True)
        if ia.method == "newton":
            line = (f"{'':14s} objective L-BFGS -> Newton: {ia.lbfgs_objective:.9g} -> {ia.objective:.9g} "
                    f"(f32 copy {ib.lbfgs_objective:.9g} -> {ib.objective:.9g}); Newton iterations "
                    f"{ia.newton_iterations}/{ib.newton_iterations}")
            if not args.no_today:
                old, new_on_old = today(a, m, a.spline.duration)
                line += f"; on today's objective: today {old:.9g}, new answer {new_on_old:.9g}"
            print(line, flush=True)
        if args.starts:
            far, lo, hi = spread_of_starts(a, m, a.spline.duration, args.starts)
            print(f"{'':14s} {args.starts} starts 1e-6 apart: answers up to {far:.3f} source frames apart, "
                  f"objective {lo:.7g} .. {hi:.7g}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
