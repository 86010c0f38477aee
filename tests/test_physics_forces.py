"""Contact forces of retimed motion (sec. 3.4, Fig. 5): fan model around the least-force centre."""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest
from scipy.optimize import linprog

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.physics.regions import forces as F  # noqa: E402
from retime.physics import regions as R  # noqa: E402


@pytest.fixture(scope="module")
def jump():
    pd = ps.rigid_jump(noise=0.02)
    frames = np.r_[np.arange(0, 120, 15), np.arange(130, 200, 7), np.arange(250, pd.times.size, 15)]
    rs = R.compute_regions(pd, R.RegionOptions(workers=1), frames=frames)
    return pd, rs, frames


def _contact_frames(pd, rs, frames):
    return [(k, i) for k, i in enumerate(frames) if pd.contact[i].any() and len(rs.polygon(k)) >= 3]


def test_lambda_at_vertices_is_the_lps(jump):
    pd, rs, frames = jump
    found = 0
    for k, i in _contact_frames(pd, rs, frames):
        fan = F.fan_model(rs, k)
        if fan.degenerate:
            continue
        found += 1
        for V, lam in zip(rs.polygon(k), rs.polygon_lam(k)):
            assert np.allclose(fan.lam(V), lam, atol=1e-8 * (1 + np.abs(lam).max()))
        assert np.allclose(fan.lam(rs.center[k]), rs.center_lam[k], atol=1e-8 * (1 + rs.center_lam[k].max()))
    assert found >= 5


def _feasible(pd, rs, k, i, u, v, lam):
    tau = pd.a[i] * u + pd.b[i] * v + pd.c[i] - pd.N[i] @ lam
    tol = 1e-6 * (1 + np.abs(tau))
    return (np.all(lam >= -1e-9) and np.all(tau >= rs.lo[k] - rs.budget[k] * v - tol)
            and np.all(tau <= rs.hi[k] + rs.budget[k] * v + tol))


def test_interpolated_lambda_is_valid_inside(jump):
    """Constraints are linear, so barycentric lambda anywhere in the hull is feasible (sec. 3.4)."""
    pd, rs, frames = jump
    rng = np.random.default_rng(0)
    for k, i in _contact_frames(pd, rs, frames):
        fan = F.fan_model(rs, k)
        if fan.degenerate:
            continue
        P = rs.polygon(k)
        for _ in range(20):
            j = rng.integers(len(P))
            w = rng.dirichlet([1, 1, 1])
            x = w[0] * fan.C + w[1] * P[j] + w[2] * P[(j + 1) % len(P)]
            kk, bary = fan.barycentric(x)
            assert np.all(bary >= -1e-9)
            assert _feasible(pd, rs, k, i, x[0], x[1], fan.lam(x))


def test_centre_is_the_least_total_force(jump):
    """Independent check with scipy's linprog: min sum |f| at the original timing."""
    pd, rs, frames = jump
    for k, i in _contact_frames(pd, rs, frames)[:6]:
        if rs.source_distance[k] > 0:
            continue
        u, v = rs.center[k]
        act = np.flatnonzero(np.any(pd.N[i] != 0, axis=0))
        Na = pd.N[i][:, act]
        w = np.linalg.norm(Na[:3], axis=0)
        budget = rs.budget[k]
        base = pd.a[i] * u + pd.b[i] * v + pd.c[i]
        A_ub = np.vstack([-Na, Na])
        b_ub = np.r_[rs.hi[k] + budget * v - base, -(rs.lo[k] - budget * v - base)]
        res = linprog(w, A_ub=A_ub, b_ub=b_ub, bounds=[(0, None)] * len(act), method="highs")
        assert res.status == 0
        assert float(w @ rs.center_lam[k][act]) == pytest.approx(res.fun, rel=1e-6, abs=1e-6)


def test_original_torques_use_the_centre_forces(jump):
    """At the original timing the fan gives the centre's least-force lambda, hence the original
    torques b + c - N lambda_centre (the 'match' target with unchanged physics)."""
    pd, rs, frames = jump
    n = 0
    for k, i in _contact_frames(pd, rs, frames):
        if rs.source_distance[k] > 0:
            continue
        fan = F.fan_model(rs, k)
        model = pd.b[i] + pd.c[i] - pd.N[i] @ fan.lam((0.0, 1.0))
        assert np.allclose(model, pd.b[i] + pd.c[i] - pd.N[i] @ rs.center_lam[k], atol=1e-6)
        n += 1
    assert n >= 5


def test_fan_outside_the_hull_extends_affinely():
    V = np.array([[-1.0, 0.0], [1.0, 0.0], [1.0, 2.0], [-1.0, 2.0]])
    L = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 1.0], [0.0, 2.0]])
    fan = F.FanModel(V, L, (0.0, 1.0), (1.0, 1.0))
    k = fan.wedge((5.0, 1.0))
    L0, Lu, Lv = fan.affine(k)
    for p in [(5.0, 1.0), (1.0, 1.0), (2.0, 1.5)]:
        assert fan.wedge(p) == k
        assert np.allclose(fan.lam(p), L0 + Lu * p[0] + Lv * p[1])
    assert np.allclose(fan.lam((1.0, 1.0)), 0.5 * (L[1] + L[2]))  # edge midpoint
