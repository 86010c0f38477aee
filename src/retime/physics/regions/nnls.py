"""A compiled Lawson-Hanson NNLS for the least-distance solves of a polygon's vertex forces
(:func:`.forces.regularised_least_forces`), warm-started from the previous point's answer.

The vertices of one frame pose the same least-distance matrix E but for its last row, and their
NNLS answers share most of their passive set (16 of 17 columns on CMU 16_16): SciPy's NNLS starts
each from zero, adding the columns one by one (73 us a vertex, two thirds of the regions' time
with ``unique_vertex_forces``). Here each point starts from the last point's answer (any z >= 0
is feasible: Lawson & Hanson's inner loop descends from it to the least squares on a passive set),
then runs their outer loop (*Solving Least Squares Problems*, ch. 23) to the same optimum: its KKT conditions (z >= 0,
the gradient E^T (t - E z) <= 0 off the passive set, the least-squares answer on it) define the
residual E z - t uniquely, whatever the start. Least squares by a Householder QR of the passive
columns that grows by one reflector per added column (when one leaves, the reflectors before it
are kept and the later columns added again), plain loops
(no BLAS threads, no fastmath): the same bits on any thread count.
:func:`.forces.least_distance_numpy` (SciPy's NNLS per point) is the twin of the parity test.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: a column whose part outside the passive columns' span is below this (relative to its norm)
#: would make the least squares singular: it is not added (Lawson & Hanson's test, ch. 23)
INDEPENDENT = 1e-10


@njit(cache=True)
def _add_column(ET, j, cols, k, V, vnorm2, R, qtb):
    """Append column ``j`` of E (row ``j`` of ET) to the Householder QR of the ``k`` passive columns ``cols[:k]``
    (reflectors in V's columns, R upper, qtb = Q^T t): its part outside their span becomes one
    more reflector, O(p k) instead of a new factorisation. False (nothing changed) if that part is
    below :data:`INDEPENDENT` of the column."""
    p = ET.shape[1]
    if k >= p:
        return False
    x = ET[j].copy()
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
def _refactor(ET, t, passive, cols, V, vnorm2, R, qtb):
    """The QR of the passive columns afresh, in column order. Returns their number k."""
    qtb[:] = t
    return _append_passive(ET, np.arange(ET.shape[0]), passive, cols, V, vnorm2, R, qtb, 0)


@njit(cache=True)
def _drop_left(ET, t, passive, cols, V, vnorm2, R, qtb, k):
    """The QR after columns left the passive set: the reflectors before the first one that left
    stay, the passive columns after it are added again. Returns their number."""
    first = 0
    while first < k and passive[cols[first]]:
        first += 1
    later = cols[first + 1:k].copy()
    qtb[:] = t
    for c in range(first):
        _reflect(V, vnorm2, c, qtb)
    return _append_passive(ET, later, passive, cols, V, vnorm2, R, qtb, first)


@njit(cache=True)
def _append_passive(ET, candidates, passive, cols, V, vnorm2, R, qtb, k):
    """Add the passive ones of ``candidates`` to the QR of k columns; one dependent on the columns
    before it leaves the passive set. Returns the new number of columns."""
    for j in candidates:
        if passive[j]:
            if _add_column(ET, j, cols, k, V, vnorm2, R, qtb):
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
def _gradient(ET, t, z, passive, r, g):
    """g = E^T (t - E z) off the passive set (the columns that may enter; ``r`` is work space)."""
    q, p = ET.shape
    r[:] = t
    for j in range(q):
        if z[j] != 0.0:
            for i in range(p):
                r[i] -= ET[j, i] * z[j]
    for j in range(q):
        acc = 0.0
        if not passive[j]:
            for i in range(p):
                acc += ET[j, i] * r[i]
        g[j] = acc


@njit(cache=True)
def nnls_warm(E, t, passive, maxiter):
    """argmin |E z - t| over z >= 0 (Lawson & Hanson), started from the passive set ``passive``
    (bool, q; updated in place to the answer's) at z = 0. Returns (z, converged)."""
    p, q = E.shape
    z = np.zeros(q)
    conv = _nnls_columns(np.ascontiguousarray(E.T), t, passive, maxiter, z, _work(p, q))
    return z, conv


@njit(cache=True)
def _work(p, q):
    """Work space of :func:`_nnls_columns` for E of shape (p, q)."""
    return (np.zeros(q), np.zeros(q), np.zeros(p), np.zeros(p, dtype=np.int64), np.zeros((p, p)),
            np.ones(p), np.zeros((p, p)), np.zeros(p), np.zeros(q, dtype=np.bool_))


@njit(cache=True)
def _nnls_columns(ET, t, passive, maxiter, z, work):
    """:func:`nnls_warm` on ``ET`` = E^T (q, p), in the given work space, from the point ``z``
    (>= 0, positive on the passive set; the answer replaces it); converged?"""
    s, g, r, cols, V, vnorm2, R, qtb, blocked = work
    q = ET.shape[0]
    k = _refactor(ET, t, passive, cols, V, vnorm2, R, qtb)
    for c in range(q):
        if not passive[c]:
            z[c] = 0.0
    # any z >= 0 is feasible: descend from the start to the least squares on a passive set
    _solve(cols, k, R, qtb, s)
    k = _descend(ET, t, passive, z, s, cols, V, vnorm2, R, qtb, k)
    blocked[:] = False
    for it in range(maxiter):
        _gradient(ET, t, z, passive, r, g)
        j = -1
        best = 0.0
        for c in range(q):
            if not passive[c] and not blocked[c] and g[c] > best:
                best = g[c]
                j = c
        if j < 0:
            return True
        if not _add_column(ET, j, cols, k, V, vnorm2, R, qtb):
            blocked[j] = True  # (numerically) in the passive columns' span
            continue
        _solve(cols, k + 1, R, qtb, s)
        if s[j] <= 0.0:  # it cannot grow: undo its reflection, skip it
            _reflect(V, vnorm2, k, qtb)
            blocked[j] = True
            continue
        passive[j] = True
        k = _descend(ET, t, passive, z, s, cols, V, vnorm2, R, qtb, k + 1)
        blocked[:] = False
    return False


@njit(cache=True)
def _descend(ET, t, passive, z, s, cols, V, vnorm2, R, qtb, k):
    """Lawson & Hanson's inner loop: from z (positive on the passive set) towards the least squares
    ``s`` on it, as far as z stays >= 0; the column reaching zero leaves, and again, until s > 0 on
    the passive set; z = s then. Returns the number of passive columns."""
    q = ET.shape[0]
    while True:
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
            return k
        for c in range(q):
            if passive[c]:
                z[c] += alpha * (s[c] - z[c])
        z[leaving] = 0.0
        for c in range(q):
            if passive[c] and z[c] <= 0.0:
                z[c] = 0.0
                passive[c] = False
        k = _drop_left(ET, t, passive, cols, V, vnorm2, R, qtb, k)
        _solve(cols, k, R, qtb, s)


@njit(cache=True)
def least_distance_residuals(E, last_rows, maxiter):
    """For each row h of ``last_rows`` (m, q): E's last row set to h, the NNLS min |E z - e_last|,
    z >= 0, each started from the previous one's passive set. Returns (residuals E z - e_last (m, p),
    converged (m,))."""
    p, q = E.shape
    m = last_rows.shape[0]
    ET = np.ascontiguousarray(E.T)
    t = np.zeros(p)
    t[p - 1] = 1.0
    res = np.zeros((m, p))
    ok = np.zeros(m, dtype=np.bool_)
    passive = np.zeros(q, dtype=np.bool_)
    z = np.zeros(q)
    work = _work(p, q)
    for k in range(m):
        ET[:, p - 1] = last_rows[k]
        ok[k] = _nnls_columns(ET, t, passive, maxiter, z, work)
        for i in range(p):
            acc = -t[i]
            for j in range(q):
                acc += ET[j, i] * z[j]
            res[k, i] = acc
        if not ok[k]:  # the next point starts afresh
            passive[:] = False
            z[:] = 0.0
    return res, ok
