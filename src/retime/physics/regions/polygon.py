"""Convex polygons in the (u, v) = (p'', p'^2) plane: area, closest point and distance, clipping by
half-planes, clean-up, counter-clockwise order and the convex hull.

The feasible regions (:mod:`retime.physics.regions`), the objective (:mod:`retime.physics.timing.objective`), the fastest timing
(:mod:`retime.physics.timing.fastest`) and the region plot (:mod:`retime.viz.regions`) all measure with these.

Polygons are (k, 2) arrays in counter-clockwise order, or, for many polygons at once, flat vertex
arrays ``px``, ``py`` with ``offsets`` (polygon i is ``offsets[i]:offsets[i + 1]``). The compiled
kernels (``@njit``) have plain NumPy twins (``*_numpy``) that compute the same thing without numba:
they are the reference the parity tests compare the kernels with (``tests/test_kernel_parity.py``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...errors import RetimeError


def polygon_area(P) -> float:
    """Signed area (positive when counter-clockwise); 0 below three vertices."""
    P = np.asarray(P, dtype=float)
    if len(P) < 3:
        return 0.0
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


# ------------------------------------------------------------------------------------------------
# Closest point and distance
# ------------------------------------------------------------------------------------------------

def closest_point(P, point):
    """Closest point of the convex polygon P (CCW, possibly degenerate) to ``point``; (q, distance)."""
    P = np.ascontiguousarray(P, dtype=float).reshape(-1, 2)
    if len(P) == 0:
        raise RetimeError("empty polygon")
    qx, qy, d = closest_point_kernel(P, float(point[0]), float(point[1]))
    return np.array([qx, qy]), d


def polygon_distance(P, point) -> float:
    """Euclidean distance from ``point`` to the convex polygon P (0 inside)."""
    return closest_point(P, point)[1]


@njit(cache=True)
def closest_point_kernel(P, x, y):
    """(qx, qy, distance) of the point of the convex polygon P (CCW) closest to (x, y)."""
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


def closest_points_numpy(P, points, inside_tol=0.0):
    """NumPy twin of :func:`closest_point_kernel` for many points and one polygon: (q (N, 2),
    distance (N,)). ``inside_tol``: a point within this cross product of every edge counts as inside."""
    P = np.asarray(P, dtype=float).reshape(-1, 2)
    X = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(P) == 0:
        raise RetimeError("empty polygon")
    A = P
    E = np.roll(P, -1, axis=0) - P
    W = X[:, None, :] - A[None, :, :]
    ee = (E ** 2).sum(-1)
    t = np.where(ee > 0.0, np.clip((W * E[None]).sum(-1) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0), 0.0)
    C = A[None] + t[..., None] * E[None]
    d = np.hypot(C[..., 0] - X[:, None, 0], C[..., 1] - X[:, None, 1])
    k = np.argmin(d, axis=1)  # the first of the nearest edges, as the kernel's strict scan
    rows = np.arange(len(X))
    q, dist = C[rows, k], d[rows, k]
    if len(P) >= 3:
        cross = E[None, :, 0] * W[..., 1] - E[None, :, 1] * W[..., 0]
        inside = np.all(cross >= -inside_tol, axis=1)
        q[inside], dist[inside] = X[inside], 0.0
    return q, dist


@njit(cache=True)
def polygon_distances(verts, offsets, frames, u, v, out):
    """out[k] = distance of (u[k], v[k]) to polygon ``frames[k]`` of the flat ``verts``/``offsets``."""
    for k in range(frames.shape[0]):
        i = frames[k]
        out[k] = closest_point_kernel(verts[offsets[i]:offsets[i + 1]], u[k], v[k])[2]


@njit(cache=True, inline="always")
def boundary_closest(p0, p1, px, py, u, v):
    """Closest point to (u, v) on the boundary of the flat polygon ``p0:p1`` (a point or a segment
    has no interior, so no inside test); nearest by squared distance."""
    nv = p1 - p0
    if nv == 1:
        return px[p0], py[p0]
    bd = 1e300
    qx, qy = px[p0], py[p0]
    for k in range(nv):
        ax, ay = px[p0 + k], py[p0 + k]
        j = p0 + (k + 1) % nv
        ex, ey = px[j] - ax, py[j] - ay
        ee = ex * ex + ey * ey
        t = 0.0
        if ee > 0:
            t = ((u - ax) * ex + (v - ay) * ey) / ee
            t = min(1.0, max(0.0, t))
        cx, cy = ax + t * ex, ay + t * ey
        d = (cx - u) ** 2 + (cy - v) ** 2
        if d < bd:
            bd = d
            qx, qy = cx, cy
    return qx, qy


@njit(cache=True, inline="always")
def edge_projection(p0, nv, e, px, py, u, v):
    """Closest point of edge e of the flat polygon at p0 (nv vertices) to (u, v), and the unclamped
    edge parameter."""
    f = e + 1 if e + 1 < nv else 0
    ax, ay = px[p0 + e], py[p0 + e]
    ex, ey = px[p0 + f] - ax, py[p0 + f] - ay
    ee = ex * ex + ey * ey
    t = ((u - ax) * ex + (v - ay) * ey) / ee if ee > 0 else 0.0
    tc = min(1.0, max(0.0, t))
    return ax + tc * ex, ay + tc * ey, t


# ------------------------------------------------------------------------------------------------
# Clipping by half-planes
# ------------------------------------------------------------------------------------------------

@njit(cache=True)
def clip_halfplanes(px, py, plam, H, tol):
    """Clip a convex polygon (CCW) by half-planes H[k] = (a, b, c): a u + b v <= c (rows normalized
    so that hypot(a, b) = 1; rows with a = b = 0 are feasibility checks on c). The per-vertex data
    ``plam`` (k, K) of new vertices (the regions' contact coefficients) is interpolated along the
    clipped edge. Returns (px, py, plam, ok)."""
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


def clip_halfplanes_numpy(px, py, plam, H, tol):
    """NumPy twin of :func:`clip_halfplanes` (one half-plane at a time, whole polygon at once)."""
    px, py, plam = (np.asarray(x, dtype=float) for x in (px, py, plam))
    for a, b, c in np.asarray(H, dtype=float).reshape(-1, 3):
        if a == 0.0 and b == 0.0:
            if c < -tol:
                return px[:0], py[:0], plam[:0], False
            continue
        if len(px) == 0:
            return px, py, plam, False
        s = a * px + b * py - c
        keep = s <= tol
        if keep.all():
            continue
        if not keep.any():
            return px[:0], py[:0], plam[:0], False
        j = np.roll(np.arange(len(px)), -1)
        cut = keep != keep[j]
        t = np.where(cut, s / np.where(cut, s - s[j], 1.0), 0.0)
        # per vertex: itself when kept, then the crossing on its outgoing edge when that edge is cut
        X = np.stack([px, px + t * (px[j] - px)], 1)
        Y = np.stack([py, py + t * (py[j] - py)], 1)
        L = np.stack([plam, plam + t[:, None] * (plam[j] - plam)], 1)
        take = np.stack([keep, cut], 1).ravel()
        px, py = X.ravel()[take], Y.ravel()[take]
        plam = L.reshape(-1, plam.shape[1])[take]
    return px, py, plam, True


# ------------------------------------------------------------------------------------------------
# Clean-up, order, hull
# ------------------------------------------------------------------------------------------------

def dedupe(P, L, eps):
    """Drop consecutive (cyclic) duplicate vertices and collinear middle points of P, and the same
    rows of the per-vertex data L."""
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


def ccw_order(P):
    """Indices that put the points of a convex polygon in counter-clockwise order around their mean."""
    c = P.mean(axis=0)
    ang = np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0])
    return np.argsort(ang, kind="stable")


def convex_hull(points) -> np.ndarray:
    """The convex hull of the points, counter-clockwise (Andrew's monotone chain); fewer than three
    distinct points come back as they are (sorted)."""
    pts = np.unique(np.asarray(points, dtype=np.float64).reshape(-1, 2), axis=0)
    if len(pts) < 3:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])
