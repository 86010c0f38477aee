"""BVH files in the styles different exporters write, checked against an independent matrix FK."""
import itertools

import numpy as np
import pytest

from _foundation_ref import bvh_text, ref_fk
from retime.errors import FormatError
from retime.motion import end_site_positions, forward_kinematics, load_motion, save_bvh

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


def random_bvh(seed, names=None, six_everywhere=False, partial_rotations=False, n_frames=7):
    """A random hierarchy with random per-joint channel layouts and random frame values."""
    rng = np.random.default_rng(seed)
    n = len(names) if names else int(rng.integers(2, 9))
    names = names or [f"joint{k}" for k in range(n)]
    parents, path = [-1], [0]  # joints numbered depth first, as a file lists them
    for k in range(1, n):
        d = int(rng.integers(0, len(path)))
        parents.append(path[d])
        path = path[: d + 1] + [k]
    offsets = rng.normal(scale=10.0, size=(n, 3))
    channels = []
    for j in range(n):
        order = ORDERS[int(rng.integers(0, 6))]
        if partial_rotations and j > 0:
            order = order[: int(rng.integers(0, 4))]  # 0 to 3 rotation channels
        rot = [a + "rotation" for a in order]
        pos = [a + "position" for a in ORDERS[int(rng.integers(0, 6))]]
        if j == 0 or six_everywhere:
            chans = pos + rot if rng.random() < 0.8 else rot + pos
        else:
            chans = rot
        channels.append(chans)
    n_ch = sum(len(c) for c in channels)
    values = rng.uniform(-170, 170, size=(n_frames, n_ch))
    col = 0
    for chans in channels:  # positions: plausible lengths
        for c in chans:
            if c.endswith("position"):
                values[:, col] = rng.normal(scale=20.0, size=n_frames)
            col += 1
    leaves = [j for j in range(n) if j not in parents]
    end_sites = [(j, rng.normal(scale=5.0, size=3)) for j in leaves]
    return names, parents, offsets, channels, values, end_sites


def check_against_reference(path, names, parents, offsets, channels, values, end_sites, fps=None):
    m = load_motion(path)
    assert m.skeleton.names == list(names)
    assert list(m.skeleton.parents) == list(parents)
    assert m.n_frames == values.shape[0]
    if fps is not None:
        assert m.fps == pytest.approx(fps, rel=1e-9)
    rv = np.round(values, 6)  # what the file holds
    ref_pos, ref_rot = ref_fk(parents, np.round(offsets, 6), channels, rv)
    pos, _ = forward_kinematics(m)
    np.testing.assert_allclose(pos, ref_pos, atol=1e-9)
    if end_sites:
        ends = end_site_positions(m)
        by_joint = {j: k for k, (j, _) in enumerate(m.skeleton.end_sites)}
        for j, off in end_sites:
            want = ref_pos[:, j] + np.einsum("fab,b->fa", ref_rot[:, j], np.round(off, 6))
            np.testing.assert_allclose(ends[:, by_joint[j]], want, atol=1e-9)
    return m


@pytest.mark.parametrize("seed", range(12))
def test_random_hierarchies_and_rotation_orders(seed, tmp_path):
    spec = random_bvh(seed)
    path = tmp_path / "a.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5]))
    check_against_reference(path, *spec)


@pytest.mark.parametrize("seed", range(6))
def test_position_channels_on_every_joint(seed, tmp_path):
    """MotionBuilder, Xsens and Perception Neuron write 6 channels on every joint."""
    spec = random_bvh(100 + seed, six_everywhere=True)
    path = tmp_path / "six.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5]))
    m = check_against_reference(path, *spec)
    assert all(len(c) == 6 for c in m.skeleton.channels)


@pytest.mark.parametrize("seed", range(6))
def test_one_two_or_no_rotation_channels(seed, tmp_path):
    spec = random_bvh(200 + seed, partial_rotations=True)
    path = tmp_path / "partial.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5]))
    check_against_reference(path, *spec)


@pytest.mark.parametrize("newline", ["\n", "\r", "\r\n", "mixed"])
@pytest.mark.parametrize("indent", ["\t", "  ", "", " \t"])
def test_line_ends_and_indentation(newline, indent, tmp_path):
    spec = random_bvh(7)
    text = bvh_text(*spec[:5], end_sites=spec[5], indent=indent)
    if newline == "mixed":
        lines = text.split("\n")
        text = "".join(ln + ("\r\n", "\n", "\r")[k % 3] for k, ln in enumerate(lines))
    else:
        text = text.replace("\n", newline)
    path = tmp_path / "a.bvh"
    path.write_bytes(text.encode())
    check_against_reference(path, *spec)


def test_mixamo_and_3dsmax_joint_names(tmp_path):
    names = ["mixamorig:Hips", "mixamorig:Spine", "Bip01 L Thigh", "Bip01 L Calf", "mixamorig:LeftArm", "Left Hand (1)"]
    spec = random_bvh(11, names=names)
    path = tmp_path / "names.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5]))
    m = check_against_reference(path, *spec)
    assert m.skeleton.index("Bip01 L Thigh") == 2
    out = tmp_path / "out.bvh"
    save_bvh(m, out)
    assert load_motion(out).skeleton.names == names


@pytest.mark.parametrize("word", ["End Site", "End site", "END SITE", "end site"])
@pytest.mark.parametrize("brace_on_line", [False, True])
def test_braces_on_joint_lines_and_end_site_spellings(word, brace_on_line, tmp_path):
    spec = random_bvh(13)
    path = tmp_path / "a.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5], end_site_word=word, brace_on_joint_line=brace_on_line))
    m = check_against_reference(path, *spec)
    assert len(m.skeleton.end_sites) == len(spec[5])


def test_braces_and_offsets_squeezed_onto_lines(tmp_path):
    text = ("HIERARCHY\nROOT Hips{ OFFSET 0 0 0\nCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n"
            "JOINT Spine{OFFSET 0 10 0 CHANNELS 3 Zrotation Yrotation Xrotation\n".replace(" CHANNELS", "\nCHANNELS")
            + "End Site { OFFSET 0 5 0 } } }\nMOTION\nFrames: 2\nFrame Time: 0.0333333\n"
            "1 2 3 90 0 0 0 0 0\n1 2 3 0 0 0 90 0 0\n")
    path = tmp_path / "squeezed.bvh"
    path.write_text(text)
    m = load_motion(path)
    assert m.skeleton.names == ["Hips", "Spine"] and m.fps == 30.0
    pos, _ = forward_kinematics(m)
    ends = end_site_positions(m)
    np.testing.assert_allclose(pos[0], [[1, 2, 3], [-9, 2, 3]], atol=1e-12)  # Rz90 sends +y to -x
    np.testing.assert_allclose(ends[0, 0], [-14, 2, 3], atol=1e-12)
    np.testing.assert_allclose(ends[1, 0], [-4, 12, 3], atol=1e-12)  # Spine's Rz90 turns the end site


@pytest.mark.parametrize("frame_time,fps", [("0.0333333", 30.0), ("0.00833333", 120.0), ("0.008333", 120.0),
                                            ("0.04", 25.0), ("1", 1.0), ("0.00416667", 240.0),
                                            ("0.0333667", 1 / 0.0333667), ("0.05", 20.0), ("0.123", 1 / 0.123)])
def test_any_frame_time(frame_time, fps, tmp_path):
    spec = random_bvh(17)
    text = bvh_text(*spec[:5], end_sites=spec[5]).replace("Frame Time: 0.03333333", f"Frame Time:\t{frame_time}")
    path = tmp_path / "a.bvh"
    path.write_text(text)
    check_against_reference(path, *spec, fps=fps)


def test_trailing_blank_lines_and_spaces(tmp_path):
    spec = random_bvh(19)
    path = tmp_path / "a.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5]).replace("\n", "  \n") + "\n\n   \n\t\n")
    check_against_reference(path, *spec)


def test_declared_frames_fewer_than_data_uses_declared(tmp_path):
    spec = random_bvh(23, n_frames=9)
    path = tmp_path / "a.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5], frames_declared=6))
    names, parents, offsets, channels, values, ends = spec
    m = check_against_reference(path, names, parents, offsets, channels, values[:6], ends)
    assert m.n_frames == 6


def test_declared_frames_more_than_data_is_a_clear_error(tmp_path):
    spec = random_bvh(29, n_frames=5)
    path = tmp_path / "a.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5], frames_declared=8))
    with pytest.raises(FormatError) as e:
        load_motion(path)
    msg = str(e.value)
    assert str(path) in msg and "5 of 8 frames" in msg and "truncated" in msg
    assert e.value.line == len(path.read_text().splitlines())  # the last line of the file


def test_joint_without_channels(tmp_path):
    text = ("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
            " JOINT Fixed\n {\n  OFFSET 0 1 0\n  JOINT Tip\n  {\n   OFFSET 0 1 0\n   CHANNELS 1 Xrotation\n"
            "   End Site\n   {\n    OFFSET 0 1 0\n   }\n  }\n }\n}\nMOTION\nFrames: 1\nFrame Time: 0.1\n0 0 0 0 0 0 90\n")
    path = tmp_path / "fixed.bvh"
    path.write_text(text)
    m = load_motion(path)
    assert m.skeleton.channels[1] == [] and m.skeleton.dof[2] == ["rx"]
    np.testing.assert_allclose(end_site_positions(m)[0, 0], [0, 2, 1], atol=1e-12)
    out = tmp_path / "out.bvh"
    save_bvh(m, out)
    np.testing.assert_allclose(end_site_positions(load_motion(out))[0, 0], [0, 2, 1], atol=1e-9)


@pytest.mark.parametrize("seed", range(4))
def test_variety_round_trips_through_the_writer(seed, tmp_path):
    spec = random_bvh(300 + seed, six_everywhere=bool(seed % 2), partial_rotations=True)
    path = tmp_path / "a.bvh"
    path.write_text(bvh_text(*spec[:5], end_sites=spec[5]))
    m = load_motion(path)
    save_bvh(m, tmp_path / "b.bvh")
    m2 = load_motion(tmp_path / "b.bvh")
    np.testing.assert_allclose(forward_kinematics(m2)[0], forward_kinematics(m)[0], atol=1e-5)
    np.testing.assert_allclose(end_site_positions(m2), end_site_positions(m), atol=1e-5)


@pytest.mark.parametrize("frames_word,time_word", [("FRAMES:", "FRAME TIME:"), ("Frames :", "FrameTime:"), ("frames:", "Frame  Time :")])
def test_motion_header_spellings(frames_word, time_word, tmp_path):
    spec = random_bvh(31)
    text = bvh_text(*spec[:5], end_sites=spec[5]).replace("Frames:", frames_word).replace("Frame Time:", time_word)
    path = tmp_path / "a.bvh"
    path.write_text(text)
    check_against_reference(path, *spec, fps=30.0)


def test_reading_closes_the_file():
    """The reader closed no file handle it opened (a ResourceWarning on every BVH and ASF read, seen
    by benchmarks/metamorphic.py; a file left open stays locked on Windows)."""
    import gc
    import warnings

    from retime.data import bundled_path

    gc.collect()  # earlier tests' garbage (sockets, pipes) warns when collected: not this reader's
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_motion(bundled_path("131_01.bvh"))
        load_motion(bundled_path("16_06.amc"))
        gc.collect()
    # only the files read here: another test's thread may still drop a handle of its own meanwhile
    read = ("131_01.bvh", "16_06.amc", "16.asf")
    assert not [w for w in caught if issubclass(w.category, ResourceWarning) and any(n in str(w.message) for n in read)]
