"""Guided time warping (Hsu, da Silva, Popović, SCA 2007).

The timing of a motion is changed so that its local velocities and accelerations
resemble those of a reference motion (by default the motion itself, which
preserves its natural timing), under keytime constraints.

Entry point: :func:`retime.guided.guided_warp`.
"""

from retime.guided.api import GuidedResult, guided_solve, guided_warp, root_frame_poses
from retime.guided.features import FeatureWeights
from retime.guided.postprocess import adaptive_smooth, moving_average

__all__ = ["guided_warp", "guided_solve", "GuidedResult", "FeatureWeights", "root_frame_poses",
           "adaptive_smooth", "moving_average"]
