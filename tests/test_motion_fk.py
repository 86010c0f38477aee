"""Forward kinematics and quaternion helpers against hand-computed poses and SciPy."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from retime.motion import Motion, Skeleton, end_site_positions, forward_kinematics
from retime.motion.fk import rest_height
from retime.motion.model import guess_meters_per_unit
from retime.motion.quat import continuous, euler_to_quat, qconj, qmul, qrot, slerp

R3 = ["Zrotation", "Xrotation", "Yrotation"]


def quat(axis, degrees):
    return Rotation.from_euler(axis, degrees, degrees=True).as_quat()


def chain(offsets, parents=None, end_sites=()):
    n = len(offsets)
    parents = list(range(-1, n - 1)) if parents is None else parents
    return Skeleton(names=[f"j{i}" for i in range(n)], parents=parents, offsets=offsets,
                    channels=[R3] * n, end_sites=list(end_sites))


def pose(skeleton, rotations, root=(0, 0, 0)):
    """A one-frame motion with the given local rotations and root position."""
    n = skeleton.n_joints
    rot = np.array(rotations, dtype=float).reshape(1, n, 4)
    tr = np.array(skeleton.offsets, dtype=float).reshape(1, n, 3).copy()
    tr[0, 0] = root
    return Motion(skeleton, rot, tr, fps=30)


I = [0, 0, 0, 1]


def test_rest_pose_positions_are_summed_offsets():
    sk = chain([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 0, 0]])
    pos, ori = forward_kinematics(pose(sk, [I] * 4))
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [0, 1, 0], [0, 3, 0], [1, 3, 0]], atol=1e-12)
    np.testing.assert_allclose(ori[0], [I] * 4, atol=1e-12)


def test_root_rotation_swings_the_whole_chain():
    # root turns 90 deg about z: the x axis goes to y
    sk = chain([[0, 0, 0], [1, 0, 0], [1, 0, 0]])
    pos, _ = forward_kinematics(pose(sk, [quat("z", 90), I, I], root=(5, 0, 0)))
    np.testing.assert_allclose(pos[0], [[5, 0, 0], [5, 1, 0], [5, 2, 0]], atol=1e-12)


def test_rotations_accumulate_down_the_chain():
    # root 90 about z, j1 another 90 about z: j2 = (0,1,0) + Rz(180) (1,0,0) = (-1, 1, 0)
    sk = chain([[0, 0, 0], [1, 0, 0], [1, 0, 0]])
    pos, ori = forward_kinematics(pose(sk, [quat("z", 90), quat("z", 90), I]))
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [0, 1, 0], [-1, 1, 0]], atol=1e-12)
    assert Rotation.from_quat(ori[0, 2]).magnitude() == pytest.approx(np.pi)


def test_mixed_axes_hand_computed():
    # root: 90 about x (y -> z). j1: 90 about z, in j1's frame; j2 offset (0,1,0):
    # local: Rz90 (0,1,0) = (-1,0,0); then root's Rx90 leaves x alone -> j2 = j1 + (-1, 0, 0)
    # j1 = Rx90 (0, 2, 0) = (0, 0, 2)
    sk = chain([[0, 0, 0], [0, 2, 0], [0, 1, 0]])
    pos, ori = forward_kinematics(pose(sk, [quat("x", 90), quat("z", 90), I]))
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [0, 0, 2], [-1, 0, 2]], atol=1e-12)
    # global orientation of j2 = Rx90 Rz90: maps x -> (0, 0, 1)... check with matrices
    m = Rotation.from_euler("x", 90, degrees=True).as_matrix() @ Rotation.from_euler("z", 90, degrees=True).as_matrix()
    np.testing.assert_allclose(Rotation.from_quat(ori[0, 2]).as_matrix(), m, atol=1e-12)


def test_branches_and_end_sites():
    # root with two legs going down-left and down-right, each with an end site (the foot)
    sk = Skeleton(names=["hips", "lleg", "rleg"], parents=[-1, 0, 0],
                  offsets=[[0, 1, 0], [0.2, 0, 0], [-0.2, 0, 0]], channels=[R3] * 3,
                  end_sites=[(1, np.array([0, -1, 0])), (2, np.array([0, -1, 0]))])
    # left leg swings forward 90 deg about x: its foot (0,-1,0) goes to (0,0,-1)
    m = pose(sk, [I, quat("x", 90), I], root=(0, 1, 0))
    pos, ori = forward_kinematics(m)
    np.testing.assert_allclose(pos[0], [[0, 1, 0], [0.2, 1, 0], [-0.2, 1, 0]], atol=1e-12)
    ends = end_site_positions(m, pos, ori)
    np.testing.assert_allclose(ends[0], [[0.2, 1, -1], [-0.2, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(end_site_positions(m), ends)
    assert rest_height(sk) == pytest.approx(1.0)


def test_animated_translation_of_a_child_joint():
    sk = chain([[0, 0, 0], [1, 0, 0]])
    m = pose(sk, [quat("y", 90), I])
    m.translations[0, 1] = [0, 0, 3]  # an animated (stretching) joint, rotated by the root's Ry90
    pos, _ = forward_kinematics(m)
    np.testing.assert_allclose(pos[0, 1], [3, 0, 0], atol=1e-12)


def test_vectorized_frames_equal_frame_by_frame():
    rng = np.random.default_rng(3)
    n, f = 6, 40
    sk = chain(rng.normal(size=(n, 3)), parents=[-1, 0, 1, 1, 3, 0])
    rot = Rotation.random(f * n, random_state=4).as_quat().reshape(f, n, 4)
    tr = np.broadcast_to(sk.offsets, (f, n, 3)).copy()
    tr[:, 0] = rng.normal(size=(f, 3))
    m = Motion(sk, rot, tr, 60)
    pos, ori = forward_kinematics(m)
    for k in (0, 17, 39):
        p1, o1 = forward_kinematics(m.frames(slice(k, k + 1)))
        np.testing.assert_allclose(pos[k], p1[0], atol=1e-12)
        # against plain 4x4 matrices
        glob = [None] * n
        for j in range(n):
            local = np.eye(4)
            local[:3, :3] = Rotation.from_quat(rot[k, j]).as_matrix()
            local[:3, 3] = tr[k, j]
            glob[j] = local if sk.parents[j] < 0 else glob[sk.parents[j]] @ local
            np.testing.assert_allclose(pos[k, j], glob[j][:3, 3], atol=1e-10)
            np.testing.assert_allclose(Rotation.from_quat(ori[k, j]).as_matrix(), glob[j][:3, :3], atol=1e-10)


def test_quaternion_helpers_match_scipy():
    a = Rotation.random(200, random_state=1)
    b = Rotation.random(200, random_state=2)
    v = np.random.default_rng(0).normal(size=(200, 3))
    np.testing.assert_allclose(Rotation.from_quat(qmul(a.as_quat(), b.as_quat())).as_matrix(), (a * b).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(qrot(a.as_quat(), v), a.apply(v), atol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(qconj(a.as_quat())).as_matrix(), a.inv().as_matrix(), atol=1e-12)


@pytest.mark.parametrize("seq", ["xyz", "zxy", "ZXY", "XYZ", "YXZ", "zyx", "x", "Y", "zx", "XZ", "XYX", "zyz"])
def test_euler_to_quat_matches_scipy(seq):
    angles = np.random.default_rng(len(seq)).uniform(-400, 400, size=(64, len(seq)))
    q = euler_to_quat(seq, angles, degrees=True)
    ref = Rotation.from_euler(seq, angles, degrees=True)
    np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), ref.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)


def test_euler_to_quat_handles_more_than_three_axes():
    angles = np.array([[10.0, 20.0, 30.0, 40.0]])
    q = euler_to_quat("ZXYZ", angles, degrees=True)
    ref = Rotation.from_euler("ZXY", angles[:, :3], degrees=True) * Rotation.from_euler("Z", angles[:, 3:], degrees=True)
    np.testing.assert_allclose(Rotation.from_quat(q).as_matrix(), ref.as_matrix(), atol=1e-12)


def test_slerp_matches_scipy_slerp():
    from scipy.spatial.transform import Slerp

    rng = np.random.default_rng(5)
    for k in range(30):
        pair = Rotation.random(2, random_state=k)
        q = pair.as_quat()
        if k % 3 == 0:
            q[1] = -q[1]  # the same rotation with the other sign: still the shorter arc
        if k % 5 == 0:
            q[1] = (Rotation.from_quat(q[0]) * Rotation.from_rotvec([1e-10, 0, 0])).as_quat()  # nearly equal
        w = rng.uniform(0, 1, size=7)
        ours = slerp(np.broadcast_to(q[0], (7, 4)), np.broadcast_to(q[1], (7, 4)), w)
        ref = Slerp([0, 1], Rotation.from_quat(q))(w)
        np.testing.assert_allclose(Rotation.from_quat(ours).as_matrix(), ref.as_matrix(), atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(ours, axis=-1), 1.0, atol=1e-12)
    # end points are the inputs (as rotations)
    q = Rotation.random(2, random_state=99).as_quat()
    np.testing.assert_allclose(slerp(q[0], q[1], 0.0), q[0], atol=1e-12)
    assert abs(abs(np.dot(slerp(q[0], q[1], 1.0), q[1])) - 1) < 1e-12


def test_slerp_is_constant_speed():
    q0, q1 = quat("z", 0), quat("z", 170)
    w = np.linspace(0, 1, 11)
    out = slerp(np.broadcast_to(q0, (11, 4)), np.broadcast_to(q1, (11, 4)), w)
    np.testing.assert_allclose(Rotation.from_quat(out).as_euler("zyx", degrees=True)[:, 0], 170 * w, atol=1e-9)


def test_continuous_removes_sign_flips():
    q = Rotation.from_euler("z", np.linspace(0, 720, 50)[:, None], degrees=True).as_quat()
    q[::3] *= -1
    c = continuous(q)
    assert np.all(np.sum(c[1:] * c[:-1], axis=-1) > 0)
    np.testing.assert_allclose(np.abs(np.sum(c * q, axis=-1)), 1.0, atol=1e-12)


@pytest.mark.parametrize("height,unit", [(1.75, 1.0), (175.0, 0.01), (1750.0, 0.001), (68.0, 0.0254),
                                         (30.0, 0.0254 / 0.45), (17.0, 0.1)])
def test_guess_meters_per_unit(height, unit):
    assert guess_meters_per_unit(height) == pytest.approx(unit)
    assert guess_meters_per_unit(float("nan")) == 1.0


@pytest.mark.parametrize("seq", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_quat_to_euler_matches_scipy_and_survives_gimbal_lock(seq):
    from retime.motion.quat import quat_to_euler, quat_to_matrix

    q = Rotation.random(500, random_state=7).as_quat()
    np.testing.assert_allclose(quat_to_matrix(q), Rotation.from_quat(q).as_matrix(), atol=1e-14)
    np.testing.assert_allclose(quat_to_euler(seq, q, degrees=True), Rotation.from_quat(q).as_euler(seq, degrees=True), atol=1e-9)
    # middle angle at +-90 degrees: the angles are not unique, the rotation must still come back
    ang = np.array([[10, 90, 5], [20, -90, 15], [-170, 90, 45], [40, 89.9999999999, -35], [0, -90, 0]], dtype=float)
    q = euler_to_quat(seq, ang, degrees=True)
    back = euler_to_quat(seq, quat_to_euler(seq, q, degrees=True), degrees=True)
    assert (Rotation.from_quat(back).inv() * Rotation.from_quat(q)).magnitude().max() < 1e-9
