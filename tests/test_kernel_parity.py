"""Each compiled hot kernel against its plain NumPy twin, on random and on real inputs: polygon
closest point and distance, half-plane clipping (physics/regions/polygon.py), the simplex phase 2 and
shadow-vertex walk (physics/regions/simplex.py) and the objective's evaluation (physics/timing/objective.py).
The twins are written without numba and without the kernels' bookkeeping (no B^-1 updates, no
wedge hints, bisection for Newton), so an error in either side shows as a mismatch."""
from __future__ import annotations

import math
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.data import bundled_path  # noqa: E402
from retime.motion import load_motion  # noqa: E402
from retime.physics.timing import objective as O  # noqa: E402
from retime.physics.regions import polygon as P  # noqa: E402
from retime.physics.regions import simplex as S  # noqa: E402
from retime.physics.regions.highs_lp import HighsPool  # noqa: E402
from retime.physics.timing.spline import TimingSpline  # noqa: E402


@pytest.fixture(scope="module")
def real():
    """The bundled standing jump: its dynamics, regions and baked objective."""
    from retime.physics.api import prepare

    terms, pd, regions, obj = prepare(load_motion(bundled_path("16_06.amc")))
    return pd, regions, obj


def _random_polygons(rng, count):
    """Convex polygons of 3 to 12 vertices, some thin, as hulls of random points."""
    out = []
    for k in range(count):
        pts = rng.normal(size=(rng.integers(3, 13), 2)) * [1.0, 10.0 ** rng.uniform(-3, 1)]
        out.append(P.convex_hull(pts + rng.normal(size=2)))
    return out


def _real_polygons(regions, step=7):
    return [regions.polygon(i) for i in range(0, regions.n_frames, step)]


# ---------------------------------------------------------------------------------------- polygon

def _check_closest(polys, rng):
    for poly in polys:
        lo, hi = poly.min(axis=0), poly.max(axis=0)
        pts = lo + (hi - lo) * rng.uniform(-0.5, 1.5, size=(40, 2))
        pts = np.vstack([pts, poly, 0.5 * (poly + np.roll(poly, -1, axis=0))])  # on vertices and edges too
        q_np, d_np = P.closest_points_numpy(poly, pts)
        for p, q, d in zip(pts, q_np, d_np):
            qx, qy, dk = P.closest_point_kernel(np.ascontiguousarray(poly), p[0], p[1])
            scale = 1.0 + np.abs(poly).max()
            assert dk == pytest.approx(d, abs=1e-12 * scale)
            assert np.allclose([qx, qy], q, atol=1e-12 * scale)


def test_closest_point_twin_random():
    rng = np.random.default_rng(1)
    _check_closest(_random_polygons(rng, 60) + [np.array([[0.3, 0.2]]), np.array([[0.0, 0.0], [1.0, 2.0]])], rng)


def test_closest_point_twin_real(real):
    _check_closest(_real_polygons(real[1]), np.random.default_rng(2))


def test_polygon_distances_kernel_matches_twin_on_all_frames(real):
    _, regions, _ = real
    rng = np.random.default_rng(3)
    frames = rng.integers(0, regions.n_frames, 500)
    u, v = rng.uniform(-20, 20, 500), rng.uniform(0, 10, 500)
    got = regions.distances(frames, u, v)
    want = [P.closest_points_numpy(regions.polygon(i), [(a, b)])[1][0] for i, a, b in zip(frames, u, v)]
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-10)


def test_distance_twin_against_brute_force():
    """Independently of both: the distance to densely sampled edges, 0 inside (winding number)."""
    rng = np.random.default_rng(3)
    poly = P.convex_hull(rng.normal(size=(12, 2)))
    pts = rng.normal(scale=2.0, size=(300, 2))
    got = P.closest_points_numpy(poly, pts)[1]
    edge = np.concatenate([np.linspace(a, b, 4000) for a, b in zip(poly, np.roll(poly, -1, axis=0))])
    brute = np.min(np.linalg.norm(pts[:, None] - edge[None], axis=-1), axis=1)
    ang = np.arctan2(*(poly[None] - pts[:, None]).transpose(2, 0, 1)[::-1])
    winding = np.abs(np.sum(np.angle(np.exp(1j * np.diff(np.concatenate([ang, ang[:, :1]], 1), axis=1))), axis=1))
    brute[winding > np.pi] = 0.0
    np.testing.assert_allclose(got, brute, atol=2e-3)
    assert P.polygon_area(poly) > 0  # the hull is counter-clockwise


def _random_halfplanes(rng, poly, k):
    """Half-planes through points near the polygon (some cut, some keep all, some remove all)."""
    ang = rng.uniform(0, 2 * math.pi, k)
    a, b = np.cos(ang), np.sin(ang)
    c = a * poly[:, 0].mean() + b * poly[:, 1].mean() + rng.normal(scale=np.ptp(poly) * 0.4 + 1e-3, size=k)
    H = np.column_stack([a, b, c])
    if rng.uniform() < 0.1:
        H = np.vstack([H, [0.0, 0.0, rng.normal()]])  # a row the timing cannot change
    return H


def _check_clip(polys, rng):
    cut = kept = emptied = 0
    for poly in polys:
        lam = rng.normal(size=(len(poly), 3))
        H = _random_halfplanes(rng, poly, rng.integers(1, 4))
        args = (np.ascontiguousarray(poly[:, 0]), np.ascontiguousarray(poly[:, 1]), lam, H, 1e-12)
        kx, ky, kl, kok = P.clip_halfplanes(*(x.copy() for x in args[:4]), args[4])
        nx, ny, nl, nok = P.clip_halfplanes_numpy(*args)
        assert kok == nok
        assert len(kx) == len(nx)
        np.testing.assert_allclose(kx, nx, atol=1e-12)
        np.testing.assert_allclose(ky, ny, atol=1e-12)
        np.testing.assert_allclose(kl, nl, atol=1e-12)
        if kok and len(kx):
            assert np.all(H[:, :2] @ np.vstack([kx, ky]) <= H[:, 2:3] + 1e-9)  # inside every half-plane
        cut += kok and 0 < len(kx) and len(kx) != len(poly)
        kept += kok and len(kx) == len(poly)
        emptied += not kok
    assert cut and kept and emptied  # every branch was exercised


def test_clip_twin_random():
    rng = np.random.default_rng(4)
    _check_clip(_random_polygons(rng, 200), rng)


def test_clip_twin_real(real):
    _check_clip(_real_polygons(real[1], step=2), np.random.default_rng(5))


# ---------------------------------------------------------------------------------------- simplex

def _frame_lps(pd, frames):
    """Real frame LPs (the regions' own construction) with HiGHS's centre basis at (0, 1)."""
    out = []
    for _, lp, w in ps.frame_lps(pd, frames):
        lp.solve_at(0.0, 1.0, w)  # the least-force LP: its basis starts the walk
        if lp.center_state is not None:
            out.append(lp)
    return out


def _random_lps(rng, count):
    """Random LPs of the regions' shape: u in a box, v in [0, v_max], lam >= 0, ranged rows
    A (u, v, lam) whose ranges hold at a random feasible point, with HiGHS's basis at that point."""
    out = []
    pool = HighsPool()
    while len(out) < count:
        m, k = int(rng.integers(3, 9)), int(rng.integers(1, 6))
        A = rng.normal(size=(m, 2 + k))
        x0 = np.r_[rng.uniform(-5, 5), rng.uniform(0.5, 8), rng.uniform(0, 2, k)]
        r = A @ x0
        from retime.physics.regions.highs_lp import FrameLP

        lp = FrameLP(A, r - rng.uniform(0.1, 3, m), r + rng.uniform(0.1, 3, m), 20.0, 30.0, pool)
        lp.solve_at(x0[0], x0[1], rng.uniform(0.5, 2, k))
        if lp.center_state is not None:
            out.append(lp)
    return out


def _same_polygon(V1, V2, tol):
    d12 = max(P.polygon_distance(P.convex_hull(V2), p) for p in V1)
    d21 = max(P.polygon_distance(P.convex_hull(V1), p) for p in V2)
    return max(d12, d21) <= tol


def _check_simplex(lps):
    for lp in lps:
        zl, zu = lp.bounds()
        basic0, zval = lp.center_state
        zval = np.clip(zval, zl, zu)
        bk, upk, stk = S.phase2(lp.A, zl, zu, basic0.copy(), zval.copy(), 500)
        bn, upn, stn = S.phase2_numpy(lp.A, zl, zu, basic0.copy(), zval.copy(), 500)
        assert stk == stn == 0
        # the same vertex of largest v (the basis may differ on a degenerate vertex)
        vk, _, _, _ = S.walk(lp.A, zl, zu, bk.copy(), upk.copy(), 0.5 * math.pi, 0)
        vn, _, _, _ = S.walk_numpy(lp.A, zl, zu, bn.copy(), upn.copy(), 0.5 * math.pi, 0)
        assert np.allclose(vk[0], vn[0], atol=1e-9 * (1 + np.abs(vk[0]).max()))
        # the whole walk from the kernel's start: the same polygon, vertex for vertex
        Vk, Xk, sk, pk = S.walk(lp.A, zl, zu, bk.copy(), upk.copy(), 0.5 * math.pi, 2000)
        Vn, Xn, sn, pn = S.walk_numpy(lp.A, zl, zu, bk.copy(), upk.copy(), 0.5 * math.pi, 2000)
        assert sk == sn == 0
        scale = 1 + np.abs(Vk).max()
        assert _same_polygon(Vk, Vn, 1e-9 * scale)
        if len(Vk) == len(Vn):
            np.testing.assert_allclose(Vk, Vn, atol=1e-9 * scale)
        # and each vertex is one of the LP: rows within their bounds, lam >= 0
        for x in Xn:
            r = lp.A @ x
            assert np.all(r >= lp.row_lo - 1e-7 * scale) and np.all(r <= lp.row_hi + 1e-7 * scale)
            assert np.all(x[2:] >= -1e-9 * scale)


def test_simplex_twin_random():
    _check_simplex(_random_lps(np.random.default_rng(6), 40))


def test_simplex_twin_real(real):
    lps = _frame_lps(real[0], range(0, len(real[0].times), 11))
    assert len(lps) >= 10
    _check_simplex(lps)


# ------------------------------------------------------------------------ vertex forces' NNLS

def _vertex_least_distance_problems(monkeypatch, clip, frames):
    """The least-distance problems of a clip's polygon vertices (``unique_vertex_forces``), as the
    regions pose them: (E, last rows, A, lo, hi, weights, spread) per frame."""
    from retime.physics.model.dynamics import dynamics_terms
    from retime.physics.regions import RegionOptions, compute_regions
    from retime.physics.regions import forces as F

    problems = []
    build = F._least_distance_problem

    def recorded(A, lo, hi, weights, spread):
        E, last = build(A, lo, hi, weights, spread)
        if len(last) > 1:  # a polygon's vertices (the centre poses one point)
            problems.append((E, last, A, lo, hi, weights, spread))
        return E, last

    monkeypatch.setattr(F, "_least_distance_problem", recorded)
    pd = dynamics_terms(load_motion(bundled_path(clip))).combine()
    compute_regions(pd, RegionOptions(workers=1, unique_vertex_forces=True), frames=frames)
    return problems


def test_vertex_nnls_twin_real(monkeypatch):
    """The warm-started compiled NNLS gives SciPy's minimiser on every vertex of 16_16's frames (the
    residual to 1e-9 of its size, the forces to 1e-8 body weights), whatever order the vertices come in
    (its start is the previous vertex's passive set: reversed, every start differs)."""
    from retime.physics.regions import forces as F
    from retime.physics.regions.nnls import least_distance_residuals

    problems = _vertex_least_distance_problems(monkeypatch, "16_16.amc", np.arange(0, 510, 9))
    assert sum(len(p[1]) for p in problems) >= 500
    for E, last, A, lo, hi, weights, spread in problems:
        ref, ref_ok = F.least_distance_numpy(E, last)
        got, ok = least_distance_residuals(E, last, 50 * E.shape[1])
        back, back_ok = least_distance_residuals(E, np.ascontiguousarray(last[::-1]), 50 * E.shape[1])
        assert ref_ok.all() and ok.all() and back_ok.all()
        scale = np.abs(ref).max()
        assert np.abs(got - ref).max() <= 1e-9 * scale
        assert np.abs(back[::-1] - ref).max() <= 1e-9 * scale
        lam_ref = F._forces_from_residuals(ref, ref_ok, A, lo, hi, weights, spread, 1e-6)
        lam_got = F._forces_from_residuals(got, ok, A, lo, hi, weights, spread, 1e-6)
        for a, b in zip(lam_ref, lam_got):
            assert (a is None) == (b is None)
            if a is not None:
                assert np.abs(a - b).max() <= 1e-8 * spread


def test_vertex_nnls_twin_random():
    """Random NNLS problems (wide and tall, some with dependent columns), from a random passive set:
    the compiled solve's residual is SciPy's."""
    from scipy.optimize import nnls

    from retime.physics.regions.nnls import nnls_warm

    rng = np.random.default_rng(11)
    for trial in range(300):
        p, q = int(rng.integers(2, 20)), int(rng.integers(2, 60))
        E = rng.normal(size=(p, q))
        if trial % 3 == 0 and q >= 4:  # dependent columns: the last two mix the first two
            E[:, -2:] = E[:, :2] @ rng.normal(size=(2, 2))
        t = rng.normal(size=p)
        z_ref, _ = nnls(E, t, maxiter=50 * q)
        z, ok = nnls_warm(E, t, rng.random(q) < 0.5, 50 * q)
        assert ok and np.all(z >= 0)
        assert np.abs((E @ z - t) - (E @ z_ref - t)).max() <= 1e-9 * (1 + np.abs(t).max())


# ---------------------------------------------------------------------------------------- objective

def _wiggly(obj, scale, seed, n=40):
    rng = np.random.default_rng(seed)
    S_ = float(obj.times[-1] - obj.times[0])
    sp = TimingSpline.uniform(S_, n, scale * S_)
    sp.w = sp.w * np.exp(0.25 * rng.normal(size=sp.w.size))
    return sp


def _check_objective(obj, seeds):
    for seed in seeds:
        sp = _wiggly(obj, [0.5, 1.0, 1.7][seed % 3], seed)
        assert O.evaluate(obj, sp) == pytest.approx(O.evaluate_numpy(obj, sp), rel=1e-9, abs=1e-12)
    rng = np.random.default_rng(seeds[0])
    ws = O.ObjectiveWorkspace.for_objective(obj)
    for _ in range(400):
        i, u, v = int(rng.integers(0, obj.n_frames)), rng.normal(scale=8.0), rng.uniform(0.0, 6.0)
        d, g = O.frame_terms(obj, i, u, v, ws)
        dn, gn = O.frame_terms_numpy(obj, i, u, v)
        assert d == pytest.approx(dn, rel=1e-9, abs=1e-12)
        assert g == pytest.approx(gn, rel=1e-9, abs=1e-12)


def test_objective_twin_synthetic():
    pd, rs, obj = ps.quarter_gravity_problem()
    _check_objective(obj, [0, 1, 2])


def test_objective_twin_real(real):
    _check_objective(real[2], [3, 4, 5])


def _check_hessian(obj, seeds):
    """The exact Hessian kernel against its twin (dense per-sample blocks, bisection, all edges and
    wedges scanned), and the per-frame second derivatives against differences of the kernel's gradient."""
    for seed in seeds:
        sp = _wiggly(obj, [0.5, 1.0, 1.7][seed % 3], seed)
        c, T = sp.coefficients(), sp.duration_of()
        hb, col, corner = O.hessian_c(obj, sp, c, T)
        hb_n, col_n, corner_n = O.hessian_numpy(obj, sp, c, T)
        assert np.abs(hb - hb_n).max() <= 1e-8 * np.abs(hb).max()
        assert np.abs(col - col_n).max() <= 1e-8 * np.abs(col).max()
        assert corner == pytest.approx(corner_n, rel=1e-8)
    rng = np.random.default_rng(seeds[0])
    ws = O.ObjectiveWorkspace.for_objective(obj)
    h = 1e-6
    for _ in range(200):
        i, u, v = int(rng.integers(0, obj.n_frames)), rng.normal(scale=8.0), rng.uniform(0.1, 6.0)
        f, fu, fv, fuu, fuv, fvv = O.frame_second_numpy(obj, i, u, v)
        g0 = np.array(O.frame_gradient(obj, i, u, v, ws))
        assert np.abs(np.array([f, fu, fv]) - g0).max() <= 1e-9 * (1.0 + np.abs(g0).max())
        du = (np.array(O.frame_gradient(obj, i, u + h, v, ws)) - O.frame_gradient(obj, i, u - h, v, ws)) / (2 * h)
        dv = (np.array(O.frame_gradient(obj, i, u, v + h, ws)) - O.frame_gradient(obj, i, u, v - h, ws)) / (2 * h)
        fd = np.array([du[1], dv[1], dv[2]])
        assert np.abs(np.array([fuu, fuv, fvv]) - fd).max() <= 1e-6 * (1.0 + np.abs(fd).max())


def test_hessian_twin_synthetic():
    pd, rs, obj = ps.quarter_gravity_problem()
    _check_hessian(obj, [0, 1, 2])


def test_hessian_twin_real(real):
    _check_hessian(real[2], [3, 4])
