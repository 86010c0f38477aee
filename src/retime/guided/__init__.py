"""Guided time warping (Hsu, da Silva, Popović, SCA 2007).

The timing of a motion is changed so that its local velocities and accelerations
resemble those of a reference motion (by default the motion itself, which
preserves its natural timing), under keytime constraints.

Entry point: :func:`retime.guided.guided_warp`.
"""

__all__ = ["guided_warp", "guided_solve", "GuidedResult", "FeatureWeights", "root_frame_poses",
           "adaptive_smooth", "moving_average"]
_LAZY = {"guided_warp": "api", "guided_solve": "api", "GuidedResult": "api", "root_frame_poses": "features",
         "FeatureWeights": "features", "adaptive_smooth": "postprocess", "moving_average": "postprocess"}


def __getattr__(name):
    # imported on first use: the command line reads Settings' defaults without loading SciPy and numba
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
