"""Timing methods as small adapters for the editor: control points and parameters in, curve out.

Every adapter is made once per editor session and method (``make(clip)``) so that a method may keep
state between edits (the physics optimizer warm-starts from its current solution, McCann et al.
§3.6). ``solve(job)`` yields ``Solution`` objects: zero or more intermediate ones (``final=False``)
while it iterates, then one final one. It polls ``job.cancelled()`` and stops early, returning nothing
more, when a newer edit has arrived.

Control points are (t, s) pairs: output time t plays source time s. The first is (0, 0), the last is
(T, S) with T the output duration. A *locked* point is a keytime: a hard constraint the method must
pass through. Unlocked points are the user's suggestions: linear interpolates them all; guided and
physics treat them as handles the optimizer may move.
"""
from __future__ import annotations

import importlib
import math
import time
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from ..errors import RetimeError
from ..warp import TimingCurve, keytime_warp


@dataclass
class ControlPoint:
    t: float
    s: float
    locked: bool = False

    def to_json(self):
        return {"t": round(self.t, 6), "s": round(self.s, 6), "locked": self.locked}


@dataclass
class Param:
    """One parameter a method exposes in the page (numbers are checked against min/max)."""

    name: str
    label: str
    kind: str  # "number", "choice", "bool"
    default: object
    min: float | None = None
    max: float | None = None
    step: float | None = None
    unit: str = ""
    choices: tuple = ()
    help: str = ""

    def to_json(self):
        d = {"name": self.name, "label": self.label, "kind": self.kind, "default": self.default,
             "unit": self.unit, "help": self.help}
        if self.kind == "number":
            d.update(min=self.min, max=self.max, step=self.step)
        if self.kind == "choice":
            d["choices"] = [list(c) for c in self.choices]
        return d

    def check(self, value):
        """The value converted and checked; RetimeError with a readable message if it is not valid."""
        if self.kind == "number":
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise RetimeError(f"{self.label}: {value!r} is not a number") from None
            if not math.isfinite(v):
                raise RetimeError(f"{self.label}: must be a finite number")
            if (self.min is not None and v < self.min) or (self.max is not None and v > self.max):
                raise RetimeError(f"{self.label}: {v:g} is outside {self.min:g} .. {self.max:g}{' ' + self.unit if self.unit else ''}")
            return v
        if self.kind == "bool":
            if not isinstance(value, bool):
                raise RetimeError(f"{self.label}: must be true or false")
            return value
        if self.kind == "choice":
            names = [c[0] for c in self.choices]
            if value not in names:
                raise RetimeError(f"{self.label}: {value!r} is not one of {', '.join(names)}")
            return value
        raise AssertionError(self.kind)


@dataclass
class Clip:
    """What the editor was started with: the motion, an optional reference, and derived data."""

    name: str
    motion: object
    reference: object | None = None
    reference_name: str | None = None


@dataclass
class Job:
    """What a method solves: the session's control points, parameters and duration.

    Stateful methods (physics) also get the edit log: ``ops`` lists (version, op) for every edit so
    far (bounded); an adapter replays those newer than the version it last saw, or resyncs from
    ``points`` when the log no longer reaches back that far. ``held`` is the point being dragged."""

    points: list[ControlPoint]
    params: dict
    duration: float
    cancelled: Callable[[], bool] = lambda: False
    version: int = 0
    ops: list = field(default_factory=list)
    held: int | None = None

    def ops_since(self, version):
        """Edits after ``version``, or None if the log does not reach back that far."""
        if version is None:
            return None
        if self.ops and self.ops[0][0] > version + 1:
            return None
        return [op for v, op in self.ops if v > version]


@dataclass
class Solution:
    curve: TimingCurve
    points: list[ControlPoint] | None = None  # control points moved by the method (None: unchanged)
    feasibility: np.ndarray | None = None  # per output frame, 0 (infeasible) .. 1 (feasible)
    info: dict = field(default_factory=dict)
    final: bool = True


class Method:
    """Base adapter. Subclasses set ``name``, ``label``, ``params`` and implement ``solve``."""

    name = ""
    label = ""
    description = ""
    params: tuple[Param, ...] = ()
    point_axes = "ts"  # which way the page lets interior control points move: "ts" both, "s" vertically

    def __init__(self, clip: Clip):
        self.clip = clip

    @classmethod
    def availability(cls, clip: Clip) -> str | None:
        """None if the method can run on this clip, else a one-line reason shown in the page."""
        return None

    def solve(self, job: Job) -> Iterator[Solution]:
        raise NotImplementedError


def keytimes_of(points, locked_only=False):
    """Interior control points as keytimes (source, output) for the warp builders."""
    inner = points[1:-1]
    return [(p.s, p.t) for p in inner if p.locked or not locked_only]


class LinearMethod(Method):
    name = "linear"
    label = "Linear"
    description = "Straight lines (or a smooth monotone spline) through every control point."
    params = (Param("smooth", "Smooth spline", "bool", False,
                    help="monotone cubic (PCHIP) through the control points instead of straight lines"),)

    def solve(self, job):
        S = self.clip.motion.duration
        curve = keytime_warp(S, keytimes_of(job.points), duration=job.duration, smooth=job.params.get("smooth", False))
        yield Solution(curve, info={"keytimes": len(job.points) - 2})


class GuidedMethod(Method):
    """Guided time warping (Hsu et al. 2007): the locked points are keytimes; the dynamic program fills in."""

    name = "guided"
    label = "Guided"
    description = "Keytimes (locked points) plus a reference: the warp whose local velocities and accelerations best match the reference (Hsu et al. 2007)."
    params = (
        Param("reference", "Reference", "choice", "self",
              choices=(("self", "the motion itself (keep its timing)"), ("reference", "the --reference motion"))),
        Param("max_speed", "Speed limit", "number", 4.0, 1.0, 16.0, 1.0, "x", help="frame skip limit s (Hsu §3.1)"),
        Param("k", "Neighbours", "number", 3.0, 1.0, 10.0, 1.0, help="k nearest reference features (Hsu §4.3)"),
    )

    @classmethod
    def availability(cls, clip):
        mod = _optional("retime.guided")
        if mod is None or not hasattr(mod, "guided_warp"):
            return "guided time warping is not installed in this build (retime.guided.guided_warp is missing)"
        return None

    def solve(self, job):
        from ..guided import guided_warp  # noqa: PLC0415 (optional method)

        params = job.params
        reference = self.clip.motion
        if params.get("reference") == "reference":
            if self.clip.reference is None:
                raise RetimeError("no reference motion: start the editor with --reference REF.bvh to use one")
            reference = self.clip.reference
        keys = keytimes_of(job.points, locked_only=True)
        curve = _call_guided(guided_warp, self.clip.motion, reference, keys, job.duration,
                             int(params.get("max_speed", 4)), int(params.get("k", 3)))
        pts = _follow(job.points, curve)
        yield Solution(curve, points=pts, info={"keytimes": len(keys)})


def _call_guided(guided_warp, motion, reference, keytimes, duration, max_speed, k):
    """Call guided_warp with the keyword names it accepts (the module is written alongside)."""
    import inspect  # noqa: PLC0415

    sig = inspect.signature(guided_warp)
    kwargs = {}
    names = sig.parameters
    for want, value in (("reference", reference), ("keytimes", keytimes), ("duration", duration),
                        ("max_speed", max_speed), ("skip", max_speed), ("s", max_speed), ("k", k)):
        if want in names:
            kwargs[want] = value
    result = guided_warp(motion, **kwargs)
    curve = getattr(result, "curve", result)
    if not isinstance(curve, TimingCurve):
        raise RetimeError("guided_warp returned no timing curve")
    return curve


def _follow(points, curve):
    """Unlocked control points moved onto the solved curve (their output time kept)."""
    out = []
    for i, p in enumerate(points):
        if p.locked or i == 0 or i == len(points) - 1:
            out.append(ControlPoint(p.t, p.s, p.locked))
        else:
            out.append(ControlPoint(p.t, float(curve(p.t)), False))
    return out


def _optional(name):
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


METHODS: dict[str, type[Method]] = {m.name: m for m in (LinearMethod, GuidedMethod)}


def register(method_cls: type[Method]) -> None:
    METHODS[method_cls.name] = method_cls


def method_catalog(clip: Clip):
    out = []
    for cls in METHODS.values():
        reason = cls.availability(clip)
        out.append({"name": cls.name, "label": cls.label, "description": cls.description,
                    "available": reason is None, "reason": reason, "point_axes": cls.point_axes,
                    "params": [p.to_json() for p in cls.params]})
    return out


def check_params(method_name, values: dict) -> dict:
    cls = METHODS.get(method_name)
    if cls is None:
        raise RetimeError(f"unknown method {method_name!r}; choose one of {', '.join(METHODS)}")
    if not isinstance(values, dict):
        raise RetimeError("parameters must be a JSON object")
    known = {p.name: p for p in cls.params}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise RetimeError(f"{cls.label} has no parameter {unknown[0]!r}")
    return {name: p.check(values[name]) for name, p in known.items() if name in values}


def default_params(method_name) -> dict:
    return {p.name: p.default for p in METHODS[method_name].params}


def now_ms():
    return time.perf_counter() * 1000.0
