"""Synthetic path dynamics with known answers, for the physics tests (no skeleton, no Pinocchio).

A single rigid body of mass m with its centre of mass at the root origin and no rotation, so the
root's generalized force (world = body frame) is m (x' p'' + x'' p'^2) - m g for the force rows and
zero for the moment rows; a foot of four sole corners with four friction-cone edges each maps through
J^T = [I; [r]x]. Two "leg" rows involve the contact forces, two "arm" rows do not. This is the
agreed ``PathDynamics`` layout: tau = a p'' + b p'^2 + c - N lam.
"""
from __future__ import annotations


import numpy as np
from scipy.optimize import nnls

from retime.physics.model.contact_basis import ContactBasis
from retime.physics.model.dynamics import PathDynamics

G = 9.81


def cone_basis(mu=0.5):
    """Four unit edges of the inscribed friction pyramid (y up)."""
    k = mu / np.sqrt(2.0)
    e = np.array([[k, 1, k], [-k, 1, k], [-k, 1, -k], [k, 1, -k]], dtype=float)
    return e / np.linalg.norm(e, axis=1, keepdims=True)


def _contact_columns(r_corners, mu=0.5):
    E = cone_basis(mu)
    cols = []
    for r in r_corners:
        for e in E:
            cols.append(np.r_[e, np.cross(r, e)])
    return np.array(cols).T  # (6, 16)


def _quintic(s0, s1, y0, y1):
    """Coefficients of the quintic with (y, y', y'') = y0 at s0 and y1 at s1 (in s - s0)."""
    h = s1 - s0
    M = np.array([
        [1, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 2, 0, 0, 0],
        [1, h, h ** 2, h ** 3, h ** 4, h ** 5], [0, 1, 2 * h, 3 * h ** 2, 4 * h ** 3, 5 * h ** 4],
        [0, 0, 2, 6 * h, 12 * h ** 2, 20 * h ** 3]], dtype=float)
    return np.linalg.solve(M, np.r_[y0, y1])


def _poly(cf, x, d):
    p = np.polynomial.polynomial.Polynomial(cf)
    for _ in range(d):
        p = p.deriv()
    return p(x)


def jump_path(fps=120.0, vy0=2.0, vx=0.6, height=1.0, t_push=(1.0, 1.6), land=0.5, total=3.0):
    """Root height y(s) and its derivatives for stand - crouch/push - flight - landing - stand."""
    n = int(round(total * fps)) + 1
    s = np.arange(n) / fps
    y, yd, ydd = np.zeros(n), np.zeros(n), np.zeros(n)
    a, b = t_push
    s_land = b + 2 * vy0 / G
    push = _quintic(a, b, [0, 0, 0], [0, vy0, -G])
    landing = _quintic(s_land, s_land + land, [0, -vy0, -G], [0, 0, 0])
    for i, si in enumerate(s):
        if a <= si < b:
            x, cf = si - a, push
        elif b <= si < s_land:
            x = si - b
            y[i], yd[i], ydd[i] = vy0 * x - 0.5 * G * x * x, vy0 - G * x, -G
            continue
        elif s_land <= si < s_land + land:
            x, cf = si - s_land, landing
        else:
            continue
        y[i], yd[i], ydd[i] = _poly(cf, x, 0), _poly(cf, x, 1), _poly(cf, x, 2)
    flight = (s >= b) & (s < s_land)
    # horizontal speed: 0 while standing, vx in flight (smoothstep ramps during push and landing)
    def ramp(x):
        x = np.clip(x, 0.0, 1.0)
        return x * x * (3 - 2 * x), 6 * x * (1 - x)
    up, dup = ramp((s - a) / (b - a))
    down, ddown = ramp((s - s_land) / land)
    xd = vx * (up - down)
    xdd = vx * (dup / (b - a) - ddown / land)
    return s, height + y, yd, ydd, flight, xd, xdd


def rigid_jump(gravity=(0.0, -G, 0.0), mass=70.0, fps=120.0, mu=0.5, vy0=2.0, vx=0.6, limits=None,
               noise=0.0, seed=0, total=3.0):
    """A jumping rigid body as PathDynamics (nv = 6 root + 2 leg + 2 arm rows, K = 16)."""
    s, y, yd, ydd, flight, vxs, vxd = jump_path(fps, vy0, vx, total=total)
    n = len(s)
    g = np.asarray(gravity, dtype=float)
    nv, K = 10, 16
    a = np.zeros((n, nv))
    b = np.zeros((n, nv))
    c = np.zeros((n, nv))
    N = np.zeros((n, nv, K))
    xd = np.stack([vxs, yd, np.zeros(n)], axis=1)
    xdd = np.stack([vxd, ydd, np.zeros(n)], axis=1)
    a[:, :3] = mass * xd
    b[:, :3] = mass * xdd
    c[:, :3] = -mass * g
    rng = np.random.default_rng(seed)
    if noise:
        # mocap-like inconsistency: a spurious angular momentum rate
        b[:, 3:6] = noise * mass * rng.normal(size=(n, 3))
    # leg rows: segment inertia along the vertical plus the contact force's moment about a knee
    a[:, 6] = 0.05 * mass * yd
    b[:, 6] = 0.05 * mass * ydd
    c[:, 6] = -0.05 * mass * g[1]
    a[:, 7] = 0.05 * mass * vxs
    b[:, 7] = 0.05 * mass * vxd
    c[:, 7] = -0.05 * mass * g[0]
    # arm rows (no contact force): inertia and weight of an arm
    a[:, 8] = 0.02 * mass * yd
    b[:, 8] = 0.02 * mass * ydd
    c[:, 8] = -0.02 * mass * g[1] * 0.3
    a[:, 9] = 0.02 * mass * vxs
    b[:, 9] = 0.02 * mass * vxd
    c[:, 9] = -0.02 * mass * g[0] * 0.3 + 0.01 * mass * g[2]
    contact = ~flight
    corners = np.array([[0.12, 0, 0.05], [-0.08, 0, 0.05], [-0.08, 0, -0.05], [0.12, 0, -0.05]])
    for i in range(n):
        if contact[i]:
            r = corners - np.array([0.0, y[i], 0.0])
            J = _contact_columns(r, mu)
            N[i, :6] = J
            N[i, 6] = 0.4 * J[1]  # vertical forces at a 0.4 m lever
            N[i, 7] = 0.4 * J[0]
    tau_lo = np.zeros(nv)
    tau_hi = np.zeros(nv)
    pd = PathDynamics(times=s, a=a, b=b, c=c, N=ContactBasis.from_dense(N), contact=contact[:, None],
                      tau_lo=tau_lo, tau_hi=tau_hi, total_mass=mass, gravity=g, fps=fps)
    if limits is None:
        tau0 = original_torques_nnls(pd)
        peak = np.max(np.abs(tau0[:, 6:]), axis=0)
        limits = 1.3 * peak + 1.0
    pd.tau_lo = np.r_[np.zeros(6), -limits]
    pd.tau_hi = np.r_[np.zeros(6), limits]
    pd.flight = flight  # for the tests: which samples fly
    return pd


def original_torques_nnls(pd):
    """Torques at the original timing with contact forces balancing the root by NNLS."""
    n, nv = pd.a.shape
    out = np.zeros((n, nv))
    for i in range(n):
        rhs = pd.b[i, :6] + pd.c[i, :6]
        lam = np.zeros(pd.N.shape[2])
        if np.any(pd.N[i] != 0):
            lam, _ = nnls(pd.N[i, :6], rhs)
        out[i] = pd.b[i] + pd.c[i] - pd.N[i] @ lam
    return out


def free_fall(g_source=G, g_new=G, mass=60.0, fps=120.0, n=40, vel=(1.0, 2.0, 0.3), noise=0.0, seed=0):
    """A ballistic rigid body recorded under g_source, simulated under g_new (no contact)."""
    s = np.arange(n) / fps
    v0 = np.asarray(vel, dtype=float)
    xd = v0[None, :] + np.outer(s, [0.0, -g_source, 0.0])
    xdd = np.tile([0.0, -g_source, 0.0], (n, 1))
    nv = 6
    a = np.zeros((n, nv))
    b = np.zeros((n, nv))
    c = np.zeros((n, nv))
    a[:, :3] = mass * xd
    b[:, :3] = mass * xdd
    c[:, :3] = -mass * np.array([0.0, -g_new, 0.0])
    if noise:
        rng = np.random.default_rng(seed)
        b[:, 3:] = noise * mass * rng.normal(size=(n, 3))
        b[:, :3] += 0.2 * noise * mass * rng.normal(size=(n, 3))
    pd = PathDynamics(times=s, a=a, b=b, c=c, N=ContactBasis.from_dense(np.zeros((n, nv, 16))),
                      contact=np.zeros((n, 1), bool), tau_lo=np.zeros(nv), tau_hi=np.zeros(nv), total_mass=mass,
                      gravity=np.array([0.0, -g_new, 0.0]), fps=fps)
    pd.vel = v0  # for the tests: the initial velocity
    return pd


def quarter_gravity_problem():
    """(pd, regions, baked objective) of a rigid jump recorded under g and retimed under g/4 with
    the API's default weights: its flight must play at sqrt(1/4)."""
    from retime.physics.timing import objective as O
    from retime.physics import regions as R

    ref = rigid_jump()
    pd = rigid_jump(gravity=(0.0, -G / 4, 0.0), limits=ref.tau_hi[6:])
    rs = R.compute_regions(pd, R.RegionOptions(workers=1, body_weight=ref.total_mass * G), reference=ref)
    target = ref.b + ref.c - np.einsum("nvk,nk->nv", ref.N, rs.lam0)
    obj = O.bake(pd, rs, target, alpha=10.0, beta=0.1, penalty="l1", gamma=0.03)
    return pd, rs, obj


def frame_lps(pd, frames, widen=0.3):
    """Real frame LPs (the regions' own construction) of ``pd``'s contact frames among ``frames``, the
    rows widened by ``widen`` body weights as a relaxed frame's are, so that (0, 1) is feasible:
    [(frame, lp, least-force weights of its contact columns)]."""
    from retime.physics.regions import RegionOptions, base_bounds
    from retime.physics.regions.forces import force_weights
    from retime.physics.regions.frame_region import _frame_lp, _lp_rows
    from retime.physics.regions.highs_lp import HighsPool

    opts = RegionOptions(workers=1)
    bw = float(pd.total_mass) * G
    lo, hi = base_bounds(pd, opts, bw, 6)
    pool = HighsPool()
    for i in frames:
        a, b, c, N = (np.asarray(x[i], dtype=float) for x in (pd.a, pd.b, pd.c, pd.N))
        act = np.flatnonzero(np.any(N != 0.0, axis=0))
        if len(act) == 0:
            continue
        rows, _ = _lp_rows(N, act, len(a))
        lp = _frame_lp(a, b, c, N, lo - widen * bw, hi + widen * bw, np.zeros(len(a)), act, rows, opts, pool)
        yield i, lp, force_weights(N[:3][:, act], 6)
