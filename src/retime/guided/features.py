"""Feature vectors of guided time warping (Hsu et al. 2007, section 3.2).

A pose is the vector of joint positions in the root (torso) coordinate frame,
in metres, prefiltered with a uniform (box) low-pass filter. A candidate
output frame is a triple of input frames ``(i, j, k)`` that play at three
consecutive output instants, one output step ``h = 1/fps`` apart. Its feature
vector is::

    y(i, j, k) = [ w_p * x_j,
                   w_v * (x_k - x_i) / (2 h),          # velocity, m/s
                   w_a * (x_k - 2 x_j + x_i) / h**2 ]   # acceleration, m/s^2

and a reference frame ``r`` (with its neighbours ``r - 1`` and ``r + 1``,
played at the same rate) gets the same vector from ``(r-1, r, r+1)``.

Weights (:class:`FeatureWeights`): ``pose`` is dimensionless, ``velocity`` is
a time in seconds and ``acceleration`` a time squared, so that all three
blocks are lengths in metres. The defaults (1, 0.1 s, 0.01 s^2) count a
velocity error of 1 m/s like a pose error of 10 cm and an acceleration error
of 10 m/s^2 (about g) like a pose error of 10 cm.

``root_height`` adds one coordinate to the pose: the root's height above the
floor (world y), times that weight. The torso-frame positions of the paper
cannot see the body's own ballistic arc (a tucked pose held through the air
barely changes in the torso frame), so without it a warp may skip through the
middle of a flight; the height is invariant to where the character stands and
which way it faces, as the rest of the feature is. ``root_height=0`` gives the
paper's features exactly.

Because ``y`` is linear in ``x_i, x_j, x_k``, every distance between a triple
feature and a reference feature can be assembled from dot products of single
frames (see :mod:`retime.guided.score`); nothing here ever has to build the
``3 * D`` dimensional triple vectors except for checks and the approximate
(KD-tree) search.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from retime.errors import RetimeError
from retime.motion import Motion, forward_kinematics


@dataclass(frozen=True)
class FeatureWeights:
    """How pose, velocity and acceleration are weighted in the feature vector.

    ``pose``: weight of joint positions (dimensionless).
    ``velocity``: seconds; multiplies velocities in m/s.
    ``acceleration``: seconds squared; multiplies accelerations in m/s^2.
    ``root_height``: weight of the root's height as an extra pose coordinate (0: the paper's
    torso-frame positions only).
    """

    pose: float = 1.0
    velocity: float = 0.1
    acceleration: float = 0.01
    root_height: float = 1.0

    def __post_init__(self):
        for name in ("pose", "velocity", "acceleration", "root_height"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise RetimeError(f"feature weight {name}={v!r} must be a finite number >= 0")
        if self.pose == 0 and self.velocity == 0 and self.acceleration == 0:
            raise RetimeError("feature weights are all zero: give pose, velocity or acceleration a weight > 0")

    def coefficients(self, fps: float) -> tuple[float, float, float]:
        """(alpha, beta, gamma) with y = [alpha x_j, beta (x_k - x_i), gamma (x_k - 2 x_j + x_i)]
        for frames that play ``1/fps`` seconds apart."""
        return (float(self.pose), float(self.velocity) * fps / 2.0, float(self.acceleration) * fps * fps)


def lowpass(values: np.ndarray, width: int) -> np.ndarray:
    """Uniform (box) low-pass filter of ``width`` samples along axis 0 (edges repeat the end values)."""
    values = np.asarray(values, dtype=np.float64)
    width = int(width)
    if width <= 1 or values.shape[0] < 2:
        return values.copy()
    from scipy.ndimage import uniform_filter1d  # here: the command line reads FeatureWeights without SciPy

    return uniform_filter1d(values, size=width, axis=0, mode="nearest")


def positions_in_root_frame(positions: np.ndarray, root_position: np.ndarray, root_quat: np.ndarray) -> np.ndarray:
    """Joint positions (F, J, 3) expressed in the root's coordinate frame.

    ``root_quat`` is (F, 4), scalar-last (x, y, z, w), the root's global orientation.
    """
    from scipy.spatial.transform import Rotation

    positions = np.asarray(positions, dtype=np.float64)
    rel = positions - np.asarray(root_position, dtype=np.float64)[:, None, :]
    rot = Rotation.from_quat(np.asarray(root_quat, dtype=np.float64))
    inv = rot.inv().as_matrix()  # (F, 3, 3)
    return np.einsum("fab,fjb->fja", inv, rel)


def compact_columns(x: np.ndarray, z: np.ndarray | None = None):
    """Drop coordinates that are constant in both pose sets and merge identical ones.

    Joints that share a position (children of one parent at the same offset, e.g. the clavicles and
    the lower neck at the end of the thorax) give identical columns; one column scaled by
    sqrt(count) gives exactly the same distances and products, with fewer dimensions.
    Returns (x', z') (z' is x' when z is None or is x).
    """
    x = np.asarray(x, dtype=np.float64)
    same = z is None or z is x
    both = x if same else np.vstack([x, np.asarray(z, dtype=np.float64)])
    keep = np.ptp(both, axis=0) > 0 if both.shape[0] > 1 else np.ones(both.shape[1], dtype=bool)
    if not keep.any():
        keep[:] = True
    first, counts = identical_columns(both, np.flatnonzero(keep))
    out = both[:, first]
    out *= np.sqrt(counts.astype(np.float64))
    if same:
        return out, out
    return np.ascontiguousarray(out[: x.shape[0]]), np.ascontiguousarray(out[x.shape[0]:])


def identical_columns(values: np.ndarray, columns) -> tuple[np.ndarray, np.ndarray]:
    """Groups of equal columns among ``columns`` of ``values`` (n, D): (first column of each group,
    group sizes), groups in the order of their first column. What ``np.unique(values[:, columns],
    axis=1, return_index=True, return_counts=True)`` finds (float equality: -0.0 == 0.0), without
    its sorted copies of the whole array: one column at a time, grouped by a hash of its values."""
    buckets: dict[int, list[list[int]]] = {}  # hash -> groups with that hash
    groups: list[list[int]] = []
    for c in columns:
        col = values[:, c]
        bucket = buckets.setdefault(hash((col + 0.0).tobytes()), [])  # + 0.0 turns -0.0 into 0.0
        for group in bucket:
            if np.array_equal(values[:, group[0]], col):
                group.append(int(c))
                break
        else:
            bucket.append([int(c)])
            groups.append(bucket[-1])
    return (np.array([g[0] for g in groups], dtype=np.int64), np.array([len(g) for g in groups], dtype=np.int64))


def reference_features(z: np.ndarray, coeffs: tuple[float, float, float], stride: int = 1) -> np.ndarray:
    """Explicit feature vectors (r - 2 stride, 3 D) of a reference pose sequence ``z`` (r, D).

    Feature r comes from frames (r, r + stride, r + 2 stride), which play one output step apart.
    """
    z = np.asarray(z, dtype=np.float64)
    st = int(stride)
    if z.shape[0] < 2 * st + 1:
        raise RetimeError(f"the reference has {z.shape[0]} frames at the analysis rate; it needs at least {2 * st + 1}")
    a, b, c = coeffs
    r = z.shape[0]
    zm, z0, zp = z[: r - 2 * st], z[st: r - st], z[2 * st:]
    return np.hstack([a * z0, b * (zp - zm), c * (zp - 2 * z0 + zm)])


def triple_features(x: np.ndarray, i, j, k, coeffs: tuple[float, float, float]) -> np.ndarray:
    """Explicit feature vectors of frame triples (arrays of indices i < j < k) of poses ``x`` (n, D)."""
    x = np.asarray(x, dtype=np.float64)
    a, b, c = coeffs
    xi, xj, xk = x[np.asarray(i)], x[np.asarray(j)], x[np.asarray(k)]
    return np.concatenate([a * xj, b * (xk - xi), c * (xk - 2 * xj + xi)], axis=-1)


# ---------------------------------------------------------------- poses (the features' input)
#: frames per forward-kinematics pass of :func:`root_frame_poses` (each frame is computed on its
#: own, so the numbers are the same; a whole long clip at once held ~10 temporaries of its size)
POSE_CHUNK_FRAMES = 4096
#: pose columns per low-pass and spline in :func:`analysis_samples` (columns are filtered and
#: interpolated independently; one spline of every column held ~9 copies of the clip's poses)
SPLINE_CHUNK_COLUMNS = 8


def root_frame_poses(motion: Motion, root_height: float = 0.0, chunk_frames: int = POSE_CHUNK_FRAMES) -> np.ndarray:
    """(F, J, 3) joint positions in the floating base's coordinate frame
    (:func:`retime.motion.rig.floating_base`; dummy roots above it and props beside the body under
    them are zero rows), in metres.

    With ``root_height`` > 0 one more row (F, J+1, 3) holds the base's height above the ground
    along the file's up axis (detected or given, :mod:`retime.motion.frame`; m) times that weight
    in its y slot (x and z zero). Computed ``chunk_frames`` frames at a time.
    """
    from retime.motion.rig import base_and_props

    base, props = base_and_props(motion.skeleton)
    rows = motion.skeleton.n_joints + (1 if root_height > 0 else 0)
    out = np.empty((motion.n_frames, rows, 3))
    for f0 in range(0, motion.n_frames, int(chunk_frames)):
        f1 = min(motion.n_frames, f0 + int(chunk_frames))
        _root_frame_chunk(motion, f0, f1, base, props, root_height, out[f0:f1])
    return out


def _root_frame_chunk(motion, f0, f1, base, props, root_height, out):
    """Frames f0..f1-1 of :func:`root_frame_poses`, written into ``out``."""
    from retime.motion.frame import up_vector

    sk = motion.skeleton
    pos, ori = forward_kinematics(motion, motion.rotations[f0:f1], motion.translations[f0:f1])
    J = sk.n_joints
    out[:, :J] = positions_in_root_frame(pos, pos[:, base], ori[:, base]) * float(sk.meters_per_unit)
    out[:, :base] = 0.0
    out[:, props] = 0.0  # IK targets and markers beside the body are not its pose
    if root_height > 0:
        out[:, J] = 0.0
        out[:, J, 1] = (pos[:, base] @ up_vector(sk.up)) * float(sk.meters_per_unit) * root_height


def pose_pair(motion, reference, root_height=0.0):
    """Flattened poses of input and reference with the columns constant in both dropped."""
    a = root_frame_poses(motion, root_height)
    b = a if reference is motion else root_frame_poses(reference, root_height)
    if reference is not motion:
        order = [reference.skeleton.index(nm) for nm in motion.skeleton.names]
        if root_height > 0:
            order.append(len(order))
        b = b[:, order]
    x = a.reshape(a.shape[0], -1)
    z = x if reference is motion else b.reshape(b.shape[0], -1)
    return compact_columns(x, z)


def _sampler(poses, fps):
    """A function of times (s) giving the poses (F, D) at ``fps`` there (cubic spline)."""
    F = poses.shape[0]
    if F < 4:
        def linear(times):
            u = np.clip(np.asarray(times) * fps, 0, F - 1)
            return np.stack([np.interp(u, np.arange(F), poses[:, c]) for c in range(poses.shape[1])], axis=1)
        return linear
    from scipy.interpolate import CubicSpline  # here: the command line reads FeatureWeights without SciPy

    spline = CubicSpline(np.arange(F) / fps, poses, axis=0)
    return lambda times: spline(np.clip(times, 0.0, (F - 1) / fps))


def analysis_samples(poses, fps, prefilter, times, chunk_columns=SPLINE_CHUNK_COLUMNS):
    """Poses (F, D) at ``fps``, low-passed with a box of ``prefilter`` seconds, at each array of
    ``times`` (s): a list of (len(t), D) arrays. A few columns at a time, each low-passed and
    splined once."""
    width = max(1, int(round(prefilter * fps)))
    out = [np.empty((len(t), poses.shape[1])) for t in times]
    for c0 in range(0, poses.shape[1], int(chunk_columns)):
        c1 = min(poses.shape[1], c0 + int(chunk_columns))
        sample = _sampler(lowpass(poses[:, c0:c1], width), fps)
        for t, o in zip(times, out):
            o[:, c0:c1] = sample(t)
    return out


def analysis_poses(motion: Motion, fps: float = 30.0, prefilter: float = 0.1, times=None,
                   root_height: float = 1.0) -> np.ndarray:
    """(frames, D) low-passed root-frame joint positions (m) at ``fps`` (or at ``times`` seconds)."""
    x = root_frame_poses(motion, root_height)
    x = x.reshape(x.shape[0], -1)
    if times is None:
        times = np.arange(int(math.floor(motion.duration * fps + 1e-9)) + 1) / fps
    return analysis_samples(x, motion.fps, prefilter, [np.asarray(times, dtype=float)])[0]
