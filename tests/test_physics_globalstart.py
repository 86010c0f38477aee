"""The grid-optimal start of the timing spline (retime.physics.timing.globalstart)."""
from __future__ import annotations

import itertools
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.physics.timing import objective as O  # noqa: E402
from retime.physics.timing.globalstart import _shortest, global_start, speed_levels  # noqa: E402

G = 9.81


def test_banded_shortest_path_equals_brute_force():
    rng = np.random.default_rng(3)
    E, J, band = 3, 5, 1
    full = rng.uniform(0, 1, size=(E, J, J))
    fdur = rng.uniform(0.1, 1, size=(E, J, J))
    fout = rng.uniform(0, 0.5, size=(E, J, J)) * (rng.uniform(size=(E, J, J)) < 0.5)
    full[1, 2, 3] = 1e300  # a forbidden edge
    cost = np.full((E, J, 2 * band + 1), 1e300)
    dur = np.zeros((E, J, 2 * band + 1))
    out = np.zeros((E, J, 2 * band + 1))
    for j in range(J):
        for k in range(2 * band + 1):
            if 0 <= j + k - band < J:
                l = j + k - band
                cost[:, j, k], dur[:, j, k], out[:, j, k] = full[:, j, l], fdur[:, j, l], fout[:, j, l]
    for mu, kappa in ((0.0, 0.0), (0.7, 0.0), (-0.3, 0.0), (0.7, 2.0)):
        best = np.inf
        for path in itertools.product(range(J), repeat=E + 1):
            if any(abs(path[e + 1] - path[e]) > band for e in range(E)):
                continue
            c = sum(full[e, path[e], path[e + 1]] for e in range(E))
            if c >= 1e300:
                continue
            c += kappa * sum(fout[e, path[e], path[e + 1]] for e in range(E))
            best = min(best, c + mu * sum(fdur[e, path[e], path[e + 1]] for e in range(E)))
        path, T, val = _shortest(cost, out, kappa, dur, mu, band)
        assert val == pytest.approx(best, rel=1e-12)
        assert T == pytest.approx(sum(fdur[e, path[e], path[e + 1]] for e in range(E)), rel=1e-12)


def test_speed_levels_hold_one_and_the_ends():
    w = speed_levels(0.05, 12.0, 320)
    assert np.isclose(w, 1.0, atol=1e-12).sum() == 1
    assert w[0] == pytest.approx(0.05, rel=0.01) and w[-1] == pytest.approx(12.0, rel=0.01)
    assert np.all(np.diff(np.log(w)) > 0)


@pytest.fixture(scope="module")
def quarter_jump():
    return ps.quarter_gravity_problem()


def test_free_duration_grid_optimum_plays_a_quarter_gravity_flight_at_half_speed(quarter_jump):
    pd, rs, obj = quarter_jump
    gs = global_start(obj, None)
    inside = (gs.times > pd.times[pd.flight][2]) & (gs.times < pd.times[pd.flight][-3])
    # the only physical flight timing is p'^2 = g'/g: speed 0.5 (to the grid's resolution, 5.5 %)
    assert np.all(np.abs(gs.speed[inside] - 0.5) <= 0.02)
    assert gs.mu == 0.0 and gs.duration > pd.times[-1]


@pytest.mark.parametrize("scale", [0.6, 1.0, 1.4])
def test_fixed_duration_is_met_by_the_price_of_time(quarter_jump, scale):
    pd, rs, obj = quarter_jump
    T = scale * pd.times[-1]
    gs = global_start(obj, T)
    assert gs.duration == pytest.approx(T, rel=0.02) and gs.duration <= T * (1 + 1e-3)
    assert gs.output_times()[-1] == pytest.approx(gs.duration, rel=1e-6)  # tables in single precision


def test_softened_frames_pay_less_for_the_same_violation(quarter_jump):
    from retime.physics.timing.globalstart import soften

    pd, rs, obj = quarter_jump
    i = int(np.flatnonzero(pd.flight)[10])
    point = (0.0, 1.0)  # the original timing: outside the quarter-gravity flight region
    d, _ = O.frame_terms(obj, i, *point)
    soft = soften(obj, np.arange(obj.n_frames) == i, factor=0.05)
    d_soft, _ = O.frame_terms(soft, i, *point)
    assert d > 0 and d_soft == pytest.approx(0.05 * d, rel=1e-9)
    j = i + 1  # other frames are untouched
    assert O.frame_terms(soft, j, *point)[0] == pytest.approx(O.frame_terms(obj, j, *point)[0], rel=1e-12)
