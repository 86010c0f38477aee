"""Shared helpers of the physics-based retiming examples (examples/physics_*.py), McCann et al. 2006.

Each example writes, for each result, into the output folder given on its command line (default
examples/out/): the retimed motion (``NAME.bvh``), its timing curve (``NAME.warp.csv``, one row per output
frame) and the per-frame report (``NAME.report.json``: contact, feasibility, distance to the feasible
region, torque norm, phase speeds), and prints a one-line summary.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from retime.data import bundled_path
from retime.motion import load_motion, save_bvh
from retime.physics.api import DEFAULT_SMOOTHING, physics_warp
from retime.physics.model.dynamics import dynamics_terms
from retime.physics.report import flight_speeds, write_report
from retime.warp import apply_timing

HERE = Path(__file__).resolve().parent


def parse_args(description):
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("out", nargs="?", default=str(HERE / "out"), help="output folder (default examples/out/)")
    args = ap.parse_args()
    Path(args.out).mkdir(parents=True, exist_ok=True)
    return args


def load(name):
    """A bundled CMU clip and its dynamics terms (computed once, recombined for every setting)."""
    m = load_motion(bundled_path(f"{name}.amc"))
    return m, dynamics_terms(m, smoothing=DEFAULT_SMOOTHING)


def retime(motion, terms, out, tag, **kw):
    """physics_warp + outputs; returns the result."""
    r = physics_warp(motion, terms=terms, **kw)
    out = Path(out)
    save_bvh(apply_timing(motion, r.curve), out / f"{tag}.bvh")
    r.curve.to_csv(out / f"{tag}.warp.csv", motion.fps)
    write_report(r.report, out / f"{tag}.report.json")
    s = r.report["summary"]
    fl = ", ".join(f"{x:.2f}" for x in flight_speeds(r.report)) or "-"
    print(f"{tag}: {s['duration']:.2f} s (source {s['source_duration']:.2f} s), flight speed {fl}, "
          f"{100 * s['feasible_fraction']:.1f}% of frames feasible -> {out / tag}.bvh")
    return r


def stance_speeds(r, terms):
    """Mean playback speed over the frames where only the left / only the right foot is down."""
    c = np.asarray(terms.contact, dtype=bool)  # left heel, left toe, right heel, right toe
    left = c[:, :2].any(axis=1) & ~c[:, 2:].any(axis=1)
    right = c[:, 2:].any(axis=1) & ~c[:, :2].any(axis=1)
    t = np.asarray(terms.times)
    out = {}
    for name, mask in (("left", left), ("right", right)):
        if mask.any():
            ts = r.spline.inverse(t[mask])
            out[name] = float(np.mean(r.spline.speed(ts)))
    return out
