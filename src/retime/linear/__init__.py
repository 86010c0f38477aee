"""Linear retiming: uniform speed changes and keytime warps (straight lines or a smooth monotone
spline through the keytimes), the baseline animation tools offer.

Entry point: :func:`retime.linear.method.solve` (the method contract of :mod:`retime.method`).
"""
from .method import NAME, Settings, solve

__all__ = ["NAME", "Settings", "solve"]
