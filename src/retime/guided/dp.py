"""Exact optimisation of guided time warping (Hsu et al. 2007, section 3.3).

A discrete warp keeps ``m`` of the ``n`` input frames, in order, the first and the last
included, consecutive kept frames at most ``s`` apart. Its cost is the sum of the local scores
``f(y_{p-1}, y_p, y_{p+1})`` of its interior frames, i.e. the weight of a path through the
vertices ``(i, j)`` (consecutive kept frames) with edges ``(i, j) -> (j, k)`` of weight
``f(i, j, k)`` (score table ``F[j, j-i-1, k-j-1]``, see :mod:`retime.guided.score`).

* :func:`solve_fixed`: the shortest path with exactly ``m - 2`` edges (recurrence (3)-(4)),
  optionally through fixed vertices (keytimes: output position ``p`` shows input frame ``a``).
  The dynamic programme runs over the *feasible band* only: at position ``p`` the frame must be
  reachable from the start in ``p`` steps of 1..s and able to reach the end (and every fixed
  frame) in the steps left. Back-pointers (one byte each) are kept for that band only.
* :func:`solve_free`: the unconstrained shortest path (free duration, V8), O(n s^2).
* :func:`brute_force`: enumeration of every warp, for tests.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange

from retime.errors import RetimeError
from retime.guided._jit import compiled
from retime.guided.limits import BACK_POINTER, MAX_SKIP_LIMIT

INF = np.inf


class InfeasibleWarp(RetimeError):
    """No warp satisfies the frame counts, the skip limit and the fixed frames.

    ``segment`` = (p0, a0, p1, a1): between output position p0 (input frame a0) and output
    position p1 (input frame a1) the ``p1 - p0`` steps must cover ``a1 - a0`` frames with gaps
    of 1..s; ``min_steps``/``max_steps`` are the numbers of steps that could.
    """

    def __init__(self, message, segment=None, min_steps=None, max_steps=None):
        super().__init__(message)
        self.segment = segment
        self.min_steps = min_steps
        self.max_steps = max_steps


@dataclass
class Band:
    lo: np.ndarray  # (m,) smallest feasible input frame at each output position
    hi: np.ndarray  # (m,) largest

    @property
    def width(self) -> np.ndarray:
        return self.hi - self.lo + 1

    def n_states(self, s: int) -> int:
        return int(self.width.sum()) * int(s)


def _segment_error(n, m, s, fixed):
    """The first pair of consecutive fixed points that no path with gaps 1..s can join."""
    pts = sorted({0: 0, m - 1: n - 1, **fixed}.items())
    for (p0, a0), (p1, a1) in zip(pts, pts[1:]):
        steps, frames = p1 - p0, a1 - a0
        lo_steps = -(-frames // s) if frames > 0 else None
        if frames < steps or frames > steps * s:
            if frames <= 0:
                msg = (f"output frames {p0} and {p1} are fixed to input frames {a0} and {a1}: "
                       "time cannot stand still or run backwards")
                return InfeasibleWarp(msg, (p0, a0, p1, a1), None, None)
            msg = (f"output frames {p0}..{p1} ({steps} steps) must cover input frames {a0}..{a1} "
                   f"({frames} frames): with gaps of 1..{s} frames that takes {lo_steps} to {frames} steps")
            return InfeasibleWarp(msg, (p0, a0, p1, a1), lo_steps, frames)
    return InfeasibleWarp(f"no warp of {n} frames to {m} frames with skip limit {s} fits the constraints")


def feasible_band(n: int, m: int, s: int, fixed=None, lower=None, upper=None) -> Band:
    """Input frames each output position can show on some feasible warp.

    fixed: {output position: input frame}; lower/upper: optional (m,) bounds per position
    (the coarse-to-fine heuristic's corridor). Raises :class:`InfeasibleWarp`.
    """
    n, m, s = int(n), int(m), int(s)
    fixed = {int(p): int(a) for p, a in (fixed or {}).items()}
    if m < 2 or n < 2:
        raise InfeasibleWarp(f"a warp needs at least 2 input and 2 output frames (got n={n}, m={m})")
    for p, a in fixed.items():
        if not (0 <= p < m) or not (0 <= a < n):
            raise InfeasibleWarp(f"fixed frame (output {p}, input {a}) lies outside 0..{m - 1} x 0..{n - 1}")
    lb = np.zeros(m, dtype=np.int64) if lower is None else np.maximum(np.asarray(lower, dtype=np.int64), 0)
    ub = np.full(m, n - 1, dtype=np.int64) if upper is None else np.minimum(np.asarray(upper, dtype=np.int64), n - 1)
    lb[0] = ub[0] = 0
    lb[m - 1] = ub[m - 1] = n - 1
    for p, a in fixed.items():
        if (p == 0 and a != 0) or (p == m - 1 and a != n - 1):
            raise InfeasibleWarp("the first and last output frames show the first and last input frames")
        lb[p] = max(lb[p], a)
        ub[p] = min(ub[p], a)
    lo, hi = _band_kernel(lb, ub, s)
    if np.any(lo > hi):
        raise _segment_error(n, m, s, fixed)
    return Band(lo, hi)


@njit(cache=True)
def _band_kernel(lb, ub, s):
    m = lb.shape[0]
    lo = np.empty(m, dtype=np.int64)
    hi = np.empty(m, dtype=np.int64)
    lo[0] = lb[0]
    hi[0] = ub[0]
    for p in range(1, m):
        lo[p] = max(lo[p - 1] + 1, lb[p])
        hi[p] = min(hi[p - 1] + s, ub[p])
    for p in range(m - 2, -1, -1):
        lo[p] = max(lo[p], lo[p + 1] - s)
        hi[p] = min(hi[p], hi[p + 1] - 1)
    return lo, hi


# ----------------------------------------------------------------------------------------------
# fixed number of output frames


@njit(cache=True, fastmath={"nsz", "contract"})
def _dp_rows(F, prev, cur, bp, bpo, lo_a, hi_a, lo_b, j0, j1, s, g):
    """One step for the middle frames j in [j0, j1) (rows j - lo_b of cur).

    prev[i - lo_a, d-1]: best cost of vertex (i, i+d) with i at position p-1 (i in [lo_a, hi_a]);
    cur[j - lo_b, e-1] = min_d prev[j-d - lo_a, d-1] + F[j, d-1, e-1]  (vertex (j, j+e));
    bp holds the minimising d. Eight e at a time, branch-free, for the SLP vectoriser.
    """
    S8 = F.shape[2]
    for j in range(j0, j1):
        jj = j - lo_b
        for d in range(1, s + 1):
            i = j - d
            g[d - 1] = prev[i - lo_a, d - 1] if (i >= lo_a and i <= hi_a) else INF
        crow = cur[jj]
        brow = bp[bpo + jj * S8: bpo + jj * S8 + S8]
        for e0 in range(0, S8, 8):
                b0 = INF
                a0 = 0.0
                b1 = INF
                a1 = 0.0
                b2 = INF
                a2 = 0.0
                b3 = INF
                a3 = 0.0
                b4 = INF
                a4 = 0.0
                b5 = INF
                a5 = 0.0
                b6 = INF
                a6 = 0.0
                b7 = INF
                a7 = 0.0
                for d in range(s):
                    gd = g[d]
                    dd = d + 1.0
                    fr = F[j, d, e0:e0 + 8]
                    v0 = gd + fr[0]
                    c0 = v0 < b0
                    b0 = v0 if c0 else b0
                    a0 = dd if c0 else a0
                    v1 = gd + fr[1]
                    c1 = v1 < b1
                    b1 = v1 if c1 else b1
                    a1 = dd if c1 else a1
                    v2 = gd + fr[2]
                    c2 = v2 < b2
                    b2 = v2 if c2 else b2
                    a2 = dd if c2 else a2
                    v3 = gd + fr[3]
                    c3 = v3 < b3
                    b3 = v3 if c3 else b3
                    a3 = dd if c3 else a3
                    v4 = gd + fr[4]
                    c4 = v4 < b4
                    b4 = v4 if c4 else b4
                    a4 = dd if c4 else a4
                    v5 = gd + fr[5]
                    c5 = v5 < b5
                    b5 = v5 if c5 else b5
                    a5 = dd if c5 else a5
                    v6 = gd + fr[6]
                    c6 = v6 < b6
                    b6 = v6 if c6 else b6
                    a6 = dd if c6 else a6
                    v7 = gd + fr[7]
                    c7 = v7 < b7
                    b7 = v7 if c7 else b7
                    a7 = dd if c7 else a7
                crow[e0 + 0] = b0
                brow[e0 + 0] = np.uint8(a0)
                crow[e0 + 1] = b1
                brow[e0 + 1] = np.uint8(a1)
                crow[e0 + 2] = b2
                brow[e0 + 2] = np.uint8(a2)
                crow[e0 + 3] = b3
                brow[e0 + 3] = np.uint8(a3)
                crow[e0 + 4] = b4
                brow[e0 + 4] = np.uint8(a4)
                crow[e0 + 5] = b5
                brow[e0 + 5] = np.uint8(a5)
                crow[e0 + 6] = b6
                brow[e0 + 6] = np.uint8(a6)
                crow[e0 + 7] = b7
                brow[e0 + 7] = np.uint8(a7)


def _make_dp(parallel):
    rng = prange if parallel else range

    def dp(F, lo, hi, s, bp, offs, nchunks):
        m = lo.shape[0]
        S8 = F.shape[2]
        wmax = 1
        for p in range(m):
            wmax = max(wmax, hi[p] - lo[p] + 1)
        prev = np.full((wmax, S8), INF)
        cur = np.full((wmax, S8), INF)
        gbuf = np.empty((nchunks, s))
        # S_1: vertices (lo[0], lo[0] + d) at positions (0, 1), cost 0
        for d in range(1, s + 1):
            if lo[1] <= lo[0] + d <= hi[1]:
                prev[0, d - 1] = 0.0
        for p in range(1, m - 1):
            j0 = lo[p]
            w = hi[p] + 1 - j0
            nc = min(nchunks, w)
            for c in rng(nc):
                a = j0 + (w * c) // nc
                b = j0 + (w * (c + 1)) // nc
                _dp_rows(F, prev, cur, bp, offs[p + 1], lo[p - 1], hi[p - 1], j0, a, b, s, gbuf[c])
            prev, cur = cur, prev
        # S_{m-1}: vertices (j, n-1), j in band m-2; return (best cost, j)
        nlast = hi[m - 1]
        best = INF
        jbest = -1
        for j in range(lo[m - 2], hi[m - 2] + 1):
            e = nlast - j
            if 1 <= e <= s:
                v = prev[j - lo[m - 2], e - 1]
                if v < best:
                    best = v
                    jbest = j
        res = np.empty(2)
        res[0] = best
        res[1] = jbest
        return res

    return dp


_dp_serial = njit(cache=True)(_make_dp(False))
_dp_parallel = njit(cache=True, parallel=True)(_make_dp(True))


@njit(cache=True)
def _backtrack(lo, S8, bp, offs, j_last, n_last):
    m = lo.shape[0]
    frames = np.empty(m, dtype=np.int64)
    frames[m - 1] = n_last
    j = j_last
    e = n_last - j_last
    q = m - 1
    frames[q - 1] = j
    while q > 1:
        d = np.int64(bp[offs[q] + (j - lo[q - 1]) * S8 + e - 1])
        e = d
        j = j - d
        q -= 1
        frames[q - 1] = j
    return frames


@dataclass
class Solution:
    frames: np.ndarray  # (m,) input frame shown at each output frame
    objective: float  # sum of local scores along the warp
    n_states: int = 0  # vertex-position pairs the search visited


def _check_table(F, n, s):
    if F.ndim != 3 or F.shape[:2] != (n, s) or F.shape[2] % 8 or F.shape[2] < s:
        raise ValueError(f"score table shape {F.shape} is not (n, s, 8 * ceil(s / 8))")
    if s > MAX_SKIP_LIMIT:
        raise RetimeError(f"the skip limit must be at most {MAX_SKIP_LIMIT} (got {s}): back-pointers are uint8")


def solve_fixed(F, m, fixed=None, band=None, parallel=None) -> Solution:
    """Exact minimum-cost warp with exactly m output frames (and the fixed frames).

    F: score table (n, s, 8 ceil(s/8)); fixed: {output position: input frame}; band: a precomputed
    :class:`Band` (e.g. a corridor), else the full feasible band.
    """
    F = np.ascontiguousarray(F, dtype=np.float64)
    n, s = F.shape[0], F.shape[1]
    _check_table(F, n, s)
    m = int(m)
    if band is None:
        band = feasible_band(n, m, s, fixed)
    lo, hi = band.lo, band.hi
    if m == 2:
        return Solution(np.array([0, n - 1]), 0.0, 1)
    widths = hi - lo + 1
    S8 = F.shape[2]
    # back-pointers of S_{p+1} (vertices (j, j+e), j at position p) at offs[p+1]
    offs = np.zeros(m + 1, dtype=np.int64)
    offs[2:] = np.cumsum(widths[:-1] * S8)
    bp = np.zeros(int(offs[-1]), dtype=BACK_POINTER)
    if parallel is None:
        # one barrier per output frame: on a busy 2-core machine a descheduled thread stalls every
        # step, so the search runs on one thread unless asked otherwise
        parallel = False
    if parallel:
        fn = compiled(_dp_parallel, _DP_SIG)
        nchunks = 4 * numba.get_num_threads()
    else:
        fn = compiled(_dp_serial, _DP_SIG)
        nchunks = 1
    res = fn(F, lo, hi, s, bp, offs, nchunks)
    cost = float(res[0])
    if not np.isfinite(cost):
        raise RetimeError("no warp with a finite score exists within the constraints (score table has gaps)")
    frames = _backtrack(lo, S8, bp, offs, int(res[1]), int(hi[m - 1]))
    return Solution(frames, cost, int(widths.sum()) * s)


_DP_SIG = numba.float64[::1](
    numba.float64[:, :, ::1], numba.int64[::1], numba.int64[::1], numba.int64, numba.uint8[::1],
    numba.int64[::1], numba.int64)


# ----------------------------------------------------------------------------------------------
# free number of output frames


@njit(cache=True)
def _dp_free(F, s):
    n = F.shape[0]
    g = np.full((n, s), INF)
    bp = np.zeros((n, s), dtype=BACK_POINTER)
    for k in range(1, n):
        for e in range(1, s + 1):
            j = k - e
            if j < 0:
                break
            if j == 0:
                g[k, e - 1] = 0.0
                continue
            best = INF
            arg = 0
            for d in range(1, s + 1):
                if j - d < 0:
                    break
                v = g[j, d - 1] + F[j, d - 1, e - 1]
                if v < best:
                    best = v
                    arg = d
            g[k, e - 1] = best
            bp[k, e - 1] = arg
    return g, bp


def solve_free(F) -> Solution:
    """Minimum-cost warp of any length (first and last frames kept, gaps 1..s)."""
    F = np.ascontiguousarray(F, dtype=np.float64)
    n, s = F.shape[0], F.shape[1]
    _check_table(F, n, s)
    if n < 2:
        raise InfeasibleWarp("a warp needs at least 2 input frames")
    g, bp = _dp_free(F, s)
    e = int(np.argmin(g[n - 1]))
    cost = float(g[n - 1, e])
    if not np.isfinite(cost):
        raise RetimeError(f"no path from frame 0 to frame {n - 1} with gaps of at most {s}")
    frames = [n - 1]
    k, e = n - 1, e + 1
    while k - e > 0:
        j = k - e
        frames.append(j)
        k, e = j, int(bp[k, e - 1])
    frames.append(0)
    return Solution(np.array(frames[::-1], dtype=np.int64), cost, n * s)


# ----------------------------------------------------------------------------------------------
# checks


def path_cost(F, frames) -> float:
    """Objective of a warp given by its frames (sum of F over interior frames)."""
    f = np.asarray(frames)
    i, j, k = f[:-2], f[1:-1], f[2:]
    return float(F[j, j - i - 1, k - j - 1].sum())


def brute_force(F, m=None, fixed=None):
    """(best cost, best frames) over every warp (all m if m is None). Small n only."""
    n, s = F.shape[0], F.shape[1]
    fixed = fixed or {}
    best, arg = INF, None
    sizes = range(2, n + 1) if m is None else [m]
    for mm in sizes:
        for mid in itertools.combinations(range(1, n - 1), mm - 2):
            frames = (0, *mid, n - 1)
            if any(b - a > s for a, b in zip(frames, frames[1:])):
                continue
            if any(frames[p] != a for p, a in fixed.items() if p < mm):
                continue
            c = path_cost(F, frames)
            if c < best:
                best, arg = c, np.array(frames)
    return best, arg


# ----------------------------------------------------------------------------------------------
# Lagrangian bounds: prune the band without losing the optimum


@njit(cache=True)
def _lagrange_forward(F, s, lam):
    """Fw[j, d-1] = min over paths from frame 0 to vertex (j-d, j) of cost + lam * steps.

    Also returns the steps of a minimising path to each vertex."""
    n = F.shape[0]
    Fw = np.full((n, s), INF)
    steps = np.zeros((n, s), dtype=np.int64)
    for j in range(1, min(s, n - 1) + 1):
        Fw[j, j - 1] = lam
        steps[j, j - 1] = 1
    for j in range(1, n - 1):
        for e in range(1, s + 1):
            k = j + e
            if k >= n:
                break
            best = INF
            bs = 0
            for d in range(1, s + 1):
                if j - d < 0:
                    break
                v = Fw[j, d - 1] + F[j, d - 1, e - 1]
                if v < best:
                    best = v
                    bs = steps[j, d - 1]
            v = best + lam
            if v < Fw[k, e - 1]:
                Fw[k, e - 1] = v
                steps[k, e - 1] = bs + 1
    return Fw, steps


@njit(cache=True)
def _lagrange_backward(F, s, lam):
    """Bw[j, d-1] = min over paths from vertex (j-d, j) to the last frame of cost + lam * steps."""
    n = F.shape[0]
    Bw = np.full((n, s), INF)
    for d in range(1, s + 1):
        Bw[n - 1, d - 1] = 0.0
    for j in range(n - 2, 0, -1):
        for d in range(1, s + 1):
            if j - d < 0:
                break
            best = INF
            for e in range(1, s + 1):
                k = j + e
                if k >= n:
                    break
                v = F[j, d - 1, e - 1] + Bw[k, e - 1]
                if v < best:
                    best = v
            Bw[j, d - 1] = best + lam
    return Bw


@njit(cache=True)
def _lagrange_path(F, s, lam):
    """Frames of a minimiser of cost + lam * steps from frame 0 to the last frame."""
    n = F.shape[0]
    Fw = np.full((n, s), INF)
    arg = np.zeros((n, s), dtype=np.int64)
    for j in range(1, min(s, n - 1) + 1):
        Fw[j, j - 1] = lam
    for j in range(1, n - 1):
        for e in range(1, s + 1):
            k = j + e
            if k >= n:
                break
            best = INF
            bd = 0
            for d in range(1, s + 1):
                if j - d < 0:
                    break
                v = Fw[j, d - 1] + F[j, d - 1, e - 1]
                if v < best:
                    best = v
                    bd = d
            v = best + lam
            if v < Fw[k, e - 1]:
                Fw[k, e - 1] = v
                arg[k, e - 1] = bd
    e = 1
    for q in range(2, s + 1):
        if Fw[n - 1, q - 1] < Fw[n - 1, e - 1]:
            e = q
    out = [n - 1]
    k = n - 1
    while k - e > 0:
        j = k - e
        out.append(j)
        d = arg[k, e - 1]
        k = j
        e = d
    out.append(0)
    res = np.empty(len(out), dtype=np.int64)
    for q in range(len(out)):
        res[q] = out[len(out) - 1 - q]
    return res


def lagrange_path(F, m, hist=None):
    """The warp minimising cost + lam * steps whose length is closest to m (any length).

    hist: the result of :func:`lagrange_multipliers` if already computed."""
    F = np.ascontiguousarray(F, dtype=np.float64)
    hist = lagrange_multipliers(F, m) if hist is None else hist
    best = None
    for _, lam in hist[:8]:
        path = _lagrange_path(F, F.shape[1], lam)
        if best is None or abs(len(path) - m) < abs(len(best) - m):
            best = path
    return best


def lagrange_multipliers(F, m, iters=48):
    """Step prices lam with their dual values min_path(cost + lam steps) - lam (m - 1) <= optimum.

    Bisection on the subgradient (steps of the lam-optimal path - (m - 1)). Returns a list of
    (dual value, lam) pairs, best first.
    """
    F = np.ascontiguousarray(F, dtype=np.float64)
    n, s = F.shape[0], F.shape[1]
    finite = F[np.isfinite(F)]
    top = float(finite.max()) if finite.size else 1.0
    lo, hi = -2.0 * top - 1.0, 2.0 * top + 1.0
    hist = []
    for _ in range(iters):
        lam = 0.5 * (lo + hi)
        Fw, steps = _lagrange_forward(F, s, lam)
        e = int(np.argmin(Fw[n - 1]))
        total = float(Fw[n - 1, e])
        if not np.isfinite(total):
            break
        hist.append((total - lam * (m - 1), lam))
        st = int(steps[n - 1, e])
        if st > m - 1:
            lo = lam  # too many steps: make steps dearer
        elif st < m - 1:
            hi = lam
        else:
            break
    hist.sort(reverse=True)
    return hist


@njit(cache=True)
def _vertex_ranges(Fws, Bws, lams, lo, hi, m, ub):
    """Per frame j, the hull [PA, PB] of positions where a vertex (j-d, j) survives the bounds."""
    n, s = Fws.shape[1], Fws.shape[2]
    L = lams.shape[0]
    PA = np.full(n, m, dtype=np.int64)
    PB = np.full(n, -1, dtype=np.int64)
    # positions where frame f is inside the band: [first p with hi_p >= f, last p with lo_p <= f]
    first = np.searchsorted(hi, np.arange(n), side="left")
    last = np.searchsorted(lo, np.arange(n), side="right") - 1
    for j in range(1, n):
        for d in range(1, s + 1):
            i = j - d
            if i < 0:
                break
            pa = max(first[j], first[i] + 1)
            pb = min(last[j], last[i] + 1)
            if pa > pb:
                continue
            ok = True
            for a in range(L):
                fa = Fws[a, j, d - 1]
                if not np.isfinite(fa):
                    ok = False
                    break
                for b in range(L):
                    C = fa + Bws[b, j, d - 1] - lams[b] * (m - 1) - ub
                    slope = lams[b] - lams[a]
                    if slope > 0:
                        lim = np.floor(-C / slope)
                        if lim < pb:
                            pb = np.int64(max(lim, -1.0))
                    elif slope < 0:
                        lim = np.ceil(C / (-slope))
                        if lim > pa:
                            pa = np.int64(min(lim, m * 1.0))
                    elif C > 0:
                        ok = False
                if not ok or pa > pb:
                    ok = False
                    break
            if ok:
                PA[j] = min(PA[j], pa)
                PB[j] = max(PB[j], pb)
    return PA, PB


@njit(cache=True)
def _paint(PA, PB, m, ascending):
    """For each position, the first frame (in the given order) whose [PA, PB] covers it (-1: none)."""
    n = PA.shape[0]
    out = np.full(m, -1, dtype=np.int64)
    nxt = np.arange(m + 1)
    for t in range(n):
        j = t if ascending else n - 1 - t
        a, b = PA[j], PB[j]
        if a > b:
            continue
        # find the first unpainted position >= a (path halving)
        p = a
        while nxt[p] != p:
            nxt[p] = nxt[nxt[p]]
            p = nxt[p]
        while p <= b:
            out[p] = j
            nxt[p] = p + 1
            q = p + 1
            while nxt[q] != q:
                nxt[q] = nxt[nxt[q]]
                q = nxt[q]
            p = q
    return out


PRICE_SPREAD = (-3.0, -1.0, -0.3, -0.1, -0.03, -0.01, 0.0, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0)


def prune_band(F, m, band: Band, upper_bound: float, spread=PRICE_SPREAD, hist=None) -> Band:
    """The band cut down to positions/frames that can still lie on a warp costing <= upper_bound.

    For a vertex (i, j) with j at output position p and step prices a, b:
    cost(prefix) >= Fw_a(i, j) - a p and cost(suffix) >= Bw_b(i, j) - b (m-1-p), where Fw/Bw are
    the cheapest paths from the start / to the end with a price per step (Lagrangian
    relaxation of the frame count). Pairs (vertex, p) whose bound exceeds the upper bound cannot
    be on an optimal warp; the optimum lies in the band of those left, so the DP over it is
    still exact.
    """
    F = np.ascontiguousarray(F, dtype=np.float64)
    s = F.shape[1]
    hist = lagrange_multipliers(F, m) if hist is None else hist
    if not hist:
        return band
    lam0 = hist[0][1]
    finite = F[:, :, :s][np.isfinite(F[:, :, :s])]
    scale = float(np.median(finite)) if finite.size else 1.0
    # a spread of step prices: the bound for a vertex at an unlikely position needs steep ones
    lams = np.array(sorted({lam0 + scale * f for f in spread}))
    Fws = np.stack([_lagrange_forward(F, s, lam)[0] for lam in lams])
    Bws = np.stack([_lagrange_backward(F, s, lam) for lam in lams])
    ub = float(upper_bound) * (1 + 1e-9) + 1e-9
    PA, PB = _vertex_ranges(Fws, Bws, lams, band.lo, band.hi, m, ub)
    lo_p = _paint(PA, PB, m, True)
    hi_p = _paint(PA, PB, m, False)
    if np.any(lo_p[1:] < 0):
        return band  # the bound is not an upper bound of this problem: keep the full band
    lo = np.maximum(band.lo, lo_p)
    hi = np.minimum(band.hi, hi_p)
    lo[0] = hi[0] = band.lo[0]
    lo2, hi2 = _band_kernel(lo, hi, s)
    if np.any(lo2 > hi2):
        return band
    return Band(lo2, hi2)
