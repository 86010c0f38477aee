"""Fig. 13 of McCann et al. 2006: how the objective changes when one control point moves away from
the optimum (16_06 at half duration), and how the two starts compare.

For every third control point of the converged timing spline, its source time is shifted by up to
+-0.15 s (the others stay) and the objective is evaluated; the curves show the valley the optimum
sits in (the paper: "in general the current timing curve lies in a large valley ... a few nearby
minima"). The grid start (dynamic programming, ``start="global"``) and the paper's uniform start are
both converged and their objective values printed. Writes ``physics_landscape.png``.

    python3 examples/physics_landscape.py [OUT_DIR]
"""
from pathlib import Path

import numpy as np

from physics_common import load, parse_args
from retime.physics.api import make_problem, prepare
from retime.physics.method import Settings
from retime.physics.timing.optimize import RetimingSession
from retime.viz.plot import save_figure
from retime.warp import snap_duration

args = parse_args(__doc__.splitlines()[0])
m, terms = load("16_06")
_, pd, regions, obj = prepare(m, terms=terms)
T = snap_duration(m.duration / 2, m.fps)
sessions = {}
for start in ("global", "uniform"):
    s = RetimingSession(make_problem(obj, m.duration, T, start=start), Settings.optimizer, fps=m.fps)
    s.reconverge(max_iter=5000, tol=1e-10)
    sessions[start] = s
    print(f"  {start} start: objective {s.objective():.5f}")
best = min(sessions.values(), key=lambda s: s.objective())
base_w = best.spline.w.copy()
base = best.objective()
offsets = np.linspace(-0.15, 0.15, 31)
cps = best.control_points()
rows = []
for k in range(2, len(cps) - 2, 3):
    vals = []
    for d in offsets:
        best.spline.w = base_w.copy()
        best.move(k, cps[k]["source_time"] + d)
        vals.append(best.objective() - base)
    rows.append((k, np.array(vals)))
best.spline.w = base_w

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(8, 4.5))
cmap = plt.get_cmap("viridis")
for n, (k, vals) in enumerate(rows):
    ax.plot(offsets, vals, color=cmap(n / max(1, len(rows) - 1)), lw=1)
ax.set_xlabel("offset of one control point from the optimum (s of source time)")
ax.set_ylabel("objective - optimum")
ax.set_yscale("symlog", linthresh=1e-3)
ax.set_title("16_06 at half duration: objective around the optimum, one control point at a time\n"
             "(colour: control point from the start to the end of the clip)")
ax.axvline(0.0, color="k", lw=0.5)
out = Path(args.out) / "physics_landscape.png"
save_figure(fig, out)
lower = sum(1 for _, v in rows if np.any(v < -1e-6))
print(f"  {len(rows)} control points probed; {lower} of them find a lower objective nearby "
      f"(a neighbouring minimum) -> {out}")
