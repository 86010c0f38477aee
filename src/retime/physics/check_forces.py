"""What ``retime check --report`` shows per frame beside the residual: the contact force of each foot,
the force no contact gives (the residual force), and the centre of mass, in the file's own axes.

All come from the clip at its own timing, (p'', p'^2) = (0, 1), under the original physics:

* ``foot_force[f]`` (body weights): the contact forces that explain the root's wrench best
  (``terms.lambda_ref``: non-negative least squares over the friction-pyramid edges, the root rows
  weighted first, :mod:`.model.dynamics`), summed over the foot's edges and sole corners (columns
  ``16 * foot + 4 * corner + edge``, :mod:`.model.contacts`). Not the regions' least-force contact
  (``RegionSet.lam0``), which leans on the residual allowance of every root row and so shows a
  ghost force of 0.09 body weight on every frame;
* ``foot_point[f]`` (file units): where that force acts, the sole corners weighted by their share
  of the foot's normal force (the foot's centre of pressure); the sole's centre when it carries none;
* ``residual_force`` (body weights): the force no contact gives, the root's force rows of
  ``b + c - N lambda_ref`` (in the root's frame, the free-flyer convention) turned into the world;
  near zero where the clip is physical, and where it is not it follows ``residual`` (the check's
  weighted-L1 residual beyond the allowance: correlation 0.99 on 16_06);
* ``com`` (file units): the centre of mass of the path the dynamics see (low-passed by
  :data:`.constants.DEFAULT_SMOOTHING`).

Newton for the whole body then holds on every frame: ``m (a_com - g) = sum of foot forces +
residual force`` (the test of this module checks it from the report alone).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..motion.frame import up_rotation
from .model.contacts import BASIS_PER_FOOT, EDGES_PER_CORNER, friction_edges
from .model.tree import kinematics

FEET = ("left", "right")


@dataclass
class FrameForces:
    """Per frame (F), in the file's axes: feet in the order of :data:`FEET`."""

    foot_force: np.ndarray  # (F, 2, 3) body weights
    foot_point: np.ndarray  # (F, 2, 3) file units
    residual_force: np.ndarray  # (F, 3) body weights
    com: np.ndarray  # (F, 3) file units

    def frame(self, i: int, digits: int = 5) -> dict:
        """Frame ``i``'s fields for ``report.frames``."""
        def r(v):
            return [round(float(x), digits) for x in v]

        return {"foot_force": {foot: r(self.foot_force[i, k]) for k, foot in enumerate(FEET)},
                "foot_point": {foot: r(self.foot_point[i, k]) for k, foot in enumerate(FEET)},
                "residual_force": r(self.residual_force[i]), "com": r(self.com[i])}


def frame_forces(motion, terms, body_weight) -> FrameForces:
    """The forces and centre of mass of ``motion``'s frames (see the module docstring), from its
    dynamics ``terms`` (with their reference forces) and the body weight (newtons)."""
    spf = int(terms.samples_per_frame)
    idx = np.arange(0, len(terms.times), spf)
    bw = float(body_weight)
    lam = np.asarray(terms.lambda_ref, dtype=float)[idx]  # (F, K)
    n = len(idx)
    edges = friction_edges(float(terms.friction))  # (4, 3), y up
    corner_force = np.einsum("fce,ed->fcd", lam[:, :2 * BASIS_PER_FOOT].reshape(n, 8, EDGES_PER_CORNER), edges)
    foot_force = corner_force.reshape(n, 2, 4, 3).sum(axis=2) / bw
    corners = np.asarray(terms.corners, dtype=float)[idx].reshape(n, 2, 4, 3)  # metres, y up
    normal = corner_force[..., 1].reshape(n, 2, 4)
    total = normal.sum(axis=2, keepdims=True)
    weights = np.where(total > 1e-9 * bw, normal / np.where(total > 0, total, 1.0), 0.25)
    foot_point = np.einsum("fkc,fkcd->fkd", weights, corners)
    root_force = np.asarray(terms.tau_ref, dtype=float)[idx, :3]
    residual = np.einsum("fab,fb->fa", root_rotations(terms, idx), root_force) / bw
    com = np.asarray(terms.com, dtype=float)[idx]
    to_file = up_rotation(motion.skeleton.up)  # file axes -> y up: its transpose turns back
    metres = float(motion.skeleton.meters_per_unit)
    return FrameForces(foot_force=foot_force @ to_file, foot_point=(foot_point @ to_file) / metres,
                       residual_force=residual @ to_file, com=(com @ to_file) / metres)


def root_rotations(terms, idx) -> np.ndarray:
    """(F, 3, 3) world rotation of the floating base at samples ``idx`` of the smoothed path (the
    frame its generalized force rows are expressed in); identity for a fixed base."""
    root, quats = terms.sole_path
    if root is None or terms.root_pos is None:
        return np.broadcast_to(np.eye(3), (len(idx), 3, 3))
    still = np.zeros((len(idx), terms.kinematic_tree.nv))
    kin = kinematics(terms.kinematic_tree, np.asarray(root)[idx], np.asarray(quats)[idx], still, still)
    return kin.R[:, 0]
