"""A compiled Lawson-Hanson NNLS for the least-distance solves of a polygon's vertex forces
(:func:`.forces.regularised_least_forces`), warm-started from the previous point's passive set.

The vertices of one frame pose the same least-distance matrix E but for its last row, and their
NNLS answers share most of their passive set (16 of 17 columns on CMU 16_16): SciPy's NNLS starts
each from zero, adding the columns one by one (73 us a vertex, two thirds of the regions' time
with ``unique_vertex_forces``). Here each point starts from the last point's passive set (the
columns kept while the least-squares answer on them stays positive), then runs Lawson & Hanson's
loop (*Solving Least Squares Problems*, ch. 23) to the same optimum: its KKT conditions (z >= 0,
the gradient E^T (t - E z) <= 0 off the passive set, the least-squares answer on it) define the
residual E z - t uniquely, whatever the start. Least squares by a Householder QR of the passive
columns that grows by one reflector per added column (refactored when one leaves), plain loops (no BLAS threads, no fastmath): the same bits on any thread count.
:func:`.forces.least_distance_numpy` (SciPy's NNLS per point) is the twin of the parity test.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: a column whose part outside the passive columns' span is below this (relative to its norm)
#: would make the least squares singular: it is not added (Lawson & Hanson's test, ch. 23)
INDEPENDENT = 1e-10


@njit(cache=True)
def _add_column(E, j, cols, k, V, vnorm2, R, qtb):
    """Append column ``j`` of E to the Householder QR of the ``k`` passive columns ``cols[:k]``
    (reflectors in V's columns, R upper, qtb = Q^T t): its part outside their span becomes one
    more reflector, O(p k) instead of a new factorisation. False (nothing changed) if that part is
    below :data:`INDEPENDENT` of the column."""
    p = E.shape[0]
    if k >= p:
        return False
    x = E[:, j].copy()
    norm2 = 0.0
    for r in range(p):
        norm2 += x[r] * x[r]
    for c in range(k):
        d = 0.0
        for r in range(c, p):
            d += V[r, c] * x[r]
        f = 2.0 * d / vnorm2[c]
        for r in range(c, p):
            x[r] -= f * V[r, c]
    below = 0.0
    for r in range(k, p):
        below += x[r] * x[r]
    if below == 0.0 or below <= (INDEPENDENT * INDEPENDENT) * norm2:
        return False
    alpha = -np.sqrt(below) if x[k] > 0.0 else np.sqrt(below)
    for r in range(k):
        R[r, k] = x[r]
    R[k, k] = alpha
    for r in range(k):
        V[r, k] = 0.0
    x[k] -= alpha
    v2 = 0.0
    for r in range(k, p):
        V[r, k] = x[r]
        v2 += x[r] * x[r]
    vnorm2[k] = v2
    _reflect(V, vnorm2, k, qtb)
    cols[k] = j
    return True


@njit(cache=True)
def _reflect(V, vnorm2, c, y):
    """y <- H_c y, the c-th Householder reflection (its own inverse)."""
    p = V.shape[0]
    d = 0.0
    for r in range(c, p):
        d += V[r, c] * y[r]
    f = 2.0 * d / vnorm2[c]
    for r in range(c, p):
        y[r] -= f * V[r, c]


@njit(cache=True)
def _refactor(E, t, passive, cols, V, vnorm2, R, qtb):
    """The QR of the passive columns afresh, in column order; a column dependent on the ones
    before it leaves the passive set. Returns their number k."""
    qtb[:] = t
    k = 0
    for j in range(E.shape[1]):
        if passive[j]:
            if _add_column(E, j, cols, k, V, vnorm2, R, qtb):
                k += 1
            else:
                passive[j] = False
    return k


@njit(cache=True)
def _solve(cols, k, R, qtb, out):
    """out = the least squares on the passive columns (R s = Q^T t), zero elsewhere."""
    out[:] = 0.0
    for c in range(k - 1, -1, -1):
        acc = qtb[c]
        for j in range(c + 1, k):
            acc -= R[c, j] * out[cols[j]]
        out[cols[c]] = acc / R[c, c]


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
    cols = np.zeros(p, dtype=np.int64)
    V = np.zeros((p, p))
    vnorm2 = np.ones(p)
    R = np.zeros((p, p))
    qtb = np.zeros(p)
    # the start: the least squares on the given set, dropping the columns it makes non-positive
    # (or that are dependent) until it is positive on all of them: a feasible Lawson-Hanson state
    k = _refactor(E, t, passive, cols, V, vnorm2, R, qtb)
    while k > 0:
        _solve(cols, k, R, qtb, s)
        bad = passive & (s <= 0.0)
        if not bad.any():
            z[:] = s
            break
        passive &= ~bad
        k = _refactor(E, t, passive, cols, V, vnorm2, R, qtb)
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
        it += 1
        if it > maxiter:
            return z, False
        if not _add_column(E, j, cols, k, V, vnorm2, R, qtb):
            blocked[j] = True  # (numerically) in the passive columns' span
            continue
        _solve(cols, k + 1, R, qtb, s)
        if s[j] <= 0.0:  # it cannot grow: undo its reflection, skip it
            _reflect(V, vnorm2, k, qtb)
            blocked[j] = True
            continue
        passive[j] = True
        k += 1
        while True:
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
            it += 1
            if it > maxiter:
                return z, False
            for c in range(q):
                if passive[c]:
                    z[c] += alpha * (s[c] - z[c])
            z[leaving] = 0.0
            for c in range(q):
                if passive[c] and z[c] <= 0.0:
                    z[c] = 0.0
                    passive[c] = False
            k = _refactor(E, t, passive, cols, V, vnorm2, R, qtb)
            _solve(cols, k, R, qtb, s)


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
