"""A compiled Lawson-Hanson NNLS for the least-distance solves of a polygon's vertex forces
(:func:`.forces.regularised_least_forces`), warm-started from the previous point's passive set.

The vertices of one frame pose the same least-distance matrix E but for its last row, and their
NNLS answers share most of their passive set (16 of 17 columns on CMU 16_16): SciPy's NNLS starts
each from zero, adding the columns one by one (73 us a vertex, two thirds of the regions' time
with ``unique_vertex_forces``). Here each point starts from the last point's passive set (the
columns kept while the least-squares answer on them stays positive), then runs Lawson & Hanson's
loop (*Solving Least Squares Problems*, ch. 23) to the same optimum: its KKT conditions (z >= 0,
the gradient E^T (t - E z) <= 0 off the passive set, the least-squares answer on it) define the
residual E z - t uniquely, whatever the start. Least squares by Householder QR of the passive
columns, plain loops (no BLAS threads, no fastmath): the same bits on any thread count.
:func:`.forces.least_distance_numpy` (SciPy's NNLS per point) is the twin of the parity test.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: a column whose part outside the passive columns' span is below this (relative to its norm)
#: would make the least squares singular: it is not added (Lawson & Hanson's test, ch. 23)
INDEPENDENT = 1e-10


@njit(cache=True)
def _passive_least_squares(E, t, passive, out):
    """out = argmin |E[:, passive] s - t| (zero off the passive set) by Householder QR; False if
    the passive columns are dependent to :data:`INDEPENDENT`."""
    p, q = E.shape
    cols = np.flatnonzero(passive)
    k = len(cols)
    out[:] = 0.0
    if k == 0:
        return True
    if k > p:
        return False
    M = np.empty((p, k))
    for c in range(k):
        M[:, c] = E[:, cols[c]]
    b = t.copy()
    for c in range(k):
        norm_col = 0.0
        for r in range(p):
            norm_col += M[r, c] * M[r, c]
        below = 0.0
        for r in range(c, p):
            below += M[r, c] * M[r, c]
        if below <= (INDEPENDENT * INDEPENDENT) * norm_col or below == 0.0:
            return False
        alpha = np.sqrt(below)
        if M[c, c] > 0.0:
            alpha = -alpha
        # Householder vector v = x - alpha e_c, stored in M[c:, c]
        M[c, c] -= alpha
        vnorm2 = 0.0
        for r in range(c, p):
            vnorm2 += M[r, c] * M[r, c]
        for j in range(c + 1, k):
            d = 0.0
            for r in range(c, p):
                d += M[r, c] * M[r, j]
            f = 2.0 * d / vnorm2
            for r in range(c, p):
                M[r, j] -= f * M[r, c]
        d = 0.0
        for r in range(c, p):
            d += M[r, c] * b[r]
        f = 2.0 * d / vnorm2
        for r in range(c, p):
            b[r] -= f * M[r, c]
        M[c, c] = alpha  # R's diagonal
    for c in range(k - 1, -1, -1):
        acc = b[c]
        for j in range(c + 1, k):
            acc -= M[c, j] * out[cols[j]]
        out[cols[c]] = acc / M[c, c]
    return True


@njit(cache=True)
def _gradient(E, t, z, g):
    """g = E^T (t - E z): the NNLS objective's descent direction."""
    p, q = E.shape
    r = t.copy()
    for j in range(q):
        if z[j] != 0.0:
            for i in range(p):
                r[i] -= E[i, j] * z[j]
    for j in range(q):
        acc = 0.0
        for i in range(p):
            acc += E[i, j] * r[i]
        g[j] = acc


@njit(cache=True)
def nnls_warm(E, t, passive, maxiter):
    """argmin |E z - t| over z >= 0 (Lawson & Hanson), started from the passive set ``passive``
    (bool, q; updated in place to the answer's). Returns (z, converged)."""
    p, q = E.shape
    z = np.zeros(q)
    s = np.zeros(q)
    g = np.zeros(q)
    # the start: the least squares on the given set, dropping the columns it makes non-positive
    # (or that are dependent) until it is positive on all of them: a feasible Lawson-Hanson state
    while passive.any():
        if not _passive_least_squares(E, t, passive, s):
            passive[np.flatnonzero(passive)[-1]] = False
            continue
        bad = passive & (s <= 0.0)
        if not bad.any():
            z[:] = s
            break
        passive &= ~bad
    blocked = np.zeros(q, dtype=np.bool_)
    it = 0
    while True:
        _gradient(E, t, z, g)
        j = -1
        best = 0.0
        for c in range(q):
            if not passive[c] and not blocked[c] and g[c] > best:
                best = g[c]
                j = c
        if j < 0:
            return z, True
        passive[j] = True
        entered = True
        while True:
            it += 1
            if it > maxiter:
                return z, False
            ok = _passive_least_squares(E, t, passive, s)
            if entered and (not ok or s[j] <= 0.0):
                # j is (numerically) in the span of the passive columns, or cannot grow: skip it
                passive[j] = False
                blocked[j] = True
                break
            entered = False
            if not ok:
                return z, False
            # step from z towards s until the first passive column reaches zero; it leaves
            alpha = 2.0
            leaving = -1
            for c in range(q):
                if passive[c] and s[c] <= 0.0:
                    a = z[c] / (z[c] - s[c])
                    if a < alpha:
                        alpha = a
                        leaving = c
            if leaving < 0:
                z[:] = s
                blocked[:] = False
                break
            for c in range(q):
                if passive[c]:
                    z[c] += alpha * (s[c] - z[c])
            z[leaving] = 0.0
            for c in range(q):
                if passive[c] and z[c] <= 0.0:
                    z[c] = 0.0
                    passive[c] = False
    return z, True


@njit(cache=True)
def least_distance_residuals(E, last_rows, maxiter):
    """For each row h of ``last_rows`` (m, q): E's last row set to h, the NNLS min |E z - e_last|,
    z >= 0, each started from the previous one's passive set. Returns (residuals E z - e_last (m, p),
    converged (m,))."""
    p, q = E.shape
    m = last_rows.shape[0]
    F = E.copy()
    t = np.zeros(p)
    t[p - 1] = 1.0
    res = np.zeros((m, p))
    ok = np.zeros(m, dtype=np.bool_)
    passive = np.zeros(q, dtype=np.bool_)
    for k in range(m):
        F[p - 1, :] = last_rows[k]
        z, conv = nnls_warm(F, t, passive, maxiter)
        ok[k] = conv
        for i in range(p):
            acc = -t[i]
            for j in range(q):
                acc += F[i, j] * z[j]
            res[k, i] = acc
        if not conv:
            passive[:] = False
    return res, ok
