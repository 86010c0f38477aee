"""The HiGHS backend of the feasible regions: HiGHS objects, warm-start bases, and one frame's LP.

Everything that talks to ``highspy`` is here, including its private raw binding ``highspy._core``
(no Python callbacks on every iteration, and ``passModel`` from raw arrays).

HiGHS objects are not thread-safe, so they are never shared: a :class:`HighsPool` belongs to one
computation (a chunk of frames of :func:`retime.physics.regions.compute_regions`, or one call of
:func:`retime.physics.regions.frame_region.residual_at`) and is handed down explicitly.
"""
from __future__ import annotations

import numpy as np

from .simplex import INF


class HighsPool:
    """HiGHS objects by kind (``"frame"``, ``"residual"``), reused frame after frame (``passModel``
    replaces the model), and the last optimal basis per LP shape, offered to the next frame of the
    same shape as a warm start. Owned by one thread."""

    def __init__(self):
        self._highs = {}
        self._bases = {}

    def highs(self, kind):
        h = self._highs.get(kind)
        if h is None:
            h = self._highs[kind] = new_highs()
        return h

    def basis(self, shape):
        return self._bases.get(shape)

    def keep_basis(self, shape, basis):
        self._bases[shape] = basis


def new_highs():
    """A quiet single-threaded primal-simplex HiGHS object (the raw binding)."""
    from highspy import _core

    h = _core._Highs()  # the raw binding: no Python callbacks on every iteration
    h.setOptionValue("output_flag", False)
    h.setOptionValue("presolve", "off")
    h.setOptionValue("solver", "simplex")
    h.setOptionValue("threads", 1)
    h.setOptionValue("simplex_strategy", 4)  # primal: the basis stays feasible when the cost turns
    return h


def _colwise(A):
    """A (m, n) dense matrix in HiGHS's column-wise form: (start, index, value)."""
    At = np.asarray(A, dtype=float).T
    nz = At != 0.0
    start = np.concatenate(([0], np.cumsum(nz.sum(axis=1)))).astype(np.int32)
    return start, np.nonzero(nz)[1].astype(np.int32), np.ascontiguousarray(At[nz])


def _highs_lp(A, col_lo, col_hi, row_lo, row_hi, cost=None):
    import highspy

    m, n = A.shape
    lp = highspy.HighsLp()
    lp.num_col_ = n
    lp.num_row_ = m
    lp.col_cost_ = np.zeros(n) if cost is None else np.asarray(cost, dtype=float)
    lp.col_lower_ = np.where(col_lo <= -INF * 0.5, -highspy.kHighsInf, col_lo)
    lp.col_upper_ = np.where(col_hi >= INF * 0.5, highspy.kHighsInf, col_hi)
    lp.row_lower_ = np.where(row_lo <= -INF * 0.5, -highspy.kHighsInf, row_lo)
    lp.row_upper_ = np.where(row_hi >= INF * 0.5, highspy.kHighsInf, row_hi)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
    lp.a_matrix_.start_, lp.a_matrix_.index_, lp.a_matrix_.value_ = _colwise(A)
    lp.a_matrix_.num_col_ = n
    lp.a_matrix_.num_row_ = m
    return lp


def pass_lp(h, A, col_lo, col_hi, row_lo, row_hi, cost=None):
    """passModel from raw arrays (a quarter of the time of building a HighsLp object)."""
    import highspy

    m, n = A.shape
    start, index, value = _colwise(A)
    # HiGHS reads any bound beyond 1e20 as infinite, so the 1e30 used here passes as it is
    st = h.passModel(n, m, len(value), 1, 1, 0.0, np.zeros(n) if cost is None else np.asarray(cost, dtype=float),
                     col_lo, col_hi, row_lo, row_hi, start, index, value, np.zeros(n, dtype=np.int32))
    if st == highspy.HighsStatus.kError:  # fall back to the model object
        h.passModel(_highs_lp(A, col_lo, col_hi, row_lo, row_hi, cost))


def solve_dual_simplex(h, A, col_lo, col_hi, row_lo, row_hi, cost):
    """Minimize cost . x over the LP with the dual simplex on HiGHS object ``h``; x or None."""
    import highspy

    h.setOptionValue("simplex_strategy", 1)
    pass_lp(h, A, col_lo, col_hi, row_lo, row_hi, cost)
    h.run()
    if h.getModelStatus() != highspy.HighsModelStatus.kOptimal:
        return None
    return np.asarray(h.getSolution().col_value)


class FrameLP:
    """One frame's LP in (u, v, lam_active): a HiGHS model kept for the frame; only costs (and, for
    the centre point, the (u, v) bounds) change between solves. ``center_state`` is the basis and
    values of the last :meth:`solve_at`, the start of the compiled walk (:mod:`.simplex`)."""

    def __init__(self, A, row_lo, row_hi, u_max, v_max, pool: HighsPool):
        import highspy

        self.A = np.ascontiguousarray(A, dtype=float)
        m, n = A.shape
        self.m, self.n = m, n
        self.col_lo = np.zeros(n)
        self.col_lo[0] = -u_max
        self.col_hi = np.full(n, INF)
        self.col_hi[0], self.col_hi[1] = u_max, v_max
        self.row_lo = np.asarray(row_lo, dtype=float)
        self.row_hi = np.asarray(row_hi, dtype=float)
        self.pool = pool
        self.h = pool.highs("frame")
        pass_lp(self.h, self.A, self.col_lo, self.col_hi, self.row_lo, self.row_hi)
        prev = pool.basis((m, n))
        if prev is not None:
            self.h.setBasis(prev)
        self.n_solves = 0
        self.center_state = None
        self._idx2 = np.array([0, 1], dtype=np.int32)
        self._kOptimal = highspy.HighsModelStatus.kOptimal

    def bounds(self):
        """(lower, upper) bounds of z = (columns, rows), as the simplex kernels take them."""
        return np.concatenate((self.col_lo, self.row_lo)), np.concatenate((self.col_hi, self.row_hi))

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
        self.pool.keep_basis((self.m, self.n), self.h.getBasis())
        return np.asarray(self.h.getSolution().col_value)

    def basis(self):
        """The optimal basis as (basic indices over (cols, rows), at-upper flags of the nonbasic)."""
        _, bv = self.h.getBasicVariables()
        bv = np.asarray(bv, dtype=np.int64)
        basic = np.where(bv >= 0, bv, self.n - bv - 1)
        sol = self.h.getSolution()
        z = np.concatenate((np.asarray(sol.col_value), np.asarray(sol.row_value)))
        zl, zu = self.bounds()
        up = (z >= zu - 1e-9 * (1.0 + np.abs(zu))) & (zu > zl) & (zu < INF * 0.5)
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
            self.pool.keep_basis((self.m, self.n), h.getBasis())
            basic, _ = self.basis()
            if len(basic) == self.m:
                self.center_state = (basic, np.concatenate((x, np.asarray(sol.row_value))))
        h.changeColsBounds(2, self._idx2, self.col_lo[:2], self.col_hi[:2])
        h.changeColsCost(n, np.arange(n, dtype=np.int32), np.zeros(n))
        return None if x is None else x[2:]
