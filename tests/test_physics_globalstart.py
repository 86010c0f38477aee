"""The grid-optimal start of the timing spline (retime.physics.globalstart) and the capture-noise
band of the regions (PathDynamics.b_noise)."""
from __future__ import annotations

import itertools
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import physics_synth as ps  # noqa: E402

from retime.data import bundled_path  # noqa: E402
from retime.motion import load_motion  # noqa: E402
from retime.physics import objective as O  # noqa: E402
from retime.physics import regions as R  # noqa: E402
from retime.physics.dynamics import NOISE_CAP, dynamics_terms  # noqa: E402
from retime.physics.globalstart import _shortest, global_start, speed_levels  # noqa: E402

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


# ------------------------------------------------------------------------------------------------
# capture-noise band

@pytest.fixture(scope="module")
def jump():
    return load_motion(bundled_path("16_06.amc"))


def test_noise_band_is_the_capped_difference_of_two_low_passes(jump):
    terms = dynamics_terms(jump, smoothing=0.05, noise_band=0.1)
    wide = dynamics_terms(jump, smoothing=0.1, noise_band=None, reference=False)
    for masses in (None, {"lfemur": 10.0}):
        pd = terms.combine(mass_factors=masses)
        b_wide = wide.combine(mass_factors=masses, with_reference=False).b
        stance = np.asarray(pd.contact).any(axis=1)
        cap = NOISE_CAP * pd.total_mass * 9.81
        expect = np.minimum(np.abs(pd.b[:, :6] - b_wide[:, :6]), cap)
        np.testing.assert_allclose(pd.b_noise[stance, :6], expect[stance], rtol=1e-9, atol=1e-9)
        assert np.all(pd.b_noise[~stance] == 0.0) and np.all(pd.b_noise[:, 6:] == 0.0)
        assert pd.b_noise[stance, :6].max() > 0.0


def test_noise_band_only_widens_the_regions(jump):
    clip = jump.frames(slice(0, 120))  # the still stance before the jump
    pd = dynamics_terms(clip, smoothing=0.05, noise_band=0.1).combine()
    opts = dict(workers=1, body_weight=pd.total_mass * 9.81)
    tight = R.compute_regions(pd, R.RegionOptions(noise=False, **opts))
    wide = R.compute_regions(pd, R.RegionOptions(noise=True, **opts))
    grew = 0
    for i in range(0, len(pd.times), 7):
        P = tight.polygon(i)
        assert np.all(wide.distances(np.full(len(P), i), P[:, 0], P[:, 1]) <= 1e-6)  # superset
        assert wide.contains(i, (0.0, 1.0))
        grew += R.polygon_area(wide.polygon(i)) > R.polygon_area(P) * (1 + 1e-6)
    assert grew > 0


def test_softened_frames_pay_less_for_the_same_violation(quarter_jump):
    from retime.physics.globalstart import soften

    pd, rs, obj = quarter_jump
    i = int(np.flatnonzero(pd.flight)[10])
    point = (0.0, 1.0)  # the original timing: outside the quarter-gravity flight region
    d, _ = O.frame_terms(obj, i, *point)
    soft = soften(obj, np.arange(obj.n_frames) == i, factor=0.05)
    d_soft, _ = O.frame_terms(soft, i, *point)
    assert d > 0 and d_soft == pytest.approx(0.05 * d, rel=1e-9)
    j = i + 1  # other frames are untouched
    assert O.frame_terms(soft, j, *point)[0] == pytest.approx(O.frame_terms(obj, j, *point)[0], rel=1e-12)
