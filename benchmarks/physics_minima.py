"""Issue 24, deliverable 3: where does a float32 copy's physics timing leave the original's?

For every clip, the problem is built as ``retime physics --scale`` builds it (regions, baked objective,
grid start, the requested duration on the frame grid) twice: from the clip as converted to BVH and
from its float32 copy (every channel rounded, written, read back: benchmarks/physics_converge.py).
Then, for each optimizer in ``--methods``:

* ``starts``: how far apart the two grid starts lie (source frames);
* ``data``: how much the copy's objective differs from the original's at one timing (the original's
  start), relative: the size of the noise the rounding puts into the problem;
* ``own`` / ``same``: how far apart the two answers lie (source frames) when each problem starts from
  its own grid start, and when the copy starts from the original's: equal numbers say the grid start
  is not where they part;
* ``barrier``: along the straight segment between the two answers (on the original's objective, 9
  points), the highest value above the higher end, relative: > 0 means the answers are two distinct
  minima with a ridge between them (a flat valley would give 0), so the timing depends on which
  one the optimizer's path reaches, not on the rounding's size.

    python3 benchmarks/physics_minima.py                         # bundled clips
    python3 benchmarks/physics_minima.py CLIP ... --methods newton,lbfgs --scale 0.5 --knot-spacing 0.2
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from physics_converge import BUNDLED, float32_copy
from retime.errors import RetimeError
from retime.method import Request
from retime.motion import load_motion
from retime.motion.files import save_motion
from retime.physics.api import conformed_gravity, make_problem, prepare
from retime.physics.method import Settings, file_gravity
from retime.physics.timing.objective import evaluate_c
from retime.physics.timing.optimize import solve


def build(path, scale, settings):
    """(motion, problem at its grid start) as the physics front end builds them."""
    m = load_motion(path)
    _, _, _, obj = prepare(m, conformed_gravity(m, file_gravity(m, settings)), settings)
    duration = Request(scale=scale).output_duration(m)
    pr = make_problem(obj, m.duration, duration, (), settings.knot_spacing, settings.w_min, settings.w_max,
                      start=settings.start)
    return m, pr


def apart(pa, wa, pb, wb, fps):
    """Largest distance between two problems' timing curves, source frames."""
    t = np.arange(0.0, min(pa.spline.duration_of(wa), pb.spline.duration_of(wb)), 1.0 / fps)
    return float(np.max(np.abs(pa.spline(t, wa) - pb.spline(t, wb)))) * fps


def barrier(pr, wa, wb, points=9):
    """Highest objective on the segment between two answers (in (c, T)) above the higher end, relative."""
    sp = pr.spline
    ca, Ta = sp.coefficients(wa), sp.duration_of(wa)
    cb, Tb = sp.coefficients(wb), sp.duration_of(wb)
    vals = [evaluate_c(pr.obj, sp, (1 - t) * ca + t * cb, (1 - t) * Ta + t * Tb, workspace=pr.workspace)
            for t in np.linspace(0.0, 1.0, points)]
    top = max(vals[0], vals[-1])
    return (max(vals) - top) / max(abs(top), 1e-12)


def clip_rows(path, scale, methods, settings):
    with tempfile.TemporaryDirectory() as tmp:
        orig, f32 = Path(tmp) / "orig.bvh", Path(tmp) / "f32.bvh"
        save_motion(load_motion(path), orig)
        float32_copy(orig, f32)
        m, pa = build(orig, scale, settings)
        _, pb = build(f32, scale, settings)
    if pa.spline.n_c != pb.spline.n_c:
        raise RetimeError("the copy's spline has another number of coefficients (its grid start gave up other frames)")
    wa0, wb0 = pa.spline.w.copy(), pb.spline.w.copy()
    starts = apart(pa, wa0, pb, wb0, m.fps)
    data = pb.value(wa0) / pa.value(wa0) - 1.0
    rows = []
    for method in methods:
        wa, ia = solve(pa, wa0, method=method, max_iter=settings.max_iter, tol=1e-9)
        wb, ib = solve(pb, wb0, method=method, max_iter=settings.max_iter, tol=1e-9)
        ws, _ = solve(pb, wa0, method=method, max_iter=settings.max_iter, tol=1e-9)
        rows.append((method, starts, data, apart(pa, wa, pb, wb, m.fps), apart(pa, wa, pb, ws, m.fps),
                     barrier(pa, wa, wb), ia, ib))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--methods", default="newton", help="optimizers, comma-separated (default: newton)")
    ap.add_argument("--knot-spacing", type=float, default=None,
                    help="the timing spline's knot spacing, output seconds (default: physics' Settings)")
    args = ap.parse_args(argv)
    clips = args.clips or sorted(str(p) for p in BUNDLED.glob("*") if p.suffix in (".amc", ".bvh"))
    settings = Settings() if args.knot_spacing is None else Settings(knot_spacing=args.knot_spacing)
    print(f"{'clip':34s} {'method':7s} {'starts':>6s} {'data':>8s} {'own':>6s} {'same':>6s} {'barrier':>8s} "
          f"{'iterations':>11s}  objective orig / f32")
    for c in clips:
        try:
            rows = clip_rows(c, args.scale, args.methods.split(","), settings)
        except RetimeError as e:  # a clip physics refuses: say so, go on
            print(f"{Path(c).name[:34]:34s} refused: {str(e).splitlines()[0][:80]}", flush=True)
            continue
        for method, starts, data, own, same, ridge, ia, ib in rows:
            print(f"{Path(c).name[:34]:34s} {method:7s} {starts:6.3f} {data:+8.1e} {own:6.3f} {same:6.3f} {ridge:+8.1e} "
                  f"{ia.iterations:5d}/{ib.iterations:5d}  {ia.objective:.7g} / {ib.objective:.7g}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
