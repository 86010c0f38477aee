"""Shared helpers of the guided time warping examples (examples/guided_*.py).

Each example writes, for each result, into the output folder given on its command line (default
examples/out/): the retimed motion (BVH), its timing curve (CSV, one row per output frame) and a
plot of the timing curve and of its playback speed on a log scale, like Fig. 5 of Hsu et al. 2007
(the centre line is the original speed, the limits tenfold slow motion and fast-forward).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

from retime.data import CMU_DIR
from retime.motion import load_motion, save_bvh
from retime.viz.plot import plot_timing, save_figure
from retime.warp import apply_timing

HERE = Path(__file__).resolve().parent


def parse_args(description):
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("out", nargs="?", default=str(HERE / "out"), help="output folder (default examples/out/)")
    ap.add_argument("--data", help="folder with CMU clips not bundled with retime (default $RETIME_CMU_DATA "
                                   "or ../shared/data/cmu)")
    args = ap.parse_args()
    Path(args.out).mkdir(parents=True, exist_ok=True)
    return args


def find_clip(name, data=None):
    """A CMU clip: bundled with retime, or in --data, $RETIME_CMU_DATA or ../shared/data/cmu."""
    for d in (data, os.environ.get("RETIME_CMU_DATA"), CMU_DIR, HERE.parent.parent / "shared" / "data" / "cmu",
              Path("/work/shared/data/cmu")):
        if d and (Path(d) / name).exists():
            return Path(d) / name
    return None


def load(name, data=None):
    path = find_clip(name, data)
    if path is None:
        print(f"  {name}: not found (bundled clips and --data); skipped", file=sys.stderr)
        return None
    return load_motion(path)


def write_result(out_dir, stem, motion, curve, title, others=(), spans=(), retimed=None):
    """BVH, warp CSV and speed plot of ``motion`` played through ``curve``.

    others: more (label, curve) pairs to draw (e.g. the linear warp); spans: (source start, source
    end, label) intervals shaded on the plot at the output times they play.
    """
    out_dir = Path(out_dir)
    retimed = apply_timing(motion, curve) if retimed is None else retimed
    bvh, csv, png = out_dir / f"{stem}.bvh", out_dir / f"{stem}.csv", out_dir / f"{stem}.png"
    save_bvh(retimed, bvh)
    curve.to_csv(csv, motion.fps)
    fig = plot_timing([("guided", curve), *others], title=title)
    ax_speed = fig.axes[-1]
    ax_warp = fig.axes[0] if len(fig.axes) > 1 else None
    for a, b, label in spans:
        t0, t1 = float(curve.inverse(a)), float(curve.inverse(b))
        ax_speed.axvspan(t0, t1, color="#fde68a", alpha=0.5, zorder=0)
        ax_speed.text(0.5 * (t0 + t1), 0.13, label, ha="center", va="bottom", fontsize=8, color="#92400e")
        if ax_warp is not None:
            ax_warp.axhspan(a, b, color="#fde68a", alpha=0.5, zorder=0)
    save_figure(fig, png)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return bvh, csv, png


def speed_where(curve, mask_fn, n=2000):
    """Mean playback speed over output times whose source time satisfies mask_fn(source_times)."""
    t = np.linspace(0.0, curve.duration, n)
    v = curve.speed(t)
    sel = mask_fn(curve(t))
    return float(np.exp(np.mean(np.log(np.maximum(v[sel], 1e-9))))) if sel.any() else float("nan")
