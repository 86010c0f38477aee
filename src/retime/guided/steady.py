"""The steady objective of guided time warping: sub-frame steps, a convex cost of speed changes.

The paper's warp keeps whole grid frames, so between keytimes it can only play at 1x, 2x, 3x ...
of the grid; its score grows linearly with the speed error, so on a steady motion blocks at 1x and
2x cost what a uniform 1.67x would, and the search plays a walk in blocks of speed (a limp).

Here the warp is refined on a finer source grid, in the spirit of GDTW (Deriso & Boyd 2019).
Each segment between fixed frames (the ends and keytimes), ``M`` output steps over ``N`` grid
frames, gets a grid of ``L`` points per *mean step* ``N / M`` (``L`` from :data:`FINE`, chosen so
that the original speed is as near a whole number of points as can be): the uniform warp is one
step of ``L`` points at every output frame, exactly representable whatever the average speed, and
a step of ``k`` points plays ``k / L`` times the segment's mean speed. The refined warp minimises::

    sum_p  c(t_p, v_p)  +  lam * sum_p rho(log v_p - log v_{p-1})

over every step (the first and the last included, so the ends are warped like any other frame):
``c(t, v)`` is the local score of playing around grid time ``t`` at ``v`` grid frames per output
frame, read from the diagonal ``F[j, v-1, v-1]`` of the squared-distance score table (bilinear in
``t`` and ``v``); ``rho(x) = |x| + x^2`` is strictly convex, so of two warps with the same scores
the steadier wins, and a speed change costs the same whether sudden or spread out: a short
excursion (a run's 0.1 s flight) is not worth its two changes, a long one (a jump's flight) is.
``lam`` is ``steadiness`` times the median of ``c`` over every frame and allowed speed.

The dynamic programme over (fine position, last step) is exact for this objective within its band:
the whole feasible band when it is small, else a corridor around the discrete warp, re-centred on
its own result while that touches the corridor's edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from retime.errors import RetimeError

INF = np.inf
#: fine grid points per mean step of a segment: the count in this range that puts the natural
#: speed nearest a whole number of points (10 makes both 1x and the mean exact at --scale 0.6 and 1.5)
FINE = range(8, 13)
#: at most this many (position, step) states per output frame in the full band; above, a corridor
FULL_BAND_STATES = 4_000_000
#: corridor half-width around the discrete warp, in grid frames
CORRIDOR = 24


@dataclass
class SteadyWarp:
    frames: np.ndarray  # (m,) fractional grid frames at the output frames
    objective: float  # the steady objective of that warp


def speed_costs(F) -> np.ndarray:
    """(n, s) cost of playing around grid frame j at v grid frames per output frame: F[j, v-1, v-1].

    Where the triple (j - v, j, j + v) leaves the clip or was not scored, the nearest scored frame's
    cost at that speed stands in (the ends play like their neighbours)."""
    n, s = F.shape[0], F.shape[1]
    v = np.arange(s)
    D = np.ascontiguousarray(F[:, v, v])
    for c in range(s):
        col = D[:, c]
        ok = np.isfinite(col)
        if ok.any() and not ok.all():
            idx = np.flatnonzero(ok)
            near = idx[np.clip(np.searchsorted(idx, np.arange(n)), 0, len(idx) - 1)]
            prev = idx[np.clip(np.searchsorted(idx, np.arange(n)) - 1, 0, len(idx) - 1)]
            pick = np.where(np.abs(prev - np.arange(n)) <= np.abs(near - np.arange(n)), prev, near)
            D[:, c] = col[pick]
    return D


def penalty_weight(D, steadiness: float) -> float:
    """lam: ``steadiness`` times the median cost over every frame and speed (1 if nothing is scored).

    The median over speeds, not the cost at one speed: on an upsampled grid v grid frames are not
    v times the original speed."""
    fin = D[np.isfinite(D)]
    scale = float(np.median(fin)) if fin.size else 1.0
    return float(steadiness) * (scale if scale > 0 else 1.0)


@njit(cache=True)
def _cost(D, t, v):
    """Bilinear interpolation of D at grid time t and speed v (grid frames per output frame)."""
    n, s = D.shape
    t = min(max(t, 0.0), n - 1.0)
    v = min(max(v, 1.0), float(s))
    j0 = min(int(t), n - 2) if n > 1 else 0
    c0 = min(int(v) - 1, s - 2) if s > 1 else 0
    ft = t - j0 if n > 1 else 0.0
    fv = v - 1.0 - c0 if s > 1 else 0.0
    j1 = min(j0 + 1, n - 1)
    c1 = min(c0 + 1, s - 1)
    a = D[j0, c0] * (1.0 - fv) + D[j0, c1] * fv
    b = D[j1, c0] * (1.0 - fv) + D[j1, c1] * fv
    return a * (1.0 - ft) + b * ft


@njit(cache=True)
def _fine_band(lb, ub, kmin, kmax):
    """Positions reachable from the start and able to reach the end with steps of kmin..kmax."""
    m = lb.shape[0]
    lo = lb.copy()
    hi = ub.copy()
    for p in range(1, m):
        lo[p] = max(lo[p], lo[p - 1] + kmin)
        hi[p] = min(hi[p], hi[p - 1] + kmax)
    for p in range(m - 2, -1, -1):
        lo[p] = max(lo[p], lo[p + 1] - kmax)
        hi[p] = min(hi[p], hi[p + 1] - kmin)
    return lo, hi


@njit(cache=True)
def _segment_dp(D, a0, h, lo, hi, kmin, kmax, lam):
    """Exact minimiser over the band of sum c + lam sum rho(change of log speed) for one segment.

    Fine position q is grid time a0 + q h; a step of k fine points plays k h grid frames per output
    frame. Returns (fine positions (m,), objective)."""
    m = lo.shape[0]
    K = kmax - kmin + 1
    rho = np.empty((K, K))
    for a in range(K):
        for b in range(K):
            x = math.log((kmin + b) / (kmin + a))
            rho[a, b] = lam * (abs(x) + x * x)
    offs = np.zeros(m + 1, dtype=np.int64)
    for p in range(m):
        offs[p + 1] = offs[p] + (hi[p] - lo[p] + 1) * K
    bp = np.zeros(offs[m], dtype=np.int16)
    wmax = 1
    for p in range(m):
        wmax = max(wmax, hi[p] - lo[p] + 1)
    prev = np.full((wmax, K), INF)
    cur = np.full((wmax, K), INF)
    # position 1: the first step, from fine position 0, has no predecessor to change from
    for q in range(lo[1], hi[1] + 1):
        k = q - lo[0]
        if kmin <= k <= kmax:
            prev[q - lo[1], k - kmin] = _cost(D, a0 + 0.5 * (q + lo[0]) * h, k * h)
    for p in range(2, m):
        for w in range(hi[p] - lo[p] + 1):
            q = lo[p] + w
            for b in range(K):
                k = kmin + b
                qp = q - k
                best = INF
                arg = -1
                if lo[p - 1] <= qp <= hi[p - 1]:
                    row = prev[qp - lo[p - 1]]
                    for a in range(K):
                        v = row[a] + rho[a, b]
                        if v < best:
                            best = v
                            arg = a
                if arg >= 0:
                    best += _cost(D, a0 + (q - 0.5 * k) * h, k * h)
                cur[w, b] = best
                bp[offs[p] + w * K + b] = arg
        prev, cur = cur, prev
    last = hi[m - 1]
    best = INF
    bb = -1
    for b in range(K):
        if prev[last - lo[m - 1], b] < best:
            best = prev[last - lo[m - 1], b]
            bb = b
    q_out = np.empty(m, dtype=np.int64)
    q_out[m - 1] = last
    q = last
    b = bb
    for p in range(m - 1, 1, -1):
        a = bp[offs[p] + (q - lo[p]) * K + b]
        q = q - (kmin + b)
        q_out[p - 1] = q
        b = a
    q_out[0] = lo[0]
    return q_out, best


def points_per_step(N, M, natural, choices=FINE) -> int:
    """Fine points per mean step (N grid frames / M steps) that put the natural speed (``natural``
    grid frames per output frame) nearest a whole number of points (the smallest of equals)."""
    def miss(L):
        x = natural * M * L / N
        return abs(x - round(x))
    return min(choices, key=lambda L: (round(miss(L), 9), L))


def _refine_segment(D, y, a0, a1, s, lam, natural, corridor):
    """The steady warp of one segment (grid frames a0 -> a1 over len(y) - 1 steps) near path y."""
    M = len(y) - 1
    N = a1 - a0
    fine = points_per_step(N, M, natural)
    h = N / (M * fine)  # grid frames per fine point: FINE points per mean step
    kmin = max(1, math.ceil(1.0 / h - 1e-9))  # at least one grid frame per output frame, as the DP
    kmax = math.floor(s / h + 1e-9)
    if kmin > kmax or kmin > fine or kmax < fine:
        raise RetimeError(f"the steady refinement has no steps between 1 and {s} grid frames here")
    end = M * fine
    full_lb = np.zeros(M + 1, dtype=np.int64)
    full_ub = np.full(M + 1, end, dtype=np.int64)
    full_ub[0] = 0
    full_lb[-1] = end
    lo, hi = _fine_band(full_lb, full_ub, kmin, kmax)
    K = kmax - kmin + 1
    centre = (np.asarray(y, dtype=float) - a0) / h
    use_corridor = int((hi - lo + 1).max()) * K * K > FULL_BAND_STATES
    radius = corridor / h
    while True:
        if use_corridor:
            lb = np.maximum(lo, np.floor(centre - radius).astype(np.int64))
            ub = np.minimum(hi, np.ceil(centre + radius).astype(np.int64))
            blo, bhi = _fine_band(lb, ub, kmin, kmax)
            if np.any(blo > bhi):
                blo, bhi = lo, hi
        else:
            blo, bhi = lo, hi
        q, obj = _segment_dp(D, float(a0), h, blo, bhi, kmin, kmax, float(lam))
        if not np.isfinite(obj):
            raise RetimeError("the steady refinement found no warp with a finite score")
        touches = use_corridor and np.any(((q == blo) & (blo > lo)) | ((q == bhi) & (bhi < hi)))
        if not touches or (blo is lo):
            return a0 + q * h, float(obj)
        centre = q.astype(float)


def steady_warp(F, frames, fixed_positions, steadiness: float, natural=1.0,
                corridor: int = CORRIDOR) -> SteadyWarp:
    """The steady warp near the discrete warp ``frames`` (grid frames at the output frames).

    F: the squared-distance score table; fixed_positions: output positions that keep their grid
    frame (both ends and the keytimes); natural: grid frames per output frame at the original
    speed (the upsampling), one number or one per output position (a segment takes its first's)."""
    frames = np.asarray(frames, dtype=np.int64)
    m = len(frames)
    D = speed_costs(np.asarray(F))
    lam = penalty_weight(D, steadiness)
    cuts = sorted({0, m - 1, *[int(p) for p in fixed_positions if 0 <= int(p) < m]})
    natural = np.broadcast_to(np.asarray(natural, dtype=float), (m,))
    out = np.empty(m)
    total = 0.0
    for p0, p1 in zip(cuts, cuts[1:]):
        part, obj = _refine_segment(D, frames[p0:p1 + 1], int(frames[p0]), int(frames[p1]), F.shape[1], lam,
                                    float(natural[p0]), int(corridor))
        out[p0:p1 + 1] = part
        total += obj
    return SteadyWarp(out, total)
