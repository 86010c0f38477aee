"""Physics-based retiming (McCann, Pollard, Srinivasa 2006): body model, path dynamics, contacts,
feasible regions and the timing optimizer.

Entry points: :func:`retime.physics.physics_warp` (retime a motion) and
:func:`retime.physics.check_clip` (how physical a clip is as captured, ``retime check``).
"""

__all__ = ["physics_warp", "PhysicsResult", "check_clip", "ClipCheck"]

_LAZY = {"physics_warp": "api", "PhysicsResult": "api", "check_clip": "check", "ClipCheck": "check"}


def __getattr__(name):
    # imported on first use: the compiled kernels load only when a caller needs them
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
