"""The clip's own physics for the page (``GET /api/session/{id}/check``): what ``retime check`` says
per source frame, in the viewer's world (metres, y up, :func:`retime.motion.frame.to_y_up`): the
residual for the strip under the scrub bar, each foot's contact force (body weights) and where it
acts, the residual force and the centre of mass for the 3-D view's arrows."""
from __future__ import annotations

import threading

import numpy as np

from ..errors import RetimeError
from ..motion.frame import to_y_up


def check_payload(motion) -> dict:
    """``retime check`` of ``motion`` as the page draws it; ``{"available": False, "reason": ...}``
    when physics cannot read the clip (not a two-legged character, too short, ...)."""
    from ..physics.check import check_clip
    from ..physics.check_forces import FEET
    from ..physics.plausibility import OFF_RESIDUAL

    try:
        result = check_clip(motion)
    except RetimeError as e:
        return {"available": False, "reason": str(e)}
    forces, sk = result.forces, motion.skeleton
    metres = float(sk.meters_per_unit)

    def world(v, scale=1.0):
        return np.round(to_y_up(np.asarray(v) * scale, sk), 5).tolist()

    s = result.summary()
    return {"available": True, "physical": s["physical"], "verdict": result.verdict_line(),
            "worst_frames": s["worst_frames"], "threshold": OFF_RESIDUAL,
            "residual": np.round(result.residual, 5).tolist(),
            "feet": {foot: {"force": world(forces.foot_force[:, k]), "point": world(forces.foot_point[:, k], metres)}
                     for k, foot in enumerate(FEET)},
            "residual_force": world(forces.residual_force), "com": world(forces.com, metres)}


class ClipInsight:
    """The payload of one clip, computed once (the first request waits for it, the rest reuse it)."""

    def __init__(self, motion):
        self.motion = motion
        self._lock = threading.Lock()
        self._payload = None

    def payload(self) -> dict:
        with self._lock:
            if self._payload is None:
                self._payload = check_payload(self.motion)
            return self._payload
