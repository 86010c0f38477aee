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


def _regularised_by_scipy(w, A, lo, hi, spread):
    """min w.lam + sum (w lam)^2 / (2 spread) s.t. lo <= A lam <= hi, lam >= 0, by SciPy's SLSQP
    from lam = 0 (in units of spread, so that its tolerances mean the same on every frame)."""
    from scipy.optimize import minimize

    s = spread
    fin_lo, fin_hi = lo > -1e20, hi < 1e20
    cons = [{"type": "ineq", "fun": lambda x: (A @ (s * x) - lo)[fin_lo] / s, "jac": lambda x: A[fin_lo]},
            {"type": "ineq", "fun": lambda x: (hi - A @ (s * x))[fin_hi] / s, "jac": lambda x: -A[fin_hi]}]
    res = minimize(lambda x: w @ x + 0.5 * np.sum((w * x) ** 2), np.zeros(len(w)), jac=lambda x: w + w ** 2 * x,
                   bounds=[(0, None)] * len(w), constraints=cons, method="SLSQP",
                   options={"ftol": 1e-13, "maxiter": 1000})
    assert res.success, res.message
    return res.x * s


def test_centre_is_the_regularised_least_force(jump):
    """Independent checks of the centre: SciPy's SLSQP on the same strictly convex problem
    (min sum f + sum f^2 / (2 spread), f = w lam) finds the same forces, and their summed force exceeds
    linprog's least summed force by no more than the quadratic term can explain."""
    pd, rs, frames = jump
    spread = rs.options.force_spread * rs.body_weight
    checked = 0
    for k, i in _contact_frames(pd, rs, frames)[:6]:
        if rs.source_distance[k] > 0 or rs.budget[k].any():
            continue  # rows exactly as below: the centre is the original timing, the rows unwidened
        act = np.flatnonzero(np.any(pd.N[i] != 0, axis=0))
        Na = pd.N[i][:, act]
        w = np.linalg.norm(Na[:3], axis=0)
        lo, hi = R.base_bounds(pd, rs.options, rs.body_weight, 6)
        base = pd.b[i] + pd.c[i]  # (u, v) = (0, 1)
        lam = rs.lam0[k][act]
        mine = _regularised_by_scipy(w, -Na, lo - base, hi - base, spread)
        assert np.abs(mine - lam).max() <= 1e-7 * rs.body_weight
        res = linprog(w, A_ub=np.vstack([-Na, Na]), b_ub=np.r_[hi - base, base - lo],
                      bounds=[(0, None)] * len(act), method="highs")
        assert res.status == 0
        quad = 0.5 * np.sum((w * res.x) ** 2) / spread
        assert res.fun - 1e-6 <= float(w @ lam) <= res.fun + quad + 1e-6
        checked += 1
    assert checked >= 3


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


def _two_identical_feet(mass=70.0):
    """One frame's LP rows for a body standing on two feet with identical basis forces (the same
    sole corners): every split of the load between the feet is optimal for the plain LP."""
    from retime.physics.regions.frame_region import _frame_lp

    bw = mass * ps.G
    corners = np.array([[0.12, -1.0, 0.05], [-0.08, -1.0, 0.05], [-0.08, -1.0, -0.05], [0.12, -1.0, -0.05]])
    foot = ps._contact_columns(corners)
    N = np.hstack([foot, foot])  # (6, 32)
    a, b = np.zeros(6), np.zeros(6)
    c = np.r_[0.0, bw, 0.0, 0.0, 0.0, 0.0]  # weight, carried by the contact forces
    band = 0.05 * bw * np.ones(6)  # the residual allowance
    return a, b, c, N, -band, band, bw


def _centre(a, b, c, N, lo, hi, bw, spread):
    from retime.physics.regions.frame_region import _frame_lp
    from retime.physics.regions.highs_lp import HighsPool

    opts = R.RegionOptions()
    act = np.arange(N.shape[1])
    lp = _frame_lp(a, b, c, N, lo, hi, np.zeros(6), act, np.arange(6), opts, HighsPool())
    w = F.force_weights(N[:3], 6)
    plain = lp.solve_at(0.0, 1.0, w)
    return plain, F.solve_center(lp, 0.0, 1.0, w, spread)


def test_centre_forces_are_unique_on_a_degenerate_face():
    """Two feet with identical basis forces: the plain least-force LP has a whole face of optima and
    a 1e-7 relative perturbation of the data moves its answer by a large fraction of the body weight;
    the regularised centre moves by O(1e-7) of it, and splits the load equally between the feet
    (the unique minimizer of a problem symmetric in the feet is symmetric)."""
    a, b, c, N, lo, hi, bw = _two_identical_feet()
    spread = R.RegionOptions().force_spread * bw
    plain0, lam0 = _centre(a, b, c, N, lo, hi, bw, spread)
    assert np.allclose(lam0[:16], lam0[16:], atol=1e-7 * bw)
    rng = np.random.default_rng(1)
    plain_moves, moves = [], []
    for _ in range(8):
        Np = N * (1 + 1e-7 * rng.standard_normal(N.shape))
        cp = c * (1 + 1e-7 * rng.standard_normal(6))
        plain, lam = _centre(a, b, cp, Np, lo, hi, bw, spread)
        plain_moves.append(np.abs(plain - plain0).max() / bw)
        moves.append(np.abs(lam - lam0).max() / bw)
    assert max(moves) <= 1e-5
    assert max(plain_moves) >= 0.05  # the defect the regularisation removes (why the test exists)


def test_centre_forces_of_a_real_frame_match_scipy(jump):
    """Frames of the bundled standing jump (CMU 16_06): the regularised centre against SciPy's SLSQP
    on the same rows, and the forces balance the body within the rows' bounds."""
    from retime.data import bundled_path
    from retime.motion import load_motion
    from retime.physics.model.dynamics import dynamics_terms

    pd = dynamics_terms(load_motion(bundled_path("16_06.amc"))).combine()
    bw = float(pd.total_mass) * ps.G
    spread = R.RegionOptions().force_spread * bw
    checked = 0
    for _, lp, w in ps.frame_lps(pd, (10, 60, 120, 150, 200, 380)):
        lam = F.solve_center(lp, 0.0, 1.0, w, spread)
        assert lam is not None
        A = lp.A[:, 2:]
        rlo, rhi = lp.row_lo - lp.A[:, 1], lp.row_hi - lp.A[:, 1]  # (u, v) = (0, 1)
        tol = 1e-6 * bw
        assert np.all(lam >= -tol) and np.all(A @ lam >= rlo - tol) and np.all(A @ lam <= rhi + tol)
        ref = _regularised_by_scipy(w, A, rlo, rhi, spread)
        assert np.abs(ref - lam).max() <= 1e-7 * bw
        checked += 1
    assert checked >= 4


def test_vertex_forces_are_unique_on_a_degenerate_face():
    """Two feet with identical basis forces: at every vertex of the frame's polygon the forces are
    the regularised least force on the vertex's rows (SciPy's SLSQP on the same rows, widened by
    the vertex slack), so the load splits equally between the feet. The walk's own lambda at a
    vertex is one corner of the face of valid forces: it leans on one foot."""
    from retime.physics.regions.frame_region import _frame_lp, frame_region
    from retime.physics.regions.highs_lp import HighsPool

    a, b, c, N, lo, hi, bw = _two_identical_feet()
    opts = R.RegionOptions(workers=1, unique_vertex_forces=True)
    spread = opts.force_spread * bw
    fr = frame_region(a, b, c, N, lo, hi, opts, bw, 6, budget=np.zeros(6))
    P, L = fr.verts, fr.lam
    assert len(P) >= 3
    assert np.abs(L[:, :16] - L[:, 16:]).max() <= 1e-6 * bw
    walked = frame_region(a, b, c, N, lo, hi, R.RegionOptions(workers=1), bw, 6, budget=np.zeros(6)).lam
    assert np.abs(walked[:, :16] - walked[:, 16:]).max() >= 0.05 * bw  # the default: the walk's corner
    lp = _frame_lp(a, b, c, N, lo, hi, np.zeros(6), np.arange(32), np.arange(6), opts, HighsPool())
    w = F.force_weights(N[:3], 6)
    slack = F.VERTEX_SLACK * spread
    for (u, v), lam in zip(P, L):
        shift = lp.A[:, 0] * u + lp.A[:, 1] * v
        ref = _regularised_by_scipy(w, lp.A[:, 2:], lp.row_lo - shift - slack, lp.row_hi - shift + slack, spread)
        assert np.abs(ref - lam).max() <= 1e-6 * bw
        rows = lp.A[:, 2:] @ lam  # valid at the vertex to twice the slack (see VERTEX_SLACK)
        assert np.all(lam >= 0) and np.all(rows >= lp.row_lo - shift - 2 * slack)
        assert np.all(rows <= lp.row_hi - shift + 2 * slack)


def test_vertex_forces_of_a_float32_copy_match(tmp_path):
    """Issue 24: the contact forces at the polygons' vertices of a float32 copy of CMU 16_33 (every
    channel rounded to float32, written, read back) equal the original's to 1e-4 body weights.
    With the walk's own lambda (the default) they move by up to 0.67 body weights (frame 83), and the
    torque coefficients baked from them by 2.4 times their size (benchmarks/physics_float32_stages.py)."""
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "benchmarks"))
    from physics_converge import float32_copy

    from retime.motion import load_motion
    from retime.motion.files import save_motion
    from retime.physics.constants import G
    from retime.physics.model.dynamics import dynamics_terms

    clip = os.path.join(os.path.dirname(__file__), "..", "src", "retime", "data", "cmu", "16_33.amc")
    save_motion(load_motion(clip), tmp_path / "orig.bvh")
    float32_copy(tmp_path / "orig.bvh", tmp_path / "f32.bvh")
    sets = []
    for name in ("orig.bvh", "f32.bvh"):
        pd = dynamics_terms(load_motion(tmp_path / name)).combine()
        opts = R.RegionOptions(workers=1, body_weight=float(pd.total_mass) * G, v_max=64.0, unique_vertex_forces=True)
        sets.append(R.compute_regions(pd, opts, frames=np.arange(0, 100)))
    ra, rb = sets
    moved = 0.0
    for i in range(ra.n_frames):
        assert ra.polygon(i).shape == rb.polygon(i).shape
        if ra.polygon_lam(i).size:
            moved = max(moved, float(np.abs(ra.polygon_lam(i) - rb.polygon_lam(i)).max()))
    assert moved <= 1e-4 * ra.body_weight
