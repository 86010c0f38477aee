"""Forward kinematics vectorized over frames (one pass over the joints, none over frames)."""
import numpy as np

from .quat import qmul, qrot


def forward_kinematics(motion, rotations=None, translations=None):
    """Global joint positions (F, J, 3) and orientations (F, J, 4) of a motion, in file units."""
    skeleton = motion.skeleton
    rotations = motion.rotations if rotations is None else rotations
    translations = motion.translations if translations is None else translations
    # joint-major copies: each joint's frames are contiguous, which makes the per-joint steps cheaper
    rot = np.ascontiguousarray(np.moveaxis(rotations, -2, 0))
    tr = np.ascontiguousarray(np.moveaxis(translations, -2, 0))
    positions = np.empty(tr.shape)
    orientations = np.empty(rot.shape)
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            positions[j] = tr[j]
            orientations[j] = rot[j]
        else:
            positions[j] = positions[p] + qrot(orientations[p], tr[j])
            orientations[j] = qmul(orientations[p], rot[j])
    return np.ascontiguousarray(np.moveaxis(positions, 0, -2)), np.ascontiguousarray(np.moveaxis(orientations, 0, -2))


def end_site_positions(motion, positions=None, orientations=None):
    """Global positions (F, E, 3) of the skeleton's end sites."""
    if positions is None:
        positions, orientations = forward_kinematics(motion)
    sites = motion.skeleton.end_sites
    if not sites:
        return np.zeros((motion.n_frames, 0, 3))
    idx = np.array([j for j, _ in sites])
    off = np.array([o for _, o in sites], dtype=float)
    return positions[:, idx] + qrot(orientations[:, idx], off[None])


def rest_height(skeleton) -> float:
    """Vertical extent of the rest pose (joints and end sites), in file units."""
    n = skeleton.n_joints
    pos = np.zeros((n, 3))
    for j, p in enumerate(skeleton.parents):
        pos[j] = skeleton.offsets[j] + (pos[p] if p >= 0 else 0.0)
    ends = np.array([pos[j] + np.asarray(o) for j, o in skeleton.end_sites]).reshape(-1, 3)
    return float(np.ptp(np.vstack([pos, ends])[:, 1]))
