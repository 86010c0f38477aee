"""Plots of timing: warp curves with their playback speed (Hsu et al. 2007, Fig. 5) and physics
feasible regions with the objective (McCann et al. 2006, Fig. 4 and 6).

Figures are built with matplotlib's object API (no pyplot state, no display needed) and written
atomically; the output type follows the file name (.png, .svg, .pdf).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from retime.errors import RetimeError

FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}
SPEED_LIMITS = (0.1, 10.0)

# One colour per method name, the same as in the videos (retime.viz.render.METHOD_COLORS).
_COLORS = {
    "original": "#46566e",
    "linear": "#d6604d",
    "guided": "#4393c3",
    "physics": "#4da36a",
}
_CYCLE = ["#d6604d", "#4393c3", "#4da36a", "#9970ab", "#e0a03c", "#46566e", "#66a61e", "#e7298a"]


def curve_color(label: str, index: int) -> str:
    key = label.lower()
    for name, color in _COLORS.items():
        if name in key:
            return color
    return _CYCLE[index % len(_CYCLE)]


def _style(ax) -> None:
    ax.spines["top"].set_visible(False)
    ax.spines["right"].set_visible(False)
    ax.spines["left"].set_color("#9aa3af")
    ax.spines["bottom"].set_color("#9aa3af")
    ax.tick_params(colors="#374151", labelsize=9)
    ax.grid(True, color="#e5e7eb", linewidth=0.8)
    ax.set_axisbelow(True)


def _new_figure(width: float, height: float, dpi: int = 100):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def check_plot_path(path) -> str:
    """The plot type of ``path`` by its extension, or the one line refusing it (before any work)."""
    ext = Path(path).suffix.lower()
    if ext not in FORMATS:
        raise RetimeError(f"{path}: unsupported plot type {ext or '(none)'}; use .png, .svg or .pdf")
    return ext


def save_figure(fig, path: str | os.PathLike, dpi: int | None = None) -> None:
    """Write ``fig`` atomically; the format comes from the extension."""
    from retime.io_util import atomic_write

    ext = check_plot_path(path)
    with atomic_write(path, "wb") as f:
        fig.savefig(f, format=FORMATS[ext], dpi=dpi or fig.dpi, facecolor="white", metadata=_metadata(ext))


def _metadata(ext: str) -> dict:
    # reproducible files: no creation date in SVG/PDF
    if ext == ".svg":
        return {"Date": None}
    if ext == ".pdf":
        return {"CreationDate": None}
    return {}


def speed_samples(curve, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """(t, ds/dt) for drawing: per segment for piecewise-linear curves, dense for smooth ones."""
    if getattr(curve, "kind", "linear") == "linear" and hasattr(curve, "t"):
        t = np.asarray(curve.t, dtype=np.float64)
        s = np.asarray(curve.s, dtype=np.float64)
        slopes = np.diff(s) / np.diff(t)
        # step function: value on [t_k, t_{k+1}), repeated at the end so the last step is drawn
        return t, np.append(slopes, slopes[-1])
    t = np.linspace(0.0, curve.duration, n)
    return t, np.asarray(curve.speed(t), dtype=np.float64)


def plot_timing(
    curves: Sequence[tuple[str, object]],
    path: str | os.PathLike | None = None,
    title: str | None = None,
    size: tuple[float, float] = (10.0, 4.0),
    dpi: int = 120,
    speed_only: bool = False,
):
    """Timing curves (source time over output time, with the identity) and their playback speed
    on a log scale with the 1x line and the 10x fast-forward / slow-motion limits (Hsu Fig. 5).

    ``curves``: (label, TimingCurve) pairs.  Returns the matplotlib Figure (also saved to ``path``).
    """
    if not curves:
        raise RetimeError("nothing to plot: no timing curve given")
    fig = _new_figure(*size, dpi=dpi)
    if speed_only:
        ax_speed = fig.add_subplot(1, 1, 1)
        ax_warp = None
    else:
        ax_warp, ax_speed = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1, 1.35]})
    t_max = max(float(c.duration) for _, c in curves)
    s_max = max(float(c.source_duration) for _, c in curves)

    if ax_warp is not None:
        _style(ax_warp)
        lim = max(t_max, s_max)
        ax_warp.plot([0, lim], [0, lim], color="#9ca3af", linestyle=(0, (4, 3)), linewidth=1.2, label="identity (1x)")
        for i, (label, curve) in enumerate(curves):
            t = np.linspace(0.0, curve.duration, 1200)
            if getattr(curve, "kind", "linear") == "linear" and hasattr(curve, "t"):
                t = np.asarray(curve.t)
            ax_warp.plot(t, curve(t), color=curve_color(label, i), linewidth=2.0, label=label)
        ax_warp.set_xlim(0, t_max * 1.02)
        ax_warp.set_ylim(0, s_max * 1.02)
        ax_warp.set_xlabel("output time t (s)", fontsize=10)
        ax_warp.set_ylabel("source time s = p(t) (s)", fontsize=10)
        ax_warp.set_title("timing curve", fontsize=11, loc="left", color="#111827")
        ax_warp.legend(frameon=False, fontsize=9, loc="upper left")

    _style(ax_speed)
    lo, hi = SPEED_LIMITS
    ax_speed.set_yscale("log")
    ax_speed.axhspan(hi, hi * 3, color="#f3f4f6", zorder=0)
    ax_speed.axhspan(lo / 3, lo, color="#f3f4f6", zorder=0)
    ax_speed.axhline(1.0, color="#6b7280", linewidth=1.2, zorder=1)
    ax_speed.axhline(hi, color="#9ca3af", linewidth=1.0, linestyle=(0, (2, 2)), zorder=1)
    ax_speed.axhline(lo, color="#9ca3af", linewidth=1.0, linestyle=(0, (2, 2)), zorder=1)
    ax_speed.text(t_max, hi * 1.08, "10x fast-forward", ha="right", va="bottom", fontsize=8, color="#6b7280")
    ax_speed.text(t_max, lo / 1.08, "10x slow motion", ha="right", va="top", fontsize=8, color="#6b7280")
    for i, (label, curve) in enumerate(curves):
        t, v = speed_samples(curve)
        v = np.clip(v, lo / 2.5, hi * 2.5)  # holds (speed 0) drawn at the bottom edge
        step = getattr(curve, "kind", "linear") == "linear"
        ax_speed.plot(t, v, color=curve_color(label, i), linewidth=1.8, label=label,
                      drawstyle="steps-post" if step else "default", zorder=2)
    ax_speed.set_ylim(lo / 2.5, hi * 2.5)
    ax_speed.set_xlim(0, t_max * 1.02)
    ax_speed.set_yticks([0.1, 0.2, 0.5, 1, 2, 5, 10])
    ax_speed.set_yticklabels(["0.1x", "0.2x", "0.5x", "1x", "2x", "5x", "10x"])
    ax_speed.minorticks_off()
    ax_speed.set_xlabel("output time t (s)", fontsize=10)
    ax_speed.set_ylabel("playback speed dp/dt", fontsize=10)
    ax_speed.set_title("playback speed (log scale)", fontsize=11, loc="left", color="#111827")
    if len(curves) > 1 or speed_only:
        ax_speed.legend(frameon=False, fontsize=9, loc="upper left", ncols=min(len(curves), 4))
    if title:
        fig.suptitle(title, fontsize=12, x=0.01, ha="left", color="#111827")
    if path is not None:
        save_figure(fig, path)
    return fig


def label_from_path(path: str | os.PathLike) -> str:
    """Legend label from a file name: 'out/16_06_guided.csv' -> '16_06_guided'."""
    return Path(path).stem
