"""Coarse-to-fine heuristic of guided time warping (Hsu et al. 2007, end of section 3.3).

1. Subsample: every ``factor``-th grid frame and every ``factor``-th output frame (keytimes
   and the ends kept).
2. Solve the subsampled problem exactly. A coarse step of g coarse frames plays the input at
   g times its speed, like a fine step of g grid frames; a coarse frame is scored with the
   full-resolution triple at the same speeds (``F[c j, g1 - 1, g2 - 1]``: the coarse table is
   a subset of the fine table's rows). Subsampling the poses themselves, as the paper does
   (``coarse_scores="subsampled"``), aliases badly on fast periodic motion (a jumping jack
   strobed at 4 Hz looks still) and was found to land 50-200% above the optimum.
3. The coarse path, interpolated to full resolution, sets intermediate keytimes; the
   full-resolution search runs in a corridor of ``radius`` grid frames around it
   (``radius=0``: the paper's hard keytimes at the coarse frames), then again around its own
   result while that improves (``refine`` passes). Only the corridor's scores are needed.

The result is a feasible warp whose objective is an upper bound of the exact optimum (the
exact solver uses it to prune, see :func:`retime.guided.dp.prune_band`).
"""

from __future__ import annotations

import time

import numpy as np

from retime.guided import dp
from retime.guided.features import lowpass
from retime.guided.problem import SolveStats, WarpProblem, band_mask


def _coarse_points(p0, a0, p1, a1, c):
    """Coarse output positions and grid frames of one segment (both ends included)."""
    M, N = p1 - p0, a1 - a0
    q = max(1, int(round(M / c)))
    pos = np.unique(np.round(np.linspace(p0, p1, q + 1)).astype(np.int64))
    g = max(1, int(round(N / c)))
    frm = np.unique(np.round(np.linspace(a0, a1, g + 1)).astype(np.int64))
    return pos, frm


def coarse_grid(problem: WarpProblem, factor: int):
    """(coarse positions -> full positions, coarse frames -> grid frames, coarse fixed frames)."""
    c = int(factor)
    n, m = problem.n, problem.m
    pts = sorted({0: 0, m - 1: n - 1, **problem.fixed}.items())
    cpos, cfrm, cfixed = [0], [0], {}
    for (p0, a0), (p1, a1) in zip(pts, pts[1:]):
        pos, frm = _coarse_points(p0, a0, p1, a1, c)
        cpos.extend(pos[1:].tolist())
        cfrm.extend(frm[1:].tolist())
        if p1 != m - 1:
            cfixed[len(cpos) - 1] = len(cfrm) - 1
    return np.array(cpos), np.array(cfrm), cfixed


def coarse_problem(problem: WarpProblem, factor: int):
    """The paper's subsampled problem: poses low-passed and subsampled (``coarse_scores="subsampled"``)."""
    c = int(factor)
    cpos, cfrm, cfixed = coarse_grid(problem, c)
    xs = lowpass(problem.x, c)[cfrm]
    zs = lowpass(problem.z, c)
    stride = c * problem.ref_stride
    if zs.shape[0] < 2 * stride + 1:  # reference too short for coarse features: fall back to stride 1
        stride = problem.ref_stride
    coarse = WarpProblem(xs, zs, problem.fps / c, len(cpos), cfixed, problem.s, problem.k, problem.weights,
                         problem.knn, problem.eps, stride)
    return coarse, cpos, cfrm


def corridor(problem: WarpProblem, cpos, cfrm, cpath, radius: int) -> dp.Band:
    """Band around the interpolated coarse path (radius in grid frames)."""
    m = problem.m
    centre = np.interp(np.arange(m), cpos, cfrm[cpath].astype(float))
    lower = np.floor(centre).astype(np.int64) - radius
    upper = np.ceil(centre).astype(np.int64) + radius
    if radius == 0:  # the paper's variant: hard keytimes at the coarse frames only
        lower = np.zeros(m, dtype=np.int64)
        upper = np.full(m, problem.n - 1, dtype=np.int64)
        fixed = dict(problem.fixed)
        for p, g in zip(cpos, cfrm[cpath]):
            fixed[int(p)] = int(g)
        return dp.feasible_band(problem.n, m, problem.s, fixed)
    return dp.feasible_band(problem.n, m, problem.s, problem.fixed, lower, upper)


def solve_upper_bound(problem: WarpProblem, F, stats: SolveStats | None = None, radius: int | None = None,
                      refine: int = 6):
    """A near-optimal feasible warp from the full score table, for pruning the exact search.

    A corridor search around the Lagrangian path (the cheapest warp of any length under the step
    price that makes its length closest to m), refined around its own result while that improves;
    the coarse-to-fine heuristic if that corridor cannot hold a warp. The step prices found on the
    way are left in ``stats.extra["lagrange"]`` for :func:`retime.guided.dp.prune_band`.
    """
    stats = stats if stats is not None else SolveStats()
    t0 = time.perf_counter()
    hist = dp.lagrange_multipliers(F, problem.m)
    stats.extra["lagrange"] = hist
    path = dp.lagrange_path(F, problem.m, hist) if hist else None
    stats.optimization_s += time.perf_counter() - t0  # the multipliers and their path; _refine adds its DPs
    radius = 6 * problem.s if radius is None else int(radius)
    sol = None
    if path is not None and len(path) >= 2:
        try:  # a corridor or refinement the warp cannot keep to: the heuristic instead
            band = corridor(problem, np.linspace(0, problem.m - 1, len(path)), path, np.arange(len(path)), radius)
            sol = _refine(problem, lambda band: F, band, radius, refine, stats)
        except dp.InfeasibleWarp:
            sol = None
    if sol is None:
        sol, F, stats = solve_heuristic(problem, F, stats=stats)
    return sol, F, stats


def _refine(problem, scores, band, radius, refine, stats):
    """DP in ``band``, then again in a corridor around each result while it improves.
    ``scores(band)``: the score table, holding at least the band's scores."""
    sol = None
    m = problem.m
    for _ in range(1 + max(0, int(refine))):
        stats.states += band.n_states(problem.s)
        F = scores(band)
        t0 = time.perf_counter()
        new = dp.solve_fixed(F, m, band=band)
        stats.optimization_s += time.perf_counter() - t0
        if sol is not None and new.objective >= sol.objective - 1e-12 * max(1.0, abs(sol.objective)):
            break
        sol = new
        if radius == 0:
            break
        band = corridor(problem, np.arange(m), sol.frames, np.arange(m), radius)
    return sol


def solve_heuristic(problem: WarpProblem, F=None, factor: int | None = None, radius: int | None = None,
                    refine: int = 6, coarse_scores: str = "rows", stats: SolveStats | None = None):
    """Coarse-to-fine warp: (Solution, score table, stats).

    F: full score table if already computed (else only the rows and corridor scores needed
    are computed, the rest of the returned table is inf). factor: subsampling (default 4, less
    for short problems so that the coarse problem keeps some 40 output frames). radius: corridor
    half-width in grid frames (default 6 s). refine: further corridor passes around the previous
    result while it improves.
    """
    stats = stats if stats is not None else SolveStats()
    if problem.m is None:
        raise ValueError("the coarse-to-fine heuristic needs a fixed number of output frames")
    n, m, s = problem.n, problem.m, problem.s
    if factor is None:
        factor = int(min(4, max(2, m // 40)))
    c = int(factor)
    radius = 6 * s if radius is None else int(radius)
    if m < 4 * c or n < 4 * c:  # too small to coarsen: solve exactly
        from retime.guided.problem import solve_exact

        return solve_exact(problem, F, stats=stats)
    scored = np.zeros((n, s), dtype=bool) if F is None else np.ones((n, s), dtype=bool)

    def need(mask):
        """Make sure F holds the scores of the vertices in mask."""
        nonlocal F
        todo = mask & ~scored
        if not todo.any():
            return
        t0 = time.perf_counter()
        G = problem.scores(todo)
        F = G if F is None else np.where(todo[:, :, None], G, F)
        scored[todo] = True
        stats.objective_s += time.perf_counter() - t0

    cpos, cfrm, cfixed = coarse_grid(problem, c)
    try:
        if coarse_scores == "subsampled":
            coarse, cpos, cfrm = coarse_problem(problem, c)
            t0 = time.perf_counter()
            Fc = coarse.scores(band_mask(coarse.band(), coarse.n, coarse.s))
            stats.objective_s += time.perf_counter() - t0
            cm, cfix = coarse.m, coarse.fixed
        elif coarse_scores == "rows":
            rows = np.zeros((n, s), dtype=bool)
            rows[cfrm] = True
            if radius == 0 or radius >= 2 * s:
                # a corridor this wide (or the whole band, radius 0) around a path through every grid
                # frame holds nearly every vertex (99% on CMU clips): scoring them with the rows takes
                # one pass over the grid instead of two, each repeating all the matrix products
                rows |= band_mask(problem.band(), n, s)
            need(rows)
            Fc = np.ascontiguousarray(F[cfrm])
            cm, cfix = len(cpos), cfixed
        else:
            raise ValueError(f"coarse_scores must be 'rows' or 'subsampled', not {coarse_scores!r}")
        t0 = time.perf_counter()
        csol = dp.solve_fixed(Fc, cm, cfix)
        band = corridor(problem, cpos, cfrm, csol.frames, radius)
        stats.optimization_s += time.perf_counter() - t0
    except dp.InfeasibleWarp:
        band = problem.band()  # the coarse grid cannot express this problem: search the whole band
    def scores(band):
        need(band_mask(band, n, s))
        return F

    sol = _refine(problem, scores, band, radius, refine, stats)
    return sol, F, stats
