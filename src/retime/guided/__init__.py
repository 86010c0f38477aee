"""Guided time warping (Hsu, da Silva, Popović, SCA 2007).

The timing of a motion is changed so that its local velocities and accelerations
resemble those of a reference motion (by default the motion itself, which
preserves its natural timing), under keytime constraints.

Entry point: :func:`retime.guided.guided_warp`.
"""
