"""Capture artifacts the physics must not mistake for dynamics: acceleration noise (the noise band
of the regions, PathDynamics.b_noise) and an exporter's leading bind pose."""
from __future__ import annotations

import numpy as np

from retime.motion.quat import slerp
from retime.physics import regions as R
from retime.physics.regions.polygon import polygon_area
from retime.physics.model.dynamics import NOISE_CAP, bind_pose_frames, dynamics_terms


def test_noise_band_is_the_local_rms_of_the_difference_of_two_low_passes(jump):
    terms = dynamics_terms(jump, smoothing=0.05, noise_band=0.1)
    wide = dynamics_terms(jump, smoothing=0.1, noise_band=None, reference=False)
    half = int(round(0.1 * jump.fps))
    for masses in (None, {"lfemur": 10.0}):
        pd = terms.combine(mass_factors=masses)
        b_wide = wide.combine(mass_factors=masses, with_reference=False).b
        stance = np.asarray(pd.contact).any(axis=1)
        cap = NOISE_CAP * pd.total_mass * 9.81
        diff = np.minimum(np.abs(pd.b[:, :6] - b_wide[:, :6]), cap)
        for i in range(0, len(diff), 9):
            window = diff[max(0, i - half):i + half + 1]  # zeros beyond the ends
            expect = np.minimum(np.sqrt(np.sum(window ** 2, axis=0) / (2 * half + 1)), cap)
            got = pd.b_noise[i, :6]
            np.testing.assert_allclose(got, expect if stance[i] else 0.0, rtol=1e-9, atol=1e-9 * cap)
        assert np.all(pd.b_noise[:, 6:] == 0.0) and pd.b_noise[stance, :6].max() > 0.0


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
        grew += polygon_area(wide.polygon(i)) > polygon_area(P) * (1 + 1e-6)
    assert grew > 0




def _with_bind_pose(m, blend=3):
    """m preceded by an identity rest pose and ``blend`` frames swinging into its first pose."""
    rest = np.zeros_like(m.rotations[:1])
    rest[..., 3] = 1.0
    rest[0, 0] = m.rotations[0, 0]  # the root keeps its orientation
    steps = [slerp(rest[0], m.rotations[0], (k + 1) / (blend + 1)) for k in range(blend)]
    rot = np.concatenate([rest, np.array(steps), m.rotations])
    tr = np.concatenate([m.translations[:1].repeat(blend + 1, axis=0), m.translations])
    return m.replace(rotations=rot, translations=tr)


def test_bind_pose_frames_are_found_and_held_out_of_the_dynamics(jump):
    assert bind_pose_frames(jump) == 0
    bound = _with_bind_pose(jump)
    k = bind_pose_frames(bound)
    assert 3 <= k <= 5
    pd = dynamics_terms(bound, smoothing=0.05).combine()
    clean = dynamics_terms(jump, smoothing=0.05).combine()
    # after the held frames and the low-pass's reach the dynamics are those of the clean clip
    i = k + 24
    np.testing.assert_allclose(pd.b[i + 4:i + 40], clean.b[i:i + 36], rtol=1e-6, atol=1e-6 * np.abs(clean.b).max())
    assert np.abs(pd.b[:k + 8]).max() <= 2 * np.abs(clean.b[:8 + 4]).max() + 1e-9
