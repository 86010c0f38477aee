"""Guided's steady objective (issue 23): steady motion plays steadily, the ends keep the skip limit,
--blend runs from the keytime spline warp to the guided warp."""
import numpy as np
import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.guided import guided_solve
from retime.guided.steady import points_per_step, speed_costs
from retime.motion import Motion, load_motion
from retime.phases import interval_speed
from retime.warp import keytime_warp

BUNDLED = ["16_03.amc", "16_06.amc", "16_15.amc", "16_15.bvh", "16_16.amc", "16_33.amc", "131_01.bvh"]


def step_speeds(curve, fps):
    t = curve.frame_times(fps)
    return np.diff(curve(t)) / np.diff(t)


def sine_walk(base: Motion, seconds=4.0, hz=1.1):
    """A periodic "walk": every joint swings about x as a sine of its own phase, the root moves on."""
    fps = base.fps
    t = np.arange(int(seconds * fps)) / fps
    J = base.skeleton.n_joints
    amp = np.linspace(0.2, 0.6, J)
    phase = np.linspace(0.0, 2 * np.pi, J, endpoint=False)
    theta = amp * np.sin(2 * np.pi * hz * t[:, None] + phase)
    rot = np.zeros((len(t), J, 4))
    rot[..., 0] = np.sin(theta / 2)
    rot[..., 3] = np.cos(theta / 2)
    tr = np.repeat(base.translations[:1], len(t), axis=0).copy()
    tr[:, 0, 0] = base.translations[0, 0, 0] + 20.0 * t  # forward at a constant pace (file units)
    tr[:, 0, 1] = base.translations[0, 0, 1] + 0.5 * np.sin(4 * np.pi * hz * t)  # bounce, twice a cycle
    return Motion(base.skeleton, rot, tr, fps)


@pytest.fixture(scope="module")
def periodic(walk):
    return sine_walk(walk)


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_periodic_motion_plays_at_a_steady_speed(periodic, scale):
    res = guided_solve(periodic, scale=scale)
    v = step_speeds(res.curve, periodic.fps)
    cut = len(v) // 20
    mid = v[cut:len(v) - cut]
    assert mid.std() / mid.mean() < 0.02
    assert mid.max() / mid.min() < 1.05
    assert np.median(mid) == pytest.approx(1 / scale, rel=0.02)


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_paper_score_plays_the_periodic_motion_in_blocks(periodic, scale):
    """The defect the steady score removes: whole-frame steps and a linear score give blocks of speed."""
    res = guided_solve(periodic, scale=scale, score="paper")
    v = step_speeds(res.curve, periodic.fps)
    cut = len(v) // 20
    mid = v[cut:len(v) - cut]
    assert mid.max() / mid.min() > 1.5


@pytest.mark.parametrize("scale", [0.6, 1.5])
@pytest.mark.parametrize("clip", BUNDLED)
def test_ends_keep_the_skip_limit(clip, scale):
    motion = load_motion(bundled_path(clip))
    res = guided_solve(motion, scale=scale)
    v = step_speeds(res.curve, motion.fps)
    assert v[0] <= res.s / res.upsample[0] + 1e-9
    assert v[-1] <= res.s / res.upsample[-1] + 1e-9
    # no pop: the first and last steps are within a factor of 1.5 of their neighbours' mean
    for end, near in ((v[0], v[1:6]), (v[-1], v[-6:-1])):
        assert 1 / 1.5 <= end / near.mean() <= 1.5


def test_blend_zero_is_the_spline_warp(jump):
    keys = [(1.2, 0.8)]
    res = guided_solve(jump, scale=0.6, keytimes=keys, blend=0.0)
    spline = keytime_warp(jump.duration, keys, res.curve.duration, smooth=True)
    t = res.curve.frame_times(jump.fps)
    assert np.array_equal(res.curve(t), spline(t))


def test_blend_moves_the_flight_speed_monotonically(jump):
    from retime.motion.feet import foot_contacts
    from retime.phases import longest_flight

    a, b = longest_flight(foot_contacts(jump), np.arange(jump.n_frames) / jump.fps)
    speeds = [interval_speed(guided_solve(jump, scale=0.6, blend=w).curve, a, b) for w in (0.0, 0.25, 0.5, 0.75, 1.0)]
    assert speeds[0] == pytest.approx(1 / 0.6, rel=0.02)  # the spline plays the flight like the rest
    assert speeds[-1] == pytest.approx(1.0, abs=0.05)  # guided at its natural speed
    assert all(x > y for x, y in zip(speeds, speeds[1:]))


def test_blend_keeps_keytimes_and_range(jump):
    res = guided_solve(jump, duration=2.0, keytimes=[(1.5, 0.9)], blend=0.4)
    assert float(res.curve(0.9)) == pytest.approx(1.5, abs=1e-9)
    assert float(res.curve(0.0)) == 0.0 and float(res.curve(2.0)) == pytest.approx(jump.duration)


def test_blend_keeps_a_keytime_between_frames(jump):
    """A keytime whose output time falls between frames (0.9042 s at 120 Hz) holds in the mix too."""
    res = guided_solve(jump, duration=2.0, keytimes=[(1.5, 0.9042)], blend=0.4)
    assert float(res.curve(0.9042)) == pytest.approx(1.5, abs=1e-9)


def test_blend_and_score_errors(jump):
    from retime.errors import RetimeError

    with pytest.raises(RetimeError, match="blend"):
        guided_solve(jump, scale=0.6, blend=1.5)
    with pytest.raises(RetimeError, match="unknown score"):
        guided_solve(jump, scale=0.6, score="fancy")
    with pytest.raises(RetimeError, match="pace weight"):
        guided_solve(jump, scale=0.6, pace=-1.0)


def test_natural_and_mean_speed_both_on_the_fine_grid():
    # --scale 0.6 on a self-referenced compression: 5 grid frames per 3 output frames, 1x = 1 grid frame
    L = points_per_step(5, 3, 1.0)
    assert (1.0 * 3 * L / 5) == pytest.approx(round(3 * L / 5))
    # --scale 1.5 on the upsampled grid (2 grid frames per analysis frame): 4 per 3, 1x = 2
    L = points_per_step(4, 3, 2.0)
    assert (2.0 * 3 * L / 4) == pytest.approx(round(2.0 * 3 * L / 4))


@pytest.mark.parametrize("N, M", [(162, 98), (163, 98), (407, 245), (5, 3)])
def test_natural_speed_of_a_compression_is_an_allowed_step(N, M):
    """A compression's natural speed is one grid frame per output frame, the slowest step allowed:
    the points per step put an allowed step within 5% of it. CMU 118_26 at --scale 0.6 (162 grid
    frames, 98 steps) had 6.05 points at 1x with 10 a step, the slowest allowed 7: its whole
    jump, flight and all, played at 1.16x."""
    from retime.guided.steady import step_range

    L = points_per_step(N, M, 1.0, 8)
    kmin, kmax = step_range(N, M, L, 8)
    natural = M * L / N
    assert kmin <= kmax
    assert min(abs(k - natural) for k in range(kmin, kmax + 1)) / natural <= 0.05


def test_speed_costs_fill_the_ends_from_their_neighbours():
    F = np.full((6, 2, 8), np.inf)
    F[1:5, 0, 0] = [1.0, 2.0, 3.0, 4.0]
    F[2:4, 1, 1] = [5.0, 6.0]
    D = speed_costs(F)
    assert D[:, 0].tolist() == [1.0, 1.0, 2.0, 3.0, 4.0, 4.0]
    assert D[:, 1].tolist() == [5.0, 5.0, 5.0, 6.0, 6.0, 6.0]


def test_cli_blend_and_score(tmp_path, capsys):
    src = str(bundled_path("16_06.amc"))
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["guided", src, "-o", str(tmp_path / "a.bvh"), "--scale", "0.6", "--blend", "0", "--warp", str(a),
                 "--quiet"]) == 0
    assert main(["linear", src, "-o", str(tmp_path / "b.bvh"), "--scale", "0.6", "--warp", str(b)]) == 0
    ours = np.loadtxt(a, delimiter=",", skiprows=1)
    line = np.loadtxt(b, delimiter=",", skiprows=1)
    # no keytimes: the spline through the ends is the uniform warp (to the last frame's rounding)
    np.testing.assert_allclose(ours[:, 1], ours[:, 0] * ours[-1, 1] / ours[-1, 0], atol=1e-9)
    assert ours.shape == line.shape
    assert main(["guided", src, "-o", str(tmp_path / "c.bvh"), "--scale", "0.6", "--score", "paper", "--quiet"]) == 0
    with pytest.raises(SystemExit):
        main(["guided", src, "-o", str(tmp_path / "d.bvh"), "--scale", "0.6", "--blend", "2"])
    assert "from 0 to 1" in capsys.readouterr().err


def test_batch_blend_column(tmp_path):
    from retime.batch.jobs import Defaults, find_clips
    from retime.batch.run import clip_task
    from retime.guided.method import Settings
    from retime.errors import RetimeError

    jobs = tmp_path / "jobs.csv"
    jobs.write_text(f"motion,scale,blend\n{bundled_path('16_06.amc')},0.6,0.25\n{bundled_path('16_03.amc')},0.6,\n")
    a, b = find_clips([str(jobs)], Defaults())
    assert a.blend == 0.25 and b.blend is None
    assert clip_task(a, "guided", a.outputs(tmp_path, "guided")).request.settings.blend == 0.25
    assert clip_task(b, "guided", b.outputs(tmp_path, "guided")).request.settings == Settings()
    jobs.write_text(f"motion,scale,blend\n{bundled_path('16_06.amc')},0.6,1.5\n")
    with pytest.raises(RetimeError, match=r"jobs.csv line 2: blend must be a number from 0 to 1"):
        find_clips([str(jobs)], Defaults())


def test_batch_blend_is_for_guided(tmp_path, capsys):
    jobs = tmp_path / "jobs.csv"
    jobs.write_text(f"motion,scale,blend\n{bundled_path('16_06.amc')},0.6,0.5\n")
    assert main(["batch", str(jobs), "-o", str(tmp_path / "out"), "--method", "linear"]) != 0
    assert "a blend is for --method guided" in capsys.readouterr().err


def test_editor_offers_blend_as_a_slider():
    from retime.editor.methods import GuidedMethod
    from retime.errors import RetimeError

    param, = [p for p in GuidedMethod.params if p.name == "blend"]
    d = param.to_json()
    assert d["kind"] == "slider" and (d["min"], d["max"]) == (0.0, 1.0)
    assert param.check("0.3") == 0.3
    with pytest.raises(RetimeError, match="outside 0 .. 1"):
        param.check(1.2)


def test_front_ends_leave_the_defaults_to_settings():
    """Settings holds the defaults of score, steadiness and blend: the command line passes only what is
    given and names Settings' values in its help, the editor's slider starts at Settings.blend."""
    import argparse

    from retime.cli.main import build_parser
    from retime.editor.methods import GuidedMethod
    from retime.guided.api import SCORES
    from retime.guided.method import Settings

    guided = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)).choices["guided"]
    options = {a.dest: a for a in guided._actions}
    assert all(options[name].default is None for name in ("score", "steadiness", "pace", "blend"))
    assert tuple(options["score"].choices) == SCORES and f"{Settings.score} (default" in options["score"].help
    assert f"default {Settings.steadiness:g}" in options["steadiness"].help
    assert f"default {Settings.pace:g}" in options["pace"].help
    param, = [p for p in GuidedMethod.params if p.name == "blend"]
    assert param.default == Settings.blend == 1.0 and "default" in options["blend"].help


# ------------------------------------------------------------------ the refinement's search is exact

def _bilinear_scipy(T, t, v):
    """T (n, s) at grid time t and speed v (column v - 1), linear between whole values, clamped:
    written with SciPy, apart from the kernel's own interpolation."""
    from scipy.interpolate import RegularGridInterpolator

    n, s = T.shape
    f = RegularGridInterpolator((np.arange(n, dtype=float), np.arange(1, s + 1, dtype=float)), T)
    return f(np.column_stack([np.clip(t, 0, n - 1), np.clip(v, 1, s)]))


def _change_price(S, t, v0, v1):
    """The integral of a(t, u) du from v0 to v1 (absolute), by SciPy's adaptive quadrature."""
    from scipy.integrate import quad

    lo, hi = sorted((v0, v1))
    edges = [lo, *[c for c in range(1, S.shape[1] + 1) if lo < c < hi], hi]  # a's kinks
    return sum(quad(lambda u: float(_bilinear_scipy(S, np.array([t]), np.array([u]))[0]), e0, e1)[0]
               for e0, e1 in zip(edges, edges[1:]))


def _objective_from_definition(D, S, x, lam):
    """The steady objective of the fractional grid path x, from the module docstring's formula."""
    v = np.diff(x)
    c = _bilinear_scipy(D, 0.5 * (x[1:] + x[:-1]), v)
    change = sum(_change_price(S, x[p], v[p - 1], v[p]) for p in range(1, len(v)))
    dl = np.diff(np.log(v))
    return float(c.sum() + (lam * (np.abs(dl) + dl ** 2)).sum() + change)


def _tiny_segment(rng, n=9, s=3, M=4):
    """Random score tables and the refinement's tables for one segment 0 -> n-1 over M steps."""
    import math

    from retime.guided import steady as st

    D = rng.uniform(0.0, 2.0, size=(n, s))
    S = rng.uniform(0.0, 1.0, size=(n, s))
    N, fine = n - 1, 3
    h = N / (M * fine)
    kmin, kmax = max(1, math.ceil(1 / h - 1e-9)), math.floor(s / h + 1e-9)
    lb = np.zeros(M + 1, dtype=np.int64)
    ub = np.full(M + 1, M * fine, dtype=np.int64)
    ub[0], lb[-1] = 0, M * fine
    lo, hi = st._fine_band(lb, ub, kmin, kmax)
    lam = float(rng.uniform(0.1, 2.0))
    cost_into, level = st._step_tables(D, S, 0.0, h, M * fine, kmin, kmax)
    rho = st.change_penalties(kmin, kmax, lam)
    return dict(D=D, S=S, h=h, kmin=kmin, kmax=kmax, lo=lo, hi=hi, lam=lam, M=M, fine=fine,
                tables=(cost_into, level, rho))


def _search(st, args, upper=np.inf):
    """The compiled search over the band with its Lagrangian bound, pruning above ``upper``."""
    cost_into, level, rho, lo, hi, kmin, kmax = args
    prices, to_go, *_ = st.step_price(cost_into, level, rho, kmin, kmax, len(lo) - 1)
    return st._segment_dp(*args, to_go, prices, upper)


@pytest.mark.parametrize("seed", range(6))
def test_segment_search_is_the_brute_force_optimum(seed):
    """Every fine path of a tiny segment enumerated and scored from the formula: the search's
    warp is the cheapest, and its objective is that warp's."""
    import itertools

    from retime.guided import steady as st

    rng = np.random.default_rng(seed)
    t = _tiny_segment(rng)
    q, obj = _search(st, (*t["tables"], t["lo"], t["hi"], t["kmin"], t["kmax"]))
    total = t["M"] * t["fine"]
    best = np.inf
    for steps in itertools.product(range(t["kmin"], t["kmax"] + 1), repeat=t["M"]):
        if sum(steps) == total:
            x = np.concatenate([[0], np.cumsum(steps)]) * t["h"]
            best = min(best, _objective_from_definition(t["D"], t["S"], x, t["lam"]))
    assert obj == pytest.approx(best, rel=1e-9)
    assert _objective_from_definition(t["D"], t["S"], q * t["h"], t["lam"]) == pytest.approx(obj, rel=1e-9)


def test_monotone_min_matches_the_full_minimum():
    """The divide-and-conquer minimum over previous steps equals the plain one for every step, also
    with rows partly inf (states not reached), on random rows and prices."""
    from retime.guided import steady as st

    rng = np.random.default_rng(1)
    for trial in range(200):
        kmin = int(rng.integers(1, 8))
        kmax = kmin + int(rng.integers(0, 40))
        K = kmax - kmin + 1
        rho = st.change_penalties(kmin, kmax, float(rng.uniform(0.0, 5.0)))
        level = np.cumsum(rng.uniform(0.0, 3.0, size=K) * (rng.uniform(size=K) < 0.8))  # never decreasing
        row = rng.uniform(0.0, 10.0, size=K)
        row[rng.uniform(size=K) < rng.uniform(0.0, 0.9)] = np.inf
        b0 = int(rng.integers(0, K))
        b1 = int(rng.integers(b0, K))
        val, arg = np.empty(K), np.empty(K, dtype=np.int64)
        st._monotone_min(row, rho, level, b0, b1, val, arg, np.empty((2 * K + 2, 4), dtype=np.int64))
        full = row[None, :] + rho + np.abs(level[:, None] - level[None, :])
        for b in range(b0, b1 + 1):
            if np.isfinite(full[b]).any():
                assert val[b] == full[b].min()
                assert arg[b] == int(np.argmin(full[b]))
            else:
                assert arg[b] == -1


def _real_segment(motion, scale):
    """The refinement's tables for the whole-clip segment of ``motion`` at ``scale``."""
    import math

    from retime.guided import api
    from retime.guided import steady as st

    seen = {}
    original = api.steady_warp

    def spy(F, frames, fixed, steadiness, natural=1.0, **kw):
        seen.update(F=F, frames=frames, steadiness=steadiness, natural=natural)
        return original(F, frames, fixed, steadiness, natural, **kw)

    api.steady_warp = spy
    try:
        guided_solve(motion, scale=scale)
    finally:
        api.steady_warp = original
    F, y = seen["F"], seen["frames"]
    D, S = st.speed_costs(F), st.change_costs(F)
    M, a0, a1 = len(y) - 1, int(y[0]), int(y[-1])
    N = a1 - a0
    fine = st.points_per_step(N, M, float(np.atleast_1d(seen["natural"])[0]))
    h = N / (M * fine)
    kmin, kmax = max(1, math.ceil(1 / h - 1e-9)), math.floor(F.shape[1] / h + 1e-9)
    lb = np.zeros(M + 1, dtype=np.int64)
    ub = np.full(M + 1, M * fine, dtype=np.int64)
    ub[0], lb[-1] = 0, M * fine
    lo, hi = st._fine_band(lb, ub, kmin, kmax)
    lam = st.penalty_weight(D, a0, a1, N / M, seen["steadiness"])
    cost_into, level = st._step_tables(D, S, float(a0), h, M * fine, kmin, kmax)
    return (cost_into, level, st.change_penalties(kmin, kmax, lam), lo, hi, kmin, kmax)




@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_segment_search_matches_its_numpy_twin_on_a_real_clip(jump, scale):
    """The compiled search against its plain twin (every pair of steps, no monotone search, no
    pruning) on a real segment; pruned with the optimum itself as the bound it is the same again."""
    from retime.guided import steady as st

    args = _real_segment(jump, scale)
    q_np, obj_np = st.segment_dp_numpy(*args)
    for upper in (np.inf, obj_np * (1 + 1e-12)):
        q, obj = _search(st, args, upper)
        assert obj == obj_np
        assert np.array_equal(q, q_np)


@pytest.mark.parametrize("seed", range(4))
def test_segment_search_matches_its_numpy_twin_on_random_tables(seed):
    from retime.guided import steady as st

    t = _tiny_segment(np.random.default_rng(100 + seed), n=40, s=5, M=14)
    args = (*t["tables"], t["lo"], t["hi"], t["kmin"], t["kmax"])
    q_np, obj_np = st.segment_dp_numpy(*args)
    for upper in (np.inf, obj_np * (1 + 1e-12)):
        q, obj = _search(st, args, upper)
        assert obj == pytest.approx(obj_np, rel=1e-12)
        assert np.array_equal(q, q_np)


@pytest.mark.parametrize("case", ["jump 0.6", "jump 1.5", "random 0", "random 1"])
def test_deepening_search_finds_the_twins_optimum(jump, case):
    """The search that starts with its bound at (or just above) the dual value and raises it until a
    warp lies within: the plain twin's optimum and warp, whatever the first bound (the dual value
    itself, which a warp can only meet when the duality gap is 0, or a thousandth of it), and with a
    known warp's objective as a cap."""
    from retime.guided import steady as st

    if case.startswith("jump"):
        args = _real_segment(jump, float(case.split()[1]))
    else:
        t = _tiny_segment(np.random.default_rng(200 + int(case.split()[1])), n=40, s=5, M=14)
        args = (*t["tables"], t["lo"], t["hi"], t["kmin"], t["kmax"])
    q_np, obj_np = st.segment_dp_numpy(*args)
    cost_into, level, rho, lo, hi, kmin, kmax = args
    prices, to_go, _, dual, _ = st.step_price(cost_into, level, rho, kmin, kmax, len(lo) - 1)
    assert dual <= obj_np * (1 + 1e-12)
    for unit, tight, known in ((1e-3 * abs(dual), True, np.inf), (1e-6, False, np.inf),
                               (1e-6, False, obj_np * 1.5)):
        q, obj = st.bounded_search(*args, to_go, prices, dual, unit, tight, known)
        assert obj == pytest.approx(obj_np, rel=1e-12)
        assert np.array_equal(q, q_np)


@pytest.mark.parametrize("case", ["jump 0.6", "jump 1.5", "random 0", "random 1"])
def test_priced_relaxation_matches_its_numpy_twin(jump, case):
    """The compiled relaxation (every pair of steps, vectorised, the warp traced afterwards) against
    its plain twin: the same bounds to the bit, least cost, step count and warp, at prices either
    side of the segment's own."""
    from retime.guided import steady as st

    if case.startswith("jump"):
        args = _real_segment(jump, float(case.split()[1]))
    else:
        t = _tiny_segment(np.random.default_rng(300 + int(case.split()[1])), n=40, s=5, M=14)
        args = (*t["tables"], t["lo"], t["hi"], t["kmin"], t["kmax"])
    cost_into, level, rho, lo, hi, kmin, kmax = args
    ahead = st._steps_ahead(cost_into, kmin, kmax)
    typical = float(np.median(cost_into[np.isfinite(cost_into)]))
    counts = set()
    for price in (-5.0 * typical, -0.5 * typical, 0.0, 0.3 * typical, 2.0 * typical, 10.0 * typical):
        B, total, count, path = st._priced_to_go(ahead, level, rho, kmin, kmax, price)
        B_np, total_np, count_np, path_np = st.priced_to_go_numpy(cost_into, level, rho, kmin, kmax, price)
        assert np.array_equal(B, B_np)
        assert total == total_np and count == count_np
        assert np.array_equal(path, path_np)
        counts.add(count)
    assert len(counts) > 1  # the prices move the warp


@pytest.mark.parametrize("price", [-1.0, 0.0, 0.7])
def test_priced_bound_is_below_every_continuation(price):
    """The pruning's bound: from every state (q, last step) of a tiny segment, every continuation
    with any number r of steps, scored from the formula, costs at least B[q, a] - price r; and the
    relaxation's own warp costs what it says."""
    import itertools

    from retime.guided import steady as st

    t = _tiny_segment(np.random.default_rng(7))
    cost_into, level, rho = t["tables"]
    kmin, kmax, end, h = t["kmin"], t["kmax"], t["M"] * t["fine"], t["h"]
    B, total, count, path = st._priced_to_go(st._steps_ahead(cost_into, kmin, kmax), level, rho, kmin, kmax, price)
    assert _objective_from_definition(t["D"], t["S"], path * h, t["lam"]) + price * count == pytest.approx(total)
    assert path[0] == 0 and path[-1] == end and len(path) == count + 1
    for q in range(end):
        for a in range(kmax - kmin + 1):
            prev_step = kmin + a
            if q - prev_step < 0:
                continue
            for r in range(1, (end - q) // kmin + 1):
                for steps in itertools.product(range(kmin, kmax + 1), repeat=r):
                    if q + sum(steps) != end:
                        continue
                    x = np.concatenate([[q - prev_step, q], q + np.cumsum(steps)]) * h
                    # the continuation's cost: the whole path's less its first step's score
                    rest = _objective_from_definition(t["D"], t["S"], x, t["lam"]) - cost_into[q, a]
                    assert rest >= B[q, a] - price * r - 1e-9


def paced_walk(base: Motion, fps=30.0, seconds=6.0, hz=1.1, turn=False):
    """A sine "walk" at ``fps`` that starts and ends standing (0.8 s still, 0.6 s ramps) or, with
    ``turn``, walks throughout and slows to 40% of its pace for 1.5 s mid-clip: the limbs' phase and
    the root advance with the pace, so the standing (or slow) parts move little, and the paper's score
    would play them faster."""
    t = np.arange(int(seconds * fps)) / fps
    if turn:
        pace = 1.0 - 0.6 * np.clip(np.minimum(t - 1.8, 4.2 - t) / 0.5, 0.0, 1.0)
    else:
        pace = np.clip(np.minimum(t - 0.8, seconds - 0.8 - t) / 0.6, 0.0, 1.0)
    travelled = np.concatenate([[0.0], np.cumsum(0.5 * (pace[1:] + pace[:-1]) / fps)])
    J = base.skeleton.n_joints
    amp = np.linspace(0.2, 0.6, J) * pace[:, None]
    theta = amp * np.sin(2 * np.pi * hz * travelled[:, None] + np.linspace(0.0, 2 * np.pi, J, endpoint=False))
    rot = np.zeros((len(t), J, 4))
    rot[..., 0] = np.sin(theta / 2)
    rot[..., 3] = np.cos(theta / 2)
    tr = np.repeat(base.translations[:1], len(t), axis=0).copy()
    tr[:, 0, 0] = base.translations[0, 0, 0] + 20.0 * travelled
    tr[:, 0, 1] = base.translations[0, 0, 1] + 0.5 * pace * np.sin(4 * np.pi * hz * travelled)
    return Motion(base.skeleton, rot, tr, fps)


def _middle_spread(motion, scale, **options):
    v = step_speeds(guided_solve(motion, scale=scale, **options).curve, motion.fps)
    cut = len(v) // 20
    mid = v[cut:len(v) - cut]
    return mid.std() / mid.mean(), mid.max() / mid.min(), np.median(mid)


@pytest.mark.parametrize("scale", [0.6, 1.5])
@pytest.mark.parametrize("turn", [False, True], ids=["standing-ends", "slows-in-a-turn"])
def test_a_walk_whose_pace_changes_plays_at_one_speed(walk, scale, turn):
    """Issue 23: an animator who speeds a walk up expects it uniformly faster, its standing or slow
    parts included (the reference's own score would squeeze them: checked with the pull off)."""
    motion = paced_walk(walk, turn=turn)
    cv, ratio, median = _middle_spread(motion, scale)
    assert cv <= 0.05 and ratio <= 1.3
    assert median == pytest.approx(1 / scale, rel=0.05)
    assert _middle_spread(motion, scale, pace=0.0)[0] > 0.05  # the defect the pull removes


@pytest.mark.parametrize("variant", ["float32", "cm", "z-up", "dummy-root"])
def test_the_steady_pace_survives_rounding_units_and_axes(walk, variant):
    """The same walk rounded to float32, in centimetres, Z-up or under a studio's dummy root plays the same."""
    from retime.motion import variants as V

    motion = paced_walk(walk)
    if variant == "float32":
        changed = Motion(motion.skeleton, motion.rotations.astype(np.float32).astype(float),
                         motion.translations.astype(np.float32).astype(float), motion.fps)
    elif variant == "cm":
        changed = V.rescale(motion, 100.0)
    elif variant == "z-up":
        changed = V.turn_up(motion, "+z")
    else:
        changed = V.add_dummy_root(motion)
    for scale in (0.6, 1.5):
        assert _middle_spread(changed, scale)[:2] == pytest.approx(_middle_spread(motion, scale)[:2], abs=0.01)


@pytest.mark.parametrize("scale", [0.6, 1.5])
def test_a_jump_flight_keeps_its_natural_speed_under_the_pull(jump, scale):
    from retime.motion.feet import foot_contacts
    from retime.phases import longest_flight

    a, b = longest_flight(foot_contacts(jump), np.arange(jump.n_frames) / jump.fps)
    assert interval_speed(guided_solve(jump, scale=scale).curve, a, b) == pytest.approx(1.0, abs=0.05)


def test_the_ground_target_leaves_room_for_the_flight():
    """pace_penalties: with no flight the pull is to the mean step; with one, the ground's steady step
    times the ground's output steps plus the flight at its natural step spans the segment."""
    from retime.guided.steady import pace_penalties

    n_fine, fine, kmin, kmax = 400, 10, 4, 40
    h = 0.2  # grid frames per fine point: natural (1 grid frame) is 5 fine points
    ground = pace_penalties(np.ones(100), 0.0, h, n_fine, kmin, kmax, fine, 1.0, 1.0)
    k = np.arange(kmin, kmax + 1)
    assert np.all(k[np.argmin(ground, axis=1)] == fine)
    grounded = np.ones(100)
    grounded[40:60] = 0.0
    pulls = pace_penalties(grounded, 0.0, h, n_fine, kmin, kmax, fine, 1.0, 1.0)
    q = np.arange(n_fine + 1)
    on = np.interp(q * h, np.arange(100), grounded)
    flying = np.sum(1.0 - on[1:])
    steady = (n_fine - flying) / (n_fine / fine - flying * h / 1.0)
    assert pulls[10] == pytest.approx((np.log(k) - np.log(steady)) ** 2)
    assert pulls[250] == pytest.approx((np.log(k) - np.log(5.0)) ** 2)
    assert steady * (n_fine / fine - flying * h) + flying == pytest.approx(n_fine)


def test_finite_median_max_matches_its_numpy_twin():
    """The one-pass median and largest finite entry equal NumPy's on the masked table, to the bit
    (the step prices, and so the search's pruning, start from them); inf if nothing is finite."""
    from retime.guided import steady as st

    rng = np.random.default_rng(2)
    for trial in range(300):
        T = rng.uniform(0.0, 10.0, size=(int(rng.integers(1, 40)), int(rng.integers(1, 9))))
        T[rng.uniform(size=T.shape) < rng.uniform(0.0, 1.0)] = np.inf
        assert tuple(map(float, st._finite_median_max(T))) == st.finite_median_max_numpy(T)
    assert tuple(map(float, st._finite_median_max(np.full((3, 2), np.inf)))) == (np.inf, np.inf)


def test_fill_gaps_takes_the_nearest_finite_row():
    """Every inf entry takes its column's nearest finite row (the earlier of two as near), brute force."""
    from retime.guided import steady as st

    rng = np.random.default_rng(3)
    for trial in range(300):
        D = rng.uniform(0.0, 1.0, size=(int(rng.integers(1, 20)), int(rng.integers(1, 5))))
        D[rng.uniform(size=D.shape) < rng.uniform(0.0, 1.0)] = np.inf
        want = D.copy()
        for c in range(D.shape[1]):
            ok = np.flatnonzero(np.isfinite(D[:, c]))
            for j in range(D.shape[0]):
                if ok.size and not np.isfinite(D[j, c]):
                    want[j, c] = D[ok[np.argmin(np.abs(ok - j))], c]  # argmin: the first, the earlier
        assert np.array_equal(st._fill_gaps(D.copy()), want)


def test_price_bisection_keeps_a_price_that_gives_the_step_count():
    """A cut that lands on a price giving exactly M steps ends the bisection there (the middle of
    the range it had narrowed would be far from it: the relaxations started 14 times further off
    on V1 and needed five instead of one)."""
    from retime.guided import steady as st

    def count_at(price):  # falls as the price rises; M = 50 steps for prices in (4.9, 5.0]
        return int(np.floor(100.0 - 10.0 * price))

    tried = []
    lo, hi = st._bisect_price(lambda p: tried.append(p) or count_at(p), 50, -1.0, 1.0, 1e3, 8)
    assert any(count_at(p) == 50 for p in tried)
    assert count_at(0.5 * (lo + hi)) == 50


def test_add_pace_matches_the_pace_penalties_table():
    """The in-place kernel adds pace_penalties' table (its NumPy twin) to the step scores, to the bit,
    with and without flights."""
    from retime.guided import steady as st

    rng = np.random.default_rng(4)
    for trial in range(40):
        n_fine, fine = int(rng.integers(20, 400)), int(rng.integers(8, 13))
        kmin, kmax = int(rng.integers(1, 6)), int(rng.integers(8, 50))
        h = float(rng.uniform(0.05, 0.6))
        grounded = (rng.uniform(size=int(n_fine * h) + 3) > rng.uniform(0.0, 0.5)).astype(float)
        args = (grounded, float(rng.uniform(0, 2)), h, n_fine, kmin, kmax, fine, float(rng.uniform(0.5, 2.0)))
        weight = float(rng.uniform(0.1, 30.0))
        scores = rng.uniform(0.0, 5.0, size=(n_fine + 1, kmax - kmin + 1))
        scores[rng.uniform(size=scores.shape) < 0.1] = np.inf
        want = scores + st.pace_penalties(*args, weight)
        st._add_pace(scores, *st.pace_targets(*args), weight)
        assert np.array_equal(scores, want)


def test_speed_tables_match_speed_costs_and_change_costs():
    """The one-pass kernel gives speed_costs' and change_costs' tables (its NumPy twins) to the bit,
    gaps filled from the nearest row, on tables with unscored triples, whole unscored columns and
    one speed."""
    from retime.guided import steady as st

    rng = np.random.default_rng(5)
    for trial in range(200):
        n, s = int(rng.integers(1, 30)), int(rng.integers(1, 9))
        F = rng.uniform(0.0, 4.0, size=(n, s, 8 * ((s + 7) // 8)))
        F[rng.uniform(size=F.shape) < rng.uniform(0.0, 0.7)] = np.inf
        if trial % 10 == 0:
            F[:, :, int(rng.integers(0, s))] = np.inf
        D, S = st._speed_tables(F)
        assert np.array_equal(D, st.speed_costs(F)) and np.array_equal(S, st.change_costs(F))


def test_a_relaxation_warp_with_the_step_count_is_the_optimum(jump):
    """The refinement returns the best price's relaxation warp without a search when it takes exactly
    the segment's step count (it is then optimal): it is the plain twin's warp, and path_objective
    sums a warp as the search does (the search's objective to the bit)."""
    from retime.guided import steady as st

    cases = [_real_segment(jump, scale) for scale in (0.6, 1.5)]
    for seed in range(6):
        t = _tiny_segment(np.random.default_rng(300 + seed), n=40, s=5, M=14)
        cases.append((*t["tables"], t["lo"], t["hi"], t["kmin"], t["kmax"]))
    exact = 0
    for args in cases:
        cost_into, level, rho, lo, hi, kmin, kmax = args
        q_np, obj_np = st.segment_dp_numpy(*args)
        for width in (None, 1.0):  # the scale's first price range, and a narrow one
            prices, to_go, path, dual, _ = st.step_price(cost_into, level, rho, kmin, kmax, len(lo) - 1,
                                                         first_width=width)
            q, obj = st._segment_dp(*args, to_go, prices, np.inf)
            assert st.path_objective(cost_into, level, rho, q, kmin) == obj
            if path is not None and len(path) == len(lo):
                exact += 1
                assert np.array_equal(path, q_np) and np.array_equal(path, q)
                assert st.path_objective(cost_into, level, rho, path, kmin) == obj
                assert obj == pytest.approx(obj_np, rel=1e-12) and dual == pytest.approx(obj, rel=1e-12)
    assert exact >= 4
