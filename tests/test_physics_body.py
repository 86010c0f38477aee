"""Body model: anthropometric defaults, soles, TOML body files and torque limits."""
import numpy as np
import pytest

from retime.data import bundled_path
from retime.errors import FormatError, RetimeError
from retime.motion import Skeleton, load_motion
from retime.physics.model.body import (DE_LEVA, STRENGTH, default_body, find_feet, read_body, world_frames, write_body)
from retime.physics.model.dynamics import dynamics_terms


def test_de_leva_segments_on_cmu(jump):
    body = default_body(jump.skeleton, motion=jump)
    assert body.total_mass == pytest.approx(70.0)
    kinds = body.segments
    assert kinds["lfemur"] == kinds["rfemur"] == "thigh"
    assert kinds["ltibia"] == "shank" and kinds["lfoot"] == kinds["ltoes"] == "foot"
    assert kinds["lhumerus"] == "upperarm" and kinds["lradius"] == "forearm" and kinds["lwrist"] == "hand"
    assert kinds["root"] == kinds["lhipjoint"] == "pelvis" and kinds["head"] == "head"
    assert kinds["thorax"] == "trunk" and kinds["lclavicle"] == "trunk"
    assert body.mass[body.index("lfemur")] == pytest.approx(DE_LEVA["thigh"][0] * 70.0)
    foot = body.mass[body.index("lfoot")] + body.mass[body.index("ltoes")]
    assert foot == pytest.approx(DE_LEVA["foot"][0] * 70.0)
    for j in range(len(body.names)):
        assert np.linalg.eigvalsh(body.inertia[j]).min() > 0
    # the thigh's centre of mass lies 41 % down the femur, toward the knee
    knee = jump.skeleton.offsets[jump.skeleton.index("ltibia")] * jump.skeleton.meters_per_unit
    assert np.allclose(body.com[body.index("lfemur")], DE_LEVA["thigh"][1] * knee)


@pytest.mark.parametrize("clip, feet, level", [
    ("16_06.amc", ("lfoot", "ltoes"), 0.015),
    ("16_15.bvh", ("lfoot", "ltoes"), 0.015),  # MotionBuilder conversion: rest pose points the feet down
    ("131_01.bvh", ("LeftAnkle", "LeftToe"), 0.03),  # stand-hop-stop: its planted poses differ by ~5 degrees
])
def test_soles_lie_flat_under_the_feet(clip, feet, level):
    motion = load_motion(bundled_path(clip))
    body = default_body(motion.skeleton, motion=motion)
    left = [f for f in body.feet if f.side == "left"][0]
    assert (left.joint, left.toe_joint) == feet
    pos, R = world_frames(motion)
    sk = motion.skeleton
    from retime.physics.model.contacts import corner_positions

    x = corner_positions(body, sk, R, pos)  # (F, 8, 3)
    # while a foot is planted its four corners are level and below the ankle
    for f, foot in enumerate(body.feet):
        j = sk.index(foot.joint)
        speed = np.linalg.norm(np.gradient(pos[:, j], axis=0), axis=1) * motion.fps
        low = pos[:, j, 1] <= np.percentile(pos[:, j, 1], 30)
        still = low & (speed <= np.percentile(speed[low], 30))  # low and slow: the foot is planted
        y = x[still][:, 4 * f:4 * f + 4, 1]
        assert np.median(np.ptp(y, axis=1)) < level
        assert np.all(y.max(axis=1) < pos[still, j, 1])


def test_body_file_round_trip(tmp_path, jump):
    body = default_body(jump.skeleton, motion=jump)
    limits = {"lfemur": np.array([300.0, 200.0, 100.0])}
    path = tmp_path / "body.toml"
    write_body(body, path, torque_limits=limits, note="test body")
    again = read_body(path, jump.skeleton)
    assert np.allclose(again.mass, body.mass) and np.allclose(again.com, body.com)
    assert np.allclose(again.inertia, body.inertia)
    for a, b in zip(again.feet, body.feet):
        assert (a.side, a.joint, a.toe_joint) == (b.side, b.joint, b.toe_joint)
        assert np.allclose(a.heel, b.heel) and np.allclose(a.toe, b.toe)
    assert np.allclose(again.torque_limits["lfemur"], limits["lfemur"])
    assert again.friction == body.friction and again.torque_margin == body.torque_margin


def test_partial_body_file_overrides_defaults(tmp_path, jump):
    path = tmp_path / "body.toml"
    path.write_text("""
mass = 80.0
friction = 0.8
[segments.lfemur]
mass = 20.0
[torque_limits]
ltibia = 150
""", encoding="utf-8")
    body = read_body(path, jump.skeleton, motion=jump)
    default = default_body(jump.skeleton, mass=80.0, motion=jump)
    j = body.index("lfemur")
    assert body.mass[j] == 20.0
    assert np.allclose(body.inertia[j], default.inertia[j] * 20.0 / default.mass[j])  # scaled with the mass
    k = body.index("rfemur")
    assert body.mass[k] == pytest.approx(default.mass[k])
    assert body.friction == 0.8
    terms = dynamics_terms(jump.frames(slice(0, 40)), body=body)
    limits = terms.joint_torque_limits()
    assert np.allclose(limits["ltibia"], 150.0)
    assert np.all(limits["lfemur"] > 0)


def test_default_torque_limits_are_clip_peaks_floored_by_strength(tmp_path, jump):
    """limit = max(margin * peak |tau| + floor, strength of the joint's segment); strength_scale = 0
    leaves the clip's own limits (the paper's rule), and a body file's strength_scale is used."""
    clip = jump.frames(slice(0, 120))
    body = default_body(clip.skeleton, motion=clip)
    terms = dynamics_terms(clip, body=body)
    tau_peak = np.abs(terms.tau_ref).max(axis=0)
    limits = terms.joint_torque_limits()
    strength = dict(zip(body.names, body.strength()))
    assert strength["lfemur"] == pytest.approx(STRENGTH["thigh"] * body.total_mass / 70.0)
    assert strength["lhand"] == pytest.approx(STRENGTH["hand"] * body.total_mass / 70.0)
    assert strength["ltoes"] == pytest.approx(STRENGTH["toe"] * body.total_mass / 70.0)
    for j, name in enumerate(terms.tree.names):
        if name not in limits:
            continue
        k = terms.tree.vidx[j]
        expected = np.maximum(1.5 * tau_peak[k:k + 3] + 2.0, strength[name])
        assert np.allclose(limits[name], expected), name
    assert np.allclose(limits["lhumerus"], strength["lhumerus"])  # a jump's shoulders: strength decides
    path = tmp_path / "weak.toml"
    path.write_text("strength_scale = 0\n", encoding="utf-8")
    weak = read_body(path, clip.skeleton, motion=clip)
    assert weak.strength_scale == 0.0 and not np.any(weak.strength())
    terms0 = dynamics_terms(clip, body=weak)
    for name, lim in terms0.joint_torque_limits().items():
        j = terms0.tree.names.index(name)
        k = terms0.tree.vidx[j]
        assert np.allclose(lim, 1.5 * np.abs(terms0.tau_ref[:, k:k + 3]).max(axis=0) + 2.0), name
    out = tmp_path / "again.toml"
    write_body(weak, out)
    assert read_body(out, clip.skeleton).strength_scale == 0.0


@pytest.mark.parametrize("text, message", [
    ("mass = [", "not a valid TOML"),
    ("weight = 3", "unknown setting 'weight'"),
    ("[segments.tail]\nmass = 1", r"\[segments.tail\] is not a joint"),
    ("[segments.lfemur]\ncom = [1, 2]", "must be a list of 3 numbers"),
    ("[segments.lfemur]\nmass = -1", "must not be negative"),
    ("[segments.lfemur]\ninertia = [1, 1, 1, 5, 0, 0]", "not positive semi-definite"),
    ("friction = 0", "must be positive"),
    ("[feet.left]\njoint = \"nope\"", "is not a joint of the skeleton"),
    ("[torque_limits]\nlfemur = [1, -2, 3]", "must not be negative"),
])
def test_body_file_errors(tmp_path, jump, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FormatError, match=message) as e:
        read_body(path, jump.skeleton)
    assert str(path) in str(e.value)


def test_feet_named_in_body_file(tmp_path):
    names = ["hips", "thigh_a", "shin_a", "paw_a", "thigh_b", "shin_b", "paw_b", "chest", "head"]
    parents = [-1, 0, 1, 2, 0, 4, 5, 0, 7]
    offsets = [[0, 1, 0], [0.1, 0, 0], [0, -0.45, 0], [0, -0.45, 0], [-0.1, 0, 0], [0, -0.45, 0], [0, -0.45, 0],
               [0, 0.3, 0], [0, 0.3, 0]]
    sk = Skeleton(names, parents, offsets, [["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation",
                                             "Yrotation"]] + [["Zrotation", "Xrotation", "Yrotation"]] * 8,
                  end_sites=[(3, np.array([0, -0.05, 0.15])), (6, np.array([0, -0.05, 0.15])),
                             (8, np.array([0, 0.2, 0]))])
    with pytest.raises(RetimeError, match=r"two-legged character.*\[feet.left\]"):
        find_feet(sk)
    path = tmp_path / "body.toml"
    path.write_text('[feet.left]\njoint = "paw_a"\n[feet.right]\njoint = "paw_b"\n', encoding="utf-8")
    body = read_body(path, sk)
    assert [f.joint for f in body.feet] == ["paw_a", "paw_b"]
    assert body.segments["shin_a"] == "shank" and body.segments["thigh_b"] == "thigh"
    assert body.total_mass == pytest.approx(70.0)


def test_mass_factors_are_checked(jump):
    body = default_body(jump.skeleton)
    with pytest.raises(RetimeError, match="no segment named 'tail'"):
        body.mass_factor_array({"tail": 2.0})
    with pytest.raises(RetimeError, match="must be positive"):
        body.mass_factor_array({"lfemur": 0.0})
    assert body.mass_factor_array({"lfemur": 10})[body.index("lfemur")] == 10
