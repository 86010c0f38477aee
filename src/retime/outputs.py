"""The files a retiming or a check leaves, written one way for every front end: the single-clip
commands and the batch workers both call these, so a clip retimed in a batch is byte for byte the
command's. Each file is written atomically; inside :func:`retime.io_util.all_or_none` they appear
together or not at all."""
from __future__ import annotations

from pathlib import Path

from .method import Result, module
from .motion import save_motion
from .warp import apply_timing


def write_retiming(name: str, motion, result: Result, output, warp=None, report=None, source=None,
                   retimed=None):
    """Method ``name``'s ``result`` on ``motion``: the retimed motion to ``output`` (``retimed``, or
    ``motion`` played through the curve; ``source``: the input file, whose scene an FBX or glTF output
    keeps), the timing curve to ``warp`` (CSV, one row per output frame) and the method's report to
    ``report`` (its module's ``write_report``; physics: the per-frame report with the regions).
    Returns the retimed motion."""
    retimed = apply_timing(motion, result.curve) if retimed is None else retimed
    save_motion(retimed, output, source=source)
    if warp:
        result.curve.to_csv(warp, retimed.fps)
    if report:
        module(name).write_report(result, report)
    return retimed


def write_check(result, report=None, plot=None, title=""):
    """A :class:`retime.physics.check.ClipCheck`'s report (JSON) and plot (the residual over time)."""
    if report:
        from .physics.report import write_report

        write_report(result.report(), report)
    if plot:
        from .viz.check import plot_check

        plot_check(result, plot, title=Path(title).name)  # the file, not the whole path
