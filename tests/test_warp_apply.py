"""Applying timing curves to motions and arrays: exact frames, SciPy's Slerp, linear translations."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from retime.data import bundled_path
from retime.errors import RetimeError
from retime.motion import load_motion
from retime.warp import TimingCurve, apply_timing, keytime_warp, resample_array, scale_warp, uniform_warp


@pytest.fixture(scope="module")
def jump():
    return load_motion(bundled_path("16_06.amc"))  # 407 frames: an odd count


def test_identity_curve_reproduces_the_motion(jump):
    out = apply_timing(jump, uniform_warp(jump.duration, jump.duration))
    assert out.n_frames == jump.n_frames and out.fps == jump.fps and out.skeleton is jump.skeleton
    np.testing.assert_array_equal(out.rotations, jump.rotations)
    np.testing.assert_array_equal(out.translations, jump.translations)


def test_scale_half_on_odd_frame_count_gives_the_even_frames_exactly(jump):
    assert jump.n_frames % 2 == 1
    out = apply_timing(jump, scale_warp(jump.duration, 0.5, jump.fps))
    assert out.n_frames == (jump.n_frames + 1) // 2
    np.testing.assert_array_equal(out.rotations, jump.rotations[::2])
    np.testing.assert_array_equal(out.translations, jump.translations[::2])


def test_scale_half_on_even_frame_count_drops_only_the_last_frame(jump):
    even = jump.frames(slice(0, 406))
    out = apply_timing(even, scale_warp(even.duration, 0.5, even.fps))
    np.testing.assert_array_equal(out.rotations, even.rotations[:-1:2])


def test_scale_two_interpolates_halfway_like_scipy(jump):
    clip = jump.frames(slice(100, 140))
    out = apply_timing(clip, scale_warp(clip.duration, 2.0, clip.fps))
    assert out.n_frames == 2 * clip.n_frames - 1
    np.testing.assert_array_equal(out.rotations[::2], clip.rotations)
    np.testing.assert_allclose(out.translations[1::2], 0.5 * (clip.translations[:-1] + clip.translations[1:]), atol=1e-15)
    for j in range(clip.skeleton.n_joints):
        ref = Slerp(np.arange(clip.n_frames), Rotation.from_quat(clip.rotations[:, j]))(np.arange(clip.n_frames - 1) + 0.5)
        got = Rotation.from_quat(out.rotations[1::2, j])
        assert (ref.inv() * got).magnitude().max() < 1e-9


@pytest.mark.parametrize("smooth", [False, True])
def test_any_curve_matches_scipy_slerp_per_joint(jump, smooth):
    curve = keytime_warp(jump.duration, [(1.0, 1.6), (2.0, 2.1)], duration=2.7, smooth=smooth)
    out = apply_timing(jump, curve)
    assert out.n_frames == int(round(2.7 * 120)) + 1
    src = curve(curve.frame_times(jump.fps)) * jump.fps  # fractional source frames
    for j in range(0, jump.skeleton.n_joints, 3):
        ref = Slerp(np.arange(jump.n_frames), Rotation.from_quat(jump.rotations[:, j]))(src)
        assert (ref.inv() * Rotation.from_quat(out.rotations[:, j])).magnitude().max() < 1e-9
    for axis in range(3):
        np.testing.assert_allclose(out.translations[:, 0, axis], np.interp(src, np.arange(jump.n_frames), jump.translations[:, 0, axis]), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(out.rotations, axis=-1), 1.0, atol=1e-12)


def test_slerp_takes_the_short_way_across_sign_flips():
    from retime.motion import Motion, Skeleton

    sk = Skeleton(names=["r"], parents=[-1], offsets=[[0, 0, 0]], channels=[["Zrotation"]])
    q = Rotation.from_euler("z", [[0.0], [40.0]], degrees=True).as_quat()
    q[1] *= -1  # same rotation, opposite hemisphere
    m = Motion(sk, q[:, None], np.zeros((2, 1, 3)), fps=1.0)
    out = apply_timing(m, uniform_warp(1.0, 4.0))
    np.testing.assert_allclose(Rotation.from_quat(out.rotations[:, 0]).as_euler("zyx", degrees=True)[:, 0], [0, 10, 20, 30, 40], atol=1e-9)


def test_output_frame_rate_can_differ(jump):
    out = apply_timing(jump, uniform_warp(jump.duration, jump.duration), fps=30.0)
    assert out.fps == 30.0
    assert out.n_frames == int(round(jump.duration * 30)) + 1
    np.testing.assert_array_equal(out.rotations[:-1], jump.rotations[:-1:4][: out.n_frames - 1])


def test_curve_past_the_end_is_refused(jump):
    with pytest.raises(RetimeError, match="past the end"):
        apply_timing(jump, TimingCurve([0, 1], [0, jump.duration + 0.5]))


def test_resample_array_matches_interp():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(50, 3, 2))
    curve = TimingCurve([0, 1, 3], [0, 1.5, 49 / 10], kind="pchip")
    out = resample_array(values, 10.0, curve, 25.0)
    src = curve(curve.frame_times(25.0)) * 10.0
    ref = np.stack([np.interp(src, np.arange(50), values[:, a, b]) for a in range(3) for b in range(2)], axis=1)
    np.testing.assert_allclose(out.reshape(len(src), -1), ref, atol=1e-12)
    frames = resample_array(np.arange(50, dtype=np.uint8), 10.0, uniform_warp(4.9, 4.9))
    np.testing.assert_array_equal(frames, np.arange(50))
