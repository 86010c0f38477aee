"""Physics reports: reading them, the feasible-region plot (McCann et al. 2006, Fig. 4 and 6) and
the per-frame contact / feasibility strip, and contact states for the renderer.

A report (written by ``retime physics --report``) is a JSON object with ``feasible_fraction`` and
``frames``, one record per output frame.  The fields read here (other fields are ignored):

    output_time, source_time   output and source time of the frame (seconds)
    source_frame       the source frame whose region applies
    p_ddot, p_dot2     the chosen timing (p'', p'^2) at the frame
    in_region          whether (p'', p'^2) lies in the frame's feasible region
    distance           distance from (p'', p'^2) to the region (0 inside)
    torque_norm        norm of the joint torques at the chosen timing
    contact            names of the contact points (or joints) touching the ground, or a
                       {name: bool} mapping
    region             optional polygon [[p'', p'^2], ...] of the feasible region
    objective          optional {"pdd": [...], "pd2": [...], "values": [[...]]}: the objective's
                       magnitude on a grid (values[i][j] at pd2[i], pdd[j])

Also accepted: ``t``/``s``, ``pdd``/``pd2`` or ``point: [p'', p'^2]``, ``contacts``, ``feasible``,
``polygon``/``hull`` for the region; ``feasible_fraction`` at the top or in ``summary``.  Regions may
also be stored once per source frame beside the frames: ``regions: [polygon, ...]`` or
``{source frame: polygon or {"polygon": ..., "objective": ...}}``.
"""

from __future__ import annotations

import json
import math
import os
import re
from typing import Any

import numpy as np

from retime.errors import FormatError, RetimeError

_POINT_KEYS = (("pdd", "pd2"), ("p_ddot", "p_dot2"), ("p_ddot", "p_dot_sq"), ("p_dd", "p_d2"))


def load_report(path: str | os.PathLike) -> dict:
    """Read and check a physics report; returns the JSON object with ``frames`` normalised."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8") as f:
            data = json.load(f)
    except FileNotFoundError:
        raise FormatError(path, "file not found") from None
    except json.JSONDecodeError as exc:
        raise FormatError(path, f"not valid JSON ({exc.msg})", line=exc.lineno) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise FormatError(path, f"cannot read ({exc})") from None
    return normalise_report(data, path)


def normalise_report(data: Any, path: str = "<report>") -> dict:
    if not isinstance(data, dict) or not isinstance(data.get("frames"), list) or not data["frames"]:
        raise FormatError(path, "not a physics report: expected an object with a non-empty 'frames' list")
    frames = []
    for i, rec in enumerate(data["frames"]):
        if not isinstance(rec, dict):
            raise FormatError(path, f"frame {i}: expected an object")
        frames.append(_frame_record(rec, i, path))
    out = dict(data)
    out["frames"] = frames
    summary = data.get("summary")
    if isinstance(summary, dict) and "feasible_fraction" in summary and "feasible_fraction" not in out:
        out["feasible_fraction"] = summary["feasible_fraction"]
    # regions stored beside the frames: a list or {index: ...}, indexed by source frame when the
    # frames name their source frame, else by output frame; an entry is a polygon or
    # {"polygon": ..., "objective": ...}
    regions = data.get("regions") or {}
    items = enumerate(regions) if isinstance(regions, list) else regions.items() if isinstance(regions, dict) else ()
    by_index = {}
    for key, extra in items:
        try:
            by_index[int(key)] = extra if isinstance(extra, dict) else {"polygon": extra}
        except (TypeError, ValueError):
            continue
    if by_index:
        use_source = all(f["source_frame"] is not None for f in frames)
        for k, rec in enumerate(frames):
            extra = by_index.get(rec["source_frame"] if use_source else k)
            if extra is None:
                continue
            more = _frame_record(dict(extra), k, path)
            for field in ("region", "objective"):
                if more.get(field) is not None and rec.get(field) is None:
                    rec[field] = more[field]
    if "feasible_fraction" not in out:
        flags = [f["feasible"] for f in frames if f["feasible"] is not None]
        out["feasible_fraction"] = float(np.mean(flags)) if flags else None
    return out


def _frame_record(rec: dict, i: int, path: str) -> dict:
    point = None
    for a, b in _POINT_KEYS:
        if a in rec and b in rec:
            point = (rec[a], rec[b])
            break
    if point is None and isinstance(rec.get("point"), (list, tuple)) and len(rec["point"]) == 2:
        point = tuple(rec["point"])
    if point is not None:
        try:
            point = (float(point[0]), float(point[1]))
        except (TypeError, ValueError):
            raise FormatError(path, f"frame {i}: the timing (p'', p'^2) must be two numbers") from None
        if not all(np.isfinite(point)):
            raise FormatError(path, f"frame {i}: the timing (p'', p'^2) is not finite ({point[0]}, {point[1]})")
    region = rec.get("region", rec.get("polygon", rec.get("hull")))
    if region is not None:
        try:
            region = np.asarray(region, dtype=np.float64).reshape(-1, 2)
        except (TypeError, ValueError):
            raise FormatError(path, f"frame {i}: the region must be a list of [p'', p'^2] points") from None
        if not np.all(np.isfinite(region)):
            raise FormatError(path, f"frame {i}: the region has a point that is not finite")
    objective = rec.get("objective")
    if isinstance(objective, dict):
        try:
            objective = {
                "pdd": np.asarray(objective["pdd"], dtype=np.float64),
                "pd2": np.asarray(objective["pd2"], dtype=np.float64),
                "values": np.asarray(objective["values"], dtype=np.float64),
            }
        except (KeyError, TypeError, ValueError):
            raise FormatError(path, f"frame {i}: objective needs 'pdd', 'pd2' and 'values' arrays") from None
        if objective["values"].shape != (len(objective["pd2"]), len(objective["pdd"])):
            raise FormatError(path, f"frame {i}: objective values must be len(pd2) x len(pdd)")
    else:
        objective = None
    contacts = rec.get("contacts", rec.get("contact"))
    if isinstance(contacts, dict):
        contacts = [str(k) for k, v in contacts.items() if v]
    elif isinstance(contacts, (list, tuple)):
        contacts = [str(c) for c in contacts]
    elif contacts is None:
        contacts = None
    else:
        raise FormatError(path, f"frame {i}: contacts must be a list of names or a {{name: bool}} object")
    feasible = rec.get("feasible", rec.get("in_region"))
    source_frame = rec.get("source_frame")
    return {
        "t": _num(rec.get("t", rec.get("output_time", rec.get("time")))),
        "s": _num(rec.get("s", rec.get("source_time"))),
        "source_frame": int(source_frame) if isinstance(source_frame, (int, float)) else None,
        "point": point,
        "feasible": None if feasible is None else bool(feasible),
        "distance": _num(rec.get("distance")),
        "torque_norm": _num(rec.get("torque_norm")),
        "contacts": contacts,
        "region": region,
        "objective": objective,
    }


def _num(v):
    try:
        return None if v is None else float(v)
    except (TypeError, ValueError):
        return None


# ---------------------------------------------------------------------- contacts for the renderer
def _contact_joint(name: str, names: list[str]) -> int | None:
    """Joint index for a contact name: the joint itself, else side + part (heel/toe/foot/hand)."""
    lower = [n.lower() for n in names]
    key = name.lower()
    if key in lower:
        return lower.index(key)
    side = "l" if re.match(r"^(l(?!ower)|left)", key) else "r" if re.match(r"^(r(?!oot)|right)", key) else None
    if side is None:
        return None
    if re.search(r"toe|ball", key):
        parts = ("toes", "toe", "toebase", "foot")
    elif re.search(r"heel|ankle|foot|sole", key):
        parts = ("foot", "ankle")
    elif re.search(r"hand|wrist|finger", key):
        parts = ("hand", "wrist")
    else:
        return None
    prefixes = ("l", "left", "l_", "left_") if side == "l" else ("r", "right", "r_", "right_")
    for part in parts:
        for pre in prefixes:
            if pre + part in lower:
                return lower.index(pre + part)
    return None


def report_contacts(report: dict, skeleton, n_frames: int, path: str = "<report>") -> np.ndarray:
    """(n_frames, J) bool: the joints in contact in each frame of the report."""
    frames = report["frames"]
    if len(frames) != n_frames:
        raise RetimeError(f"{path}: the report has {len(frames)} frames, the motion {n_frames}")
    names = list(skeleton.names)
    out = np.zeros((n_frames, len(names)), dtype=bool)
    unknown = set()
    for k, rec in enumerate(frames):
        for c in rec["contacts"] or ():
            j = _contact_joint(c, names)
            if j is None:
                unknown.add(c)
            else:
                out[k, j] = True
    if unknown and not out.any():
        raise RetimeError(f"{path}: no joint matches the contact names {sorted(unknown)[:4]}")
    return out


def report_source_contacts(report: dict, skeleton, n_source: int, path: str = "<report>") -> np.ndarray:
    """(n_source, J) bool: contact joints per *source* frame, from the frames' ``source_frame``
    (source frames no output frame shows take the nearest one that is shown)."""
    frames = report["frames"]
    src = [f["source_frame"] for f in frames]
    if any(s is None for s in src):
        raise RetimeError(f"{path}: the report does not name the source frame of each output frame")
    per_output = report_contacts(report, skeleton, len(frames), path)
    known = np.full(n_source, -1, dtype=np.int64)
    for k, i in enumerate(src):
        if 0 <= i < n_source:
            known[i] = k
    shown = np.nonzero(known >= 0)[0]
    if len(shown) == 0:
        raise RetimeError(f"{path}: the report's source frames do not fit a motion of {n_source} frames")
    nearest = shown[np.clip(np.searchsorted(shown, np.arange(n_source)), 0, len(shown) - 1)]
    left = shown[np.clip(np.searchsorted(shown, np.arange(n_source)) - 1, 0, len(shown) - 1)]
    pick = np.where(np.abs(left - np.arange(n_source)) <= np.abs(nearest - np.arange(n_source)), left, nearest)
    return per_output[known[pick]]


def contacts_through_curve(source_contacts: np.ndarray, source_fps: float, curve, n_frames: int, fps: float) -> np.ndarray:
    """Per-frame contacts of a motion played through ``curve``: those of the source frame shown."""
    t = np.minimum(np.arange(n_frames) / fps, curve.duration)
    idx = np.clip(np.rint(np.asarray(curve(t)) * source_fps).astype(int), 0, len(source_contacts) - 1)
    return source_contacts[idx]


def contact_names(report: dict) -> list[str]:
    seen: dict[str, None] = {}
    for rec in report["frames"]:
        for c in rec["contacts"] or ():
            seen.setdefault(c, None)
    return sorted(seen, key=lambda n: (not n.lower().startswith("l"), n))


# ---------------------------------------------------------------------- the region plot
def _polygon_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Euclidean distance from each point (N, 2) to the convex hull of ``poly`` (0 inside)."""
    from retime.physics.regions.polygon import closest_points_numpy, convex_hull

    hull = convex_hull(poly)
    if len(hull) == 0:
        return np.full(len(points), np.inf)
    return closest_points_numpy(hull, points, inside_tol=1e-12)[1]


def pick_frame(report: dict) -> int:
    """Default frame to show: the one farthest from its region, else the middle frame with a region."""
    frames = report["frames"]
    dists = [(f["distance"] or 0.0, i) for i, f in enumerate(frames) if f["region"] is not None]
    if dists:
        best = max(dists, key=lambda d: d[0])  # the first of the farthest
        return best[1] if best[0] > 0 else dists[len(dists) // 2][1]
    return len(frames) // 2


def plot_regions(report: dict, frame: int | None, path=None, title: str | None = None, size=(11.0, 6.2), dpi=110):
    """McCann Fig. 4/6 for one frame plus the per-frame contact / feasibility strip. Returns the frame index."""
    from matplotlib import colors as mcolors
    from matplotlib.patches import Polygon

    from retime.viz.plot import _new_figure, _style, save_figure

    frames = report["frames"]
    n = len(frames)
    if frame is None:
        frame = pick_frame(report)
    if not 0 <= frame < n:
        raise RetimeError(f"--frame {frame} is outside the report (frames 0 to {n - 1})")
    rec = frames[frame]
    fig = _new_figure(*size, dpi=dpi)
    gs = fig.add_gridspec(2, 2, height_ratios=[3.2, 1.25], width_ratios=[1.0, 1.0])
    ax = fig.add_subplot(gs[0, 0])
    ax_info = fig.add_subplot(gs[0, 1])
    ax_strip = fig.add_subplot(gs[1, :])

    # --- region and objective for the frame
    _style(ax)
    poly = rec["region"]
    pts = [(0.0, 1.0)] + ([rec["point"]] if rec["point"] is not None else [])
    extent_pts = np.array(pts + (poly.tolist() if poly is not None and len(poly) else []))
    lo = extent_pts.min(axis=0)
    hi = extent_pts.max(axis=0)
    span = np.maximum(hi - lo, 0.5)
    lo, hi = lo - 0.35 * span, hi + 0.35 * span
    obj = rec["objective"]
    heat_label = None
    if obj is not None:
        X, Y, Z = obj["pdd"], obj["pd2"], obj["values"]
        lo = np.minimum(lo, [X.min(), Y.min()])
        hi = np.maximum(hi, [X.max(), Y.max()])
        heat_label = "objective"
    elif poly is not None and len(poly):
        X = np.linspace(lo[0], hi[0], 240)
        Y = np.linspace(lo[1], hi[1], 240)
        gx, gy = np.meshgrid(X, Y)
        Z = _polygon_distance(np.stack([gx.ravel(), gy.ravel()], 1), poly).reshape(gx.shape) ** 2
        heat_label = "squared distance to the region (Eq. 14, first term)"
    if heat_label is not None:
        Zp = np.abs(np.asarray(Z, dtype=np.float64))
        positive = Zp[Zp > 0]
        vmin = max(positive.min(), positive.max() * 1e-4) if positive.size else 1e-6
        vmax = max(Zp.max(), vmin * 10)
        mesh = ax.pcolormesh(X, Y, np.maximum(Zp, vmin), shading="auto", cmap="magma_r",
                             norm=mcolors.LogNorm(vmin=vmin, vmax=vmax), rasterized=True, zorder=0)
        cb = fig.colorbar(mesh, ax=ax, fraction=0.046, pad=0.02)
        cb.set_label(heat_label, fontsize=8)
        cb.ax.tick_params(labelsize=7)
    if poly is not None and len(poly) >= 3:
        from retime.physics.regions.polygon import convex_hull

        hull = convex_hull(poly)
        ax.add_patch(Polygon(hull, closed=True, facecolor=(0.30, 0.64, 0.42, 0.18), edgecolor="#2f7d4f",
                             linewidth=2.0, zorder=2, label="feasible region"))
    elif poly is not None and len(poly):
        ax.plot(poly[:, 0], poly[:, 1], color="#2f7d4f", linewidth=2.0, zorder=2, label="feasible region")
    else:
        ax.text(0.5, 0.04, "no region stored for this frame", transform=ax.transAxes, ha="center", fontsize=8, color="#6b7280")
    ax.plot([0.0], [1.0], marker="o", markersize=8, markerfacecolor="white", markeredgecolor="#111827",
            markeredgewidth=1.6, linestyle="none", zorder=4, label="original timing (0, 1)")
    if rec["point"] is not None:
        ax.plot([rec["point"][0]], [rec["point"][1]], marker="*", markersize=14, color="#d6604d",
                markeredgecolor="#7f1d1d", linestyle="none", zorder=5, label="chosen timing")
    ax.axhline(0, color="#9ca3af", linewidth=0.8, zorder=1)
    ax.axvline(0, color="#9ca3af", linewidth=0.8, zorder=1)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(min(lo[1], -0.05 * span[1]), hi[1])
    ax.set_xlabel("p''  (source acceleration, 1/s)", fontsize=9)
    ax.set_ylabel("p'^2  (squared playback speed)", fontsize=9)
    ax.set_title(f"frame {frame}: feasible region in the (p'', p'^2) plane", fontsize=10, loc="left")
    ax.legend(frameon=True, framealpha=0.9, fontsize=8, loc="best")

    # --- numbers for the frame
    ax_info.axis("off")
    lines = [("frame", f"{frame} of {n}")]
    if rec["t"] is not None:
        lines.append(("output time", f"{rec['t']:.3f} s"))
    if rec["s"] is not None:
        lines.append(("source time", f"{rec['s']:.3f} s"))
    if rec["point"] is not None:
        pdd, pd2 = rec["point"]
        lines.append(("p''", f"{pdd:.3f}"))
        lines.append(("p'^2  (speed)", f"{pd2:.3f}  ({math.sqrt(max(pd2, 0.0)):.2f}x)"))
    if rec["feasible"] is not None:
        lines.append(("feasible", "yes" if rec["feasible"] else "no"))
    if rec["distance"] is not None:
        lines.append(("distance to region", f"{rec['distance']:.4g}"))
    if rec["torque_norm"] is not None:
        lines.append(("torque norm", f"{rec['torque_norm']:.4g}"))
    contacts = rec["contacts"] or []
    lines.append(("contacts", "\n".join(", ".join(contacts[i:i + 2]) for i in range(0, len(contacts), 2)) or "none (flight)"))
    ff = report.get("feasible_fraction")
    if ff is not None:
        lines.append(("feasible fraction (clip)", f"{float(ff):.3f}"))
    y = 0.95
    for k, v in lines:
        ax_info.text(0.02, y, k, fontsize=9.5, color="#6b7280", transform=ax_info.transAxes, va="top")
        ax_info.text(0.48, y, v, fontsize=9.5, color="#111827", transform=ax_info.transAxes, va="top", linespacing=1.4)
        y -= 0.085 * (1 + v.count("\n"))

    # --- per-frame strip
    _contact_strip(ax_strip, report, frame)
    if title:
        fig.suptitle(title, fontsize=12, x=0.01, ha="left")
    if path is not None:
        save_figure(fig, path)
    return frame


def _contact_strip(ax, report: dict, frame: int | None = None) -> None:
    """Rows of contact state per contact name and a feasibility row, over the report's frames."""
    frames = report["frames"]
    n = len(frames)
    names = contact_names(report)
    rows = names + ["feasible"]
    img = np.ones((len(rows), n, 3))
    contact_rgb = np.array([1.0, 0.69, 0.0])
    for k, rec in enumerate(frames):
        active = set(rec["contacts"] or ())
        for r, name in enumerate(names):
            if name in active:
                img[r, k] = contact_rgb
            else:
                img[r, k] = (0.95, 0.96, 0.97)
        feas = rec["feasible"]
        img[-1, k] = (0.85, 0.87, 0.9) if feas is None else (0.30, 0.64, 0.42) if feas else (0.84, 0.33, 0.27)
    ts = [rec["t"] for rec in frames]
    if all(t is not None for t in ts) and n > 1:
        x0, x1 = ts[0], ts[-1]
        xlabel = "output time (s)"
    else:
        x0, x1 = 0, n - 1
        xlabel = "output frame"
    half = 0.5 * (x1 - x0) / max(n - 1, 1)
    ax.imshow(img, aspect="auto", interpolation="nearest", extent=(x0 - half, x1 + half, len(rows) - 0.5, -0.5))
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels(rows, fontsize=8)
    ax.set_xlabel(xlabel, fontsize=9)
    ax.tick_params(labelsize=8)
    for spine in ax.spines.values():
        spine.set_color("#d1d5db")
    if frame is not None:
        x = x0 + (x1 - x0) * frame / max(n - 1, 1)
        ax.axvline(x, color="#111827", linewidth=1.2)
    ff = report.get("feasible_fraction")
    title = "contacts (orange) and feasibility (green = feasible, red = not)"
    if ff is not None:
        title += f"; feasible fraction {float(ff):.3f}"
    ax.set_title(title, fontsize=9, loc="left")


def plot_contact_strip(report: dict, path=None, size=(10.0, 2.2), dpi=120):
    """Only the per-frame contact / feasibility strip (for the demo report)."""
    from retime.viz.plot import _new_figure, save_figure

    fig = _new_figure(*size, dpi=dpi)
    ax = fig.add_subplot(1, 1, 1)
    _contact_strip(ax, report)
    if path is not None:
        save_figure(fig, path)
    return fig


# ---------------------------------------------------------------------- from a physics result
def physics_frame_region(result, report: dict, frame: int, n: int = 120) -> None:
    """Fill ``report['frames'][frame]`` with its region polygon and the objective on a grid.

    ``result`` is a ``retime.physics`` result (``regions`` and ``objective``); the objective's
    magnitude at (p'', p'^2) is Eq. 14's integrand: alpha times the squared distance to the region
    plus the torque term, as McCann et al. show it in Fig. 6.
    """
    from retime.physics.timing.objective import frame_terms

    rec = report["frames"][frame]
    i = rec["source_frame"]
    if i is None:
        raise RetimeError("the report does not name the source frame of each output frame")
    poly = np.asarray(result.regions.polygon(i), dtype=np.float64).reshape(-1, 2)
    rec["region"] = poly
    pts = [(0.0, 1.0)] + ([rec["point"]] if rec["point"] is not None else []) + poly.tolist()
    pts = np.array(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = np.maximum(hi - lo, 0.5)
    lo, hi = lo - 0.35 * span, hi + 0.35 * span
    lo[1] = max(lo[1], -0.05 * span[1])
    U = np.linspace(lo[0], hi[0], n)
    V = np.linspace(lo[1], hi[1], n)
    from retime.physics.timing.objective import ObjectiveWorkspace

    obj = result.objective
    hints = ObjectiveWorkspace.for_objective(obj)
    Z = np.empty((n, n))
    for a, v in enumerate(V):
        for b, u in enumerate(U):
            d, f = frame_terms(obj, i, u, v, hints)
            Z[a, b] = obj.arrays.alpha * d * d + f
    rec["objective"] = {"pdd": U, "pd2": V, "values": Z}
