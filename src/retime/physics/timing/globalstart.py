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

Speeds are fine (320 levels from 0.05x to 12x, 1.7 % apart) and an edge changes the speed by at
most ``band`` levels, so small p'' exist at any speed and an edge costs O(band), not O(levels). The
edge costs are computed once (compiled, in parallel over edges); each bisection step is one
O(E J band) pass. ``kappa`` makes the duration/cost front non-convex, so the Lagrangian may jump over
the target duration; it is then lowered (down to 0, the objective alone) until the target is met
within 2 %. The best path's speed profile is fitted by the spline (with twice the control points
when the path gives frames up) and refined by the local optimizer
(:mod:`.optimize`) on the objective, with the frames the path gives up softened (:func:`soften`) so
that the refinement keeps the violation where the grid optimum put it.

How the two starts compare on the CMU jumps (the fraction of output frames feasible, with this
start and with the paper's uniform one): ``benchmarks/physics_jumps.py`` and
``benchmarks/physics_jumps.py --start uniform``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from .objective import BakedObjective, _frame_parts, penalty

_BIG = 1e300
_FORBIDDEN = 1e30  # an edge cost at or above this is not allowed (fits float32)
KAPPA = 40.0  # price of an output second outside the region, in the objective's units (alpha = 10 per body weight)


@dataclass
class GlobalStart:
    """The grid optimum: speed profile over source frames and what it cost."""

    times: np.ndarray  # (m,) source times of the nodes
    speed: np.ndarray  # (m,) playback speed p' at the nodes
    duration: float  # output seconds of the path
    mu: float  # price of an output second that gave this duration
    seconds: float
    outside: np.ndarray  # (n,) bool: frames the path leaves outside their regions

    def output_times(self) -> np.ndarray:
        """Output time of every node (v linear in s between nodes)."""
        ds = np.diff(self.times)
        w0, w1 = self.speed[:-1], self.speed[1:]
        return np.r_[0.0, np.cumsum(2.0 * ds / (w0 + w1))]

    def speed_at_output(self, t) -> np.ndarray:
        return np.interp(t, self.output_times(), self.speed)


def speed_levels(w_lo=0.05, w_hi=12.0, levels=320) -> np.ndarray:
    """Geometric speeds from w_lo to w_hi with 1 exactly on the grid."""
    lo, hi = math.log(w_lo), math.log(w_hi)
    step = (hi - lo) / (levels - 1)
    k0 = round(-lo / step)
    return np.exp((np.arange(levels) - k0) * step)


@njit(cache=True, error_model="numpy", inline="always")
def _sample(m, u, v, ob, cache, d_tol):
    """The objective's integrand f at frame m and whether (u, v) lies outside its region by more than
    d_tol (in the penalty's own measure)."""
    alpha = ob.alpha
    g, _, _, _, _, d2, _, _ = _frame_parts(m, u, v, ob, cache)
    pen = penalty(d2, alpha, ob.delta)
    return g + pen, alpha > 0.0 and pen > alpha * d_tol


# parallel=True doubles its compile (2.0 s -> 4.1 s, paid once, at install) and pays on long clips
# (the 2-minute capture: 15.0 s instead of 18.5 s); each edge writes only its own cells
@njit(cache=True, parallel=True, error_model="numpy")
def _edge_costs(nodes, times, w, band, ob, d_tol, u_max, cost, outt, dur):
    """Objective cost[e, j, k], output time outside the regions outt[e, j, k] and output time
    dur[e, j, k] of the edge from (nodes[e], w[j]) to (nodes[e + 1], w[j + k - band])."""
    E = len(nodes) - 1
    J = len(w)
    gamma = ob.gamma
    for e in prange(E):
        cache = np.zeros(len(ob.poff) - 1, dtype=np.int64)
        ia, ib = nodes[e], nodes[e + 1]
        sa, L = times[ia], times[ib] - times[ia]
        for j in range(J):
            vj = w[j] * w[j]
            for k in range(2 * band + 1):
                l = j + k - band
                outt[e, j, k] = 0.0
                if l < 0 or l >= J:
                    cost[e, j, k] = _FORBIDDEN
                    dur[e, j, k] = 0.0
                    continue
                vl = w[l] * w[l]
                u = (vl - vj) / (2.0 * L)
                if abs(u) > u_max:
                    cost[e, j, k] = _FORBIDDEN
                    dur[e, j, k] = 0.0
                    continue
                c = 0.0
                o = 0.0
                for m in range(ia, ib):
                    ds = times[m + 1] - times[m]
                    v = vj + (vl - vj) * (times[m] - sa) / L
                    pd = math.sqrt(v)
                    f, out = _sample(m, u, v, ob, cache, d_tol)
                    if out:
                        o += ds / pd
                    c += ds * (f / pd + gamma * (pd + 1.0 / pd - 2.0))
                cost[e, j, k] = c
                outt[e, j, k] = o
                dur[e, j, k] = 2.0 * L / (w[j] + w[l])  # exact for v linear in s
    return cost, outt, dur


@njit(cache=True)
def _shortest(cost, outt, kappa, dur, mu, band):
    """Least sum of cost + kappa * outt + mu * dur over paths through the banded grid (edge (e, j, k) goes from level
    j to level j + k - band); returns (levels per node, duration, value)."""
    E, J, B = cost.shape
    V = np.zeros(J)
    back = np.zeros((E, J), dtype=np.int64)
    Vn = np.empty(J)
    for e in range(E):
        for l in range(J):
            Vn[l] = _BIG
        for j in range(J):
            if V[j] >= _BIG:
                continue
            for k in range(B):
                c = cost[e, j, k]
                if c >= _FORBIDDEN:
                    continue
                l = j + k - band
                x = V[j] + c + kappa * outt[e, j, k] + mu * dur[e, j, k]
                if x < Vn[l]:
                    Vn[l] = x
                    back[e, l] = j
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
        T += dur[e, path[e], path[e + 1] - path[e] + band]
    return path, T, best


@njit(cache=True, error_model="numpy")
def _outside(nodes, times, speed, ob, d_tol, out):
    """out[m] = frame m lies outside its region (beyond d_tol) on the path's speed profile."""
    cache = np.zeros(len(ob.poff) - 1, dtype=np.int64)
    for e in range(len(nodes) - 1):
        ia, ib = nodes[e], nodes[e + 1]
        sa, L = times[ia], times[ib] - times[ia]
        vj, vl = speed[e] ** 2, speed[e + 1] ** 2
        u = (vl - vj) / (2.0 * L)
        for m in range(ia, ib + 1 if e == len(nodes) - 2 else ib):
            v = vj + (vl - vj) * (times[m] - sa) / L
            out[m] = _sample(m, u, v, ob, cache, d_tol)[1]


def global_start(obj: BakedObjective, duration=None, stride=None, levels=320, band=10, w_lo=0.05, w_hi=12.0,
                 kappa=KAPPA, d_tol=1e-2, u_max=60.0, iters=60, accept=0.02) -> GlobalStart | None:
    """The grid-optimal speed profile of ``obj`` (see the module docstring), lasting ``duration``
    output seconds (None: free). Speeds are ``levels`` geometric steps from ``w_lo`` to ``w_hi``; an
    edge changes the speed by at most ``band`` steps; nodes every ``stride`` source frames (default 2,
    more for clips over 2400 frames, so that the tables stay under about 100 MB). Returns None when
    no grid path exists."""
    t0 = time.perf_counter()
    times = np.asarray(obj.times, dtype=float)
    n = len(times)
    if stride is None:
        stride = max(2, math.ceil(n / 1200))
    nodes = np.unique(np.r_[np.arange(0, n - 1, max(1, int(stride))), n - 1]).astype(np.int64)
    w = speed_levels(w_lo, w_hi, levels)
    E, J, B = len(nodes) - 1, len(w), 2 * int(band) + 1
    cost = np.empty((E, J, B), dtype=np.float32)  # single precision: the sums along a path are double
    outt = np.empty((E, J, B), dtype=np.float32)
    dur = np.empty((E, J, B), dtype=np.float32)
    _edge_costs(nodes, times, w, int(band), obj.arrays, float(d_tol), float(u_max), cost, outt, dur)
    path, T, val = _shortest(cost, outt, float(kappa), dur, 0.0, int(band))
    if val >= _BIG:
        return None
    mu = 0.0
    if duration is not None:
        # the price of infeasible output time makes the duration jump with mu (the Lagrangian only
        # reaches the convex hull of the duration/cost front): lower it until the duration is met
        target = float(duration)
        p0, T0 = path, T
        for k in (kappa, kappa / 4, kappa / 16, 0.0):
            if k != kappa:  # the free-duration optimum at this price (at kappa: found above)
                p0, T0, _ = _shortest(cost, outt, float(k), dur, 0.0, int(band))
            path, T, mu = _meet_duration(cost, outt, float(k), dur, int(band), target, p0, T0, iters)
            if abs(T - target) <= accept * target:
                break
    speed = w[path]
    out = np.zeros(n, dtype=np.bool_)
    _outside(nodes, times, speed, obj.arrays, float(d_tol), out)
    return GlobalStart(times[nodes], speed, float(T), float(mu), time.perf_counter() - t0, out)


def _meet_duration(cost, outt, kappa, dur, band, target, path, T, iters):
    """Bisection on the price of an output second. The duration jumps where the optimum changes its
    mind, so the answer is the longest path not over ``target`` (the spline's fit then stretches it by
    the remaining fraction), or the nearest one if every path is longer."""
    lo, hi, step = 0.0, 0.0, 1.0
    seen = [(T, path, 0.0)]
    if T > target:
        while step < 1e9:
            hi = step
            p, Th, _ = _shortest(cost, outt, kappa, dur, hi, band)
            seen.append((Th, p, hi))
            if Th <= target:
                break
            lo, step = hi, step * 4.0
    else:
        while step < 1e9:
            lo = -step
            p, Tl, _ = _shortest(cost, outt, kappa, dur, lo, band)
            seen.append((Tl, p, lo))
            if Tl >= target:
                break
            hi, step = lo, step * 4.0
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        p, Tm, _ = _shortest(cost, outt, kappa, dur, mid, band)
        seen.append((Tm, p, mid))
        if abs(Tm - target) <= 1e-3 * target:
            break
        if Tm > target:
            lo = mid
        else:
            hi = mid
    under = [x for x in seen if x[0] <= target * (1 + 1e-3)]
    T, path, mu = max(under, key=lambda x: x[0]) if under else min(seen, key=lambda x: abs(x[0] - target))
    return path, T, mu


def soften(obj: BakedObjective, frames, factor=0.05) -> BakedObjective:
    """A copy of ``obj`` whose feasibility term is ``factor`` times weaker at ``frames`` (bool (n,)):
    the frames the grid optimum gives up, so that the local refinement does not spread their
    violation back over their neighbours (the distance metric of those frames is scaled)."""
    import dataclasses

    frames = np.asarray(frames, dtype=bool)
    ob = obj.arrays
    scale, px, py, cen = ob.scale.copy(), ob.px.copy(), ob.py.copy(), ob.cen.copy()
    for i in np.flatnonzero(frames):
        a, b = ob.poff[i], ob.poff[i + 1]
        scale[i] *= factor
        px[a:b] *= factor
        py[a:b] *= factor
        cen[i] *= factor
    return dataclasses.replace(obj, arrays=ob._replace(scale=scale, px=px, py=py, cen=cen))
