"""Sane ranges and a memory limit: a request that cannot fit is refused up front, in one line.

* Frame rates between :data:`MIN_FPS` (0.001 Hz) and :data:`MAX_FPS` (100,000 Hz).
* A file's numbers (channel values, offsets, lengths) within :data:`MAX_VALUE` (1e12) in size: no
  angle or length in any unit is larger, and the arithmetic on them (differences, sums of squares)
  then stays far from overflowing into inf and NaN.
* :data:`MEMORY_LIMIT`: the most memory a command may plan to use, ``RETIME_MAX_MEMORY`` (bytes,
  or with a K/M/G/T suffix: ``16G``), by default half the machine's memory (at most 16 GiB). Readers,
  the retiming of a motion and the methods estimate what they will allocate and call
  :func:`check_memory` first.
"""
from __future__ import annotations

import os

import numpy as np

from .errors import RetimeError

MIN_FPS, MAX_FPS = 0.001, 100_000.0
MAX_VALUE = 1e12
_SUFFIX = {"k": 2 ** 10, "m": 2 ** 20, "g": 2 ** 30, "t": 2 ** 40}


def _physical_memory() -> int:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 8 * 2 ** 30


def memory_limit() -> int:
    """Bytes a command may plan to use (see the module docstring)."""
    text = os.environ.get("RETIME_MAX_MEMORY", "").strip().lower()
    if text:
        try:
            scale = _SUFFIX.get(text[-1], 1)
            value = float(text[:-1] if text[-1] in _SUFFIX else text) * scale
            if value > 0:
                return int(value)
        except ValueError:
            pass
        raise RetimeError(f"RETIME_MAX_MEMORY={text!r} is not a size (bytes, or 512M, 16G, ...)")
    return int(min(16 * 2 ** 30, _physical_memory() // 2))


def _size(n: float) -> str:
    for unit, scale in (("TB", 2 ** 40), ("GB", 2 ** 30), ("MB", 2 ** 20)):
        if n >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n / 1024:.0f} KB"


def check_memory(nbytes: float, what: str) -> None:
    """Refuse ``what`` if it would need more than the memory limit."""
    limit = memory_limit()
    if not nbytes <= limit:
        raise RetimeError(f"{what} would need about {_size(nbytes)} of memory, more than the limit of {_size(limit)}; "
                          "ask for less, or raise the limit with RETIME_MAX_MEMORY (e.g. RETIME_MAX_MEMORY=64G)")


def check_fps(fps: float, what: str = "frame rate") -> float:
    if not (MIN_FPS <= fps <= MAX_FPS):
        raise RetimeError(f"{what} {fps:.6g} Hz is outside {MIN_FPS:g} to {MAX_FPS:,.0f} Hz")
    return float(fps)


def number_problem(values) -> str | None:
    """What is wrong with a file's numbers ('a value that is not finite ...'), or None."""
    values = np.asarray(values, dtype=float)
    if numbers_fine(values):
        return None
    if not np.all(np.isfinite(values)):
        return "a value that is not finite (NaN or inf)"
    return f"the value {values[np.abs(values) > MAX_VALUE][0]:g}, beyond +-{MAX_VALUE:g} (no angle or length is this large)"


def numbers_fine(values) -> bool:
    """All finite and within :data:`MAX_VALUE` (one pass, for a whole file's values)."""
    return bool(np.all(np.abs(values) <= MAX_VALUE))
