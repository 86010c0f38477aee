"""physics_warp and ``retime physics`` on a real CMU jump (16_06, bundled): the paper's results."""
from __future__ import annotations

import json

import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.motion import load_motion
from retime.physics.api import DEFAULT_SMOOTHING, physics_warp
from retime.physics.model.dynamics import dynamics_terms
from retime.physics.report import flight_speeds
from retime.warp import TimingCurve


@pytest.fixture(scope="module")
def jump():
    m = load_motion(bundled_path("16_06.amc"))
    return m, dynamics_terms(m, smoothing=DEFAULT_SMOOTHING)


@pytest.mark.parametrize("start", ["global", "uniform"])
def test_half_duration_keeps_the_flight_at_natural_speed(jump, start):
    """Fig. 1: half the duration; idle time absorbs the speed-up, the flight stays near 1x (from the
    grid start and from the paper's uniform one)."""
    m, terms = jump
    r = physics_warp(m, scale=0.5, terms=terms, start=start)
    s = r.report["summary"]
    assert r.curve.duration == pytest.approx(m.duration / 2, abs=0.5 / m.fps)
    assert s["mean_speed"] == pytest.approx(2.0, rel=0.01)
    (fl,) = flight_speeds(r.report)
    assert 0.8 <= fl <= 1.3
    assert s["feasible_fraction"] >= 0.85
    stance = [p["speed"] for p in s["phases"] if p["state"] == "stance"]
    assert min(stance) > 1.5  # the stances carry the speed-up


def test_quarter_gravity_plays_the_flight_at_half_speed(jump):
    """Fig. 9: ballistic flight scales with sqrt(g / g') = 0.5 (free duration)."""
    m, terms = jump
    r = physics_warp(m, gravity=(0.0, -9.81 / 4, 0.0), terms=terms)
    s = r.report["summary"]
    (fl,) = flight_speeds(r.report)
    assert 0.42 <= fl <= 0.6
    assert s["feasible_fraction"] >= 0.9
    assert r.curve.duration > m.duration


def test_unchanged_physics_leaves_the_timing_alone(jump):
    m, terms = jump
    r = physics_warp(m, terms=terms)
    t = np.linspace(0, r.curve.duration, 400)
    assert r.curve.duration == pytest.approx(m.duration, abs=1.5 / m.fps)
    assert np.max(np.abs(r.spline.speed(t) - 1.0)) < 0.03
    assert r.report["summary"]["feasible_fraction"] == 1.0


def test_keytime_moves_a_point_of_the_flight_earlier(jump):
    """Fig. 8: a mid-flight point plays earlier; the constraint holds and the flight keeps its speed."""
    m, terms = jump
    fl = np.flatnonzero(~r_contact(terms).any(axis=1))
    s_mid = terms.times[fl[len(fl) // 2]]
    r = physics_warp(m, duration=m.duration, keytimes=[(s_mid, s_mid - 0.4)], terms=terms)
    assert r.spline(s_mid - 0.4) == pytest.approx(s_mid, abs=1e-4)
    (speed,) = flight_speeds(r.report)
    assert 0.8 <= speed <= 1.3


def r_contact(terms):
    return np.asarray(terms.contact, dtype=bool)


def test_report_has_a_row_per_output_frame(jump):
    m, terms = jump
    r = physics_warp(m, scale=0.8, terms=terms)
    frames = r.report["frames"]
    assert len(frames) == r.curve.n_frames(m.fps)
    keys = {"output_time", "source_time", "speed", "p_ddot", "p_dot2", "contact", "in_region", "distance",
            "residual", "torque_norm"}
    assert keys <= set(frames[0])
    frac = np.mean([f["in_region"] for f in frames])
    assert r.report["summary"]["feasible_fraction"] == pytest.approx(frac, abs=1e-4)
    assert all(f["torque_norm"] > 0 for f in frames)


def _residual_by_linprog(pd, regions, i, u, v):
    """The residual of a timing (u, v) at source frame i, from the model's rows by SciPy's linprog:
    the least weighted L1 slack s+ + s- with lo <= a u + b v + c - N lam + s+ - s- <= hi, lam >= 0."""
    from scipy.optimize import linprog

    a, b, c, N = (np.asarray(x[i], dtype=float) for x in (pd.a, pd.b, pd.c, pd.N))
    lo = regions.lo[i] - regions.budget[i] * v
    hi = regions.hi[i] + regions.budget[i] * v
    nv, K = N.shape
    n_root = int(np.sum(np.cumprod((np.asarray(pd.tau_lo) == 0) & (np.asarray(pd.tau_hi) == 0))))
    bw, opts = regions.body_weight, regions.options
    cost = np.full(nv, 1.0 / (bw * opts.moment_arm))
    cost[: min(3, n_root)] = 1.0 / bw
    cost[n_root:] *= opts.actuated_slack_cost
    value = a * u + b * v + c
    finite_lo, finite_hi = lo > -1e29, hi < 1e29
    # rows: value - N lam + s+ - s- <= hi  and  -(value - N lam + s+ - s-) <= -lo
    I = np.eye(nv)
    A = np.vstack([np.hstack([-N, I, -I])[finite_hi], np.hstack([N, -I, I])[finite_lo]])
    rhs = np.concatenate([(hi - value)[finite_hi], (value - lo)[finite_lo]])
    res = linprog(np.concatenate([np.zeros(K), cost, cost]), A_ub=A, b_ub=rhs, bounds=(0, None), method="highs-ds")
    assert res.status == 0
    return res.fun


def _inside_convex(P, point):
    """A point in a convex polygon (either orientation): on one side of every edge."""
    P = np.asarray(P, dtype=float)
    d = np.roll(P, -1, axis=0) - P
    w = np.asarray(point) - P
    cross = d[:, 0] * w[:, 1] - d[:, 1] * w[:, 0]
    return bool(np.all(cross >= -1e-9) or np.all(cross <= 1e-9))


def test_in_region_agrees_with_an_independent_lp(jump):
    """The report's in_region against the residual found by SciPy's linprog from the model's rows, and
    its distance against a plain point-in-polygon test (neither shares code with the report)."""
    m, terms = jump
    r = physics_warp(m, scale=0.3, terms=terms)  # shorter than any physical timing: some frames outside
    frames, regions, pd = r.report["frames"], r.regions, r.dynamics
    assert any(not f["in_region"] for f in frames) and any(f["in_region"] for f in frames)
    checked = 0
    for f in frames[::3]:
        i, u, v = f["source_frame"], f["p_ddot"], f["p_dot2"]
        if f["distance"] == 0:
            assert _inside_convex(regions.polygon(i), (u, v))
            continue
        want = _residual_by_linprog(pd, regions, i, u, v)
        assert f["residual"] == pytest.approx(want, rel=1e-3, abs=2e-5)
        assert f["in_region"] == (want <= 0.01 + 1e-6)
        checked += 1
    assert checked >= 5


def test_cli_writes_motion_warp_report_and_body(tmp_path):
    src = bundled_path("16_06.amc")
    out, warp, rep, body = (tmp_path / n for n in ("out.bvh", "warp.csv", "rep.json", "body.toml"))
    code = main(["physics", str(src), "-o", str(out), "--scale", "0.5", "--warp", str(warp), "--report", str(rep),
                 "--write-body", str(body), "--quiet"])
    assert code == 0
    curve = TimingCurve.from_csv(warp)
    assert curve.duration == pytest.approx(load_motion(src).duration / 2, abs=0.01)
    data = json.loads(rep.read_text())
    assert data["summary"]["feasible_fraction"] >= 0.85
    assert "torque" in body.read_text().lower()
    assert load_motion(out).n_frames == len(data["frames"])


@pytest.mark.parametrize("args,msg", [
    (["--mass", "nosuch=2"], "no segment named 'nosuch'"),
    (["--keytime", "99=1"], "outside the clip"),
])
def test_cli_errors_are_one_line(tmp_path, capsys, args, msg):
    code = main(["physics", str(bundled_path("16_06.amc")), "-o", str(tmp_path / "o.bvh"), "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 2 and msg in err and "Traceback" not in err


def test_cli_refuses_to_overwrite_its_input(tmp_path, capsys):
    src = tmp_path / "in.bvh"
    src.write_text("x")
    code = main(["physics", str(src), "-o", str(src), "--quiet"])
    assert code == 2 and "overwrite" in capsys.readouterr().err


def test_cli_says_when_the_duration_is_below_the_least_physical_one(tmp_path, capsys):
    src = bundled_path("16_06.amc")
    rep = tmp_path / "r.json"
    assert main(["physics", str(src), "-o", str(tmp_path / "a.bvh"), "--scale", "0.4", "--report", str(rep)]) == 0
    out = capsys.readouterr().out
    least = json.loads(rep.read_text())["summary"]["least_duration"]
    assert 0.4 * 3.383 < least < 3.383 and f"less than {least:.3f} s" in out
    assert main(["physics", str(src), "-o", str(tmp_path / "b.bvh"), "--scale", "0.6"]) == 0
    assert "no timing of this clip is physical" not in capsys.readouterr().out


def test_an_unknown_start_is_refused(jump):
    from retime.errors import RetimeError

    m, terms = jump
    with pytest.raises(RetimeError, match="unknown start"):
        physics_warp(m, scale=0.5, terms=terms, start="random")
