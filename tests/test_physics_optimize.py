"""The timing spline and its optimization (sec. 3, 3.6): monotone curve, exact locks, keytimes,
the optimizers and the interactive session."""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.physics.api import make_problem  # noqa: E402
from retime.physics.method import Settings  # noqa: E402
from retime.physics.timing.optimize import RetimingSession, solve  # noqa: E402
from retime.physics.timing.spline import TimingSpline  # noqa: E402

G = 9.81


def test_uniform_spline_is_linear_timing():
    sp = TimingSpline.uniform(3.0, 12, 2.0)
    t = np.linspace(0, 2, 101)
    assert np.allclose(sp(t), 1.5 * t) and np.allclose(sp.speed(t), 1.5) and np.allclose(sp.accel(t), 0, atol=1e-9)
    assert sp.duration == 2.0
    free = TimingSpline.uniform(3.0, 12)
    assert free.free and free.duration == pytest.approx(3.0)


@pytest.mark.parametrize("seed", range(3))
def test_any_positive_w_gives_a_monotone_curve_through_the_ends(seed):
    rng = np.random.default_rng(seed)
    for T in (None, 2.5):
        sp = TimingSpline.uniform(4.0, 20, T)
        sp.w = np.exp(rng.normal(size=sp.w.size))
        t = np.linspace(0, sp.duration, 2001)
        p = sp(t)
        assert p[0] == pytest.approx(0.0, abs=1e-12) and p[-1] == pytest.approx(4.0)
        assert np.all(np.diff(p) > 0)
        kappa = 4.0 / (sp.duration * np.dot(sp.w, sp.d))
        assert np.min(sp.speed(t)) >= kappa * sp.w.min() * (1 - 1e-9)


@pytest.mark.parametrize("free,locks", [(False, {}), (True, {}), (False, {5: 1.1, 12: 2.4}), (True, {7: 1.9})])
def test_chain_rule_and_gauge_match_finite_differences(free, locks):
    rng = np.random.default_rng(1)
    sp = TimingSpline.uniform(4.0, 18, None if free else 3.0)
    sp.locks = dict(locks)
    sp.w = np.exp(0.3 * rng.normal(size=sp.w.size))
    a = rng.normal(size=sp.n_c)
    bT = 0.7

    def F(w):
        return float(a @ sp.coefficients(w) + bT * sp.duration_of(w))

    g = sp.chain(a, bT)
    gv, gg = sp.gauge()
    for k in range(0, sp.w.size, 3):
        e = np.zeros(sp.w.size)
        e[k] = 1e-6
        assert g[k] == pytest.approx((F(sp.w + e) - F(sp.w - e)) / 2e-6, rel=1e-6, abs=1e-9)
        assert gg[k] == pytest.approx((sp.gauge(sp.w + e)[0] - sp.gauge(sp.w - e)[0]) / 2e-6, rel=1e-5, abs=1e-8)
    c = sp.coefficients()
    for k, v in locks.items():
        assert c[k] == pytest.approx(v, abs=1e-12)


def test_knot_insertion_keeps_the_curve_and_removal_refits():
    rng = np.random.default_rng(2)
    sp = TimingSpline.uniform(3.0, 10, 2.0)
    sp.w = np.exp(0.2 * rng.normal(size=sp.w.size))
    t = np.linspace(0, 2, 501)
    before = sp(t)
    sp.insert_knot(0.537)
    assert len(sp.w) == 10 + sp.degree  # 10 interior knots now
    assert np.max(np.abs(sp(t) - before)) < 1e-12
    sp.remove_knot(3)
    assert np.max(np.abs(sp(t) - before)) < 0.02 * 3.0


class _CubicSpline(TimingSpline):
    degree = 3  # the paper's cubic, as the timing spline was before issue 24


def _accel_at_source_time(sp, s, w):
    """p'' at the output time where source time ``s`` plays: what a fixed source sample reads."""
    return float(sp.accel(sp.inverse(np.array([s]), w), w)[0])


@pytest.mark.parametrize("spline_class", [_CubicSpline, TimingSpline])
def test_third_derivative_is_continuous_across_knots_only_for_the_quartic(spline_class):
    """The root of issue 24's kinks (131_01, 131_03): a sample at fixed source time s reads
    p''(p^-1(s)); where p^-1(s) is a knot its derivative along a coefficient is one-sided unless p'''
    is continuous there. Finite differences on each side of every interior knot, of p'' in t and of
    the sample's p'' in w: they jump for the cubic and agree for the quartic."""
    rng = np.random.default_rng(4)
    sp = spline_class.uniform(3.0, 7, 2.0)
    sp.w = np.exp(0.4 * rng.normal(size=sp.w.size))
    T, h = sp.duration, 1e-5
    jumps_t, jumps_w, scale = [], [], []
    for knot in sp.interior * T:
        left = (sp.accel(knot) - sp.accel(knot - h)) / h
        right = (sp.accel(knot + h) - sp.accel(knot)) / h
        jumps_t.append(abs(right - left))
        scale.append(abs(right) + abs(left))
        s = float(sp(knot))
        k = int(np.searchsorted(sp.xi, knot / T)) - 1  # a w the knot's span reads
        e = np.zeros(sp.w.size)
        e[k] = 1e-4
        mid = _accel_at_source_time(sp, s, sp.w)
        up = (_accel_at_source_time(sp, s, sp.w + e) - mid) / 1e-4
        down = (mid - _accel_at_source_time(sp, s, sp.w - e)) / 1e-4
        jumps_w.append(abs(up - down) / (abs(up) + abs(down)))
    if spline_class.degree == 3:
        assert min(jumps_t) > 1e-2 * max(scale) and max(jumps_w) > 1e-2
    else:
        assert max(jumps_t) < 1e-3 * max(scale) and max(jumps_w) < 1e-3


@pytest.fixture(scope="module")
def quarter_jump():
    """A rigid jump recorded under g, retimed under g/4: the flight must play at sqrt(1/4)."""
    return ps.quarter_gravity_problem()


def _flight_speed(pd, spline):
    s = pd.times[pd.flight]
    t0, t1 = spline.inverse(np.array([s[0], s[-1]]))
    return (s[-1] - s[0]) / (t1 - t0)


@pytest.mark.parametrize("method", ["newton", "lbfgs", "lbfgsb"])
def test_quarter_gravity_halves_the_flight_speed(quarter_jump, method):
    pd, rs, obj = quarter_jump
    pr = make_problem(obj, pd.times[-1], None)
    w, info = solve(pr, method=method, max_iter=3000)
    pr.spline.w = w
    assert pr.spline.free and pr.spline.duration > pd.times[-1]
    assert 0.45 <= _flight_speed(pd, pr.spline) <= 0.56


@pytest.mark.parametrize("method", ["newton", "lbfgs", "slsqp", "gd"])
def test_keytimes_hold_exactly(quarter_jump, method):
    pd, rs, obj = quarter_jump
    S = pd.times[-1]
    kt = [(1.8, 1.5), (2.4, 2.6)]
    pr = make_problem(obj, S, S, keytimes=kt)
    w, info = solve(pr, method=method, max_iter=1000 if method != "gd" else 300)
    pr.spline.w = w
    for s_star, t_star in kt:
        assert pr.spline(t_star) == pytest.approx(s_star, abs=2e-5)
    assert info.constraint_violation < 2e-5


def test_methods_reach_the_same_optimum(quarter_jump):
    pd, rs, obj = quarter_jump
    S = pd.times[-1]
    vals = []
    for method in ("newton", "lbfgs", "lbfgsb", "slsqp"):
        pr = make_problem(obj, S, 0.9 * S, knot_spacing=0.2)
        w, info = solve(pr, method=method, max_iter=2000)
        vals.append(info.objective)
    assert max(vals) - min(vals) <= 2e-3 * max(1.0, min(vals))


def test_session_move_lock_add_remove(quarter_jump):
    pd, rs, obj = quarter_jump
    S = pd.times[-1]
    sess = RetimingSession(make_problem(obj, S, S), Settings.optimizer, fps=120.0)
    sess.reconverge(max_iter=3000, tol=1e-9)
    e0 = sess.objective()
    cps = sess.control_points()
    k = len(cps) // 2
    target = 0.5 * (cps[k]["source_time"] + cps[k + 1]["source_time"])
    sess.move(k, target, lock=True)
    assert sess.control_points()[k]["locked"]
    e_moved = sess.objective()
    info = sess.reconverge(max_iter=3000, tol=1e-9)
    assert sess.spline.coefficients()[k] == pytest.approx(target, abs=1e-12)  # exact, not penalized
    assert info.objective <= e_moved and info.objective >= e0 - 1e-2 * e0
    # adding a point leaves the curve as it is
    t = np.linspace(0, S, 301)
    before = sess.spline(t)
    j = sess.add(0.313 * S)
    assert np.max(np.abs(sess.spline(t) - before)) < 1e-9
    assert any(cp["locked"] for cp in sess.control_points())
    sess.remove(j)
    sess.lock(next(cp["index"] for cp in sess.control_points() if cp["locked"]), False)
    assert not any(cp["locked"] for cp in sess.control_points())
    sess.reconverge(max_iter=3000, tol=1e-9)
    assert sess.objective() <= e0 * (1 + 1e-3)  # no constraint left: no worse than before
    curve = sess.curve()
    assert curve.duration == pytest.approx(S) and np.all(np.diff(curve(t)) >= 0)


def test_the_quick_stage_solves_at_half_the_samples_and_reports_the_full_objective(quarter_jump):
    """The editor's answer during a drag: L-BFGS on the objective at half the sample density (half the
    cost per evaluation), then reported on the full objective, within a few source ms of the polish."""
    from retime.physics.timing.optimize import PREVIEW_STRIDE

    pd, rs, obj = quarter_jump
    S = pd.times[-1]
    sess = RetimingSession(make_problem(obj, S, 0.8 * S), Settings.optimizer, fps=120.0)
    sess.reconverge(max_iter=3000, tol=1e-9)
    cps = sess.control_points()
    k = len(cps) // 2
    sess.move(k, 0.5 * (cps[k]["source_time"] + cps[k + 1]["source_time"]), lock=True)
    moved = sess.objective()
    preview = sess.preview_problem()
    assert PREVIEW_STRIDE == 2 and len(preview.obj.arrays.s) == (len(obj.arrays.s) - 1) // 2 + 1
    assert preview.spline is sess.spline
    info = sess.reconverge(quick=True)
    assert not info.converged and info.message.startswith("quick")
    assert info.objective == sess.objective() < moved  # the full objective, not the preview's, and lower
    t = np.linspace(0.0, sess.spline.duration, 500)
    quick = sess.spline(t)
    sess.reconverge()
    # source seconds: 6.5 ms measured; loose, since the polish may settle in a nearby minimum (1-2 frames)
    assert np.max(np.abs(quick - sess.spline(t))) <= 0.02


def _kkt_by_differences(pr, w, h=1e-7):
    """The KKT residual of optimize.kkt_residual computed independently: central differences of E
    along each w_k, the bounds' sign rule, least-squares keytime multipliers, relative to |E|."""
    E = pr.value(w)
    g = np.empty(len(w))
    for k in range(len(w)):
        e = np.zeros(len(w))
        e[k] = h * w[k]
        g[k] = (pr.value(w + e) - pr.value(w - e)) / (2 * h * w[k])
    free = ~(((w <= pr.w_min * (1 + 1e-9)) & (g > 0)) | ((w >= pr.w_max * (1 - 1e-9)) & (g < 0)))
    if pr.n_eq:
        J = pr.eq(w)[1]
        g = g + J.T @ np.linalg.lstsq(J[:, free].T, -g[free], rcond=None)[0]
    return float(np.max(np.where(free, np.abs(g) * w, 0.0))) / abs(E)


@pytest.mark.parametrize("keytimes", [(), [(1.8, 1.5), (2.4, 2.6)]])
def test_kkt_residual_is_the_relative_projected_gradient(quarter_jump, keytimes):
    """The optimizer block's residual: at the start and at the answer it agrees with finite differences
    of the objective; with keytimes it is the Lagrangian's (the objective's own gradient does not
    vanish at a constrained optimum)."""
    from retime.physics.timing.optimize import kkt_residual

    pd, rs, obj = quarter_jump
    S = pd.times[-1]
    pr = make_problem(obj, S, S, keytimes=keytimes)
    w0 = pr.spline.w.copy()
    w, info = solve(pr, max_iter=3000)
    for x in (w0, w):
        val, r = kkt_residual(pr, x)
        assert val == pytest.approx(pr.value(x), rel=1e-12)
        assert r == pytest.approx(_kkt_by_differences(pr, x), rel=2e-3, abs=1e-6)
    assert info.kkt_residual == pytest.approx(kkt_residual(pr, w)[1], rel=1e-12)
    assert info.kkt_residual < kkt_residual(pr, w0)[1]
    if keytimes:  # without multipliers the residual is the objective's gradient: far larger
        g = np.abs(pr.fun(w)[1] - pr.gauge * pr.spline.gauge(w)[1]) * w
        assert np.max(g) / info.objective > 10 * info.kkt_residual


def test_report_says_why_the_optimizer_stopped(quarter_jump):
    from retime.physics.report import build_report

    pd, rs, obj = quarter_jump
    S = pd.times[-1]
    pr = make_problem(obj, S, None)
    for max_iter, why in ((5, "iteration limit"), (3000, "objective gained less than tol")):
        w, info = solve(pr, method="lbfgs", max_iter=max_iter)
        pr.spline.w = w
        block = build_report(pr.spline, pd, rs, 120.0, info=info)["summary"]["optimizer"]
        assert block["stopped"].startswith(why) and block["converged"] == (max_iter > 5)
        assert block["kkt_residual"] == info.kkt_residual and np.isfinite(info.kkt_residual)
        assert block["iterations"] == info.iterations


def test_bad_keytimes_are_refused():
    from retime.errors import RetimeError
    from retime.warp import check_keytimes

    with pytest.raises(RetimeError, match="outside the clip"):
        check_keytimes([(5.0, 1.0)], 3.0, 2.0)
    with pytest.raises(RetimeError, match="out of order"):
        check_keytimes([(1.0, 1.5), (2.0, 1.0)], 3.0, 2.0)


def test_spline_fit_is_the_dense_least_squares_solution():
    """The banded normal-equation solve of TimingSpline.fit against NumPy's dense lstsq."""
    from scipy.interpolate import BSpline

    from retime.physics.timing.spline import banded_least_squares

    rng = np.random.default_rng(3)
    for n in (5, 60, 400):
        k = np.sort(rng.uniform(0.01, 0.99, n))
        tau = np.linspace(0, 1, 20 * (n + 3))
        D = BSpline.design_matrix(tau, np.r_[0, 0, 0, k, 1, 1, 1], 2)
        y = 1.5 + np.sin(9 * tau) + 0.1 * rng.normal(size=tau.size)
        dense = np.linalg.lstsq(D.toarray(), y, rcond=None)[0]
        assert np.allclose(banded_least_squares(D, y), dense, atol=1e-9)


def test_knot_removal_refits_like_the_dense_least_squares():
    """remove_knot's banded refit against NumPy's dense lstsq of the same sampled speed."""
    from scipy.interpolate import BSpline

    rng = np.random.default_rng(4)
    sp = TimingSpline.uniform(3.0, 40, 2.0)
    sp.w = np.exp(0.3 * rng.normal(size=sp.w.size))
    old = sp.copy()
    sp.remove_knot(17)
    xi1 = sp.xi[1:-1]
    tau = np.linspace(0, 1, 40 * (len(sp.interior) + sp.degree))
    D = BSpline.design_matrix(tau, xi1, sp.degree - 1)  # of p'
    dense = np.linalg.lstsq(D.toarray(), old.speed(tau * old.duration), rcond=None)[0]
    assert len(sp.w) == len(old.w) - 1
    assert np.allclose(sp.w, np.maximum(dense, 1e-3), atol=1e-9)
