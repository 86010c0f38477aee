"""Unit quaternions as (..., 4) arrays in SciPy's scalar-last order (x, y, z, w), vectorized."""
import numpy as np


def qmul(a, b):
    """Hamilton product a*b (rotation b first, then a)."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def qconj(q):
    return q * np.array([-1.0, -1.0, -1.0, 1.0])


def qrot(q, v):
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4)."""
    u = q[..., :3]
    w = q[..., 3:4]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def axis_quat(axis: int, angle):
    """Rotations by ``angle`` (radians, any shape) about coordinate axis 0, 1 or 2 (x, y, z)."""
    angle = np.asarray(angle, dtype=float)
    q = np.zeros(angle.shape + (4,))
    q[..., axis] = np.sin(0.5 * angle)
    q[..., 3] = np.cos(0.5 * angle)
    return q


def euler_to_quat(seq: str, angles, degrees=False):
    """Euler angles (..., len(seq)) -> quaternions (..., 4), with SciPy's ``from_euler`` meaning:
    upper-case ``seq`` = intrinsic axes (rotating frame), lower-case = extrinsic (fixed axes), the first
    axis in ``seq`` applied first. Vectorized with plain NumPy (SciPy's Rotation is slow per call)."""
    angles = np.asarray(angles, dtype=float)
    if degrees:
        angles = np.deg2rad(angles)
    intrinsic = seq.isupper()
    q = None
    for k, ax in enumerate(seq.lower()):
        qk = axis_quat("xyz".index(ax), angles[..., k])
        q = qk if q is None else (qmul(q, qk) if intrinsic else qmul(qk, q))
    if q is None:
        q = np.zeros(angles.shape[:-1] + (4,))
        q[..., 3] = 1.0
    return q


def quat_to_matrix(q):
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    x, y, z, w = np.moveaxis(np.asarray(q, dtype=float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], axis=-1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], axis=-1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def quat_to_euler(seq: str, q, degrees=False):
    """Intrinsic Tait-Bryan angles (..., 3) for three distinct upper-case axes, e.g. "ZXY":
    R = R_a(angle0) R_b(angle1) R_c(angle2). The middle angle lies in [-90, 90] degrees; at gimbal lock
    the last angle is set to 0 (the rotation is still reproduced exactly)."""
    if len(seq) != 3 or len(set(seq.upper())) != 3 or not seq.isupper():
        raise ValueError(f"quat_to_euler needs three distinct intrinsic axes, got {seq!r}")
    i, j, k = ("XYZ".index(c) for c in seq)
    sign = 1.0 if (j - i) % 3 == 1 else -1.0  # even (cyclic) or odd permutation of XYZ
    m = quat_to_matrix(q)
    cos_b = np.hypot(m[..., i, i], m[..., i, j])
    beta = np.arctan2(sign * m[..., i, k], cos_b)
    alpha = np.arctan2(-sign * m[..., j, k], m[..., k, k])
    gamma = np.arctan2(-sign * m[..., i, j], m[..., i, i])
    lock = cos_b < 1e-9
    if np.any(lock):
        alpha = np.where(lock, np.arctan2(sign * m[..., k, j], m[..., j, j]), alpha)
        gamma = np.where(lock, 0.0, gamma)
    out = np.stack([alpha, beta, gamma], axis=-1)
    return np.rad2deg(out) if degrees else out


def slerp(q0, q1, w):
    """Spherical linear interpolation, vectorized; w broadcasts against q0[..., 0].

    Takes the shorter arc (q and -q are the same rotation), as SciPy's Slerp does.
    """
    w = np.asarray(w, dtype=float)
    dot = np.einsum("...i,...i->...", q0, q1)
    sign = np.where(dot < 0.0, -1.0, 1.0)
    dot = np.minimum(np.abs(dot), 1.0)
    theta = np.arccos(dot)
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-8  # (nearly) the same rotation: linear interpolation is exact enough
    inv = np.divide(1.0, sin_theta, out=np.zeros_like(sin_theta), where=~small)
    k0 = np.where(small, 1.0 - w, np.sin((1.0 - w) * theta) * inv)
    k1 = np.where(small, w, np.sin(w * theta) * inv) * sign
    out = q0 * k0[..., None]
    out += q1 * k1[..., None]
    out /= np.sqrt(np.einsum("...i,...i->...", out, out))[..., None]
    return out


def continuous(q, axis=0):
    """Flip signs along ``axis`` so consecutive quaternions lie in the same hemisphere."""
    q = np.array(q, dtype=float, copy=True)
    q = np.moveaxis(q, axis, 0)
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    q[1:] *= flips[..., None]
    return np.moveaxis(q, 0, axis)
