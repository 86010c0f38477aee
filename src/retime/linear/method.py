"""The linear method behind the contract of :mod:`retime.method`."""
from __future__ import annotations

import time
from dataclasses import dataclass

from ..errors import RetimeError
from ..method import Report, Request, Result, settings_record, summary
from ..phases import keytime_phases
from ..warp import keytime_warp, scale_warp

NAME = "linear"


@dataclass(frozen=True)
class Settings:
    smooth: bool = False  # a monotone cubic (PCHIP) through the keytimes instead of straight lines


def solve(motion, request: Request) -> Result:
    settings = request.settings_or(Settings)
    if motion.n_frames < 2:
        raise RetimeError("a single frame has no timing to change")
    t0 = time.perf_counter()
    if request.scale is not None and not request.keytimes:
        curve = scale_warp(motion.duration, float(request.scale), motion.fps)  # frame k shows k / (fps scale)
    else:
        curve = keytime_warp(motion.duration, request.keytimes, request.output_duration(motion), smooth=settings.smooth)
    seconds = time.perf_counter() - t0
    report = Report(summary(NAME, curve, motion.fps, keytime_phases(curve, request.keytimes), {"method": seconds},
                            settings=settings_record(settings)))
    return Result(curve, report, info={"keytimes": len(request.keytimes)})
