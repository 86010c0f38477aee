"""The one method contract (retime.method): every method takes a motion and a Request and returns a
curve, a report of one schema and the solver's info; a new method is one module."""
import sys
import textwrap

import numpy as np
import pytest

from retime.errors import RetimeError
from retime.method import METHODS, Request, settings_type, solve

COMMON = {"method", "source_duration", "duration", "output_frames", "mean_speed", "phases", "timings", "warnings",
          "notes"}


@pytest.fixture(scope="module")
def short_jump(jump):
    return jump.frames(slice(180, 407))  # 1.9 s around the flight: quick physics


@pytest.mark.parametrize("name", ["linear", "guided", "physics"])
def test_every_method_answers_in_one_schema(short_jump, name):
    r = solve(name, short_jump, Request(scale=0.5))
    s = r.report.summary
    assert COMMON <= set(s) and s["method"] == name
    assert s["duration"] == pytest.approx(r.curve.duration, abs=1e-6)
    assert s["source_duration"] == pytest.approx(short_jump.duration, abs=1e-6)
    assert s["output_frames"] == r.curve.n_frames(short_jump.fps)
    # the phases tile the source and the output, and each speed is its spans' ratio
    ph = s["phases"]
    assert ph and ph[0]["source_start"] == 0.0 and ph[-1]["source_end"] == pytest.approx(short_jump.duration, abs=1e-5)
    for a, b in zip(ph, ph[1:]):
        assert a["source_end"] == b["source_start"] and a["output_end"] == pytest.approx(b["output_start"], abs=1e-5)
    for p in ph:
        want = (p["source_end"] - p["source_start"]) / (p["output_end"] - p["output_start"])
        assert p["speed"] == pytest.approx(want, rel=1e-3)
    assert all(v >= 0 for v in s["timings"].values())
    assert isinstance(r.info, dict) and r.info
    if name == "physics":
        assert len(r.report.frames) == s["output_frames"] and 0 <= s["feasible_fraction"] <= 1
        assert {p["state"] for p in ph} == {"stance", "flight"}


def test_linear_phases_between_keytimes_have_the_keyed_speeds(short_jump):
    S = short_jump.duration
    r = solve("linear", short_jump, Request(duration=1.0, keytimes=[(0.5 * S, 0.25)]))
    speeds = [p["speed"] for p in r.report.summary["phases"]]
    assert speeds == pytest.approx([0.5 * S / 0.25, 0.5 * S / 0.75], rel=1e-4)


def test_the_contract_and_the_full_entry_point_agree(short_jump):
    from retime.physics import physics_warp
    from retime.physics.method import Settings

    r = solve("physics", short_jump, Request(duration=1.2, settings=Settings(gravity_scale=0.5)))
    g = -9.81 * 0.5 * np.array([0.0, 1.0, 0.0])
    direct = physics_warp(short_jump, duration=1.2, gravity=tuple(g))
    t = np.linspace(0, 1.2, 50)
    np.testing.assert_allclose(r.curve(t), direct.curve(t), atol=1e-12)


def test_requests_and_settings_are_checked(short_jump):
    with pytest.raises(RetimeError, match="not both"):
        Request(duration=1.0, scale=0.5)
    with pytest.raises(RetimeError, match="positive"):
        Request(scale=-1)
    with pytest.raises(RetimeError, match="unknown method 'nosuch'"):
        solve("nosuch", short_jump, Request())
    with pytest.raises(RetimeError, match="settings must be retime.linear.method.Settings"):
        solve("linear", short_jump, Request(scale=0.5, settings=settings_type("guided")()))
    with pytest.raises(RetimeError, match="mass nosuch=2"):
        solve("physics", short_jump, Request(scale=0.5, settings=settings_type("physics")(mass_factors={"nosuch": 2})))


def test_a_new_method_is_one_module(tmp_path, monkeypatch, short_jump):
    (tmp_path / "hold_start.py").write_text(textwrap.dedent('''
        """A toy method: hold the first pose for a given time, then play the clip as it is."""
        from dataclasses import dataclass

        from retime.method import Report, Result, summary
        from retime.phases import keytime_phases
        from retime.warp import TimingCurve

        NAME = "hold_start"


        @dataclass(frozen=True)
        class Settings:
            hold: float = 0.5


        def solve(motion, request):
            s = request.settings_or(Settings)
            S = motion.duration
            curve = TimingCurve([0.0, s.hold, s.hold + S], [0.0, 0.0, S])
            return Result(curve, Report(summary(NAME, curve, motion.fps, keytime_phases(curve), {"method": 0.0})))
    '''))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setitem(METHODS, "hold_start", "hold_start")  # the registry: name -> module
    r = solve("hold_start", short_jump, Request())
    assert r.curve.duration == pytest.approx(short_jump.duration + 0.5)
    assert r.curve(0.25) == 0.0 and r.report.summary["method"] == "hold_start"
    sys.modules.pop("hold_start", None)


@pytest.mark.parametrize("name, request_", [
    ("linear", Request(scale=0.5)),
    ("linear", Request(duration=2.0, keytimes=[(1.5, 0.9)], settings=settings_type("linear")(smooth=True))),
    ("guided", Request(duration=1.7)),
    ("guided", Request(duration=1.7, settings=settings_type("guided")(fast=True))),
    ("physics", Request(duration=1.7)),
], ids=["linear", "linear-smooth", "guided", "guided-fast", "physics"])
def test_speed_is_the_derivative_of_every_methods_curve(jump, name, request_):
    """curve.speed at the output frames against a forward difference of the curve over 0.2 ms. Physics on
    16_06 at 1.7 s was exactly 0 at 8 of 205 frames: its curve had knot intervals of 1e-17 s, across which
    the monotone cubic's slope is zero, while the CSV it wrote never played slower than 1.004x."""
    curve = solve(name, jump, request_).curve
    t = curve.frame_times(jump.fps)
    h = 2e-4
    ahead = np.minimum(t + h, curve.duration)
    behind = np.where(ahead > t, t, t - h)  # the last frame looks back
    numeric = (curve(ahead) - curve(behind)) / (ahead - behind)
    np.testing.assert_allclose(curve.speed(t), numeric, rtol=1e-2, atol=1e-2)  # the difference sees s'' h / 2
    assert curve.speed(t).min() > 0.1  # none of these requests holds a frame


def test_a_live_session_is_the_solve_and_takes_edits(short_jump):
    """retime.method.session: converged from the same start, the live session's curve is solve's; a
    locked edit holds through re-convergence; a second session of the same setting reuses the first's
    dynamics and regions."""
    from retime.method import session

    request = Request(duration=1.2)
    live = session("physics", short_jump, request)
    live.reconverge(max_iter=3000, tol=1e-9)
    solved = solve("physics", short_jump, request)
    t = np.linspace(0.0, 1.2, 61)
    np.testing.assert_allclose(live.curve(short_jump.fps)(t), solved.curve(t), atol=1e-9)
    k = len(live.control_points()) // 2
    s_k = live.control_points()[k]["source_time"] + 0.05
    live.move(k, s_k, lock=True)
    live.reconverge(max_iter=300)
    point = live.control_points()[k]
    assert point["locked"] and live.is_locked(k) and point["source_time"] == pytest.approx(s_k, abs=1e-9)
    assert 0.0 <= live.feasibility(short_jump.fps).fraction <= 1.0
    again = session("physics", short_jump, request, shared=live.shared)
    assert again.shared is live.shared
    other = session("physics", short_jump, Request(duration=1.2, settings=settings_type("physics")(gravity_scale=0.5)),
                    shared=live.shared)
    assert other.shared.terms is live.shared.terms and other.shared.regions is not live.shared.regions
    with pytest.raises(RetimeError, match="linear has no live session"):
        session("linear", short_jump, request)
