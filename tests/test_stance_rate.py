"""The frame rate from a gait's single-support frames (:mod:`retime.physics.stance_rate`, issue 25):
the residual kernel against SciPy's NNLS, the estimate's exact scaling with time, and walks played
at the wrong Frame Time named ``frame_rate`` with their factor (the dev-data ones skip when
../shared/data is absent)."""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import nnls

from retime.data import bundled_path
from retime.motion import load_motion
from retime.motion import mistakes as M
from retime.physics.check import check_clip
from retime.physics.model.dynamics import RIDGE, dynamics_terms
from retime.physics.plausibility import STANCE_RATE
from retime.physics.stance_rate import RATES, SOLE_ON_FLOOR_M, _bearing_columns, _residuals, sole_on_floor, stance_rate

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def _factor(sentence: str) -> float:
    k, how = re.search(r"plays? (\d+\.\d+)x too (slow|fast)", sentence).groups()
    return float(k) if how == "slow" else 1.0 / float(k)


def test_the_residual_kernel_is_the_nonnegative_least_squares_residual():
    rng = np.random.default_rng(3)
    n, K = 12, 9
    A = rng.normal(size=(n, 6, K))
    A[:, :, 5:] = 0.0  # columns of a foot off the floor: skipped
    b, c = rng.normal(size=(n, 6)), rng.normal(size=(n, 6))
    out = np.zeros((len(RATES), n))
    _residuals(A, b, c, RATES, float(RIDGE), out)
    for i in range(n):
        for k in (0, 7, 15, 30):
            w = RATES[k] ** 2 * b[i] + c[i]
            assert out[k, i] == pytest.approx(nnls(A[i, :, :5], w)[1], rel=1e-6, abs=1e-9)


def test_only_the_sole_corners_on_the_floor_bear():
    # left foot rolled onto its toe (heel corners 2 cm up), right foot flat but for one toe corner
    # just above the tolerance: their columns (4 friction edges a corner) are zeroed, the rest kept
    corners = np.zeros((1, 8, 3))
    corners[0, :, 1] = [0.02, 0.02, 0.0, 0.001, 0.0, 0.002, 0.003, 0.003 + SOLE_ON_FLOOR_M]
    assert sole_on_floor(corners).tolist() == [[False, False, True, True, True, True, True, False]]
    values = np.ones((1, 6, 32))
    kept = _bearing_columns(values, corners)
    assert kept[0, :, :8].sum() == 0 and kept[0, :, 8:16].min() == 1.0
    assert kept[0, :, 16:28].min() == 1.0 and kept[0, :, 28:].sum() == 0
    assert _bearing_columns(np.ones((1, 6, 4)), None).min() == 1.0  # not the feet's corners: left alone


def test_the_median_of_steps_and_its_uncertainty():
    from retime.physics.stance_rate import StanceRate

    agreeing = StanceRate(0.8, 2.0, np.zeros(0), np.array([0.8, 0.8, 0.8, 0.8]))
    assert agreeing.uncertainty == 0.0 and agreeing.steps_beyond(0.8) == 4
    spread = StanceRate(0.9, 2.0, np.zeros(0), np.exp([-0.3, -0.2, -0.1, 0.0, 0.1]))
    # MAD 0.1 in log: 1.4826 * 0.1 * 1.2533 / sqrt(5)
    assert spread.uncertainty == pytest.approx(0.0831, abs=1e-3) and spread.steps_beyond(0.9) == 3
    assert StanceRate(1.2, 0.4, np.zeros(0), np.array([1.2])).uncertainty == float("inf")


def test_a_stance_rate_is_named_when_its_steps_agree_and_cautioned_when_not():
    from retime.physics.plausibility import stance_finding
    from retime.physics.stance_rate import StanceRate

    def rate(steps):
        steps = np.asarray(steps, dtype=float)
        return StanceRate(float(np.exp(np.median(np.log(steps)))), 2.0, np.zeros(0), steps)

    cause, caution = stance_finding(rate([0.82, 0.84, 0.85, 0.86, 0.88]), 120.0)
    assert cause.code == "frame_rate" and caution is None and "too fast" in cause.sentence
    assert "the median of 5 steps" in cause.sentence and "5 of them below 1" in cause.sentence
    # outside the band, but on one step, or on steps spread from 0.5 to 1.5: a caution, not a cause
    for doubtful in ([0.8], [0.5, 0.6, 0.85, 1.3, 1.5]):
        cause, caution = stance_finding(rate(doubtful), 120.0)
        assert cause is None and caution.code == "frame_rate_unconfirmed"
        assert caution.sentence.startswith("frame rate unconfirmed") and "no flight to measure" in caution.sentence
    from retime.physics.plausibility import SourceCheck

    # physics' warning says the caution too
    assert SourceCheck(True, 0.0, 0.0, cautions=[caution]).message() == caution.sentence
    assert SourceCheck(True, 0.0, 0.0).message() == ""
    assert stance_finding(rate([0.97, 1.0, 1.02]), 120.0) == (None, None)  # inside the band: the clip's own
    assert stance_finding(None, 120.0) == (None, None)


def _pendulum_on_one_foot(k: float, fps: float = 100.0, seconds: float = 0.6):
    """A point mass of 70 kg vaulting over one foot as an inverted pendulum (c_h'' = g/h (c_h - p_h),
    height h constant), as the path dynamics of a clip played ``k`` times too slow: its velocity
    terms are 1/k^2 of the real ones. One contact point at p with the friction pyramid's 4 edges;
    root rows: force, then moment about the centre of mass (the root)."""
    from types import SimpleNamespace

    from retime.physics.constants import G
    from retime.physics.model.contacts import friction_edges
    from retime.physics.model.dynamics import PathDynamics

    m, h, p = 70.0, 0.9, np.array([0.0, 0.0, 0.1])
    w = np.sqrt(G / h)
    t = np.arange(int(seconds * fps)) / fps - 0.5 * seconds
    # CoM behind the foot and decelerating, then ahead and accelerating (x); swaying back (z)
    d = np.stack([0.12 * np.sinh(w * t), np.zeros_like(t), -0.04 * np.cosh(w * t)], axis=1)
    com = p + d + np.array([0.0, h, 0.0])
    accel = (G / h) * d
    n = len(t)
    b, c = np.zeros((n, 6)), np.zeros((n, 6))
    b[:, :3] = m * accel / k ** 2
    c[:, 1] = m * G
    edges = friction_edges(0.5)
    N = np.zeros((n, 6, 4))
    N[:, :3] = edges.T[None]
    N[:, 3:] = np.cross(p - com[:, None, :], edges[None]).transpose(0, 2, 1)
    contact = np.zeros((n, 4), bool)
    contact[:, :2] = True  # the left foot alone
    pd0 = PathDynamics(times=t - t[0], a=np.zeros((n, 6)), b=b, c=c, N=N, contact=contact, tau_lo=np.zeros(6),
                       tau_hi=np.zeros(6), total_mass=m, fps=fps)
    return SimpleNamespace(samples_per_frame=1, fps=fps, smoothing=0.05), pd0


@pytest.mark.parametrize("k", [1.0, 0.8, 1.25])
def test_an_inverted_pendulum_on_one_foot_gives_its_time_factor(k):
    # the contact force points from the foot to the centre of mass (no moment about it) only at the
    # true rate: there the residual is zero, anywhere else the foot cannot give the wrench
    terms, pd0 = _pendulum_on_one_foot(k)
    found = stance_rate(terms, pd0)
    assert found.time_factor == pytest.approx(k, rel=0.02)
    # (zero at the grid's rate nearest k: exactly at k = 1, which the grid holds)
    assert found.residual.min() < 0.05 * min(found.residual[0], found.residual[-1])
    if k == 1.0:
        assert found.residual.min() < 1e-9
    assert found.seconds == pytest.approx(0.6)
    assert len(found.steps) == 1 and found.steps[0] == found.time_factor  # one stance: one step


def test_the_stance_rate_scales_with_time_exactly(walk):
    # velocity terms 1/k^2 as large (the clip played k times too slow): each step's rate is k times as
    # large, to rounding, when k is a whole number of the grid's steps (a step whose best rate lay
    # below the grid may come into it, so the median moves by about k, not exactly)
    terms = dynamics_terms(walk)
    pd0 = terms.combine()
    k = float(RATES[3] / RATES[0])
    own, slow = stance_rate(terms, pd0), stance_rate(terms, dataclasses.replace(pd0, b=pd0.b / k ** 2))
    assert own.time_factor is not None and len(own.steps) >= 2
    assert np.isclose(slow.steps[:, None], k * own.steps[None], rtol=1e-9).any(axis=0).all()
    assert slow.time_factor == pytest.approx(k * own.time_factor, rel=0.05)
    assert STANCE_RATE[0] <= own.time_factor <= STANCE_RATE[1]


def test_the_frames_judged_can_be_given(walk):
    # the single-support frames given are the default; its first three steps give those steps only
    from scipy.ndimage import label

    from retime.physics.stance_rate import single_support

    terms = dynamics_terms(walk)
    pd0 = terms.combine()
    own = stance_rate(terms, pd0)
    single = single_support(np.asarray(pd0.contact)[::int(terms.samples_per_frame)], terms.fps, terms.smoothing)
    given = stance_rate(terms, pd0, frames=single)
    assert given.time_factor == own.time_factor and np.array_equal(given.steps, own.steps)
    step_of, _ = label(single)
    first = stance_rate(terms, pd0, frames=(step_of >= 1) & (step_of <= 3))
    assert 0 < len(first.steps) < len(own.steps) and np.array_equal(first.steps, own.steps[:len(first.steps)])


def test_a_walk_played_too_slow_is_named_from_its_stance(walk, jump):
    real = check_clip(walk)
    assert real.physical and real.verdict.flight.seconds == 0.0  # no flight to measure
    c = check_clip(M.wrong_frame_time(walk, 1.25))
    assert c.verdict.codes == ["frame_rate"] and "no flight to measure" in c.verdict.causes[0]
    assert _factor(c.verdict.causes[0]) == pytest.approx(1.25, rel=0.1)
    assert "Frame Time 0.0104 s" in c.verdict.causes[0]
    assert c.summary()["stance_time_factor"] == pytest.approx(1.25, rel=0.1) and c.summary()["stance_steps"] >= 2
    assert check_clip(jump).verdict.stance is None  # where a flight is measured, it decides


def _dev(name):
    path = DATA / name
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return load_motion(path)


@pytest.mark.parametrize("factor", [0.8, 1.25])
def test_a_walk_at_the_wrong_frame_time_is_named_with_its_factor(factor):
    walk = _dev("bvh-dev/AV_8Walk_Meredith_HVHA_Rep1.bvh")
    assert check_clip(walk).physical
    c = check_clip(M.wrong_frame_time(walk, factor))
    assert c.verdict.codes == ["frame_rate"]
    assert _factor(c.verdict.causes[0]) == pytest.approx(factor, rel=0.1)


@pytest.mark.parametrize("name, factor", [("16_16.amc", 0.8), ("16_31.amc", 0.8), ("16_17.amc", 1.25),
                                          ("16_33.amc", 1.25)])
def test_a_cmu_walk_at_the_wrong_frame_time_is_named(name, factor):
    # CMU subject 16's walks keep the heel 'in contact' through push-off; on the whole sole their own
    # rate read 1.07-1.13 and these variants were missed (0.90-0.96 and 1.11-1.15)
    walk = _dev(f"cmu/{name}")
    assert check_clip(walk).physical
    c = check_clip(M.wrong_frame_time(walk, factor))
    assert c.verdict.codes == ["frame_rate"] and "no flight to measure" in c.verdict.causes[0]
    assert _factor(c.verdict.causes[0]) == pytest.approx(factor, rel=0.15)


def test_a_dance_is_not_judged_as_a_gait():
    # a samba on one foot at a time, travelling 0.24 m/s: its stance rate (0.56) is not a gait's
    c = check_clip(_dev("bvh-dev/samba_dancing.bvh"))
    assert c.physical and c.verdict.stance is None


def test_a_caution_is_exit_3_and_in_the_report(capsys, monkeypatch, tmp_path):
    # the bundled walk 16_15 (no flight) with its stance rate replaced by one step at 0.8: physical,
    # but the frame rate unconfirmed, said in the verdict line, the report and the exit code
    import json

    from retime.cli import main
    from retime.physics import plausibility
    from retime.physics.stance_rate import StanceRate

    monkeypatch.setattr(plausibility, "stance_rate", lambda terms: StanceRate(0.8, 0.4, np.zeros(0), np.array([0.8])))
    report = tmp_path / "r.json"
    code = main(["check", str(bundled_path("16_15.amc")), "--report", str(report)])
    out = capsys.readouterr().out
    assert code == 3 and "physical as captured, with a caution" in out and "[frame_rate_unconfirmed]" in out
    summary = json.loads(report.read_text())["summary"]
    assert summary["physical"] and summary["cautions"] == ["frame_rate_unconfirmed"] and summary["codes"] == []
    assert summary["stance_steps"] == 1 and "one step" in summary["caution_sentences"][0]


def _guess(mpu, leg_m=0.814, confidence="unusual scale"):
    from types import SimpleNamespace

    return SimpleNamespace(unit_confidence=confidence, meters_per_unit=mpu, leg_m=leg_m, height_m=1.5)


def test_flights_at_g_under_an_unusual_guessed_unit_are_a_caution():
    # jumping.bvh's guess (0.0376 m a unit, legs 0.81 m) with its Frame Time x1.25: the flight falls at
    # 0.95 g under the guess, at 0.64 g in inches, the nearest common unit, where its legs are 0.55 m (a
    # child's): both are human, and flights and stance forces measure only unit x rate^2, so the check
    # does not decide; the caution names both readings with their numbers
    from types import SimpleNamespace

    from retime.physics.plausibility import unit_caution

    c = unit_caution(SimpleNamespace(ratio=0.95), 95.9, _guess(0.0376))
    assert c.code == "units_unconfirmed" and "in inches, the nearest common unit," in c.sentence
    assert "legs 0.81 m" in c.sentence and "legs 0.55 m" in c.sentence and "at the file's 95.9 fps" in c.sentence
    assert _factor(c.sentence) == pytest.approx(np.sqrt(0.0376 / (0.95 * 0.0254)), rel=0.01)  # 1.25x too slow
    assert "likely 120" in c.sentence and "--units in or --units 0.0376" in c.sentence
    # what the metadata says is given, not weighed: 95.9 fps is no common capture rate, 100 fps is
    assert "95.9 fps, no common capture rate;" in c.sentence
    c = unit_caution(SimpleNamespace(ratio=1.04), 100.0, _guess(0.0376))  # jumping.bvh written at 100 fps
    assert c.code == "units_unconfirmed" and "the file's 100.0 fps;" in c.sentence
    assert unit_caution(SimpleNamespace(ratio=0.95), 120.0, _guess(0.0376, confidence="sure")) is None
    # a guess that is a common unit, or one whose nearest common unit also gives flights at about g: nothing
    assert unit_caution(SimpleNamespace(ratio=1.0), 120.0, _guess(0.0254, confidence="likely")) is None
    assert unit_caution(SimpleNamespace(ratio=1.0), 120.0, _guess(0.028)) is None


def test_a_common_unit_that_makes_no_human_is_not_the_cause():
    # the body's size decides where only one reading is human: flights at 3.76 g under the guess
    # (jumping.bvh at Frame Time x0.63) fall at 1 g in centimetres, but there its legs would be 0.22 m:
    # the rate is wrong (it was named the unit before), by the factor the guess gives
    from types import SimpleNamespace

    from retime.physics.plausibility import flight_cause, unit_caution

    c = flight_cause(SimpleNamespace(ratio=3.76, time_factor=1 / np.sqrt(3.76), flights=[0], seconds=0.2), 190.3,
                     _guess(0.0376))
    assert c.code == "frame_rate" and "in centimetres they would fall at 1 g, but with legs 0.22 m" in c.sentence
    assert _factor(c.sentence) == pytest.approx(1 / np.sqrt(3.76), rel=0.01)
    # a child-sized body in the unit that fits is human: the unit stays the likely cause, the rate named beside it
    c = flight_cause(SimpleNamespace(ratio=1.48, time_factor=1 / np.sqrt(1.48), flights=[0], seconds=0.3), 119.9,
                     _guess(0.0376))
    assert c.code == "units" and "likely in," in c.sentence and "legs 0.55 m" in c.sentence
    # a guess whose nearest common unit makes no human (0.004 m a unit: legs 2.0 m in cm, 0.20 m in mm) is
    # confirmed by flights at g: no caution
    assert unit_caution(SimpleNamespace(ratio=1.0), 120.0, _guess(0.004)) is None
    assert unit_caution(SimpleNamespace(ratio=1.0), 120.0, _guess(0.004, leg_m=float("nan"))) is not None


def test_a_real_jump_at_a_rate_that_fits_centimetres_is_named_a_wrong_rate():
    # jumping.bvh (an unusual scale, 0.0376 m a unit, guessed) with its Frame Time x0.63: its flight
    # falls at 3.76 g, at 1 g in centimetres, where its legs would be 0.22 m long
    m = M.wrong_frame_time(_dev("bvh-dev/jumping.bvh"), 0.63)
    c = check_clip(m)
    assert c.verdict.codes == ["frame_rate"] and "no human's" in c.verdict.causes[0]
    assert _factor(c.verdict.causes[0]) < 0.6  # 1.94x too fast under the guess (1.59x in inches)