"""Feasible regions (McCann et al. 2006, sec. 3.3): known answers and independent checks."""
from __future__ import annotations

import math
import os
import sys

import numpy as np
import pytest
from scipy.optimize import linprog

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.errors import RetimeError  # noqa: E402
from retime.physics import regions as R  # noqa: E402
from retime.physics.regions.frame_region import frame_region  # noqa: E402
from retime.physics.regions.polygon import closest_point, polygon_area, polygon_distance  # noqa: E402

G = 9.81


def opts(**kw):
    kw.setdefault("workers", 1)
    return R.RegionOptions(**kw)


@pytest.mark.parametrize("g_new", [G / 4, G, 2 * G])
def test_free_fall_only_timing_is_g_ratio(g_new):
    """A free-falling body recorded under g and retimed under g': p'^2 = g'/g, p'' = 0 exactly."""
    pd = ps.free_fall(g_source=G, g_new=g_new)
    rs = R.compute_regions(pd, opts(relax=False))
    for i in range(rs.n_frames):
        P = rs.polygon(i)
        assert np.allclose(P, [0.0, g_new / G], atol=1e-6), (i, P)


def test_free_fall_with_relaxation_on_keeps_the_timing():
    """Same with the relaxation machinery on (exact data, reference physics = the recording): the
    region is exactly the allowance around (0, g'/g): |vx u| <= eps g', |vy u - g v + g'| <= eps g',
    a parallelogram of area 4 eps^2 g'^2 / (g max(|vx|, |vz|))."""
    ref = ps.free_fall(g_source=G, g_new=G)
    g2 = G / 4
    pd = ps.free_fall(g_source=G, g_new=g2)
    o = opts(body_weight=ref.total_mass * G)
    eps = o.allowance
    rs = R.compute_regions(pd, o, reference=ref)
    assert np.all(rs.source_residual == 0)
    assert not rs.relaxed.any()
    vx = max(abs(pd.vel[0]), abs(pd.vel[2]))
    for i in range(rs.n_frames):
        P = rs.polygon(i)
        assert rs.contains(i, (0.0, g2 / G))
        assert polygon_area(P) == pytest.approx(4 * eps ** 2 * g2 ** 2 / (G * vx), rel=1e-6)
        vy = pd.a[i, 1] / pd.total_mass
        assert np.all(np.abs(vx * P[:, 0]) <= eps * g2 + 1e-9)
        assert np.all(np.abs(vy * P[:, 0] - G * P[:, 1] + g2) <= eps * g2 + 1e-9)


def test_noisy_free_fall_budget_scales_with_speed():
    """With capture noise the original timing needs a residual; its budget grows with p'^2, so under
    a quarter of the gravity the region still holds (0, 1/4) and stays narrow."""
    ref = ps.free_fall(g_source=G, g_new=G, noise=1.0)
    pd = ps.free_fall(g_source=G, g_new=G / 4, noise=1.0)
    rs = R.compute_regions(pd, opts(body_weight=ref.total_mass * G), reference=ref)
    assert np.mean(rs.source_residual > 0) > 0.8
    for i in range(rs.n_frames):
        assert rs.contains(i, (0.0, 0.25), tol=1e-9), i
        P = rs.polygon(i)
        assert 0.12 < P[:, 1].min() and P[:, 1].max() < 0.4
    with pytest.raises(RetimeError, match="relaxation is off"):
        R.compute_regions(pd, opts(relax=False))


def test_unchanged_physics_keeps_original_timing_feasible():
    pd = ps.rigid_jump(noise=0.02)
    rs = R.compute_regions(pd, opts())
    assert np.all(rs.source_distance == 0.0)
    for i in range(0, rs.n_frames, 7):
        assert rs.contains(i, (0.0, 1.0), tol=1e-7)


def test_standing_pose_contains_original_timing():
    pd = ps.rigid_jump()
    rs = R.compute_regions(pd, opts(), frames=np.arange(0, 100, 10))
    assert np.all(rs.source_residual == 0)
    for i in range(rs.n_frames):
        P = rs.polygon(i)
        assert rs.contains(i, (0.0, 1.0))
        assert P[:, 1].max() == pytest.approx(rs.options.v_max)  # a still body may play at any speed


def test_batched_distances_equal_per_frame_distances():
    pd = ps.rigid_jump(noise=0.02)
    rs = R.compute_regions(pd, opts())
    rng = np.random.default_rng(3)
    frames = rng.integers(0, rs.n_frames, 200)
    u, v = rng.normal(0, 20, 200), rng.uniform(0, 30, 200)
    d = rs.distances(frames, u, v)
    expected = [rs.distance(int(i), (a, b)) for i, a, b in zip(frames, u, v)]
    assert np.allclose(d, expected, atol=1e-12)
    assert np.any(d == 0) and np.any(d > 0)


def _random_frame(seed, m=24, K=16, extra=8):
    rng = np.random.default_rng(seed)
    nv = m + extra
    a = rng.normal(size=nv) * 5
    b = rng.normal(size=nv) * 5
    c = rng.normal(size=nv) * 50
    N = np.zeros((nv, K))
    N[:m] = rng.normal(size=(m, K))
    lam0 = rng.uniform(0, 3, K)
    tau0 = b + c - N @ lam0
    lo = tau0 - rng.uniform(5, 50, nv)
    hi = tau0 + rng.uniform(5, 50, nv)
    lo[:6] = hi[:6] = 0.0
    c[:6] -= tau0[:6]
    return a, b, c, N, lo, hi


@pytest.mark.parametrize("seed", range(4))
def test_parametric_walk_matches_highs_refinement(seed):
    a, b, c, N, lo, hi = _random_frame(seed)
    r1 = frame_region(a, b, c, N, lo, hi, opts(solver="parametric"), 100.0, 6)
    r2 = frame_region(a, b, c, N, lo, hi, opts(solver="highs", tol=1e-7), 100.0, 6)
    assert r1.n_lp <= 4 < r2.n_lp
    d12 = max(polygon_distance(r2.verts, p) for p in r1.verts)
    d21 = max(polygon_distance(r1.verts, p) for p in r2.verts)
    assert d12 < 1e-6 and d21 < 1e-6
    assert polygon_area(r1.verts) == pytest.approx(polygon_area(r2.verts), rel=1e-6)


@pytest.mark.parametrize("seed", range(3))
def test_support_function_equals_independent_lp(seed):
    """For any direction, the polygon's extent equals the optimum of the full LP (Eq. 13) solved
    independently by scipy's linprog over (u, v, lambda)."""
    a, b, c, N, lo, hi = _random_frame(seed + 10)
    o = opts()
    r = frame_region(a, b, c, N, lo, hi, o, 100.0, 6)
    budget = r.budget
    K = N.shape[1]
    rng = np.random.default_rng(seed)
    for th in rng.uniform(0, 2 * math.pi, 12):
        d = np.array([math.cos(th), math.sin(th)])
        # rows: lo1 - budget v <= a u + b v + c - N lam <= hi1 + budget v
        A_ub = np.vstack([np.c_[a, b - budget, -N], -np.c_[a, b + budget, -N]])
        b_ub = np.r_[r.hi - c, -(r.lo - c)]
        res = linprog(np.r_[-d, np.zeros(K)], A_ub=A_ub, b_ub=b_ub,
                      bounds=[(-o.u_max, o.u_max), (0, o.v_max)] + [(0, None)] * K, method="highs")
        assert res.status == 0
        assert float(np.max(r.verts @ d)) == pytest.approx(-res.fun, abs=1e-6)


def test_vertex_forces_satisfy_the_constraints():
    pd = ps.rigid_jump(noise=0.02)
    rs = R.compute_regions(pd, opts(), frames=np.arange(0, pd.times.size, 9))
    idx = np.arange(0, pd.times.size, 9)
    for k, i in enumerate(idx):
        for (u, v), lam in zip(rs.polygon(k), rs.polygon_lam(k)):
            tau = pd.a[i] * u + pd.b[i] * v + pd.c[i] - pd.N[i] @ lam
            slack = 1e-6 * (1 + np.abs(tau))
            assert np.all(lam >= 0)
            assert np.all(tau >= rs.lo[k] - rs.budget[k] * v - slack)
            assert np.all(tau <= rs.hi[k] + rs.budget[k] * v + slack)


def test_impossible_frame_is_relaxed_not_empty():
    """A foot that can only pull (cone pointing down) cannot carry the body: still a region."""
    pd = ps.rigid_jump()
    i = 10
    N = -pd.N[i]
    lo, hi = pd.tau_lo.copy(), pd.tau_hi.copy()
    o = opts(body_weight=pd.total_mass * G, allowance=0.0)
    r = frame_region(pd.a[i], pd.b[i], pd.c[i], N, lo, hi, o, pd.total_mass * G, 6, budget=np.zeros(len(lo)))
    assert r.relaxed and r.relaxation > 0.5 and len(r.verts) >= 1
    assert r.relaxation > o.max_relaxation  # flagged as implausible by compute_regions


def test_parallel_equals_serial():
    pd = ps.rigid_jump(noise=0.01)
    r1 = R.compute_regions(pd, opts(workers=1))
    r2 = R.compute_regions(pd, opts(workers=2))
    # warm starts differ between the two, so ties may pick other (equally optimal) bases: compare the
    # polygons as sets and the centre's least force, not the raw arrays
    for i in range(r1.n_frames):
        P, Q = r1.polygon(i), r2.polygon(i)
        assert max(polygon_distance(Q, p) for p in P) < 1e-7
        assert max(polygon_distance(P, q) for q in Q) < 1e-7
    w = np.linalg.norm(pd.N[:, :3, :], axis=1)
    assert np.allclose((w * r1.center_lam).sum(1), (w * r2.center_lam).sum(1), rtol=1e-6, atol=1e-6)


def test_polygon_geometry_helpers():
    P = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    assert polygon_area(P) == pytest.approx(2.0)
    assert closest_point(P, (1.0, 0.5))[1] == 0.0
    q, d = closest_point(P, (3.0, 2.0))
    assert np.allclose(q, [2.0, 1.0]) and d == pytest.approx(math.sqrt(2))
    q, d = closest_point(P[:2], (1.0, 1.0))  # a segment
    assert np.allclose(q, [1.0, 0.0]) and d == pytest.approx(1.0)


def test_regions_of_a_fixed_base_chain_have_no_contact_columns():
    """A fixed-base chain (the Fig. 12 benchmark's) has K = 0: its regions pack and join into
    (P, 0) contact forces, in one chunk and in several (CHUNKED_FRAMES and more frames)."""
    from chain import chain_terms

    pd = chain_terms(3, n_frames=130).combine()
    for frames in (np.arange(5), None):
        rs = R.compute_regions(pd, R.RegionOptions(workers=1, body_weight=30.0), frames=frames)
        n = 5 if frames is not None else len(pd.times)
        assert rs.lam.shape == (rs.offsets[-1], 0) and len(rs.offsets) == n + 1 and rs.lam0.shape == (n, 0)


def _center_lam_in_a_pool_worker(_):
    return R.compute_regions(ps.rigid_jump(noise=0.01), opts(workers=2)).center_lam


def test_a_pool_worker_solves_the_regions_itself():
    """A caller's multiprocessing.Pool worker is daemonic and may have no children: asked for 2
    workers it solves the chunks itself (it failed with 'daemonic processes are not allowed to have
    children'), with the serial answer."""
    import multiprocessing as mp

    with mp.get_context("fork").Pool(1) as pool:
        lam = pool.map(_center_lam_in_a_pool_worker, [0])[0]
    serial = R.compute_regions(ps.rigid_jump(noise=0.01), opts(workers=1)).center_lam
    assert np.allclose(lam, serial, rtol=1e-6, atol=1e-6)
