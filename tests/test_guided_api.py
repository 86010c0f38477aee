"""guided_warp on bundled CMU clips: durations, keytimes, identity, flight speed, errors, CLI."""
import csv

import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.errors import RetimeError
from retime.guided import guided_solve, guided_warp
from retime.phases import flights as contact_flights, interval_speed
from retime.motion.feet import foot_contacts
from retime.motion import load_motion
from retime.warp import apply_timing


def test_identity_when_duration_and_reference_unchanged(jump):
    res = guided_solve(jump)
    assert res.m == res.n
    assert np.array_equal(res.frames, np.arange(res.n))
    t = np.linspace(0, jump.duration, 50)
    np.testing.assert_allclose(res.curve(t), t, atol=1e-9)


def flight_phases(motion):
    return contact_flights(foot_contacts(motion), motion.fps)


@pytest.mark.parametrize("scale", [0.6, 1.5])
@pytest.mark.parametrize("clip", ["jump", "high_jump"])
def test_flight_keeps_its_speed(clip, scale, request):
    motion = request.getfixturevalue(clip)
    res = guided_solve(motion, scale=scale)
    curve = res.curve
    # the path starts at the first grid frame and ends at the last: the whole clip plays
    assert res.frames[0] == 0 and res.frames[-1] == res.n - 1
    assert curve(0.0) == 0.0 and curve(curve.duration) == pytest.approx(motion.duration)
    flights = flight_phases(motion)
    assert len(flights) == 1
    (a, b), = flights
    assert abs(interval_speed(curve, a, b) - 1.0) < 0.15
    overall = motion.duration / curve.duration
    assert abs(overall - 1 / scale) < 0.05
    # the rest of the clip absorbs the change: it plays clearly faster (or slower) than 1
    rest = interval_speed(curve, 0.0, a)
    assert (rest > 1.3) if scale < 1 else (rest < 0.8)
    # every output frame of the discrete warp advances 1..s grid frames
    gaps = np.diff(res.frames)
    assert gaps.min() >= 1 and gaps.max() <= res.s
    assert len(res.frames) == res.m


def test_heuristic_is_feasible_and_not_better(jump):
    exact = guided_solve(jump, scale=0.6)
    fast = guided_solve(jump, scale=0.6, fast=True)
    assert not fast.exact and exact.exact
    assert fast.objective >= exact.objective - 1e-9
    assert fast.curve.duration == exact.curve.duration


def test_keytimes_are_hit_exactly(jump):
    keys = [(1.0, 0.7), (2.3, 1.55)]
    res = guided_solve(jump, duration=2.4, keytimes=keys)
    for src, dst in keys:
        assert res.curve(dst) == pytest.approx(src, abs=1e-9)
        assert res.raw_curve(dst) == pytest.approx(src, abs=1e-9)
    assert res.curve.duration == pytest.approx(2.4)
    assert np.all(np.diff(res.curve(np.linspace(0, 2.4, 400))) >= -1e-12)


def test_other_reference_and_free_duration(jump, high_jump):
    res = guided_solve(jump, reference=high_jump, duration=jump.duration)
    assert res.upsample == [2]  # the grid is upsampled so that the warp may slow down
    assert res.curve.duration == pytest.approx(jump.duration)
    free = guided_solve(jump, reference=high_jump, free=True, max_skip=8)
    assert free.curve.source_duration == pytest.approx(jump.duration)
    assert free.m == len(free.frames) and free.exact


def test_errors(jump):
    with pytest.raises(RetimeError, match="shortest possible is"):
        guided_warp(jump, duration=0.2)
    with pytest.raises(RetimeError, match="collide|closer than one frame"):
        guided_warp(jump, duration=3.0, keytimes=[(1.0, 1.0), (1.005, 1.005)])
    with pytest.raises(RetimeError, match="out of order or collide"):
        guided_warp(jump, duration=3.0, keytimes=[(1.0, 1.0), (1.0, 1.5)])
    short = jump.frames(slice(0, 4))  # 4 frames at 120 Hz: 1 frame at 30 Hz
    with pytest.raises(RetimeError, match="at least 3"):
        guided_warp(jump, reference=short)
    walk = load_motion(bundled_path("131_01.bvh"))
    with pytest.raises(RetimeError, match="skeleton differs"):
        guided_warp(jump, reference=walk)
    with pytest.raises(RetimeError, match="fixed output duration"):
        guided_warp(jump, free=True, keytimes=[(1.0, 1.0)])


def test_cli(tmp_path, capsys):
    src = str(bundled_path("16_06.amc"))
    out, warp = tmp_path / "g.bvh", tmp_path / "g.csv"
    assert main(["guided", src, "-o", str(out), "--scale", "0.6", "--warp", str(warp), "--quiet"]) == 0
    m = load_motion(out)
    jump = load_motion(src)
    assert m.n_frames == int(np.floor(jump.duration * 0.6 * jump.fps + 1e-6)) + 1
    rows = list(csv.reader(warp.read_text().splitlines()))
    assert rows[0] == ["output_time", "source_time"] and len(rows) == m.n_frames + 1
    assert main(["guided", src, "-o", str(out), "--duration", "0.2"]) == 2
    assert "shortest possible" in capsys.readouterr().err
    assert main(["guided", src, "-o", str(tmp_path / "x.bvh"), "--scale", "1.5", "--fast",
                 "--adaptive-smoothing", "--quiet"]) == 0
    with pytest.raises(SystemExit):
        main(["guided", src, "-o", str(out), "--duration", "2", "--free"])


def test_apply_matches_curve(jump):
    curve = guided_warp(jump, scale=0.6)
    out = apply_timing(jump, curve)
    assert out.n_frames == curve.n_frames(jump.fps)


def test_upper_bound_and_pruned_exact_search_agree(jump):
    """The exact search with heuristic bound and Lagrangian pruning finds the plain DP's optimum."""
    from retime.guided import dp
    from retime.guided.heuristic import solve_heuristic, solve_upper_bound
    from retime.guided.problem import WarpProblem
    from retime.guided.features import analysis_poses

    x = analysis_poses(jump)
    problem = WarpProblem(np.vstack([x, x[::-1], x]), np.vstack([x, x[::-1], x]), 30.0, 180, {}, 8, 3)
    F = problem.scores()
    exact = dp.solve_fixed(F, problem.m)
    ub, _, _ = solve_upper_bound(problem, F)
    heur, _, _ = solve_heuristic(problem, F)
    assert exact.objective <= ub.objective <= heur.objective + 1e-9
    pruned = dp.prune_band(F, problem.m, problem.band(), ub.objective)
    assert pruned.n_states(8) < problem.band().n_states(8)
    assert dp.solve_fixed(F, problem.m, band=pruned).objective == pytest.approx(exact.objective, rel=1e-12)


def test_paper_features_without_root_height(jump):
    from retime.guided import FeatureWeights

    res = guided_solve(jump, scale=0.6, weights=FeatureWeights(root_height=0.0))
    assert res.curve.duration == pytest.approx(guided_solve(jump, scale=0.6).curve.duration)


def test_mixed_compression_and_expansion_between_keytimes(jump):
    """First second compressed 2x, the rest expanded: each segment gets its own grid density."""
    res = guided_solve(jump, duration=4.0, keytimes=[(1.0, 0.5)])
    assert res.upsample[0] == 1 and res.upsample[1] >= 2
    assert res.curve(0.5) == pytest.approx(1.0, abs=1e-9)
    assert res.curve.duration == pytest.approx(4.0)
    assert interval_speed(res.curve, 0.0, 1.0) == pytest.approx(2.0, rel=1e-6)
    assert interval_speed(res.curve, 1.0, jump.duration) == pytest.approx((jump.duration - 1.0) / 3.5, rel=1e-6)
    (a, b), = flight_phases(jump)
    assert abs(interval_speed(res.curve, a, b) - 1.0) < 0.15


def test_cli_weights(tmp_path, capsys):
    src = str(bundled_path("16_06.amc"))
    out = tmp_path / "w.bvh"
    assert main(["guided", src, "-o", str(out), "--scale", "0.6", "--weights", "1,1,0.1,0", "--quiet"]) == 0
    with pytest.raises(SystemExit):
        main(["guided", src, "-o", str(out), "--weights", "1,-2,0"])
    assert "must be a finite number >= 0" in capsys.readouterr().err


def test_pruned_path_of_guided_solve_is_exact(jump, monkeypatch):
    """guided_solve prunes big problems (upper bound + Lagrangian bounds); force it on a small one."""
    from retime.guided import api

    plain = guided_solve(jump, scale=0.6)
    monkeypatch.setattr(api, "PRUNE_STATES", 0)
    pruned = guided_solve(jump, scale=0.6)
    assert pruned.stats.pruned_states is not None and pruned.stats.pruned_states <= pruned.stats.states
    assert pruned.objective == pytest.approx(plain.objective, rel=1e-12)
    assert np.array_equal(pruned.frames, plain.frames) or pruned.objective == pytest.approx(plain.objective)


def test_upper_bound_falls_back_when_its_corridor_cannot_hold_the_warp(jump, monkeypatch):
    """The exact search's upper bound (long clips) goes on by the heuristic when the Lagrangian path's
    corridor is infeasible, and the exact warp is the same."""
    import retime.guided.api as api
    import retime.guided.heuristic as heuristic
    from retime.guided import dp

    want = guided_solve(jump, scale=0.5).frames

    real, calls = heuristic.corridor, []

    def infeasible_first(*a, **k):  # the Lagrangian path's corridor is the first one built
        calls.append(1)
        if len(calls) == 1:
            raise dp.InfeasibleWarp("no warp in this corridor")
        return real(*a, **k)

    monkeypatch.setattr(api, "PRUNE_STATES", 0)  # every problem takes the upper-bound path
    monkeypatch.setattr(heuristic, "corridor", infeasible_first)
    got = guided_solve(jump, scale=0.5)
    assert len(calls) > 1 and got.exact and np.array_equal(got.frames, want)


# --- bounded memory: the clip-rate poses are made in chunks; the chunks must not change a bit
def test_root_frame_poses_in_chunks_are_the_same(jump):
    from retime.guided.features import root_frame_poses

    whole = root_frame_poses(jump, 1.0, chunk_frames=jump.n_frames)
    for chunk in (1, 7, 64):
        assert root_frame_poses(jump, 1.0, chunk_frames=chunk).tobytes() == whole.tobytes()


def test_analysis_samples_in_column_chunks_are_the_same(jump):
    from scipy.interpolate import CubicSpline

    from retime.guided.features import analysis_samples, root_frame_poses
    from retime.guided.features import lowpass

    poses = root_frame_poses(jump, 1.0).reshape(jump.n_frames, -1)
    grid = np.linspace(0.0, jump.duration, 57)
    rate = np.arange(int(jump.duration * 30) + 1) / 30
    # what one spline of all columns gives (the unchunked computation)
    spline = CubicSpline(np.arange(jump.n_frames) / jump.fps, lowpass(poses, 12), axis=0)
    whole = [spline(np.clip(t, 0.0, (jump.n_frames - 1) / jump.fps)) for t in (grid, rate)]
    for chunk in (1, 3, 8, poses.shape[1]):
        got = analysis_samples(poses, jump.fps, 0.1, [grid, rate], chunk_columns=chunk)  # 12 frames at 120 Hz
        assert [g.tobytes() for g in got] == [w.tobytes() for w in whole]


def test_identical_columns_finds_what_unique_finds():
    from retime.guided.features import identical_columns

    rng = np.random.default_rng(3)
    v = rng.normal(size=(50, 6))
    v = v[:, [0, 1, 0, 2, 3, 1, 4, 0, 5]]  # columns 0, 2, 7 and 1, 5 are equal
    v[:, 4] = 0.0
    v[:, 6] = np.where(np.arange(50) % 2, -0.0, 0.0)  # equal to column 4 as floats, as np.unique counts it
    cols = np.array([0, 1, 2, 3, 4, 5, 6, 7, 8])
    _, first, counts = np.unique(v[:, cols], axis=1, return_index=True, return_counts=True)
    order = np.argsort(first)
    got_first, got_counts = identical_columns(v, cols)
    assert got_first.tolist() == cols[first[order]].tolist()
    assert got_counts.tolist() == counts[order].tolist()


def test_heuristic_scores_in_one_pass(jump, monkeypatch):
    """The coarse rows and the corridor's vertices are scored together: one pass over the grid
    (each pass repeats the matrix products with the whole reference), and the same warp."""
    from retime.guided.problem import WarpProblem

    before = guided_solve(jump, scale=0.5, fast=True)
    passes = []
    scores = WarpProblem.scores
    monkeypatch.setattr(WarpProblem, "scores", lambda self, mask=None: passes.append(mask) or scores(self, mask))
    after = guided_solve(jump, scale=0.5, fast=True)
    assert len(passes) == 1
    assert after.frames.tobytes() == before.frames.tobytes() and after.objective == before.objective
