"""The retiming curve p(t): a monotone quartic B-spline from output time to source time (sec. 3, 3.6).

    p(t) = sum_k c_k N_k(t / T),   t in [0, T],   clamped B-spline of degree q = 4 on knots in [0, 1]

**Why quartic, not the paper's cubic.** The objective samples fixed source times s, at output times
p^-1(s) that move with the coefficients. As a sample crosses a knot, the p'' it reads changes at the
rate p''' dt/dc, and a cubic's p''' jumps at every knot: the objective's gradient jumped there, and the
optimizer parked on whichever crossing the input's rounding picked (131_01, 131_03). A quartic with
simple knots is C3, so p''' and the gradient are continuous; a sample reads q + 1 = 5 coefficients
(:attr:`TimingSpline.band`: the Hessian's off-diagonals in c).

Monotonicity is built into the parameters: the optimizer works on ``w``, the control coefficients
of the derivative, a B-spline of degree q - 1 ``p'(t) = kappa * sum_k w_k M_k(t / T)``. Since B-spline
basis functions are non-negative and sum to one, ``w_k >= w_min > 0`` makes the curve strictly
increasing, with ``p' >= kappa * w_min`` everywhere. The coefficients follow by integration::

    c_0 = 0,   c_k = S * W_k / W,   W_k = sum_{i<k} w_i d_i,   W = W_{n-1},   d_i = (xi_{i+q+1} - xi_{i+1}) / q

so ``p(T) = S`` (the whole source plays) for every ``w``. With a **fixed duration** T the scale of
``w`` is free (kappa = q S / (T W)); with a **free duration** ``T = S / W`` (kappa = 1), so the
optimizer chooses the duration through the same bound-constrained variables.

The *control points* shown to a user are the B-spline's (Greville abscissa, coefficient) pairs:
``(T (xi_{k+1} + ... + xi_{k+q}) / q, c_k)``. Adding one inserts a knot (Boehm's algorithm, the
curve is unchanged); removing one drops a knot and refits by least squares.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.interpolate import BSpline

from ...errors import RetimeError

DEGREE = 4  # quartic: C3, so p''' (at which a sample's p'' changes as it crosses a knot) is continuous


class TimingSpline:
    """Knots (interior, normalized to (0, 1)), derivative coefficients ``w``, source duration ``S``
    and either a fixed duration ``T`` or ``T=None`` (free)."""

    degree = DEGREE

    @property
    def band(self) -> int:
        """Off-diagonals of the objective's Hessian in c: a sample reads c_m .. c_{m + band}."""
        return self.degree

    @property
    def support(self) -> int:
        """Coefficients one sample reads (band + 1)."""
        return self.degree + 1

    def __init__(self, interior_knots, w, source_duration, duration=None, locks=None):
        k = np.asarray(interior_knots, dtype=float).ravel()
        if np.any(np.diff(k) <= 0) or (len(k) and (k[0] <= 0 or k[-1] >= 1)):
            raise RetimeError("spline knots must increase strictly inside (0, 1)")
        self.interior = k
        self.S = float(source_duration)
        self.fixed_T = None if duration is None else float(duration)
        w = np.asarray(w, dtype=float).ravel()
        if len(w) != len(k) + self.degree:
            raise RetimeError(f"a spline with {len(k)} interior knots needs {len(k) + self.degree} derivative coefficients")
        self.w = w
        self.locks = dict(locks or {})  # control point index -> source time (exact by construction)
        self._prepare()

    # -- construction --------------------------------------------------------------------------
    @classmethod
    def uniform(cls, source_duration, n_spans, duration=None):
        """Uniform knots, constant speed S / T (the original timing when T == S)."""
        n_spans = max(1, int(n_spans))
        interior = np.arange(1, n_spans) / n_spans
        T = source_duration if duration is None else duration
        w = np.full(n_spans - 1 + cls.degree, source_duration / T)
        return cls(interior, w, source_duration, duration)

    @classmethod
    def fit(cls, interior_knots, source_duration, duration, func_t, dfunc_t=None, w_min=1e-3):
        """Least-squares fit of p' to a given speed profile (t -> ds/dt), then exact end conditions."""
        k = np.asarray(interior_knots, dtype=float)
        q = cls.degree - 1  # of p'
        xi1 = np.r_[np.zeros(q + 1), k, np.ones(q + 1)]
        tau = np.linspace(0, 1, 20 * (len(k) + q + 1))
        D = BSpline.design_matrix(tau, xi1, q)  # sparse, q + 1 nonzeros a row
        y = np.asarray(dfunc_t(tau * duration), dtype=float)
        w = banded_least_squares(D, y, q)
        w = np.maximum(w, w_min)
        return cls(k, w, source_duration, None if duration is None else duration)

    def copy(self):
        return TimingSpline(self.interior.copy(), self.w.copy(), self.S, self.fixed_T, self.locks)

    def _prepare(self):
        k, q = self.interior, self.degree
        self.xi = np.r_[np.zeros(q + 1), k, np.ones(q + 1)]
        self.n_c = len(k) + q + 1
        self.d = (self.xi[q + 1:q + self.n_c] - self.xi[1:self.n_c]) / q
        self.breaks = np.r_[0.0, k, 1.0]
        self.span_matrices = _span_matrices(self.xi, self.breaks, q)

    # -- parameters -> curve -------------------------------------------------------------------
    @property
    def free(self) -> bool:
        return self.fixed_T is None

    def pieces(self):
        """(indices, values) of the pinned coefficients: 0, the locked ones, the last."""
        idx = [0] + sorted(k for k in self.locks if 0 < k < self.n_c - 1) + [self.n_c - 1]
        val = [0.0] + [float(self.locks[k]) for k in idx[1:-1]] + [self.S]
        return idx, val

    def _pieces_arrays(self):
        idx, val = self.pieces()
        return np.asarray(idx, dtype=np.int64), np.asarray(val, dtype=float)

    def coefficients(self, w=None):
        """c from w: each piece between pinned coefficients is normalized to its pinned span."""
        w = self.w if w is None else w
        idx, val = self._pieces_arrays()
        return _coefficients(np.asarray(w, dtype=float), self.d, idx, val)

    def duration_of(self, w=None) -> float:
        w = self.w if w is None else w
        if self.fixed_T is not None:
            return self.fixed_T
        return self.S / float(np.dot(w, self.d))

    @property
    def duration(self) -> float:
        return self.duration_of()

    def chain(self, gc, gT, w=None):
        """Gradient with respect to ``w`` from gradients with respect to c and T."""
        w = self.w if w is None else w
        idx, val = self._pieces_arrays()
        return _chain(np.asarray(w, dtype=float), self.d, idx, val, np.asarray(gc, dtype=float), float(gT), self.S,
                      self.fixed_T is None)

    def gauge(self, w=None):
        """Each piece's speed scale D_j / (W_j T) is free (the curve does not depend on it); this
        sum of (W_j T / D_j - 1)^2 and its gradient pins it near 1 so that w reads as playback speed."""
        w = self.w if w is None else w
        idx, val = self._pieces_arrays()
        return _gauge(np.asarray(w, dtype=float), self.d, idx, val, self.S,
                      -1.0 if self.fixed_T is None else self.fixed_T)

    # -- evaluation ----------------------------------------------------------------------------
    def _bspline(self, w=None):
        return BSpline(self.xi, self.coefficients(w), self.degree, extrapolate=False)

    def __call__(self, t, w=None):
        T = self.duration_of(w)
        tau = np.clip(np.asarray(t, dtype=float) / T, 0.0, 1.0)
        return np.clip(self._bspline(w)(tau), 0.0, self.S)

    def speed(self, t, w=None):
        T = self.duration_of(w)
        tau = np.clip(np.asarray(t, dtype=float) / T, 0.0, 1.0)
        return self._bspline(w).derivative(1)(tau) / T

    def accel(self, t, w=None):
        T = self.duration_of(w)
        tau = np.clip(np.asarray(t, dtype=float) / T, 0.0, 1.0)
        return self._bspline(w).derivative(2)(tau) / T ** 2

    def inverse(self, s, w=None):
        """Output times at which the source times ``s`` play (Newton on the monotone curve)."""
        s = np.clip(np.asarray(s, dtype=float), 0.0, self.S)
        T = self.duration_of(w)
        tt = np.linspace(0, T, 64 * (len(self.interior) + 1) + 1)
        ss = self(tt, w)
        t = np.interp(s, ss, tt)
        for _ in range(6):
            v = self.speed(t, w)
            t = np.clip(t - (self(t, w) - s) / np.maximum(v, 1e-12), 0.0, T)
        return t

    def control_points(self, w=None):
        """(output times (Greville abscissae), source times (coefficients))."""
        T = self.duration_of(w)
        q = self.degree
        g = sum(self.xi[j:j + self.n_c] for j in range(1, q + 1)) / q
        return g * T, self.coefficients(w)

    def timing_curve(self, fps, per_frame=4):
        """A :class:`retime.warp.TimingCurve` sampling the spline densely (monotone cubic between)."""
        from ...warp import TimingCurve

        T = self.duration
        n = max(8, int(np.ceil(T * fps * per_frame)) + 1)
        grid = np.linspace(0.0, T, n)
        # the breaks where they are not a grid time already: a break a rounding error from a grid time made
        # a knot interval of 1e-17 s, across which the monotone cubic's slope is zero (false stops)
        breaks = self.breaks * T
        k = np.clip(np.searchsorted(grid, breaks), 1, n - 1)
        apart = np.minimum(breaks - grid[k - 1], grid[k] - breaks) > 1e-9 * max(T, 1.0)
        t = np.union1d(grid, breaks[apart])
        s = self(t)
        s[0], s[-1] = 0.0, self.S
        s = np.maximum.accumulate(s)
        return TimingCurve(t, s, kind="pchip")

    # -- editing -------------------------------------------------------------------------------
    def set_coefficients(self, c):
        """Set w from coefficients c (c_0 = 0, c_last = S, increasing), keeping the duration; locked
        coefficients take their values from c."""
        c = np.asarray(c, dtype=float)
        inc = np.diff(c)
        if np.any(inc <= 0):
            raise RetimeError("control points must increase in source time")
        T = self.duration
        for k in self.locks:
            self.locks[k] = float(c[k])
        self.w = inc / (self.d * T)

    def insert_knot(self, tau):
        """Boehm knot insertion at normalized time ``tau``: one more control point, same curve.
        (Locks refer to coefficient indices: the caller re-maps them, see RetimingSession.add.)"""
        tau = float(tau)
        if not (0 < tau < 1) or np.any(np.abs(self.interior - tau) < 1e-9):
            raise RetimeError(f"cannot add a control point at normalized time {tau:.6f}: outside (0, 1) or on an existing knot")
        T = self.duration
        c = self.coefficients()
        xi = self.xi
        p = self.degree
        kspan = int(np.searchsorted(xi, tau, side="right") - 1)
        newc = np.empty(len(c) + 1)
        for i in range(len(newc)):
            if i <= kspan - p:
                newc[i] = c[i]
            elif i >= kspan + 1:
                newc[i] = c[i - 1]
            else:
                a = (tau - xi[i]) / (xi[i + p] - xi[i])
                newc[i] = (1 - a) * c[i - 1] + a * c[i]
        self.interior = np.sort(np.r_[self.interior, tau])
        self._prepare()
        self.w = np.diff(newc) / (self.d * T)
        return int(np.searchsorted(self.interior, tau)) + 1

    def remove_knot(self, index, w_min=1e-3):
        """Drop interior knot ``index`` and refit the curve's speed by least squares."""
        if not (0 <= index < len(self.interior)):
            raise RetimeError(f"no interior knot {index}")
        T = self.duration
        old = self.copy()
        self.interior = np.delete(self.interior, index)
        self._prepare()
        xi1 = self.xi[1:-1]  # the knots of p', degree q - 1
        q = self.degree - 1
        tau = np.linspace(0, 1, 40 * (len(self.interior) + q + 1))
        D = BSpline.design_matrix(tau, xi1, q)  # sparse: a dense one is 40 K^2 doubles for K knots
        y = old.speed(tau * T)
        self.w = np.maximum(banded_least_squares(D, y, q), w_min)


def banded_least_squares(D, y, bandwidth=2):
    """argmin |D w - y| for a sparse design matrix whose normal matrix D^T D is banded (a B-spline
    basis of degree ``bandwidth``): Cholesky of the band, O(n) time and memory. A dense lstsq of a
    2,600-frame clip's fit took 15 s and 1.3 GB."""
    from scipy.linalg import solveh_banded

    D = D.tocsc()
    N = (D.T @ D).todia()
    n = N.shape[0]
    ab = np.zeros((bandwidth + 1, n))
    for off, diag in zip(N.offsets, N.data):
        if 0 <= off <= bandwidth:  # upper diagonals, in solveh_banded's layout
            ab[bandwidth - off, off:] = diag[off:]
    return solveh_banded(ab, D.T @ y)


@njit(cache=True)
def _coefficients(w, d, idx, val):
    n_c = len(w) + 1
    c = np.empty(n_c)
    for j in range(len(idx) - 1):
        a, b = idx[j], idx[j + 1]
        tot = 0.0
        for i in range(a, b):
            tot += w[i] * d[i]
        D = val[j + 1] - val[j]
        acc = 0.0
        c[a] = val[j]
        for i in range(a, b):
            acc += w[i] * d[i]
            c[i + 1] = val[j] + D * acc / tot
        c[b] = val[j + 1]
    return c


@njit(cache=True)
def _chain(w, d, idx, val, gc, gT, S, free):
    n = len(w)
    c = _coefficients(w, d, idx, val)
    g = np.zeros(n)
    W = 0.0
    for i in range(n):
        W += w[i] * d[i]
    for j in range(len(idx) - 1):
        a, b = idx[j], idx[j + 1]
        D = val[j + 1] - val[j]
        Wj = 0.0
        for i in range(a, b):
            Wj += w[i] * d[i]
        mean = 0.0
        for k in range(a, b + 1):
            mean += gc[k] * (c[k] - val[j]) / D
        after = 0.0
        for i in range(b - 1, a - 1, -1):
            after += gc[i + 1]
            g[i] = (D * d[i] / Wj) * (after - mean)
    if free:
        T = S / W
        for i in range(n):
            g[i] -= gT * T * d[i] / W
    return g


@njit(cache=True)
def _gauge(w, d, idx, val, S, fixed_T):
    n = len(w)
    W = 0.0
    for i in range(n):
        W += w[i] * d[i]
    free = fixed_T < 0
    T = S / W if free else fixed_T
    total = 0.0
    g = np.zeros(n)
    for j in range(len(idx) - 1):
        a, b = idx[j], idx[j + 1]
        D = val[j + 1] - val[j]
        Wj = 0.0
        for i in range(a, b):
            Wj += w[i] * d[i]
        r = Wj * T / D - 1.0
        total += r * r
        for i in range(a, b):
            g[i] += 2.0 * r * T * d[i] / D
        if free:
            for i in range(n):
                g[i] -= 2.0 * r * Wj * T * d[i] / (W * D)
    return total, g


def _span_matrices(xi, breaks, q):
    """Per span m: (q+1)x(q+1) matrix G with row r = coefficient of x^r (x = tau - breaks[m]) of the
    degree-q basis functions N_{m+l}, l = 0..q (columns)."""
    n_span = len(breaks) - 1
    n_c = len(xi) - q - 1
    out = np.zeros((n_span, q + 1, q + 1))
    ys = np.linspace(0.1, 0.9, q + 1)
    V = np.vander(ys, q + 1, increasing=True)  # in y = x / h: well conditioned
    for m in range(n_span):
        a, b = breaks[m], breaks[m + 1]
        h = b - a
        D = BSpline.design_matrix(a + h * ys, xi, q).toarray()[:, m:m + q + 1]
        out[m] = np.linalg.solve(V, D) / (h ** np.arange(q + 1))[:, None]
        if m + q + 1 > n_c:
            raise RetimeError("internal: spline span outside coefficients")
    return out
