"""Editor sessions: one per browser tab, isolated from each other.

A session holds the control points, the chosen method and its parameters, the method adapters'
state, the latest solution and the files it exported. Edits (move, add, remove, lock a control
point; change method or parameters) are applied at once and bump ``version``; a solve works on a
snapshot and polls ``version`` to stop when a newer edit has arrived.
"""
from __future__ import annotations

import contextlib
import math
import os
import re
import secrets
import threading
import time
from dataclasses import dataclass

import numpy as np

from ..errors import RetimeError
from ..io_util import all_or_none
from ..motion import save_bvh
from ..warp import apply_timing, output_duration
from .methods import ADAPTERS, Clip, ControlPoint, Job, Solution, check_params, default_params

MAX_POINTS = 200
MAX_OPS = 64  # edits in one message
EDIT_FIELDS = ("op", "index", "t", "s", "hold", "locked", "method", "values", "duration")
OP_LOG = 4096  # edits remembered for stateful methods to replay (older: they resync from the points)
S_GAP = 1e-3  # seconds: neighbouring control points' source times differ at least this much
MIN_SPEED, MAX_SPEED = 1 / 20, 20.0  # the duration may change by this factor at the most


@dataclass
class Snapshot:
    version: int
    method: str
    points: list[ControlPoint]
    params: dict
    duration: float
    ops: list  # every (version, op) applied so far that a stateful method may still need to replay
    held: int | None = None  # the control point the user is holding (dragging), if any
    keytimes: list = None  # (source, output) keytimes kept apart from the points (physics)


class Session:
    def __init__(self, sid: str, clip: Clip, outdir, fps: float, stopping: threading.Event | None = None):
        self.id = sid
        self.clip = clip
        self.outdir = outdir
        self.fps = fps
        S = clip.motion.duration
        self.points = [ControlPoint(0.0, 0.0, True), ControlPoint(S, S, True)]
        self.method = "linear"
        self.params = {name: default_params(name, clip) for name in ADAPTERS}
        self.adapters = {}
        self.version = 0
        self.solution: Solution | None = None
        self.solution_version = -1
        self._good = None  # (method, points, params) of the last state that solved
        self.exports: dict[str, object] = {}
        self.lock = threading.RLock()
        self.solve_lock = threading.Lock()  # one solve at a time per session (adapters keep state)
        self.closed = threading.Event()  # it was evicted: its solves stop
        self.stopping = stopping or threading.Event()  # the editor is stopping: every solve stops
        self.last_used = time.monotonic()
        self.op_log: list[tuple[int, dict]] = []  # (version, op) for stateful adapters; bounded
        self.held = None
        self.keytimes: list[tuple[float, float]] = []  # (source, output) kept apart from points (physics)

    # -- edits ----------------------------------------------------------------------------------
    @property
    def source_duration(self):
        return self.clip.motion.duration

    @property
    def duration(self):
        return self.points[-1].t

    def apply(self, ops) -> int:
        """Apply a list of edits atomically (all or none); returns the new version."""
        if not isinstance(ops, list):
            ops = [ops]
        if len(ops) > MAX_OPS:
            raise RetimeError(f"too many edits in one message ({len(ops)}; at most {MAX_OPS})")
        with self.lock:
            points = [ControlPoint(p.t, p.s, p.locked) for p in self.points]
            method, params = self.method, {k: dict(v) for k, v in self.params.items()}
            held = self.held
            self._merged = False
            self._kt = list(self.keytimes)  # edited alongside the points, kept only if all edits apply
            for op in ops:
                method = self._apply_one(op, points, method, params)
                if op["op"] == "move":
                    held = op["index"] if op.get("hold") else None
                elif op["op"] in ("release", "add", "remove", "reset", "duration", "method"):
                    held = None
            self.points, self.method, self.params, self.held = points, method, params, held
            self.keytimes = [] if self._merged else self._kt
            self.version += 1
            # only the fields an edit has: a page's extra fields (or junk) are not kept for ever
            self.op_log.extend((self.version, self._logged(op)) for op in ops)
            del self.op_log[:-OP_LOG]
            self.last_used = time.monotonic()
            return self.version

    def _logged(self, op):
        out = {k: op[k] for k in EDIT_FIELDS if k in op}
        if isinstance(out.get("values"), dict):  # only the method's own, checked settings
            known = self.params.get(out.get("method", self.method), {})
            out["values"] = {k: known[k] for k in out["values"] if k in known}
        return out

    def _apply_one(self, op, points, method, params):
        if not isinstance(op, dict) or not isinstance(op.get("op"), str):
            raise RetimeError("each edit must be an object with an 'op' field")
        kind = op["op"]
        if kind == "move":
            i = self._index(op, points)
            spline = ADAPTERS[method].point_axes == "s"  # knots fixed in normalized time
            t = _num(op, "t") if not spline or i == len(points) - 1 else points[i].t
            self._move(points, i, t, _num(op, "s"), scale_inner=spline)
            if ADAPTERS[method].edits_are_keytimes and 0 < i < len(points) - 1:
                points[i].locked = True
        elif kind == "add":
            self._add(points, _num(op, "t"), _num(op, "s"),
                      bool(op.get("locked", False)) or ADAPTERS[method].edits_are_keytimes)
        elif kind == "remove":
            i = self._index(op, points)
            if i in (0, len(points) - 1):
                raise RetimeError("the first and last control points cannot be removed")
            del points[i]
        elif kind == "lock":
            i = self._index(op, points)
            if i in (0, len(points) - 1):
                raise RetimeError("the first and last control points are always locked")
            points[i].locked = bool(op.get("locked", True))
        elif kind == "method":
            name = op.get("method")
            if name not in ADAPTERS:
                raise RetimeError(f"unknown method {name!r}; choose one of {', '.join(ADAPTERS)}")
            reason = ADAPTERS[name].availability(self.clip)
            if reason:
                raise RetimeError(reason)
            if ADAPTERS[name].point_axes == "ts" and self._kt and not self._merged:
                self._merge_keytimes(points)
            method = name
        elif kind == "params":
            name = op.get("method", method)
            checked = check_params(name, op.get("values", {}), self.clip)
            params.setdefault(name, default_params(name, self.clip)).update(checked)
        elif kind == "duration":
            self._set_duration(points, _num(op, "duration"))
        elif kind == "release":
            pass  # the user let go of a dragged point (stateful methods may move it again)
        elif kind == "reset":
            S = self.source_duration
            points[:] = [ControlPoint(0.0, 0.0, True), ControlPoint(S, S, True)]
            self._merged = True  # (drops the keytimes)
        else:
            raise RetimeError(f"unknown edit {kind!r}")
        return method

    def _merge_keytimes(self, points):
        """Keytimes a method kept apart (physics) become locked points again for the other methods;
        points within a frame of one give way to it."""
        gap = self._gap()
        for src, out in self._kt:
            points[:] = [p for i, p in enumerate(points) if i in (0, len(points) - 1) or abs(p.t - out) >= gap]
            k = int(np.searchsorted([p.t for p in points], out))
            if 0 < k < len(points) and points[k - 1].s < src < points[k].s:
                points.insert(k, ControlPoint(float(out), float(src), True))
            else:  # not monotone with the points around it: those give way too
                points[:] = [p for i, p in enumerate(points) if i in (0, len(points) - 1)
                             or (p.t < out and p.s < src) or (p.t > out and p.s > src)]
                k = int(np.searchsorted([p.t for p in points], out))
                points.insert(k, ControlPoint(float(out), float(src), True))
        self._merged = True

    @staticmethod
    def _index(op, points):
        i = op.get("index")
        if not isinstance(i, int) or isinstance(i, bool) or not (0 <= i < len(points)):
            raise RetimeError(f"no control point {i!r} (there are {len(points)})")
        return i

    def _gap(self):
        return 1.0 / self.fps

    def _move(self, points, i, t, s, scale_inner=False):
        """Move point i, clamped so that the curve stays monotone (the ends keep their source time)."""
        gap, n = self._gap(), len(points)
        if i == 0:
            return  # (0, 0) is fixed
        if i == n - 1:
            self._set_duration(points, t, scale_inner=scale_inner, clamp=True)
            return
        lo_t, hi_t = points[i - 1].t + gap, points[i + 1].t - gap
        lo_s, hi_s = points[i - 1].s + S_GAP, points[i + 1].s - S_GAP
        if lo_t > hi_t or lo_s > hi_s:
            return
        points[i].t = float(np.clip(t, lo_t, hi_t))
        points[i].s = float(np.clip(s, lo_s, hi_s))

    def _add(self, points, t, s, locked):
        if len(points) >= MAX_POINTS:
            raise RetimeError(f"at most {MAX_POINTS} control points")
        gap = self._gap()
        if not (gap <= t <= points[-1].t - gap):
            raise RetimeError(f"a new control point must lie inside the output (0 .. {points[-1].t:.3f} s)")
        k = int(np.searchsorted([p.t for p in points], t))
        if t - points[k - 1].t < gap or points[k].t - t < gap:
            raise RetimeError("too close to another control point (less than one frame apart)")
        if points[k].s - points[k - 1].s < 2 * S_GAP:
            raise RetimeError("no room between the neighbouring control points' source times")
        s = float(np.clip(s, points[k - 1].s + S_GAP, points[k].s - S_GAP))
        points.insert(k, ControlPoint(float(t), s, locked))

    def _set_duration(self, points, duration, scale_inner=True, clamp=False):
        S = self.source_duration
        lo, hi = max(S * MIN_SPEED, 2 / self.fps), S * MAX_SPEED
        if not (lo <= duration <= hi):
            if clamp:
                duration = float(np.clip(duration, lo, hi))
            else:
                raise RetimeError(f"duration {duration:g} s is outside {lo:.3g} .. {hi:.3g} s "
                                  f"(at most {MAX_SPEED:g} times faster or slower than the source)")
        T = output_duration(S, self.fps, duration=duration)  # the rule every door follows
        old = points[-1].t
        if scale_inner:
            for p in points[1:-1]:
                p.t *= T / old
            self._kt = [(src, out * T / old) for src, out in self._kt]
        elif len(points) > 2:
            T = max(T, points[-2].t + self._gap())
        points[-1].t = T
        points[-1].s = S
        # points squeezed closer than a frame apart by the scaling are dropped (the order stays valid)
        k = 1
        while k < len(points) - 1:
            if points[k].t - points[k - 1].t < self._gap() or points[-1].t - points[k].t < self._gap():
                del points[k]
            else:
                k += 1

    # -- solving --------------------------------------------------------------------------------
    def snapshot(self) -> Snapshot:
        with self.lock:
            return Snapshot(self.version, self.method, [ControlPoint(p.t, p.s, p.locked) for p in self.points],
                            dict(self.params.setdefault(self.method, default_params(self.method, self.clip))),
                            self.duration, list(self.op_log), self.held, list(self.keytimes))

    def adapter(self, name):
        if name not in self.adapters:
            self.adapters[name] = ADAPTERS[name](self.clip)
        return self.adapters[name]

    def solve(self, snap: Snapshot, cancelled=None, status=None, gone=None):
        """Run the method on a snapshot; yields solutions that are still current. Thread-safe.
        ``gone``: the page that asked has closed; the solve stops, as it does when the session is
        evicted or the editor stops (``stopping``)."""
        own = (lambda: self.version != snap.version) if cancelled is None else cancelled

        def ended():
            return self.stopping.is_set() or self.closed.is_set() or (gone is not None and gone())

        def stale():
            return ended() or own()

        with self.solve_lock:
            if stale():
                return
            adapter = self.adapter(snap.method)
            job = Job(snap.points, snap.params, snap.duration, stale, snap.version, snap.ops, snap.held,
                      status or (lambda message: None), list(snap.keytimes or []),
                      gone=ended)
            try:
                for sol in adapter.solve(job):
                    with self.lock:
                        if self.version != snap.version:
                            return
                        if sol.points is not None and sol.final:
                            self.points = [ControlPoint(p.t, p.s, p.locked) for p in sol.points]
                        if sol.final:
                            self.solution, self.solution_version = sol, snap.version
                            if sol.keytimes is not None:
                                self.keytimes = [(float(a), float(b)) for a, b in sol.keytimes]
                            self._good = (self.method, [ControlPoint(p.t, p.s, p.locked) for p in self.points],
                                          {k: dict(v) for k, v in self.params.items()})
                    yield sol
                    if stale():
                        return
            except Exception:
                self._revert(snap)
                raise

    def _revert(self, snap):
        """A solve failed: go back to the last state that solved (if nothing newer came meanwhile)."""
        with self.lock:
            if self.version == snap.version and self._good is not None:
                self.method, points, params = self._good
                self.points = [ControlPoint(p.t, p.s, p.locked) for p in points]
                self.params = {k: dict(v) for k, v in params.items()}
                self.version += 1

    def solve_now(self) -> Solution:
        """Solve the current state to the end (for the HTTP API)."""
        for _ in range(8):
            snap = self.snapshot()
            final = None
            for sol in self.solve(snap):
                if sol.final:
                    final = sol
            if final is not None:
                return final
        raise RetimeError("the session kept changing while it was being solved; try again")

    def solution_json(self, sol: Solution, snap: Snapshot | None = None, seq=None):
        fps = self.fps
        curve = sol.curve
        t = curve.frame_times(fps)
        s = curve(t)
        s[-1] = curve.source_duration
        speed = np.asarray(curve.speed(t), dtype=float)
        points = sol.points if sol.points is not None else (snap.points if snap else self.points)
        out = {
            "type": "solution", "seq": seq, "version": snap.version if snap else self.version,
            "final": sol.final, "method": snap.method if snap else self.method,
            "params": dict(snap.params) if snap else dict(self.params.get(self.method, {})),
            "duration": curve.duration, "source_duration": curve.source_duration,
            "points": [p.to_json() for p in points],
            "curve": {"t": _round(t), "s": _round(s)},
            "speed": _round(np.maximum(speed, 0.0)),
            "feasibility": None if sol.feasibility is None else _round(np.asarray(sol.feasibility, float), 4),
            "keytimes": [[round(a, 6), round(b, 6)] for a, b in (sol.keytimes or [])],
            "info": _jsonable(sol.info),
        }
        return out

    # -- export ---------------------------------------------------------------------------------
    def export(self):
        """Write the retimed BVH and the warp CSV of the current solution into the output folder."""
        with self.lock:
            sol = self.solution if self.solution_version == self.version else None
            method = self.method
        if sol is None:
            sol = self.solve_now()
        motion = self.clip.motion
        retimed = apply_timing(motion, sol.curve)
        stem = re.sub(r"[^A-Za-z0-9_-]+", "_", self.clip.name)[:40] or "motion"
        bvh, csv = _reserve_pair(self.outdir, f"{stem}-{method}")
        try:
            with all_or_none():  # both files or neither (a full disk leaves no BVH without its CSV)
                save_bvh(retimed, bvh)
                sol.curve.to_csv(csv, motion.fps)
        except BaseException as e:
            for path in (bvh, csv):
                with contextlib.suppress(OSError):
                    path.unlink()
            if isinstance(e, OSError):
                raise RetimeError(f"{self.outdir}: cannot write the export ({e.strerror or e}); nothing was written") from None
            raise
        files = []
        for path in (bvh, csv):
            self.exports[path.name] = path
            files.append({"name": path.name, "bytes": path.stat().st_size})
        return {"files": files, "frames": retimed.n_frames, "duration": retimed.duration, "folder": str(self.outdir)}


def _reserve_pair(outdir, prefix):
    """(bvh, csv) paths of a new export, reserved atomically: both names are created empty with
    O_EXCL, so concurrent exports never share a name (the writes then replace them)."""
    for k in range(1, 10000):
        paths = [outdir / f"{prefix}-{k:03d}.bvh", outdir / f"{prefix}-{k:03d}.csv"]
        made = []
        try:
            for path in paths:
                os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
                made.append(path)
            return paths[0], paths[1]
        except FileExistsError:
            for path in made:
                with contextlib.suppress(OSError):
                    path.unlink()
        except OSError as e:
            for path in made:
                with contextlib.suppress(OSError):
                    path.unlink()
            raise RetimeError(f"{outdir}: cannot write the export ({e.strerror or e})") from None
    raise RetimeError(f"{outdir}: too many exports already; clean up the output folder")


def _num(op, key):
    v = op.get(key)
    try:
        ok = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
    except OverflowError:  # an integer of hundreds of digits
        ok = False
    if not ok:
        raise RetimeError(f"edit {op.get('op')!r}: {key} must be a finite number")
    return float(v)


def _round(a, digits=6):
    return np.round(np.asarray(a, dtype=float).ravel(), digits).tolist()


def _jsonable(info):
    out = {}
    for k, v in (info or {}).items():
        if isinstance(v, (np.floating, np.integer)):
            v = v.item()
        if isinstance(v, float) and not np.isfinite(v):
            v = None
        if isinstance(v, (str, int, float, bool)) or v is None:
            out[str(k)] = v
    return out


class SessionStore:
    """Sessions by unguessable id; bounded in number, idle ones expire."""

    def __init__(self, clip: Clip, outdir, fps, max_sessions=64, idle_seconds=6 * 3600):
        self.clip, self.outdir, self.fps = clip, outdir, fps
        self.max_sessions, self.idle_seconds = max_sessions, idle_seconds
        self.sessions: dict[str, Session] = {}
        self.lock = threading.Lock()
        self.stopping = threading.Event()  # set at shutdown

    def create(self) -> Session:
        with self.lock:
            self._expire()
            if len(self.sessions) >= self.max_sessions:
                oldest = min(self.sessions.values(), key=lambda s: s.last_used)
                oldest.closed.set()
                del self.sessions[oldest.id]
            sid = secrets.token_urlsafe(18)
            session = Session(sid, self.clip, self.outdir, self.fps, stopping=self.stopping)
            self.sessions[sid] = session
            return session

    def get(self, sid) -> Session | None:
        with self.lock:
            s = self.sessions.get(sid) if isinstance(sid, str) else None
            if s is not None:
                s.last_used = time.monotonic()
            return s

    def _expire(self):
        now = time.monotonic()
        for sid in [k for k, s in self.sessions.items() if now - s.last_used > self.idle_seconds]:
            self.sessions[sid].closed.set()
            del self.sessions[sid]
