"""``retime check``'s verdicts (issue 25): flight gravity from each flight's parabola, and one cause
code per mistake made from a good capture (a wrong Frame Time, radians, the wrong up axis, a locked
root, a treadmill); real runs are physical. Variants are built here from the bundled clips; the
dev-data tests skip when ../shared/data is absent."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.motion import load_motion, save_bvh
from retime.motion import mistakes as M
from retime.physics.ballistic import FlightGravity, Flight, fit_flights
from retime.physics.check import check_clip
from retime.physics.constants import G

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def _factor(sentence: str) -> float:
    k, how = re.search(r"plays (\d+\.\d+)x too (slow|fast)", sentence).groups()
    return float(k) if how == "slow" else 1.0 / float(k)


def test_a_parabola_through_each_flight_gives_its_gravity():
    fps = 120.0
    t = np.arange(240) / fps
    height = 1.0 + 0.01 * np.sin(7 * t)  # stance: anything
    air = np.zeros(240, bool)
    for a, b, g in ((20, 70, 7.0), (120, 145, 9.0), (200, 232, 9.0)):  # 0.39 s at 7, 0.18 + 0.24 s at 9
        air[a:b] = True
        tt = t[a:b] - t[a]
        height[a:b] = 1.0 + 1.5 * tt - 0.5 * g * tt ** 2
    fit = fit_flights(height, air, fps)
    assert [round(f.g, 6) for f in fit.flights] == [7.0, 9.0, 9.0]
    assert [(f.first, f.last) for f in fit.flights] == [(21, 68), (121, 143), (201, 230)]  # a frame in from each end
    # the weighted median: the two 9 g flights last longer together than the 7 g one
    assert fit.g == pytest.approx(9.0) and fit.time_factor == pytest.approx(np.sqrt(G / 9.0))
    assert fit_flights(height, air & (np.arange(240) < 100), fps).g == pytest.approx(7.0)
    short = np.zeros(240, bool)
    short[50:55] = True  # 5 frames, 3 after the trim: no parabola
    assert fit_flights(height, short, fps).flights == []


def test_the_weighted_median_follows_durations():
    f = FlightGravity(fps=100.0, flights=[Flight(0, 10, 5.0, 0.0), Flight(0, 30, 9.0, 0.0), Flight(0, 12, 20.0, 0.0)])
    assert f.g == 9.0 and f.seconds == pytest.approx(0.52)


@pytest.mark.parametrize("clip", ["16_06.amc", "16_03.amc"])
def test_bundled_jumps_fall_at_1g(clip):
    # the smoothed centre of mass's median acceleration read 0.87 g on 16_06
    c = check_clip(load_motion(bundled_path(clip)))
    assert c.physical and c.verdict.codes == []
    assert abs(c.flight_g - 1.0) < 0.08 and len(c.verdict.flight.flights) == 1


@pytest.mark.parametrize("factor", [0.8, 1.25])
def test_a_wrong_frame_time_is_named_with_its_factor(jump, factor):
    c = check_clip(M.wrong_frame_time(jump, factor))
    assert not c.physical and c.verdict.codes == ["frame_rate"]
    sentence = c.verdict.causes[0]
    # the jump itself falls at 1.07 g: the factor found is within 5 % of the one applied
    assert _factor(sentence) == pytest.approx(factor, rel=0.05)
    assert f"Frame Time {factor / 120:.4f} s" in sentence and "likely 120, give --fps 120" in sentence


def test_the_cli_names_the_frame_rate_and_exits_1(jump, tmp_path, capsys):
    slow = tmp_path / "slow.bvh"
    save_bvh(M.wrong_frame_time(jump, 1.25), slow)
    assert main(["check", str(slow), "--report", str(tmp_path / "r.json")]) == 1
    out = capsys.readouterr().out
    assert "[frame_rate] plays 1.2" in out and "x too slow: Frame Time 0.0104 s; 0.008" in out
    import json

    report = json.loads((tmp_path / "r.json").read_text())
    assert report["summary"]["codes"] == ["frame_rate"]
    frames = report["frames"]
    assert len(frames) == jump.n_frames and {"frame", "time", "residual", "flight", "airborne"} <= set(frames[0])
    assert sum(f["airborne"] for f in frames) > 0.2 * 120  # the 0.4 s flight


@pytest.mark.parametrize("mistake, code", [(M.radians_as_degrees, "radians"), (M.up_read_as, "up_axis"),
                                           (M.root_locked, "root_locked")])
def test_each_mistake_on_a_jump_gives_its_cause(jump, mistake, code):
    c = check_clip(mistake(jump))
    assert not c.physical and c.verdict.codes[0] == code


def test_a_treadmill_walk_is_named_a_treadmill(walk):
    c = check_clip(M.treadmill(walk))
    assert not c.physical and c.verdict.codes == ["treadmill"]
    assert c.verdict.travel < 0.2 and "a treadmill" in c.verdict.causes[0]
    real = check_clip(walk)
    assert real.physical and real.verdict.travel > 1.0  # the walk itself travels 1.3 m/s


def test_a_locked_walk_is_in_place_not_a_treadmill(walk):
    c = check_clip(M.root_locked(walk))
    assert not c.physical and c.verdict.codes == ["root_locked"]


def test_mistakes_do_not_touch_the_original(jump):
    before = (jump.skeleton.up, jump.skeleton.meters_per_unit, jump.skeleton.frame, jump.fps)
    M.up_read_as(jump)
    M.wrong_frame_time(jump, 2.0)
    assert (jump.skeleton.up, jump.skeleton.meters_per_unit, jump.skeleton.frame, jump.fps) == before


# --- the dev data -------------------------------------------------------------------------------

def _dev(name):
    path = DATA / name
    if not path.exists():
        pytest.skip(f"{path} is absent")
    return load_motion(path)


@pytest.mark.parametrize("name", ["cmu/16_35.amc", "cmu/16_45.amc", "cmu/16_55.amc", "bvh-dev/run.bvh"])
def test_real_runs_are_physical(name):
    # all four were NOT physical before (flight gravity 0.47-0.72 g; 'no foot on the floor' in 53 %)
    c = check_clip(_dev(name))
    assert c.physical, c.verdict.causes
    if c.flight_g is not None:
        assert 0.9 < c.flight_g < 1.2


@pytest.mark.parametrize("factor", [0.8, 1.25])
def test_a_run_at_the_wrong_frame_time_is_named(factor):
    c = check_clip(M.wrong_frame_time(_dev("cmu/16_45.amc"), factor))
    assert c.verdict.codes == ["frame_rate"]
    assert _factor(c.verdict.causes[0]) == pytest.approx(factor, rel=0.1)


def test_a_treadmill_run_is_named_a_treadmill():
    c = check_clip(M.treadmill(_dev("cmu/16_45.amc")))
    assert c.verdict.codes == ["treadmill"]


def test_a_cartwheel_is_held_up_not_a_wrong_rate():
    c = check_clip(_dev("bvh-dev/cart.bvh"))
    assert c.verdict.codes == ["held_up"]


@pytest.mark.parametrize("name", ["cmu/16_01.amc", "cmu/16_31.amc", "cmu/16_33.amc"])
def test_a_locked_root_is_named_not_a_wrong_up_axis(name):
    # pinned, this jump and these walks were read +z / -x up (a swinging hand at its turning points
    # rests on a 'wall') and the check said up_axis
    c = check_clip(M.root_locked(_dev(name)))
    assert not c.physical and c.verdict.codes == ["root_locked"]


def test_the_verdict_line_and_the_cause_print_one_flight_g():
    # 0.9553 g read 0.95 in the verdict line (rounded to 0.955, then printed to 2 places) and 0.96 in
    # the cause: both now format the unrounded ratio
    from retime.physics.check import ClipCheck
    from retime.physics.plausibility import SourceCheck, flight_cause

    flight = FlightGravity(fps=120.0, flights=[Flight(0, 48, 0.9553 * G, 0.0)])
    verdict = SourceCheck(False, 0.0, 0.0, [flight_cause(flight, 120.0, None)], flight)
    n = 4
    c = ClipCheck(fps=120.0, times=np.arange(n) / 120.0, residual=np.zeros(n), torque_excess=np.zeros(n),
                  com_accel=np.zeros((n, 3)), flight=np.zeros(n, bool), foot_slide=np.zeros(n), verdict=verdict)
    line = c.verdict_line()
    assert "the centre of mass falls at 0.96 g. " in line and "falls at 0.96 g, not 1 g" in line and "0.95 g" not in line
    assert c.summary()["flight_g"] == verdict.as_dict()["flight_g"] == 0.9553
