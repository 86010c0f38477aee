"""The motion as a smooth path q(s) on the configuration manifold, with its tangent derivatives.

The source frames are joined by one C2 curve: each joint's quaternion components (made sign
continuous) and the root position are optionally low-pass filtered (a Gaussian of ``smoothing``
seconds, with odd reflection at the ends so a constant velocity passes unchanged) and then
interpolated by a not-a-knot cubic spline through the frames (compiled, for thousands of joints); the curve's rotation is the normalized
quaternion. Derivatives are exact derivatives of that curve (no finite differences), in the
tangent space used by Pinocchio and :mod:`retime.physics.model.tree`:

* ball joint: body angular velocity w = 2 Im(conj(Q) Q') / |Q|^2 and its derivative
  w' = (2 Im(conj(Q) Q'') - 2 (Q . Q') w) / |Q|^2 (the rate of the same body-frame vector);
* free root: (R^T p', w) and (R^T p'' - w x R^T p', w').

Smoothing only shapes the path used for dynamics; the output motion keeps the original poses.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ...errors import RetimeError
from ...motion.feet import MIN_FRAMES, lowpass
from ...motion.quat import continuous
from .tree import FIXED, FREE


@dataclass
class PathSamples:
    """Configurations and tangent derivatives at source times (SI units)."""

    times: np.ndarray  # (n,) seconds
    root_pos: np.ndarray  # (n, 3) world position of the root joint
    quats: np.ndarray  # (n, nb, 4) local rotations (x, y, z, w), unit
    qd: np.ndarray  # (n, nv) dq/ds
    qdd: np.ndarray  # (n, nv) d2q/ds2


def sample_times(n_frames: int, fps: float, samples_per_frame: int = 1) -> np.ndarray:
    """Source times of the samples: every frame and ``samples_per_frame - 1`` points between frames."""
    spf = int(samples_per_frame)
    if spf < 1:
        raise RetimeError(f"samples per frame must be at least 1, got {samples_per_frame}")
    return np.arange((n_frames - 1) * spf + 1) / (fps * spf)


@njit(cache=True)
def _spline_moments(Y, h):
    """Second derivatives (F, D) at the knots of the not-a-knot cubic spline through Y (F, D) at
    uniform spacing h (F >= 4). For uniform knots not-a-knot gives 6 M_1 = r_1 and
    6 M_{F-2} = r_{F-2} directly, then a (1, 4, 1) tridiagonal system for the rest (Thomas
    algorithm, all channels at once)."""
    F, D = Y.shape
    M = np.zeros((F, D))
    k = 6.0 / (h * h)
    for i in range(1, F - 1):  # right-hand sides, kept in M for now
        for d in range(D):
            M[i, d] = k * (Y[i - 1, d] - 2.0 * Y[i, d] + Y[i + 1, d])
    for d in range(D):
        M[1, d] /= 6.0
        M[F - 2, d] /= 6.0
    m = F - 4  # interior unknowns M_2 .. M_{F-3}
    if m > 0:
        cp = np.empty(m)
        denom = np.empty(m)
        cp[0] = 0.25
        denom[0] = 4.0
        for j in range(1, m):
            denom[j] = 4.0 - cp[j - 1]
            cp[j] = 1.0 / denom[j]
        for d in range(D):
            M[2, d] -= M[1, d]
            M[F - 3, d] -= M[F - 2, d]
        for j in range(m):  # forward sweep: M[j+2] <- d'_j
            i = j + 2
            for d in range(D):
                prev = M[i - 1, d] if j > 0 else 0.0
                M[i, d] = (M[i, d] - prev) / denom[j]
        for j in range(m - 2, -1, -1):  # back substitution
            i = j + 2
            for d in range(D):
                M[i, d] -= cp[j] * M[i + 1, d]
    for d in range(D):
        M[0, d] = 2.0 * M[1, d] - M[2, d]
        M[F - 1, d] = 2.0 * M[F - 2, d] - M[F - 3, d]
    return M


@njit(cache=True)
def _spline_eval(Y, M, h, s, X0, X1, X2):
    """Value, first and second derivative at times s (n,) of the spline (knots at 0, h, 2h, ...)."""
    F, D = Y.shape
    for q in range(len(s)):
        i = min(max(int(np.floor(s[q] / h)), 0), F - 2)
        u = s[q] - i * h  # time since knot i
        v = h - u  # time to knot i+1
        # X0 = ca M_i + cb M_i+1 + v/h y_i + u/h y_i+1, and so on
        ca0 = (v * v * v / h - h * v) / 6.0
        cb0 = (u * u * u / h - h * u) / 6.0
        ya0 = v / h
        yb0 = u / h
        ca1 = -v * v / (2 * h) + h / 6.0
        cb1 = u * u / (2 * h) - h / 6.0
        ca2 = v / h
        cb2 = u / h
        for d in range(D):
            a, b = M[i, d], M[i + 1, d]
            ya, yb = Y[i, d], Y[i + 1, d]
            X0[q, d] = ca0 * a + cb0 * b + ya0 * ya + yb0 * yb
            X1[q, d] = ca1 * a + cb1 * b + (yb - ya) / h
            X2[q, d] = ca2 * a + cb2 * b


@njit(cache=True)
def _tangents(X0, X1, X2, jtype, vidx, quats, qd, qdd):
    """Unit quaternions and tangent-space q', q'' from spline values of [root position, quaternion
    components of every joint] (see the module docstring)."""
    n = X0.shape[0]
    nb = jtype.shape[0]
    w = np.empty(3)
    dw = np.empty(3)
    for i in range(n):
        for j in range(nb):
            o = 3 + 4 * j
            qx, qy, qz, qw = X0[i, o], X0[i, o + 1], X0[i, o + 2], X0[i, o + 3]
            dx, dy, dz, dd = X1[i, o], X1[i, o + 1], X1[i, o + 2], X1[i, o + 3]
            ex, ey, ez, ee = X2[i, o], X2[i, o + 1], X2[i, o + 2], X2[i, o + 3]
            n2 = qx * qx + qy * qy + qz * qz + qw * qw
            nrm = np.sqrt(n2)
            quats[i, j, 0] = qx / nrm
            quats[i, j, 1] = qy / nrm
            quats[i, j, 2] = qz / nrm
            quats[i, j, 3] = qw / nrm
            t = jtype[j]
            if t == FIXED:
                continue
            # Im(conj(Q) P) = qw pv - pw qv - qv x pv
            w[0] = 2.0 * (qw * dx - dd * qx - (qy * dz - qz * dy)) / n2
            w[1] = 2.0 * (qw * dy - dd * qy - (qz * dx - qx * dz)) / n2
            w[2] = 2.0 * (qw * dz - dd * qz - (qx * dy - qy * dx)) / n2
            qdot = 2.0 * (qx * dx + qy * dy + qz * dz + qw * dd) / n2
            dw[0] = 2.0 * (qw * ex - ee * qx - (qy * ez - qz * ey)) / n2 - qdot * w[0]
            dw[1] = 2.0 * (qw * ey - ee * qy - (qz * ex - qx * ez)) / n2 - qdot * w[1]
            dw[2] = 2.0 * (qw * ez - ee * qz - (qx * ey - qy * ex)) / n2 - qdot * w[2]
            k = vidx[j]
            if t == FREE:
                # R^T p' and R^T p'' - w x R^T p' with R from the unit quaternion
                x, y, z, ww = quats[i, j, 0], quats[i, j, 1], quats[i, j, 2], quats[i, j, 3]
                R00 = 1 - 2 * (y * y + z * z)
                R01 = 2 * (x * y - ww * z)
                R02 = 2 * (x * z + ww * y)
                R10 = 2 * (x * y + ww * z)
                R11 = 1 - 2 * (x * x + z * z)
                R12 = 2 * (y * z - ww * x)
                R20 = 2 * (x * z - ww * y)
                R21 = 2 * (y * z + ww * x)
                R22 = 1 - 2 * (x * x + y * y)
                p1x, p1y, p1z = X1[i, 0], X1[i, 1], X1[i, 2]
                p2x, p2y, p2z = X2[i, 0], X2[i, 1], X2[i, 2]
                vx = R00 * p1x + R10 * p1y + R20 * p1z
                vy = R01 * p1x + R11 * p1y + R21 * p1z
                vz = R02 * p1x + R12 * p1y + R22 * p1z
                ax = R00 * p2x + R10 * p2y + R20 * p2z - (w[1] * vz - w[2] * vy)
                ay = R01 * p2x + R11 * p2y + R21 * p2z - (w[2] * vx - w[0] * vz)
                az = R02 * p2x + R12 * p2y + R22 * p2z - (w[0] * vy - w[1] * vx)
                qd[i, k], qd[i, k + 1], qd[i, k + 2] = vx, vy, vz
                qdd[i, k], qdd[i, k + 1], qdd[i, k + 2] = ax, ay, az
                k += 3
            for a in range(3):
                qd[i, k + a] = w[a]
                qdd[i, k + a] = dw[a]


def path_samples(fps, root_pos, quats, jtype, vidx, nv, times=None, smoothing=0.0) -> PathSamples:
    """Sample the smooth path through frames (root_pos (F, 3) or None, quats (F, nb, 4)) at ``times``
    (default: the frames), for a tree with joint types ``jtype`` and velocity offsets ``vidx``."""
    quats = np.asarray(quats, dtype=float)
    F, nb = quats.shape[:2]
    if F < MIN_FRAMES:
        raise RetimeError(f"physics needs at least {MIN_FRAMES} frames, the motion has {F}")
    times = np.arange(F) / fps if times is None else np.asarray(times, dtype=float)
    root_pos = np.zeros((F, 3)) if root_pos is None else np.asarray(root_pos, dtype=float)
    X = np.concatenate([root_pos, continuous(quats).reshape(F, nb * 4)], axis=1)
    X = np.ascontiguousarray(lowpass(X, smoothing * fps))
    h = 1.0 / fps
    M = _spline_moments(X, h)
    n = len(times)
    X0, X1, X2 = (np.empty((n, X.shape[1])) for _ in range(3))
    _spline_eval(X, M, h, times, X0, X1, X2)
    q = np.empty((n, nb, 4))
    qd = np.zeros((n, nv))
    qdd = np.zeros((n, nv))
    _tangents(X0, X1, X2, np.asarray(jtype, dtype=np.int64), np.asarray(vidx, dtype=np.int64), q, qd, qdd)
    return PathSamples(times=times, root_pos=X0[:, :3], quats=q, qd=qd, qdd=qdd)
