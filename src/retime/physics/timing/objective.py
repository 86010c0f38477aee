"""The retiming objective (McCann et al. 2006, Eq. 14, sec. 3.5-3.6), baked and compiled.

    E = integral over output time of  alpha pen(d) + beta |tau(p'', p'^2) - tau'|^2 / tau_scale^2
      + gamma * integral over source time of (p' + 1/p' - 2)

``d`` is the distance from (p'', p'^2) to the frame's region, in the plane (``metric="plane"``, the
paper's) or with u and v scaled per frame by the root wrench they demand (``"residual"``, the
default, :func:`residual_scales`); ``pen(d)`` is d^2 as in Eq. 14 (``penalty="l2"``) or the exact
penalty sqrt(d^2 + delta^2) - delta (``"l1"``, which :mod:`retime.physics.api` uses). The last
term, a mild preference for the original speed, is not the paper's (``gamma = 0`` removes it).
``tau`` are the actuated joint torques with the fan contact model of :mod:`retime.physics.regions.forces`;
the target ``tau'`` is zero (``"minimize"``, least effort) or the original motion's torques at its
original timing (``"match"``). ``tau_scale^2`` is the mean squared original torque, so ``beta`` is
dimensionless. Inside one fan wedge lambda is affine in (p'', p'^2), hence the squared torque error
is a quadratic in (u, v) = (p'', p'^2): **six coefficients** per frame and wedge, of
v^2 = p'^4, u^2 = p''^2, u v = p'^2 p'', v = p'^2, u = p'' and 1 (sec. 3.6). Baking them removes the
dependence on the number of degrees of freedom from every later evaluation.

**Excess torque error.** When the physics change (a quarter of the gravity, a heavier thigh),
part of the torque difference cannot be removed by any timing: the target torques of ``"match"``
hold up the original weight. Integrated over output time, that unreachable floor rewards playing such
frames faster, whatever their dynamics (and with ``"minimize"`` and a free duration it would shrink
the clip without end). By default (``excess=True``) each frame's torque term is therefore measured
from the least value any timing could give it (exactly 0 at the original timing for ``"match"``
with unchanged physics, so the paper's setting is unaffected); ``excess=False`` keeps Eq. 14 as
written.

**Integration.** The integral over output time is taken over source time instead,
``E = integral f / p' ds``, with samples at a fixed spacing of 1 / (samples_per_frame * fps) in
source time (4 per source frame by default, as the paper asks: "at least once every quarter of a
source frame"). Each sample takes the terms of its nearest frame (``interp="nearest"``, the default)
or blends the two frames around it (``"linear"``, as the paper interpolates the coefficients). Each
sample's output time is found by inverting the spline (Newton,
amortized by locality), so the set of samples and their frames never change during optimization
and the objective is smooth in the spline's parameters. Its gradient is analytic: with respect to the
coefficients c and the duration T (each sample touches the spline's ``support`` = 5 coefficients), then through
:meth:`TimingSpline.chain` to the optimizer's variables.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from ...errors import RetimeError
from ..regions.polygon import boundary_closest, edge_projection

OBJECTIVES = ("match", "minimize")
FAN_BLEND = 0.01  # body weights: the torque term's kinks at the fan rays are smoothed over this band,
# the force model's own uncertainty (regions widen every frame's rows by a pad of 1% of body weight)
FAN_BLEND_ANGLE = 0.25  # radians: the smoothing's half-width near the centre, where eps / r would grow


class BakedArrays(NamedTuple):
    """What the compiled evaluation reads (see :func:`bake`), passed to every kernel as one value."""

    poff: np.ndarray  # (n+1,) polygon offsets
    px: np.ndarray  # (P,) polygon vertices, in the frame's metric
    py: np.ndarray
    cen: np.ndarray  # (n, 2) fan centres, in the frame's metric
    scale: np.ndarray  # (n, 2) metric of the feasibility term: (u, v) -> (scale_u u, scale_v v)
    mode: np.ndarray  # (n,) 0 = fan wedges, 1 = one torque model + fan distance, 2 = degenerate polygon
    wc: np.ndarray  # (P, 6) torque coefficients per wedge (wedge k of frame i at poff[i] + k)
    s: np.ndarray  # (Ns,) source sample times
    omega: np.ndarray  # (Ns,) trapezoid weights in source time
    fi: np.ndarray  # (Ns,) frame index of each sample
    fw: np.ndarray  # (Ns,) weight of frame fi + 1
    alpha: float  # weight of the feasibility term
    delta: float  # 0: alpha d^2 (Eq. 14); > 0: alpha (sqrt(d^2 + delta^2) - delta) (exact penalty)
    gamma: float  # weight of the speed regularizer gamma (p' + 1/p' - 2) per source second
    blend: float  # half-width (body weights, the frame's metric) of the smoothing across fan rays; 0: none
    ray: np.ndarray  # (P,) angle of each vertex's ray from its frame's fan centre, in the metric


@dataclass
class BakedObjective:
    """The baked objective (see :func:`bake`): immutable once baked, so sessions and threads may
    share it; what an evaluation changes lives in an :class:`ObjectiveWorkspace`."""

    times: np.ndarray  # (n,) frame source times
    arrays: BakedArrays
    beta: float
    tau_scale: float
    seconds: float = 0.0

    @property
    def n_frames(self) -> int:
        return len(self.times)


@dataclass
class ObjectiveWorkspace:
    """The mutable side of evaluating one objective: the last fan wedge found per frame, where the
    next lookup starts (amortized: consecutive evaluations ask about nearby timings). Belongs to one
    optimization (:class:`~.optimize.Problem`, hence one :class:`~.optimize.RetimingSession`) and
    one thread."""

    wedge: np.ndarray  # (n,) int64

    @classmethod
    def for_objective(cls, obj: BakedObjective) -> ObjectiveWorkspace:
        return cls(np.zeros(obj.n_frames, dtype=np.int64))


def _wedges(obj, workspace):
    return (workspace or ObjectiveWorkspace.for_objective(obj)).wedge


def samples(times, samples_per_frame=4, interp="nearest"):
    """Source sample times, trapezoid weights, frame index and interpolation weight.

    ``interp="linear"`` blends the two frames around a sample (the paper's linear interpolation of
    coefficients); ``"nearest"`` (default) takes the nearest frame's, which needs one frame
    evaluation per sample instead of up to two for the same sampling density."""
    times = np.asarray(times, dtype=float)
    spf = int(samples_per_frame)
    if spf < 1:
        raise RetimeError("samples per frame must be at least 1")
    n = len(times)
    sub = np.arange(spf) / spf
    s = (times[:-1, None] + sub[None, :] * np.diff(times)[:, None]).ravel()
    s = np.append(s, times[-1])
    fi = np.minimum(np.repeat(np.arange(n - 1), spf), n - 2)
    fi = np.append(fi, n - 2)
    fw = np.append(np.tile(sub, n - 1), 1.0)
    if interp == "nearest":
        fi = np.minimum(np.rint(fi + fw).astype(np.int64), n - 1)
        fw = np.zeros_like(fw)
    elif interp != "linear":
        raise RetimeError(f"unknown interpolation {interp!r} (use 'nearest' or 'linear')")
    om = np.empty_like(s)
    ds = np.diff(s)
    om[0] = ds[0] / 2
    om[-1] = ds[-1] / 2
    om[1:-1] = (ds[:-1] + ds[1:]) / 2
    return s, om, fi.astype(np.int64), fw


def subsampled(obj: BakedObjective, stride: int) -> BakedObjective:
    """The same objective integrated on every ``stride``-th sample (the last one kept), with the
    trapezoid weights of that coarser spacing: what :func:`samples` gives for ``samples_per_frame /
    stride`` samples per frame, without baking again (the frames' coefficients are shared)."""
    a = obj.arrays
    idx = np.arange(0, len(a.s), int(stride))
    if idx[-1] != len(a.s) - 1:
        idx = np.append(idx, len(a.s) - 1)
    s = a.s[idx]
    ds = np.diff(s)
    om = np.empty_like(s)
    om[0] = ds[0] / 2
    om[-1] = ds[-1] / 2
    om[1:-1] = (ds[:-1] + ds[1:]) / 2
    return dataclasses.replace(obj, arrays=a._replace(s=s, omega=om, fi=a.fi[idx], fw=a.fw[idx]))


def target_torques(kind, pd0, regions0):
    """Target torques per frame (all rows): zeros or the original's (see forces.original_torques)."""
    from ..regions.forces import original_torques

    if kind == "minimize":
        return np.zeros_like(np.asarray(pd0.c, dtype=float))
    if kind == "match":
        return original_torques(pd0, regions0)
    raise RetimeError(f"unknown objective {kind!r} (use 'match' or 'minimize')")


def actuated_mask(pd):
    lo, hi = np.asarray(pd.tau_lo), np.asarray(pd.tau_hi)
    return ~((lo == 0) & (hi == 0))


def residual_scales(pd, body_weight, moment_arm=1.0, floor=0.01, actuated_cost=0.0):
    """Per frame, body weights of root wrench per unit of p'' and of p'^2: (n, 2).

    The root rows of a timing (u, v) demand the external wrench a u + b v + c; moving by du needs
    |a_root| du more of it. Scaling the (p'', p'^2) plane by these before measuring the distance to
    the region makes the feasibility term count how much force a violation would take: a stance
    frame played too fast costs what its small accelerations ask, a flight frame played too fast
    costs (p'^2 - 1) body weights. ``floor`` keeps still frames from costing nothing at all."""
    n_root = int(getattr(pd, "n_root", 6))
    nr = np.asarray(pd.a).shape[1] if actuated_cost > 0 else n_root
    a = np.asarray(pd.a, dtype=float)[:, :nr]
    b = np.asarray(pd.b, dtype=float)[:, :nr]
    w = np.full(nr, body_weight * moment_arm)
    w[: min(3, n_root)] = body_weight
    w[n_root:] /= max(actuated_cost, 1e-300)
    if nr == 0:
        return np.ones((len(a), 2))
    su = np.linalg.norm(a / w, axis=1)
    sv = np.linalg.norm(b / w, axis=1)
    return np.maximum(np.stack([su, sv], axis=1), floor)


def bake(pd, regions, target, alpha=1.0, beta=1.0, tau_scale=None, samples_per_frame=4,
         metric="residual", excess=True, gamma=0.0, u_max=None, v_range=None, penalty="l2",
         delta=1e-3, interp="nearest", fan_blend=FAN_BLEND) -> BakedObjective:
    """Bake Eq. 14 into per-frame, per-wedge coefficients (sec. 3.6).

    ``metric``: ``"plane"`` measures the distance to the region in the (p'', p'^2) plane as the
    paper does; ``"residual"`` (default) scales the plane per frame by :func:`residual_scales`.
    ``excess``: subtract from each frame's torque term the least value any timing could give it
    (see the module docstring); ``False`` keeps Eq. 14 literally.)"""
    import time

    t0 = time.perf_counter()
    act = np.flatnonzero(actuated_mask(pd)).astype(np.int64)
    # read in place on the actuated rows: copies of them were 0.2 GB of a 10-minute capture's peak
    a, b, c, tgt = (np.asarray(x, dtype=float) for x in (pd.a, pd.b, pd.c, target))
    basis = pd.N  # a ContactBasis, read on its own rows: no dense (n, nv, K) copy
    rows = basis.row_index()[act]  # each actuated row's place in basis.values (-1: always zero)
    if tau_scale is None:
        tau_scale = float(np.sqrt(np.mean(np.sum(tgt[:, act] ** 2, axis=1)))) or 1.0
    poff = np.asarray(regions.offsets, dtype=np.int64)
    px = np.ascontiguousarray(regions.verts[:, 0])
    py = np.ascontiguousarray(regions.verts[:, 1])
    cen = np.ascontiguousarray(regions.center, dtype=float)
    lam = np.ascontiguousarray(regions.lam, dtype=float)
    clam = np.ascontiguousarray(regions.center_lam, dtype=float)
    has_contact = np.any(clam != 0, axis=1) | np.array(
        [np.any(regions.polygon_lam(i) != 0) for i in range(regions.n_frames)])
    mode = _fan_modes(poff, px, py, cen)
    mode = np.where((mode == 0) & ~has_contact, 1, mode).astype(np.int64)
    wc = np.zeros((len(px), 6))
    for part, values in basis.chunks():  # frame by frame: each chunk's wedges are written in place
        _bake_kernel(a[part], b[part], c[part], tgt[part], act, values, rows, poff[part.start:part.stop + 1], px, py,
                     cen[part], lam, clam[part], mode[part], beta / tau_scale ** 2, wc)
    if excess:
        U = float(u_max if u_max is not None else regions.options.u_max)
        vlo, vhi = v_range if v_range is not None else (0.0, float(regions.options.v_max))
        _subtract_floor(poff, wc, U, float(vlo), float(vhi))
    if metric == "plane":
        scale = np.ones((len(poff) - 1, 2))
    elif metric == "residual":
        scale = residual_scales(pd, regions.body_weight or 1.0, regions.options.moment_arm)
    elif metric == "residual_all":
        scale = residual_scales(pd, regions.body_weight or 1.0, regions.options.moment_arm,
                                actuated_cost=regions.options.actuated_slack_cost)
    else:
        raise RetimeError(f"unknown metric {metric!r} (use 'residual', 'residual_all' or 'plane')")
    cnt = np.diff(poff)
    sx = np.repeat(scale[:, 0], cnt)
    sy = np.repeat(scale[:, 1], cnt)
    s, om, fi, fw = samples(regions.times, samples_per_frame, interp)
    # pack what one lookup touches together: per vertex (x, y, six coefficients), per frame (scale, centre)
    V = np.empty((len(px), 8))
    V[:, 0], V[:, 1], V[:, 2:] = px * sx, py * sy, wc
    Fr = np.empty((len(poff) - 1, 4))
    Fr[:, :2], Fr[:, 2:] = scale, cen * scale
    C = np.ascontiguousarray
    if penalty not in ("l1", "l2"):
        raise RetimeError(f"unknown penalty {penalty!r} (use 'l2' or 'l1')")
    # each vertex's ray angle from its frame's fan centre, in the metric (a uniform rescaling, as soften's,
    # keeps it): the smoothing across rays reads these instead of an arctan2 per ray and sample
    ray = np.arctan2(V[:, 1] - np.repeat(Fr[:, 3], cnt), V[:, 0] - np.repeat(Fr[:, 2], cnt))
    arrays = BakedArrays(poff, C(V[:, 0]), C(V[:, 1]), C(Fr[:, 2:]), C(Fr[:, :2]), mode, C(V[:, 2:]), s, om, fi, fw,
                         float(alpha), 0.0 if penalty == "l2" else float(delta), float(gamma), float(fan_blend),
                         C(ray))
    out = BakedObjective(np.asarray(regions.times, float), arrays, float(beta), float(tau_scale))
    out.seconds = time.perf_counter() - t0
    return out


@njit(cache=True)
def _fan_modes(poff, px, py, cen):
    n = len(poff) - 1
    mode = np.zeros(n, dtype=np.int64)
    for i in range(n):
        p0, p1 = poff[i], poff[i + 1]
        nv = p1 - p0
        if nv < 3:
            mode[i] = 2
            continue
        area = 0.0
        ext = 0.0
        for k in range(nv):
            j = p0 + (k + 1) % nv
            area += px[p0 + k] * py[j] - py[p0 + k] * px[j]
            ext = max(ext, abs(px[p0 + k]) + abs(py[p0 + k]))
        if area <= 1e-12 * (1.0 + ext * ext):
            mode[i] = 2
            continue
        for k in range(nv):
            j = p0 + (k + 1) % nv
            r0x, r0y = px[p0 + k] - cen[i, 0], py[p0 + k] - cen[i, 1]
            r1x, r1y = px[j] - cen[i, 0], py[j] - cen[i, 1]
            if r0x * r1y - r0y * r1x <= 1e-14 * (1.0 + ext * ext):
                mode[i] = 2
                break
    return mode


@njit(cache=True, inline="always")
def _q(w, u, v):
    return w[0] * v * v + w[1] * u * u + w[2] * u * v + w[3] * v + w[4] * u + w[5]


@njit(cache=True)
def _quad_min_box(w, U, vlo, vhi):
    """Least value over [-U, U] x [vlo, vhi] of the convex quadratic
    w0 v^2 + w1 u^2 + w2 u v + w3 v + w4 u + w5: interior stationary point, else an edge."""
    h11, h12, h22 = 2.0 * w[1], w[2], 2.0 * w[0]
    g1, g2 = w[4], w[3]
    det = h11 * h22 - h12 * h12
    tr = h11 + h22
    if det > 1e-12 * (tr * tr + 1e-300):
        u = -(h22 * g1 - h12 * g2) / det
        v = -(-h12 * g1 + h11 * g2) / det
        if -U <= u <= U and vlo <= v <= vhi:
            return _q(w, u, v)
    best = 1e300
    # edges u = +-U (minimize over v), v = vlo / vhi (minimize over u)
    for k in range(2):
        u = -U if k == 0 else U
        v = -(h12 * u + g2) / h22 if h22 > 0 else vlo
        v = min(vhi, max(vlo, v))
        best = min(best, _q(w, u, v), _q(w, u, vlo), _q(w, u, vhi))
        v = vlo if k == 0 else vhi
        u = -(h12 * v + g1) / h11 if h11 > 0 else 0.0
        u = min(U, max(-U, u))
        best = min(best, _q(w, u, v), _q(w, -U, v), _q(w, U, v))
    return best


@njit(cache=True)
def _subtract_floor(poff, wc, U, vlo, vhi):
    """Make each frame's torque term an excess over the least value any timing in the box gives it
    (a lower bound: the smallest box-constrained minimum over the frame's wedge quadratics)."""
    for i in range(len(poff) - 1):
        lo = 1e300
        for k in range(poff[i], poff[i + 1]):
            lo = min(lo, _quad_min_box(wc[k], U, vlo, vhi))
        if lo < 1e300:
            for k in range(poff[i], poff[i + 1]):
                wc[k, 5] -= lo


@njit(cache=True)
def _coefs(A, B, D, scale, out):
    aa = 0.0
    bb = 0.0
    ab = 0.0
    bd = 0.0
    ad = 0.0
    dd = 0.0
    for r in range(A.shape[0]):
        aa += A[r] * A[r]
        bb += B[r] * B[r]
        ab += A[r] * B[r]
        bd += B[r] * D[r]
        ad += A[r] * D[r]
        dd += D[r] * D[r]
    out[0] = scale * bb  # v^2   (p'^4)
    out[1] = scale * aa  # u^2   (p''^2)
    out[2] = scale * 2.0 * ab  # u v   (p'^2 p'')
    out[3] = scale * 2.0 * bd  # v     (p'^2)
    out[4] = scale * 2.0 * ad  # u     (p'')
    out[5] = scale * dd  # 1


@njit(cache=True)
def _bake_kernel(a, b, c, tgt, act, N, rows, poff, px, py, cen, lam, clam, mode, scale, wc):
    """wc per vertex. a, b, c, tgt (n, nv) are read on the actuated rows ``act`` (nr,) in place; N
    (n, R, K) is the contact basis on its own rows (:class:`retime.physics.model.contact_basis.ContactBasis`), ``rows``
    the place of each actuated row in it (-1: a row of zeros), read one frame at a time."""
    n = a.shape[0]
    nr = len(act)
    K = N.shape[2]
    A = np.empty(nr)
    B = np.empty(nr)
    D = np.empty(nr)
    Ni = np.empty((nr, K))
    for i in range(n):
        p0, p1 = poff[i], poff[i + 1]
        nvx = p1 - p0
        for r in range(nr):
            if rows[r] >= 0:
                Ni[r] = N[i, rows[r]]
            else:
                Ni[r] = 0.0
        Fc = Ni @ clam[i]
        if mode[i] != 0:
            for r in range(nr):
                A[r] = a[i, act[r]]
                B[r] = b[i, act[r]]
                D[r] = c[i, act[r]] - Fc[r] - tgt[i, act[r]]
            for k in range(nvx):
                _coefs(A, B, D, scale, wc[p0 + k])
            continue
        F = np.empty((nvx, nr))
        for k in range(nvx):
            F[k] = Ni @ lam[p0 + k]
        cu, cv = cen[i, 0], cen[i, 1]
        for k in range(nvx):
            l = (k + 1) % nvx
            e0x, e0y = px[p0 + k] - cu, py[p0 + k] - cv
            e1x, e1y = px[p0 + l] - cu, py[p0 + l] - cv
            det = e0x * e1y - e1x * e0y
            m00, m01 = e1y / det, -e1x / det
            m10, m11 = -e0y / det, e0x / det
            for r in range(nr):
                dk = F[k, r] - Fc[r]
                dl = F[l, r] - Fc[r]
                nlu = m00 * dk + m10 * dl
                nlv = m01 * dk + m11 * dl
                nl0 = Fc[r] - cu * nlu - cv * nlv
                A[r] = a[i, act[r]] - nlu
                B[r] = b[i, act[r]] - nlv
                D[r] = c[i, act[r]] - nl0 - tgt[i, act[r]]
            _coefs(A, B, D, scale, wc[p0 + k])


# ------------------------------------------------------------------------------------------------
# Evaluation
# ------------------------------------------------------------------------------------------------

@njit(cache=True, error_model="numpy", inline="always")
def _frame_parts(i, u0, v0, ob, cache):
    """Frame i at (u, v) = (p'', p'^2) of the baked arrays ``ob``: the torque term g and its gradient
    (gu, gv), the offset (du, dv) from the region's closest point and its square d2 (in the frame's
    metric, which scales u by su and v by sv). ``cache[i]``: the wedge to start from, updated."""
    g, gu, gv, _, _, _, du, dv, d2, su, sv = _frame_geometry(i, u0, v0, ob, cache)
    return g, gu, gv, du, dv, d2, su, sv


@njit(cache=True, error_model="numpy", inline="always")
def _frame_geometry(i, u0, v0, ob, cache):
    """:func:`_frame_parts` with the torque term's second derivatives (guu, guv, gvv) after its gradient."""
    poff, px, py, cen, scale, mode, wc = ob.poff, ob.px, ob.py, ob.cen, ob.scale, ob.mode, ob.wc
    su, sv = scale[i, 0], scale[i, 1]
    u, v = su * u0, sv * v0
    p0, p1 = poff[i], poff[i + 1]
    nv = p1 - p0
    md = mode[i]
    cu, cv = cen[i, 0], cen[i, 1]
    at_centre = True
    if md == 2:
        qx, qy = boundary_closest(p0, p1, px, py, u, v)
        k = 0
        # a degenerate polygon is a point or a segment: its interior is empty
    else:
        dx, dy = u - cu, v - cv
        k = cache[i]
        if k >= nv:
            k = 0
        # walk the fan to the wedge containing (u, v). At the centre (the original timing, up to
        # rounding) every wedge gives the same value, and the walk would chase the rounding's random
        # direction around the polygon: keep the cached wedge.
        at_centre = dx * dx + dy * dy <= 1e-24 * (1.0 + cu * cu + cv * cv)
        for _ in range(0 if at_centre else nv + 1):
            j = k + 1 if k + 1 < nv else 0
            r0x, r0y = px[p0 + k] - cu, py[p0 + k] - cv
            r1x, r1y = px[p0 + j] - cu, py[p0 + j] - cv
            c0 = r0x * dy - r0y * dx
            c1 = dx * r1y - dy * r1x
            if c0 >= 0.0 and c1 > 0.0:
                break
            if c0 < 0.0:
                k = k - 1 if k > 0 else nv - 1
            else:
                k = j
        cache[i] = k
        j = k + 1 if k + 1 < nv else 0
        ax, ay = px[p0 + k], py[p0 + k]
        ex, ey = px[p0 + j] - ax, py[p0 + j] - ay
        side = ex * (v - ay) - ey * (u - ax)
        if side >= 0.0:
            qx, qy = u, v
        else:
            # outside, beyond edge k: walk along the boundary while the distance drops
            qx, qy, t = edge_projection(p0, nv, k, px, py, u, v)
            d = (qx - u) ** 2 + (qy - v) ** 2
            if t < 0.0 or t > 1.0:
                step = -1 if t < 0.0 else 1
                e = k
                for _ in range(nv):
                    e = e + step
                    if e < 0:
                        e = nv - 1
                    elif e >= nv:
                        e = 0
                    q2x, q2y, t2 = edge_projection(p0, nv, e, px, py, u, v)
                    d2 = (q2x - u) ** 2 + (q2y - v) ** 2
                    if d2 < d:
                        qx, qy, d = q2x, q2y, d2
                        if 0.0 <= t2 <= 1.0:
                            break
                    else:
                        break
    kw = p0 + k if md == 0 else p0
    g, gu, gv = _wedge_quadratic(wc, kw, u0, v0)
    guu, guv, gvv = 2.0 * wc[kw, 1], wc[kw, 2], 2.0 * wc[kw, 0]
    if md == 0 and not at_centre and ob.blend > 0.0 and _near_a_ray(p0, nv, k, u, v, cu, cv, px, py, ob.blend):
        g, gu, gv, guu, guv, gvv = _fan_blend(p0, nv, k, u, v, u0, v0, su, sv, cu, cv, ob.ray, wc, ob.blend,
                                              g, gu, gv, guu, guv, gvv)
    du, dv = u - qx, v - qy
    return g, gu, gv, guu, guv, gvv, du, dv, du * du + dv * dv, su, sv


@njit(cache=True, error_model="numpy", inline="always")
def _wedge_quadratic(wc, kw, u0, v0):
    """The torque term of wedge row ``kw`` at (u, v) and its gradient."""
    w0, w1, w2, w3, w4, w5 = wc[kw, 0], wc[kw, 1], wc[kw, 2], wc[kw, 3], wc[kw, 4], wc[kw, 5]
    g = w0 * v0 * v0 + w1 * u0 * u0 + w2 * u0 * v0 + w3 * v0 + w4 * u0 + w5
    return g, 2.0 * w1 * u0 + w2 * v0 + w4, 2.0 * w0 * v0 + w2 * u0 + w3


@njit(cache=True, error_model="numpy", inline="always")
def _angle_between(a, b):
    """(b - a) mod 2 pi, in [0, 2 pi)."""
    x = b - a
    two_pi = 2.0 * math.pi
    x -= two_pi * math.floor(x / two_pi)
    return x


@njit(cache=True, error_model="numpy", inline="always")
def _smooth_step(x):
    """(S, dS/dx) of the C2 step from 0 at x <= -1 to 1 at x >= 1 (S(0) = 1/2, S(-x) = 1 - S(x))."""
    if x <= -1.0:
        return 0.0, 0.0
    if x >= 1.0:
        return 1.0, 0.0
    return fan_blend_weight(x)


@njit(cache=True, error_model="numpy", inline="always")
def _near_a_ray(p0, nv, k, u, v, cu, cv, px, py, eps):
    """Is (u, v) within the smoothing band of either ray of wedge k? Without trigonometry (the usual
    answer is no): the angle from a ray is below the band iff it points the same way and
    cross < tan(band) dot."""
    dx, dy = u - cu, v - cv
    r = math.sqrt(dx * dx + dy * dy)
    tb = math.tan(eps * FAN_BLEND_ANGLE / (eps + r * FAN_BLEND_ANGLE))
    j = k + 1 if k + 1 < nv else 0
    r0x, r0y = px[p0 + k] - cu, py[p0 + k] - cv
    r1x, r1y = px[p0 + j] - cu, py[p0 + j] - cv
    dot0 = r0x * dx + r0y * dy
    dot1 = r1x * dx + r1y * dy
    return (dot0 > 0.0 and r0x * dy - r0y * dx < tb * dot0) or (dot1 > 0.0 and dx * r1y - dy * r1x < tb * dot1)


@njit(cache=True, error_model="numpy")
def _fan_blend(p0, nv, k, u, v, u0, v0, su, sv, cu, cv, ray, wc, eps, g, gu, gv, guu, guv, gvv):
    """The torque term mollified in the fan's angle (see :data:`FAN_BLEND`): each wedge q's
    quadratic weighted by psi_q = S((phi - theta_q) / b) - S((phi - theta_{q+1}) / b), its indicator
    over the angle phi smoothed by a C2 kernel of half-width b (a partition of unity: the weights sum
    to 1). b = eps / r far from the centre (eps in the frame's metric, body weights), softly capped at
    FAN_BLEND_ANGLE near it: b = eps B / (eps + r B). Where no ray is within b of phi this is the
    wedge's own quadratic ``g``; the fan's kinks (wedge k's gradient differs from its neighbours')
    become C2, whatever the wedges' widths. (u, v) in the metric, (u0, v0) the timing itself.
    Returns the value, its gradient and its second derivatives (uu, uv, vv) in (u0, v0); ``g`` .. ``gvv``
    are wedge k's own."""
    dx, dy = u - cu, v - cv
    r2 = dx * dx + dy * dy
    r = math.sqrt(r2)
    B = FAN_BLEND_ANGLE
    band = eps * B / (eps + r * B)
    j = k + 1 if k + 1 < nv else 0
    phi = math.atan2(dy, dx)
    th_k = ray[p0 + k]
    lo = _angle_between(th_k, phi)  # phi - theta_k >= 0
    hi = lo - _angle_between(th_k, ray[p0 + j])  # phi - theta_{k+1} <= 0
    if lo >= band and hi <= -band:
        return g, gu, gv, guu, guv, gvv  # no ray within the band: the wedge's own quadratic
    dphi_u, dphi_v = -dy * su / r2, dx * sv / r2
    dband_dr = -eps * B * B / ((eps + r * B) ** 2)
    db_u, db_v = dband_dr * dx * su / r, dband_dr * dy * sv / r
    # second derivatives in (u0, v0) of the angle phi and of the band b(r) (the metric scales u by su, v by sv)
    r4 = r2 * r2
    phi_uu, phi_uv, phi_vv = 2.0 * dx * dy * su * su / r4, (dy * dy - dx * dx) * su * sv / r4, -2.0 * dx * dy * sv * sv / r4
    d2band_dr2 = 2.0 * eps * B ** 3 / ((eps + r * B) ** 3)
    r3 = r2 * r
    ru, rv = dx * su / r, dy * sv / r
    b_uu = d2band_dr2 * ru * ru + dband_dr * dy * dy * su * su / r3
    b_uv = d2band_dr2 * ru * rv - dband_dr * dx * dy * su * sv / r3
    b_vv = d2band_dr2 * rv * rv + dband_dr * dx * dx * sv * sv / r3
    tot, tu, tv = 0.0, 0.0, 0.0
    tuu, tuv, tvv = 0.0, 0.0, 0.0
    # wedge k, then outwards on both sides while the wedge's nearer ray is within the band
    for direction in range(2):
        q = k
        d_lo, d_hi = lo, hi  # phi - theta_q, phi - theta_{q+1} (unwrapped around phi)
        for step in range(nv):
            if step > 0:
                if direction == 0:  # the wedge below: its upper ray is q's lower one
                    qn = q - 1 if q > 0 else nv - 1
                    d_hi = d_lo
                    d_lo = d_lo + _angle_between(ray[p0 + qn], ray[p0 + q])
                else:
                    qn = q + 1 if q + 1 < nv else 0
                    qnn = qn + 1 if qn + 1 < nv else 0
                    d_lo = d_hi
                    d_hi = d_hi - _angle_between(ray[p0 + qn], ray[p0 + qnn])
                q = qn
                if (direction == 0 and d_hi >= band) or (direction == 1 and d_lo <= -band):
                    break
            if direction == 1 and step == 0:
                continue  # wedge k counted once
            s_lo, ds_lo = _smooth_step(d_lo / band)
            s_hi, ds_hi = _smooth_step(d_hi / band)
            psi = s_lo - s_hi
            if psi == 0.0 and ds_lo == 0.0 and ds_hi == 0.0:
                continue
            gq, guq, gvq = _wedge_quadratic(wc, p0 + q, u0, v0)
            # d psi: d(d / b) = d phi / b - (d / b) db / b
            xl, xh = d_lo / band, d_hi / band
            dpsi_u = ds_lo * (dphi_u - xl * db_u) / band - ds_hi * (dphi_u - xh * db_u) / band
            dpsi_v = ds_lo * (dphi_v - xl * db_v) / band - ds_hi * (dphi_v - xh * db_v) / band
            tot += psi * gq
            tu += psi * guq + gq * dpsi_u
            tv += psi * gvq + gq * dpsi_v
            # second derivatives of x = d / b: (phi_ij - x_i b_j - x_j b_i - x b_ij) / b, per ray
            xlu, xlv = (dphi_u - xl * db_u) / band, (dphi_v - xl * db_v) / band
            xhu, xhv = (dphi_u - xh * db_u) / band, (dphi_v - xh * db_v) / band
            c_lo, c_hi = _smooth_step_curvature(xl), _smooth_step_curvature(xh)
            psi_uu = (c_lo * xlu * xlu + ds_lo * (phi_uu - 2.0 * xlu * db_u - xl * b_uu) / band
                      - c_hi * xhu * xhu - ds_hi * (phi_uu - 2.0 * xhu * db_u - xh * b_uu) / band)
            psi_uv = (c_lo * xlu * xlv + ds_lo * (phi_uv - xlu * db_v - xlv * db_u - xl * b_uv) / band
                      - c_hi * xhu * xhv - ds_hi * (phi_uv - xhu * db_v - xhv * db_u - xh * b_uv) / band)
            psi_vv = (c_lo * xlv * xlv + ds_lo * (phi_vv - 2.0 * xlv * db_v - xl * b_vv) / band
                      - c_hi * xhv * xhv - ds_hi * (phi_vv - 2.0 * xhv * db_v - xh * b_vv) / band)
            tuu += psi_uu * gq + 2.0 * dpsi_u * guq + psi * 2.0 * wc[p0 + q, 1]
            tuv += psi_uv * gq + dpsi_u * gvq + dpsi_v * guq + psi * wc[p0 + q, 2]
            tvv += psi_vv * gq + 2.0 * dpsi_v * gvq + psi * 2.0 * wc[p0 + q, 0]
    return tot, tu, tv, tuu, tuv, tvv


@njit(cache=True, error_model="numpy", inline="always")
def _smooth_step_curvature(x):
    """d2S/dx2 of :func:`fan_blend_weight`'s step (0 outside (-1, 1))."""
    if x <= -1.0 or x >= 1.0:
        return 0.0
    return -3.75 * x * (1.0 - x * x)


@njit(cache=True, error_model="numpy", inline="always")
def fan_blend_weight(x):
    """(w, dw/dx) of the C2 step from 0 at x = -1 to 1 at x = 1 (w(0) = 1/2, w(-x) = 1 - w(x))."""
    x2 = x * x
    return 0.5 + x * (15.0 - 10.0 * x2 + 3.0 * x2 * x2) / 16.0, 15.0 * (1.0 - x2) * (1.0 - x2) / 16.0


@njit(cache=True, error_model="numpy", inline="always")
def penalty(d2, alpha, delta):
    """The feasibility term of a squared distance d2: alpha d2 (Eq. 14, delta <= 0) or the exact penalty
    alpha (sqrt(d2 + delta^2) - delta)."""
    if d2 == 0.0:
        return 0.0
    if delta <= 0.0:
        return alpha * d2
    return alpha * (math.sqrt(d2 + delta * delta) - delta)


@njit(cache=True, error_model="numpy", inline="always")
def _frame_eval(i, u0, v0, ob, cache):
    """f, df/du, df/dv of frame i at (u, v) = (p'', p'^2) (polygon and centre in the frame's metric)."""
    alpha, delta = ob.alpha, ob.delta
    g, gu, gv, du, dv, d2, su, sv = _frame_parts(i, u0, v0, ob, cache)
    if d2 == 0.0:  # inside the region: only the torque term
        return g, gu, gv
    if delta <= 0.0:
        return alpha * d2 + g, 2.0 * alpha * du * su + gu, 2.0 * alpha * dv * sv + gv
    r = math.sqrt(d2 + delta * delta)
    k = alpha / r
    return alpha * (r - delta) + g, k * du * su + gu, k * dv * sv + gv


@njit(cache=True, error_model="numpy", inline="always")
def _distance_curvature(p0, nv, px, py, x, y):
    """Half the Hessian of the squared distance from (x, y) (outside) to the boundary of polygon p0
    (nv vertices), in the metric: n n^T (n the unit normal) where the closest point is inside an edge,
    the identity where it is a vertex. (kxx, kxy, kyy); the nearest edge by a scan of all of them."""
    best, t_best, nx, ny = 1e300, 0.0, 0.0, 0.0
    for e in range(nv if nv > 1 else 1):
        qx, qy, t = edge_projection(p0, nv, e, px, py, x, y)
        d = (qx - x) ** 2 + (qy - y) ** 2
        if d < best:
            best, t_best, nx, ny = d, t, x - qx, y - qy
    if 0.0 < t_best < 1.0 and best > 0.0:
        return nx * nx / best, nx * ny / best, ny * ny / best
    return 1.0, 0.0, 1.0


@njit(cache=True, error_model="numpy", inline="always")
def _frame_second(i, u0, v0, ob, cache):
    """f, df/du, df/dv, d2f/du2, d2f/dudv, d2f/dv2 of frame i at (u, v) = (p'', p'^2)."""
    alpha, delta = ob.alpha, ob.delta
    g, gu, gv, guu, guv, gvv, du, dv, d2, su, sv = _frame_geometry(i, u0, v0, ob, cache)
    if d2 == 0.0:  # inside the region: only the torque term
        return g, gu, gv, guu, guv, gvv
    p0 = ob.poff[i]
    kxx, kxy, kyy = _distance_curvature(p0, ob.poff[i + 1] - p0, ob.px, ob.py, su * u0, sv * v0)
    if delta <= 0.0:  # alpha d^2: gradient 2 alpha (du, dv), Hessian 2 alpha K (in the metric)
        a2 = 2.0 * alpha
        return (alpha * d2 + g, a2 * du * su + gu, a2 * dv * sv + gv,
                a2 * kxx * su * su + guu, a2 * kxy * su * sv + guv, a2 * kyy * sv * sv + gvv)
    # alpha (r - delta), r = sqrt(d^2 + delta^2): gradient alpha / r (du, dv), Hessian alpha / r (K - d d^T / r^2)
    r = math.sqrt(d2 + delta * delta)
    k = alpha / r
    r2 = r * r
    return (alpha * (r - delta) + g, k * du * su + gu, k * dv * sv + gv,
            k * (kxx - du * du / r2) * su * su + guu, k * (kxy - du * dv / r2) * su * sv + guv,
            k * (kyy - dv * dv / r2) * sv * sv + gvv)


@njit(cache=True, error_model="numpy")
def _span_poly(c, Msp, n_span):
    """Per span, the power coefficients of p in x = tau - break (row m: a_0 .. a_q)."""
    q1 = Msp.shape[1]
    Asp = np.empty((n_span, q1))
    for m in range(n_span):
        for r in range(q1):
            acc = 0.0
            for l in range(q1):
                acc += Msp[m, r, l] * c[m + l]
            Asp[m, r] = acc
    return Asp


@njit(cache=True, error_model="numpy", inline="always")
def _horner(A, m, x):
    """(P, P', P'', p''') at x of the polynomial with power coefficients A[m, :] (Horner, with derivatives)."""
    v, d1, d2, d3 = 0.0, 0.0, 0.0, 0.0
    for r in range(A.shape[1] - 1, -1, -1):
        d3 = d3 * x + d2
        d2 = d2 * x + d1
        d1 = d1 * x + v
        v = v * x + A[m, r]
    return v, d1, 2.0 * d2, 6.0 * d3


@njit(cache=True, error_model="numpy", inline="always")
def _horner_column(M, m, l, x):
    """(N, N', N'') at x of basis function l of span m (power coefficients M[m, :, l])."""
    v, d1, d2 = 0.0, 0.0, 0.0
    for r in range(M.shape[1] - 1, -1, -1):
        d2 = d2 * x + d1
        d1 = d1 * x + v
        v = v * x + M[m, r, l]
    return v, d1, 2.0 * d2


@njit(cache=True, error_model="numpy", inline="always")
def _horner_column3(M, m, l, x):
    """(N, N', N'', N''') at x of basis function l of span m (power coefficients M[m, :, l])."""
    v, d1, d2, d3 = 0.0, 0.0, 0.0, 0.0
    for r in range(M.shape[1] - 1, -1, -1):
        d3 = d3 * x + d2
        d2 = d2 * x + d1
        d1 = d1 * x + v
        v = v * x + M[m, r, l]
    return v, d1, 2.0 * d2, 6.0 * d3


@njit(cache=True, error_model="numpy", inline="always")
def _fourth_derivative(A, m, x):
    """p'''' at x of the polynomial with power coefficients A[m, :] (0 below degree 4)."""
    acc = 0.0
    for r in range(A.shape[1] - 1, 3, -1):
        acc = acc * x + A[m, r] * (r * (r - 1) * (r - 2) * (r - 3))
    return acc


@njit(cache=True, error_model="numpy", inline="always")
def _first_span(Asp, s0):
    """The span whose polynomial starts at or below source time s0 (binary search)."""
    lo_, hi_ = 0, Asp.shape[0] - 1
    while lo_ < hi_:
        mid = (lo_ + hi_ + 1) // 2
        if s0 >= Asp[mid, 0]:
            lo_ = mid
        else:
            hi_ = mid - 1
    return lo_


@njit(cache=True, error_model="numpy", inline="always")
def _next_sample(Asp, breaks, S, sj, m, x, P1, P2, s_prev):
    """(span, x) of source time sj, from the previous sample's (span m, x, p' and p'' there, its time):
    the span walk, a second-order predictor (the inverse function's Taylor series) and one Newton step,
    bisection only if that misses the tolerance."""
    n_span = len(breaks) - 1
    while m + 1 < n_span and sj >= Asp[m + 1, 0]:
        m += 1
        x = 0.0
        P1 = Asp[m, 1]
        P2 = 2.0 * Asp[m, 2]
        s_prev = Asp[m, 0]
    h = breaks[m + 1] - breaks[m]
    if P1 > 0.0:
        ds = (sj - s_prev) / P1
        x += ds - 0.5 * P2 * ds * ds / P1
    return m, _invert(Asp, m, sj, x, h, S, 1)


@njit(cache=True, error_model="numpy", inline="always")
def _invert(A, m, sj, x, h, S, steps):
    """x in [0, h] with span m's polynomial A[m] (increasing) equal to sj: ``steps`` Newton steps from
    the guess x, a safeguarded bisection-Newton only if they miss the tolerance."""
    ok = False
    if 0.0 <= x <= h:
        for _ in range(steps):
            fx, d, _, _ = _horner(A, m, x)
            if d <= 0.0:
                break
            x -= (fx - sj) / d
        ok = 0.0 <= x <= h and abs(_horner(A, m, x)[0] - sj) <= 1e-12 * (1.0 + S)
    if not ok:
        lo, hi = 0.0, h
        x = 0.5 * h
        for _ in range(80):
            fx, d, _, _ = _horner(A, m, x)
            fx -= sj
            if abs(fx) <= 1e-13 * (1.0 + S):
                break
            if fx > 0:
                hi = x
            else:
                lo = x
            xn = x - fx / d if d > 0 else 0.5 * (lo + hi)
            if xn <= lo or xn >= hi:
                xn = 0.5 * (lo + hi)
            if hi - lo <= 1e-16 * (1.0 + h):
                break
            x = xn
    return x


@njit(cache=True, error_model="numpy")
def _chunk(j0, j1, Asp, T, S, breaks, Msp, ob, cache, want_grad, gc):
    """Samples j0..j1-1 of the objective (see _evaluate); gradient added into gc."""
    s, omega, fi, fw, gamma = ob.s, ob.omega, ob.fi, ob.fw, ob.gamma
    gT = 0.0
    total = 0.0
    m = _first_span(Asp, s[j0])
    x = 0.0
    invT = 1.0 / T
    P1 = 0.0
    P2 = 0.0
    s_prev = s[j0]
    for jj in range(j0, j1):
        sj = s[jj]
        m, x = _next_sample(Asp, breaks, S, sj, m, x, P1, P2, s_prev)
        s_prev = sj
        _, P1, P2, P3 = _horner(Asp, m, x)
        pd = P1 * invT
        pdd = P2 * invT * invT
        u = pdd
        v = pd * pd
        i = fi[jj]
        wgt = fw[jj]
        f, fu, fv = 0.0, 0.0, 0.0
        if wgt < 1.0:
            f0, fu0, fv0 = _frame_eval(i, u, v, ob, cache)
            f += (1.0 - wgt) * f0
            fu += (1.0 - wgt) * fu0
            fv += (1.0 - wgt) * fv0
        if wgt > 0.0:
            f1, fu1, fv1 = _frame_eval(i + 1, u, v, ob, cache)
            f += wgt * f1
            fu += wgt * fu1
            fv += wgt * fv1
        om = omega[jj]
        ipd = 1.0 / pd
        total += om * (f * ipd + gamma * (pd + ipd - 2.0))
        if want_grad:
            # h = f / p' + gamma (p' + 1/p' - 2) with u = p'', v = p'^2
            hp = om * (2.0 * fv - (f + gamma) * ipd * ipd + gamma)
            hpp = om * fu * ipd
            gT += hp * (-pd * invT) + hpp * (-2.0 * pdd * invT)
            for l in range(Msp.shape[2]):
                N0, N1, N2 = _horner_column(Msp, m, l, x)
                dtau = -N0 / P1
                dpd = (N1 + P2 * dtau) * invT
                dpdd = (N2 + P3 * dtau) * invT * invT
                gc[m + l] += hp * dpd + hpp * dpdd
    return total, gT


@njit(cache=True, error_model="numpy")
def _evaluate(c, T, breaks, Msp, ob, cache, want_grad, gc):
    """Objective (and gradient w.r.t. c and T when want_grad) of the spline with coefficients c."""
    Asp = _span_poly(c, Msp, len(breaks) - 1)
    for k in range(len(gc)):
        gc[k] = 0.0
    return _chunk(0, len(ob.s), Asp, T, c[len(c) - 1], breaks, Msp, ob, cache, want_grad, gc)


@njit(cache=True, error_model="numpy", parallel=True)
def _evaluate_par(nch, c, T, breaks, Msp, ob, cache, want_grad, gc):
    """_evaluate split into ``nch`` chunks of samples run on parallel threads."""
    Asp = _span_poly(c, Msp, len(breaks) - 1)
    ns = len(ob.s)
    tot = np.zeros(nch)
    gts = np.zeros(nch)
    gcs = np.zeros((nch, len(gc)))
    S = c[len(c) - 1]
    for k in prange(nch):
        j0 = (ns * k) // nch
        j1 = (ns * (k + 1)) // nch
        tot[k], gts[k] = _chunk(j0, j1, Asp, T, S, breaks, Msp, ob, cache, want_grad, gcs[k])
    for q in range(len(gc)):
        acc = 0.0
        for k in range(nch):
            acc += gcs[k, q]
        gc[q] = acc
    # summed by plain loops in chunk order: under parallel=True numba turns tot.sum() into a parallel
    # reduction split by the thread count, whose rounding then depends on the machine
    val, gT = 0.0, 0.0
    for k in range(nch):
        val += tot[k]
        gT += gts[k]
    return val, gT


@njit(cache=True, error_model="numpy")
def _hessian_chunk(j0, j1, Asp, T, S, breaks, Msp, ob, cache, hb, hcol):
    """Samples j0..j1-1 of the objective's exact Hessian in (c, T), added into hb (hb[k, o] =
    d2E / dc_k dc_{k+o}) and hcol (d2E / dc_k dT); returns d2E / dT2. Per sample, with x its spline
    parameter (p(x) = s_j, so dx/dc_l = -N_l / p'), p' = P1 / T and p'' = P2 / T^2: the sample's term
    h(p', u = p'') = f(u, p'^2) / p' + gamma (p' + 1/p' - 2) gives J^T (d2h) J + h_p' d2p' + h_u d2p'',
    where d2 p' and d2 p'' carry the inverse's implicit second derivatives
    x_lk = -(p'' x_l x_k + N_l' x_k + N_k' x_l) / p'."""
    s, omega, fi, fw, gamma = ob.s, ob.omega, ob.fi, ob.fw, ob.gamma
    q1 = Msp.shape[2]
    N1 = np.empty(q1)
    N2 = np.empty(q1)
    N3 = np.empty(q1)
    dx = np.empty(q1)
    dpd = np.empty(q1 + 1)  # d p' / d(c_m .. c_{m+b}, T)
    dpdd = np.empty(q1 + 1)
    hTT = 0.0
    invT = 1.0 / T
    # the samples' walk along the spline (the same as _chunk's, whose helpers hold its logic)
    m, x, P1, P2, s_prev = _first_span(Asp, s[j0]), 0.0, 0.0, 0.0, s[j0]
    for jj in range(j0, j1):
        sj = s[jj]
        m, x = _next_sample(Asp, breaks, S, sj, m, x, P1, P2, s_prev)
        s_prev = sj
        _, P1, P2, P3 = _horner(Asp, m, x)
        P4 = _fourth_derivative(Asp, m, x)
        pd = P1 * invT
        pdd = P2 * invT * invT
        i = fi[jj]
        wgt = fw[jj]
        f, fu, fv, fuu, fuv, fvv = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for side in range(2):
            weight = 1.0 - wgt if side == 0 else wgt
            if weight > 0.0:
                a0, a1, a2, a3, a4, a5 = _frame_second(i + side, pdd, pd * pd, ob, cache)
                f += weight * a0
                fu += weight * a1
                fv += weight * a2
                fuu += weight * a3
                fuv += weight * a4
                fvv += weight * a5
        om = omega[jj]
        ipd = 1.0 / pd
        fg = f + gamma
        hp = om * (2.0 * fv - fg * ipd * ipd + gamma)  # dh/dp'
        hu = om * fu * ipd  # dh/dp''
        hpp = om * (4.0 * pd * fvv - 2.0 * fv * ipd + 2.0 * fg * ipd * ipd * ipd)
        hpu = om * (2.0 * fuv - fu * ipd * ipd)
        huu = om * fuu * ipd
        for l in range(q1):
            N0, N1[l], N2[l], N3[l] = _horner_column3(Msp, m, l, x)
            dx[l] = -N0 / P1
            dpd[l] = (N1[l] + P2 * dx[l]) * invT
            dpdd[l] = (N2[l] + P3 * dx[l]) * invT * invT
        dpd[q1] = -pd * invT
        dpdd[q1] = -2.0 * pdd * invT
        for l in range(q1 + 1):
            for k in range(l, q1 + 1):
                hk = (hpp * dpd[l] * dpd[k] + hpu * (dpd[l] * dpdd[k] + dpdd[l] * dpd[k])
                      + huu * dpdd[l] * dpdd[k])
                if k < q1:
                    xlk = -(P2 * dx[l] * dx[k] + N1[l] * dx[k] + N1[k] * dx[l]) / P1
                    P1lk = N2[l] * dx[k] + N2[k] * dx[l] + P3 * dx[l] * dx[k] + P2 * xlk
                    P2lk = N3[l] * dx[k] + N3[k] * dx[l] + P4 * dx[l] * dx[k] + P3 * xlk
                    hb[m + l, k - l] += hk + hp * P1lk * invT + hu * P2lk * invT * invT
                elif l < q1:  # d2 p' / dc_l dT = -(d p' / dc_l) / T, d2 p'' / dc_l dT = -2 (d p'' / dc_l) / T
                    hcol[m + l] += hk - (hp * dpd[l] + 2.0 * hu * dpdd[l]) * invT
                else:  # d2 p' / dT2 = 2 p' / T^2, d2 p'' / dT2 = 6 p'' / T^2
                    hTT += hk + (2.0 * hp * pd + 6.0 * hu * pdd) * invT * invT
    return hTT


@njit(cache=True, error_model="numpy")
def _hessian(c, T, breaks, Msp, ob, cache, hb, hcol):
    """The exact Hessian (see _hessian_chunk) into the zeroed hb and hcol; returns d2E / dT2."""
    Asp = _span_poly(c, Msp, len(breaks) - 1)
    return _hessian_chunk(0, len(ob.s), Asp, T, c[len(c) - 1], breaks, Msp, ob, cache, hb, hcol)


@njit(cache=True, error_model="numpy", parallel=True)
def _hessian_par(nch, c, T, breaks, Msp, ob, cache, hb, hcol):
    """_hessian split into ``nch`` chunks of samples run on parallel threads, summed in chunk order."""
    Asp = _span_poly(c, Msp, len(breaks) - 1)
    ns = len(ob.s)
    hbs = np.zeros((nch, hb.shape[0], hb.shape[1]))
    hcols = np.zeros((nch, len(hcol)))
    hTTs = np.zeros(nch)
    S = c[len(c) - 1]
    for k in prange(nch):
        j0 = (ns * k) // nch
        j1 = (ns * (k + 1)) // nch
        hTTs[k] = _hessian_chunk(j0, j1, Asp, T, S, breaks, Msp, ob, cache, hbs[k], hcols[k])
    for q in range(hb.shape[0]):
        for o in range(hb.shape[1]):
            acc = 0.0
            for k in range(nch):
                acc += hbs[k, q, o]
            hb[q, o] = acc
        acc = 0.0
        for k in range(nch):
            acc += hcols[k, q]
        hcol[q] = acc
    hTT = 0.0
    for k in range(nch):
        hTT += hTTs[k]
    return hTT


PARALLEL_MIN_SAMPLES = 20000  # threads pay off only for long clips; on a shared 2-core machine a busy
# core stalls every parallel call, which an interactive loop of short calls cannot afford
PARALLEL_CHUNKS = 8  # a long clip's samples are summed in this many chunks, whatever the thread count, so
# its value and gradient do not depend on the machine (they did with one chunk per thread); on one thread
# the chunks are also faster than one pass (10-minute capture: 16 ms against 25 ms; 8 ms on two threads)


def _kernel(obj):
    if len(obj.arrays.s) < PARALLEL_MIN_SAMPLES:  # the usual case
        return _evaluate
    return lambda *args: _evaluate_par(PARALLEL_CHUNKS, *args)


def evaluate(obj: BakedObjective, spline, w=None, grad=False, workspace: ObjectiveWorkspace | None = None):
    """E(w) (and dE/dw). ``workspace``: the caller's wedge hints (default: fresh ones)."""
    w = spline.w if w is None else w
    c = spline.coefficients(w)
    T = spline.duration_of(w)
    gc = np.zeros(len(c))
    val, gT = _kernel(obj)(c, T, spline.breaks, spline.span_matrices, obj.arrays, _wedges(obj, workspace), grad, gc)
    if not grad:
        return float(val)
    return float(val), spline.chain(gc, gT, w)


def evaluate_c(obj: BakedObjective, spline, c, T, grad=False, workspace: ObjectiveWorkspace | None = None):
    """E and (dE/dc, dE/dT) for raw coefficients (tests, benchmarks)."""
    gc = np.zeros(len(c))
    val, gT = _kernel(obj)(np.asarray(c, float), float(T), spline.breaks, spline.span_matrices, obj.arrays,
                           _wedges(obj, workspace), grad, gc)
    return (float(val), gc, float(gT)) if grad else float(val)


def hessian_c(obj: BakedObjective, spline, c, T, workspace: ObjectiveWorkspace | None = None):
    """The exact Hessian of E in (c, T), in one pass over the samples: (hb, col, corner) with
    hb[k, o] = d2E / dc_k dc_{k+o} (o = 0 .. spline.band), col[k] = d2E / dc_k dT, corner = d2E / dT2
    (the T parts whether or not the duration is free)."""
    c = np.asarray(c, float)
    hb = np.zeros((len(c), spline.span_matrices.shape[2]))
    col = np.zeros(len(c))
    args = (c, float(T), spline.breaks, spline.span_matrices, obj.arrays, _wedges(obj, workspace), hb, col)
    if len(obj.arrays.s) < PARALLEL_MIN_SAMPLES:
        corner = _hessian(*args)
    else:
        corner = _hessian_par(PARALLEL_CHUNKS, *args)
    return hb, col, float(corner)


def frame_terms(obj: BakedObjective, i, u, v, workspace: ObjectiveWorkspace | None = None):
    """(distance to the region in the objective's metric, torque term) of frame i at (u, v)."""
    g, _, _, _, _, d2, _, _ = _frame_parts(int(i), float(u), float(v), obj.arrays, _wedges(obj, workspace))
    return math.sqrt(d2), g


def frame_gradient(obj: BakedObjective, i, u, v, workspace: ObjectiveWorkspace | None = None):
    """(f, df/du, df/dv) of frame i with the baked weights (tests)."""
    return _frame_eval(int(i), float(u), float(v), obj.arrays, _wedges(obj, workspace))


# ------------------------------------------------------------------------------------------------
# NumPy twins (the reference of tests/test_kernel_parity.py): the same objective, computed afresh
# without numba, without wedge hints and without Newton's method
# ------------------------------------------------------------------------------------------------

def frame_terms_numpy(obj: BakedObjective, i, u, v):
    """Twin of :func:`frame_terms`: (distance in the objective's metric, torque term)."""
    from ..regions.polygon import closest_points_numpy

    ob = obj.arrays
    su, sv = ob.scale[i]
    x, y = su * u, sv * v
    p0, p1 = ob.poff[i], ob.poff[i + 1]
    P = np.column_stack([ob.px[p0:p1], ob.py[p0:p1]])
    k = 0
    if ob.mode[i] == 2:  # a point or a segment: no interior
        E = np.roll(P, -1, axis=0) - P
        ee = (E ** 2).sum(1)
        t = np.clip(((x - P[:, 0]) * E[:, 0] + (y - P[:, 1]) * E[:, 1]) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
        C = P + np.where(ee > 0, t, 0.0)[:, None] * E
        d = float(np.min(np.hypot(C[:, 0] - x, C[:, 1] - y))) if len(P) > 1 else float(np.hypot(*(P[0] - (x, y))))
    else:
        d = float(closest_points_numpy(P, [(x, y)])[1][0])
        # the fan wedge k whose rays from the centre enclose the direction to (x, y)
        R0 = P - ob.cen[i]
        R1 = np.roll(R0, -1, axis=0)
        dx, dy = x - ob.cen[i, 0], y - ob.cen[i, 1]
        between = (R0[:, 0] * dy - R0[:, 1] * dx >= 0.0) & (dx * R1[:, 1] - dy * R1[:, 0] > 0.0)
        k = int(np.argmax(between)) if between.any() else 0
    def quadratic(row):
        w = ob.wc[row]
        return w[0] * v * v + w[1] * u * u + w[2] * u * v + w[3] * v + w[4] * u + w[5]

    g = quadratic(p0 + k if ob.mode[i] == 0 else p0)  # mode 1: one torque model for the frame
    at_centre = ob.mode[i] != 0 or dx * dx + dy * dy <= 1e-24 * (1.0 + float(ob.cen[i] @ ob.cen[i]))
    if not at_centre and ob.blend > 0.0:
        # the mollified fan (see _fan_blend): every wedge's quadratic times its smoothed indicator
        theta = np.arctan2(R0[:, 1], R0[:, 0])
        widths = np.mod(np.roll(theta, -1) - theta, 2 * np.pi)  # wedge q spans theta[q] .. theta[q + 1]
        phi = np.arctan2(dy, dx)
        r = np.hypot(dx, dy)
        band = ob.blend * FAN_BLEND_ANGLE / (ob.blend + r * FAN_BLEND_ANGLE)
        wrap = lambda a: np.mod(a + np.pi, 2 * np.pi) - np.pi  # noqa: E731
        lo_ray, hi_ray = wrap(phi - theta), wrap(phi - np.roll(theta, -1))
        # unwrapped from the ray nearer to phi (the other one is a wedge's width away)
        d_lo = np.where(np.abs(lo_ray) <= np.abs(hi_ray), lo_ray, hi_ray + widths)
        d_hi = d_lo - widths
        step = lambda x: np.where(x <= -1, 0.0, np.where(x >= 1, 1.0, 0.5 + np.clip(x, -1, 1) * (  # noqa: E731
            15.0 - 10.0 * np.clip(x, -1, 1) ** 2 + 3.0 * np.clip(x, -1, 1) ** 4) / 16.0))
        psi = step(d_lo / band) - step(d_hi / band)
        if np.abs(psi[k] - 1.0) > 0.0:  # a ray within the band: blend, else the wedge's own quadratic
            g = float(sum(psi[q] * quadratic(p0 + q) for q in np.flatnonzero(psi != 0.0)))
    return d, float(g)


def _penalty_numpy(d2, alpha, delta):
    if delta <= 0.0:
        return alpha * d2
    return np.where(d2 == 0.0, 0.0, alpha * (np.sqrt(d2 + delta * delta) - delta))


def _sample_positions_numpy(ob, spline, c):
    """(span, x, derivative): each sample's span and parameter x there (p(x) = s_j, by bisection), and
    derivative(x, order), the order-th derivative of each sample's span polynomial."""
    breaks, Msp = spline.breaks, spline.span_matrices
    n_span, q1 = len(breaks) - 1, Msp.shape[1]
    Asp = np.einsum("mrl,ml->mr", Msp, c[np.arange(n_span)[:, None] + np.arange(q1)])  # s(x) per span
    m = np.clip(np.searchsorted(Asp[:, 0], ob.s, side="right") - 1, 0, n_span - 1)
    A = Asp[m]
    r = np.arange(q1)

    def derivative(x, order):  # of each sample's span polynomial, at x
        fall = np.prod([np.maximum(r - j, 0) for j in range(order)], axis=0) if order else np.ones(q1)
        return np.sum(A * fall * x[:, None] ** np.maximum(r - order, 0), axis=1)

    lo, hi = np.zeros(len(m)), (breaks[m + 1] - breaks[m]).astype(float)
    for _ in range(200):
        x = 0.5 * (lo + hi)
        above = derivative(x, 0) > ob.s
        hi, lo = np.where(above, x, hi), np.where(above, lo, x)
    return m, 0.5 * (lo + hi), derivative


def evaluate_numpy(obj: BakedObjective, spline, w=None) -> float:
    """Twin of :func:`evaluate` (the value): each sample's output time by bisection on its span's
    polynomial, each frame term by :func:`frame_terms_numpy`."""
    ob = obj.arrays
    w = spline.w if w is None else w
    c = spline.coefficients(w)
    T = spline.duration_of(w)
    m, x, derivative = _sample_positions_numpy(ob, spline, c)
    pd = derivative(x, 1) / T
    u = derivative(x, 2) / T ** 2
    v = pd * pd
    f = np.zeros(len(m))
    for side, weight in ((0, 1.0 - ob.fw), (1, ob.fw)):
        for j in np.flatnonzero(weight > 0.0):
            d, g = frame_terms_numpy(obj, ob.fi[j] + side, u[j], v[j])
            f[j] += weight[j] * (g + _penalty_numpy(d * d, ob.alpha, ob.delta))
    return float(np.sum(ob.omega * (f / pd + ob.gamma * (pd + 1.0 / pd - 2.0))))


def frame_second_numpy(obj: BakedObjective, i, u, v):
    """Twin of the kernels' per-frame second derivatives: (f, f_u, f_v, f_uu, f_uv, f_vv) of frame i at
    (u, v) = (p'', p'^2), from the polygon by a scan of all its edges and the fan's wedges all at once."""
    ob = obj.arrays
    su, sv = ob.scale[i]
    x, y = su * u, sv * v
    p0, p1 = ob.poff[i], ob.poff[i + 1]
    P = np.column_stack([ob.px[p0:p1], ob.py[p0:p1]])
    d, g = frame_terms_numpy(obj, i, u, v)
    metric = np.array([su, sv])

    def quadratic(row):  # value, gradient, Hessian in (u, v) of one wedge's quadratic
        w = ob.wc[row]
        return (w[0] * v * v + w[1] * u * u + w[2] * u * v + w[3] * v + w[4] * u + w[5],
                np.array([2 * w[1] * u + w[2] * v + w[4], 2 * w[0] * v + w[2] * u + w[3]]),
                np.array([[2 * w[1], w[2]], [w[2], 2 * w[0]]]))

    dxy = np.array([x, y]) - ob.cen[i]
    R0 = P - ob.cen[i]
    between = (R0[:, 0] * dxy[1] - R0[:, 1] * dxy[0] >= 0.0) & (
        dxy[0] * np.roll(R0, -1, axis=0)[:, 1] - dxy[1] * np.roll(R0, -1, axis=0)[:, 0] > 0.0)
    k = int(np.argmax(between)) if ob.mode[i] == 0 and between.any() else 0
    _, grad, hess = quadratic(p0 + k)
    r2 = float(dxy @ dxy)
    if ob.mode[i] == 0 and ob.blend > 0.0 and r2 > 1e-24 * (1.0 + float(ob.cen[i] @ ob.cen[i])):
        theta = np.arctan2(R0[:, 1], R0[:, 0])
        widths = np.mod(np.roll(theta, -1) - theta, 2 * np.pi)
        phi = np.arctan2(dxy[1], dxy[0])
        r = math.sqrt(r2)
        B, eps = FAN_BLEND_ANGLE, ob.blend
        band = eps * B / (eps + r * B)
        wrap = lambda a: np.mod(a + np.pi, 2 * np.pi) - np.pi  # noqa: E731
        lo_ray, hi_ray = wrap(phi - theta), wrap(phi - np.roll(theta, -1))
        d_lo = np.where(np.abs(lo_ray) <= np.abs(hi_ray), lo_ray, hi_ray + widths)
        ends = np.stack([d_lo, d_lo - widths])  # (2, wedges): phi minus each wedge's lower, upper ray
        if np.any(np.abs(ends / band) < 1.0):  # a ray within the band
            # derivatives in (u, v) of phi and of b(r), through the metric
            nrm = dxy * metric
            dphi = np.array([-dxy[1] * su, dxy[0] * sv]) / r2
            ddphi = np.array([[2 * dxy[0] * dxy[1] * su * su, (dxy[1] ** 2 - dxy[0] ** 2) * su * sv],
                              [(dxy[1] ** 2 - dxy[0] ** 2) * su * sv, -2 * dxy[0] * dxy[1] * sv * sv]]) / r2 ** 2
            dr = nrm / r
            ddr = (np.diag(metric ** 2) - np.outer(dr, dr)) / r
            b1, b2 = -eps * B * B / (eps + r * B) ** 2, 2 * eps * B ** 3 / (eps + r * B) ** 3
            db, ddb = b1 * dr, b2 * np.outer(dr, dr) + b1 * ddr
            X = ends / band
            inside = np.abs(X) < 1.0
            S = np.where(X <= -1, 0.0, np.where(X >= 1, 1.0, 0.5 + X * (15 - 10 * X ** 2 + 3 * X ** 4) / 16))
            S1 = np.where(inside, 15 * (1 - X ** 2) ** 2 / 16, 0.0)
            S2 = np.where(inside, -3.75 * X * (1 - X ** 2), 0.0)
            dX = (dphi[None, None, :] - X[..., None] * db) / band  # (2, wedges, 2)
            ddX = (ddphi - dX[..., :, None] * db[None, :] - dX[..., None, :] * db[:, None]
                   - X[..., None, None] * ddb) / band
            sign = np.array([1.0, -1.0])[:, None]
            psi = (sign * S).sum(0)
            dpsi = (sign[..., None] * S1[..., None] * dX).sum(0)
            ddpsi = (sign[..., None, None] * (S2[..., None, None] * dX[..., :, None] * dX[..., None, :]
                                              + S1[..., None, None] * ddX)).sum(0)
            grad, hess = np.zeros(2), np.zeros((2, 2))
            for q in range(len(P)):
                gq, gradq, hessq = quadratic(p0 + q)
                grad += psi[q] * gradq + gq * dpsi[q]
                hess += psi[q] * hessq + np.outer(dpsi[q], gradq) + np.outer(gradq, dpsi[q]) + gq * ddpsi[q]
    f = g
    if d > 0.0:
        E = np.roll(P, -1, axis=0) - P
        ee = (E ** 2).sum(1)
        t = np.where(ee > 0, ((x - P[:, 0]) * E[:, 0] + (y - P[:, 1]) * E[:, 1]) / np.where(ee > 0, ee, 1.0), 0.0)
        C = P + np.clip(t, 0.0, 1.0)[:, None] * E
        e = int(np.argmin(((C - [x, y]) ** 2).sum(1)))
        off = np.array([x, y]) - C[e]
        K = np.outer(off, off) / (off @ off) if 0.0 < t[e] < 1.0 and len(P) > 1 else np.eye(2)
        if ob.delta <= 0.0:
            dpen, ddpen = 2 * ob.alpha * off, 2 * ob.alpha * K
            f += ob.alpha * d * d
        else:
            rr = math.sqrt(d * d + ob.delta ** 2)
            dpen, ddpen = ob.alpha / rr * off, ob.alpha / rr * (K - np.outer(off, off) / rr ** 2)
            f += ob.alpha * (rr - ob.delta)
        grad = grad + metric * dpen
        hess = hess + np.outer(metric, metric) * ddpen
    return f, grad[0], grad[1], hess[0, 0], hess[0, 1], hess[1, 1]


def hessian_numpy(obj: BakedObjective, spline, c, T):
    """Twin of :func:`hessian_c`: the same (hb, col, corner), assembled from dense per-sample 6 x 6
    blocks (the span's coefficients and T) with the samples' spline parameters by bisection."""
    ob = obj.arrays
    c = np.asarray(c, float)
    Msp = spline.span_matrices
    m, x, _ = _sample_positions_numpy(ob, spline, c)
    q1 = Msp.shape[1]
    r = np.arange(q1)
    M = Msp[m]  # (Ns, power, basis)

    def basis(order):  # (Ns, q1): d^order N_l / dx^order at each sample
        fall = np.prod([np.maximum(r - j, 0) for j in range(order)], axis=0) if order else np.ones(q1)
        return np.einsum("jrl,jr->jl", M, fall * x[:, None] ** np.maximum(r - order, 0))

    N = [basis(k) for k in range(5)]
    cs = c[m[:, None] + r]
    P1, P2, P3, P4 = ((Nk * cs).sum(1) for Nk in N[1:])
    pd, pdd = P1 / T, P2 / T ** 2
    F = np.zeros((len(m), 6))
    for j in range(len(m)):
        for side, weight in ((0, 1.0 - ob.fw[j]), (1, ob.fw[j])):
            if weight > 0.0:
                F[j] += weight * np.array(frame_second_numpy(obj, ob.fi[j] + side, pdd[j], pd[j] ** 2))
    f, fu, fv, fuu, fuv, fvv = F.T
    om, gam = ob.omega, ob.gamma
    hp = om * (2 * fv - (f + gam) / pd ** 2 + gam)
    hu = om * fu / pd
    hpp = om * (4 * pd * fvv - 2 * fv / pd + 2 * (f + gam) / pd ** 3)
    hpu = om * (2 * fuv - fu / pd ** 2)
    huu = om * fuu / pd
    dx = -N[0] / P1[:, None]
    Jp = np.column_stack([(N[1] + P2[:, None] * dx) / T, -pd / T])  # d p' / d(c_m .. c_{m+b}, T)
    Ju = np.column_stack([(N[2] + P3[:, None] * dx) / T ** 2, -2 * pdd / T])
    outer = lambda a, b: a[:, :, None] * b[:, None, :]  # noqa: E731
    blocks = (hpp[:, None, None] * outer(Jp, Jp) + hpu[:, None, None] * (outer(Jp, Ju) + outer(Ju, Jp))
              + huu[:, None, None] * outer(Ju, Ju))
    xlk = -(P2[:, None, None] * outer(dx, dx) + outer(N[1], dx) + outer(dx, N[1])) / P1[:, None, None]
    d2P1 = outer(N[2], dx) + outer(dx, N[2]) + P3[:, None, None] * outer(dx, dx) + P2[:, None, None] * xlk
    d2P2 = outer(N[3], dx) + outer(dx, N[3]) + P4[:, None, None] * outer(dx, dx) + P3[:, None, None] * xlk
    blocks[:, :q1, :q1] += (hp[:, None, None] * d2P1 / T + hu[:, None, None] * d2P2 / T ** 2)
    cross = -(hp[:, None] * Jp[:, :q1] + 2 * hu[:, None] * Ju[:, :q1]) / T
    blocks[:, :q1, q1] += cross
    blocks[:, q1, :q1] += cross
    blocks[:, q1, q1] += (2 * hp * pd + 6 * hu * pdd) / T ** 2
    n_c = len(c)
    H = np.zeros((n_c + 1, n_c + 1))
    idx = np.concatenate([m[:, None] + r, np.full((len(m), 1), n_c)], axis=1)
    np.add.at(H, (idx[:, :, None], idx[:, None, :]), blocks)
    hb = np.zeros((n_c, q1))
    for o in range(q1):
        hb[:n_c - o, o] = np.diagonal(H[:n_c, :n_c], o)
    return hb, H[:n_c, n_c].copy(), float(H[n_c, n_c])


# ------------------------------------------------------------------------------------------------
# Without baking (Fig. 12's NP-Obj): per-dof torques at every sample, for comparison only
# ------------------------------------------------------------------------------------------------

@dataclass
class UnbakedObjective:
    """The same objective as :class:`BakedObjective`, kept per degree of freedom: at every sample
    lambda = L0 + Lu u + Lv v on the fan wedge, tau = a u + b v + c - N lambda for every actuated row."""

    baked: BakedObjective
    a: np.ndarray  # (n, nr) actuated rows
    b: np.ndarray
    c: np.ndarray
    tgt: np.ndarray
    N: np.ndarray  # (n, nr, K)
    lam_aff: np.ndarray  # (P, 3, K) per wedge: L0, Lu, Lv
    scale: float  # beta / tau_scale^2


def unbaked(pd, regions, target, obj: BakedObjective) -> UnbakedObjective:
    """Per-wedge affine contact models and the per-dof dynamics for :func:`evaluate_unbaked`."""
    from ..regions.forces import fan_model

    act = actuated_mask(pd)
    K = pd.N.shape[2]
    lam_aff = np.zeros((len(obj.arrays.px), 3, K))
    for i in range(regions.n_frames):
        fan = fan_model(regions, i)
        p0, p1 = regions.offsets[i], regions.offsets[i + 1]
        for k in range(p1 - p0):
            L0, Lu, Lv = fan.affine(k if not fan.degenerate else -1)
            lam_aff[p0 + k] = (L0, Lu, Lv)
    arr = lambda x: np.ascontiguousarray(np.asarray(x, dtype=float)[:, act])  # noqa: E731
    return UnbakedObjective(obj, arr(pd.a), arr(pd.b), arr(pd.c), arr(target),
                            pd.N.rows_dense(np.flatnonzero(act)), lam_aff,
                            obj.beta / obj.tau_scale ** 2)


@njit(cache=True, error_model="numpy")
def _evaluate_unbaked(c, T, breaks, Msp, ob, cache, a, b, cc, tgt, N, lam_aff, tscale):
    s, omega, fi, poff, mode, wc, gamma = ob.s, ob.omega, ob.fi, ob.poff, ob.mode, ob.wc, ob.gamma
    n_span = len(breaks) - 1
    Asp = _span_poly(c, Msp, n_span)
    nr = a.shape[1]
    K = N.shape[2]
    lam = np.empty(K)
    total = 0.0
    m = 0
    x = 0.0
    invT = 1.0 / T
    for jj in range(len(s)):
        sj = s[jj]
        while m + 1 < n_span and sj >= Asp[m + 1, 0]:
            m += 1
            x = 0.0
        h = breaks[m + 1] - breaks[m]
        x = _invert(Asp, m, sj, min(max(x, 0.0), h), h, sj, 2)
        _, P1, P2, _ = _horner(Asp, m, x)
        pd = P1 * invT
        u = P2 * invT * invT
        v = pd * pd
        i = fi[jj]
        # distance term and wedge from the baked geometry (alpha only), torque term per dof
        fdist, _, _ = _frame_eval(i, u, v, ob, cache)
        p0 = poff[i]
        kw = p0 + (cache[i] if mode[i] == 0 else 0)
        for q in range(K):
            lam[q] = lam_aff[kw, 0, q] + lam_aff[kw, 1, q] * u + lam_aff[kw, 2, q] * v
        err = 0.0
        for r in range(nr):
            tau = a[i, r] * u + b[i, r] * v + cc[i, r] - tgt[i, r]
            for q in range(K):
                tau -= N[i, r, q] * lam[q]
            err += tau * tau
        wk = wc[kw]
        g = wk[0] * v * v + wk[1] * u * u + wk[2] * u * v + wk[3] * v + wk[4] * u + wk[5]
        f = fdist - g + tscale * err  # _frame_eval added the baked torque term: replace it
        total += omega[jj] * (f / pd + gamma * (pd + 1.0 / pd - 2.0))
    return total


def evaluate_unbaked(u_obj: UnbakedObjective, spline, w=None) -> float:
    """The objective without baking (value only; the excess floor is not subtracted)."""
    o = u_obj.baked
    w = spline.w if w is None else w
    return float(_evaluate_unbaked(spline.coefficients(w), spline.duration_of(w), spline.breaks,
                                   spline.span_matrices, o.arrays, _wedges(o, None), u_obj.a, u_obj.b, u_obj.c,
                                   u_obj.tgt, u_obj.N, u_obj.lam_aff, u_obj.scale))
