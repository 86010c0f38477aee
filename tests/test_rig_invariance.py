"""Every rig, every exporter: the same performance written as another rig or exporter would write it
(turned to another up axis, in other units, renamed, under a dummy root, with 6-channel joints)
gets the same timing curve from linear, guided and physics retiming. Metamorphic: no expected
numbers, only the original's own curve. Also each detection and each message."""
from pathlib import Path

import numpy as np
import pytest

from retime.data import bundled_path
from retime.errors import RetimeError
from retime.guided import guided_warp
from retime.motion import Motion, Skeleton, load_motion, save_bvh
from retime.motion import variants as V
from retime.motion.conform import conform
from retime.motion.frame import UNITS
from retime.motion.rig import part_of, side_and_part
from retime.physics.api import physics_warp
from retime.warp import scale_warp

DEV = Path(__file__).resolve().parents[2] / "shared" / "data" / "bvh-dev"
need_dev = pytest.mark.skipif(not DEV.is_dir(), reason="../shared/data/bvh-dev is not beside the repository")

VARIANTS = {
    "z-up": lambda m: V.turn_up(m, "+z"),
    "-z-up": lambda m: V.turn_up(m, "-z"),
    "x-up": lambda m: V.turn_up(m, "+x"),
    "mm": lambda m: V.rescale(m, m.skeleton.meters_per_unit / UNITS["mm"]),
    "inches": lambda m: V.rescale(m, m.skeleton.meters_per_unit / UNITS["in"]),
    "metres": lambda m: V.rescale(m, m.skeleton.meters_per_unit),
    "mixamo": lambda m: V.rename(m, "mixamo"),
    "unreal": lambda m: V.rename(m, "unreal"),
    "rigify": lambda m: V.rename(m, "rigify"),
    "kinect": lambda m: V.rename(m, "kinect"),
    "second life": lambda m: V.rename(m, "secondlife"),
    "xsens": lambda m: V.rename(m, "xsens"),
    "3ds max biped": lambda m: V.rename(m, "biped"),
    "cmu": lambda m: V.rename(m, "cmu"),
    "dummy root with the travel": lambda m: V.add_dummy_root(m, share=1.0),
    "static dummy root": lambda m: V.add_dummy_root(m, share=0.0),
    "travel split": lambda m: V.add_dummy_root(m, share=0.5),
    "dummy root with IK targets": lambda m: V.add_dummy_root(m, share=1.0, props=2),
    "6 channels": lambda m: V.six_channels(m),
    "all at once: a Z-up Xsens rig in cm under a dummy root with an IK target":
        lambda m: V.turn_up(V.rename(V.add_dummy_root(V.rescale(m, 100 * m.skeleton.meters_per_unit), share=0.5,
                                                      props=1), "xsens"), "+z"),
}


def _written(motion, tmp_path, name):
    """The variant as a BVH file read back: what a user of that rig would hand retime."""
    path = tmp_path / f"{name.replace(' ', '_')}.bvh"
    save_bvh(motion, path)
    return load_motion(path)


def _curves(motion):
    S = motion.duration
    lin = scale_warp(S, 0.7, motion.fps)
    gui = guided_warp(motion, duration=lin.duration)
    phy = physics_warp(motion, scale=0.7)
    return lin, gui, phy


@pytest.fixture(scope="module")
def jump():
    return load_motion(bundled_path("16_06.amc"))


@pytest.fixture(scope="module")
def jump_curves(jump, tmp_path_factory):
    # the original also goes through a BVH file, so both sides see the same 6-decimal rounding
    original = _written(jump, tmp_path_factory.mktemp("orig"), "orig")
    return original, _curves(original)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_variant_has_the_same_timing(variant, jump_curves, tmp_path):
    original, (lin0, gui0, phy0) = jump_curves
    v = _written(VARIANTS[variant](original), tmp_path, variant)
    assert v.skeleton.frame.limbs is not None
    assert np.isclose(v.skeleton.meters_per_unit * v.skeleton.frame.leg_m / v.skeleton.meters_per_unit,
                      original.skeleton.frame.leg_m, rtol=1e-4)
    lin, gui, phy = _curves(v)
    t = np.linspace(0, lin0.duration, 400)
    frame = 1.0 / original.fps
    assert lin.duration == lin0.duration and np.allclose(lin(t), lin0(t), atol=1e-12)
    # guided: features are positions in the floating base's frame and its height along up
    assert np.abs(gui(t) - gui0(t)).max() < 1e-6
    # physics: the same problem up to rounding; its optimum is flat to a few ms (1e-7 m of rounding moves it up to 0.7 frame)
    assert phy.curve.duration == phy0.curve.duration
    dev = np.abs(phy.curve(t) - phy0.curve(t))
    assert dev.max() < frame and dev.mean() < 0.4 * frame, (dev.max(), dev.mean())
    s, s0 = phy.report["summary"], phy0.report["summary"]
    assert abs(s["feasible_fraction"] - s0["feasible_fraction"]) <= 0.02


def test_variants_are_detected(jump_curves, tmp_path):
    original, _ = jump_curves
    for name, up in (("z-up", "+z"), ("-z-up", "-z"), ("x-up", "+x")):
        v = _written(VARIANTS[name](original), tmp_path, name)
        assert v.skeleton.up == up and v.skeleton.frame.up_confidence > 0.95
    for name, unit in (("mm", "mm"), ("inches", "in"), ("metres", "m")):
        v = _written(VARIANTS[name](original), tmp_path, name)
        assert v.skeleton.frame.unit == unit and v.skeleton.frame.unit_confidence == "sure"
    v = _written(VARIANTS["static dummy root"](original), tmp_path, "dummy")
    c = conform(v)
    assert c.removed_roots == ["Reference"] and c.motion.skeleton.n_joints == original.skeleton.n_joints
    assert any("dummy root 'Reference'" in n for n in c.notes())


def test_structure_finds_the_limbs_when_names_say_nothing(jump, tmp_path):
    sk = jump.skeleton
    anonymous = Motion(Skeleton([f"j{k}" for k in range(sk.n_joints)], sk.parents, sk.offsets, sk.channels,
                                sk.end_sites, dof=sk.dof), jump.rotations, jump.translations, jump.fps)
    v = _written(anonymous, tmp_path, "anonymous")
    limbs = v.skeleton.frame.limbs
    assert limbs.how == "structure"
    named = jump.skeleton.frame.limbs
    for side in ("left", "right"):
        assert limbs.legs[side][2] == named.legs[side][2]  # the same foot joint, on the same side
    assert v.skeleton.up == "+y" and v.skeleton.frame.unit == "m"
    r = physics_warp(v, scale=0.7)
    assert r.report["summary"]["feasible_fraction"] > 0.9


def _quadruped(tmp_path):
    """A four-legged animal walking in place: a horizontal spine, four 3-bone legs, neck and tail."""
    names = ["pelvis", "spine", "chest", "neck", "head"]
    parents = [-1, 0, 1, 2, 3]
    offsets = [[0, 0, 0], [0, 0, 0.3], [0, 0, 0.3], [0, 0.1, 0.2], [0, 0.05, 0.15]]
    for k, (attach, x) in enumerate([(0, 0.12), (0, -0.12), (2, 0.12), (2, -0.12)]):
        base = len(names)
        names += [f"leg{k}a", f"leg{k}b", f"leg{k}c"]
        parents += [attach, base, base + 1]
        offsets += [[x, 0, 0], [0, -0.3, 0], [0, -0.3, 0.0]]
    F = 60
    channels = [["Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"]] + \
               [["Zrotation", "Xrotation", "Yrotation"]] * (len(names) - 1)
    sk = Skeleton(names, parents, offsets, channels, end_sites=[(len(names) - 1, np.array([0, -0.05, 0]))])
    rot = np.zeros((F, len(names), 4))
    rot[..., 3] = 1
    t = np.arange(F) / 30
    swing = 0.3 * np.sin(2 * np.pi * t)
    for k in range(4):
        j = 5 + 3 * k
        sign = 1 if k in (0, 3) else -1
        rot[:, j, 0] = np.sin(sign * swing / 2)
        rot[:, j, 3] = np.cos(sign * swing / 2)
    tr = np.broadcast_to(np.asarray(offsets, dtype=float), (F, len(names), 3)).copy()
    tr[:, 0] = [0, 0.62, 0]
    path = tmp_path / "dog.bvh"
    save_bvh(Motion(sk, rot, tr, 30.0), path)
    return path


def test_a_quadruped_gets_the_biped_sentence(tmp_path):
    m = load_motion(_quadruped(tmp_path))
    assert m.skeleton.frame.limbs is None and "four legs" in m.skeleton.frame.biped
    with pytest.raises(RetimeError, match="physics-based retiming needs a two-legged character.*four legs"):
        physics_warp(m, scale=0.7)
    g = guided_warp(m, duration=0.7 * m.duration)  # guided still works on it
    assert g.duration == pytest.approx(0.7 * m.duration, abs=1 / m.fps)


def test_guided_on_a_quadruped_says_it_looks_for_no_jump_flights(tmp_path, capsys):
    """The steady pace pull keeps a jump's flight at its natural speed from the feet's contacts;
    a rig without two feet has none to find, so guided plays it at one pace and says why."""
    from retime.cli import main

    out = tmp_path / "out.bvh"
    assert main(["guided", str(_quadruped(tmp_path)), "--scale", "0.7", "-o", str(out), "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "warning: no jump flights looked for" in said and "not a two-legged character" in said
    assert "four legs" in said and "physics" not in said  # why, in guided's words


@pytest.mark.parametrize("name, side, part", [
    ("mixamorig:LeftFoot", "left", "foot"), ("Beta:RightUpLeg", "right", "thigh"), ("Character1_LeftLeg", "left", "shank"),
    ("Bip01 L Foot", "left", "foot"), ("Bip01 R Calf", "right", "shank"), ("FootLeft", "left", "foot"),
    ("lFoot", "left", "foot"), ("thigh_l", "left", "thigh"), ("foot.L", "left", "foot"), ("DEF-shin.R", "right", "shank"),
    ("L_Foot", "left", "foot"), ("LEFT_KNEE", "left", "shank"), ("lfemur", "left", "thigh"), ("rtibia", "right", "shank"),
    ("lShldrBend", "left", "upperarm"), ("rForearmTwist", "right", "forearm"), ("mAnkleLeft", "left", "foot"),
    ("mKneeRight", "right", "shank"), ("calf_r", "right", "shank"), ("ball_l", "left", "toe"),
    ("LeftUpperLeg", "left", "thigh"), ("RightLowerLeg", "right", "shank"), ("upperarm_l", "left", "upperarm"),
    ("lowerarm_r", "right", "forearm"), ("lclavicle", "left", "clavicle"), ("RightShoulder", "right", "clavicle"),
    ("lowerback", None, None), ("LHipJoint", "left", None), ("HEad", None, "head"), ("mixamorig:HeadTop_End", None, None),
    ("mixamorig:LeftHandThumb1", "left", None), ("L_Talus_RIGMESH", "left", None), ("ik_foot_l", "left", None),
])
def test_joint_names_of_every_convention(name, side, part):
    assert part_of(name) == part
    if part is not None:
        assert side_and_part(name)[0] == side


@need_dev
@pytest.mark.parametrize("file, up, unit", [
    ("01_01.bvh", "+y", "cmu"), ("AV_8Walk_Meredith_HVHA_Rep1.bvh", "+y", "in"), ("jesse_dance.bvh", "+y", "cm"),
    ("run.bvh", "+y", "cm"), ("cart.bvh", "+y", "cm"), ("wd2_short_broad_jump.bvh", "+y", "m"),
    ("woddy2_walk_straight_fast.bvh", "+y", "cm"), ("Gangnam Style.bvh", "+y", "cm"), ("samba_dancing.bvh", "+y", "cm"),
    ("cxk.bvh", "+z", "mm"), ("ZombieIdel.bvh", "+y", "cm"), ("file.bvh", "+y", "mm"), ("DAZ3D.bvh", "+y", "cm"),
])
def test_dev_files_up_and_units(file, up, unit):
    m = load_motion(DEV / file)
    assert m.skeleton.up == up and m.skeleton.frame.unit == unit
    assert m.skeleton.frame.limbs is not None and m.skeleton.frame.limbs.how == "names"
    assert 1.1 < m.skeleton.frame.height_m < 1.8 or file.startswith("wd2")  # SNU's rig has no head


@need_dev
def test_unusual_scale_is_kept_and_said():
    m = load_motion(DEV / "jumping.bvh")  # the AnimatedDrawings capture: Z-up, about 0.04 m per unit
    assert m.skeleton.up == "+z" and m.skeleton.frame.unit_confidence == "unusual scale"
    assert 0.035 < m.skeleton.meters_per_unit < 0.045


@pytest.fixture(scope="module")
def dev_originals(tmp_path_factory):
    """file -> (the file written and read back, its physics result at 0.7): each original is solved
    once for all its variants."""
    runs = {}

    def run(file):
        if file not in runs:
            original = _written(load_motion(DEV / file), tmp_path_factory.mktemp("orig"), "orig")
            runs[file] = original, physics_warp(original, scale=0.7)
        return runs[file]
    return run


@need_dev
@pytest.mark.parametrize("file", ["wd2_short_broad_jump.bvh", "jumping.bvh"])
@pytest.mark.parametrize("variant", ["z-up", "inches", "mixamo", "unreal", "dummy root with the travel", "6 channels"])
def test_dev_variants_have_the_same_physics_timing(file, variant, tmp_path, dev_originals):
    original, a = dev_originals(file)
    v = _written(VARIANTS[variant](original), tmp_path, variant)
    b = physics_warp(v, scale=0.7)
    t = np.linspace(0, a.curve.duration, 300)
    dev = np.abs(a.curve(t) - b.curve(t))
    assert dev.max() < 1.0 / original.fps and dev.mean() < 0.4 / original.fps, (dev.max(), dev.mean())
    ga = guided_warp(original, duration=a.curve.duration)
    gb = guided_warp(v, duration=a.curve.duration)
    assert np.abs(ga(t) - gb(t)).max() < 1e-6


def test_radians_are_detected_and_can_be_given(jump, tmp_path):
    path = tmp_path / "deg.bvh"
    save_bvh(jump.frames(slice(0, 120)), path)
    lines = path.read_text().splitlines()
    start = lines.index("MOTION") + 3
    sk = load_motion(path).skeleton
    rot_cols = [k for k, c in enumerate(c for chans in sk.channels for c in chans) if c.endswith("rotation")]
    rows = []
    for ln in lines[start:]:
        v = np.array(ln.split(), dtype=float)
        v[rot_cols] = np.deg2rad(v[rot_cols])
        rows.append(" ".join(f"{x:.9f}" for x in v))
    rad = tmp_path / "rad.bvh"
    rad.write_text("\n".join(lines[:start] + rows) + "\n")
    a, b = load_motion(path), load_motion(rad)
    assert a.skeleton.angles == "deg" and b.skeleton.angles == "rad"
    assert np.allclose(np.abs(np.sum(a.rotations * b.rotations, axis=-1)), 1.0, atol=1e-6)
    assert load_motion(rad, angles="deg").skeleton.angles == "deg"


def test_up_and_units_can_be_given(jump, tmp_path):
    path = tmp_path / "j.bvh"
    save_bvh(jump.frames(slice(0, 60)), path)
    m = load_motion(path, up="-x", units="in")
    assert m.skeleton.up == "-x" and m.skeleton.meters_per_unit == UNITS["in"] and m.skeleton.frame.unit_confidence == "given"
    m = load_motion(path, units="0.04")
    assert m.skeleton.meters_per_unit == 0.04


def test_renderer_and_editor_stand_every_file_up(jump_curves, tmp_path):
    from retime.editor.server import Clip, skeleton_payload
    from retime.viz.render import track_from_motion

    original, _ = jump_curves
    v = _written(VARIANTS["z-up"](original), tmp_path, "zup")
    a, b = track_from_motion(original), track_from_motion(v)
    assert np.allclose(a.positions, b.positions, atol=1e-5)
    pa, _ = skeleton_payload(Clip("a", original, None, None))
    pb, _ = skeleton_payload(Clip("b", v, None, None))
    assert np.allclose(np.frombuffer(pa, "<f4"), np.frombuffer(pb, "<f4"), atol=1e-4)


def test_info_prints_what_was_detected_and_the_floating_base(jump_curves, tmp_path, capsys):
    from retime.cli import main

    original, _ = jump_curves
    path = tmp_path / "zup_dummy.bvh"
    save_bvh(V.six_channels(V.add_dummy_root(V.turn_up(original, "+z"), share=0.5, props=1)), path)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "up        +z (detected, 100% of frames agree)" in out
    assert "units     metres" in out and "sure" in out
    assert "floating base is 'root' (below the dummy root 'Reference')" in out
    assert "IK_Target0" in out and "read as fixed bones" in out
    assert main(["info", str(path), "--up", "y", "--units", "cm"]) == 0
    out = capsys.readouterr().out
    assert "up        +y (given)" in out and "centimetres" in out and "given" in out


# ---------------------------------------------------------------------------------------------
# names never change the body

CONVENTIONS = ["mixamo", "unreal", "rigify", "biped", "kinect", "cmu"]
BUNDLED_RIGS = ["16_06.amc", "131_01.bvh"]  # CMU's ASF skeleton and a cgspeed BVH conversion


def _body(motion):
    from retime.physics.model.body import default_body

    m = conform(motion).motion
    return default_body(m.skeleton, motion=m)


def _assert_same_body(a, b, what):
    """Joint by joint (the names differ): segment kinds, masses, centres of mass, inertias, soles and
    strengths (the torque limits' floor: a Kinect toe, FootLeft, had the foot's)."""
    assert [a.segments[n] for n in a.names] == [b.segments[n] for n in b.names], what
    np.testing.assert_allclose(b.strength(), a.strength(), rtol=1e-9, err_msg=what)
    np.testing.assert_allclose(b.mass, a.mass, rtol=1e-6, atol=1e-6, err_msg=what)
    np.testing.assert_allclose(b.com, a.com, atol=1e-6, err_msg=what)
    np.testing.assert_allclose(b.inertia, a.inertia, atol=1e-7, err_msg=what)
    for fa, fb in zip(a.feet, b.feet):
        assert (fa.side, a.names.index(fa.joint), a.names.index(fa.toe_joint)) == \
            (fb.side, b.names.index(fb.joint), b.names.index(fb.toe_joint)), what
        np.testing.assert_allclose(np.r_[fb.heel, fb.toe], np.r_[fa.heel, fa.toe], atol=1e-6, err_msg=what)


def _rig_files():
    files = [bundled_path(n) for n in BUNDLED_RIGS]
    if DEV.is_dir():
        files += sorted(DEV.glob("*.bvh"))
    return files


@pytest.mark.parametrize("path", _rig_files(), ids=lambda p: p.name)
def test_every_naming_convention_gives_the_same_body(path, tmp_path):
    original = _written(load_motion(path), tmp_path, "orig")
    body = _body(original)
    assert sum(body.segments[n] == "thigh" for n in body.names) >= 2
    for convention in CONVENTIONS:
        renamed = _written(V.rename(original, convention), tmp_path, convention)
        _assert_same_body(body, _body(renamed), f"{path.name} as {convention}")


UNREAL_CMU = {"root": "pelvis", "lowerback": "spine_01", "upperback": "spine_02", "thorax": "spine_03",
              "lowerneck": "neck_01", "upperneck": "neck_02", "head": "head"}
for _s in "lr":
    UNREAL_CMU.update({f"{_s}hipjoint": f"hip_{_s}", f"{_s}femur": f"thigh_{_s}", f"{_s}tibia": f"calf_{_s}",
                       f"{_s}foot": f"foot_{_s}", f"{_s}toes": f"ball_{_s}", f"{_s}clavicle": f"clavicle_{_s}",
                       f"{_s}humerus": f"upperarm_{_s}", f"{_s}radius": f"lowerarm_{_s}", f"{_s}wrist": f"hand_{_s}",
                       f"{_s}hand": f"middle_metacarpal_{_s}", f"{_s}fingers": f"middle_01_{_s}",
                       f"{_s}thumb": f"thumb_01_{_s}"})


def test_a_pelvis_side_bone_named_like_a_hip_is_not_the_thigh(jump, tmp_path):
    """The issue's reproduction: the CMU jump with Unreal names, its pelvis-side hip joints called
    hip_l / hip_r (a thigh word) above thigh_l / thigh_r, gave a right thigh of 5.87 kg, a left one
    of 9.91 kg (the hip bones were taken into the thighs, one on the wrong side), and moved the
    physics timing by 3.9 source frames."""
    import dataclasses

    original = _written(jump, tmp_path, "orig")
    sk = dataclasses.replace(original.skeleton, names=[UNREAL_CMU[n] for n in original.skeleton.names])
    renamed = _written(original.replace(skeleton=sk), tmp_path, "unreal_by_hand")
    a, b = _body(original), _body(renamed)
    _assert_same_body(a, b, "CMU as Unreal, by hand")
    thigh = {n: float(m) for n, m in zip(b.names, b.mass) if b.segments[n] == "thigh"}
    assert set(thigh) == {"thigh_l", "thigh_r"} and thigh["thigh_l"] == pytest.approx(thigh["thigh_r"], rel=0.02)
    assert b.segments["hip_l"] == b.segments["hip_r"] == "pelvis"
    pa, pb = physics_warp(original, scale=0.7), physics_warp(renamed, scale=0.7)
    t = np.linspace(0, pa.curve.duration, 300)
    assert np.abs(pa.curve(t) - pb.curve(t)).max() < 0.5 / original.fps


# ---------------------------------------------------------------------------------------------
# up from gravity and contacts

def _turned_up(motion, variant_up):
    """The up axis a file has after V.turn_up(motion, variant_up), from the file's own up."""
    return V.turned_up(motion.skeleton.up, variant_up)


FLOOR_VARIANTS = {"as written": lambda m: m, "z-up": lambda m: V.turn_up(m, "+z"), "x-up": lambda m: V.turn_up(m, "+x"),
                  "-z-up": lambda m: V.turn_up(m, "-z"), "dummy root": lambda m: V.add_dummy_root(m, share=0.5)}


def _assert_frame_kept(original, variant_name, tmp_path, factor=1.0):
    """The variant (and, with ``factor``, rescaled to other units) reads with the up axis the turn
    gives and the same metres per unit."""
    base = VARIANTS_UNITS(original, factor)
    v = _written(FLOOR_VARIANTS[variant_name](base), tmp_path, f"{variant_name}-{factor:g}")
    expected_up = _turned_up(original, "+z" if variant_name == "z-up" else "+x" if variant_name == "x-up"
                             else "-z" if variant_name == "-z-up" else "+y")
    assert v.skeleton.up == expected_up, (variant_name, factor, v.skeleton.up, expected_up)
    assert v.skeleton.meters_per_unit * factor == pytest.approx(original.skeleton.meters_per_unit, rel=1e-3), \
        (variant_name, factor, v.skeleton.frame.unit, original.skeleton.frame.unit)
    return v


def VARIANTS_UNITS(motion, factor):
    return motion if factor == 1.0 else V.rescale(motion, factor)


@pytest.fixture(scope="module")
def kneeling(tmp_path_factory):
    from floor_poses import kneeling_bow

    # written in inches, as the file was
    return _written(V.rescale(kneeling_bow(), 1 / UNITS["in"]), tmp_path_factory.mktemp("kneel"), "kneel")


def test_a_kneeling_bow_is_read_y_up_in_inches(kneeling, tmp_path):
    """The issue's kneeling and bowing clip (Y-up, inches) was read +z up at 0.034 m per unit (here
    the head goes forward, along +x: +x at 0.039 before the fix). Its knees, shins and insteps rest
    on the floor, the weight over them: +y, inches, under every turn, unit and dummy root."""
    assert kneeling.skeleton.up == "+y" and kneeling.skeleton.frame.unit == "in"
    for name in FLOOR_VARIANTS:
        _assert_frame_kept(kneeling, name, tmp_path)
    for factor in (UNITS["in"] / UNITS["cm"], UNITS["in"] / UNITS["mm"]):
        _assert_frame_kept(kneeling, "z-up", tmp_path, factor)


def test_a_bow_deep_throughout_is_read_y_up(tmp_path):
    """Bowed so deep throughout that the head is ahead of the feet in every frame, with nothing at
    rest on a floor along that axis: the head-above-feet axis stood (+x, as the issue's kneeling
    clip was read), taken for a root-locked body that hangs. Its knees, shins and insteps rest on the
    floor in every frame: +y, inches, under every turn and dummy root."""
    from floor_poses import kneeling_bow

    m = _written(V.rescale(kneeling_bow(least=1.0), 1 / UNITS["in"]), tmp_path, "deep")
    assert m.skeleton.up == "+y" and m.skeleton.frame.unit == "in"
    for name in FLOOR_VARIANTS:
        _assert_frame_kept(m, name, tmp_path)


@pytest.mark.parametrize("name", ["16_15.amc", "16_01.amc", "16_31.amc", "16_33.amc"])
def test_a_root_locked_clip_keeps_its_up_axis(name):
    """Pinned at the root, a body hangs and nothing rests on the floor under its feet, while a
    swinging hand rests at its turning points on a 'wall' (16_01 read +z, 16_31 and 16_33 -x, in
    33-51 % of their frames): the head, above the feet in every frame, keeps +y."""
    from retime.motion import mistakes as M

    path = bundled_path(name) if name == "16_15.amc" else DEV.parent / "cmu" / name
    if not path.exists():
        pytest.skip(f"{path} is absent")
    m = M.root_locked(load_motion(path))
    assert m.skeleton.up == "+y" and m.skeleton.frame.up_confidence > 0.95


@pytest.fixture(scope="module")
def elephant_file(tmp_path_factory):
    from floor_poses import elephant

    return _written(elephant(), tmp_path_factory.mktemp("elephant"), "elephant")


def test_an_elephant_with_biped_names_is_y_up_and_four_legged(elephant_file, tmp_path):
    """The issue's elephant (Y-up, metres, 3ds Max Biped names) was read +x at 0.698 m per unit (here
    +x at 0.46) and physics ran it. Its four feet rest on the floor: +y under every turn and dummy
    root; its hands (the front feet) bear weight as often as its feet, so physics refuses it with
    the two-legged sentence whatever its names, and guided and linear retiming still run on it."""
    m = elephant_file
    assert m.skeleton.up == "+y" and m.skeleton.frame.limbs is None and "four limbs" in m.skeleton.frame.biped
    for name in FLOOR_VARIANTS:
        v = _written(FLOOR_VARIANTS[name](m), tmp_path, name)
        assert v.skeleton.up == _turned_up(m, {"z-up": "+z", "x-up": "+x", "-z-up": "-z"}.get(name, "+y")), name
        assert v.skeleton.frame.limbs is None and "four limbs" in v.skeleton.frame.biped, name
    with pytest.raises(RetimeError, match="physics-based retiming needs a two-legged character.*four limbs"):
        physics_warp(m, scale=0.7)
    g = guided_warp(m, duration=0.7 * m.duration)
    assert g.duration == pytest.approx(0.7 * m.duration, abs=1 / m.fps)
    assert scale_warp(m.duration, 0.7, m.fps).duration == pytest.approx(0.7 * m.duration, abs=1 / m.fps)


@need_dev
@pytest.mark.parametrize("file", sorted(p.name for p in DEV.glob("*.bvh")) if DEV.is_dir() else [])
def test_dev_files_keep_their_up_and_units_turned_rescaled_and_rerooted(file, tmp_path):
    original = _written(load_motion(DEV / file), tmp_path, "orig")
    for name in ("z-up", "x-up", "dummy root"):
        _assert_frame_kept(original, name, tmp_path)
    _assert_frame_kept(original, "as written", tmp_path, original.skeleton.meters_per_unit / UNITS["mm"])


def test_a_body_lying_on_its_back_is_read_y_up(tmp_path):
    """Head level with the feet (read -x before the fix): the back on the floor says +y, under
    every turn and dummy root, in centimetres."""
    from floor_poses import lying

    m = _written(V.rescale(lying(), 1 / UNITS["cm"]), tmp_path, "lying")
    assert m.skeleton.up == "+y" and m.skeleton.frame.unit == "cm"
    for name in FLOOR_VARIANTS:
        _assert_frame_kept(m, name, tmp_path)


def _crouch_with_still_hands(seconds=2.0, fps=30.0):
    """(positions (F, J, 3), parents, the two ankles): a body standing on its feet (y up, metres) and
    crouching 10 cm, its arms out and down sideways to hands that stay still in the world, 16 finger joints
    each (a Rigify rig keyed on its torso and feet, its IK hands left unkeyed): the fingers are the lowest
    points along +z and -z, still, under the centre of mass, and outnumber the resting toes."""
    t = np.arange(int(seconds * fps)) / fps
    hips = np.zeros((len(t), 3))
    hips[:, 1] = 0.95 - 0.05 * (1 - np.cos(2 * np.pi * 0.5 * t))
    joints = [(-1, hips), (0, hips + [0, 0.3, 0]), (1, hips + [0, 0.6, 0])]  # hips, chest, head
    ankles = []
    for side in (1.0, -1.0):
        hip = hips + [0, -0.05, 0.1 * side]
        ankle = np.broadcast_to([0.0, 0.08, 0.1 * side], hip.shape)
        knee = 0.5 * (hip + ankle) + [0.1, 0, 0]
        k = len(joints)
        joints += [(0, hip), (k, knee), (k + 1, ankle), (k + 2, ankle + [0.15, -0.08, 0])]
        ankles.append(k + 2)
        shoulder = hips + [0, 0.35, 0.2 * side]
        hand = np.broadcast_to([-0.05, 0.95, 0.75 * side], hip.shape)  # a little behind the body, as arms hang
        k = len(joints)
        joints += [(1, shoulder), (k, 0.5 * (shoulder + hand)), (k + 1, hand)]
        for finger in range(4):
            for bone in range(4):
                joints.append((k + 2 if bone == 0 else len(joints) - 1,
                               hand + [0.02 * finger - 0.1, -0.02 * bone - 0.01, 0.03 * (bone + 1) * side]))
    return np.stack([p for _, p in joints], axis=1), np.array([p for p, _ in joints]), ankles, fps


def test_a_body_standing_on_its_feet_with_still_hands_is_y_up():
    """The keyed Rigify clip (torso and IK feet keyed, IK hands left still) was read +x up: its still
    fingers, the lowest points sideways, outnumber its resting toes and overruled the head above the
    feet. A floor that never holds a foot does not overrule one the feet stand on; the feet are what
    tells it (without them, the old reading comes back)."""
    from retime.motion.frame import up_from_contacts

    positions, parents, ankles, fps = _crouch_with_still_hands()
    prior = ("+y", 1.0)
    lift = np.median(positions[:, 2] - positions[:, ankles].mean(axis=1), axis=0)
    # the old reading: a floor of still fingers, sideways (+x or z, whichever fingers rest lowest)
    assert up_from_contacts(positions, parents, fps, prior[0], lift, prior[1])[0][1] in "xz"
    assert up_from_contacts(positions, parents, fps, prior[0], lift, prior[1], ankles) == prior
    turned = positions[..., [1, 2, 0]]  # y up -> z up: the rule follows the axes
    lift = np.median(turned[:, 2] - turned[:, ankles].mean(axis=1), axis=0)
    assert up_from_contacts(turned, parents, fps, "+z", lift, 1.0, ankles) == ("+z", 1.0)


def test_rigify_spine_names_give_the_head(jump, tmp_path):
    """Rigify names its neck and head as spine joints (DEF-spine.004 to .006, above the chest DEF-spine.003
    that carries the shoulders): no head was found, so the standing height, one of the two unit cues,
    was measured from the root ("root 0.13 m above the feet" on the keyed Rigify clip). The top of the
    spine above the arms' branch is the head: the same head height as the CMU names give."""
    import dataclasses

    original = _written(jump, tmp_path, "orig")
    rigify = V.rename(original, "rigify")
    spine = {"DEF-Root0": "DEF-spine", "DEF-Lowerback11": "DEF-spine.001", "DEF-Upperback12": "DEF-spine.002",
             "DEF-Thorax13": "DEF-spine.003", "DEF-neck": "DEF-spine.004", "DEF-neck1": "DEF-spine.005",
             "DEF-head": "DEF-spine.006"}
    assert set(spine) <= set(rigify.skeleton.names), rigify.skeleton.names
    sk = dataclasses.replace(rigify.skeleton, names=[spine.get(n, n) for n in rigify.skeleton.names])
    renamed = _written(rigify.replace(skeleton=sk), tmp_path, "rigify_spine")
    frame = renamed.skeleton.frame
    assert renamed.skeleton.names[frame.limbs.head] == "DEF-spine.006"
    assert frame.height_m == pytest.approx(original.skeleton.frame.height_m, rel=1e-6)
    assert (frame.unit, frame.unit_confidence) == (original.skeleton.frame.unit, original.skeleton.frame.unit_confidence)
