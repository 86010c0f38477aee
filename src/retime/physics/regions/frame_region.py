"""One frame's feasible region, its relaxation and its centre (McCann et al. 2006, sec. 3.3-3.4).

The constraints of a frame (Eq. 13) become, in the (u, v) = (p'', p'^2) plane, half-planes (rows
without contact forces, :func:`_halfplanes`) and an LP in (u, v, lam) (the rest, :func:`_frame_lp`);
the polygon is traced by the compiled simplex of :mod:`.simplex` or by HiGHS alone, clipped by the
half-planes (:mod:`.polygon`), and relaxed when the captured motion or the changed physics need it
(:func:`source_fit`, :func:`_residual_lp`). See :mod:`retime.physics.regions` for the whole model and the options.

Every function that solves an LP takes the :class:`~.highs_lp.HighsPool` it may use; without one it
makes its own, so nothing is shared between calls unless the caller says so.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from ...errors import RetimeError
from .highs_lp import FrameLP, HighsPool, solve_dual_simplex
from .polygon import ccw_order, clip_halfplanes, closest_point, dedupe
from .simplex import INF, phase2, walk


@dataclass
class RegionOptions:
    """How feasible regions are computed (:mod:`retime.physics.regions`). Units: u = p'' in 1/s, v = p'^2 (dimensionless)."""

    u_max: float = 60.0
    v_max: float = 64.0  # up to 8x speed (still frames, which any speed suits)
    solver: str = "parametric"  # "parametric" (HiGHS + shadow-vertex walk) or "highs" (refinement)
    tol: float = 1e-3  # "highs": polygon accuracy in the (p'', p'^2) plane
    relax: bool = True  # False: exact regions (an empty one is an error)
    allowance: float = 0.05  # residual root wrench every frame may use, fraction of body weight
    relax_pad: float = 0.01  # fraction of body weight added around every residual budget
    noise: bool = True  # widen the root rows by the capture-noise band b_noise p'^2 (PathDynamics.b_noise)
    max_relaxation: float = 0.05  # frames needing more extra relaxation are flagged implausible
    moment_arm: float = 1.0  # metres: a root moment of W * moment_arm counts like a force of W
    actuated_slack_cost: float = 10.0
    body_weight: float | None = None  # newtons; default: estimated from the gravity term
    center: tuple = (0.0, 1.0)  # the timing whose contact forces anchor the force model (sec. 3.4)
    # body weights: the least-force contact forces are made unique by a quadratic term
    # (forces.regularised_least_force) under which a basis force of this size costs twice per newton what
    # an unloaded one does. One body weight keeps the summed force within a few % of the least (16_16:
    # median 1.7%, at most 2.4%) while forces move by at most this times a change of the cost per newton
    # (float32 rounding: 1e-7 body weights, against half a body weight for the plain LP's vertex)
    force_spread: float = 1.0
    # the polygon vertices' forces: the walk's own (one corner of a face of valid forces, which moves
    # with float rounding: up to 1.2 body weights on a float32 copy), or the regularised least force
    # at each vertex (forces.unique_vertex_forces: unique, moves <= 1e-4 of its size). On, a float32
    # copy's timing is within 0.1 source frame on 19 of 33 clips (15 off), median 0.074 (0.16), but
    # 16_16 0.014 -> 0.43 and AV_8Walk 1.2 -> 2.8 (nearby minima; README), and Fig. 12's Feasible
    # stage costs about 0.45 ms a frame more (16_16 under load: 0.75-0.89 -> 1.26-1.38; SciPy's NNLS
    # per vertex cost 1.7 more, regions.nnls now): off until the lead decides
    unique_vertex_forces: bool = False
    workers: int | None = None  # processes for many frames (default: all cores, at most 2)


@dataclass
class FrameRegion:
    """One frame's polygon and what it was computed from (see :class:`~retime.physics.regions.RegionSet`)."""

    verts: np.ndarray
    lam: np.ndarray
    center: np.ndarray
    center_lam: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    budget: np.ndarray
    source_residual: float
    lam0: np.ndarray
    relaxation: float
    relaxed: bool
    source_distance: float
    n_lp: int
    n_pivots: int


def row_weights(n_root, nv, body_weight, opts):
    """Newtons per unit of residual: body weight on the root force rows, weight x moment arm on the
    root moment rows and on the joint rows."""
    w = np.full(nv, body_weight * opts.moment_arm)
    w[: min(3, n_root)] = body_weight
    return w


def row_costs(n_root, nv, body_weight, opts):
    cost = 1.0 / row_weights(n_root, nv, body_weight, opts)
    cost[n_root:] *= opts.actuated_slack_cost
    return cost


def _box_polygon(opts, K):
    U, V = opts.u_max, opts.v_max
    P = np.array([[-U, 0.0], [U, 0.0], [U, V], [-U, V]])
    return P, np.zeros((4, K))


def _split(a, b, lo, hi, rho, rows):
    """Rows lo - rho v <= a u + b v (+ ...) <= hi + rho v as one-sided or ranged LP rows.

    Returns (coefficient of u, of v, lower, upper, source row) per LP row: a row without budget
    stays ranged; a row with budget rho > 0 becomes an upper row with v-coefficient b - rho and a
    lower row with b + rho."""
    rows = np.asarray(rows, dtype=np.int64)
    has = rho[rows] > 0
    if not has.any():
        return a[rows], b[rows], lo[rows], hi[rows], rows
    r0 = rows[~has]
    r1 = rows[has]
    cat = np.concatenate
    cu = cat((a[r0], a[r1], a[r1]))
    cv = cat((b[r0], b[r1] - rho[r1], b[r1] + rho[r1]))
    lo_ = cat((lo[r0], np.full(len(r1), -INF), lo[r1]))
    hi_ = cat((hi[r0], hi[r1], np.full(len(r1), INF)))
    src = cat((r0, r1, r1))
    return cu, cv, lo_, hi_, src


def _halfplanes(a, b, c, lo, hi, rho, rows):
    """Rows without contact forces as normalized half-planes (a, b, c): a u + b v <= c."""
    return _halfplanes_kernel(a, b, c, lo, hi, rho, np.asarray(rows, dtype=np.int64))


@njit(cache=True)
def _halfplanes_kernel(a, b, c, lo, hi, rho, rows):
    out = np.empty((2 * len(rows) + 1, 3))
    k = 0
    for r in rows:
        for side in range(2):  # upper: a u + (b - rho) v <= hi - c ; lower: -a u - (b + rho) v <= c - lo
            if side == 0:
                bound = hi[r] - c[r]
                if hi[r] >= INF * 0.5:
                    continue
                cu, cv = a[r], b[r] - rho[r]
            else:
                bound = c[r] - lo[r]
                if lo[r] <= -INF * 0.5:
                    continue
                cu, cv = -a[r], -(b[r] + rho[r])
            nrm = math.hypot(cu, cv)
            if nrm > 1e-12 * (1.0 + abs(bound)):
                out[k, 0], out[k, 1], out[k, 2] = cu / nrm, cv / nrm, bound / nrm
            else:  # a row the timing cannot change: feasible iff its bound is not negative
                out[k, 0], out[k, 1], out[k, 2] = 0.0, 0.0, bound
            k += 1
    return out[:k].copy()


class Residual(NamedTuple):
    """The least residual that makes a frame feasible (:func:`_residual_lp`)."""

    rows: np.ndarray  # (nv,) residual per row, N or N m
    total: float  # weighted sum, body weights
    point: tuple  # the timing (u, v) that needs it


def _residual_lp(a, b, c, N, lo, hi, rho, act, n_root, body_weight, opts, pool: HighsPool, fix=None) -> Residual:
    """Least weighted-L1 row residual that makes the frame feasible, over all (u, v) in the box or at
    ``fix`` = (u, v)."""
    nv = len(a)
    cost_row = row_costs(n_root, nv, body_weight, opts)
    K = len(act)
    cu, cv, lo_, hi_, src = _split(a, b, lo, hi, rho, np.arange(nv))
    m = len(src)
    S = np.zeros((m, nv))
    S[np.arange(m), src] = 1.0
    # columns: u, v, lam (K), s+ (nv), s- (nv); row value + s+ - s- within its bounds
    A = np.hstack([cu[:, None], cv[:, None], -N[np.ix_(src, act)], S, -S])
    col_lo = np.zeros(2 + K + 2 * nv)
    col_hi = np.full(2 + K + 2 * nv, INF)
    if fix is None:
        col_lo[0], col_hi[0], col_hi[1] = -opts.u_max, opts.u_max, opts.v_max
    else:
        col_lo[0], col_lo[1] = fix
        col_hi[0], col_hi[1] = fix
    cost = np.concatenate((np.zeros(2 + K), cost_row, cost_row))
    x = solve_dual_simplex(pool.highs("residual"), A, col_lo, col_hi, lo_ - c[src], hi_ - c[src], cost)
    if x is None:  # slacks are free: cannot happen
        raise RetimeError("internal: the relaxation LP failed")
    r = np.abs(x[2 + K: 2 + K + nv] - x[2 + K + nv:])
    r[r <= 1e-9 * row_weights(n_root, nv, body_weight, opts)] = 0.0
    return Residual(r, float(np.sum(r * cost_row)), (float(x[0]), float(x[1])))


def unactuated_rows(pd) -> int:
    """Number of leading unactuated rows (the root's six) of the path dynamics ``pd``."""
    n = getattr(pd, "n_root", None)
    if n is not None:
        return int(n)
    lo, hi = np.asarray(pd.tau_lo), np.asarray(pd.tau_hi)
    free = (lo == 0) & (hi == 0)
    n = 0
    while n < len(free) and free[n]:
        n += 1
    return n


def residual_at(pd, regions, i, u, v, pool: HighsPool | None = None) -> float:
    """Extra residual (body weights, weighted L1 as in the relaxation) that the timing (u, v) needs
    at frame ``i`` beyond the frame's region bounds: 0 inside the region. ``pool``: HiGHS objects
    to reuse over many calls (default: new ones for this call)."""
    opts = regions.options
    bw = regions.body_weight
    n_root = unactuated_rows(pd)
    a, b, c, N = (np.asarray(x[i], dtype=float) for x in (pd.a, pd.b, pd.c, pd.N))
    lo = regions.lo[i] - regions.budget[i] * v
    hi = regions.hi[i] + regions.budget[i] * v
    act = np.flatnonzero(np.any(N != 0.0, axis=0))
    if len(act) == 0:
        val = a * u + b * v + c
        r = np.abs(val - np.clip(val, lo, hi))
        return float(np.sum(r * row_costs(n_root, len(a), bw, opts)))
    return _residual_lp(a, b, c, N, lo, hi, np.zeros(len(a)), act, n_root, bw, opts, pool or HighsPool(),
                        fix=(float(u), float(v))).total


def _widen(lo, hi, amount, pad):
    grow = np.where(amount > 0, amount + pad, 0.0)
    return lo - grow, hi + grow


def _lp_rows(N, act, nv):
    if len(act) == 0:
        return np.zeros(0, dtype=int), np.arange(nv)
    mask = np.any(N[:, act] != 0.0, axis=1)
    return np.flatnonzero(mask), np.flatnonzero(~mask)


def _frame_lp(a, b, c, N, lo, hi, rho, act, rows, opts, pool):
    cu, cv, lo_, hi_, src = _split(a, b, lo, hi, rho, rows)
    A = np.hstack([cu[:, None], cv[:, None], -N[np.ix_(src, act)]])
    return FrameLP(A, lo_ - c[src], hi_ - c[src], opts.u_max, opts.v_max, pool)


def _point_ok(a, b, c, lo, hi, rows, u, v, tol):
    val = a[rows] * u + b[rows] * v + c[rows]
    return bool(np.all(val >= lo[rows] - tol) and np.all(val <= hi[rows] + tol))


class SourceFit(NamedTuple):
    """How far the original timing (0, 1) is from feasible at one frame (:func:`source_fit`)."""

    budget: np.ndarray  # (nv,) |row residual| the captured motion needs at (0, 1)
    residual: float  # that residual in body weights
    lam0: np.ndarray  # (K,) least-force contact coefficients at (0, 1), rows widened by budget and pad
    n_lp: int  # LP solves
    lp: FrameLP | None  # the frame LP when it can serve for the region as it is (zero budget)


def source_fit(a, b, c, N, lo, hi, opts: RegionOptions, body_weight: float, n_root: int,
               pool: HighsPool | None = None, keep_lp: bool = False) -> SourceFit:
    """How far the original timing (0, 1) is from feasible at one frame (original physics).
    ``keep_lp``: the caller will trace the region on these very rows, so return the frame LP with
    the walk's start (an extra LP solve)."""
    from .forces import force_weights, solve_center

    pool = pool or HighsPool()
    nv, Kall = N.shape
    act = np.flatnonzero(np.any(N != 0.0, axis=0))
    rows, other = _lp_rows(N, act, nv)
    w = row_weights(n_root, nv, body_weight, opts)
    tol = 1e-9 * body_weight
    lam0 = np.zeros(Kall)
    zero = np.zeros(nv)
    n_lp = 0
    if len(act) == 0:
        val = b + c
        r = np.abs(val - np.clip(val, lo, hi))
        r[r <= tol] = 0.0
        return SourceFit(r, float(np.sum(r * row_costs(n_root, nv, body_weight, opts))), lam0, 0, None)
    fw = force_weights(N[:3][:, act] if n_root >= 3 else N[:, act], n_root)
    if _point_ok(a, b, c, lo, hi, other, 0.0, 1.0, tol):
        lp = _frame_lp(a, b, c, N, lo, hi, zero, act, rows, opts, pool)
        lam = solve_center(lp, 0.0, 1.0, fw, opts.force_spread * body_weight, walk_start=keep_lp)
        n_lp += lp.n_solves
        if lam is not None:
            lam0[act] = np.maximum(lam, 0.0)
            return SourceFit(zero, 0.0, lam0, n_lp, lp if keep_lp else None)
    budget, res, _ = _residual_lp(a, b, c, N, lo, hi, zero, act, n_root, body_weight, opts, pool, fix=(0.0, 1.0))
    n_lp += 1
    lo1, hi1 = _widen(lo, hi, budget, opts.relax_pad * w)
    lp = _frame_lp(a, b, c, N, lo1, hi1, zero, act, rows, opts, pool)
    lam = solve_center(lp, 0.0, 1.0, fw, opts.force_spread * body_weight)
    n_lp += lp.n_solves
    if lam is not None:
        lam0[act] = np.maximum(lam, 0.0)
    return SourceFit(budget, res, lam0, n_lp, None)


def _trace(lp, opts, x0):
    """Polygon vertices (k, 2 + n_lam) of an LP whose first solve gave x0; (X, pivots)."""
    X = None
    piv = 0
    if opts.solver == "parametric":
        basic, up = lp.basis()
        zl, zu = lp.bounds()
        if len(basic) == lp.m:
            _, Xw, status, piv = walk(lp.A, zl, zu, basic, up, 0.5 * math.pi, 2000)
            if status == 0 and len(Xw) >= 1:
                X = Xw
    if X is None:
        X = _trace_highs(lp, opts.tol, first=x0)
    return X, piv


def _polygon(a, b, c, N, lo, hi, rho, act, rows, other, opts, Kall, eps, pool, lp=None):
    """Clipped polygon, its lambdas, the LP (None in flight), LP solves, pivots; P is None if empty."""
    H = _halfplanes(a, b, c, lo, hi, rho, other)
    n_lp = 0
    piv = 0
    if len(act) == 0:
        lp = None
        P, L = _box_polygon(opts, Kall)
    else:
        if lp is None:
            lp = _frame_lp(a, b, c, N, lo, hi, rho, act, rows, opts, pool)
        before = lp.n_solves
        P = L = None
        X = None
        if opts.solver == "parametric" and lp.center_state is not None:
            # start from the centre LP's basis: phase 2 to "max v" and the walk, all without HiGHS
            basic, zval = lp.center_state
            zl, zu = lp.bounds()
            zval = np.clip(zval, zl, zu)
            basic, up, st = phase2(lp.A, zl, zu, basic.copy(), zval, 500)
            if st == 0:
                _, Xw, status, piv = walk(lp.A, zl, zu, basic, up, 0.5 * math.pi, 2000)
                if status == 0 and len(Xw) >= 1:
                    X = Xw
        x0 = None
        if X is None:
            x0 = lp.maximize(0.0, 1.0)
            if x0 is not None:
                X, piv = _trace(lp, opts, x0)
        if X is not None:
            P = X[:, :2].copy()
            L = np.zeros((len(X), Kall))
            L[:, act] = np.maximum(X[:, 2:], 0.0)
        n_lp += lp.n_solves - before
        if P is None:
            return None, None, lp, n_lp, piv
    px, py, pl, ok = clip_halfplanes(P[:, 0].copy(), P[:, 1].copy(), L, H, eps)
    if not ok:
        return None, None, lp, n_lp, piv
    P, L = dedupe(np.column_stack([px, py]), pl, eps)
    if len(P) == 0:
        return None, None, lp, n_lp, piv
    return P, L, lp, n_lp, piv


def frame_region(a, b, c, N, lo, hi, opts: RegionOptions, body_weight: float, n_root: int,
                 budget=None, noise=None, pool: HighsPool | None = None) -> FrameRegion:
    """The feasible polygon of one frame (the model: :mod:`retime.physics.regions`).

    ``budget`` (nv,): row residuals the captured motion needs at this frame under the original
    physics (:func:`source_fit`); ``None`` means these coefficients *are* the original physics and the
    budget is fitted here. Row r is then bounded by ``lo - pad - budget p'^2 ... hi + pad + budget p'^2``
    (``pad`` only on rows with a budget): the captured motion's inconsistency is taken to come from
    its accelerations, so it grows with p'^2. ``pool``: the HiGHS objects to use (warm starts from
    the frames solved with it before); default: new ones."""
    from .forces import force_weights, solve_center, unique_vertex_forces

    pool = pool or HighsPool()
    a, b, c, N = (np.asarray(x, dtype=float) for x in (a, b, c, N))
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    nv, Kall = N.shape
    act = np.flatnonzero(np.any(N != 0.0, axis=0))
    rows, other = _lp_rows(N, act, nv)
    w = row_weights(n_root, nv, body_weight, opts)
    pad = opts.relax_pad * w
    eps = 1e-9 * (opts.u_max + opts.v_max)
    n_lp = 0
    lp0 = None
    noisy = bool(opts.relax and noise is not None and opts.noise and np.any(np.asarray(noise) > 0))
    if budget is None:
        # the source fit's LP can start the walk only without the noise band (it has no budget rows)
        budget, src_res, lam0, k, lp0 = source_fit(a, b, c, N, lo, hi, opts, body_weight, n_root, pool,
                                                   keep_lp=not noisy)
        n_lp += k
    else:
        budget = np.asarray(budget, dtype=float)
        src_res = float(np.sum(budget * row_costs(n_root, nv, body_weight, opts)))
        lam0 = np.zeros(Kall)
    if not opts.relax:
        budget = np.zeros(nv)
    lo1 = lo - np.where(budget > 0, pad, 0.0)
    hi1 = hi + np.where(budget > 0, pad, 0.0)
    if noisy:
        budget = budget + np.asarray(noise, dtype=float)
    P, L, lp, k, piv = _polygon(a, b, c, N, lo1, hi1, budget, act, rows, other, opts, Kall, eps, pool, lp=lp0)
    n_lp += k
    level = 0.0
    relaxed = False
    if P is None:
        if not opts.relax:
            raise RetimeError("empty feasible region (relaxation is off)")
        extra, _, point = _residual_lp(a, b, c, N, lo1, hi1, budget, act, n_root, body_weight, opts, pool)
        n_lp += 1
        lo1, hi1 = _widen(lo1, hi1, extra, pad)
        level = float(np.max(np.where(extra > 0, (extra + pad) / w, 0.0)))
        relaxed = True
        P, L, lp, k, piv2 = _polygon(a, b, c, N, lo1, hi1, budget, act, rows, other, opts, Kall, eps, pool)
        n_lp += k
        piv += piv2
        if P is None:  # numerical corner: fall back to the least-residual timing itself
            P = np.array([point])
            L = np.zeros((1, Kall))
    # fan centre (sec. 3.4): the original timing, or the nearest feasible point pulled inwards
    target = np.asarray(opts.center, dtype=float)
    q, dist = closest_point(P, target)
    center = q
    if dist > 0 and len(P) >= 3:
        center = q + 0.02 * (P.mean(axis=0) - q)
    clam = np.zeros(Kall)
    fw = force_weights(N[:3][:, act] if n_root >= 3 else N[:, act], n_root)
    if lp is not None and opts.unique_vertex_forces:
        L = unique_vertex_forces(lp, P, L, act, fw, opts.force_spread * body_weight)
    if lp is not None and (lp is lp0 or noisy) and dist == 0.0 and not relaxed and np.any(lam0 != 0):
        # the centre is the original timing: its least-force LP was solved already (with the noise
        # band too: those forces still fit the wider rows, and "match" then costs nothing there)
        clam = lam0.copy()
    elif lp is not None:
        before = lp.n_solves
        lam_c = solve_center(lp, center[0], center[1], fw, opts.force_spread * body_weight)
        n_lp += lp.n_solves - before  # HiGHS runs only if NNLS gave up
        if lam_c is None:  # the centre sits on a clipped edge within round-off: nearest vertex
            lam_c = _nearest_vertex_lam(P, L, center)[act]
        clam[act] = np.maximum(lam_c, 0.0)
    return FrameRegion(P, L, center, clam, lo1, hi1, budget, src_res, lam0, level, relaxed, dist, n_lp, piv)


def _nearest_vertex_lam(P, L, point):
    """The contact coefficients of the polygon vertex nearest to ``point``."""
    d = np.hypot(P[:, 0] - point[0], P[:, 1] - point[1])
    return L[int(np.argmin(d))]




def _trace_highs(lp: FrameLP, tol, first=None):
    """Adaptive refinement (Fig. 4): axis directions, then edge normals until every edge holds to tol."""
    pts = []  # list of (angle, x)
    dirs = [0.5 * math.pi, 0.0, math.pi, 1.5 * math.pi]
    for k, th in enumerate(dirs):
        x = first if (k == 0 and first is not None) else lp.maximize(math.cos(th), math.sin(th))
        if x is None:
            return None
        pts.append((th, x))
    pts.sort(key=lambda p: p[0])
    # refine edges between consecutive support points
    stack = [(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
    done = []
    guard = 0
    while stack:
        guard += 1
        (ta, xa), (tb, xb) = stack.pop()
        pa, pb = xa[:2], xb[:2]
        e = pb - pa
        if np.hypot(*e) <= tol:
            done.append((ta, xa))
            continue
        nrm = np.array([e[1], -e[0]]) / np.hypot(*e)  # outward for CCW order
        x = lp.maximize(nrm[0], nrm[1])
        if x is None or guard > 400:
            done.append((ta, xa))
            continue
        if float(nrm @ (x[:2] - pa)) > tol:
            tm = math.atan2(nrm[1], nrm[0]) % (2 * math.pi)
            stack.append(((tm, x), (tb, xb)))
            stack.append(((ta, xa), (tm, x)))
        else:
            done.append((ta, xa))
    X = np.array([x for _, x in done])
    order = ccw_order(X[:, :2])
    return X[order]


