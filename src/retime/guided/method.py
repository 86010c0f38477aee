"""Guided time warping behind the contract of :mod:`retime.method`.

:class:`Settings` is where guided's options and their defaults are written, once: the command line's
options and help, the editor's controls, batch's ``blend`` column and the Blender panel read them from
here, and :func:`retime.guided.guided_warp` / :func:`retime.guided.guided_solve` take the same names
as keywords."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

from ..errors import RetimeError
from ..method import Report, Request, Result, settings_record, summary
from ..phases import keytime_phases
from .limits import MAX_SKIP_LIMIT
from .features import FeatureWeights

NAME = "guided"
#: local scores: "steady" (sub-frame steps, a convex penalty on speed changes) and "paper" (Hsu et al. eq. 2)
SCORES = ("steady", "paper")
KNN = ("exact", "approx")


@dataclass(frozen=True)
class Settings:
    """Guided's options (checked when made: every front end gets the same one-line errors)."""

    reference: object = None  # the Motion whose timing to imitate (None: the input itself)
    free: bool = False  # let the search choose the duration (the request gives none)
    max_skip: int = 8  # skip limit s: an output frame advances at most s grid frames (up to MAX_SKIP_LIMIT)
    neighbors: int = 3  # k of the k-nearest-neighbour local score
    fast: bool = False  # coarse-to-fine heuristic instead of the exact search
    analysis_fps: float = 30.0  # rate of the search (Hz; the paper's)
    weights: FeatureWeights | None = None  # pose, velocity, acceleration, root height (None: FeatureWeights())
    prefilter: float = 0.1  # width of the box low-pass on joint positions (s)
    upsample: int | None = None  # grid frames per analysis frame (None: automatic)
    smoothing: int = 5  # moving-average window of the warp in analysis frames (1 = none)
    knn: str = "exact"  # or "approx" (KD-tree with relative error eps)
    eps: float = 0.0
    progress: bool = False  # stage messages and the compile notice on stderr
    score: str = "steady"  # or "paper": the paper's mean distances on whole grid frames
    steadiness: float = 3.0  # weight of the steady score's speed-change penalty
    pace: float = 10.0  # steady score: pull to one steady speed (a jump's flight: its natural one), x the change penalty's weight; 0 = off
    blend: float = 1.0  # the reference's influence: 0 = the keytime spline warp, 1 = the guided warp

    def __post_init__(self):
        if self.score not in SCORES:
            raise RetimeError(f"unknown score {self.score!r}: use one of {', '.join(SCORES)}")
        if self.knn not in KNN:
            raise RetimeError(f"unknown nearest-neighbour search {self.knn!r}: use one of {', '.join(KNN)}")
        if not 0.0 <= float(self.blend) <= 1.0:
            raise RetimeError(f"--blend must be between 0 and 1, got {self.blend:g}")
        if not (float(self.steadiness) >= 0 and math.isfinite(self.steadiness)):
            raise RetimeError(f"the steadiness must be a finite number >= 0, got {self.steadiness:g}")
        if not (float(self.pace) >= 0 and math.isfinite(self.pace)):
            raise RetimeError(f"the pace weight must be a finite number >= 0, got {self.pace:g}")
        if not 1 <= int(self.max_skip) <= MAX_SKIP_LIMIT:
            raise RetimeError(f"--max-skip must be between 1 and {MAX_SKIP_LIMIT}, got {self.max_skip}")
        if int(self.neighbors) < 1:
            raise RetimeError(f"--neighbors must be at least 1, got {self.neighbors}")
        if not float(self.analysis_fps) > 0:
            raise RetimeError(f"the analysis rate must be positive, got {self.analysis_fps}")


def solve(motion, request: Request) -> Result:
    from ..jit import compile_watch, stderr_if
    from .api import guided_result

    s = request.settings_or(Settings)
    t0 = time.perf_counter()
    with compile_watch(stderr_if(s.progress)) as jit:
        result = guided_result(motion, s, request)
    total = time.perf_counter() - t0
    stats = result.stats
    timings = {"scores": stats.objective_s, "search": stats.optimization_s,
               "method": total - jit.seconds, "compile": jit.seconds}
    settings = settings_record(s, leave_out=("reference", "weights"))
    settings["reference"] = "input" if s.reference is None else "given"
    report = Report(summary(NAME, result.curve, motion.fps, keytime_phases(result.curve, request.keytimes), timings,
                            warnings=result.warnings, objective=float(result.objective), exact=bool(result.exact), settings=settings))
    info = {"objective": float(result.objective), "exact": bool(result.exact), "n": result.n, "m": result.m,
            "r": result.r, "s": result.s, "k": result.k}
    return Result(result.curve, report, info=info, detail=result)
