"""A procedurally animated 31-joint stick figure (CMU joint layout), for tests and benchmarks.

It needs no motion file: a figure that walks forward along +x and makes one jump, in metres, y up.
"""

from __future__ import annotations

import numpy as np

# (name, parent, rest offset from parent in metres); CMU ASF joint names and hierarchy.
_JOINTS = [
    ("root", -1, (0.0, 0.0, 0.0)),
    ("lhipjoint", 0, (0.0, -0.05, 0.09)),
    ("lfemur", 1, (0.0, -0.42, 0.0)),
    ("ltibia", 2, (0.0, -0.41, 0.0)),
    ("lfoot", 3, (0.12, -0.04, 0.0)),
    ("ltoes", 4, (0.06, 0.0, 0.0)),
    ("rhipjoint", 0, (0.0, -0.05, -0.09)),
    ("rfemur", 6, (0.0, -0.42, 0.0)),
    ("rtibia", 7, (0.0, -0.41, 0.0)),
    ("rfoot", 8, (0.12, -0.04, 0.0)),
    ("rtoes", 9, (0.06, 0.0, 0.0)),
    ("lowerback", 0, (0.0, 0.1, 0.0)),
    ("upperback", 11, (0.0, 0.12, 0.0)),
    ("thorax", 12, (0.0, 0.12, 0.0)),
    ("lowerneck", 13, (0.0, 0.1, 0.0)),
    ("upperneck", 14, (0.0, 0.06, 0.0)),
    ("head", 15, (0.0, 0.06, 0.0)),
    ("lclavicle", 13, (0.0, 0.06, 0.17)),
    ("lhumerus", 17, (0.0, -0.28, 0.02)),
    ("lradius", 18, (0.0, -0.25, 0.0)),
    ("lwrist", 19, (0.0, -0.04, 0.0)),
    ("lhand", 20, (0.0, -0.06, 0.0)),
    ("lfingers", 21, (0.0, -0.04, 0.0)),
    ("lthumb", 20, (0.03, -0.03, 0.0)),
    ("rclavicle", 13, (0.0, 0.06, -0.17)),
    ("rhumerus", 24, (0.0, -0.28, -0.02)),
    ("rradius", 25, (0.0, -0.25, 0.0)),
    ("rwrist", 26, (0.0, -0.04, 0.0)),
    ("rhand", 27, (0.0, -0.06, 0.0)),
    ("rfingers", 28, (0.0, -0.04, 0.0)),
    ("rthumb", 27, (0.03, -0.03, 0.0)),
]

NAMES = [j[0] for j in _JOINTS]
PARENTS = np.array([j[1] for j in _JOINTS], dtype=np.int64)
OFFSETS = np.array([j[2] for j in _JOINTS], dtype=np.float64)


def _rot_z(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    out = np.zeros(a.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, -s
    out[..., 1, 0], out[..., 1, 1] = s, c
    out[..., 2, 2] = 1.0
    return out


def synthetic_figure(n_frames: int = 240, fps: float = 120.0) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(positions (F, 31, 3), parents, names): a walk along +x with one jump in the middle."""
    t = np.arange(n_frames) / fps
    T = max(t[-1], 1e-9)
    phase = 2 * np.pi * 1.0 * t
    angles = np.zeros((n_frames, len(NAMES)))
    swing = 0.45 * np.sin(phase)
    angles[:, NAMES.index("lfemur") - 1] = swing
    angles[:, NAMES.index("rfemur") - 1] = -swing
    angles[:, NAMES.index("lfemur")] = -0.5 * np.maximum(0, np.sin(phase + 1.2))
    angles[:, NAMES.index("rfemur")] = -0.5 * np.maximum(0, np.sin(phase + 1.2 + np.pi))
    angles[:, NAMES.index("lclavicle")] = -0.4 * np.sin(phase)
    angles[:, NAMES.index("rclavicle")] = 0.4 * np.sin(phase)
    angles[:, NAMES.index("lhumerus")] = 0.3
    angles[:, NAMES.index("rhumerus")] = 0.3
    rot = _rot_z(angles)
    # root path: forward walk, a jump (parabola) in the middle third
    root = np.zeros((n_frames, 3))
    root[:, 0] = 1.1 * t
    jump = (t > T / 3) & (t < T / 3 + 0.45)
    tj = t - T / 3
    root[:, 1] = 0.95 + 0.03 * np.cos(2 * phase) + np.where(jump, 4.9 * tj * (0.45 - tj), 0.0)
    pos = np.zeros((n_frames, len(NAMES), 3))
    glob = np.zeros((n_frames, len(NAMES), 3, 3))
    for j, p in enumerate(PARENTS):
        if p < 0:
            glob[:, j] = rot[:, j]
            pos[:, j] = root
        else:
            glob[:, j] = glob[:, p] @ rot[:, j]
            pos[:, j] = pos[:, p] + np.einsum("fij,j->fi", glob[:, p], OFFSETS[j])
    return pos, PARENTS.copy(), list(NAMES)
