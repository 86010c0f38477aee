"""Capture glitches in a clip's poses: a few frames that jump away from the motion and back.

A glitch is a run of at most ``GLITCH_SECONDS`` of frames whose pose jumps more than
``JUMP_RATIO`` times the local median frame-to-frame change into the run and out of it, while the
frames on either side of the run are close to each other (the motion carries on across it). A run
at either end of the clip has one side only: the clip starts (or ends) in a pose it leaves in one
jump. A step that persists is not a glitch, and neither is a fast but smooth movement (a jump's
flight): its big changes come one after another, so the change across a frame is about twice the
change into it. Guided plays glitch frames as a gap: their poses are replaced by the line through
their neighbours, so that the warp is not pulled to play a glitch at its natural speed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a jump into or out of a glitch is larger than this many local median frame-to-frame changes
JUMP_RATIO = 20.0
#: the longest glitch (s): 3 frames at 120 Hz, 1 at 30 Hz
GLITCH_SECONDS = 0.025
#: the window of the local median change (s)
MEDIAN_SECONDS = 0.5
#: across an interior glitch the poses differ by less than this fraction of the smaller jump
ACROSS_FRACTION = 0.25


@dataclass(frozen=True)
class Glitch:
    first: int  # first glitch frame
    last: int  # last glitch frame (inclusive)
    ratio: float  # the larger jump at its edges, in local median changes

    def message(self, fps: float, clip: str = "source") -> str:
        at = f"({self.first / fps:.3f} s)"
        frames = (f"frame {self.first} {at} looks" if self.first == self.last
                  else f"frames {self.first}-{self.last} {at} look")
        return (f"{clip} {frames} like a capture glitch (the pose jumps "
                f"{self.ratio:.0f}x the median change); played as a gap")


def find_glitches(poses: np.ndarray, fps: float) -> list[Glitch]:
    """The glitches of ``poses`` (F, D) sampled at ``fps`` (see the module docstring)."""
    from scipy.ndimage import median_filter  # here: the command line imports guided without SciPy

    x = np.asarray(poses, dtype=np.float64)
    F = x.shape[0]
    if F < 4:
        return []
    change = np.linalg.norm(np.diff(x, axis=0), axis=1)  # change[i]: frame i -> i + 1
    typical = np.median(change)
    if not typical > 0:
        return []
    window = max(3, int(round(MEDIAN_SECONDS * fps)) | 1)
    local = np.maximum(median_filter(change, size=window, mode="nearest"), typical * 1e-3)
    ratio = change / local
    jumps = np.flatnonzero(ratio > JUMP_RATIO)
    longest = max(1, int(round(GLITCH_SECONDS * fps)))
    found, used = [], set()
    for a, b in zip(jumps[:-1], jumps[1:]):  # an interior run: frames a+1..b
        across = np.linalg.norm(x[b + 1] - x[a])
        if b - a <= longest and across < ACROSS_FRACTION * min(change[a], change[b]) and a not in used:
            found.append(Glitch(int(a) + 1, int(b), float(max(ratio[a], ratio[b]))))
            used.update((a, b))
    if jumps.size and jumps[0] + 1 <= longest and jumps[0] not in used and jumps[0] + 2 < F:
        found.insert(0, Glitch(0, int(jumps[0]), float(ratio[jumps[0]])))  # the clip starts in it
    if jumps.size and F - 1 - jumps[-1] <= longest and jumps[-1] not in used and jumps[-1] >= 1:
        found.append(Glitch(int(jumps[-1]) + 1, F - 1, float(ratio[jumps[-1]])))  # the clip ends in it
    return found


def fill_glitches(poses: np.ndarray, glitches) -> np.ndarray:
    """A copy of ``poses`` with each glitch's frames on the line through the frames around it (at an
    end of the clip: continued from the two frames after, or before, it)."""
    x = np.array(poses, dtype=np.float64)
    for g in glitches:
        run = np.arange(g.first, g.last + 1)[:, None]
        if g.first == 0:
            a, b = g.last + 1, g.last + 2
        elif g.last == x.shape[0] - 1:
            a, b = g.first - 2, g.first - 1
        else:
            a, b = g.first - 1, g.last + 1
        x[g.first:g.last + 1] = x[a] + (run - a) * (x[b] - x[a]) / (b - a)
    return x
