"""Post-processing: moving average of the warp and adaptive local averaging of the motion."""
import numpy as np
import pytest

from retime.data import bundled_path
from retime.guided import adaptive_smooth, moving_average
from retime.motion import load_motion
from retime.warp import TimingCurve, apply_timing, uniform_warp


def test_moving_average_keeps_fixed_points_and_order():
    rng = np.random.default_rng(0)
    v = np.cumsum(rng.random(60) * 3 + 0.01)
    out = moving_average(v, 7, fixed=[20, 41])
    for i in (0, 20, 41, 59):
        assert out[i] == v[i]
    assert np.all(np.diff(out) > 0)
    # interior away from fixed points: plain centred mean of 7
    assert out[30] == pytest.approx(v[27:34].mean())
    # shrinking windows next to a fixed point
    assert out[21] == pytest.approx(v[20:23].mean())
    assert np.array_equal(moving_average(v, 1), v)


def test_adaptive_smoothing_is_plain_resampling_without_compression():
    m = load_motion(bundled_path("16_06.amc"))
    curve = uniform_warp(m.duration, 2 * m.duration)  # slower: each frame covers half a source frame
    a = adaptive_smooth(m, curve)
    b = apply_timing(m, curve)
    assert np.array_equal(a.rotations, b.rotations) and np.array_equal(a.translations, b.translations)


def test_adaptive_smoothing_averages_over_the_covered_interval():
    m = load_motion(bundled_path("16_06.amc"))
    k = 6  # six source frames per output frame
    T = (m.n_frames - 1) / k / m.fps
    curve = TimingCurve([0.0, T], [0.0, m.duration])
    out = adaptive_smooth(m, curve)
    f = 20  # output frame 20 covers source frames 120 - 3 .. 120 + 3
    c = f * k
    tr = m.translations[:, 0]
    # integral of the piecewise-linear signal over [c-3, c+3] (trapezoid, exact for linear pieces)
    w = np.array([0.5, 1, 1, 1, 1, 1, 0.5])
    want = (tr[c - 3:c + 4] * w[:, None]).sum(axis=0) / 6
    np.testing.assert_allclose(out.translations[f, 0], want, rtol=1e-9, atol=1e-9)
    q = out.rotations[f]
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0)
    # close to the plain slerp frame (the motion is smooth), but not equal
    plain = apply_timing(m, curve).rotations[f]
    dots = np.abs(np.sum(q * plain, axis=-1))
    assert np.all(dots > 0.99)
