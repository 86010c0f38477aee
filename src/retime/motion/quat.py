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


def qnormalize(q):
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


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
