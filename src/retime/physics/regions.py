"""Feasible timing regions (McCann et al. 2006, sec. 3.3).

At every sample of the path, the torques are linear in the retiming (Eq. 6) and in the contact force
coefficients lambda (Eq. 11)::

    tau = a p'' + b p'^2 + c - N lam,   lam >= 0,   lo <= tau <= hi          (Eq. 13)

with the root's six rows unactuated (lo = hi = 0). The **feasible region** of a frame is the projection
of this polytope in (p'', p'^2, lam) onto the (u, v) = (p'', p'^2) plane: a convex polygon. It is
computed here per frame:

* **Rows that do not involve lam** (every row in flight, the arm and head rows in contact) are
  half-planes of the (u, v) plane and are intersected exactly in 2-D (no LP). The projection of the
  rest commutes with them, so they clip the LP's polygon afterwards.
* **Rows with lam** define a small LP in (u, v, lam). It is solved by HiGHS (``highspy``), one
  ``Highs`` model per frame that keeps its basis; only the cost direction changes. Two ways of
  tracing the polygon:

  - ``method="parametric"`` (default): HiGHS solves the frame's centre LP (least contact force at the
    original timing, sec. 3.4) -- the one HiGHS solve per frame; with its basis, a compiled phase-2
    primal simplex reaches the vertex of largest p'^2, and a parametric (shadow-vertex) simplex rotates
    the cost direction through 360 degrees from there, pivoting exactly at the angles where the basis
    stops being optimal. Every non-degenerate pivot lands on the next vertex of the projection, so the
    polygon is exact (to floating point). On numerical trouble it falls back to ...
  - ``method="highs"``: adaptive refinement with HiGHS alone (Fig. 4): maximize in the four axis
    directions, then along the outward normal of every edge found so far; an edge is final when the
    LP cannot push past it by more than ``tol``, so the polygon is exact to ``tol`` (it always lies
    inside the true region).

* The (u, v) box ``|p''| <= u_max``, ``0 <= p'^2 <= v_max`` bounds the search (a still frame accepts
  any timing; the box stands for "anything reasonable").

**Relaxation: the data's own inconsistency is the yardstick.** Motion capture with an estimated
body is never exactly physical: in flight the centre-of-mass acceleration of the captured motion
differs from g by 10-30% from frame to frame, and a foot may sit where it cannot quite carry the body.
Taken literally, the original timing would be infeasible at such frames, and a retiming with
unchanged physics would move away from it. So each frame gets a *residual budget*: the smallest row
residual (least weighted L1 over slack variables: 1 per newton of root force, 1 per newton-metre /
``moment_arm`` of root moment, ``actuated_slack_cost`` times that beyond a torque limit, all per body
weight = mass x 9.81 m/s^2) with which the **original timing (0, 1) under the original physics** is
feasible (:func:`source_fit`; zero at frames that are physical as captured). The frame's rows are
widened by that residual times p'^2 (the captured motion's inconsistency comes from its twice
differentiated accelerations and the estimated inertias, which scale with p'^2) plus ``relax_pad``
(1% of the body weight), for the original physics and for changed ones alike: a retiming is feasible
at a frame when it needs no more residual root wrench than the captured motion itself did at that
speed. With unchanged physics the original timing is therefore always feasible. Besides, every
frame's root rows may use a residual of ``allowance`` = 5% of the body weight under the current
gravity -- the modelling error biomechanics accepts for residual forces of captured motion.

**Capture-noise band.** A still stance played 4x faster has 16x its accelerations, and at such a
stance the captured accelerations are mostly sway and twice-differentiated marker noise: which of
the two decides whether a fast stance is feasible. So in stance (never in flight, where the parabola
is known well) the root rows are also widened by ``PathDynamics.b_noise`` p'^2: the local RMS
(over +-0.1 s) of how much their p'^2 coefficient b changes between the dynamics' low-pass and a
twice wider one (0.1 s), each difference capped at 2% of body weight (near a takeoff or a landing the
wide low-pass blurs real impacts). A timing is then
feasible if a path within the capture's own uncertainty can carry it. ``noise = False`` turns it off.
With unchanged physics the fan centre keeps the source fit's least-force lambda, so "match" still
costs nothing at the original timing.

If a region is still empty (changed physics can ask for more than the body can give), the smallest
extra residual is found the same way over all timings in the box, added with the pad, and reported
as ``relaxation`` (fraction of body weight); frames needing more than ``max_relaxation`` (5%) are
flagged ``implausible``. No frame is ever left without a region, so the optimizer never meets an
empty one. The bounds actually used are kept (``lo``, ``hi``) so that everything computed afterwards
can be checked against them.

Per frame the result also records ``source_residual`` (the budget in body weights: how far the
original timing is from feasible as captured) and ``source_distance`` (how far (0, 1) lies outside
the final region in the (p'', p'^2) plane; 0 with unchanged physics).
"""
from __future__ import annotations

import math
import os
import threading
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..errors import RetimeError

STANDARD_G = 9.81
_INF = 1e30


@dataclass
class RegionOptions:
    """How feasible regions are computed. Units: u = p'' in 1/s, v = p'^2 (dimensionless)."""

    u_max: float = 60.0
    v_max: float = 64.0  # up to 8x speed (still frames, which any speed suits)
    method: str = "parametric"  # "parametric" (HiGHS + shadow-vertex walk) or "highs" (refinement)
    tol: float = 1e-3  # "highs": polygon accuracy in the (p'', p'^2) plane
    relax: bool = True  # False: exact regions (an empty one is an error)
    allowance: float = 0.05  # residual root wrench every frame may use, fraction of body weight
    relax_pad: float = 0.01  # fraction of body weight added around every residual budget
    noise: bool = True  # widen the root rows by the capture-noise band b_noise p'^2 (PathDynamics.b_noise)
    max_relaxation: float = 0.05  # frames needing more extra relaxation are flagged implausible
    moment_arm: float = 1.0  # metres: a root moment of W * moment_arm counts like a force of W
    actuated_slack_cost: float = 10.0
    body_weight: float | None = None  # newtons; default: estimated from the gravity term
    center: tuple = (0.0, 1.0)  # the timing whose contact forces anchor the force model (sec. 3.4)
    workers: int | None = None  # processes for many frames (default: all cores, at most 2)


@dataclass
class RegionSet:
    """Per-frame convex polygons in the (u, v) = (p'', p'^2) plane, with the contact model.

    Polygon ``i`` has vertices ``verts[offsets[i]:offsets[i+1]]`` in counter-clockwise order and the
    contact force coefficients ``lam`` (full width K, zero for unused columns) found at each of them.
    ``center[i]`` is the fan centre of sec. 3.4 (the original timing (0, 1) when it is feasible, else
    the nearest feasible point pulled slightly inwards) with ``center_lam[i]`` the least total contact
    force there. ``lo``/``hi`` are the torque bounds actually used (widened on relaxed frames).
    """

    times: np.ndarray
    offsets: np.ndarray
    verts: np.ndarray
    lam: np.ndarray
    center: np.ndarray
    center_lam: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    budget: np.ndarray  # (n, nv) row residuals the captured motion needs (original physics)
    source_residual: np.ndarray  # (n,) their weighted sum, in body weights
    lam0: np.ndarray  # (n, K) contact coefficients of the original timing (original physics)
    relaxation: np.ndarray  # extra relaxation beyond the budget, fraction of body weight (0 = none)
    relaxed: np.ndarray
    implausible: np.ndarray
    source_distance: np.ndarray
    n_lp: np.ndarray  # LP solves per frame (HiGHS runs)
    n_pivots: np.ndarray  # parametric pivots per frame
    contact: np.ndarray
    options: RegionOptions = field(default_factory=RegionOptions)
    body_weight: float = 0.0
    seconds: float = 0.0

    @property
    def n_frames(self) -> int:
        return len(self.offsets) - 1

    def polygon(self, i: int) -> np.ndarray:
        return self.verts[self.offsets[i]:self.offsets[i + 1]]

    def polygon_lam(self, i: int) -> np.ndarray:
        return self.lam[self.offsets[i]:self.offsets[i + 1]]

    def contains(self, i: int, point, tol: float = 1e-9) -> bool:
        return polygon_distance(self.polygon(i), point) <= tol

    def distance(self, i: int, point) -> float:
        return polygon_distance(self.polygon(i), point)

    def distances(self, frames, u, v) -> np.ndarray:
        """Distance of each point (u[k], v[k]) to the region of frame ``frames[k]`` (0 inside), at once."""
        frames = np.asarray(frames, dtype=np.int64)
        u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
        out = np.empty(len(frames))
        _distances_kernel(np.ascontiguousarray(self.verts, dtype=float), np.asarray(self.offsets, dtype=np.int64),
                          frames, np.ascontiguousarray(u), np.ascontiguousarray(v), out)
        return out


# ------------------------------------------------------------------------------------------------
# 2-D geometry
# ------------------------------------------------------------------------------------------------

def polygon_area(P) -> float:
    P = np.asarray(P, dtype=float)
    if len(P) < 3:
        return 0.0
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def closest_point(P, point):
    """Closest point of the convex polygon P (CCW, possibly degenerate) to ``point``; (q, distance)."""
    P = np.ascontiguousarray(P, dtype=float).reshape(-1, 2)
    if len(P) == 0:
        raise RetimeError("empty polygon")
    qx, qy, d = _closest_kernel(P, float(point[0]), float(point[1]))
    return np.array([qx, qy]), d


@njit(cache=True)
def _closest_kernel(P, x, y):
    n = P.shape[0]
    if n >= 3:
        inside = True
        for k in range(n):
            ax, ay = P[k, 0], P[k, 1]
            bx, by = P[(k + 1) % n, 0], P[(k + 1) % n, 1]
            if (bx - ax) * (y - ay) - (by - ay) * (x - ax) < 0.0:
                inside = False
                break
        if inside:
            return x, y, 0.0
    qx, qy = P[0, 0], P[0, 1]
    bd = math.hypot(qx - x, qy - y)
    for k in range(n):
        ax, ay = P[k, 0], P[k, 1]
        ex, ey = P[(k + 1) % n, 0] - ax, P[(k + 1) % n, 1] - ay
        ee = ex * ex + ey * ey
        t = 0.0
        if ee > 0.0:
            t = min(1.0, max(0.0, ((x - ax) * ex + (y - ay) * ey) / ee))
        cx, cy = ax + t * ex, ay + t * ey
        d = math.hypot(cx - x, cy - y)
        if d < bd:
            qx, qy, bd = cx, cy, d
    return qx, qy, bd


@njit(cache=True)
def _distances_kernel(verts, offsets, frames, u, v, out):
    for k in range(frames.shape[0]):
        i = frames[k]
        out[k] = _closest_kernel(verts[offsets[i]:offsets[i + 1]], u[k], v[k])[2]


def polygon_distance(P, point) -> float:
    return closest_point(P, point)[1]


def _inside(P, p, tol=0.0):
    e = np.roll(P, -1, axis=0) - P
    w = p[None, :] - P
    cross = e[:, 0] * w[:, 1] - e[:, 1] * w[:, 0]
    scale = np.hypot(e[:, 0], e[:, 1])
    return bool(np.all(cross >= -tol * np.maximum(scale, 1e-300)))


@njit(cache=True)
def _clip_halfplanes(px, py, plam, H, tol):
    """Clip a convex polygon (CCW) by half-planes H[k] = (a, b, c): a u + b v <= c (rows normalized
    so that hypot(a, b) = 1; rows with a = b = 0 are feasibility checks on c). Contact coefficients
    of new vertices are interpolated along the clipped edge. Returns (px, py, plam, ok)."""
    for k in range(H.shape[0]):
        a, b, c = H[k, 0], H[k, 1], H[k, 2]
        if a == 0.0 and b == 0.0:
            if c < -tol:
                return px[:0], py[:0], plam[:0], False
            continue
        n = px.shape[0]
        if n == 0:
            return px, py, plam, False
        s = np.empty(n)
        allin = True
        allout = True
        for i in range(n):
            s[i] = a * px[i] + b * py[i] - c
            if s[i] > tol:
                allin = False
            else:
                allout = False
        if allin:
            continue
        if allout:
            return px[:0], py[:0], plam[:0], False
        K = plam.shape[1]
        qx = np.empty(2 * n)
        qy = np.empty(2 * n)
        ql = np.empty((2 * n, K))
        m = 0
        for i in range(n):
            j = (i + 1) % n
            si, sj = s[i], s[j]
            if si <= tol:
                qx[m] = px[i]
                qy[m] = py[i]
                ql[m] = plam[i]
                m += 1
            if (si <= tol) != (sj <= tol):
                t = si / (si - sj)
                qx[m] = px[i] + t * (px[j] - px[i])
                qy[m] = py[i] + t * (py[j] - py[i])
                ql[m] = plam[i] + t * (plam[j] - plam[i])
                m += 1
        px, py, plam = qx[:m].copy(), qy[:m].copy(), ql[:m].copy()
    return px, py, plam, True


def _dedupe(P, L, eps):
    """Drop consecutive (cyclic) duplicate vertices and collinear middle points."""
    if len(P) == 0:
        return P, L
    keep = _dedupe_kernel(np.ascontiguousarray(P, dtype=float), eps)
    return P[keep], L[keep]


@njit(cache=True)
def _dedupe_kernel(P, eps):
    n = P.shape[0]
    keep = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if m == 0 or math.hypot(P[i, 0] - P[keep[m - 1], 0], P[i, 1] - P[keep[m - 1], 1]) > eps:
            keep[m] = i
            m += 1
    while m > 1 and math.hypot(P[keep[m - 1], 0] - P[keep[0], 0], P[keep[m - 1], 1] - P[keep[0], 1]) <= eps:
        m -= 1
    changed = True
    while changed and m >= 3:
        changed = False
        for i in range(m):
            ia, ib, ic = keep[(i - 1) % m], keep[i], keep[(i + 1) % m]
            abx, aby = P[ib, 0] - P[ia, 0], P[ib, 1] - P[ia, 1]
            acx, acy = P[ic, 0] - P[ia, 0], P[ic, 1] - P[ia, 1]
            cr = abx * acy - aby * acx
            if abs(cr) <= eps * max(math.hypot(acx, acy), 1e-300):
                for j in range(i, m - 1):
                    keep[j] = keep[j + 1]
                m -= 1
                changed = True
                break
    return keep[:m].copy()


# ------------------------------------------------------------------------------------------------
# Parametric (shadow-vertex) primal simplex walk around the projection
# ------------------------------------------------------------------------------------------------

@njit(cache=True)
def _standard_form(A, basic):
    """M = [A, -I] (variables x then row activities) and the basis bookkeeping."""
    m, n = A.shape
    nt = n + m
    M = np.zeros((m, nt))
    M[:, :n] = A
    for r in range(m):
        M[r, n + r] = -1.0
    isbasic = np.zeros(nt, dtype=np.bool_)
    pos = -np.ones(nt, dtype=np.int64)
    for r in range(m):
        isbasic[basic[r]] = True
        pos[basic[r]] = r
    return M, isbasic, pos


@njit(cache=True)
def _ratio_test(col, dirn, basic, z, zl, zu, tmax):
    """Bounded primal ratio test: how far the entering variable may move (``dirn`` = +-1, its own
    range ``tmax``) before a basic variable hits a bound; ties go to the larger pivot.
    Returns (step, leaving row or -1, leaves at its upper bound)."""
    leave = -1
    leave_up = False
    bestpiv = 0.0
    for r in range(len(col)):
        al = -dirn * col[r]  # dz_B / dt
        if abs(al) <= 1e-11:
            continue
        j = basic[r]
        if al > 0.0:
            if zu[j] >= _INF * 0.5:
                continue
            t = (zu[j] - z[j]) / al
            tu = True
        else:
            if zl[j] <= -_INF * 0.5:
                continue
            t = (zl[j] - z[j]) / al
            tu = False
        if t < 0.0:
            t = 0.0
        if t < tmax - 1e-12 * (1.0 + tmax) or (abs(t - tmax) <= 1e-12 * (1.0 + tmax) and abs(al) > bestpiv):
            tmax, leave, leave_up, bestpiv = t, r, tu, abs(al)
    return tmax, leave, leave_up


@njit(cache=True)
def _entering_column(Binv, A, jin, col):
    """col = B^-1 M_jin for M = [A, -I]."""
    m, n = A.shape
    if jin < n:
        for r in range(m):
            acc = 0.0
            for q in range(m):
                acc += Binv[r, q] * A[q, jin]
            col[r] = acc
    else:
        for r in range(m):
            col[r] = -Binv[r, jin - n]


@njit(cache=True)
def _eta_update(Binv, col, leave):
    """Binv after the basic variable of row ``leave`` is replaced by the column with B^-1 a = col."""
    m = len(col)
    piv = col[leave]
    for q in range(m):
        Binv[leave, q] /= piv
    for r in range(m):
        if r != leave:
            f = col[r]
            if f != 0.0:
                for q in range(m):
                    Binv[r, q] -= f * Binv[leave, q]


@njit(cache=True)
def _phase2(A, zl, zu, basic, zval, max_iter):
    """Primal simplex for "maximize x1" from a feasible basis whose nonbasic variables may sit
    strictly between their bounds (the centre LP's basis once (u, v) are released): such variables
    enter in whichever direction improves, and are finally pushed to a bound, so that the returned
    basis is a proper vertex basis (the walk's starting point). Returns (basic, at_upper, status)."""
    m, n = A.shape
    nt = n + m
    M, isbasic, pos = _standard_form(A, basic)
    B = np.empty((m, m))
    for r in range(m):
        B[:, r] = M[:, basic[r]]
    Binv = np.linalg.inv(B)
    z = zval.copy()
    rhs = np.zeros(m)
    col = np.zeros(m)
    y = np.zeros(m)
    scale = 1.0
    for j in range(nt):
        for r in range(m):
            scale = max(scale, abs(M[r, j]))
    status = 1
    for it in range(max_iter):
        for r in range(m):
            rhs[r] = 0.0
        for j in range(nt):
            if not isbasic[j] and z[j] != 0.0:
                for r in range(m):
                    rhs[r] -= M[r, j] * z[j]
        for r in range(m):
            acc = 0.0
            for q in range(m):
                acc += Binv[r, q] * rhs[q]
            z[basic[r]] = acc
        for r in range(m):
            y[r] = -Binv[pos[1], r] if isbasic[1] else 0.0
        jin = -1
        best = 1e-9
        dirn = 0.0
        for j in range(nt):
            if isbasic[j] or zu[j] - zl[j] <= 0.0:
                continue
            dot = 0.0
            for r in range(m):
                if M[r, j] != 0.0:
                    dot += y[r] * M[r, j]
            d = (-1.0 if j == 1 else 0.0) - dot
            atl = z[j] <= zl[j]
            atu = z[j] >= zu[j]
            if d < -best and not atu:
                best, jin, dirn = -d, j, 1.0
            elif d > best and not atl:
                best, jin, dirn = d, j, -1.0
        if jin < 0:
            for j in range(nt):  # optimal: push the remaining interior nonbasics to a bound
                if not isbasic[j] and zl[j] < z[j] < zu[j]:
                    jin, dirn = j, 1.0
                    break
            if jin < 0:
                status = 0
                break
        _entering_column(Binv, A, jin, col)
        tmax, leave, leave_up = _ratio_test(col, dirn, basic, z, zl, zu,
                                            (zu[jin] - z[jin]) if dirn > 0 else (z[jin] - zl[jin]))
        if tmax >= _INF * 0.5:
            status = 2
            break
        z[jin] += dirn * tmax
        if leave < 0:
            z[jin] = zu[jin] if dirn > 0 else zl[jin]
            continue
        jout = basic[leave]
        z[jout] = zu[jout] if leave_up else zl[jout]
        piv = col[leave]
        basic[leave] = jin
        isbasic[jin] = True
        isbasic[jout] = False
        pos[jin] = leave
        pos[jout] = -1
        if abs(piv) < 1e-9 * scale or it % 25 == 24:
            for r in range(m):
                B[:, r] = M[:, basic[r]]
            Binv = np.linalg.inv(B)
        else:
            _eta_update(Binv, col, leave)
    up = np.zeros(nt, dtype=np.bool_)
    for j in range(nt):
        if not isbasic[j] and zu[j] > zl[j] and z[j] >= zu[j]:
            up[j] = True
    return basic, up, status


@njit(cache=True)
def _walk(A, zl, zu, basic, atupper, theta0, max_iter):
    """Trace the projection of {x : zl_x <= x <= zu_x, zl_s <= A x <= zu_s} onto (x0, x1).

    Variables z = (x (n), s (m)) with A x - s = 0. ``basic`` (m,) lists the basic variables of a
    basis optimal for the direction (cos theta0, sin theta0); nonbasic variables sit at their lower
    bound unless ``atupper``. The cost direction is rotated counter-clockwise; at each angle where a
    reduced cost changes sign the entering variable is pivoted in (bounded ratio test), which moves to
    the next vertex. Returns (verts (k, 2), xs (k, n), status, pivots); status 0 = ok."""
    m, n = A.shape
    nt = n + m
    M, isbasic, pos = _standard_form(A, basic)
    up = atupper.copy()
    out_v = np.empty((4 * max_iter + 8, 2))
    out_x = np.empty((4 * max_iter + 8, n))
    nout = 0
    scale = 0.0
    for j in range(nt):
        for r in range(m):
            if abs(M[r, j]) > scale:
                scale = abs(M[r, j])
    B = np.empty((m, m))
    for r in range(m):
        B[:, r] = M[:, basic[r]]
    Binv = np.linalg.inv(B)
    z = np.zeros(nt)
    rhs = np.zeros(m)
    y1 = np.zeros(m)
    y2 = np.zeros(m)
    col = np.zeros(m)
    theta = theta0
    end = theta0 + 2.0 * math.pi
    status = 0
    it = 0
    since_refactor = 0
    while True:
        # primal values of the current basis
        for j in range(nt):
            if not isbasic[j]:
                z[j] = zu[j] if up[j] else zl[j]
        for r in range(m):
            rhs[r] = 0.0
        for j in range(n):
            if not isbasic[j] and z[j] != 0.0:
                for r in range(m):
                    rhs[r] -= A[r, j] * z[j]
        for r in range(m):
            j = n + r
            if not isbasic[j]:
                rhs[r] += z[j]
        for r in range(m):
            acc = 0.0
            for q in range(m):
                acc += Binv[r, q] * rhs[q]
            z[basic[r]] = acc
        if nout == 0 or abs(z[0] - out_v[nout - 1, 0]) + abs(z[1] - out_v[nout - 1, 1]) > 1e-12 * (
                1.0 + abs(z[0]) + abs(z[1])):
            out_v[nout, 0] = z[0]
            out_v[nout, 1] = z[1]
            out_x[nout] = z[:n]
            nout += 1
        if it >= max_iter:
            status = 1
            break
        it += 1
        # reduced costs d_j(theta) = cos(theta) d1_j + sin(theta) d2_j for costs -x0 and -x1
        for r in range(m):
            y1[r] = -Binv[pos[0], r] if isbasic[0] else 0.0
            y2[r] = -Binv[pos[1], r] if isbasic[1] else 0.0
        best = 1e300
        jin = -1
        ct = math.cos(theta)
        st = math.sin(theta)
        for j in range(nt):
            if isbasic[j] or zu[j] - zl[j] <= 0.0:
                continue
            if j < n:
                dot1 = 0.0
                dot2 = 0.0
                for r in range(m):
                    mr = A[r, j]
                    if mr != 0.0:
                        dot1 += y1[r] * mr
                        dot2 += y2[r] * mr
            else:
                dot1 = -y1[j - n]
                dot2 = -y2[j - n]
            d1 = (-1.0 if j == 0 else 0.0) - dot1
            d2 = (-1.0 if j == 1 else 0.0) - dot2
            sg = -1.0 if up[j] else 1.0
            Ag = sg * (d1 * ct + d2 * st)
            Bg = sg * (-d1 * st + d2 * ct)
            R = math.hypot(Ag, Bg)
            if R <= 1e-12:
                continue
            if Ag <= 1e-10 * R and Bg < 0.0:
                delta = 0.0
            else:
                delta = math.atan2(Bg, Ag) + 0.5 * math.pi
                if delta < 0.0:
                    delta += 2.0 * math.pi
                elif delta >= 2.0 * math.pi:
                    delta -= 2.0 * math.pi
            if delta < best - 1e-13:
                best = delta
                jin = j
        if jin < 0 or theta + best >= end:
            break
        theta += best
        # ratio test: move the entering variable away from its bound
        dirn = -1.0 if up[jin] else 1.0
        _entering_column(Binv, A, jin, col)
        tmax, leave, leave_up = _ratio_test(col, dirn, basic, z, zl, zu, zu[jin] - zl[jin])
        if tmax >= _INF * 0.5:
            status = 2  # unbounded ray: cannot happen for a bounded projection
            break
        if leave < 0:
            up[jin] = not up[jin]  # bound flip
            continue
        jout = basic[leave]
        basic[leave] = jin
        isbasic[jin] = True
        isbasic[jout] = False
        pos[jin] = leave
        pos[jout] = -1
        up[jout] = leave_up
        piv = col[leave]
        if abs(piv) < 1e-9 * scale or since_refactor >= 25:
            for r in range(m):
                B[:, r] = M[:, basic[r]]
            if abs(np.linalg.det(B)) == 0.0:
                status = 3
                break
            Binv = np.linalg.inv(B)
            since_refactor = 0
        else:
            _eta_update(Binv, col, leave)
            since_refactor += 1
    return out_v[:nout].copy(), out_x[:nout].copy(), status, it


# ------------------------------------------------------------------------------------------------
# HiGHS models
# ------------------------------------------------------------------------------------------------

_LOCAL = threading.local()  # per thread: HiGHS objects are not thread-safe, and editor or Dask threads share a process


def _pool() -> dict:
    """This thread's HiGHS objects and warm-start bases."""
    pool = getattr(_LOCAL, "pool", None)
    if pool is None:
        pool = _LOCAL.pool = {}
    return pool


def _pooled_highs(kind):
    """One HiGHS object per kind and process, reused frame after frame (passModel replaces the
    model; the last basis is offered to the next frame of the same shape as a warm start)."""
    pool = _pool()
    h = pool.get(kind)
    if h is None:
        h = pool[kind] = _new_highs()
    return h


def _new_highs():
    from highspy import _core

    h = _core._Highs()  # the raw binding: no Python callbacks on every iteration
    h.setOptionValue("output_flag", False)
    h.setOptionValue("presolve", "off")
    h.setOptionValue("solver", "simplex")
    h.setOptionValue("threads", 1)
    h.setOptionValue("simplex_strategy", 4)  # primal: the basis stays feasible when the cost turns
    return h


def _highs_lp(A, col_lo, col_hi, row_lo, row_hi, cost=None):
    import highspy

    m, n = A.shape
    lp = highspy.HighsLp()
    lp.num_col_ = n
    lp.num_row_ = m
    lp.col_cost_ = np.zeros(n) if cost is None else np.asarray(cost, dtype=float)
    lp.col_lower_ = np.where(col_lo <= -_INF * 0.5, -highspy.kHighsInf, col_lo)
    lp.col_upper_ = np.where(col_hi >= _INF * 0.5, highspy.kHighsInf, col_hi)
    lp.row_lower_ = np.where(row_lo <= -_INF * 0.5, -highspy.kHighsInf, row_lo)
    lp.row_upper_ = np.where(row_hi >= _INF * 0.5, highspy.kHighsInf, row_hi)
    At = np.asarray(A, dtype=float).T
    nz = At != 0.0
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_ = np.concatenate(([0], np.cumsum(nz.sum(axis=1)))).astype(np.int32)
    lp.a_matrix_.index_ = np.nonzero(nz)[1].astype(np.int32)
    lp.a_matrix_.value_ = At[nz]
    lp.a_matrix_.num_col_ = n
    lp.a_matrix_.num_row_ = m
    return lp


def _pass_lp(h, A, col_lo, col_hi, row_lo, row_hi, cost=None):
    """passModel from raw arrays (a quarter of the time of building a HighsLp object)."""
    import highspy

    m, n = A.shape
    At = np.asarray(A, dtype=float).T
    nz = At != 0.0
    start = np.concatenate(([0], np.cumsum(nz.sum(axis=1)))).astype(np.int32)
    index = np.nonzero(nz)[1].astype(np.int32)
    value = np.ascontiguousarray(At[nz])
    # HiGHS reads any bound beyond 1e20 as infinite, so the 1e30 used here passes as it is
    st = h.passModel(n, m, len(value), 1, 1, 0.0, np.zeros(n) if cost is None else np.asarray(cost, dtype=float),
                     col_lo, col_hi, row_lo, row_hi, start, index, value, np.zeros(n, dtype=np.int32))
    if st == highspy.HighsStatus.kError:  # fall back to the model object
        h.passModel(_highs_lp(A, col_lo, col_hi, row_lo, row_hi, cost))


class FrameLP:
    """One frame's LP in (u, v, lam_active): a HiGHS model kept for the frame; only costs (and, for
    the centre point, the (u, v) bounds) change between solves."""

    def __init__(self, A, row_lo, row_hi, u_max, v_max):
        import highspy

        self.A = np.ascontiguousarray(A, dtype=float)
        m, n = A.shape
        self.m, self.n = m, n
        self.col_lo = np.zeros(n)
        self.col_lo[0] = -u_max
        self.col_hi = np.full(n, _INF)
        self.col_hi[0], self.col_hi[1] = u_max, v_max
        self.row_lo = np.asarray(row_lo, dtype=float)
        self.row_hi = np.asarray(row_hi, dtype=float)
        self.h = _pooled_highs("frame")
        _pass_lp(self.h, self.A, self.col_lo, self.col_hi, self.row_lo, self.row_hi)
        prev = _pool().get(("basis", m, n))
        if prev is not None:
            self.h.setBasis(prev)
        self.n_solves = 0
        self.center_state = None
        self._idx2 = np.array([0, 1], dtype=np.int32)
        self._kOptimal = highspy.HighsModelStatus.kOptimal

    def _run(self):
        """Solve; on numerical trouble (status neither optimal nor infeasible) retry from scratch with
        the dual simplex, which HiGHS finds more robust on badly scaled rows."""
        import highspy

        self.h.run()
        self.n_solves += 1
        st = self.h.getModelStatus()
        if st in (self._kOptimal, highspy.HighsModelStatus.kInfeasible):
            return st == self._kOptimal
        self.h.setOptionValue("simplex_strategy", 1)
        self.h.clearSolver()
        self.h.run()
        self.n_solves += 1
        self.h.setOptionValue("simplex_strategy", 4)
        return self.h.getModelStatus() == self._kOptimal

    def maximize(self, du, dv):
        """Maximize du*u + dv*v; returns x (n,) or None if infeasible."""
        self.h.changeColsCost(2, self._idx2, np.array([-du, -dv]))
        if not self._run():
            return None
        _pool()[("basis", self.m, self.n)] = self.h.getBasis()
        return np.asarray(self.h.getSolution().col_value)

    def basis(self):
        """The optimal basis as (basic indices over (cols, rows), at-upper flags of the nonbasic)."""
        _, bv = self.h.getBasicVariables()
        bv = np.asarray(bv, dtype=np.int64)
        basic = np.where(bv >= 0, bv, self.n - bv - 1)
        sol = self.h.getSolution()
        z = np.concatenate((np.asarray(sol.col_value), np.asarray(sol.row_value)))
        zu = np.concatenate((self.col_hi, self.row_hi))
        zl = np.concatenate((self.col_lo, self.row_lo))
        up = (z >= zu - 1e-9 * (1.0 + np.abs(zu))) & (zu > zl) & (zu < _INF * 0.5)
        up[basic] = False
        return basic, up

    def solve_at(self, u, v, cost_lam):
        """Fix (u, v) and minimize cost_lam . lam; returns lam or None."""
        h = self.h
        n = self.n
        h.changeColsBounds(2, self._idx2, np.array([u, v]), np.array([u, v]))
        cost = np.zeros(n)
        cost[2:] = cost_lam
        h.changeColsCost(n, np.arange(n, dtype=np.int32), cost)
        ok = self._run()
        x = None
        self.center_state = None
        if ok:
            sol = h.getSolution()
            x = np.asarray(sol.col_value)
            _pool()[("basis", self.m, self.n)] = h.getBasis()
            basic, _ = self.basis()
            if len(basic) == self.m:
                self.center_state = (basic, np.concatenate((x, np.asarray(sol.row_value))))
        h.changeColsBounds(2, self._idx2, self.col_lo[:2], self.col_hi[:2])
        h.changeColsCost(n, np.arange(n, dtype=np.int32), np.zeros(n))
        return None if x is None else x[2:]


def _trace_highs(lp: FrameLP, tol, first=None):
    """Adaptive refinement (Fig. 4): axis directions, then edge normals until every edge holds to tol."""
    pts = []  # list of (angle, x)
    dirs = [0.5 * math.pi, 0.0, math.pi, 1.5 * math.pi]
    for k, th in enumerate(dirs):
        x = first if (k == 0 and first is not None) else lp.maximize(math.cos(th), math.sin(th))
        if x is None:
            return None
        pts.append((th, x))
    pts.sort(key=lambda p: p[0])
    # refine edges between consecutive support points
    stack = [(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
    done = []
    guard = 0
    while stack:
        guard += 1
        (ta, xa), (tb, xb) = stack.pop()
        pa, pb = xa[:2], xb[:2]
        e = pb - pa
        if np.hypot(*e) <= tol:
            done.append((ta, xa))
            continue
        nrm = np.array([e[1], -e[0]]) / np.hypot(*e)  # outward for CCW order
        x = lp.maximize(nrm[0], nrm[1])
        if x is None or guard > 400:
            done.append((ta, xa))
            continue
        if float(nrm @ (x[:2] - pa)) > tol:
            tm = math.atan2(nrm[1], nrm[0]) % (2 * math.pi)
            stack.append(((tm, x), (tb, xb)))
            stack.append(((ta, xa), (tm, x)))
        else:
            done.append((ta, xa))
    X = np.array([x for _, x in done])
    order = _ccw_order(X[:, :2])
    return X[order]


def _ccw_order(P):
    c = P.mean(axis=0)
    ang = np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0])
    return np.argsort(ang, kind="stable")


# ------------------------------------------------------------------------------------------------
# One frame
# ------------------------------------------------------------------------------------------------

@dataclass
class _FrameResult:
    verts: np.ndarray
    lam: np.ndarray
    center: np.ndarray
    center_lam: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    budget: np.ndarray
    source_residual: float
    lam0: np.ndarray
    relaxation: float
    relaxed: bool
    source_distance: float
    n_lp: int
    n_pivots: int


def _row_weights(n_root, nv, body_weight, opts):
    """Newtons per unit of residual: body weight on the root force rows, weight x moment arm on the
    root moment rows and on the joint rows."""
    w = np.full(nv, body_weight * opts.moment_arm)
    w[: min(3, n_root)] = body_weight
    return w


def _row_costs(n_root, nv, body_weight, opts):
    cost = 1.0 / _row_weights(n_root, nv, body_weight, opts)
    cost[n_root:] *= opts.actuated_slack_cost
    return cost


def _box_polygon(opts, K):
    U, V = opts.u_max, opts.v_max
    P = np.array([[-U, 0.0], [U, 0.0], [U, V], [-U, V]])
    return P, np.zeros((4, K))


def _split(a, b, lo, hi, rho, rows):
    """Rows lo - rho v <= a u + b v (+ ...) <= hi + rho v as one-sided or ranged LP rows.

    Returns (coefficient of u, of v, lower, upper, source row) per LP row: a row without budget
    stays ranged; a row with budget rho > 0 becomes an upper row with v-coefficient b - rho and a
    lower row with b + rho."""
    rows = np.asarray(rows, dtype=np.int64)
    has = rho[rows] > 0
    if not has.any():
        return a[rows], b[rows], lo[rows], hi[rows], rows
    r0 = rows[~has]
    r1 = rows[has]
    cat = np.concatenate
    cu = cat((a[r0], a[r1], a[r1]))
    cv = cat((b[r0], b[r1] - rho[r1], b[r1] + rho[r1]))
    lo_ = cat((lo[r0], np.full(len(r1), -_INF), lo[r1]))
    hi_ = cat((hi[r0], hi[r1], np.full(len(r1), _INF)))
    src = cat((r0, r1, r1))
    return cu, cv, lo_, hi_, src


def _halfplanes(a, b, c, lo, hi, rho, rows):
    """Rows without contact forces as normalized half-planes (a, b, c): a u + b v <= c."""
    return _halfplanes_kernel(a, b, c, lo, hi, rho, np.asarray(rows, dtype=np.int64))


@njit(cache=True)
def _halfplanes_kernel(a, b, c, lo, hi, rho, rows):
    out = np.empty((2 * len(rows) + 1, 3))
    k = 0
    for r in rows:
        for side in range(2):  # upper: a u + (b - rho) v <= hi - c ; lower: -a u - (b + rho) v <= c - lo
            if side == 0:
                bound = hi[r] - c[r]
                if hi[r] >= _INF * 0.5:
                    continue
                cu, cv = a[r], b[r] - rho[r]
            else:
                bound = c[r] - lo[r]
                if lo[r] <= -_INF * 0.5:
                    continue
                cu, cv = -a[r], -(b[r] + rho[r])
            nrm = math.hypot(cu, cv)
            if nrm > 1e-12 * (1.0 + abs(bound)):
                out[k, 0], out[k, 1], out[k, 2] = cu / nrm, cv / nrm, bound / nrm
            else:  # a row the timing cannot change: feasible iff its bound is not negative
                out[k, 0], out[k, 1], out[k, 2] = 0.0, 0.0, bound
            k += 1
    return out[:k].copy()


def _residual_lp(a, b, c, N, lo, hi, rho, act, n_root, body_weight, opts, fix=None):
    """Least weighted-L1 row residual that makes the frame feasible, over all (u, v) in the box or at
    ``fix`` = (u, v). Returns (residual per row (nv,) in N or N m, total in body-weight units)."""
    import highspy

    nv = len(a)
    cost_row = _row_costs(n_root, nv, body_weight, opts)
    K = len(act)
    cu, cv, lo_, hi_, src = _split(a, b, lo, hi, rho, np.arange(nv))
    m = len(src)
    S = np.zeros((m, nv))
    S[np.arange(m), src] = 1.0
    # columns: u, v, lam (K), s+ (nv), s- (nv); row value + s+ - s- within its bounds
    A = np.hstack([cu[:, None], cv[:, None], -N[np.ix_(src, act)], S, -S])
    col_lo = np.zeros(2 + K + 2 * nv)
    col_hi = np.full(2 + K + 2 * nv, _INF)
    if fix is None:
        col_lo[0], col_hi[0], col_hi[1] = -opts.u_max, opts.u_max, opts.v_max
    else:
        col_lo[0], col_lo[1] = fix
        col_hi[0], col_hi[1] = fix
    cost = np.concatenate((np.zeros(2 + K), cost_row, cost_row))
    h = _pooled_highs("residual")
    h.setOptionValue("simplex_strategy", 1)
    _pass_lp(h, A, col_lo, col_hi, lo_ - c[src], hi_ - c[src], cost)
    h.run()
    if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:  # slacks are free: cannot happen
        raise RetimeError("internal: the relaxation LP failed")
    x = np.asarray(h.getSolution().col_value)
    r = np.abs(x[2 + K: 2 + K + nv] - x[2 + K + nv:])
    r[r <= 1e-9 * _row_weights(n_root, nv, body_weight, opts)] = 0.0
    _LOCAL.last_point = (float(x[0]), float(x[1]))  # per thread (read by the caller)
    return r, float(np.sum(r * cost_row))


def residual_at(pd, regions, i, u, v) -> float:
    """Extra residual (body weights, weighted L1 as in the relaxation) that the timing (u, v) needs
    at frame ``i`` beyond the frame's region bounds: 0 inside the region."""
    opts = regions.options
    bw = regions.body_weight
    n_root = unactuated_rows(pd)
    a, b, c, N = (np.asarray(x[i], dtype=float) for x in (pd.a, pd.b, pd.c, pd.N))
    lo = regions.lo[i] - regions.budget[i] * v
    hi = regions.hi[i] + regions.budget[i] * v
    act = np.flatnonzero(np.any(N != 0.0, axis=0))
    if len(act) == 0:
        val = a * u + b * v + c
        r = np.abs(val - np.clip(val, lo, hi))
        return float(np.sum(r * _row_costs(n_root, len(a), bw, opts)))
    _, res = _residual_lp(a, b, c, N, lo, hi, np.zeros(len(a)), act, n_root, bw, opts, fix=(float(u), float(v)))
    return res


def _widen(lo, hi, amount, pad):
    grow = np.where(amount > 0, amount + pad, 0.0)
    return lo - grow, hi + grow


def _lp_rows(N, act, nv):
    if len(act) == 0:
        return np.zeros(0, dtype=int), np.arange(nv)
    mask = np.any(N[:, act] != 0.0, axis=1)
    return np.flatnonzero(mask), np.flatnonzero(~mask)


def _frame_lp(a, b, c, N, lo, hi, rho, act, rows, opts):
    cu, cv, lo_, hi_, src = _split(a, b, lo, hi, rho, rows)
    A = np.hstack([cu[:, None], cv[:, None], -N[np.ix_(src, act)]])
    return FrameLP(A, lo_ - c[src], hi_ - c[src], opts.u_max, opts.v_max)


def _point_ok(a, b, c, lo, hi, rows, u, v, tol):
    val = a[rows] * u + b[rows] * v + c[rows]
    return bool(np.all(val >= lo[rows] - tol) and np.all(val <= hi[rows] + tol))


def source_fit(a, b, c, N, lo, hi, opts: RegionOptions, body_weight: float, n_root: int, keep_lp=False):
    """How far the original timing (0, 1) is from feasible at one frame (original physics).

    Returns (budget (nv,) = |row residual| the captured motion needs at (0, 1), that residual in
    body-weight units, lam0 (K,) least-force contact coefficients at (0, 1) once the rows are
    widened by the budget and the pad, number of LP solves) and, with ``keep_lp``, the frame LP when
    it can serve for the region as it is (zero budget)."""
    from .forces import force_weights, solve_center

    nv, Kall = N.shape
    act = np.flatnonzero(np.any(N != 0.0, axis=0))
    rows, other = _lp_rows(N, act, nv)
    w = _row_weights(n_root, nv, body_weight, opts)
    tol = 1e-9 * body_weight
    lam0 = np.zeros(Kall)
    zero = np.zeros(nv)
    n_lp = 0
    if len(act) == 0:
        val = b + c
        r = np.abs(val - np.clip(val, lo, hi))
        r[r <= tol] = 0.0
        out = (r, float(np.sum(r * _row_costs(n_root, nv, body_weight, opts))), lam0, 0)
        return out + (None,) if keep_lp else out
    fw = force_weights(N[:3][:, act] if n_root >= 3 else N[:, act], n_root)
    if _point_ok(a, b, c, lo, hi, other, 0.0, 1.0, tol):
        lp = _frame_lp(a, b, c, N, lo, hi, zero, act, rows, opts)
        lam = solve_center(lp, 0.0, 1.0, fw)
        n_lp += lp.n_solves
        if lam is not None:
            lam0[act] = np.maximum(lam, 0.0)
            out = (zero, 0.0, lam0, n_lp)
            return out + (lp,) if keep_lp else out
    budget, res = _residual_lp(a, b, c, N, lo, hi, zero, act, n_root, body_weight, opts, fix=(0.0, 1.0))
    n_lp += 1
    lo1, hi1 = _widen(lo, hi, budget, opts.relax_pad * w)
    lp = _frame_lp(a, b, c, N, lo1, hi1, zero, act, rows, opts)
    lam = solve_center(lp, 0.0, 1.0, fw)
    n_lp += lp.n_solves
    if lam is not None:
        lam0[act] = np.maximum(lam, 0.0)
    out = (budget, res, lam0, n_lp)
    return out + (None,) if keep_lp else out


def _trace(lp, opts, x0):
    """Polygon vertices (k, 2 + n_lam) of an LP whose first solve gave x0; (X, pivots)."""
    X = None
    piv = 0
    if opts.method == "parametric":
        basic, up = lp.basis()
        zl = np.concatenate((lp.col_lo, lp.row_lo))
        zu = np.concatenate((lp.col_hi, lp.row_hi))
        if len(basic) == lp.m:
            V, Xw, status, piv = _walk(lp.A, zl, zu, basic, up, 0.5 * math.pi, 2000)
            if status == 0 and len(Xw) >= 1:
                X = Xw
    if X is None:
        X = _trace_highs(lp, opts.tol, first=x0)
    return X, piv


def _polygon(a, b, c, N, lo, hi, rho, act, rows, other, opts, Kall, eps, lp=None):
    """Clipped polygon, its lambdas, the LP (None in flight), LP solves, pivots; P is None if empty."""
    H = _halfplanes(a, b, c, lo, hi, rho, other)
    n_lp = 0
    piv = 0
    if len(act) == 0:
        lp = None
        P, L = _box_polygon(opts, Kall)
    else:
        if lp is None:
            lp = _frame_lp(a, b, c, N, lo, hi, rho, act, rows, opts)
        before = lp.n_solves
        P = L = None
        X = None
        if opts.method == "parametric" and lp.center_state is not None:
            # start from the centre LP's basis: phase 2 to "max v" and the walk, all without HiGHS
            basic, zval = lp.center_state
            zl = np.concatenate((lp.col_lo, lp.row_lo))
            zu = np.concatenate((lp.col_hi, lp.row_hi))
            zval = np.clip(zval, zl, zu)
            basic, up, st = _phase2(lp.A, zl, zu, basic.copy(), zval, 500)
            if st == 0:
                V, Xw, status, piv = _walk(lp.A, zl, zu, basic, up, 0.5 * math.pi, 2000)
                if status == 0 and len(Xw) >= 1:
                    X = Xw
        x0 = None
        if X is None:
            x0 = lp.maximize(0.0, 1.0)
            if x0 is not None:
                X, piv = _trace(lp, opts, x0)
        if X is not None:
            P = X[:, :2].copy()
            L = np.zeros((len(X), Kall))
            L[:, act] = np.maximum(X[:, 2:], 0.0)
        n_lp += lp.n_solves - before
        if P is None:
            return None, None, lp, n_lp, piv
    px, py, pl, ok = _clip_halfplanes(P[:, 0].copy(), P[:, 1].copy(), L, H, eps)
    if not ok:
        return None, None, lp, n_lp, piv
    P, L = _dedupe(np.column_stack([px, py]), pl, eps)
    if len(P) == 0:
        return None, None, lp, n_lp, piv
    return P, L, lp, n_lp, piv


def frame_region(a, b, c, N, lo, hi, opts: RegionOptions, body_weight: float, n_root: int,
                 budget=None, noise=None) -> _FrameResult:
    """The feasible polygon of one frame (see the module docstring).

    ``budget`` (nv,): row residuals the captured motion needs at this frame under the original
    physics (:func:`source_fit`); ``None`` means these coefficients *are* the original physics and the
    budget is fitted here. Row r is then bounded by ``lo - (pad + budget) p'^2 ... hi + ...``
    (``pad`` only on rows with a budget): the captured motion's inconsistency is taken to come from
    its accelerations, so it grows with p'^2."""
    from .forces import force_weights, solve_center

    a, b, c, N = (np.asarray(x, dtype=float) for x in (a, b, c, N))
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    nv, Kall = N.shape
    act = np.flatnonzero(np.any(N != 0.0, axis=0))
    rows, other = _lp_rows(N, act, nv)
    w = _row_weights(n_root, nv, body_weight, opts)
    pad = opts.relax_pad * w
    eps = 1e-9 * (opts.u_max + opts.v_max)
    n_lp = 0
    lp0 = None
    if budget is None:
        budget, src_res, lam0, k, lp0 = source_fit(a, b, c, N, lo, hi, opts, body_weight, n_root, keep_lp=True)
        n_lp += k
    else:
        budget = np.asarray(budget, dtype=float)
        src_res = float(np.sum(budget * _row_costs(n_root, nv, body_weight, opts)))
        lam0 = np.zeros(Kall)
    if not opts.relax:
        budget = np.zeros(nv)
    lo1 = lo - np.where(budget > 0, pad, 0.0)
    hi1 = hi + np.where(budget > 0, pad, 0.0)
    noisy = bool(opts.relax and noise is not None and opts.noise and np.any(np.asarray(noise) > 0))
    if noisy:
        budget = budget + np.asarray(noise, dtype=float)
        lp0 = None  # the source fit's LP has no budget rows
    P, L, lp, k, piv = _polygon(a, b, c, N, lo1, hi1, budget, act, rows, other, opts, Kall, eps, lp=lp0)
    n_lp += k
    level = 0.0
    relaxed = False
    if P is None:
        if not opts.relax:
            raise RetimeError("empty feasible region (relaxation is off)")
        extra, _ = _residual_lp(a, b, c, N, lo1, hi1, budget, act, n_root, body_weight, opts)
        n_lp += 1
        lo1, hi1 = _widen(lo1, hi1, extra, pad)
        level = float(np.max(np.where(extra > 0, (extra + pad) / w, 0.0)))
        relaxed = True
        point = _LOCAL.last_point
        P, L, lp, k, piv2 = _polygon(a, b, c, N, lo1, hi1, budget, act, rows, other, opts, Kall, eps)
        n_lp += k
        piv += piv2
        if P is None:  # numerical corner: fall back to the least-residual timing itself
            P = np.array([point])
            L = np.zeros((1, Kall))
    # fan centre (sec. 3.4): the original timing, or the nearest feasible point pulled inwards
    target = np.asarray(opts.center, dtype=float)
    q, dist = closest_point(P, target)
    center = q
    if dist > 0 and len(P) >= 3:
        center = q + 0.02 * (P.mean(axis=0) - q)
    clam = np.zeros(Kall)
    if lp is not None and (lp is lp0 or noisy) and dist == 0.0 and not relaxed and np.any(lam0 != 0):
        # the centre is the original timing: its least-force LP was solved already (with the noise
        # band too: those forces still fit the wider rows, and "match" then costs nothing there)
        clam = lam0.copy()
    elif lp is not None:
        lam_c = solve_center(lp, center[0], center[1], force_weights(N[:3][:, act] if n_root >= 3 else N[:, act], n_root))
        n_lp += 1
        if lam_c is None:  # the centre sits on a clipped edge within round-off: nearest vertex
            lam_c = _interp_on_polygon(P, L, center)[act]
        clam[act] = np.maximum(lam_c, 0.0)
    return _FrameResult(P, L, center, clam, lo1, hi1, budget, src_res, lam0, level, relaxed, dist, n_lp, piv)


def _interp_on_polygon(P, L, point):
    d = np.hypot(P[:, 0] - point[0], P[:, 1] - point[1])
    return L[int(np.argmin(d))]


# ------------------------------------------------------------------------------------------------
# All frames
# ------------------------------------------------------------------------------------------------

def unactuated_rows(pd) -> int:
    n = getattr(pd, "n_root", None)
    if n is not None:
        return int(n)
    lo, hi = np.asarray(pd.tau_lo), np.asarray(pd.tau_hi)
    free = (lo == 0) & (hi == 0)
    n = 0
    while n < len(free) and free[n]:
        n += 1
    return n


def estimate_body_weight(pd) -> float:
    """Body weight at standard gravity: total mass x 9.81 when known, else |root gravity force|."""
    m = getattr(pd, "total_mass", None) or getattr(pd, "mass", None)
    if m:
        return float(m) * STANDARD_G
    n_root = unactuated_rows(pd)
    g = getattr(pd, "gravity", None)
    if n_root >= 3:
        f = float(np.median(np.linalg.norm(np.asarray(pd.c)[:, :3], axis=1)))
        if g is not None and np.linalg.norm(g) > 0:
            f *= STANDARD_G / float(np.linalg.norm(g))
        if f > 0:
            return f
    return float(np.median(np.linalg.norm(np.asarray(pd.c), axis=1))) or 1.0


_SHARED = {}


def _work(frames):
    pd, ref, opts, bw, n_root = _SHARED["args"]
    _pool().clear()  # warm starts only within a chunk: the answer must not depend on the scheduling
    return [_one(pd, ref, i, opts, bw, n_root) for i in frames]


def base_bounds(pd, opts, bw, n_root):
    """Torque bounds with the residual allowance on the root rows: the modelling error every frame
    may use, ``allowance`` (5%) of the body's weight under the current gravity (|g| / 9.81 times
    the standard body weight) -- biomechanics accepts residual forces of a few percent of body
    weight in inverse dynamics of captured motion."""
    lo = np.asarray(pd.tau_lo, dtype=float).copy()
    hi = np.asarray(pd.tau_hi, dtype=float).copy()
    if opts.relax and opts.allowance > 0 and n_root:
        g = getattr(pd, "gravity", None)
        gscale = 1.0 if g is None else float(np.linalg.norm(g)) / STANDARD_G
        w = _row_weights(n_root, len(lo), bw, opts)[:n_root]
        lo[:n_root] -= opts.allowance * gscale * w
        hi[:n_root] += opts.allowance * gscale * w
    return lo, hi


def _bounds_cached(pd, opts, bw, n_root):
    cache = getattr(_LOCAL, "bounds", None)
    if cache is None:
        cache = _LOCAL.bounds = {}
    key = (id(pd), id(opts), bw, n_root)
    if key not in cache:
        if len(cache) > 8:
            cache.clear()
        cache[key] = (pd, base_bounds(pd, opts, bw, n_root))  # keep pd alive: ids stay unique
    return cache[key][1]


def _one(pd, ref, i, opts, bw, n_root):
    lo, hi = _bounds_cached(pd, opts, bw, n_root)
    budget = None
    n_ref = 0
    lam0 = res0 = None
    if ref is not None:
        rlo, rhi = _bounds_cached(ref, opts, bw, n_root)
        budget, res0, lam0, n_ref = source_fit(np.asarray(ref.a[i], float), np.asarray(ref.b[i], float),
                                               np.asarray(ref.c[i], float), np.asarray(ref.N[i], float),
                                               rlo, rhi, opts, bw, n_root)
    noise = getattr(pd, "b_noise", None)
    r = frame_region(pd.a[i], pd.b[i], pd.c[i], pd.N[i], lo, hi, opts, bw, n_root, budget=budget,
                     noise=None if noise is None else noise[i])
    if ref is not None:
        r.lam0, r.source_residual = lam0, res0
        r.n_lp += n_ref
    return r


class Cancelled(RetimeError):
    """The caller asked a long computation to stop (the editor's tab closed, Ctrl-C)."""


def _may_fork() -> bool:
    """A process pool by fork only from the main thread of a process with no other thread: a
    fork from a thread (the editor's solver threads, Dask workers) copies locks held elsewhere and
    the parent's signal handlers, and its pool could then hang for ever."""
    return threading.current_thread() is threading.main_thread() and threading.active_count() == 1


def _worker_signals():
    import signal

    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a pool's terminate() must end its workers
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle


def compute_regions(pd, options: RegionOptions | None = None, reference=None, frames=None,
                    progress=False, cancel=None) -> RegionSet:
    """Feasible regions and the contact-force model (centre LP) of every sample of ``pd``.

    ``reference``: the path dynamics of the *original* physics when ``pd`` has changed parameters
    (gravity, masses, ...); the frames' residual budgets and the original timing's contact forces
    (``lam0``) come from it. ``None``: ``pd`` is the original physics. ``cancel``: a function
    asked between frames; when it returns True the computation stops with :class:`Cancelled`.
    A process pool is used only from a lone main thread (:func:`_may_fork`)."""
    import time

    opts = options or RegionOptions()
    if opts.method not in ("parametric", "highs"):
        raise RetimeError(f"unknown region method {opts.method!r} (use 'parametric' or 'highs')")
    t0 = time.perf_counter()
    idx = np.arange(len(pd.times)) if frames is None else np.asarray(frames)
    n = len(idx)
    bw = float(opts.body_weight) if opts.body_weight else estimate_body_weight(reference or pd)
    n_root = unactuated_rows(pd)
    workers = opts.workers
    if workers is None:
        workers = min(2, os.cpu_count() or 1) if n >= 120 else 1
    # warm starts only within a chunk of frames, and the same chunks whether a pool runs them or
    # this thread does: the answer must not depend on the scheduling, nor on what ran before
    pooled = workers > 1 and n >= 2 * workers
    chunks = [list(ch) for ch in np.array_split(idx, 4 * workers) if len(ch)] if pooled else [list(idx)]
    results = None
    if pooled and cancel is None and _may_fork():
        import multiprocessing as mp

        try:
            ctx = mp.get_context("fork")
        except ValueError:
            ctx = None
        if ctx is not None:
            _SHARED["args"] = (pd, reference, opts, bw, n_root)
            try:
                with ctx.Pool(workers, initializer=_worker_signals) as pool:
                    parts = pool.map(_work, chunks)
                results = [r for part in parts for r in part]
            finally:
                _SHARED.clear()
    if results is None:
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=n, desc="feasible regions", unit="frame", disable=None)
        results = []
        for chunk in chunks:
            _pool().clear()
            for i in chunk:
                if cancel is not None and cancel():
                    raise Cancelled("stopped")
                results.append(_one(pd, reference, int(i), opts, bw, n_root))
                if bar is not None:
                    bar.update(1)
        if bar is not None:
            bar.close()
    K = np.asarray(pd.N).shape[2]
    offsets = np.zeros(n + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([len(r.verts) for r in results])
    contact = getattr(pd, "contact", None)
    rs = RegionSet(
        times=np.asarray(pd.times, dtype=float)[idx],
        offsets=offsets,
        verts=np.concatenate([r.verts for r in results]).reshape(-1, 2),
        lam=np.concatenate([r.lam for r in results]).reshape(int(offsets[-1]), K),
        center=np.array([r.center for r in results]).reshape(n, 2),
        center_lam=np.array([r.center_lam for r in results]).reshape(n, K),
        lo=np.array([r.lo for r in results]),
        hi=np.array([r.hi for r in results]),
        budget=np.array([r.budget for r in results]),
        source_residual=np.array([r.source_residual for r in results]),
        lam0=np.array([r.lam0 for r in results]).reshape(n, K),
        relaxation=np.array([r.relaxation for r in results]),
        relaxed=np.array([r.relaxed for r in results], dtype=bool),
        implausible=np.array([r.relaxation > opts.max_relaxation for r in results], dtype=bool),
        source_distance=np.array([r.source_distance for r in results]),
        n_lp=np.array([r.n_lp for r in results], dtype=np.int64),
        n_pivots=np.array([r.n_pivots for r in results], dtype=np.int64),
        contact=np.asarray(contact)[idx] if contact is not None else np.zeros((n, 0), bool),
        options=opts,
        body_weight=bw,
    )
    rs.seconds = time.perf_counter() - t0
    getattr(_LOCAL, "bounds", {}).clear()
    return rs
