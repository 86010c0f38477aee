"""Feasible timing regions (McCann et al. 2006, sec. 3.3).

At every sample of the path, the torques are linear in the retiming (Eq. 6) and in the contact force
coefficients lambda (Eq. 11)::

    tau = a p'' + b p'^2 + c - N lam,   lam >= 0,   lo <= tau <= hi          (Eq. 13)

with the root's six rows unactuated (lo = hi = 0). The **feasible region** of a frame is the projection
of this polytope in (p'', p'^2, lam) onto the (u, v) = (p'', p'^2) plane: a convex polygon. It is
computed per frame (:mod:`.frame_region`):

* **Rows that do not involve lam** (every row in flight, the arm and head rows in contact) are
  half-planes of the (u, v) plane and are intersected exactly in 2-D (no LP). The projection of the
  rest commutes with them, so they clip the LP's polygon afterwards.
* **Rows with lam** define a small LP in (u, v, lam). It is solved by HiGHS (``highspy``,
  :mod:`.highs_lp`), one ``Highs`` model per frame that keeps its basis; only the cost direction changes. Two ways of
  tracing the polygon:

  - ``solver="parametric"`` (default): HiGHS solves one LP per frame -- the centre LP (least contact
    force at the original timing, sec. 3.4) when the region has the source fit's rows, else "max
    p'^2" on the region's own rows (the noise band's); from its basis, a compiled phase-2
    primal simplex (:mod:`.simplex`) reaches the vertex of largest p'^2, and a parametric (shadow-vertex) simplex rotates
    the cost direction through 360 degrees from there, pivoting exactly at the angles where the basis
    stops being optimal. Every non-degenerate pivot lands on the next vertex of the projection, so the
    polygon is exact (to floating point). On numerical trouble (the walk stops short) it falls
    back to the refinement below.
  - ``solver="highs"``: adaptive refinement with HiGHS alone (Fig. 4): maximize in the four axis
    directions, then along the outward normal of every edge found so far; an edge is final when the
    LP cannot push past it by more than ``tol``, so the polygon is exact to ``tol`` (it always lies
    inside the true region).

* The (u, v) box ``|p''| <= u_max``, ``0 <= p'^2 <= v_max`` bounds the search (a still frame accepts
  any timing; the box stands for "anything reasonable").

**Relaxation: the data's own inconsistency is the yardstick.** Motion capture with an estimated
body is never exactly physical: in flight the centre-of-mass acceleration of the captured motion
differs from g from frame to frame (``retime check`` prints the median, ``flight_g``), and a foot may sit where it cannot quite carry the body.
Taken literally, the original timing would be infeasible at such frames, and a retiming with
unchanged physics would move away from it. So each frame gets a *residual budget*: the smallest row
residual (least weighted L1 over slack variables: 1 per newton of root force, 1 per newton-metre /
``moment_arm`` of root moment, ``actuated_slack_cost`` times that beyond a torque limit, all per body
weight = mass x 9.81 m/s^2) with which the **original timing (0, 1) under the original physics** is
feasible (:func:`source_fit`; zero at frames that are physical as captured). The frame's rows are
widened by that residual times p'^2 (the captured motion's inconsistency comes from its twice
differentiated accelerations and the estimated inertias, which scale with p'^2) plus ``relax_pad``
(1% of the body weight), for the original physics and for changed ones alike: a retiming is feasible
at a frame when it needs no more residual root wrench than the captured motion itself did at that
speed. With unchanged physics the original timing is therefore always feasible. Besides, every
frame's root rows may use a residual of ``allowance`` = 5% of the body weight under the current
gravity -- the modelling error biomechanics accepts for residual forces of captured motion.

**Capture-noise band.** A still stance played 4x faster has 16x its accelerations, and at such a
stance the captured accelerations are mostly sway and twice-differentiated marker noise: which of
the two decides whether a fast stance is feasible. So in stance (never in flight, where the parabola
is known well) the root rows are also widened by ``PathDynamics.b_noise`` p'^2: the local RMS
(over +-0.1 s) of how much their p'^2 coefficient b changes between the dynamics' low-pass and a
twice wider one (0.1 s), each difference capped at 2% of body weight (near a takeoff or a landing the
wide low-pass blurs real impacts). A timing is then
feasible if a path within the capture's own uncertainty can carry it. ``noise = False`` turns it off.
With unchanged physics the fan centre keeps the source fit's least-force lambda, so "match" still
costs nothing at the original timing.

If a region is still empty (changed physics can ask for more than the body can give), the smallest
extra residual is found the same way over all timings in the box, added with the pad, and reported
as ``relaxation`` (fraction of body weight); frames needing more than ``max_relaxation`` (5%) are
flagged ``implausible``. No frame is ever left without a region, so the optimizer never meets an
empty one. The bounds actually used are kept (``lo``, ``hi``) so that everything computed afterwards
can be checked against them.

Per frame the result also records ``source_residual`` (the budget in body weights: how far the
original timing is from feasible as captured) and ``source_distance`` (how far (0, 1) lies outside
the final region in the (p'', p'^2) plane; 0 with unchanged physics).

This module is the driver over all frames (:func:`compute_regions`); the pieces live apart:
:mod:`.polygon` (2-D geometry), :mod:`.simplex` (the compiled walk), :mod:`.highs_lp` (HiGHS) and
:mod:`.frame_region` (one frame, its relaxation and centre).
"""
from __future__ import annotations

import os
import threading
from dataclasses import dataclass, field

import numpy as np

from ...errors import RetimeError
from ..constants import G
from .frame_region import FrameRegion, RegionOptions, frame_region, row_weights, source_fit, unactuated_rows
from .highs_lp import HighsPool
from .polygon import polygon_distance, polygon_distances



@dataclass
class RegionSet:
    """Per-frame convex polygons in the (u, v) = (p'', p'^2) plane, with the contact model.

    Polygon ``i`` has vertices ``verts[offsets[i]:offsets[i+1]]`` in counter-clockwise order and the
    contact force coefficients ``lam`` (full width K, zero for unused columns) found at each of them.
    ``center[i]`` is the fan centre of sec. 3.4 (the original timing (0, 1) when it is feasible, else
    the nearest feasible point pulled slightly inwards) with ``center_lam[i]`` the least total contact
    force there (made unique: :func:`.forces.regularised_least_force`). ``lo``/``hi`` are the torque bounds actually used (widened on relaxed frames).
    """

    times: np.ndarray
    offsets: np.ndarray
    verts: np.ndarray
    lam: np.ndarray
    center: np.ndarray
    center_lam: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    budget: np.ndarray  # (n, nv) row residuals the captured motion needs (original physics)
    source_residual: np.ndarray  # (n,) their weighted sum, in body weights
    lam0: np.ndarray  # (n, K) contact coefficients of the original timing (original physics)
    relaxation: np.ndarray  # extra relaxation beyond the budget, fraction of body weight (0 = none)
    relaxed: np.ndarray
    implausible: np.ndarray
    source_distance: np.ndarray
    n_lp: np.ndarray  # LP solves per frame (HiGHS runs)
    n_pivots: np.ndarray  # parametric pivots per frame
    contact: np.ndarray
    options: RegionOptions = field(default_factory=RegionOptions)
    body_weight: float = 0.0
    seconds: float = 0.0

    @property
    def n_frames(self) -> int:
        return len(self.offsets) - 1

    def polygon(self, i: int) -> np.ndarray:
        return self.verts[self.offsets[i]:self.offsets[i + 1]]

    def polygon_lam(self, i: int) -> np.ndarray:
        return self.lam[self.offsets[i]:self.offsets[i + 1]]

    def contains(self, i: int, point, tol: float = 1e-9) -> bool:
        return polygon_distance(self.polygon(i), point) <= tol

    def distance(self, i: int, point) -> float:
        return polygon_distance(self.polygon(i), point)

    def distances(self, frames, u, v) -> np.ndarray:
        """Distance of each point (u[k], v[k]) to the region of frame ``frames[k]`` (0 inside), at once."""
        frames = np.asarray(frames, dtype=np.int64)
        u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
        out = np.empty(len(frames))
        polygon_distances(np.ascontiguousarray(self.verts, dtype=float), np.asarray(self.offsets, dtype=np.int64),
                          frames, np.ascontiguousarray(u), np.ascontiguousarray(v), out)
        return out


def estimate_body_weight(pd) -> float:
    """Body weight at standard gravity: total mass x 9.81 when known, else |root gravity force| (under
    ``pd.gravity``, y-up, m/s^2: the dynamics' own, scaled back to standard)."""
    if pd.total_mass:
        return float(pd.total_mass) * G
    n_root = unactuated_rows(pd)
    g = np.asarray(pd.gravity, dtype=float)
    if n_root >= 3:
        f = float(np.median(np.linalg.norm(np.asarray(pd.c)[:, :3], axis=1)))
        if np.linalg.norm(g) > 0:
            f *= G / float(np.linalg.norm(g))
        if f > 0:
            return f
    return float(np.median(np.linalg.norm(np.asarray(pd.c), axis=1))) or 1.0


def base_bounds(pd, opts, bw, n_root):
    """Torque bounds with the residual allowance on the root rows: the modelling error every frame
    may use, ``allowance`` (5%) of the body's weight under the current gravity (|g| / 9.81 times
    the standard body weight) -- biomechanics accepts residual forces of a few percent of body
    weight in inverse dynamics of captured motion."""
    lo = np.asarray(pd.tau_lo, dtype=float).copy()
    hi = np.asarray(pd.tau_hi, dtype=float).copy()
    if opts.relax and opts.allowance > 0 and n_root:
        gscale = float(np.linalg.norm(pd.gravity)) / G  # the dynamics' gravity (y-up), against standard
        w = row_weights(n_root, len(lo), bw, opts)[:n_root]
        lo[:n_root] -= opts.allowance * gscale * w
        hi[:n_root] += opts.allowance * gscale * w
    return lo, hi


@dataclass(frozen=True)
class RegionJob:
    """What every frame of one :func:`compute_regions` call needs: the dynamics (and the original
    physics' as ``reference``), the options, and the torque bounds computed once for the call.

    Solving is by chunks of frames (:meth:`solve`); each chunk gets its own
    :class:`~.highs_lp.HighsPool`, so warm starts stay within a chunk, the answer does not depend on
    which thread or process runs which chunk nor on what ran before, and two threads never share
    a HiGHS object."""

    pd: object
    reference: object
    opts: RegionOptions
    body_weight: float
    n_root: int
    bounds: tuple  # (lo, hi) of pd
    reference_bounds: tuple | None  # (lo, hi) of the reference

    @classmethod
    def build(cls, pd, reference, opts, body_weight, n_root):
        ref_bounds = None if reference is None else base_bounds(reference, opts, body_weight, n_root)
        return cls(pd, reference, opts, body_weight, n_root, base_bounds(pd, opts, body_weight, n_root), ref_bounds)

    def solve(self, frames, cancel=None, step=None) -> dict:
        """The regions of ``frames`` (one chunk) with fresh HiGHS objects, packed (:func:`_pack`).
        ``cancel`` is asked before each frame; ``step`` is called after each."""
        pool = HighsPool()
        out = []
        for i in frames:
            if cancel is not None and cancel():
                raise Cancelled("stopped")
            out.append(self.frame(int(i), pool))
            if step is not None:
                step()
        return _pack(out, self.pd.N.shape[2])

    def frame(self, i, pool: HighsPool) -> FrameRegion:
        pd, ref, opts, bw, n_root = self.pd, self.reference, self.opts, self.body_weight, self.n_root
        lo, hi = self.bounds
        fit = None
        if ref is not None:
            rlo, rhi = self.reference_bounds
            fit = source_fit(np.asarray(ref.a[i], float), np.asarray(ref.b[i], float), np.asarray(ref.c[i], float),
                             np.asarray(ref.N[i], float), rlo, rhi, opts, bw, n_root, pool)
        noise = pd.b_noise
        r = frame_region(pd.a[i], pd.b[i], pd.c[i], pd.N[i], lo, hi, opts, bw, n_root,
                         budget=None if fit is None else fit.budget, noise=None if noise is None else noise[i],
                         pool=pool)
        if fit is not None:
            r.lam0, r.source_residual = fit.lam0, fit.residual
            r.n_lp += fit.n_lp
        return r


class Cancelled(RetimeError):
    """The caller asked a long computation to stop (the editor's tab closed, Ctrl-C)."""


CHUNKS = 8  # chunks of frames with their own warm starts (a pool shares them out)
CHUNKED_FRAMES = 120  # fewer frames: one chunk, solved here


def _may_fork() -> bool:
    """A process pool by fork only from the main thread of a process with no other thread: a
    fork from a thread (the editor's solver threads, Dask workers) copies locks held elsewhere and
    the parent's signal handlers, and its pool could then hang for ever. Never from a daemonic
    process (a caller's multiprocessing.Pool worker), which may have no children."""
    import multiprocessing as mp

    return (threading.current_thread() is threading.main_thread() and threading.active_count() == 1
            and not mp.current_process().daemon)


_WORKER_JOB: RegionJob | None = None  # set only in a forked worker process, once, by _start_worker


def _start_worker(job):
    """A forked worker's start: it keeps the job it was forked with (fork copies it, so nothing but
    the chunks' frame indices is ever pickled), and leaves signals to the parent."""
    import signal

    global _WORKER_JOB
    _WORKER_JOB = job
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # a pool's terminate() must end its workers
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle


def _solve_in_worker(frames):
    return _WORKER_JOB.solve(frames)


def _solve_forked(job, chunks, workers):
    """The chunks solved by a pool of forked processes; None where fork is not available."""
    import multiprocessing as mp

    try:
        ctx = mp.get_context("fork")
    except ValueError:
        return None
    with ctx.Pool(workers, initializer=_start_worker, initargs=(job,)) as pool:
        return pool.map(_solve_in_worker, chunks)


def compute_regions(pd, options: RegionOptions | None = None, reference=None, frames=None,
                    progress=False, cancel=None) -> RegionSet:
    """Feasible regions and the contact-force model (centre LP) of every sample of ``pd``.

    ``reference``: the path dynamics of the *original* physics when ``pd`` has changed parameters
    (gravity, masses, ...); the frames' residual budgets and the original timing's contact forces
    (``lam0``) come from it. ``None``: ``pd`` is the original physics. ``cancel``: a function
    asked between frames; when it returns True the computation stops with :class:`Cancelled`.
    A process pool is used only from a lone main thread (:func:`_may_fork`). All solver state is
    this call's own (:class:`RegionJob`), so calls from several threads run side by side."""
    import time

    opts = options or RegionOptions()
    if opts.solver not in ("parametric", "highs"):
        raise RetimeError(f"unknown region solver {opts.solver!r} (use 'parametric' or 'highs')")
    t0 = time.perf_counter()
    idx = np.arange(len(pd.times)) if frames is None else np.asarray(frames)
    n = len(idx)
    bw = float(opts.body_weight) if opts.body_weight else estimate_body_weight(reference or pd)
    n_root = unactuated_rows(pd)
    job = RegionJob.build(pd, reference, opts, bw, n_root)
    workers = opts.workers
    if workers is None:
        workers = min(2, os.cpu_count() or 1) if n >= CHUNKED_FRAMES else 1
    # warm starts only within a chunk of frames, and the same chunks whatever runs them (a pool of
    # any size or this thread): the answer must not depend on the machine, the scheduling, nor on
    # what ran before
    n_chunks = CHUNKS if n >= CHUNKED_FRAMES else 1
    chunks = [list(ch) for ch in np.array_split(idx, n_chunks) if len(ch)]
    pooled = workers > 1 and len(chunks) >= workers
    results = None
    if pooled and cancel is None and _may_fork():
        results = _solve_forked(job, chunks, workers)
    if results is None:
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=n, desc="feasible regions", unit="frame", disable=None)
        results = []
        for chunk in chunks:
            results.append(job.solve(chunk, cancel, None if bar is None else lambda: bar.update(1)))
        if bar is not None:
            bar.close()
    rs = _region_set(pd, idx, results, opts, bw)
    rs.seconds = time.perf_counter() - t0
    return rs


def _pack(results: list[FrameRegion], K: int) -> dict:
    """A chunk's frame results as one array per field: a worker returns these, so that neither the
    pickles nor the parent hold tens of thousands of small arrays (their freed memory stayed in the
    heap: 0.4 GB of a 10-minute capture's peak)."""
    n = len(results)
    n_verts = np.array([len(r.verts) for r in results], dtype=np.int64)
    P = int(n_verts.sum())  # explicit: a fixed-base chain has K = 0 contact columns
    return dict(
        n_verts=n_verts,
        verts=np.concatenate([r.verts for r in results]).reshape(P, 2) if n else np.zeros((0, 2)),
        lam=np.concatenate([r.lam for r in results]).reshape(P, K) if n else np.zeros((0, K)),
        center=np.array([r.center for r in results]).reshape(n, 2),
        center_lam=np.array([r.center_lam for r in results]).reshape(n, K),
        lo=np.array([r.lo for r in results]),
        hi=np.array([r.hi for r in results]),
        budget=np.array([r.budget for r in results]),
        source_residual=np.array([r.source_residual for r in results]),
        lam0=np.array([r.lam0 for r in results]).reshape(n, K),
        relaxation=np.array([r.relaxation for r in results]),
        relaxed=np.array([r.relaxed for r in results], dtype=bool),
        source_distance=np.array([r.source_distance for r in results]),
        n_lp=np.array([r.n_lp for r in results], dtype=np.int64),
        n_pivots=np.array([r.n_pivots for r in results], dtype=np.int64),
    )


def _region_set(pd, idx, packs: list[dict], opts, bw) -> RegionSet:
    """The chunks' packed results (:func:`_pack`) as one :class:`RegionSet`."""
    n = len(idx)

    def joined(name):
        return np.concatenate([p[name] for p in packs])

    offsets = np.zeros(n + 1, dtype=np.int64)
    offsets[1:] = np.cumsum(joined("n_verts"))
    contact = pd.contact
    relaxation = joined("relaxation")
    return RegionSet(
        times=np.asarray(pd.times, dtype=float)[idx],
        offsets=offsets,
        verts=joined("verts"),
        lam=joined("lam"),
        center=joined("center"),
        center_lam=joined("center_lam"),
        lo=joined("lo"),
        hi=joined("hi"),
        budget=joined("budget"),
        source_residual=joined("source_residual"),
        lam0=joined("lam0"),
        relaxation=relaxation,
        relaxed=joined("relaxed"),
        implausible=relaxation > opts.max_relaxation,
        source_distance=joined("source_distance"),
        n_lp=joined("n_lp"),
        n_pivots=joined("n_pivots"),
        contact=np.asarray(contact)[idx] if contact is not None else np.zeros((n, 0), bool),
        options=opts,
        body_weight=bw,
    )
