"""The plot of ``retime check``: the residual force a clip's own timing needs, frame by frame, over
its stance/flight strip, with the worst frames marked."""
from __future__ import annotations

import numpy as np

from .plot import _new_figure, _style, save_figure


def plot_check(check, path, title: str = "") -> None:
    """Write :func:`check_figure` to ``path`` (.png, .svg or .pdf)."""
    save_figure(check_figure(check, title), path)


def check_figure(check, title: str = ""):
    """Residual (body weights) over time, the 25% line, flight shaded, the worst frames named with their
    residual; the scale reaches the worst frame (a 99th-percentile scale cut a landing's peak off)."""
    from ..physics.plausibility import OFF_RESIDUAL

    fig = _new_figure(8.0, 3.6)
    ax, strip = fig.subplots(2, 1, sharex=True, height_ratios=[5, 1])
    t, r = check.times, check.residual
    ax.fill_between(t, 0, r, color="#d6604d", alpha=0.35, linewidth=0)
    ax.plot(t, r, color="#b2182b", linewidth=1.2, label="residual force the contacts cannot give")
    ax.axhline(OFF_RESIDUAL, color="#6b7280", linewidth=0.9, linestyle="--", label=f"{OFF_RESIDUAL:.0%} of body weight")
    for i in check.worst_frames(3):
        ax.annotate(f"frame {i}: {r[i]:.2f}", (t[i], r[i]), textcoords="offset points", xytext=(4, 4), fontsize=8,
                    color="#374151")
    ax.set_ylabel("body weights")
    ax.set_ylim(0, max(1.0, float(np.max(r)) * 1.25 if len(r) else 1.0))  # headroom for the worst frame's label
    verdict = "physical as captured" if check.physical else "NOT physical as captured"
    ax.set_title(f"{title + ': ' if title else ''}{verdict}", fontsize=10, loc="left")
    ax.legend(fontsize=8, loc="best", frameon=False)  # clear of the peaks and their labels
    _style(ax)
    state = np.where(check.flight, 1.0, 0.0)[None]
    dt = 1.0 / check.fps
    strip.imshow(state, aspect="auto", cmap="Greys", vmin=0, vmax=1.6, extent=(t[0] - dt / 2, t[-1] + dt / 2, 0, 1))
    strip.set_yticks([0.5], ["flight"])
    strip.set_xlabel("source time (s)")
    strip.tick_params(labelsize=8)
    return fig
