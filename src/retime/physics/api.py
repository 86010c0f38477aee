"""Physics-based retiming in one call (McCann, Pollard, Srinivasa 2006).

    result = physics_warp(motion, duration=None, gravity=None, objective="match")  # gravity: down
    retimed = apply_timing(motion, result.curve)

Pipeline: path dynamics of the motion (:mod:`retime.physics.model.dynamics`, computed once; gravity and mass
changes recombine them), feasible regions and contact forces per frame (:mod:`.regions`,
:mod:`.regions.forces`), the objective of Eq. 14 baked per frame (:mod:`.timing.objective`), and the timing spline
optimized (:mod:`.timing.optimize`) from the grid optimum of the same objective (:mod:`.timing.globalstart`; the
paper's uniform timing with ``start="uniform"``, the keytimes' piecewise-linear timing with keytimes). ``result.session`` continues interactively.

Defaults, and why (measured on CMU jumps 16_06, 16_03, 13_11, 118_26; see the tests and README):

* ``alpha = 10`` with ``penalty = "l1"``: the feasibility term is an exact penalty
  ``alpha * (sqrt(d^2 + delta^2) - delta)`` of the distance d to the region, measured in body weights of
  residual force (``metric = "residual"``, :func:`objective.residual_scales`). Eq. 14's squared
  distance (``penalty = "l2"``, ``metric = "plane"``) spreads an unavoidable violation (halving a
  jump) thinly over many frames; the exact penalty keeps it on the few frames where it costs the
  least force, so most frames stay feasible (16_06 at half duration with clip-only torque limits:
  78% -> 94% of frames feasible; 100% with the strength floor of :mod:`.model.body`).
* ``beta = 0.1``: torques (normalized by the original's RMS torque) choose among physical timings;
  ``excess = True`` measures them from what any timing could reach (see :mod:`.timing.objective`).
* ``gamma = 0.03``: a weak pull of the playback speed towards 1 (``gamma * (p' + 1/p' - 2)`` per
  source second, symmetric in slowing down and speeding up), so frames that physics leaves free keep
  their timing and never stall; stronger values fight the speed-ups a shorter duration needs
  (16_06 at half duration: 94% feasible with 0.03, 88% with 0.1).
* control points every ``knot_spacing`` = 0.05 s of source time; 4 objective samples per source frame.
* ``smoothing = 0.05`` s: the path is low-passed (Gaussian) for the dynamics. The timing spline cannot
  follow anything faster, and twice-differentiated capture noise would otherwise decide how fast a
  still stance may be played (:data:`.constants.DEFAULT_SMOOTHING`, used by :mod:`.model.dynamics` too).
* the **capture-noise band** (:data:`.model.dynamics.NOISE_BAND` = 0.1 s, :data:`.model.dynamics.NOISE_CAP` = 2 %
  of body weight): in stance the root rows may also use the local RMS of b(0.05 s) - b(0.1 s) times
  p'^2, what the capture's accelerations are uncertain by (see :mod:`.regions`). Without it, the sway and marker
  noise of a still stance, 16- to 25-fold at 4-5x speed, decided how fast a stance could be played:
  the least physical duration (:mod:`.timing.fastest`) of 16_05 was 1.30 s, more than its half duration
  1.23 s; with it 1.20 s.
* ``start = "global"``: the spline starts from the grid optimum of the same objective
  (:mod:`.timing.globalstart`, dynamic programming over source frame x speed, which puts a violation that
  cannot be avoided on few output frames) instead of the uniform timing; ``"uniform"`` is the paper's
  start. With keytimes the start is their piecewise-linear timing.

Without ``duration`` (and ``scale``) the duration is free: the optimizer chooses it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import RetimeError
from ..motion.frame import up_vector
from ..warp import TimingCurve, snap_duration
from .constants import DEFAULT_SMOOTHING, MAX_GRAVITY, STANDARD_GRAVITY, G
from .timing.fastest import fastest_timing
from .timing.globalstart import global_start, soften
from .method import Settings, check_masses, file_gravity
from .timing.objective import BakedObjective, bake, target_torques
from .plausibility import check_source
from ..warp import check_keytimes
from .timing.optimize import Problem, RetimingSession, SolveInfo
from .regions import RegionOptions, RegionSet, compute_regions
from .report import build_report
from .timing.spline import TimingSpline



@dataclass
class PhysicsResult:
    curve: TimingCurve
    report: dict
    spline: TimingSpline
    session: RetimingSession
    dynamics: object
    regions: RegionSet
    objective: BakedObjective
    info: SolveInfo
    timings: dict = field(default_factory=dict)
    terms: object = None  # the DynamicsTerms (body, torque limits, ...)


class LiveSession(RetimingSession):
    """An interactive retiming (:func:`.method.session`), with what it was computed from
    (``shared``, a :class:`.method.Shared`) and where its current timing is feasible."""

    def __init__(self, problem, shared, optimizer, fps):
        super().__init__(problem, optimizer=optimizer, fps=fps)
        self.shared = shared

    def feasibility(self, fps):
        """Per output frame at ``fps``: :func:`.regions.feasibility.spline_feasibility` of the current spline."""
        from .regions.feasibility import spline_feasibility

        return spline_feasibility(self.spline, self.shared.dynamics, self.shared.regions, fps)

    def is_locked(self, index) -> bool:
        return index in self.spline.locks


def _changed(gravity, mass_factors, friction, torque_scale):
    g = np.asarray(gravity, dtype=float)
    return (not np.allclose(g, STANDARD_GRAVITY) or bool(mass_factors) or friction is not None
            or float(torque_scale) != 1.0)



def prepare(motion, gravity=STANDARD_GRAVITY, settings=None, *, terms=None, region_options=None, timings=None,
            cancel=None):
    """Dynamics, regions and the baked objective: everything but the spline. ``gravity``: y-up
    (m/s^2, the conformed motion's world; :func:`conformed_gravity` turns the file's into it);
    ``settings``: a :class:`.method.Settings` (None: its defaults; its gravity fields are not read
    here). ``cancel``: asked between frames of the regions; True stops with :class:`.regions.Cancelled`."""
    s = Settings() if settings is None else settings
    timings = {} if timings is None else timings
    terms, pd0, pd, regions = prepare_regions(motion, gravity, s.mass_factors or None, s.body, s.contacts, s.friction,
                                              s.torque_scale, region_options, terms, s.progress, timings, s.smoothing,
                                              cancel)
    opts = regions.options
    t0 = time.perf_counter()
    tau0 = np.asarray(pd0.b) + np.asarray(pd0.c) - pd0.N.forces(regions.lam0)
    target = tau0 if s.objective == "match" else target_torques(s.objective, pd0, regions)
    act = ~((np.asarray(pd.tau_lo) == 0) & (np.asarray(pd.tau_hi) == 0))
    tau_scale = float(np.sqrt(np.mean(np.sum(tau0[:, act] ** 2, axis=1)))) or 1.0
    obj = bake(pd, regions, target, alpha=s.alpha, beta=s.beta, tau_scale=tau_scale,
               samples_per_frame=s.samples_per_frame, metric=s.metric, excess=s.excess, gamma=s.gamma,
               v_range=(s.w_min ** 2, min(opts.v_max, s.w_max ** 2)), penalty=s.penalty, delta=s.delta)
    timings["bake"] = time.perf_counter() - t0
    return terms, pd, regions, obj


def prepare_regions(motion, gravity=STANDARD_GRAVITY, mass_factors=None, body=None, contacts=None, friction=None,
                    torque_scale=1.0, region_options=None, terms=None, progress=False, timings=None,
                    smoothing=DEFAULT_SMOOTHING, cancel=None):
    """Dynamics under the original and the asked physics (pd0, pd) and the feasible regions:
    (terms, pd0, pd, regions). What ``retime check`` needs; :func:`prepare` adds the objective."""
    from .model.dynamics import dynamics_terms

    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    if terms is None:
        terms = dynamics_terms(motion, body, contacts=contacts, smoothing=smoothing)
    pd0 = terms.combine()
    changed = _changed(gravity, mass_factors, friction, torque_scale)
    pd = terms.combine(gravity=gravity, mass_factors=mass_factors, friction=friction,
                       torque_scale=torque_scale) if changed else pd0
    timings["dynamics"] = time.perf_counter() - t0
    opts = region_options or RegionOptions()
    if opts.body_weight is None:
        opts.body_weight = float(pd0.total_mass) * G
    if opts.v_max < 64.0:
        opts.v_max = 64.0
    t0 = time.perf_counter()
    regions = compute_regions(pd, opts, reference=pd0 if changed else None, progress=progress, cancel=cancel)
    timings["regions"] = time.perf_counter() - t0
    return terms, pd0, pd, regions


def make_problem(obj, source_duration, duration=None, keytimes=(), knot_spacing=None, w_min=None, w_max=None,
                 start=None, timings=None):
    """The spline problem: knots every ``knot_spacing`` (output time, uniform), the duration (None:
    free) and keytimes; None for ``knot_spacing``, ``w_min``, ``w_max``, ``start``: :class:`.method.Settings`'.
    ``start="global"`` (no keytimes) starts from the grid optimum
    (:mod:`.timing.globalstart`) and softens the frames it gives up in the problem's objective, for this and
    every later re-convergence of a session built on it; ``"uniform"`` is the paper's start; keytimes
    start from their piecewise-linear timing."""
    d = Settings()
    knot_spacing = d.knot_spacing if knot_spacing is None else knot_spacing
    w_min = d.w_min if w_min is None else w_min
    w_max = d.w_max if w_max is None else w_max
    start = d.start if start is None else start
    S = float(source_duration)
    kt = check_keytimes(keytimes, S, duration)
    n_spans = max(4, int(np.ceil(S / knot_spacing)))
    spline = TimingSpline.uniform(S, n_spans, duration)
    gs = None
    if start == "global" and not kt:
        gs = global_start(obj, duration)
        if timings is not None and gs is not None:
            timings["global_start"] = gs.seconds
    if gs is not None:
        T = duration if duration is not None else gs.duration
        r = gs.duration / T
        gives_up = bool(gs.outside.any())
        # where the grid gives frames up, its sharp speed changes around them need control points twice
        # as dense, or the fit spills the violation onto their neighbours
        interior = TimingSpline.uniform(S, 2 * n_spans).interior if gives_up else spline.interior
        spline = TimingSpline.fit(interior, S, T, None, lambda t: r * gs.speed_at_output(t * r), w_min=w_min)
        if duration is None:
            spline.fixed_T = None
        if gives_up:
            obj = soften(obj, gs.outside)
    elif kt:
        # start from the piecewise-linear keytime timing (constraints then hold up to the fit)
        T = duration if duration is not None else S
        ts = np.r_[0.0, [t for _, t in kt], T if duration is not None else max(T, kt[-1][1] + (S - kt[-1][0]))]
        ss = np.r_[0.0, [s for s, _ in kt], S]
        slopes = np.diff(ss) / np.diff(ts)

        def speed(t):
            k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(slopes) - 1)
            return slopes[k]

        spline = TimingSpline.fit(spline.interior, S, duration if duration is not None else ts[-1],
                                  None, speed, w_min=w_min)
        if duration is None:
            spline.fixed_T = None
    return Problem(obj, spline, keytimes=kt, w_min=w_min, w_max=max(w_max, 1.5 * S / (duration or S)))


def conformed_gravity(motion, gravity=None) -> np.ndarray:
    """Gravity (m/s^2) given in the file's own axes (None: 9.81 down the detected up axis, see
    :mod:`retime.motion.frame`), in the y-up world physics works in."""
    from ..motion.frame import up_rotation

    R = up_rotation(motion.skeleton.up)
    if gravity is None:
        return np.asarray(STANDARD_GRAVITY, dtype=float)
    g = np.asarray(gravity, dtype=float)
    if g.shape != (3,) or not np.all(np.isfinite(g)) or np.linalg.norm(g) > MAX_GRAVITY:
        raise RetimeError(f"gravity must be three finite numbers, at most {MAX_GRAVITY:g} m/s^2 long, got {gravity!r}")
    return R @ g


def physics_warp(motion, duration=None, scale=None, keytimes=(), *, terms=None, region_options=None,
                 **options) -> PhysicsResult:
    """Retime ``motion`` physically; see the module docstring. A thin keyword wrapper over
    ``retime.method.solve("physics", ...)``: ``duration`` in seconds (or ``scale`` times the source
    duration; neither: free duration), ``keytimes`` [(source s, output s)], and ``options``, the
    fields of :class:`.method.Settings` (``gravity`` in m/s^2 in the file's own axes, or
    ``gravity_scale``; ``mass_factors`` {segment name: factor}; ``objective``, ``alpha``, ...), which
    also holds their defaults. ``terms``: this motion's dynamics, to reuse them."""
    from ..method import Request, settings_from
    from .method import solve

    settings = settings_from(Settings, options)
    return solve(motion, Request(duration, scale, keytimes, settings), terms=terms,
                 region_options=region_options).detail


def physics_result(motion, settings, request, terms=None, region_options=None) -> PhysicsResult:
    """The physics retiming of ``motion`` for a request and physics' ``settings`` (what
    :func:`.method.solve` reports)."""
    s = settings
    fps = float(motion.fps)
    S = motion.duration
    duration = request.output_duration(motion)  # the rule every door follows (None: free)
    keytimes = request.keytimes
    progress = s.progress
    mass_factors = check_masses(motion, s.mass_factors)
    check_keytimes(keytimes, S, duration)  # before the dynamics: fail fast
    from ..jit import compile_watch, stderr_if

    with compile_watch(stderr_if(progress)) as jit:
        timings = {}
        gravity = file_gravity(motion, s)
        file_g = -G * up_vector(motion.skeleton.up) if gravity is None else np.asarray(gravity, dtype=float)
        terms, pd, regions, obj = prepare(motion, conformed_gravity(motion, gravity), s, terms=terms,
                                          region_options=region_options, timings=timings)
        source = check_source(motion, terms, regions)  # said before the retiming, by the caller
        problem = make_problem(obj, S, duration, keytimes, s.knot_spacing, s.w_min, s.w_max, start=s.start,
                               timings=timings)
        session = RetimingSession(problem, optimizer=s.optimizer, fps=fps)
        t0 = time.perf_counter()
        info = session.reconverge(max_iter=s.max_iter, tol=1e-9)
        timings["optimize"] = time.perf_counter() - t0
        spline = session.spline
        if spline.free and not problem.keytimes:
            # put the free duration on the output frame grid (a uniform stretch of < half a frame)
            T = spline.duration
            Ts = snap_duration(T, fps)
            spline.w = spline.w * (T / Ts)
        curve = spline.timing_curve(fps)
        fastest = fastest_timing(regions)  # the least physical duration, for the report
        report = build_report(spline, pd, regions, fps, info=info,
                              extra={"objective_kind": s.objective, "gravity": [float(x) for x in file_g],
                                     "up": motion.skeleton.up, "meters_per_unit": float(motion.skeleton.meters_per_unit),
                                     "conform_notes": [n for n in getattr(terms, "conform_notes", [])
                                                       if n not in getattr(terms, "conform_warnings", [])],
                                     "source_check": source.as_dict(),
                                     "warnings": [w for w in [source.message()] if w]
                                     + list(getattr(terms, "conform_warnings", [])),
                                     "mass_factors": dict(mass_factors or {}), "timings": {k: round(v, 4) for k, v in timings.items()},
                                     "bind_pose_frames": int(getattr(terms, "bind_pose_frames", 0)),
                                     "least_duration": None if not np.isfinite(fastest.duration) else round(fastest.duration, 4)})
        result = PhysicsResult(curve, report, spline, session, pd, regions, obj, info, timings, terms)
    # the compiler's time is not the method's: reported apart (phases include it on a first run)
    result.timings["compile"] = round(jit.seconds, 4)
    result.report["summary"]["timings"]["compile"] = round(jit.seconds, 4)
    return result
