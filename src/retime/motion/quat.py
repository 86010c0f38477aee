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


def qnormalize(q):
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def slerp(q0, q1, w):
    """Spherical linear interpolation, vectorized; w broadcasts against q0[..., 0].

    Takes the shorter arc (q and -q are the same rotation), as SciPy's Slerp does.
    """
    w = np.asarray(w, dtype=float)[..., None]
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    small = sin_theta < 1e-8
    safe = np.where(small, 1.0, sin_theta)
    k0 = np.where(small, 1.0 - w, np.sin((1.0 - w) * theta) / safe)
    k1 = np.where(small, w, np.sin(w * theta) / safe)
    return qnormalize(k0 * q0 + k1 * q1)


def continuous(q, axis=0):
    """Flip signs along ``axis`` so consecutive quaternions lie in the same hemisphere."""
    q = np.array(q, dtype=float, copy=True)
    q = np.moveaxis(q, axis, 0)
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.cumprod(np.where(dots < 0, -1.0, 1.0), axis=0)
    q[1:] *= flips[..., None]
    return np.moveaxis(q, 0, axis)
