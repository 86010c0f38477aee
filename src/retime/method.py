"""The one contract every timing method follows: a motion and a :class:`Request` in, a
:class:`Result` (timing curve, report, solver info) out.

    from retime.method import Request, solve
    from retime.warp import apply_timing

    result = solve("physics", motion, Request(scale=0.5))
    retimed = apply_timing(motion, result.curve)
    result.report.summary["feasible_fraction"]

A method is one module (``retime.linear.method``, ``retime.guided.method``,
``retime.physics.method``) with

* ``NAME``: what the command line and the editor call it;
* ``Settings``: a dataclass of the method's own options, every field with a default;
* ``solve(motion, request) -> Result``;
* optionally ``session(motion, request, ...)``: a live session for an editor (:func:`session`).

Adding a method is writing such a module and naming it in :data:`METHODS`.
The command line, the demo, the editor and the batch runner call methods only through here.
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field, fields
from typing import Any

from .errors import RetimeError
from .warp import TimingCurve, output_duration

#: method name -> module implementing the contract (imported on first use: a method's compiled
#: kernels load only when it is asked for)
METHODS: dict[str, str] = {
    "linear": "retime.linear.method",
    "guided": "retime.guided.method",
    "physics": "retime.physics.method",
}


@dataclass(frozen=True)
class Request:
    """What to retime to. ``duration`` (output seconds) or ``scale`` (output lasts ``scale`` times
    the source; 0.5 = twice as fast), or neither: the method's default (the source's duration for
    linear and guided, a free duration for physics). ``keytimes``: (source s, output s) pairs the
    curve passes through. ``settings``: the method's own ``Settings`` (None: its defaults)."""

    duration: float | None = None
    scale: float | None = None
    keytimes: tuple = ()
    settings: Any = None

    def __post_init__(self):
        if self.duration is not None and self.scale is not None:
            raise RetimeError("give a duration or a scale, not both")
        for name in ("duration", "scale"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise RetimeError(f"{name} must be a positive number, got {value!r}")
        object.__setattr__(self, "keytimes", tuple((float(s), float(t)) for s, t in self.keytimes))

    def output_duration(self, motion) -> float | None:
        """The requested duration on the output frame grid (None: not requested, a free duration);
        :func:`retime.warp.output_duration` is the rule."""
        return output_duration(motion.duration, motion.fps, self.duration, self.scale)

    def settings_or(self, settings_type):
        """The request's settings, checked to be the method's own type (its defaults when None)."""
        if self.settings is None:
            return settings_type()
        if not isinstance(self.settings, settings_type):
            raise RetimeError(f"settings must be {settings_type.__module__}.{settings_type.__qualname__}, "
                              f"got {type(self.settings).__name__}")
        return self.settings


@dataclass
class Report:
    """What a method says about its curve, in one schema for every method.

    ``summary`` always holds ``method``, ``source_duration``, ``duration``, ``output_frames``,
    ``mean_speed``, ``phases`` (each: ``state``, ``source_start``, ``source_end``, ``output_start``,
    ``output_end``, ``speed``; stance and flight for physics, the stretches between keytimes for
    linear and guided), ``timings`` (seconds per stage; ``compile`` is the compiler's, apart from
    the method's), ``warnings`` and ``notes``; a method adds its own figures (physics:
    ``feasible_fraction``; guided: ``objective``). ``frames``: one record per output frame where the
    method has per-frame numbers (physics), else empty."""

    summary: dict
    frames: list = field(default_factory=list)

    def to_json(self) -> dict:
        return {"summary": self.summary, "frames": self.frames}


@dataclass
class Result:
    """A method's answer. ``info``: the solver's own figures (iterations, convergence, exactness);
    ``detail``: the method's full result (:class:`retime.guided.GuidedResult`,
    :class:`retime.physics.PhysicsResult`) for callers that go on from it (plots, sessions)."""

    curve: TimingCurve
    report: Report
    info: dict = field(default_factory=dict)
    detail: Any = None


def summary(method: str, curve: TimingCurve, fps: float, phases: list, timings: dict, warnings=(), notes=(),
            **extra) -> dict:
    """A report summary with the fields every method gives (see :class:`Report`); ``fps``: the
    output's frame rate."""
    T, S = curve.duration, curve.source_duration
    out = {"method": method, "source_duration": round(float(S), 6), "duration": round(float(T), 6),
           "output_frames": curve.n_frames(fps),
           "mean_speed": round(float(S / T), 4) if T > 0 else None,
           "phases": phases, "timings": {k: round(float(v), 4) for k, v in timings.items()},
           "warnings": list(warnings), "notes": list(notes)}
    out.update(extra)
    return out


def module(name: str):
    """The module implementing method ``name``."""
    if name not in METHODS:
        raise RetimeError(f"unknown method {name!r}; choose one of {', '.join(METHODS)}")
    return importlib.import_module(METHODS[name])


def settings_type(name: str):
    return module(name).Settings


def solve(name: str, motion, request: Request | None = None) -> Result:
    """Retime ``motion`` with method ``name`` (see the module docstring)."""
    request = Request() if request is None else request
    return module(name).solve(motion, request)


def session(name: str, motion, request: Request | None = None, **options):
    """A live session of method ``name`` on ``motion`` for an editor: edits of the curve's control
    points and re-convergence from the current solution, for the methods that keep state between
    edits (``retime.physics.method.session``; ``options``: what that method's session takes, e.g. the
    ``shared`` computations of an earlier session)."""
    request = Request() if request is None else request
    mod = module(name)
    if not hasattr(mod, "session"):
        raise RetimeError(f"{name} has no live session: each edit is solved again with solve()")
    return mod.session(motion, request, **options)


def settings_from(settings_type, options: dict):
    """A method's ``Settings`` from keyword options (what the keyword wrappers such as
    :func:`retime.physics.physics_warp` take), unknown names refused in one line."""
    known = {f.name for f in fields(settings_type)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise RetimeError(f"unknown option {unknown[0]!r}; {settings_type.__module__} takes {', '.join(sorted(known))}")
    return settings_type(**options)


def settings_record(settings, leave_out=()) -> dict:
    """A method's settings for its report, by reference (``asdict`` would deep-copy a reference
    motion or a contact table only to drop it)."""
    return {f.name: getattr(settings, f.name) for f in fields(settings) if f.name not in leave_out}
