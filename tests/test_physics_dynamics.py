"""Path dynamics: checked against analytic answers, Pinocchio and momentum finite differences."""
import copy
import re

import numpy as np
import pinocchio as pin
import pytest

from retime.physics.model.body import default_body
from chain import chain_terms, chain_tree  # benchmarks/chain.py: the Fig. 12 chains
from retime.physics.model.dynamics import dynamics_terms, path_dynamics, reference_forces
from retime.physics.model.path import path_samples
from _pinocchio_ref import pinocchio_state, to_pinocchio
from retime.motion.quat import quat_to_matrix
from retime.physics.model.tree import (FIXED, FREE, SPHERICAL, TreeModel, generalized_forces, kinematics,
                                 points_jacobian_transpose, project,
                                 wrenches)


def random_tree(rng, parents, jtypes):
    nb = len(parents)
    A = rng.normal(size=(nb, 3, 3))
    inertia = np.einsum("nij,nkj->nik", A, A) * 0.05 + 0.01 * np.eye(3)
    return TreeModel([f"j{i}" for i in range(nb)], parents, jtypes, rng.normal(size=(nb, 3)) * 0.3,
                     rng.uniform(0.5, 5, nb), rng.normal(size=(nb, 3)) * 0.1, inertia)


def random_state(rng, tree, n):
    quats = rng.normal(size=(n, tree.n_bodies, 4))
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    return rng.normal(size=(n, 3)), quats, rng.normal(size=(n, tree.nv)), rng.normal(size=(n, tree.nv))


@pytest.fixture(scope="module")
def jump_terms(jump):
    return dynamics_terms(jump)


def test_inverse_dynamics_matches_pinocchio_rnea():
    rng = np.random.default_rng(1)
    tree = random_tree(rng, [-1, 0, 1, 2, 0, 4, 0, 6, 7, 7],
                       [FREE, SPHERICAL, SPHERICAL, FIXED, SPHERICAL, SPHERICAL, FIXED, SPHERICAL, SPHERICAL, SPHERICAL])
    g = np.array([0.3, -9.81, 1.2])
    root, quats, qd, qdd = random_state(rng, tree, 6)
    tau = generalized_forces(tree, root, quats, qd, qdd, g)
    model, vmap = to_pinocchio(tree, g)
    data = model.createData()
    for i in range(len(tau)):
        q, v, a = pinocchio_state(tree, model, root[i], quats[i], qd[i], qdd[i])
        ref = pin.rnea(model, data, q, v, a)[vmap]
        assert np.allclose(tau[i], ref, rtol=1e-10, atol=1e-9 * np.abs(ref).max())


def test_terms_are_rnea_pieces():
    """a = M q', b = M q'' + C q', c = g(q): each against Pinocchio's mass matrix and RNEA."""
    rng = np.random.default_rng(2)
    tree = random_tree(rng, [-1, 0, 1, 1, 3], [FREE, SPHERICAL, SPHERICAL, SPHERICAL, SPHERICAL])
    root, quats, qd, qdd = random_state(rng, tree, 3)
    kin = kinematics(tree, root, quats, qd, qdd)
    W = wrenches(tree, kin)
    g = np.array([0.0, -9.81, 0.0])
    abc = project(tree, kin.R, kin.o, np.stack([W[:, 0], W[:, 1], np.einsum("nkbs,k->nbs", W[:, 2:], g)], 1))
    model, vmap = to_pinocchio(tree, g)
    data = model.createData()
    for i in range(3):
        q, v, a = pinocchio_state(tree, model, root[i], quats[i], qd[i], qdd[i])
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.allclose(abc[i, 0], (M @ v)[vmap], atol=1e-9)
        assert np.allclose(abc[i, 2], pin.computeGeneralizedGravity(model, data, q)[vmap], atol=1e-9)
        model.gravity = pin.Motion.Zero()
        assert np.allclose(abc[i, 1], pin.rnea(model, data, q, v, a)[vmap], atol=1e-9)
        model.gravity = pin.Motion(g, np.zeros(3))


def test_point_jacobian_transpose_matches_pinocchio_frames():
    rng = np.random.default_rng(3)
    tree = random_tree(rng, [-1, 0, 1, 2, 0, 4], [FREE, SPHERICAL, FIXED, SPHERICAL, SPHERICAL, SPHERICAL])
    root, quats, qd, qdd = random_state(rng, tree, 4)
    kin = kinematics(tree, root, quats, qd, qdd)
    bodies, local = [3, 5, 0], rng.normal(size=(3, 3)) * 0.2
    x = kin.o[:, bodies] + np.einsum("npij,pj->npi", kin.R[:, bodies], local)
    dirs = rng.normal(size=(3, 2, 3))
    N = points_jacobian_transpose(tree, kin.R, kin.o, bodies, x, dirs)
    model, vmap = to_pinocchio(tree)
    frames = [model.addFrame(pin.Frame(f"p{k}", b + 1, 0, pin.SE3(np.eye(3), local[k]), pin.FrameType.OP_FRAME))
              for k, b in enumerate(bodies)]
    data = model.createData()
    for i in range(4):
        q, _, _ = pinocchio_state(tree, model, root[i], quats[i], qd[i], qdd[i])
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for k, fid in enumerate(frames):
            assert np.allclose(data.oMf[fid].translation, x[i, k])
            J = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
            for e in range(2):
                assert np.allclose(N[i, :, 2 * k + e], (J.T @ dirs[k, e])[vmap], atol=1e-12)


def pendulum(length=0.8, mass=2.0, radius=0.03):
    inertia = np.diag([1, 0, 1]) * mass * length ** 2 / 12 + np.diag([1, 2, 1]) * mass * radius ** 2 / 4
    return TreeModel(["pendulum"], [-1], [SPHERICAL], np.zeros((1, 3)), [mass], [[0.0, -length / 2, 0.0]],
                     inertia[None])


def test_pendulum_torques_are_analytic():
    """A rod swinging about z: tau_z = I_pivot theta'' + m g (l/2) sin(theta), split into a, b, c."""
    L, m = 0.8, 2.0
    tree = pendulum(L, m)
    I_pivot = m * L * L / 3 + m * 0.03 ** 2 / 4
    s = np.linspace(0, 2, 9)
    theta, dtheta, ddtheta = 0.7 * np.sin(3 * s), 2.1 * np.cos(3 * s), -6.3 * np.sin(3 * s)
    quats = np.zeros((len(s), 1, 4))
    quats[:, 0, 2], quats[:, 0, 3] = np.sin(theta / 2), np.cos(theta / 2)
    qd = np.zeros((len(s), 3))
    qdd = np.zeros((len(s), 3))
    qd[:, 2], qdd[:, 2] = dtheta, ddtheta
    kin = kinematics(tree, None, quats, qd, qdd)
    W = wrenches(tree, kin)
    a, b, cy = (project(tree, kin.R, kin.o, W[:, [k]])[:, 0] for k in (0, 1, 3))
    c = -9.81 * cy
    assert np.allclose(a[:, 2], I_pivot * dtheta)
    assert np.allclose(b[:, 2], I_pivot * ddtheta)
    assert np.allclose(c[:, 2], m * 9.81 * L / 2 * np.sin(theta))
    assert np.allclose(a[:, :2], 0, atol=1e-12) and np.allclose(c[:, :2], 0, atol=1e-12)
    # the centripetal force pulls along the rod and has no moment about the pivot: b_xy = 0
    assert np.allclose(b[:, :2], 0, atol=1e-12)


def free_body_path(times, g=np.array([0.0, -9.81, 0.0])):
    """A box tossed through the air, spinning about its long principal axis (torque-free)."""
    p = np.array([0.1, 1.0, -0.3]) + np.outer(times, [0.5, 3.0, 1.0]) + 0.5 * np.outer(times ** 2, g)
    angle = 4.0 * times  # about the body z axis
    quats = np.zeros((len(times), 1, 4))
    axis = np.array([0.0, 0.0, 1.0])
    quats[:, 0, :3] = np.sin(angle / 2)[:, None] * axis
    quats[:, 0, 3] = np.cos(angle / 2)
    return p, quats


def test_free_fall_root_terms_and_only_ballistic_timing():
    m = 3.0
    inertia = np.diag([0.2, 0.3, 0.1])
    tree = TreeModel(["box"], [-1], [FREE], np.zeros((1, 3)), [m], [[0.0, 0.0, 0.0]], inertia[None])
    fps = 200.0
    times = np.arange(61) / fps
    p, quats = free_body_path(times)
    path = path_samples(fps, p, quats, tree.jtype, tree.vidx, tree.nv)
    kin = kinematics(tree, path.root_pos, path.quats, path.qd, path.qdd)
    W = wrenches(tree, kin)
    gy = -9.81
    a, b, c = (project(tree, kin.R, kin.o, W[:, [k]])[:, 0] for k in (0, 1, 3))
    c = c * gy
    R = quat_to_matrix(path.quats[:, 0])
    inner = slice(5, -5)
    # c = -m g in the body frame (the support must push up with m |g|), no moment
    assert np.allclose(np.linalg.norm(c[:, :3], axis=1), m * 9.81)
    assert np.allclose(np.einsum("nji,nj->ni", R, c[:, :3] * 0 + np.array([0, m * 9.81, 0]))[inner], c[inner, :3])
    assert np.allclose(c[:, 3:], 0, atol=1e-9)
    # a = M q' = (m R^T p', I w); b + c = 0: the original timing is ballistic
    vel = np.array([0.5, 3.0, 1.0]) + np.outer(times, [0, gy, 0])
    assert np.allclose(a[inner, :3], m * np.einsum("nji,nj->ni", R, vel)[inner], rtol=1e-6, atol=1e-6)
    assert np.allclose(a[inner, 3:], inertia @ [0, 0, 4.0], atol=1e-6)
    assert np.allclose((b + c)[inner], 0, atol=1e-5)
    # with gravity g' the only timing whose root wrench vanishes is p'' = 0, p'^2 = g'/g
    for scale in (0.25, 1.0, 2.0):
        for i in range(8, 50, 7):
            A = np.column_stack([a[i], b[i]])
            sol, *_ = np.linalg.lstsq(A, -scale * c[i], rcond=None)
            assert np.allclose(sol, [0.0, scale], atol=1e-6)


def test_root_wrench_equals_momentum_rate_of_change(jump):
    """Independent of Pinocchio: total force and moment on the root (b + c, original timing) equal
    the rate of change of linear and angular momentum computed from positions and orientations by
    central differences, minus gravity."""

    body = default_body(jump.skeleton)
    tree = body.tree(jump.skeleton)
    h = 1e-4
    s0 = (np.array([60, 144, 252]) + 0.37) / jump.fps  # away from the spline knots (frames)
    times = np.concatenate([s0 - 2 * h, s0 - h, s0, s0 + h, s0 + 2 * h])
    path = path_samples(jump.fps, jump.root_positions, jump.rotations, tree.jtype, tree.vidx, tree.nv, times=times)
    kin = kinematics(tree, path.root_pos, path.quats, path.qd, path.qdd)
    W = wrenches(tree, kin)
    total = (W[:, 1] + np.einsum("nkbs,k->nbs", W[:, 2:], [0, -9.81, 0])).sum(axis=1)  # (n, 6) world
    k = len(s0)
    R, o = kin.R, kin.o
    com = o + np.einsum("nbij,bj->nbi", R, body.com)
    m = body.mass

    def momentum(i0, i1):
        vc = (com[i1] - com[i0]) / (2 * h)
        P = (m[:, None] * vc).sum(0)
        cm = 0.5 * (com[i0] + com[i1])
        dR = np.einsum("bij,bkj->bik", R[i1], R[i0]) - np.einsum("bij,bkj->bik", R[i0], R[i1])
        w = np.stack([dR[:, 2, 1], dR[:, 0, 2], dR[:, 1, 0]], -1) / (4 * h)  # from R_dot R^T
        Rm = R[i0 + k]
        Iw = np.einsum("bij,bjk,blk->bil", Rm, body.inertia, Rm)
        L = (np.cross(cm, m[:, None] * vc) + np.einsum("bij,bj->bi", Iw, w)).sum(0)
        return P, L

    for q in range(k):
        Pm, Lm = momentum(q, q + 2 * k)  # at s0 - h
        Pp, Lp = momentum(q + 2 * k, q + 4 * k)  # at s0 + h
        weight = m.sum() * 9.81
        force = (Pp - Pm) / (2 * h) - m.sum() * np.array([0, -9.81, 0])
        moment = (Lp - Lm) / (2 * h) - np.cross((m[:, None] * com[q + 2 * k]).sum(0), [0, -9.81 * 1.0, 0]) * 1.0
        assert np.allclose(total[q + 2 * k, :3], force, atol=2e-3 * weight)
        assert np.allclose(total[q + 2 * k, 3:], moment, atol=2e-3 * weight)


def test_recombination_equals_recomputation(jump, jump_terms):
    factors = {"lfemur": 10.0, "head": 0.5}
    g = (3.0, -4.0, 1.0)
    fast = jump_terms.combine(gravity=g, mass_factors=factors, friction=0.8)
    body = copy.deepcopy(jump_terms.body)
    for name, f in factors.items():
        j = body.index(name)
        body.mass[j] *= f
        body.inertia[j] *= f
    slow = dynamics_terms(jump, body=body, reference=False).combine(gravity=g, friction=0.8)
    for key in ("a", "b", "c", "N"):
        x, y = getattr(fast, key), getattr(slow, key)
        assert np.allclose(x, y, rtol=1e-9, atol=1e-9 * np.abs(y).max()), key
    assert fast.total_mass == pytest.approx(slow.total_mass)
    assert np.all(fast.contact == slow.contact)


def test_path_dynamics_interface(jump, jump_terms):
    d = jump_terms.combine()
    n, nv = d.a.shape
    assert n == jump.n_frames and nv == 6 + 3 * 28  # CMU: 2 fixed hip joints
    assert d.b.shape == d.c.shape == (n, nv) and d.N.shape == (n, nv, 32)
    assert d.contact.shape == (n, 4) and d.contact.dtype == bool
    assert d.n_root == 6 and np.all(d.tau_lo[:6] == 0) and np.all(d.tau_hi[:6] == 0)
    assert np.all(d.tau_hi[6:] > 0) and np.allclose(d.tau_lo, -d.tau_hi)
    assert len(d.dof_names) == nv and d.dof_names[6] == "lfemur:x"
    # the root carries the body's weight: |c_root force| = m g
    assert np.allclose(np.linalg.norm(d.c[:, :3], axis=1), d.total_mass * 9.81)
    # columns of a point not in contact are zero
    off = ~d.contact[:, 0]
    assert off.any() and np.all(d.N[off][:, :, :8] == 0)
    # reference forces reproduce the reference torques and respect the limits
    assert np.allclose(d.torques(0.0, 1.0, d.lambda_ref), d.tau_ref)
    assert np.all(d.lambda_ref >= 0)
    assert np.all(np.abs(d.tau_ref[:, 6:]) <= d.tau_hi[6:])
    # in stance the contact forces explain the root wrench up to mocap noise
    stance = d.contact.any(1)
    resid = np.linalg.norm(d.tau_ref[stance, :3], axis=1) / (d.total_mass * 9.81)
    assert np.median(resid) < 0.05


def test_sub_frame_samples_agree_with_frames(jump):
    coarse = path_dynamics(jump.frames(slice(0, 60)), samples_per_frame=1)
    fine = path_dynamics(jump.frames(slice(0, 60)), samples_per_frame=4)
    assert len(fine.times) == 4 * 59 + 1
    assert np.allclose(fine.times[::4], coarse.times)
    for key in ("a", "b", "c"):
        assert np.allclose(getattr(fine, key)[::4], getattr(coarse, key), atol=1e-8)
    # in between, the terms are continuous: a midpoint lies near the average of its neighbours
    mid = 0.5 * (coarse.c[10] + coarse.c[11])
    assert np.linalg.norm(fine.c[42] - mid) < 0.05 * np.linalg.norm(mid)


def test_path_derivatives_are_tangent_derivatives():
    """q(s + h) = integrate(q(s), q' h + q'' h^2 / 2) + O(h^3) on the manifold (Pinocchio's Lie
    group integrator, free-flyer and spherical joints)."""
    rng = np.random.default_rng(4)
    tree = random_tree(rng, [-1, 0, 1, 0], [FREE, SPHERICAL, FIXED, SPHERICAL])
    F = 20
    quats = rng.normal(size=(F, 4, 4)) * 0.3 + np.array([0, 0, 0, 1.0])
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    quats[:, 2] = [0, 0, 0, 1]
    root = rng.normal(size=(F, 3))
    model, _ = to_pinocchio(tree)
    errors = []
    for h in (1e-2, 1e-3):
        s = np.array([0.2, 0.2 + h, 0.33, 0.33 + h])
        P = path_samples(30.0, root, quats, tree.jtype, tree.vidx, tree.nv, times=s)
        err = 0.0
        for i in (0, 2):
            q0, v, a = pinocchio_state(tree, model, P.root_pos[i], P.quats[i], P.qd[i], P.qdd[i])
            q1, _, _ = pinocchio_state(tree, model, P.root_pos[i + 1], P.quats[i + 1], P.qd[i], P.qdd[i])
            err = max(err, np.abs(pin.difference(model, pin.integrate(model, q0, v * h + a * h * h / 2), q1)).max())
        errors.append(err)
    assert errors[1] < errors[0] / 500  # third order


def test_reference_forces_are_nonnegative_least_squares():
    from scipy.optimize import nnls

    rng = np.random.default_rng(5)
    n, nv, K = 20, 30, 32
    N = rng.normal(size=(n, nv, K))
    N[::3, :, 16:] = 0
    w = rng.normal(size=(n, nv)) * 3
    lam = reference_forces(w, N, 6, ridge=0.0 + 1e-12)
    weight = np.ones(nv)
    weight[:6] = 100
    for i in range(n):
        act = np.flatnonzero(np.any(N[i] != 0, axis=0))
        ref = nnls(N[i][:, act] * weight[:, None], w[i] * weight, maxiter=2000)[0]
        f = lambda x: np.sum(((N[i][:, act] @ x - w[i]) * weight) ** 2)  # noqa: E731
        assert f(lam[i, act]) <= f(ref) * (1 + 1e-6) + 1e-9
        assert np.all(lam[i] >= 0) and np.all(lam[i, np.setdiff1d(np.arange(K), act)] == 0)


def test_chain_matches_pinocchio():
    terms = chain_terms(10, n_frames=12, fps=30.0)
    d = terms.combine(gravity=(0.0, -9.81, 0.0))
    assert d.n_root == 0 and d.N.shape == (12, 30, 0) and np.all(d.tau_hi > 0)
    tree = chain_tree(10)
    model, vmap = to_pinocchio(tree)
    data = model.createData()
    from chain import chain_path

    P = path_samples(30.0, None, chain_path(10, 12, 30.0), tree.jtype, tree.vidx, tree.nv)
    for i in range(12):
        q, v, a = pinocchio_state(tree, model, np.zeros(3), P.quats[i], P.qd[i], P.qdd[i])
        assert np.allclose(d.b[i] + d.c[i], pin.rnea(model, data, q, v, a)[vmap], atol=1e-9)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.allclose(d.a[i], (M @ v)[vmap], atol=1e-9)


def test_short_and_non_rigid_motions(jump):
    d = path_dynamics(jump.frames(slice(100, 104)))
    assert d.a.shape[0] == 4 and np.all(np.isfinite(d.a)) and np.all(np.isfinite(d.tau_hi))
    from retime.errors import RetimeError

    with pytest.raises(RetimeError, match="at least 4 frames"):
        path_dynamics(jump.frames(slice(0, 3)))
    stretched = jump.replace(translations=jump.translations.copy())
    stretched.translations[7, 3] *= 1.1  # the left knee slides along the femur in frame 7: made rigid, reported
    terms = dynamics_terms(stretched, reference=False)
    assert any("'ltibia' stretches: its offset moves by up to 4." in n and "frame 7" in n
               for n in terms.conform_notes), terms.conform_notes
    stretched.translations[7, 3] *= 1.3  # 43 %, with the foot on the floor: refused, with the figures and what to do
    with pytest.raises(RetimeError, match=r"moves 'l(foot|toes)' by 1\d\.\d cm at frame 7, where it is on the floor"
                                          r".*'ltibia' stretches: its offset moves by up to 1\d\.\d cm at frame 7 "
                                          r"\(\d+% of its 39.7 cm bone\).*re-export"):
        path_dynamics(stretched)


def _slide(motion, joint, frames, angle_deg, length_gain):
    """The joint's offset turned by up to ``angle_deg`` about the parent's z axis and lengthened by up
    to ``length_gain`` over ``frames`` (a smooth bump, zero outside): a Perception Neuron joint that
    slides over its parent's bone."""
    from scipy.spatial.transform import Rotation

    out = motion.replace(translations=motion.translations.copy())
    bump = np.zeros(motion.n_frames)
    bump[frames] = np.sin(np.linspace(0, np.pi, len(frames))) ** 2
    for f in np.nonzero(bump)[0]:
        turn = Rotation.from_euler("z", angle_deg * bump[f], degrees=True).as_matrix()
        out.translations[f, joint] = turn @ motion.translations[f, joint] * (1 + length_gain * bump[f])
    return out


def test_a_sliding_joint_is_made_rigid_unless_it_moves_a_foot_on_the_floor(jump):
    """The issue's Perception Neuron file: the foot joint's offset moves by 10.6 cm while its length
    only goes from 40.4 to 44.3 cm. Said apart (a slide, with both figures), made rigid with a
    warning while the foot is in the air (16_06 is in flight at frames 256-295), refused with the
    figure when the rigid bones would move the foot where it stands on the floor."""
    from retime.errors import RetimeError

    foot = jump.skeleton.index("lfoot")
    in_air = _slide(jump, foot, np.arange(256, 296), 13.0, 0.09)
    warnings = dynamics_terms(in_air, reference=False).conform_warnings
    note = next(n for n in warnings if "'lfoot' slides" in n)
    assert float(re.search(r"moves the feet by at most ([\d.]+) cm where they are on the floor", note).group(1)) < 5
    moved, short, long_, turn = (float(x) for x in re.search(
        r"moves by up to ([\d.]+) cm.*changes ([\d.]+) to ([\d.]+) cm, its direction by up to (\d+) degrees",
        note).groups())
    bone = 100 * np.linalg.norm(jump.skeleton.offsets[foot]) * jump.skeleton.meters_per_unit  # 43.9 cm
    assert short == pytest.approx(bone, abs=0.3) and long_ == pytest.approx(1.09 * bone, abs=0.3)
    assert turn == pytest.approx(13, abs=1.5) and 9 < moved < 12
    from retime.physics.api import physics_warp

    summary = physics_warp(in_air, scale=0.7).report["summary"]  # physics says it as a warning, not a note
    assert any("'lfoot' slides" in w for w in summary["warnings"])
    assert not any("slides" in n for n in summary["conform_notes"])
    on_floor = _slide(jump, foot, np.arange(40, 80), 13.0, 0.09)  # standing before the jump
    with pytest.raises(RetimeError, match=r"moves 'l(foot|toes)' by ([6-9]|1\d)\.\d cm at frame (4\d|5\d|6\d|7\d), "
                                          r"where it is on the floor \(physics allows 5 cm\).*'lfoot' slides"):
        path_dynamics(on_floor)


def test_noise_band_is_finite_beside_large_differences():
    """The noise band's running RMS: the filter's running sum leaves slightly negative residues
    after a stretch of large values (here -1e-9 on a 1e3-scale difference), whose square root
    warned 'invalid value encountered in sqrt' (an OpenNI/Kinect file) and was NaN."""
    from types import SimpleNamespace

    from retime.physics.model.dynamics import DynamicsTerms

    rng = np.random.default_rng(0)
    n, nr = 3000, 6
    diff = np.zeros((n, nr))
    diff[:1500] = rng.normal(size=(1500, nr)) * 1e3
    fake = SimpleNamespace(tree=SimpleNamespace(n_root=nr, mass=np.ones(1)), contact=np.ones((n, 1), dtype=bool),
                           fps=120.0, samples_per_frame=1)
    abc = np.zeros((n, 3, nr))
    abc[:, 1] = diff
    b_noise = DynamicsTerms._noise(fake, abc, np.zeros((n, nr)), np.ones(1))
    assert np.isfinite(b_noise).all() and (b_noise >= 0).all()
    assert b_noise[-1000:].max() < 1e-3  # far from the large values the band is about zero
