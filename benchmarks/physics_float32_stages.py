"""Issue 24: where in the physics pipeline does a float32 copy's rounding grow?

For each clip: a BVH as converted and its float32 copy (every motion channel rounded to float32,
written, read back; :func:`physics_converge.float32_copy`), both run through the physics pipeline
stage by stage at ``--scale`` (default 0.5). Per stage it prints the largest change of the copy
against the original, relative to the stage's own size (the largest magnitude of that array over
the clip), and the frame where it happens; discrete stages (contact states, polygon vertex counts,
the grid start's frames given up) print how many frames differ. The input's own rounding is ~3e-8
relative; a stage whose change is orders of magnitude above its inputs' amplifies it.

    python3 benchmarks/physics_float32_stages.py                     # 16_33, 02_04
    python3 benchmarks/physics_float32_stages.py CLIP.bvh ... --scale 0.5 --no-solve
    python3 benchmarks/physics_float32_stages.py CLIP.bvh --perturb 1e-9   # the optimizer's share
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

from physics_converge import float32_copy
from retime.motion import load_motion
from retime.motion.files import save_motion
from retime.physics.api import make_problem, prepare
from retime.physics.method import Settings
from retime.motion.feet import above_own_floor, local_floor
from retime.physics.model.dynamics import dynamics_terms
from retime.physics.regions import RegionOptions
from retime.physics.timing.globalstart import global_start
from retime.physics.timing.optimize import RetimingSession
from retime.warp import output_duration

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DEFAULT_CLIPS = [SHARED / "cmu" / "16_33.amc", SHARED / "cmu" / "02_04.bvh"]


def change(a, b, frames_axis=0):
    """(largest change relative to the array's size, the frame it is on) of b against a."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape:
        return None, None
    if a.size == 0:
        return 0.0, None
    size = float(np.max(np.abs(a))) or 1.0
    d = np.abs(a - b).reshape(a.shape[0], -1).max(axis=1) if a.ndim else np.abs(a - b).reshape(1)
    k = int(np.argmax(d))
    return float(d[k]) / size, k


def frame_of_sample(k, spf):
    return None if k is None else k // spf


def line(name, rel, where, note=""):
    r = "shape differs" if rel is None else f"{rel:9.2e}"
    w = "" if where is None else f"frame {where}"
    print(f"  {name:34s} {r:>13s}  {w:12s} {note}", flush=True)


def polygons(regions):
    """Per frame the vertex count, and the frames whose polygons have equal counts in both."""
    return np.diff(regions.offsets)


def stages(motion_a, motion_b, scale, solve, perturb=0.0, unique_vertex_forces=False):
    fps = motion_a.fps
    s = Settings()
    spf = s.samples_per_frame
    line("input: root positions", *change(motion_a.root_positions, motion_b.root_positions))
    line("input: joint rotations", *change(motion_a.rotations, motion_b.rotations))
    ta, tb = (dynamics_terms(m, s.body, contacts=s.contacts, smoothing=s.smoothing) for m in (motion_a, motion_b))
    rel, k = change(ta.sole_path[0], tb.sole_path[0])
    line("smoothed path: root", rel, frame_of_sample(k, 1))
    rel, k = change(ta.sole_path[1], tb.sole_path[1])
    line("smoothed path: joint quaternions", rel, k)
    rel, k = change(ta.com, tb.com)
    line("centre of mass", rel, k)
    rel, k = change(ta.corners, tb.corners)
    line("sole corners", rel, k)
    line("body: segment masses", *change(ta.tree.mass, tb.tree.mass))
    low_a = np.minimum(ta.corners[:, 0::2, 1], ta.corners[:, 1::2, 1])
    low_b = np.minimum(tb.corners[:, 0::2, 1], tb.corners[:, 1::2, 1])
    fa, fb = local_floor(low_a, fps), local_floor(low_b, fps)
    line("floor estimate (local floor)", *change(fa, fb))
    line("heights above own floor", *change(above_own_floor(low_a, fps), above_own_floor(low_b, fps)))
    flips = np.flatnonzero(np.any(ta.contact != tb.contact, axis=1))
    line("contact states (samples differing)", float(len(flips)), None,
         f"frames {sorted(set(int(i) for i in flips // spf))[:12]}" if len(flips) else "")
    line("torque limits", *change(ta.tau_limit, tb.tau_limit))
    line("reference torques tau_ref", *change(ta.tau_ref, tb.tau_ref))
    rel, k = change(ta.lambda_ref, tb.lambda_ref)
    line("reference forces lambda_ref", rel, k)

    settings = s
    _, pda, ra, oa = prepare(motion_a, terms=ta, settings=settings,
                             region_options=RegionOptions(unique_vertex_forces=unique_vertex_forces))
    _, pdb, rb, ob = prepare(motion_b, terms=tb, settings=settings,
                             region_options=RegionOptions(unique_vertex_forces=unique_vertex_forces))
    for name in ("a", "b", "c", "b_noise"):
        line(f"path dynamics {name}", *change(getattr(pda, name), getattr(pdb, name)))
    line("regions: budget (source residual)", *change(ra.budget, rb.budget))
    line("regions: lam0 (original forces)", *change(ra.lam0, rb.lam0))
    line("regions: fan centres", *change(ra.center, rb.center))
    line("regions: centre forces", *change(ra.center_lam, rb.center_lam))
    line("regions: torque bounds lo/hi", *change(np.c_[ra.lo, ra.hi], np.c_[rb.lo, rb.hi]))
    line("regions: relaxation", *change(ra.relaxation, rb.relaxation))
    na, nb = polygons(ra), polygons(rb)
    differ = np.flatnonzero(na != nb)
    line("regions: vertex counts (frames differing)", float(len(differ)), None,
         f"frames {differ[:12].tolist()}" if len(differ) else "")
    vmax, vk, lmax, lk = 0.0, None, 0.0, None
    vsize = float(np.max(np.abs(ra.verts))) or 1.0
    lsize = float(np.max(np.abs(ra.lam))) or 1.0
    for i in np.flatnonzero(na == nb):
        dv = float(np.max(np.abs(ra.polygon(i) - rb.polygon(i)), initial=0.0)) / vsize
        dl = float(np.max(np.abs(ra.polygon_lam(i) - rb.polygon_lam(i)), initial=0.0)) / lsize
        if dv > vmax:
            vmax, vk = dv, int(i)
        if dl > lmax:
            lmax, lk = dl, int(i)
    line("regions: polygon vertices", vmax, vk)
    line("regions: vertex forces", lmax, lk)
    A, B = oa.arrays, ob.arrays
    for name in ("cen", "scale", "mode"):
        line(f"baked: {name}", *change(getattr(A, name), getattr(B, name)))
    if A.poff.shape == B.poff.shape and np.array_equal(A.poff, B.poff):
        frame_of = np.repeat(np.arange(len(A.poff) - 1), np.diff(A.poff))
        for name in ("px", "py", "wc", "ray"):
            rel, k = change(getattr(A, name), getattr(B, name))
            line(f"baked: {name}", rel, None if k is None else int(frame_of[k]))
    else:
        line("baked: wedges", None, None)
    T = output_duration(motion_a.duration, fps, None, scale)  # as physics asks for it: on the frame grid
    ga, gb = global_start(oa, T), global_start(ob, T)
    line("grid start: duration", abs(ga.duration - gb.duration) / ga.duration, None)
    rel, k = change(ga.speed, gb.speed)
    line("grid start: speed at nodes", rel, None if k is None else int(round(ga.times[k] * fps)))
    line("grid start: frames given up (differ)", float(np.sum(ga.outside != gb.outside)), None)
    t = np.arange(0.0, T, 1.0 / fps)
    pa, pb = make_problem(oa, motion_a.duration, T), make_problem(ob, motion_b.duration, T)
    start_a, start_b = pa.spline(t, pa.spline.w), pb.spline(t, pb.spline.w)
    k = int(np.argmax(np.abs(start_a - start_b)))
    line("spline start: timing (source frames)", float(np.abs(start_a - start_b)[k] * fps), k, "(output frame)")
    if pa.spline.n_c == pb.spline.n_c:
        va, vb = pa.value(pa.spline.w), pb.value(pa.spline.w)
        line("objective at the original's start", abs(vb / va - 1.0), None)
    if not solve:
        return
    sa, sb = RetimingSession(pa, optimizer=s.optimizer, fps=fps), RetimingSession(pb, optimizer=s.optimizer, fps=fps)
    ia, ib = sa.reconverge(max_iter=s.max_iter, tol=1e-9), sb.reconverge(max_iter=s.max_iter, tol=1e-9)
    wa = sa.spline.w
    if pa.spline.n_c == pb.spline.n_c:
        line("objective at the original's answer", abs(pb.value(wa) / pa.value(wa) - 1.0), None)
    fa_, fb_ = sa.spline(t, wa), sb.spline(t, sb.spline.w)
    k = int(np.argmax(np.abs(fa_ - fb_)))
    line("final timing (source frames)", float(np.abs(fa_ - fb_)[k] * fps), k,
         f"(output frame) objective {ia.objective:.9g} / {ib.objective:.9g}")
    if perturb:
        # the optimizer's own amplification: the original's problem, its torque coefficients moved
        # by a relative ``perturb`` (no rounding of the input at all)
        rng = np.random.default_rng(0)
        wc = oa.arrays.wc * (1.0 + perturb * rng.standard_normal(oa.arrays.wc.shape))
        pc = make_problem(dataclasses.replace(oa, arrays=oa.arrays._replace(wc=wc)), motion_a.duration, T)
        sc = RetimingSession(pc, optimizer=s.optimizer, fps=fps)
        ic = sc.reconverge(max_iter=s.max_iter, tol=1e-9)
        fc = sc.spline(t, sc.spline.w)
        k = int(np.argmax(np.abs(fa_ - fc)))
        line(f"final timing, wc x (1 + {perturb:g} N(0,1))", float(np.abs(fa_ - fc)[k] * fps), k,
             f"(output frame) objective {ia.objective:.9g} / {ic.objective:.9g}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("clips", nargs="*")
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--no-solve", action="store_true", help="stop before the optimizer")
    ap.add_argument("--perturb", type=float, default=0.0,
                    help="also solve the original with its torque coefficients moved by this relative noise")
    ap.add_argument("--unique-vertex-forces", action="store_true",
                    help="the regions' vertex forces made unique (RegionOptions.unique_vertex_forces)")
    args = ap.parse_args(argv)
    for c in args.clips or DEFAULT_CLIPS:
        with tempfile.TemporaryDirectory() as tmp:
            src, f32 = Path(tmp) / "orig.bvh", Path(tmp) / "f32.bvh"
            save_motion(load_motion(c), src)
            float32_copy(src, f32)
            print(f"{Path(c).name}: change of the float32 copy, relative to each stage's size", flush=True)
            stages(load_motion(src), load_motion(f32), args.scale, not args.no_solve, args.perturb,
                   args.unique_vertex_forces)
    return 0


if __name__ == "__main__":
    sys.exit(main())
