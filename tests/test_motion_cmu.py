"""Reading CMU captures: AMC against a BVH conversion of the same capture, BVH against an independent
reader, round trips through BVH, ASF conventions, the AMC fast and slow paths, the shared clips."""
import shutil

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from _foundation_ref import ref_bvh_positions, ref_read_bvh, shared_clip
from retime.data import bundled_path
from retime.motion import end_site_positions, forward_kinematics, load_motion, save_bvh
from retime.motion.asf import read_asf
from retime.motion.bvh import bvh_text, fps_from_frame_time
from retime.motion.fk import rest_height

INCH = 0.0254
CMU_UNIT = INCH / 0.45


@pytest.fixture(scope="module")
def amc_16_15():
    return load_motion(bundled_path("16_15.amc"))


@pytest.fixture(scope="module")
def bvh_16_15():
    return load_motion(bundled_path("16_15.bvh"))


def test_amc_agrees_with_bvh_of_the_same_capture(amc_16_15, bvh_16_15):
    a, b = amc_16_15, bvh_16_15
    assert a.n_frames == b.n_frames == 471
    assert a.fps == b.fps == 120.0
    assert b.skeleton.meters_per_unit == pytest.approx(0.01)  # MotionBuilder wrote centimetres
    pa, oa = forward_kinematics(a)
    pb, ob = forward_kinematics(b)
    common = [n for n in b.skeleton.names if n in a.skeleton.names]
    assert len(common) == 29  # the BVH drops the two zero-length hip joints
    ia = [a.skeleton.index(n) for n in common]
    ib = [b.skeleton.index(n) for n in common]
    scale = b.skeleton.meters_per_unit
    err = np.abs(pa[:, ia] - pb[:, ib] * scale)
    assert err[::4].max() < 2e-5  # metres, on every 4th frame (the converter resampled the others)
    assert err[1::4].max() > 1e-3  # ...and the test can tell frames apart
    # joint frames: the BVH's differ from the ASF's world-aligned ones by a constant rotation per joint
    # (the ASF bone axis), so AMC^-1 * BVH must not change from frame to frame
    for ja, jb in zip(ia, ib):
        rel = Rotation.from_quat(oa[::4, ja]).inv() * Rotation.from_quat(ob[::4, jb])
        assert (rel[0].inv() * rel).magnitude().max() < 5e-5
    # end sites (toes, fingers, head top) agree too
    ea, eb = end_site_positions(a, pa, oa), end_site_positions(b, pb, ob)
    names_a = [a.skeleton.names[j] for j, _ in a.skeleton.end_sites]
    for k, (j, _) in enumerate(b.skeleton.end_sites):
        name = b.skeleton.names[j]
        assert np.abs(ea[::4, names_a.index(name)] - eb[::4, k] * scale).max() < 2e-5, name


def test_bvh_root_offset_is_not_added(bvh_16_15):
    text = bundled_path("16_15.bvh").read_text()
    _, _, offsets, _, _, values, _ = ref_read_bvh(text)
    np.testing.assert_allclose(offsets[0], values[0, :3])  # the OFFSET repeats frame 1's position
    np.testing.assert_allclose(bvh_16_15.root_positions[0], values[0, :3])
    pos, _ = forward_kinematics(bvh_16_15)
    np.testing.assert_allclose(pos[:, 0], values[:, :3], atol=1e-9)


@pytest.mark.parametrize("name", ["16_15.bvh", "131_01.bvh", "02_04.bvh", "131_03.bvh"])
def test_bvh_positions_match_an_independent_reader(name):
    path = bundled_path(name) if name in ("16_15.bvh", "131_01.bvh") else shared_clip(name)
    if path is None:
        pytest.skip(f"{name} is not bundled and /work/shared is absent")
    names, ref = ref_bvh_positions(path)
    m = load_motion(path)
    assert m.skeleton.names == names
    assert m.n_frames == ref.shape[0]
    pos, _ = forward_kinematics(m)
    assert np.abs(pos - ref).max() < 1e-9 * max(1.0, np.abs(ref).max())


def _same_motion(a, b, pos_tol):
    assert a.n_frames == b.n_frames
    assert a.fps == pytest.approx(b.fps, rel=1e-9)
    assert a.skeleton.names == b.skeleton.names
    np.testing.assert_array_equal(a.skeleton.parents, b.skeleton.parents)
    np.testing.assert_allclose(a.skeleton.offsets[1:], b.skeleton.offsets[1:], atol=1e-9)
    angle = (Rotation.from_quat(a.rotations.reshape(-1, 4)).inv() * Rotation.from_quat(b.rotations.reshape(-1, 4))).magnitude()
    assert angle.max() < 1e-6  # 6 printed decimals of a degree
    pa, _ = forward_kinematics(a)
    pb, _ = forward_kinematics(b)
    assert np.abs(pa - pb).max() < pos_tol
    assert [j for j, _ in a.skeleton.end_sites] == [j for j, _ in b.skeleton.end_sites]
    ea, eb = end_site_positions(a), end_site_positions(b)
    assert np.abs(ea - eb).max() < pos_tol


@pytest.mark.parametrize("name", ["16_15.bvh", "131_01.bvh", "16_15.amc", "16_06.amc", "16_33.amc"])
def test_round_trip_through_bvh(name, tmp_path):
    m = load_motion(bundled_path(name))
    out = tmp_path / "out.bvh"
    save_bvh(m, out)
    m2 = load_motion(out)
    height = rest_height(m.skeleton)
    _same_motion(m, m2, pos_tol=1e-6 * height)
    assert m2.skeleton.meters_per_unit == pytest.approx(m.skeleton.meters_per_unit)
    if name.endswith(".amc"):
        assert m2.skeleton.meters_per_unit == 1.0  # AMC-derived BVH is in metres
    # writing again reproduces the same numbers: the round trip is exact to printing precision
    text1 = out.read_text()
    text2 = bvh_text(m2)
    v1, v2 = ref_read_bvh(text1)[5], ref_read_bvh(text2)[5]
    assert np.abs(v1 - v2).max() <= 1.0000001e-6
    assert text1.splitlines()[:40] == text2.splitlines()[:40]


def test_written_bvh_reads_the_same_in_an_independent_reader(tmp_path):
    m = load_motion(bundled_path("16_06.amc"))
    save_bvh(m, tmp_path / "a.bvh")
    names, ref = ref_bvh_positions(tmp_path / "a.bvh")
    pos, _ = forward_kinematics(m)
    assert names == m.skeleton.names
    assert np.abs(pos - ref).max() < 1e-5  # metres


def test_frame_time_snaps_to_the_rate_it_rounds():
    assert fps_from_frame_time("0.00833333") == 120.0
    assert fps_from_frame_time("0.008333") == 120.0
    assert fps_from_frame_time("0.0333333") == 30.0
    assert fps_from_frame_time("0.04") == 25.0
    assert fps_from_frame_time("0.0333667") == pytest.approx(1 / 0.0333667)  # 29.97 Hz stays
    assert fps_from_frame_time("0.0125") == 80.0
    assert fps_from_frame_time("0.012") == pytest.approx(1 / 0.012)  # too few digits to call it 83 Hz
    assert fps_from_frame_time("0.0333") == pytest.approx(1 / 0.0333)


# -- ASF / AMC conventions --------------------------------------------------------------------------
def _asf_lengths(path):
    """bone name -> length in file units, read straight from the text."""
    out, name = {}, None
    for line in path.read_text().splitlines():
        t = line.split()
        if t and t[0] == "name":
            name = t[1]
        elif t and t[0] == "length" and name:
            out[name] = float(t[1])
    return out


def test_asf_units_and_rest_offsets():
    asf = read_asf(bundled_path("16.asf"))
    sk = asf.skeleton
    assert sk.n_joints == 31 and sk.names[0] == "root"
    assert sk.meters_per_unit == 1.0
    assert asf.length_scale == pytest.approx(CMU_UNIT)
    lengths = _asf_lengths(bundled_path("16.asf"))
    # a joint sits at the end of its parent bone: |offset| = parent bone length in metres
    for j in range(1, sk.n_joints):
        parent = sk.names[sk.parents[j]]
        if parent != "root":
            assert np.linalg.norm(sk.offsets[j]) == pytest.approx(lengths[parent] * CMU_UNIT, rel=1e-9)
    assert 1.45 < rest_height(sk) < 1.85
    assert sk.dof[sk.index("ltibia")] == ["rx"]
    assert sk.dof[sk.index("root")] == ["tx", "ty", "tz", "rx", "ry", "rz"]
    assert all(p < j for j, p in enumerate(sk.parents))
    assert sk.limits[sk.index("ltibia")] == [(-10.0, 170.0)]


def test_amc_standing_pose_is_human_sized():
    m = load_motion(bundled_path("16_06.amc"))
    pos, _ = forward_kinematics(m)
    assert m.fps == 120.0 and m.n_frames == 407
    assert 0.85 < pos[0, 0, 1] < 1.15  # pelvis height standing, metres
    feet = [m.skeleton.index(n) for n in ("ltoes", "rtoes")]
    assert np.abs(pos[0, feet, 1]).max() < 0.15


def _write_tiny_asf(path, axis="0 0 90 XYZ", units="length 1\n  angle deg", root_order="TX TY TZ RX RY RZ"):
    path.write_text(f"""# tiny skeleton
:version 1.10
:name tiny
:units
  mass 1.0
  {units}
:documentation
  hand-made
:root
   order {root_order}
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name a
     direction 1 0 0
     length 10
     axis {axis}
    dof rx
    limits (-180.0 180.0)
  end
  begin
     id 2
     name b
     direction 1 0 0
     length 10
     axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root a
    a b
  end
""")


def test_asf_amc_hand_computed(tmp_path):
    """Bone a's axis is turned 90 deg about z, so its rx dof turns it about the world y axis."""
    _write_tiny_asf(tmp_path / "tiny.asf")
    (tmp_path / "tiny_01.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2 3 0 0 0\na 0\n"
                                          "2\nroot 1 2 3 0 0 0\na 90\n")
    m = load_motion(tmp_path / "tiny_01.amc")  # finds tiny.asf beside it
    assert m.skeleton.names == ["root", "a", "b"]
    assert m.fps == 120.0
    pos, _ = forward_kinematics(m)
    s = 10 * INCH  # length 1 -> one unit is an inch
    root = np.array([1, 2, 3]) * INCH
    np.testing.assert_allclose(pos[0], [root, root, root + [s, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(pos[1], [root, root, root + [0, 0, -s]], atol=1e-12)
    ends = end_site_positions(m)
    np.testing.assert_allclose(ends[1, 0], root + [0, 0, -2 * s], atol=1e-12)


def test_asf_radians_and_root_order(tmp_path):
    _write_tiny_asf(tmp_path / "deg.asf")
    _write_tiny_asf(tmp_path / "rad.asf", axis=f"0 0 {float(np.pi / 2)!r} XYZ", units="length 1\n  angle rad",
                    root_order="RX RY RZ TX TY TZ")
    (tmp_path / "deg.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2 3 10 20 30\na 40\n")
    (tmp_path / "rad.amc").write_text(f":FULLY-SPECIFIED\n:RADIANS\n1\nroot {float(np.radians(10))!r} {float(np.radians(20))!r} "
                                      f"{float(np.radians(30))!r} 1 2 3\na {float(np.radians(40))!r}\n")
    a = load_motion(tmp_path / "deg.amc", asf=tmp_path / "deg.asf")
    b = load_motion(tmp_path / "rad.amc", asf=tmp_path / "rad.asf", fps=30)
    assert b.fps == 30.0
    np.testing.assert_allclose(forward_kinematics(a)[0], forward_kinematics(b)[0], atol=1e-12)


def test_amc_slow_path_equals_fast_path(tmp_path):
    """A file whose frames list bones in different orders (still valid) takes the line-by-line path."""
    src = bundled_path("16_06.amc")
    fast = load_motion(src)
    lines = src.read_text().splitlines()
    k = lines.index("3")  # frame 3: swap its root and lowerback lines
    lines[k + 1], lines[k + 2] = lines[k + 2], lines[k + 1]
    shutil.copy(bundled_path("16.asf"), tmp_path / "16.asf")
    (tmp_path / "16_06.amc").write_text("\n".join(lines) + "\n")
    slow = load_motion(tmp_path / "16_06.amc")
    np.testing.assert_array_equal(slow.rotations, fast.rotations)
    np.testing.assert_array_equal(slow.translations, fast.translations)


@pytest.mark.parametrize("newline", ["\n", "\r", "\r\n", "mixed"])
def test_asf_amc_line_ends(newline, tmp_path):
    ref = load_motion(bundled_path("16_33.amc"))
    for name in ("16.asf", "16_33.amc"):
        lines = bundled_path(name).read_text().splitlines()
        if newline == "mixed":
            text = "".join(ln + ("\r\n", "\n", "\r")[i % 3] for i, ln in enumerate(lines))
        else:
            text = newline.join(lines) + newline
        (tmp_path / name).write_bytes(text.encode())
    m = load_motion(tmp_path / "16_33.amc")
    np.testing.assert_array_equal(m.rotations, ref.rotations)
    np.testing.assert_array_equal(m.translations, ref.translations)


# -- the developers' shared clips (skipped in a user's clone) ---------------------------------------
SHARED = [("13_29.amc", 4592, 1.0), ("13_17.amc", 4840, 1.0), ("13_11.amc", 415, 1.0), ("13_39.amc", 351, 1.0),
          ("118_26.amc", 651, 1.0), ("16_09.amc", 496, 1.0), ("02_04.bvh", 484, 0.01),
          ("131_03.bvh", 1102, CMU_UNIT), ("131_01.bvh", 994, CMU_UNIT), ("16_15.bvh", 471, 0.01)]


@pytest.mark.parametrize("name,frames,unit", SHARED)
def test_shared_clips_load(name, frames, unit):
    path = shared_clip(name)
    if path is None:
        pytest.skip("/work/shared is absent")
    m = load_motion(path)
    assert m.n_frames == frames
    assert m.fps == 120.0
    sk = m.skeleton
    assert sk.meters_per_unit == pytest.approx(unit)
    assert 1.3 < rest_height(sk) * sk.meters_per_unit < 1.9
    pos, _ = forward_kinematics(m)
    assert np.all(np.isfinite(pos))
    pelvis = pos[:, 0, 1] * sk.meters_per_unit
    assert 0.5 < np.median(pelvis) < 1.2
    np.testing.assert_allclose(np.linalg.norm(m.rotations, axis=-1), 1.0, atol=1e-12)
