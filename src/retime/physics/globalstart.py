"""A globally optimal start for the timing spline: dynamic programming over (source frame, speed).

McCann et al. optimize the spline locally from the uniform timing and note (sec. 5, Fig. 13) that
nearby minima can trap it. When a clip must be shortened more than physics allows anywhere, the
local optimizer also spreads the unavoidable violation over long stretches (every frame a little
outside its region) instead of spending it where it shows least. Along the path the timing is only
a speed profile v(s) = p'^2 over source time with dv/ds = 2 p'' (the robotics view of Bobrow, TOPP),
so the baked objective of :mod:`.objective` can be minimized *globally* on a grid:

* nodes: every ``stride``-th source frame times ``levels`` playback speeds, geometric between
  ``w_lo`` and ``w_hi`` (1 is on the grid);
* an edge from speed w_j at frame a to w_l at frame b has constant p'' = (v_l - v_j) / (2 (s_b - s_a))
  and v linear in s, its cost the objective's integrand ``f / p' + gamma (p' + 1/p' - 2)`` summed
  over the frames it spans, plus ``kappa`` per output second spent outside a region (an L0-like
  price: a violation that cannot be avoided is put on as few output frames as possible, which is
  what a viewer, and the report's ``feasible_fraction``, count);
* the duration: a price ``mu`` per output second, found by bisection so the path lasts ``T``
  (``mu = 0`` for a free duration).

The edge costs are computed once (compiled, in parallel over edges); each bisection step is one
O(E J^2) pass. The best path's speed profile is then fitted by the spline and refined by the local
optimizer (:mod:`.optimize`) on the exact objective.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .objective import BakedObjective, _frame_eval

_BIG = 1e300


@dataclass
class GlobalStart:
    """The grid optimum: speed profile over source frames and what it cost."""

    times: np.ndarray  # (m,) source times of the nodes
    speed: np.ndarray  # (m,) playback speed p' at the nodes
    duration: float  # output seconds of the path
    mu: float  # price of an output second that gave this duration
    seconds: float

    def output_times(self) -> np.ndarray:
        """Output time of every node (v linear in s between nodes)."""
        ds = np.diff(self.times)
        w0, w1 = self.speed[:-1], self.speed[1:]
        return np.r_[0.0, np.cumsum(2.0 * ds / (w0 + w1))]

    def speed_at_output(self, t) -> np.ndarray:
        return np.interp(t, self.output_times(), self.speed)


def speed_levels(w_lo=0.05, w_hi=8.0, levels=96) -> np.ndarray:
    """Geometric speeds from w_lo to w_hi with 1 exactly on the grid."""
    lo, hi = math.log(w_lo), math.log(w_hi)
    step = (hi - lo) / (levels - 1)
    k0 = round(-lo / step)
    return np.exp((np.arange(levels) - k0) * step)


@njit(cache=True, parallel=True, fastmath=True, error_model="numpy")
def _edge_costs(nodes, times, w, poff, px, py, cen, scale, mode, wc, alpha, delta, gamma, kappa, d_tol, u_max,
                cost, dur):
    """cost[e, j, l], dur[e, j, l] of the edge from (nodes[e], w[j]) to (nodes[e + 1], w[l])."""
    E = len(nodes) - 1
    J = len(w)
    for e in prange(E):
        cache = np.zeros(len(poff) - 1, dtype=np.int64)
        ia, ib = nodes[e], nodes[e + 1]
        sa, L = times[ia], times[ib] - times[ia]
        for j in range(J):
            vj = w[j] * w[j]
            for l in range(J):
                vl = w[l] * w[l]
                u = (vl - vj) / (2.0 * L)
                if abs(u) > u_max:
                    cost[e, j, l] = _BIG
                    dur[e, j, l] = 0.0
                    continue
                c = 0.0
                for m in range(ia, ib):
                    ds = times[m + 1] - times[m]
                    v = vj + (vl - vj) * (times[m] - sa) / L
                    pd = math.sqrt(v)
                    f, _, _ = _frame_eval(m, u, v, poff, px, py, cen, scale, mode, wc, cache, alpha, delta)
                    g, _, _ = _frame_eval(m, u, v, poff, px, py, cen, scale, mode, wc, cache, 0.0, 0.0)
                    pen = f - g  # alpha (sqrt(d^2 + delta^2) - delta)
                    h = f / pd + gamma * (pd + 1.0 / pd - 2.0)
                    if alpha > 0.0 and pen > alpha * d_tol:
                        h += kappa / pd
                    c += ds * h
                cost[e, j, l] = c
                dur[e, j, l] = 2.0 * L / (w[j] + w[l])  # exact for v linear in s
    return cost, dur


@njit(cache=True, fastmath=True)
def _shortest(cost, dur, mu, start_level):
    """Least sum of cost + mu * dur over paths through the grid; returns (levels per node, duration)."""
    E, J, _ = cost.shape
    V = np.zeros(J)
    if start_level >= 0:
        for j in range(J):
            V[j] = 0.0 if j == start_level else _BIG
    back = np.zeros((E, J), dtype=np.int64)
    Vn = np.empty(J)
    for e in range(E):
        for l in range(J):
            best = _BIG
            arg = 0
            for j in range(J):
                if V[j] >= _BIG:
                    continue
                c = cost[e, j, l]
                if c >= _BIG:
                    continue
                x = V[j] + c + mu * dur[e, j, l]
                if x < best:
                    best = x
                    arg = j
            Vn[l] = best
            back[e, l] = arg
        for l in range(J):
            V[l] = Vn[l]
    path = np.zeros(E + 1, dtype=np.int64)
    best = _BIG
    for l in range(J):
        if V[l] < best:
            best = V[l]
            path[E] = l
    T = 0.0
    for e in range(E - 1, -1, -1):
        path[e] = back[e, path[e + 1]]
        T += dur[e, path[e], path[e + 1]]
    return path, T, best


def global_start(obj: BakedObjective, duration=None, stride=2, levels=96, w_lo=0.05, w_hi=8.0, kappa=1.0,
                 d_tol=1e-2, u_max=60.0, iters=40) -> GlobalStart | None:
    """The grid-optimal speed profile of ``obj`` (see the module docstring), lasting ``duration``
    output seconds (None: free). Returns None when no grid path exists."""
    t0 = time.perf_counter()
    times = np.asarray(obj.times, dtype=float)
    n = len(times)
    nodes = np.unique(np.r_[np.arange(0, n - 1, max(1, int(stride))), n - 1]).astype(np.int64)
    w = speed_levels(w_lo, w_hi, levels)
    E, J = len(nodes) - 1, len(w)
    cost = np.empty((E, J, J))
    dur = np.empty((E, J, J))
    _edge_costs(nodes, times, w, obj.poff, obj.px, obj.py, obj.cen, obj.scale, obj.mode, obj.wc, obj.alpha,
                obj.delta, obj.gamma, float(kappa), float(d_tol), float(u_max), cost, dur)
    path, T, val = _shortest(cost, dur, 0.0, -1)
    if val >= _BIG:
        return None
    mu = 0.0
    if duration is not None:
        target = float(duration)
        # more price per output second -> shorter; bracket, then bisect
        lo, hi = 0.0, 0.0
        step = 1.0
        if T > target:
            while True:
                hi = step
                p, Th, _ = _shortest(cost, dur, hi, -1)
                if Th <= target or step > 1e8:
                    break
                lo, step = hi, step * 4.0
        else:
            while True:
                lo = -step
                p, Tl, _ = _shortest(cost, dur, lo, -1)
                if Tl >= target or step > 1e8:
                    break
                hi, step = lo, step * 4.0
        best = (abs(T - target), path, T, 0.0)
        for _ in range(iters):
            mid = 0.5 * (lo + hi)
            p, Tm, _ = _shortest(cost, dur, mid, -1)
            if abs(Tm - target) < best[0]:
                best = (abs(Tm - target), p, Tm, mid)
            if Tm > target:
                lo = mid
            else:
                hi = mid
            if abs(Tm - target) <= 1e-4 * target:
                break
        _, path, T, mu = best
    return GlobalStart(times[nodes], w[path], float(T), float(mu), time.perf_counter() - t0)
