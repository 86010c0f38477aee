"""The time-optimal physical timing (retime.physics.timing.fastest): known answers."""
from __future__ import annotations

import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.physics import regions as R  # noqa: E402
from retime.physics.timing.fastest import fastest_timing  # noqa: E402

G = 9.81


@pytest.mark.parametrize("g_new", [G / 4, 2 * G])
def test_a_free_fall_has_one_timing_and_it_is_the_fastest(g_new):
    pd = ps.free_fall(g_source=G, g_new=g_new)
    rs = R.compute_regions(pd, R.RegionOptions(relax=False, workers=1))
    ft = fastest_timing(rs)
    S = pd.times[-1]
    assert ft.duration == pytest.approx(S * np.sqrt(G / g_new), rel=1e-6)
    np.testing.assert_allclose(ft.speed, np.sqrt(g_new / G), rtol=1e-6)


def _boxes(times, vmax, umax):
    """Regions |u| <= umax, 0 <= v <= vmax[i] (counter-clockwise rectangles)."""
    verts = []
    for vm in vmax:
        verts += [[-umax, 0.0], [umax, 0.0], [umax, vm], [-umax, vm]]
    return SimpleNamespace(times=times, offsets=np.arange(0, 4 * len(times) + 1, 4), verts=np.array(verts))


def test_a_speed_limit_is_met_bang_bang():
    """Speed limit v <= 4 except v <= 1 at the middle frame, |p''| <= U: the fastest timing brakes
    and accelerates as hard as allowed, v(s) = min(4, 1 + 2 U |s - s_mid|) (Bobrow)."""
    fps, U = 240.0, 3.0
    times = np.arange(0, 721) / fps
    mid = 360
    vmax = np.full(len(times), 4.0)
    vmax[mid] = 1.0
    ft = fastest_timing(_boxes(times, vmax, U))
    s = np.linspace(0, times[-1], 200001)
    v = np.minimum(4.0, 1.0 + 2 * U * np.abs(s - times[mid]))
    exact = np.trapezoid(1.0 / np.sqrt(v), s) if hasattr(np, "trapezoid") else np.trapz(1.0 / np.sqrt(v), s)
    assert ft.duration == pytest.approx(exact, rel=2e-3)
    np.testing.assert_allclose(ft.speed ** 2, np.minimum(4.0, 1.0 + 2 * U * np.abs(times - times[mid])), atol=0.03)


def test_a_blocked_clip_says_where():
    times = np.arange(0, 50) / 120.0
    vmax = np.full(len(times), 4.0)
    rs = _boxes(times, vmax, 3.0)
    rs.verts[4 * 20:4 * 21, 1] += 10.0  # frame 20 needs v >= 10, out of reach under |p''| <= 3
    ft = fastest_timing(rs)
    assert not np.isfinite(ft.duration) and 0 <= ft.blocked_frame <= 20
