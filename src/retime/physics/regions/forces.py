"""Contact forces for retimed motion (McCann et al. 2006, sec. 3.4, Fig. 5).

Each vertex of a frame's feasible polygon comes with contact force coefficients lambda valid there
(the regularised least force at the vertex, :func:`unique_vertex_forces`: the walk's own lambda is
one corner of a face of valid ones). Inside the polygon there is a family of valid lambda; the paper anchors it with one
extra point: the **centre**, the original timing (p'', p'^2) = (0, 1) (or, when that is infeasible,
the closest feasible point pulled 2% towards the polygon's centroid), where the lambda of **least summed
contact force** is found (made unique by a small quadratic term, :func:`regularised_least_force`: the
plain LP's optimum is a whole face, and the vertex it returned moved with the input's float rounding,
by up to half the body weight on CMU 13_11). The polygon is triangulated as a fan around the centre, and lambda at
any (p'', p'^2) is interpolated barycentrically in its triangle. The constraints of Eq. 13 are
linear, so an interpolated lambda is valid wherever the point is inside the polygon; outside it the
same affine map of the fan wedge extends the model (the objective's feasibility term then dominates).

Summed force: the friction-cone basis forces are weighted by their magnitude, read from the root's
force rows of N (for a free-floating root they are the force itself in the root frame), so the cost is
the sum of the contact forces' magnitudes. Without a floating root every basis force costs 1.
"""
from __future__ import annotations

import numpy as np


def force_weights(N_act, n_root):
    """Magnitude of each basis force (columns of N restricted to the active ones)."""
    if n_root >= 3:
        w = np.linalg.norm(N_act[:3], axis=0)
        w = np.where(w > 1e-12, w, 1.0)
        return w
    return np.ones(N_act.shape[1])


def solve_center(lp, u, v, weights, spread, walk_start=False):
    """Contact force coefficients of least summed force at the timing (u, v) = (p'', p'^2) on a
    frame's LP (sec. 3.4), made unique (:func:`regularised_least_force`, ``spread`` in newtons).
    ``walk_start``: also solve the plain LP first, whose basis starts the polygon's walk
    (``lp.center_state``). None if (u, v) is infeasible."""
    weights = np.asarray(weights, dtype=float)
    lam = None
    if walk_start:
        lam = lp.solve_at(float(u), float(v), weights)
        if lam is None:
            return None
    A = lp.A[:, 2:]
    shift = lp.A[:, 0] * float(u) + lp.A[:, 1] * float(v)
    unique = regularised_least_force(A, lp.row_lo - shift, lp.row_hi - shift, weights, spread)
    if unique is not None:
        return unique
    # infeasible, or NNLS stopped short (numerical trouble): the plain LP decides
    return lam if walk_start else lp.solve_at(float(u), float(v), weights)


#: how far (in units of the force spread, i.e. body weights) a vertex's rows are widened for its
#: unique forces: a vertex lies on the region's boundary, where the rows leave the forces no
#: interior and the least-distance solve fails on round-off (with 1e-9 no vertex failed, but a
#: vertex's forces still moved by 0.11 body weights on AV_8Walk's float32 copy: the thin slab's
#: shape follows the vertex's own round-off). The forces hold their rows to twice this (the slack,
#: and the solve's own check).
VERTEX_SLACK = 1e-6


def unique_vertex_forces(lp, P, L, act, weights, spread):
    """The polygon's vertex forces ``L`` (k, K) made unique: at each vertex (u, v) of ``P`` the
    regularised least force (:func:`regularised_least_force`) on the frame's LP rows, on the active
    columns ``act``. The walk's own lambda at a vertex is one corner of a face of equally good
    forces, and which corner it reaches depends on its pivots' ties: a float32 copy of a clip moved
    vertex forces by up to a quarter of the body weight, and the torque coefficients baked from them
    by more than their own size (16_33). The rows are widened by :data:`VERTEX_SLACK` body weights
    (a vertex sits on them, see there) plus what the walk's own lambda misses them by (a vertex
    clipped or merged within the polygon's tolerance can sit that far outside), so that the walk's
    lambda is feasible and the solve has room; a vertex where it still gives up keeps that lambda."""
    out = np.array(L, dtype=float, copy=True)
    A = lp.A[:, 2:]
    P = np.asarray(P, dtype=float)
    shift = P @ lp.A[:, :2].T  # (k, rows)
    lo, hi = lp.row_lo[None] - shift, lp.row_hi[None] - shift
    walked = out[:, act] @ A.T
    missed = np.maximum(np.max(np.where(np.isfinite(lo), lo - walked, 0.0), axis=1, initial=0.0),
                        np.max(np.where(np.isfinite(hi), walked - hi, 0.0), axis=1, initial=0.0))
    slack = (VERTEX_SLACK * float(spread) + missed)[:, None]
    # NNLS's answer on a thin vertex misses the rows by ~1e-9 body weights: checked to the slack
    for k, lam in enumerate(regularised_least_forces(A, lo - slack, hi + slack, weights, spread, tol=VERTEX_SLACK)):
        if lam is not None:
            out[k] = 0.0
            out[k, act] = np.maximum(lam, 0.0)
    return out


def regularised_least_force(A, lo, hi, weights, spread, tol=1e-9):
    """The unique lam >= 0 with lo <= A lam <= hi that minimizes, with f_k = weights_k lam_k the
    force on basis k (newtons),

        sum f_k + sum f_k^2 / (2 spread);

    None if there is none (to ``tol`` times ``spread``). The plain least-force LP has whole faces of
    optima (a vertical load can lean on any pair of opposite friction-cone edges, two feet can share it in any ratio), and which
    vertex it returns jumps with the float noise of the input; the quadratic term makes the
    minimizer unique and Lipschitz in the data (a change of the per-newton cost by e moves the
    forces by at most ``spread`` e).

    Solved as a least-distance problem (Lawson & Hanson, *Solving Least Squares Problems*, ch. 23):
    in units of ``spread``, y = w x + 1 turns the objective into |y|^2 / 2 + const, and the LDP
    min |y| s.t. G y >= h is the NNLS min |E z - e_last|, z >= 0, with E = [G^T; h^T]. SciPy's NNLS
    is robust on the degenerate rows where HiGHS's active-set QP stops with a solve error."""
    E, last = _least_distance_problem(A, np.asarray(lo, dtype=float)[None], np.asarray(hi, dtype=float)[None],
                                      weights, spread)
    residual, converged = least_distance_numpy(E, last)
    return _forces_from_residuals(residual, converged, A, np.asarray(lo, dtype=float)[None],
                                  np.asarray(hi, dtype=float)[None], weights, spread, tol)[0]


def regularised_least_forces(A, lo, hi, weights, spread, tol=1e-9):
    """:func:`regularised_least_force` for each row of ``lo`` and ``hi`` (m, rows), which must be
    finite on the same rows: one least-distance matrix, each point's NNLS started from the previous
    point's passive set (:func:`.nnls.least_distance_residuals`, compiled; the same minimiser as
    SciPy's, :func:`least_distance_numpy`, a fifth of the time on a polygon's vertices)."""
    from .nnls import least_distance_residuals

    E, last = _least_distance_problem(A, lo, hi, weights, spread)
    residual, converged = least_distance_residuals(np.ascontiguousarray(E), last, 50 * E.shape[1])
    return _forces_from_residuals(residual, converged, A, lo, hi, weights, spread, tol)


def _least_distance_problem(A, lo, hi, weights, spread):
    """The least-distance NNLS of :func:`regularised_least_force` for each row of ``lo``/``hi``:
    (E with a placeholder last row, the last rows (m, q)): min |E z - e_last|, z >= 0."""
    w = np.asarray(weights, dtype=float)
    s = float(spread)
    A = np.asarray(A, dtype=float)
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    n = len(w)
    has_lo, has_hi = lo[0] > -1e20, hi[0] < 1e20
    if np.any((lo > -1e20) != has_lo) or np.any((hi < 1e20) != has_hi):
        raise ValueError("the bounds must be finite on the same rows for every point")
    Ar = A / w  # x = (y - 1) / w in units of spread
    A1 = Ar.sum(axis=1)
    G = np.vstack([np.diag(1.0 / w), Ar[has_lo], -Ar[has_hi]])
    E = np.vstack([G.T, np.zeros((1, G.shape[0]))])
    last = np.hstack([np.broadcast_to(1.0 / w, (len(lo), n)), lo[:, has_lo] / s + A1[has_lo],
                      -hi[:, has_hi] / s - A1[has_hi]])
    return E, np.ascontiguousarray(last)


def least_distance_numpy(E, last):
    """SciPy's NNLS for each last row (from zero): the twin of :func:`.nnls.least_distance_residuals`
    (residuals E z - e_last (m, p), converged (m,))."""
    from scipy.optimize import nnls

    p = E.shape[0]
    target = np.zeros(p)
    target[-1] = 1.0
    F = E.copy(order="K")  # E's own layout (Fortran, as built): the products' summation order
    residual = np.zeros((len(last), p))
    converged = np.zeros(len(last), dtype=bool)
    for k, row in enumerate(last):
        F[-1] = row
        try:
            z, _ = nnls(F, target, maxiter=50 * F.shape[1])
        except RuntimeError:  # iteration limit
            continue
        residual[k] = F @ z - target
        converged[k] = True
    return residual, converged


def _forces_from_residuals(residual, converged, A, lo, hi, weights, spread, tol):
    """Each point's forces from its least-distance residual r = E z - e_last (see
    :func:`regularised_least_force`); None when the rows are incompatible (r_last = 0), NNLS stopped
    at its limit, or the answer misses a row by more than ``tol`` times ``spread``."""
    w = np.asarray(weights, dtype=float)
    s = float(spread)
    n = len(w)
    r_last = residual[:, -1:]
    # e_last in the cone of E's columns (r_last = 0): the rows are incompatible
    good = np.asarray(converged, dtype=bool) & (np.abs(r_last[:, 0]) > 1e-12)
    lam = s * (-residual[:, :n] / np.where(good[:, None], r_last, 1.0) - 1.0) / w
    Al = lam @ np.asarray(A, dtype=float).T
    good &= ~(np.any(lam < -tol * s, axis=1) | np.any(Al < np.asarray(lo) - tol * s, axis=1)
              | np.any(Al > np.asarray(hi) + tol * s, axis=1))
    return [lam[k] if good[k] else None for k in range(len(lam))]


class FanModel:
    """Barycentric contact model of one frame: centre C, polygon V (CCW), lambda at each."""

    def __init__(self, verts, lam, center, center_lam):
        self.V = np.asarray(verts, dtype=float)
        self.L = np.asarray(lam, dtype=float)
        self.C = np.asarray(center, dtype=float)
        self.LC = np.asarray(center_lam, dtype=float)
        self.degenerate = len(self.V) < 3 or _area(self.V) <= 1e-12 * (1.0 + np.abs(self.V).max() ** 2)
        if not self.degenerate:
            R = self.V - self.C
            cross = R[:, 0] * np.roll(R[:, 1], -1) - R[:, 1] * np.roll(R[:, 0], -1)
            if np.any(cross <= 0):  # centre not strictly inside: fall back to a constant model
                self.degenerate = True

    def wedge(self, point):
        """Index k of the fan wedge (C, V_k, V_k+1) containing ``point`` (-1 if degenerate)."""
        if self.degenerate:
            return -1
        p = np.asarray(point, dtype=float) - self.C
        R = self.V - self.C
        Rn = np.roll(R, -1, axis=0)
        c1 = R[:, 0] * p[1] - R[:, 1] * p[0]
        c2 = p[0] * Rn[:, 1] - p[1] * Rn[:, 0]
        ok = np.flatnonzero((c1 >= 0) & (c2 > 0))
        if len(ok) == 0:
            ok = np.flatnonzero((c1 >= -1e-12) & (c2 >= -1e-12))
        return int(ok[0]) if len(ok) else 0

    def affine(self, k):
        """lambda = L0 + Lu u + Lv v on wedge k (arrays of length K)."""
        if k < 0:
            z = np.zeros_like(self.LC)
            return self.LC.copy(), z, z.copy()
        n = len(self.V)
        Vk, Vl = self.V[k], self.V[(k + 1) % n]
        Mi = np.linalg.inv(np.column_stack([Vk - self.C, Vl - self.C]))
        dk = self.L[k] - self.LC
        dl = self.L[(k + 1) % n] - self.LC
        Lu = Mi[0, 0] * dk + Mi[1, 0] * dl
        Lv = Mi[0, 1] * dk + Mi[1, 1] * dl
        L0 = self.LC - self.C[0] * Lu - self.C[1] * Lv
        return L0, Lu, Lv

    def lam(self, point):
        """Interpolated lambda at ``point`` = (p'', p'^2)."""
        k = self.wedge(point)
        L0, Lu, Lv = self.affine(k)
        return L0 + Lu * point[0] + Lv * point[1]

    def barycentric(self, point):
        """(k, weights for (C, V_k, V_k+1))."""
        k = self.wedge(point)
        if k < 0:
            return k, np.array([1.0, 0.0, 0.0])
        n = len(self.V)
        M = np.column_stack([self.V[k] - self.C, self.V[(k + 1) % n] - self.C])
        bk = np.linalg.solve(M, np.asarray(point, dtype=float) - self.C)
        return k, np.array([1.0 - bk.sum(), bk[0], bk[1]])


def _area(P):
    x, y = P[:, 0], P[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def fan_model(regions, i) -> FanModel:
    return FanModel(regions.polygon(i), regions.polygon_lam(i), regions.center[i], regions.center_lam[i])


def contact_lambda(regions, i, point):
    """Contact force coefficients of frame ``i`` at the timing ``point`` = (p'', p'^2)."""
    return fan_model(regions, i).lam(point)


def torques(pd, regions, i, point):
    """Joint torques (all rows) of frame ``i`` at ``point`` = (p'', p'^2) with the fan contact model."""
    lam = contact_lambda(regions, i, point)
    u, v = float(point[0]), float(point[1])
    return pd.a[i] * u + pd.b[i] * v + pd.c[i] - pd.N[i] @ lam


def original_torques(pd, regions):
    """Torques of the original timing: at (0, 1) with the centre's least-force contact (n, nv).

    When (0, 1) is feasible the centre *is* (0, 1); otherwise the contact forces are those of the
    nearest feasible timing (the centre), and the inertial terms still those of the original speed."""
    lam = regions.center_lam
    return np.asarray(pd.b) + np.asarray(pd.c) - pd.N.forces(lam)
