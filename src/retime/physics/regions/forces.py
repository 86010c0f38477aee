"""Contact forces for retimed motion (McCann et al. 2006, sec. 3.4, Fig. 5).

Each vertex of a frame's feasible polygon comes with the contact force coefficients lambda the LP
found there. Inside the polygon there is a family of valid lambda; the paper anchors it with one
extra point: the **centre**, the original timing (p'', p'^2) = (0, 1) (or, when that is infeasible,
the closest feasible point pulled 2% towards the polygon's centroid), where an LP finds the lambda of
**least summed contact force**. The polygon is triangulated as a fan around the centre, and lambda at
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


def solve_center(lp, u, v, weights=None):
    """Least summed contact force at the timing (u, v) = (p'', p'^2) on a frame's LP (sec. 3.4)."""
    n_lam = lp.n - 2
    if weights is None:
        weights = getattr(lp, "force_weights", None)
    if weights is None:
        weights = np.ones(n_lam)
    return lp.solve_at(float(u), float(v), np.asarray(weights, dtype=float))


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
