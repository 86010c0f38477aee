"""The compiled primal simplex that traces a frame's feasible region (McCann et al. 2006, sec. 3.3).

A frame's LP has columns x = (u, v, lam) with bounds and rows A x within bounds; with the row
activities s = A x as variables too, every constraint is a bound on z = (x, s) and A x - s = 0. Its
feasible region is the projection of that polytope onto (u, v) = (x0, x1).

* :func:`phase2`: from a feasible basis (HiGHS's, for the frame's centre LP) a bounded primal simplex
  to the vertex of largest v, so that the walk starts at a proper vertex;
* :func:`walk`: the parametric (shadow-vertex) simplex: the cost direction (cos theta, sin theta) is
  rotated through 360 degrees and the basis pivots exactly where it stops being optimal; every
  non-degenerate pivot lands on the next vertex of the projection, so the polygon is exact (to
  floating point).

Both keep B^-1 dense (m is a few dozen rows) with eta updates and a refactorization every 25 pivots
or on a small pivot. :func:`phase2_numpy` and :func:`walk_numpy` are plain NumPy twins (B^-1 solved
afresh at every step), the reference of ``tests/test_kernel_parity.py``.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

INF = 1e30  # a bound at or beyond INF / 2 is no bound


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
            if zu[j] >= INF * 0.5:
                continue
            t = (zu[j] - z[j]) / al
            tu = True
        else:
            if zl[j] <= -INF * 0.5:
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
def phase2(A, zl, zu, basic, zval, max_iter):
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
        if tmax >= INF * 0.5:
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
def walk(A, zl, zu, basic, atupper, theta0, max_iter):
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
        if tmax >= INF * 0.5:
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
# NumPy twins (reference for the parity tests; B^-1 is never kept, every step solves with B)
# ------------------------------------------------------------------------------------------------

def _ratio_test_numpy(col, dirn, basic, z, zl, zu, tmax):
    """Twin of :func:`_ratio_test`."""
    leave, leave_up, bestpiv = -1, False, 0.0
    for r, j in enumerate(basic):
        al = -dirn * col[r]
        if abs(al) <= 1e-11:
            continue
        if al > 0.0:
            if zu[j] >= INF * 0.5:
                continue
            t, tu = (zu[j] - z[j]) / al, True
        else:
            if zl[j] <= -INF * 0.5:
                continue
            t, tu = (zl[j] - z[j]) / al, False
        t = max(t, 0.0)
        tie = abs(t - tmax) <= 1e-12 * (1.0 + tmax)
        if t < tmax - 1e-12 * (1.0 + tmax) or (tie and abs(al) > bestpiv):
            tmax, leave, leave_up, bestpiv = t, r, tu, abs(al)
    return tmax, leave, leave_up


def _basic_values(M, basic, z):
    """z with its basic entries solved from M z = 0 for the nonbasic ones as they are."""
    nb = np.ones(M.shape[1], dtype=bool)
    nb[basic] = False
    z = z.copy()
    z[basic] = np.linalg.solve(M[:, basic], -(M[:, nb] @ z[nb]))
    return z


def _dual(M, basic, j):
    """y with y_r = -(B^-1)[row of basic variable j, r] (zero when j is not basic)."""
    B = M[:, basic]
    where = np.flatnonzero(basic == j)
    if len(where) == 0:
        return np.zeros(len(basic))
    e = np.zeros(len(basic))
    e[where[0]] = 1.0
    return -np.linalg.solve(B.T, e)


def phase2_numpy(A, zl, zu, basic, zval, max_iter):
    """Twin of :func:`phase2`: (basic, at_upper, status)."""
    A = np.asarray(A, dtype=float)
    m, n = A.shape
    nt = n + m
    M = np.hstack([A, -np.eye(m)])
    basic = np.array(basic, dtype=np.int64)
    z = np.array(zval, dtype=float)
    status = 1
    for _ in range(max_iter):
        z = _basic_values(M, basic, z)
        isbasic = np.zeros(nt, dtype=bool)
        isbasic[basic] = True
        cost = np.zeros(nt)
        cost[1] = -1.0
        d = cost - _dual(M, basic, 1) @ M
        jin, best, dirn = -1, 1e-9, 0.0
        for j in range(nt):
            if isbasic[j] or zu[j] - zl[j] <= 0.0:
                continue
            if d[j] < -best and not z[j] >= zu[j]:
                best, jin, dirn = -d[j], j, 1.0
            elif d[j] > best and not z[j] <= zl[j]:
                best, jin, dirn = d[j], j, -1.0
        if jin < 0:
            interior = [j for j in range(nt) if not isbasic[j] and zl[j] < z[j] < zu[j]]
            if not interior:
                status = 0
                break
            jin, dirn = interior[0], 1.0
        col = np.linalg.solve(M[:, basic], M[:, jin])
        tmax, leave, leave_up = _ratio_test_numpy(col, dirn, basic, z, zl, zu,
                                                  (zu[jin] - z[jin]) if dirn > 0 else (z[jin] - zl[jin]))
        if tmax >= INF * 0.5:
            status = 2
            break
        z[jin] += dirn * tmax
        if leave < 0:
            z[jin] = zu[jin] if dirn > 0 else zl[jin]
            continue
        jout = basic[leave]
        z[jout] = zu[jout] if leave_up else zl[jout]
        basic[leave] = jin
    isbasic = np.zeros(nt, dtype=bool)
    isbasic[basic] = True
    up = ~isbasic & (zu > zl) & (z >= zu)
    return basic, up, status


def walk_numpy(A, zl, zu, basic, atupper, theta0, max_iter):
    """Twin of :func:`walk`: (verts (k, 2), xs (k, n), status, pivots)."""
    A = np.asarray(A, dtype=float)
    m, n = A.shape
    nt = n + m
    M = np.hstack([A, -np.eye(m)])
    basic = np.array(basic, dtype=np.int64)
    up = np.array(atupper, dtype=bool)
    out_v, out_x = [], []
    theta, end = theta0, theta0 + 2.0 * math.pi
    status = it = 0
    c1 = np.zeros(nt)
    c1[0] = -1.0
    c2 = np.zeros(nt)
    c2[1] = -1.0
    while True:
        isbasic = np.zeros(nt, dtype=bool)
        isbasic[basic] = True
        z = np.where(up, zu, zl)
        z = _basic_values(M, basic, np.where(isbasic, 0.0, z))
        if not out_v or abs(z[0] - out_v[-1][0]) + abs(z[1] - out_v[-1][1]) > 1e-12 * (1.0 + abs(z[0]) + abs(z[1])):
            out_v.append(z[:2].copy())
            out_x.append(z[:n].copy())
        if it >= max_iter:
            status = 1
            break
        it += 1
        # reduced costs of the costs -x0 and -x1; the one of direction theta is their rotation
        d1 = c1 - _dual(M, basic, 0) @ M
        d2 = c2 - _dual(M, basic, 1) @ M
        sg = np.where(up, -1.0, 1.0)
        ct, st = math.cos(theta), math.sin(theta)
        Ag = sg * (d1 * ct + d2 * st)
        Bg = sg * (-d1 * st + d2 * ct)
        best, jin = 1e300, -1
        for j in range(nt):
            if isbasic[j] or zu[j] - zl[j] <= 0.0:
                continue
            R = math.hypot(Ag[j], Bg[j])
            if R <= 1e-12:
                continue
            if Ag[j] <= 1e-10 * R and Bg[j] < 0.0:
                delta = 0.0  # already out of optimality: pivot now
            else:
                delta = (math.atan2(Bg[j], Ag[j]) + 0.5 * math.pi) % (2.0 * math.pi)
            if delta < best - 1e-13:
                best, jin = delta, j
        if jin < 0 or theta + best >= end:
            break
        theta += best
        dirn = -1.0 if up[jin] else 1.0
        col = np.linalg.solve(M[:, basic], M[:, jin])
        tmax, leave, leave_up = _ratio_test_numpy(col, dirn, basic, z, zl, zu, zu[jin] - zl[jin])
        if tmax >= INF * 0.5:
            status = 2
            break
        if leave < 0:
            up[jin] = not up[jin]
            continue
        jout = basic[leave]
        basic[leave] = jin
        up[jout] = leave_up
        up[jin] = False
    return np.array(out_v).reshape(-1, 2), np.array(out_x).reshape(-1, n), status, it
