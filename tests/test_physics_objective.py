"""The baked objective (Eq. 14, sec. 3.5-3.6): coefficients, integration and the analytic gradient."""
from __future__ import annotations

import dataclasses
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.physics.regions import forces as F  # noqa: E402
from retime.physics.timing import objective as O  # noqa: E402
from retime.physics import regions as R  # noqa: E402
from retime.physics.regions.polygon import polygon_distance  # noqa: E402
from retime.physics.timing.spline import TimingSpline  # noqa: E402

G = 9.81


@pytest.fixture(scope="module")
def setup():
    ref = ps.rigid_jump(noise=0.02)
    pd = ps.rigid_jump(gravity=(0.0, -G / 2, 0.0), limits=ref.tau_hi[6:], noise=0.02)
    # the (u, v) box of the regions' original default (5x speed): the checks below are about the
    # objective's algebra, and the numbers they were tuned on
    rs = R.compute_regions(pd, R.RegionOptions(workers=1, body_weight=ref.total_mass * G, v_max=25.0), reference=ref)
    target = ref.b + ref.c - np.einsum("nvk,nk->nv", ref.N, rs.lam0)
    return pd, rs, target


def _wiggly_spline(S, T, n=24, seed=0):
    rng = np.random.default_rng(seed)
    sp = TimingSpline.uniform(S, n, T)
    sp.w = sp.w * np.exp(0.3 * rng.normal(size=sp.w.size))
    return sp


@pytest.mark.parametrize("penalty,metric,free", [("l2", "plane", False), ("l1", "residual", False),
                                                 ("l1", "residual", True), ("l2", "residual", True)])
def test_gradient_matches_finite_differences(setup, penalty, metric, free):
    pd, rs, target = setup
    S = pd.times[-1]
    obj = O.bake(pd, rs, target, alpha=10.0, beta=0.5, penalty=penalty, metric=metric, gamma=0.1)
    sp = _wiggly_spline(S, None if free else 0.8 * S)
    w = sp.w.copy()
    E, g = O.evaluate(obj, sp, w, grad=True)
    assert np.isfinite(E) and E > 0
    rng = np.random.default_rng(1)
    for _ in range(6):
        d = rng.normal(size=w.size)
        d /= np.linalg.norm(d)
        h = 1e-6
        fd = (O.evaluate(obj, sp, w + h * d) - O.evaluate(obj, sp, w - h * d)) / (2 * h)
        assert g @ d == pytest.approx(fd, rel=2e-4, abs=1e-7 * (1 + abs(E)))


def test_gradient_with_respect_to_c_and_T(setup):
    pd, rs, target = setup
    S = pd.times[-1]
    obj = O.bake(pd, rs, target, alpha=5.0, beta=1.0, penalty="l2", gamma=0.2)
    sp = _wiggly_spline(S, 0.7 * S, seed=3)
    c = sp.coefficients()
    T = sp.duration
    E, gc, gT = O.evaluate_c(obj, sp, c, T, grad=True)
    h = 1e-7
    for k in range(1, len(c) - 1, 5):
        e = np.zeros_like(c)
        e[k] = h
        fd = (O.evaluate_c(obj, sp, c + e, T) - O.evaluate_c(obj, sp, c - e, T)) / (2 * h)
        assert gc[k] == pytest.approx(fd, rel=1e-4, abs=1e-6)
    fd = (O.evaluate_c(obj, sp, c, T + h) - O.evaluate_c(obj, sp, c, T - h)) / (2 * h)
    assert gT == pytest.approx(fd, rel=1e-4)


def test_six_coefficients_reproduce_the_torque_error(setup):
    """g(u, v) from the baked coefficients equals beta |tau_act(u, v) - tau'|^2 / tau_scale^2 with
    tau from the fan contact model computed directly (no baking; without the smoothing across the
    fan's rays, which the fan model does not have)."""
    pd, rs, target = setup
    beta = 0.7
    obj = O.bake(pd, rs, target, alpha=1.0, beta=beta, excess=False, metric="plane", fan_blend=0.0)
    act = O.actuated_mask(pd)
    rng = np.random.default_rng(2)
    for i in range(0, rs.n_frames, 11):
        fan = F.fan_model(rs, i)
        for _ in range(5):
            u, v = rng.uniform(-3, 3), rng.uniform(0.05, 4)
            tau = pd.a[i] * u + pd.b[i] * v + pd.c[i] - pd.N[i] @ fan.lam((u, v))
            direct = beta * np.sum((tau - target[i])[act] ** 2) / obj.tau_scale ** 2
            _, g = O.frame_terms(obj, i, u, v)
            assert g == pytest.approx(direct, rel=1e-9, abs=1e-12)


def test_excess_is_nonnegative_and_a_constant_shift(setup):
    pd, rs, target = setup
    raw = O.bake(pd, rs, target, alpha=1.0, beta=1.0, excess=False)
    exc = O.bake(pd, rs, target, alpha=1.0, beta=1.0, excess=True, v_range=(0.0, 25.0))
    rng = np.random.default_rng(4)
    for i in range(0, rs.n_frames, 13):
        shifts = []
        for u, v in zip(rng.uniform(-60, 60, 30), rng.uniform(0, 25, 30)):
            g_raw = O.frame_terms(raw, i, u, v)[1]
            g_exc = O.frame_terms(exc, i, u, v)[1]
            assert g_exc >= -1e-9
            shifts.append(g_raw - g_exc)
        assert np.ptp(shifts) < 1e-8 * (1 + max(shifts))


def test_distance_term_matches_geometry(setup):
    pd, rs, target = setup
    obj = O.bake(pd, rs, target, alpha=1.0, beta=0.0, metric="plane")
    rng = np.random.default_rng(5)
    for i in range(0, rs.n_frames, 17):
        for u, v in zip(rng.normal(0, 3, 10), rng.uniform(0, 6, 10)):
            d, _ = O.frame_terms(obj, i, u, v)
            assert d == pytest.approx(polygon_distance(rs.polygon(i), (u, v)), abs=1e-9)


@pytest.mark.parametrize("interp", ["linear", "nearest"])
def test_integral_matches_output_time_quadrature(setup, interp):
    """E = integral over output time (plus gamma (p' + 1/p' - 2) per source second), checked against
    a dense uniform quadrature in output time with the same per-frame integrand."""
    pd, rs, target = setup
    S = pd.times[-1]
    obj = O.bake(pd, rs, target, alpha=3.0, beta=1.0, penalty="l2", gamma=0.3, interp=interp)
    sp = _wiggly_spline(S, 1.3 * S, seed=7)
    E = O.evaluate(obj, sp)
    t = np.linspace(0, sp.duration, 40001)
    s, pdot, pdd = sp(t), sp.speed(t), sp.accel(t)
    fps = 1.0 / (pd.times[1] - pd.times[0])
    f = np.empty_like(t)
    for k, (sk, u, v) in enumerate(zip(s, pdd, pdot ** 2)):
        x = min(sk * fps, rs.n_frames - 1 - 1e-12)
        i = int(x)
        wgt = x - i
        if interp == "nearest":
            i, wgt = int(round(x)), 0.0
        f0 = O.frame_gradient(obj, i, u, v)[0]
        f1 = O.frame_gradient(obj, min(i + 1, rs.n_frames - 1), u, v)[0]
        f[k] = (1 - wgt) * f0 + wgt * f1 + 0.3 * (pdot[k] + 1 / pdot[k] - 2) * pdot[k]
    ref = np.sum((f[1:] + f[:-1]) / 2 * np.diff(t))
    assert E == pytest.approx(ref, rel=2e-3)


def test_samples_are_four_per_source_frame():
    times = np.arange(11) / 120.0
    s, om, fi, fw = O.samples(times, 4, "linear")
    assert len(s) == 41 and np.allclose(np.diff(s), 1 / 480)
    assert om.sum() == pytest.approx(times[-1])
    assert np.all((fi >= 0) & (fi <= 9)) and np.allclose(times[fi] + fw / 120.0, s)
    s2, om2, fi2, fw2 = O.samples(times, 4, "nearest")
    assert np.allclose(s2, s) and np.all(fw2 == 0) and np.all(np.abs(times[fi2] - s) <= 0.5 / 120 + 1e-12)


def test_residual_scales_are_body_weights_per_unit_timing():
    pd = ps.free_fall(noise=0.0)
    sc = O.residual_scales(pd, pd.total_mass * G)
    # root force m x'' per unit p'^2 is m g: one body weight; per unit p'' it is m |x'| / W
    assert np.allclose(sc[:, 1], 1.0)
    assert np.allclose(sc[:, 0], np.linalg.norm(pd.a[:, :3], axis=1) / (pd.total_mass * G))


def test_unbaked_evaluation_equals_baked(setup):
    """NP-Obj (per dof, no baking) and Obj (six coefficients) are the same function."""
    pd, rs, target = setup
    S = pd.times[-1]
    obj = O.bake(pd, rs, target, alpha=2.0, beta=0.8, excess=False, gamma=0.05)
    ub = O.unbaked(pd, rs, target, obj)
    for seed in range(3):
        sp = _wiggly_spline(S, 0.9 * S, seed=seed)
        assert O.evaluate_unbaked(ub, sp) == pytest.approx(O.evaluate(obj, sp), rel=1e-9)


def test_bake_reads_the_actuated_rows_in_place_exactly_as_from_a_copy(setup):
    """The bake kernel reads a, b, c, the target and N on the actuated rows frame by frame (no
    (n, rows) or (n, rows, K) copies): the same coefficients, bit for bit, as the kernel run on copies."""
    pd, rs, target = setup
    obj = O.bake(pd, rs, target, alpha=1.0, beta=0.7, excess=False, metric="plane")
    act = O.actuated_mask(pd)
    a, b, c, tgt = (np.ascontiguousarray(np.asarray(x, float)[:, act]) for x in (pd.a, pd.b, pd.c, target))
    copy = np.ascontiguousarray(np.asarray(pd.N, float)[:, act, :])
    poff = np.asarray(rs.offsets, np.int64)
    px, py = np.ascontiguousarray(rs.verts[:, 0]), np.ascontiguousarray(rs.verts[:, 1])
    wc = np.zeros((len(px), 6))
    every = np.arange(copy.shape[1])
    O._bake_kernel(a, b, c, tgt, every, copy, every, poff, px, py, np.ascontiguousarray(rs.center),
                   np.ascontiguousarray(rs.lam), np.ascontiguousarray(rs.center_lam), obj.arrays.mode, 0.7 / obj.tau_scale ** 2, wc)
    assert act.sum() < act.size  # the root rows are left out, so the rows really are a subset
    assert np.array_equal(wc, obj.arrays.wc)


def test_long_clip_objective_does_not_depend_on_the_thread_count(setup, monkeypatch):
    """Clips from PARALLEL_MIN_SAMPLES samples sum the objective in PARALLEL_CHUNKS fixed chunks: the
    same value and gradient, bit for bit, on one thread as on two (one chunk per thread made a long
    clip's answer depend on the machine), and the same as one pass up to rounding."""
    import numba

    pd, rs, target = setup
    obj = O.bake(pd, rs, target, alpha=1.0, beta=0.7)
    S = float(pd.times[-1])
    sp = _wiggly_spline(S, 0.8 * S, seed=1)
    one_pass = O.evaluate(obj, sp, grad=True)
    monkeypatch.setattr(O, "PARALLEL_MIN_SAMPLES", 0)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        single = O.evaluate(obj, sp, grad=True)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        double = O.evaluate(obj, sp, grad=True)
    finally:
        numba.set_num_threads(threads)
    assert single[0] == double[0] and np.array_equal(single[1], double[1])
    assert single[0] == pytest.approx(one_pass[0], rel=1e-12)
    assert np.allclose(single[1], one_pass[1], rtol=1e-10, atol=1e-12 * np.abs(one_pass[1]).max())



def test_long_clip_hessian_does_not_depend_on_the_thread_count(setup, monkeypatch):
    """The exact Hessian of a long clip sums the same fixed chunks: bit for bit the same on one thread
    as on two, and the same as one pass up to rounding."""
    import numba

    pd, rs, target = setup
    obj = O.bake(pd, rs, target, alpha=1.0, beta=0.7)
    S = float(pd.times[-1])
    sp = _wiggly_spline(S, 0.8 * S, seed=1)
    c, T = sp.coefficients(), sp.duration_of()
    one_pass = O.hessian_c(obj, sp, c, T)
    monkeypatch.setattr(O, "PARALLEL_MIN_SAMPLES", 0)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        single = O.hessian_c(obj, sp, c, T)
        numba.set_num_threads(min(2, numba.config.NUMBA_NUM_THREADS))
        double = O.hessian_c(obj, sp, c, T)
    finally:
        numba.set_num_threads(threads)
    assert np.array_equal(single[0], double[0]) and np.array_equal(single[1], double[1]) and single[2] == double[2]
    assert np.allclose(single[0], one_pass[0], rtol=1e-10, atol=1e-12 * np.abs(one_pass[0]).max())
    assert single[2] == pytest.approx(one_pass[2], rel=1e-10)

def _rays(obj, i):
    """(centre, ray directions as angles) of frame i's fan in the objective's metric."""
    ob = obj.arrays
    p0, p1 = ob.poff[i], ob.poff[i + 1]
    cx, cy = ob.cen[i]
    return (cx, cy), np.arctan2(ob.py[p0:p1] - cy, ob.px[p0:p1] - cx)


def test_torque_term_is_smooth_across_the_fan_rays():
    """Issue 24: the fan model's torque term is piecewise quadratic, with kinks at the rays from the
    centre through the vertices where L-BFGS stalled. Blended over FAN_BLEND, the term and its
    gradient are continuous across every ray (they jump without the blend), and the gradient
    inside the band matches finite differences of the term."""
    from retime.data import bundled_path
    from retime.motion import load_motion
    from retime.physics.api import prepare

    _, _, _, obj = prepare(load_motion(bundled_path("16_06.amc")))
    obj = dataclasses.replace(obj, arrays=obj.arrays._replace(alpha=0.0))  # the torque term alone
    ob = obj.arrays
    kinked = checked = inside = 0
    for i in np.flatnonzero(ob.mode == 0)[::7]:
        (cx, cy), theta = _rays(obj, i)
        su, sv = ob.scale[i]
        for th in theta[::3]:
            r = 0.5 * O.FAN_BLEND
            jumps = []
            for step in (1e-9, 1e-10):  # either side of the ray, this far from it (metric units)
                (f0, gu0, gv0), (f1, gu1, gv1) = [
                    O.frame_gradient(obj, i, (cx + r * np.cos(th + side * step / r)) / su,
                                     (cy + r * np.sin(th + side * step / r)) / sv) for side in (-1, 1)]
                scale = 1.0 + abs(gu0) + abs(gv0)
                assert abs(f1 - f0) <= 1e-6 * scale
                jumps.append(abs(gu1 - gu0) + abs(gv1 - gv0))
            # continuous: the gradient's difference shrinks with the distance (a kink's does not)
            assert jumps[1] <= 0.2 * jumps[0] + 1e-7 * scale, (i, th, jumps)
            checked += 1
            # inside the band of a ray between wedges wider than 0.02 rad (the band is then a
            # quarter of the narrower one at this radius): the analytic gradient is the derivative
            k = int(np.argmin(np.abs(theta - th)))
            widths = np.mod(np.roll(theta, -1) - theta, 2 * np.pi)
            if min(widths[k], widths[k - 1]) < 0.02:
                continue
            a = th + 1e-3
            u, v = (cx + r * np.cos(a)) / su, (cy + r * np.sin(a)) / sv
            f, gu, gv = O.frame_gradient(obj, i, u, v)
            h = 1e-8
            fdu = (O.frame_gradient(obj, i, u + h, v)[0] - O.frame_gradient(obj, i, u - h, v)[0]) / (2 * h)
            fdv = (O.frame_gradient(obj, i, u, v + h)[0] - O.frame_gradient(obj, i, u, v - h)[0]) / (2 * h)
            assert gu == pytest.approx(fdu, rel=1e-3, abs=1e-7)
            assert gv == pytest.approx(fdv, rel=1e-3, abs=1e-7)
            inside += 1
    assert checked > 50 and inside > 10
    # without the blend the same rays do kink: the test above would see it
    raw = dataclasses.replace(obj, arrays=ob._replace(blend=0.0))
    for i in np.flatnonzero(ob.mode == 0)[::7]:
        (cx, cy), theta = _rays(raw, i)
        su, sv = ob.scale[i]
        for th in theta[::3]:
            r = 0.5 * O.FAN_BLEND
            g = [O.frame_gradient(raw, i, (cx + r * np.cos(th + s * 1e-9 / r)) / su,
                                  (cy + r * np.sin(th + s * 1e-9 / r)) / sv) for s in (-1, 1)]
            kinked += abs(g[1][1] - g[0][1]) + abs(g[1][2] - g[0][2]) > 1e-4 * (1 + abs(g[0][1]) + abs(g[0][2]))
    assert kinked > 10


@pytest.mark.parametrize("stride", [1, 2, 4])
def test_a_subsampled_objective_is_the_one_baked_with_fewer_samples(setup, stride):
    """subsampled(obj, k): the samples, trapezoid weights and frames that samples() gives for 4 / k
    samples per frame, and so the same objective value as baking at that density."""
    pd, rs, target = setup
    obj = O.bake(pd, rs, target)
    sub = O.subsampled(obj, stride)
    s, om, fi, fw = O.samples(rs.times, 4 // stride)
    a = sub.arrays
    assert np.allclose(a.s, s, rtol=0, atol=1e-12) and np.allclose(a.omega, om, rtol=0, atol=1e-12)
    assert np.array_equal(a.fi, fi) and np.array_equal(a.fw, fw)
    direct = O.bake(pd, rs, target, samples_per_frame=4 // stride)
    sp = _wiggly_spline(rs.times[-1], 0.8 * rs.times[-1])
    assert O.evaluate(sub, sp) == pytest.approx(O.evaluate(direct, sp), rel=1e-12)
