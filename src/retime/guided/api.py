"""Guided time warping on motions: :func:`guided_warp` and :func:`guided_solve`.

Pipeline (Hsu, da Silva, Popović 2007):

1. Poses: joint positions in the root's frame, in metres (:func:`retime.guided.features.root_frame_poses`), low-passed
   with a box of ``prefilter`` seconds at the clip's own rate.
2. Analysis grid: output frames at ``analysis_fps`` (30 Hz, as in the paper). Keytimes cut the
   clip into segments; a segment whose output is longer than its input (an expansion, or any
   segment when the reference is another motion) is upsampled (``upsample`` grid frames per
   analysis frame) so that every segment is a compression of its grid (section 3.1).
   The input is sampled on that grid (cubic interpolation), the reference at the analysis rate.
3. Local scores of all frame triples (exact kNN, or approximate), then the exact constrained
   shortest path through the keytimes (or the coarse-to-fine heuristic with ``fast=True``, or
   the unconstrained path with ``free=True``).
4. The chosen grid frames give source times at the output frames; a moving average (keytimes
   kept) smooths them, and the result is a :class:`retime.warp.TimingCurve` in seconds at the
   clip's own rate: apply it with :func:`retime.warp.apply_timing` (slerp) or
   :func:`retime.guided.postprocess.adaptive_smooth` (local averaging).
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from retime.errors import RetimeError
from retime.guided.features import FeatureWeights, analysis_samples, pose_pair
from retime.guided.glitches import fill_glitches, find_glitches
from retime.guided.heuristic import solve_heuristic, solve_upper_bound
from retime.guided.method import SCORES  # noqa: F401 (the scores' names, where callers found them)
from retime.guided.postprocess import moving_average
from retime.guided.problem import SolveStats, WarpProblem, solve_exact
from retime.guided.steady import steady_warp
from retime.motion import Motion
from retime.warp import TimingCurve, check_keytimes, keytime_warp

#: above this many DP states the exact solver first runs the heuristic for an upper bound and
#: prunes the band with Lagrangian bounds (exact either way)
PRUNE_STATES = 20_000_000


@dataclass
class GuidedResult:
    """What :func:`guided_solve` found."""

    curve: TimingCurve  # the smoothed timing curve: output seconds -> source seconds
    raw_curve: TimingCurve  # the warp before smoothing (piecewise linear through source_times)
    objective: float  # the chosen warp's objective: the steady one, or eq. 1 for score "paper"
    exact: bool  # globally optimal (False: coarse-to-fine heuristic)
    frames: np.ndarray  # (m,) grid frame the discrete search chose for each output frame
    output_times: np.ndarray  # (m,) output time of each analysis frame (s)
    source_times: np.ndarray  # (m,) source time shown there before smoothing (s)
    n: int  # grid frames (after upsampling)
    m: int  # output frames at the analysis rate
    r: int  # reference frames at the analysis rate
    s: int  # skip limit
    k: int  # neighbours
    analysis_fps: float
    upsample: list = field(default_factory=list)  # grid frames per analysis frame, per segment
    stats: SolveStats = field(default_factory=SolveStats)
    warnings: list = field(default_factory=list)  # for the user: capture glitches played as gaps


def _check_reference(motion: Motion, reference: Motion):
    diff = motion.skeleton.same_structure(reference.skeleton)
    if diff:
        shown = ", ".join(diff[:8]) + (f" and {len(diff) - 8} more" if len(diff) > 8 else "")
        raise RetimeError(f"the reference's skeleton differs from the input's in joints {shown} "
                          "(missing on one side or with another parent); guided warping needs the same skeleton")


def _segments(S, T, keytimes, A):
    """Segment ends in source seconds, output seconds and output positions (analysis frames)."""
    src = [0.0] + [k[0] for k in keytimes] + [S]
    dst = [0.0] + [k[1] for k in keytimes] + [T]
    pos = [int(round(b * A)) for b in dst]
    for q in range(1, len(pos)):
        if pos[q] <= pos[q - 1]:
            if q == len(pos) - 1 and len(pos) == 2:
                raise RetimeError(f"the output ({T:g} s) is shorter than one frame at the {A:g} Hz analysis rate")
            raise RetimeError(f"keytimes at output {dst[q - 1]:g} s and {dst[q]:g} s are closer than one "
                              f"frame at the {A:g} Hz analysis rate; move them apart")
    return src, dst, pos


def _upsampling(src, pos, A, s, self_reference, upsample, free):
    """Grid frames per analysis frame for each segment."""
    ups = []
    for q in range(len(src) - 1):
        if upsample is not None:
            ups.append(int(upsample))
            continue
        if free:
            ups.append(1 if self_reference else 4)
            continue
        # grid frames the segment needs: one per output frame (compression with itself as the
        # reference), about two with another reference (so the warp can also slow down)
        M = pos[q + 1] - pos[q]
        need = M if self_reference else max(M, 2 * M - 2)
        u = 1
        while round((src[q + 1] - src[q]) * A * u) < need:
            u += 1
        ups.append(u)
    return ups


def _shortest(src, dst, pos, ups, A, s, T):
    """Error for a segment the skip limit cannot compress enough (or that cannot be filled)."""
    for q in range(len(src) - 1):
        N = max(1, int(round((src[q + 1] - src[q]) * A * ups[q])))
        M = pos[q + 1] - pos[q]
        if N > s * M:
            steps = -(-N // s)
            if len(src) == 2:
                return RetimeError(f"a duration of {T:g} s is too short for --max-skip {s}: the shortest "
                                   f"possible is {steps / A:g} s ({steps + 1} frames at {A:g} Hz); "
                                   "ask for a longer duration or raise --max-skip")
            return RetimeError(f"between keytimes {src[q]:g}={dst[q]:g} and {src[q + 1]:g}={dst[q + 1]:g} s "
                               f"the output is too short for --max-skip {s}: it needs at least "
                               f"{steps / A:g} s there; move the keytimes or raise --max-skip")
        if N < M:
            return RetimeError(f"between source times {src[q]:g} and {src[q + 1]:g} s the output is longer "
                               f"than {ups[q]} grid frame(s) per analysis frame can fill; raise the upsampling")
    return None


def guided_solve(motion: Motion, reference: Motion | None = None, duration: float | None = None,
                 scale: float | None = None, free: bool = False, keytimes=(), quiet: bool = True,
                 **options) -> GuidedResult:
    """Guided time warp of ``motion``; returns a :class:`GuidedResult` (``.curve`` is the timing curve).

    A thin keyword wrapper over ``retime.method.solve("guided", ...)``: ``options`` are the fields of
    :class:`retime.guided.method.Settings` (``max_skip``, ``neighbors``, ``fast``, ``score``, ``blend``,
    ...), which also holds their defaults and meanings.

    motion: the input. reference: the motion whose timing to imitate (default: ``motion`` itself,
    which preserves its natural timing); it must have the same skeleton.
    duration / scale / free: output length in seconds, as a factor of the input's (0.5 = half as
    long), or chosen by the optimisation (the paper's unconstrained search, V8). With none of
    them the output lasts as long as the input.
    keytimes: [(source s, output s), ...] that the warp passes through exactly.
    quiet: no stage messages on stderr (``Settings.progress`` the other way round).
    """
    from retime.guided.method import Settings
    from retime.method import Request, settings_from, solve

    if free and (duration is not None or scale is not None):
        raise RetimeError("give only one of duration, scale and free")
    settings = settings_from(Settings, dict(options, reference=reference, free=bool(free), progress=not quiet))
    return solve("guided", motion, Request(duration, scale, keytimes, settings)).detail


def guided_result(motion: Motion, settings, request) -> GuidedResult:
    """The guided warp of ``motion`` for a :class:`retime.method.Request` and guided's ``settings``
    (:func:`retime.guided.method.solve` reports it; see the module docstring for the pipeline)."""
    t_start = time.perf_counter()
    st = settings
    reference, free, fast, keytimes = st.reference, bool(st.free), bool(st.fast), request.keytimes
    score, steadiness, blend = st.score, float(st.steadiness), float(st.blend)
    s, neighbors, A = int(st.max_skip), int(st.neighbors), float(st.analysis_fps)
    prefilter, upsample, smoothing, knn, eps = st.prefilter, st.upsample, st.smoothing, st.knn, st.eps
    if motion.n_frames < 2:
        raise RetimeError("a single frame has no timing to change")
    if free and (request.duration is not None or request.scale is not None):
        raise RetimeError("give only one of duration, scale and free")
    weights = st.weights or FeatureWeights()
    self_ref = reference is None or reference is motion
    reference = motion if self_ref else reference
    if not self_ref:
        _check_reference(motion, reference)
    S = motion.duration
    if free:
        if keytimes:
            raise RetimeError("keytimes need a fixed output duration; drop --free or the keytimes")
        if fast:  # the coarse-to-fine heuristic works within a fixed frame count; it was silently exact
            raise RetimeError("--fast (the coarse-to-fine search) needs a fixed output duration, and a free duration "
                              "is searched exactly; drop --fast or --free")
        T = None
    else:
        T = request.output_duration(motion)
        T = S if T is None else T
    keys = check_keytimes(keytimes, S, T if T is not None else S) if keytimes else []
    if free:
        src, dst, pos = [0.0, S], [0.0, S], [0, max(1, int(round(S * A)))]
    else:
        src, dst, pos = _segments(S, T, keys, A)
    ups = _upsampling(src, pos, A, s, self_ref, upsample, free)
    if not free:
        err = _shortest(src, dst, pos, ups, A, s, T)
        if err is not None:
            raise err

    # --- poses on the grid and at the analysis rate
    x_src, z_src = pose_pair(motion, reference, weights.root_height)
    x_src, z_src, warnings = _without_glitches(x_src, z_src, motion, reference)
    grid, fixed = [], {}
    for q in range(len(src) - 1):
        N = max(1, int(round((src[q + 1] - src[q]) * A * ups[q])))
        grid.append(src[q] + (src[q + 1] - src[q]) * np.arange(N) / N)
        if 0 < q:
            fixed[pos[q]] = int(sum(len(g) for g in grid[:-1]))
    grid.append(np.array([S]))
    grid_times = np.concatenate(grid)
    n = grid_times.size
    r_times = np.arange(int(math.floor(reference.duration * A + 1e-9)) + 1) / A
    if self_ref:  # one low-pass and spline gives both
        x, z = analysis_samples(x_src, motion.fps, prefilter, [grid_times, r_times])
    else:
        x, = analysis_samples(x_src, motion.fps, prefilter, [grid_times])
        z, = analysis_samples(z_src, reference.fps, prefilter, [r_times])
    del x_src, z_src  # the clip-rate poses: the biggest arrays so far
    if z.shape[0] < 3:
        raise RetimeError(f"the reference is {reference.duration:.3g} s long: at {A:g} Hz that is "
                          f"{z.shape[0]} frame(s), and the local score needs at least 3")
    m = None if free else pos[-1] + 1
    problem = WarpProblem(x, z, A, m, fixed, s, neighbors, weights, knn, float(eps))
    stats = SolveStats()
    progress = _Progress(not st.progress)
    if free:
        progress.say("scoring and searching (free duration)")
        sol, F, stats = solve_exact(problem, stats=stats)
        exact = True
    elif fast:
        progress.say("coarse-to-fine search")
        sol, F, stats = solve_heuristic(problem, stats=stats)
        exact = False
    else:
        band = problem.band()
        ub = None
        F = None
        if band.n_states(s) > PRUNE_STATES:
            progress.say(f"scoring {n} x {s}^2 frame triples against {z.shape[0]} reference frames")
            t0 = time.perf_counter()
            F = problem.scores()
            stats.objective_s += time.perf_counter() - t0
            progress.say("upper bound")
            hsol, _, hstats = solve_upper_bound(problem, F)
            ub = hsol.objective
            stats.extra["upper_bound"] = ub
            stats.extra["lagrange"] = hstats.extra.get("lagrange")
            stats.optimization_s += hstats.optimization_s
        progress.say("exact search")
        sol, F, stats = solve_exact(problem, F, upper_bound=ub, stats=stats,
                                    lagrange=stats.extra.pop("lagrange", None) if ub is not None else None)
        exact = True
    progress.close()

    frames = sol.frames
    objective = float(sol.objective)
    if score == "steady":
        t0 = time.perf_counter()
        natural = ups[0] if free else np.append(np.repeat(ups, np.diff(pos)), ups[-1])  # grid frames at 1x
        grounded = _grounded(motion, grid_times, warnings) if st.pace > 0 else None
        warp = steady_warp(F, frames, list(fixed), steadiness, natural,  # the keytimes' positions; the ends too
                           grounded=grounded, pace=float(st.pace))
        stats.optimization_s += time.perf_counter() - t0
        stats.extra["discrete_objective"] = objective
        stats.extra["steady_segments_kept"] = warp.kept  # left as the whole-frame warp: no steady warp fits
        objective = warp.objective
        src_t = np.interp(warp.frames, np.arange(n), grid_times)
    else:
        src_t = grid_times[frames]
    if free:
        out_t = np.arange(len(frames)) / A
        fixed_out = []
    else:
        out_t = np.empty(m)
        for q in range(len(pos) - 1):
            p = np.arange(pos[q], pos[q + 1] + 1)
            out_t[p] = dst[q] + (p - pos[q]) * (dst[q + 1] - dst[q]) / (pos[q + 1] - pos[q])
        fixed_out = pos
    smooth_t = moving_average(src_t, int(smoothing) | 1 if smoothing > 1 else 1, fixed_out)
    smooth_t = np.maximum.accumulate(np.clip(smooth_t, 0.0, S))
    curve = TimingCurve(out_t, smooth_t, kind="pchip")
    raw = TimingCurve(out_t, src_t, kind="linear")
    if blend < 1.0:
        spline = keytime_warp(S, keys, curve.duration, smooth=True)
        curve = blended(spline, curve, blend, motion.fps, [t for _, t in keys])
    stats.extra["total_s"] = time.perf_counter() - t_start
    return GuidedResult(curve, raw, objective, exact, frames, out_t, src_t, n, len(frames),
                        z.shape[0], s, neighbors, A, ups, stats, warnings)


#: a flight this long (s) keeps its natural speed: a jump's (0.37-0.61 s in the benchmark's clips;
#: 0.25 s of free fall rises 7.7 cm), not a run's (at most 0.18 s there), which plays with the run;
#: nor one longer than 1 s (a 1.2 m rise: no jump, but feet the contact test never finds on the floor)
JUMP_FLIGHT = (0.25, 1.0)
#: and so do this many seconds either side of it (take-off, landing, and the warp's smoothing window)
FLIGHT_MARGIN = 0.1


def _grounded(motion, grid_times, warnings):
    """0 within FLIGHT_MARGIN s of a flight lasting JUMP_FLIGHT s (contacts of the input as
    physics and the reports detect them), else 1, at the grid times: where the steady score pulls
    the warp to one steady speed (1) or to the natural speed (0). A rig without two feet has no
    flights to find (guided works on any skeleton): all 1, and ``warnings`` says so."""
    from retime.errors import RetimeError
    from retime.phases import flights
    from retime.motion.feet import NotTwoLegged, foot_contacts

    t = np.asarray(grid_times, dtype=float)
    grounded = np.ones(t.size)
    try:
        contacts = foot_contacts(motion)
    except RetimeError as e:
        # the detector's message speaks to physics' users; a guided user is told why in guided's words
        why = (f"{e.where}this skeleton is not a two-legged character: {e.why}" if isinstance(e, NotTwoLegged)
               else str(e))
        warnings.append(f"no jump flights looked for ({why}); every frame is pulled to one steady pace "
                        "(--pace 0 keeps the reference's own pace)")
        return grounded
    for a, b in flights(contacts, motion.fps, min_frames=1):
        if JUMP_FLIGHT[0] - 1e-9 <= b + 1.0 / motion.fps - a <= JUMP_FLIGHT[1]:
            grounded[(t >= a - FLIGHT_MARGIN) & (t <= b + FLIGHT_MARGIN)] = 0.0
    return grounded


def _without_glitches(x, z, motion, reference):
    """The input's and the reference's poses with their capture glitches filled as gaps
    (:mod:`retime.guided.glitches`), and a warning for each."""
    glitches = find_glitches(x, motion.fps)
    warnings = [g.message(motion.fps) for g in glitches]
    x_filled = fill_glitches(x, glitches) if glitches else x
    if z is x:
        return x_filled, x_filled, warnings
    ref_glitches = find_glitches(z, reference.fps)
    warnings += [g.message(reference.fps, "reference") for g in ref_glitches]
    return x_filled, fill_glitches(z, ref_glitches) if ref_glitches else z, warnings


def blended(spline: TimingCurve, guided: TimingCurve, weight: float, fps: float, keys_out=()) -> TimingCurve:
    """(1 - weight) spline + weight guided, exact at the frames of ``fps`` and at the keytimes' output
    times ``keys_out`` (where both curves agree, so the mix keeps them) (Hsu et al. sec. 5: a
    control of the reference's influence). Weight 0 is ``spline`` itself, 1 is ``guided``; either
    curve is monotone, so their mix is, and a phase's speed moves linearly with the weight."""
    if weight <= 0.0:
        return spline
    if weight >= 1.0:
        return guided
    t = np.union1d(guided.frame_times(fps), [guided.duration, *keys_out])
    return TimingCurve(t, (1.0 - weight) * spline(t) + weight * guided(t), kind="pchip")


def guided_warp(motion: Motion, reference: Motion | None = None, duration: float | None = None,
                scale: float | None = None, free: bool = False, keytimes=(), **options) -> TimingCurve:
    """The guided timing curve of ``motion`` (output seconds -> source seconds).

    Same arguments as :func:`guided_solve` (which also returns the objective, the chosen frames
    and timings). Example::

        from retime.motion import load_motion
        from retime.warp import apply_timing
        from retime.guided import guided_warp

        jump = load_motion("16_06.amc")
        curve = guided_warp(jump, duration=0.6 * jump.duration)  # keeps the flight's speed
        shorter = apply_timing(jump, curve)
    """
    return guided_solve(motion, reference, duration, scale, free, keytimes, **options).curve


class _Progress:
    """Stage messages on stderr (a tqdm bar) when asked for and stderr is a terminal."""

    def __init__(self, quiet):
        self.bar = None
        if not quiet and sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=0, bar_format="{desc} [{elapsed}]", file=sys.stderr, leave=False)

    def say(self, text):
        if self.bar is not None:
            self.bar.set_description_str(f"guided: {text}")
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()


