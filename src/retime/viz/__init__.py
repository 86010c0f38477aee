"""Seeing timing: plots of timing curves and physics regions, skeleton videos, video retiming."""
