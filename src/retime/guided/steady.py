"""The steady objective of guided time warping: sub-frame steps, a convex cost of speed changes.

The paper's warp keeps whole grid frames, so between keytimes it can only play at 1x, 2x, 3x ...
of the grid, and its score grows linearly with the speed error: on a steady motion blocks at 1x and
2x cost what a uniform 1.67x would, and the search plays a walk in blocks of speed (a limp).

Here the discrete warp is refined on a finer source grid, in the spirit of GDTW (Deriso & Boyd
2019, time warping with a slope regulariser). Each segment between fixed frames (the ends and
keytimes), ``M`` output steps over ``N`` grid frames, gets ``L`` points per *mean step* ``N / M``
(``L`` from :data:`FINE`, chosen to put the original speed on a whole number of points): the
uniform warp, one step of ``L`` points at every output frame, is exactly representable whatever the
average speed, and a step of ``k`` points plays ``k / L`` times the segment's mean speed. The refined
warp minimises::

    sum_p  c(t_p, v_p)  +  a(t_p, v_p) |v_p - v_{p-1}|  +  lam rho(log v_p - log v_{p-1})

with ``rho(x) = |x| + x^2``, over every step, the first and the last included (the ends are warped
like any other frame). ``c(t, v)`` is the paper's local score of playing around grid time ``t`` at
``v`` grid frames per output frame: the steady triple ``F[j, v-1, v-1]``, linear in ``t`` and ``v``
between whole values; its kink at the original speed keeps a flight at exactly its speed. ``a`` is
the table's own price of a change of speed (:func:`change_costs`): high where the body moves fast,
low where it stands still. ``rho`` is strictly convex, so of two warps with the same scores the
steadier wins (a walk plays uniformly), and it charges a change the same sudden or spread out: a
short excursion (a run's 0.1 s flight) is not worth its two changes, a long one (a jump's flight)
is. ``lam`` is ``steadiness`` times the median score of the segment's frames played uniformly: the
penalty is measured against what the reference objects to in the uniform warp, independent of the
feature scale and of the clip.

The dynamic programme over (fine position, last step) is exact for this objective within its band:
the whole feasible band when it is small, else a corridor around the discrete warp, re-centred on
its own result while that touches the corridor's edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


INF = np.inf
#: fine grid points per mean step of a segment: the count in this range that puts the natural
#: speed nearest a whole number of points (10 makes both 1x and the mean exact at --scale 0.6 and 1.5)
FINE = range(8, 13)
#: at most this many transitions (positions x steps x steps) per output frame in the whole band; above it
#: the refinement searches a corridor
FULL_BAND_STATES = 4_000_000
#: corridor half-width around the discrete warp, in grid frames
CORRIDOR = 24


@dataclass
class SteadyWarp:
    frames: np.ndarray  # (m,) fractional grid frames at the output frames
    objective: float  # the steady objective of that warp
    kept: int = 0  # segments left as the whole-frame warp (no steady warp within the step limits)


def _fill_gaps(D):
    """Each column's inf entries (triples off the clip, or not scored) from the nearest finite row."""
    n = D.shape[0]
    rows = np.arange(n)
    for c in range(D.shape[1]):
        col = D[:, c]
        ok = np.isfinite(col)
        if ok.any() and not ok.all():
            idx = np.flatnonzero(ok)
            at = np.searchsorted(idx, rows)
            after = idx[np.clip(at, 0, len(idx) - 1)]
            before = idx[np.clip(at - 1, 0, len(idx) - 1)]
            D[:, c] = col[np.where(np.abs(before - rows) <= np.abs(after - rows), before, after)]
    return D


def speed_costs(F) -> np.ndarray:
    """(n, s) cost of playing around grid frame j at v grid frames per output frame: F[j, v-1, v-1].

    Where the triple (j - v, j, j + v) leaves the clip or was not scored, the nearest scored frame's
    cost at that speed stands in (the ends play like their neighbours)."""
    v = np.arange(F.shape[1])
    return _fill_gaps(np.ascontiguousarray(F[:, v, v]))


def change_costs(F) -> np.ndarray:
    """(n, s) the table's own cost of a speed change of one grid frame around grid frame j between
    speeds v and v + 1 (column v - 1): the mean of the two unequal triples (j - v, j, j + v + 1),
    (j - v - 1, j, j + v) less the mean of the two steady ones, at least 0 (the last column repeats
    the one before). High where the body moves fast (a flight), low where it stands still."""
    n, s = F.shape[0], F.shape[1]
    S = np.zeros((n, s))
    if s < 2:
        return S
    c = np.arange(s - 1)
    with np.errstate(invalid="ignore"):
        S[:, :-1] = 0.5 * (F[:, c, c + 1] + F[:, c + 1, c]) - 0.5 * (F[:, c, c] + F[:, c + 1, c + 1])
    S[:, :-1][np.isnan(S[:, :-1])] = np.inf
    S[:, -1] = S[:, -2]
    return np.maximum(_fill_gaps(S), 0.0)


def penalty_weight(D, a0: int, a1: int, mean_step: float, steadiness: float) -> float:
    """lam of a segment (grid frames a0..a1): ``steadiness`` times the median of c over its frames
    played at the mean step (their mean if that is 0; 1 if the reference objects to nothing)."""
    uniform = _uniform_costs(D, int(a0), int(a1), float(mean_step))
    uniform = uniform[np.isfinite(uniform)]
    scale = float(np.median(uniform)) if uniform.size else 0.0
    if not scale > 0:
        scale = float(uniform.mean()) if uniform.size else 0.0
    return float(steadiness) * (scale if scale > 0 else 1.0)


@njit(cache=True)
def _bilinear(T, t, v):
    """T (n, s) at grid time t and speed v (column v - 1), linear between whole values, clamped."""
    n, s = T.shape
    t = min(max(t, 0.0), n - 1.0)
    v = min(max(v, 1.0), float(s))
    j0 = min(int(t), n - 2) if n > 1 else 0
    ft = t - j0 if n > 1 else 0.0
    c0 = min(int(v) - 1, s - 2) if s > 1 else 0
    fv = v - 1.0 - c0 if s > 1 else 0.0
    j1 = min(j0 + 1, n - 1)
    c1 = min(c0 + 1, s - 1)
    a = T[j0, c0] * (1.0 - fv) + T[j0, c1] * fv
    b = T[j1, c0] * (1.0 - fv) + T[j1, c1] * fv
    return a * (1.0 - ft) + b * ft


@njit(cache=True)
def _uniform_costs(D, a0, a1, v):
    """c at grid frames a0..a1 played at speed v."""
    out = np.empty(a1 - a0 + 1)
    for j in range(a0, a1 + 1):
        out[j - a0] = _bilinear(D, float(j), v)
    return out


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
def _step_tables(D, S, a0, h, n_fine, kmin, kmax):
    """(n_fine + 1, K) the two scores of a step of kmin + b fine points, by fine position q: ``c``
    of the step that ends at q, and ``a`` (the price of a change) of the step that starts there.
    They depend on the position and the step alone, not on the output frame, so the search reads
    them instead of interpolating them again at every output frame whose band holds q."""
    K = kmax - kmin + 1
    cost_into = np.empty((n_fine + 1, K))
    change_from = np.empty((n_fine + 1, K))
    for q in range(n_fine + 1):
        for b in range(K):
            k = kmin + b
            cost_into[q, b] = _bilinear(D, a0 + (q - 0.5 * k) * h, k * h)
            change_from[q, b] = _bilinear(S, a0 + q * h, k * h)  # the triple's middle frame is q
    return cost_into, change_from


@njit(cache=True)
def _segment_dp(D, cost_into, change_from, a0, h, lo, hi, kmin, kmax, lam):
    """Exact minimiser over the band of the steady objective for one segment.

    Fine position q is grid time a0 + q h; a step of k fine points plays k h grid frames per output
    frame; cost_into, change_from: :func:`_step_tables`. Returns (fine positions (m,), objective)."""
    m = lo.shape[0]
    K = kmax - kmin + 1
    rho = np.empty((K, K))
    dv = np.empty((K, K))
    for a in range(K):
        for b in range(K):
            x = math.log((kmin + b) / (kmin + a))
            rho[a, b] = lam * (abs(x) + x * x)
            dv[a, b] = abs(b - a) * h  # the change in grid frames per output frame
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
            prev[q - lo[1], k - kmin] = _bilinear(D, a0 + 0.5 * (q + lo[0]) * h, k * h)
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
                    sc = change_from[qp, b]
                    for a in range(K):
                        v = row[a] + rho[a, b] + sc * dv[a, b]
                        if v < best:
                            best = v
                            arg = a
                if arg >= 0:
                    best += cost_into[q, b]
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


def _refine_segment(D, S, y, a0, a1, s, steadiness, natural, corridor, max_passes=8):
    """The steady warp of one segment (grid frames a0 -> a1 over len(y) - 1 steps) near path y:
    (fractional grid frames, objective)."""
    M = len(y) - 1
    N = a1 - a0
    fine = points_per_step(N, M, natural)
    h = N / (M * fine)  # grid frames per fine point
    kmin = max(1, math.ceil(1.0 / h - 1e-9))  # at least one grid frame per output frame, as the DP
    kmax = math.floor(s / h + 1e-9)  # at most the skip limit
    if not kmin <= fine <= kmax:  # no fine steps between 1 and s grid frames: the caller keeps y
        return None, math.inf
    lam = penalty_weight(D, a0, a1, N / M, steadiness)
    lb = np.zeros(M + 1, dtype=np.int64)
    ub = np.full(M + 1, M * fine, dtype=np.int64)
    ub[0] = 0
    lb[-1] = M * fine
    lo, hi = _fine_band(lb, ub, kmin, kmax)
    K = kmax - kmin + 1
    cost_into, change_from = _step_tables(D, S, float(a0), h, M * fine, kmin, kmax)
    if int((hi - lo + 1).max()) * K * K <= FULL_BAND_STATES:
        q, obj = _segment_dp(D, cost_into, change_from, float(a0), h, lo, hi, kmin, kmax, float(lam))
        return (a0 + q * h, float(obj)) if np.isfinite(obj) else (None, math.inf)
    centre = (np.asarray(y, dtype=float) - a0) / h
    radius = corridor / h
    for _ in range(max_passes):
        blo, bhi = _fine_band(np.maximum(lo, np.floor(centre - radius).astype(np.int64)),
                              np.minimum(hi, np.ceil(centre + radius).astype(np.int64)), kmin, kmax)
        if np.any(blo > bhi):  # the corridor holds no warp with these steps: the whole band
            blo, bhi = lo, hi
        q, obj = _segment_dp(D, cost_into, change_from, float(a0), h, blo, bhi, kmin, kmax, float(lam))
        touches = np.any(((q == blo) & (blo > lo)) | ((q == bhi) & (bhi < hi)))
        if not touches or not np.isfinite(obj):
            break
        centre = q.astype(float)
    if not np.isfinite(obj):  # no warp with a finite score (a clip too short or too broken for it)
        return None, math.inf
    return a0 + q * h, float(obj)


def steady_warp(F, frames, fixed_positions, steadiness: float, natural=1.0,
                corridor: int = CORRIDOR) -> SteadyWarp:
    """The steady warp near the discrete warp ``frames`` (grid frames at the output frames).

    F: the score table; fixed_positions: output positions that keep their grid
    frame (both ends and the keytimes); natural: grid frames per output frame at the original
    speed (the upsampling), one number or one per output position (a segment takes its first's)."""
    frames = np.asarray(frames, dtype=np.int64)
    m = len(frames)
    D = speed_costs(np.asarray(F))
    S = change_costs(np.asarray(F))
    cuts = sorted({0, m - 1, *[int(p) for p in fixed_positions if 0 <= int(p) < m]})
    natural = np.broadcast_to(np.asarray(natural, dtype=float), (m,))
    out = np.empty(m)
    total, kept = 0.0, 0
    for p0, p1 in zip(cuts, cuts[1:]):
        part, obj = _refine_segment(D, S, frames[p0:p1 + 1], int(frames[p0]), int(frames[p1]), F.shape[1], steadiness,
                                    float(natural[p0]), int(corridor))
        if part is None:  # the whole-frame warp stands for this segment (said by the caller)
            part, obj, kept = frames[p0:p1 + 1].astype(float), 0.0, kept + 1
        out[p0:p1 + 1] = part
        total += obj
    return SteadyWarp(out, total, kept)
