"""Guided time warping behind the contract of :mod:`retime.method`."""
from __future__ import annotations

import time
from dataclasses import dataclass

from ..method import Report, Request, Result, settings_record, summary
from ..phases import keytime_phases
from .api import guided_solve
from .features import FeatureWeights

NAME = "guided"


@dataclass(frozen=True)
class Settings:
    """Guided's options (see :func:`retime.guided.api.guided_solve` for each)."""

    reference: object = None  # the Motion whose timing to imitate (None: the input itself)
    free: bool = False  # let the search choose the duration (the request gives none)
    max_skip: int = 8
    neighbors: int = 3
    fast: bool = False  # coarse-to-fine heuristic instead of the exact search
    analysis_fps: float = 30.0
    weights: FeatureWeights | None = None
    prefilter: float = 0.1
    upsample: int | None = None
    smoothing: int = 5
    knn: str = "exact"  # or "approx" (KD-tree with relative error eps)
    eps: float = 0.0
    progress: bool = False  # stage messages and the compile notice on stderr
    score: str = "steady"  # or "paper": the paper's mean distances on whole grid frames
    steadiness: float = 3.0  # weight of the steady score's speed-change penalty
    blend: float = 1.0  # the reference's influence: 0 = the keytime spline warp, 1 = the guided warp


def solve(motion, request: Request) -> Result:
    from ..jit import compile_watch, stderr_if

    s = request.settings_or(Settings)
    t0 = time.perf_counter()
    with compile_watch(stderr_if(s.progress)) as jit:
        result = guided_solve(motion, s.reference, duration=request.duration, scale=request.scale, free=s.free,
                              keytimes=request.keytimes, max_skip=s.max_skip, neighbors=s.neighbors, fast=s.fast,
                              analysis_fps=s.analysis_fps, weights=s.weights, prefilter=s.prefilter,
                              upsample=s.upsample, smoothing=s.smoothing, knn=s.knn, eps=s.eps, quiet=not s.progress,
                              score=s.score, steadiness=s.steadiness, blend=s.blend)
    total = time.perf_counter() - t0
    stats = result.stats
    timings = {"scores": stats.objective_s, "search": stats.optimization_s,
               "method": total - jit.seconds, "compile": jit.seconds}
    settings = settings_record(s, leave_out=("reference", "weights"))
    settings["reference"] = "input" if s.reference is None else "given"
    report = Report(summary(NAME, result.curve, motion.fps, keytime_phases(result.curve, request.keytimes), timings,
                            objective=float(result.objective), exact=bool(result.exact), settings=settings))
    info = {"objective": float(result.objective), "exact": bool(result.exact), "n": result.n, "m": result.m,
            "r": result.r, "s": result.s, "k": result.k}
    return Result(result.curve, report, info=info, detail=result)
