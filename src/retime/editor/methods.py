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

import math
import threading
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from ..errors import RetimeError
from ..guided.method import Settings as GuidedSettings
from ..method import Request, session, solve
from ..physics.constants import G
from ..physics.method import OBJECTIVES, Settings as PhysicsSettings
from ..warp import TimingCurve


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
    kind: str  # "number", "slider" (a number shown as a slider), "choice", "bool"
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
        if self.kind in ("number", "slider"):
            d.update(min=self.min, max=self.max, step=self.step)
        if self.kind == "choice":
            d["choices"] = [list(c) for c in self.choices]
        return d

    def check(self, value):
        """The value converted and checked; RetimeError with a readable message if it is not valid."""
        if self.kind in ("number", "slider"):
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise RetimeError(f"{self.label}: {str(value)[:40]!r} is not a number") from None
            except OverflowError:  # an integer of hundreds of digits
                raise RetimeError(f"{self.label}: a number too large (must be finite)") from None
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
    status: Callable[[str], None] = lambda message: None  # progress line for the page (long steps)
    keytimes: list = field(default_factory=list)  # (source, output) kept apart from the points (physics)
    gone: Callable[[], bool] = lambda: False  # the tab has closed or the editor stops: stop shared work too

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
    keytimes: list | None = None  # (source, output) constraints that are not control points (physics)


class Method:
    """Base adapter. Subclasses set ``name``, ``label``, ``params`` and implement ``solve``."""

    name = ""
    label = ""
    description = ""
    params: tuple[Param, ...] = ()
    point_axes = "ts"  # which way the page lets interior control points move: "ts" both, "s" vertically
    edits_are_keytimes = False  # True: a point the user moves or adds becomes a keytime (locked)

    def __init__(self, clip: Clip):
        self.clip = clip

    @classmethod
    def param_specs(cls, clip: Clip) -> tuple[Param, ...]:
        """The parameters shown for this clip (some depend on its skeleton)."""
        return cls.params

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
        from ..linear import Settings

        request = Request(duration=job.duration, keytimes=keytimes_of(job.points),
                          settings=Settings(smooth=bool(job.params.get("smooth", False))))
        yield Solution(solve("linear", self.clip.motion, request).curve, info={"keytimes": len(job.points) - 2})


class GuidedMethod(Method):
    """Guided time warping (Hsu et al. 2007): the locked points are keytimes; the dynamic program fills in."""

    name = "guided"
    label = "Guided"
    description = ("Keytimes (locked points) plus a reference: the warp whose local velocities and accelerations "
                   "best match the reference, by exact dynamic programming (Hsu et al. 2007). Points you move or add "
                   "become keytimes; unlocked points follow the solution.")
    edits_are_keytimes = True
    _d = GuidedSettings()  # the defaults are Settings'
    params = (
        Param("reference", "Reference", "choice", "self",
              choices=(("self", "the motion itself (keep its timing)"), ("reference", "the --reference motion"))),
        Param("max_skip", "Skip limit", "number", float(_d.max_skip), 1.0, 32.0, 1.0, "frames",
              help="most analysis frames one output frame may advance (Hsu §3.1)"),
        Param("neighbors", "Neighbours", "number", float(_d.neighbors), 1.0, 10.0, 1.0,
              help="k nearest reference features (Hsu §4.3)"),
        Param("fast", "Coarse-to-fine", "bool", _d.fast, help="the heuristic of Hsu §3.3 instead of the exact search"),
        Param("blend", "Reference influence", "slider", _d.blend, 0.0, 1.0, 0.05,
              help="0: the smooth spline through the keytimes; 1: the guided warp; between: a mix (Hsu §5)"),
        Param("pace", "Pace pull", "number", float(_d.pace), 0.0, 100.0, 1.0,
              help="pulls walks and runs to one steady speed (a jump's flight keeps its own); 0: the reference's own pace"),
    )

    def solve(self, job):
        params = job.params
        reference = None
        if params.get("reference") == "reference":
            if self.clip.reference is None:
                raise RetimeError("no reference motion: start the editor with --reference REF to use one")
            reference = self.clip.reference
        keys = keytimes_of(job.points, locked_only=True)
        given = {k: type(getattr(self._d, k))(params[k]) for k in ("max_skip", "neighbors", "fast", "blend", "pace")
                 if k in params}
        settings = GuidedSettings(reference=reference, **given)
        result = solve("guided", self.clip.motion, Request(duration=job.duration, keytimes=keys, settings=settings))
        curve = result.curve
        info = {"keytimes": len(keys), "objective": result.info["objective"], "exact": result.info["exact"]}
        yield Solution(curve, points=_follow(job.points, curve), info=info)


def _follow(points, curve):
    """Unlocked control points moved onto the solved curve (their output time kept)."""
    out = []
    for i, p in enumerate(points):
        if p.locked or i == 0 or i == len(points) - 1:
            out.append(ControlPoint(p.t, p.s, p.locked))
        else:
            out.append(ControlPoint(p.t, float(curve(p.t)), False))
    return out


class PhysicsMethod(Method):
    """Physics-based retiming (McCann et al. 2006) as an interactive session (§3.6).

    The control points are the timing spline's (their output times are knots, so they move only
    vertically); locking one holds it (a constraint for the optimizer); the point being dragged is
    held while the user holds it and let go afterwards, so the optimizer may pull it back ("fight
    with or help the optimizer"). Locked points of another method become keytimes when the physics
    session is (re)built: on switching to it, or when the duration or a parameter changes. Dynamics
    and feasible regions are computed once per clip and setting and shared by all sessions."""

    name = "physics"
    label = "Physics"
    description = ("The timing that keeps the motion physically plausible (contact forces, joint torques) for the "
                   "new duration, keytimes, gravity or masses (McCann et al. 2006). Points move vertically.")
    point_axes = "s"
    _d = PhysicsSettings()  # the defaults are Settings'
    MAX_ITER = 300
    RUN_SECONDS = 2.0
    QUICK_SECONDS = 0.06
    MAX_RUNS = 4

    @classmethod
    def param_specs(cls, clip):
        parts = [("none", "none (all masses as estimated)")] + [(n, f"{n} and below") for n in _limb_roots(clip)]
        return (
            Param("gravity", "Gravity", "number", G, 0.5, 40.0, 0.1, "m/s²", help="strength of gravity (down)"),
            Param("objective", "Objective", "choice", cls._d.objective,
                  choices=tuple(zip(OBJECTIVES, ("match the original torques", "minimize torques")))),
            Param("mass_part", "Heavier / lighter part", "choice", "none", choices=tuple(parts)),
            Param("mass_factor", "Mass factor", "number", 1.0, 0.1, 10.0, 0.1, "×", help="that part's mass times this"),
            Param("alpha", "Feasibility weight", "number", cls._d.alpha, 0.1, 10000.0, 1.0,
                  help="α of Eq. 14 (torque matching has weight 1)"),
        )

    def __init__(self, clip):
        super().__init__(clip)
        self.rs = None  # the physics RetimingSession
        self.key = None
        self.seen = None  # the session version whose edits rs reflects
        self.temp_lock = None  # index locked only because the user is holding it

    def _key(self, params):
        return (float(params.get("gravity", G)), params.get("objective", self._d.objective),
                params.get("mass_part", "none"), float(params.get("mass_factor", 1.0)),
                float(params.get("alpha", self._d.alpha)))

    def _build(self, job, key):
        keytimes = {(round(p.s, 9), round(p.t, 9)) for p in job.points[1:-1] if p.locked}
        keytimes = sorted(keytimes | {(round(a, 9), round(b, 9)) for a, b in job.keytimes})
        request = Request(duration=job.duration, keytimes=keytimes, settings=self._settings(key))
        self.rs = _physics_session(self.clip, request, job.status, job.gone)
        self.key, self.temp_lock = key, None

    def _settings(self, key):
        """The physics Settings of the page's controls: gravity is a strength down the clip's up axis."""
        gravity, objective, part, factor, alpha = key
        masses = {}
        if part != "none" and factor != 1.0:
            sk = self.clip.motion.skeleton
            root = sk.index(part)
            masses = {sk.names[j]: factor for j in range(sk.n_joints) if _descends(sk.parents, j, root)}
        return PhysicsSettings(gravity_scale=gravity / G, mass_factors=masses, objective=objective, alpha=alpha)

    def _replay(self, ops):
        rs = self.rs
        for op in ops:
            kind = op["op"]
            n = len(rs.control_points())
            if kind in ("method", "reset", "duration"):
                return False  # (a parameter change shows in the key)
            if kind == "move":
                i = op["index"]
                if i == n - 1:
                    return False  # a new duration: rebuild
                if not 0 < i < n - 1:
                    continue
                if self.temp_lock is not None and self.temp_lock != i:
                    self._let_go()
                hold = bool(op.get("hold"))
                was_locked = rs.is_locked(i)
                rs.move(i, op["s"], lock=hold)
                if hold and not was_locked:
                    self.temp_lock = i
            elif kind == "release":
                self._let_go()
            elif kind == "add":
                self._let_go()
                i = rs.add(op["t"])
                rs.move(i, op["s"], lock=bool(op.get("locked")))
            elif kind == "remove":
                self._let_go()
                if 0 < op["index"] < n - 1:
                    rs.remove(op["index"])
            elif kind == "lock":
                if self.temp_lock == op["index"]:
                    self.temp_lock = None
                rs.lock(op["index"], bool(op.get("locked", True)))
        return True

    def _let_go(self):
        if self.temp_lock is not None:
            self.rs.lock(self.temp_lock, False)
            self.temp_lock = None

    def solve(self, job):
        key = self._key(job.params)
        ops = job.ops_since(self.seen) if self.rs is not None and key == self.key else None
        if ops is None or not self._replay(ops):
            self._build(job, key)
        self.seen = job.version
        if job.held is None:
            self._let_go()
        if job.cancelled():
            return
        # a short first run: a drag usually re-converges within it, and then the optimum is the only
        # message (an intermediate one would cost the page a redraw before the answer it waits for)
        info = self.rs.reconverge(max_iter=self.MAX_ITER, max_seconds=self.QUICK_SECONDS, quick=True)
        if job.cancelled():
            return
        if info.converged:
            yield self._solution(info, final=True)
            return
        yield self._solution(info, final=False)
        # warm-started optimizer runs; a newer edit cancels between runs (the loop then solves the newest
        # state). Runs are long enough for the augmented Lagrangian to converge (restarting it often
        # would not), and bounded so that a hard case still shows progress.
        for k in range(self.MAX_RUNS):
            info = self.rs.reconverge(max_iter=self.MAX_ITER, max_seconds=self.RUN_SECONDS)
            if job.cancelled():
                return
            if info.converged or k == self.MAX_RUNS - 1:
                break
            yield self._solution(info, final=False)
        yield self._solution(info, final=True)

    def _solution(self, info, final):
        rs = self.rs
        fps = self.clip.motion.fps
        curve = rs.curve(fps)
        pts = [ControlPoint(p["output_time"], p["source_time"], bool(p["locked"])) for p in rs.control_points()]
        pts[0] = ControlPoint(0.0, 0.0, True)
        pts[-1] = ControlPoint(curve.duration, curve.source_duration, True)
        out = {"objective": info.objective, "iterations": info.iterations, "converged": info.converged,
               "keytimes": len(rs.keytimes), "constraint_violation": info.constraint_violation}
        feas = None
        if final:
            found = rs.feasibility(fps)
            feas = strip_shade(found.residual, found.tol)
            out["feasible_fraction"] = round(found.fraction, 4)
        return Solution(curve, points=pts, feasibility=feas, info=out, final=final, keytimes=list(rs.keytimes))


def strip_shade(residual, tol):
    """The page's strip per output frame: 1 in the region (residual within tol), falling to 0 at 100 x
    tol (a log scale of the residual, capped at 0.95 outside)."""
    r = np.asarray(residual, dtype=float)
    return np.where(r <= tol, 1.0, np.clip(1.0 - np.log10(np.maximum(r, tol) / tol) / 2.0, 0.0, 0.95))


_PHYSICS_CACHE: dict = {}  # (id(motion), settings) -> a session's .shared (retime.physics.method.Shared); a few
_CACHE_LOCK = threading.Lock()  # guards the cache and the per-setting locks, never a computation
_SETTING_LOCKS: dict = {}


def _physics_session(clip, request, status, gone=lambda: False):
    """A live physics session of the clip (:func:`retime.method.session`). Its dynamics, regions and
    objective (``.shared``) are computed once per clip and setting and shared by the sessions that
    follow. Different settings compute side by side (each computation owns its solver state); one
    setting is computed by one thread while the others wait for it. ``gone``: the asking session's
    tab has closed or the editor is stopping; the computation then stops."""
    cache_key = (id(clip.motion), _hashable(request.settings))
    with _CACHE_LOCK:
        shared = _PHYSICS_CACHE.get(cache_key)
        setting_lock = _SETTING_LOCKS.setdefault(cache_key, threading.Lock())
    if shared is not None:
        return session("physics", clip.motion, request, shared=shared)
    with setting_lock:
        with _CACHE_LOCK:
            shared = _PHYSICS_CACHE.get(cache_key)
            # else a session under another setting lends its body dynamics; the regions are this setting's
            other = next((v for (m, _), v in _PHYSICS_CACHE.items() if m == id(clip.motion)), None)
        if shared is not None:
            return session("physics", clip.motion, request, shared=shared)
        status("physics: computing the motion's dynamics and feasible regions (once per setting)…")
        try:
            live = session("physics", clip.motion, request, shared=other, cancel=gone)
            out = live.shared
        except BaseException:  # failed or cancelled: nothing cached, so no lock kept for it either
            with _CACHE_LOCK:
                _SETTING_LOCKS.pop(cache_key, None)
            raise
        with _CACHE_LOCK:
            if len(_PHYSICS_CACHE) >= 6:
                old = next(iter(_PHYSICS_CACHE))
                _PHYSICS_CACHE.pop(old)
                _SETTING_LOCKS.pop(old, None)
            _PHYSICS_CACHE[cache_key] = out
        status("")
        return live


def _hashable(settings):
    """A settings' cache key (its mass factors are a dict)."""
    return tuple((k, tuple(sorted(v.items())) if isinstance(v, dict) else v) for k, v in vars(settings).items())


def _descends(parents, j, root):
    while j >= 0:
        if j == root:
            return True
        j = int(parents[j])
    return False


def _limb_roots(clip):
    """Joints that start a limb (a child of the root or of a branching joint), for mass changes."""
    sk = clip.motion.skeleton
    parents = [int(p) for p in sk.parents]
    n_children = [parents.count(j) for j in range(len(parents))]
    return [sk.names[j] for j in range(1, len(parents))
            if parents[j] >= 0 and (parents[j] == 0 or n_children[parents[j]] > 1) and n_children[j] > 0]


ADAPTERS: dict[str, type[Method]] = {m.name: m for m in (LinearMethod, GuidedMethod, PhysicsMethod)}


def register(method_cls: type[Method]) -> None:
    ADAPTERS[method_cls.name] = method_cls


def method_catalog(clip: Clip):
    out = []
    for cls in ADAPTERS.values():
        reason = cls.availability(clip)
        out.append({"name": cls.name, "label": cls.label, "description": cls.description,
                    "available": reason is None, "reason": reason, "point_axes": cls.point_axes,
                    "params": [p.to_json() for p in cls.param_specs(clip)]})
    return out


def check_params(method_name, values: dict, clip: Clip) -> dict:
    cls = ADAPTERS.get(method_name)
    if cls is None:
        raise RetimeError(f"unknown method {method_name!r}; choose one of {', '.join(ADAPTERS)}")
    if not isinstance(values, dict):
        raise RetimeError("parameters must be a JSON object")
    known = {p.name: p for p in cls.param_specs(clip)}
    unknown = sorted(set(values) - set(known))
    if unknown:
        raise RetimeError(f"{cls.label} has no parameter {unknown[0]!r}")
    return {name: p.check(values[name]) for name, p in known.items() if name in values}


def default_params(method_name, clip: Clip) -> dict:
    return {p.name: p.default for p in ADAPTERS[method_name].param_specs(clip)}
