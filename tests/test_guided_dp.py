"""Exact optimisation of guided time warping against brute-force enumeration."""
import numpy as np
import pytest

from retime.guided import dp


def random_table(rng, n, s):
    F = np.full((n, s, 8 * ((s + 7) // 8)), np.inf)
    F[:, :, :s] = rng.random((n, s, s)) ** 2
    return F


def check_warp(frames, n, m, s, fixed=()):
    frames = np.asarray(frames)
    assert len(frames) == m and frames[0] == 0 and frames[-1] == n - 1
    gaps = np.diff(frames)
    assert np.all(gaps >= 1) and np.all(gaps <= s)
    for p, a in dict(fixed).items():
        assert frames[p] == a


@pytest.mark.parametrize("seed", range(6))
def test_fixed_length_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        n = int(rng.integers(3, 13))
        s = int(rng.integers(1, 10))
        F = random_table(rng, n, s)
        m = int(rng.integers(-(-(n - 1) // s) + 1, n + 1))
        fixed = {}
        if m > 3 and rng.random() < 0.4:
            p = int(rng.integers(1, m - 1))
            fixed = {p: int(rng.integers(p, n - (m - 1 - p)))}
        best, _ = dp.brute_force(F, m, fixed)
        if not np.isfinite(best):
            with pytest.raises(dp.InfeasibleWarp):
                dp.solve_fixed(F, m, fixed)
            continue
        for parallel in (False, True):
            sol = dp.solve_fixed(F, m, fixed, parallel=parallel)
            check_warp(sol.frames, n, m, s, fixed)
            assert sol.objective == pytest.approx(best, rel=1e-12, abs=1e-12)
            assert dp.path_cost(F, sol.frames) == pytest.approx(sol.objective, rel=1e-12, abs=1e-12)


def test_free_length_matches_brute_force():
    rng = np.random.default_rng(9)
    for _ in range(60):
        n = int(rng.integers(2, 12))
        s = int(rng.integers(1, 6))
        F = random_table(rng, n, s)
        best, _ = dp.brute_force(F)
        sol = dp.solve_free(F)
        check_warp(sol.frames, n, len(sol.frames), s)
        assert sol.objective == pytest.approx(best, rel=1e-12, abs=1e-12)


def test_identity_when_no_frame_may_be_dropped():
    rng = np.random.default_rng(1)
    F = random_table(rng, 30, 8)
    sol = dp.solve_fixed(F, 30)
    assert np.array_equal(sol.frames, np.arange(30))


def test_band_is_exactly_the_reachable_set():
    n, m, s = 17, 9, 3
    fixed = {4: 7}
    band = dp.feasible_band(n, m, s, fixed)
    # brute force reachability: frame a at position p lies on some feasible path
    import itertools
    ok = np.zeros((m, n), dtype=bool)
    for mid in itertools.combinations(range(1, n - 1), m - 2):
        f = (0, *mid, n - 1)
        if max(np.diff(f)) <= s and f[4] == 7:
            ok[np.arange(m), f] = True
    for p in range(m):
        frames = np.nonzero(ok[p])[0]
        assert band.lo[p] == frames.min() and band.hi[p] == frames.max()
        assert np.all(ok[p, band.lo[p]:band.hi[p] + 1])
    assert band.lo[4] == band.hi[4] == 7


def test_infeasible_messages():
    with pytest.raises(dp.InfeasibleWarp, match="takes 3 to 20 steps"):
        dp.feasible_band(21, 3, 8)  # 20 frames in 2 steps of at most 8
    with pytest.raises(dp.InfeasibleWarp) as info:
        dp.feasible_band(30, 20, 4, {5: 2})
    assert info.value.segment is not None


@pytest.mark.parametrize("seed", range(4))
def test_lagrangian_pruning_keeps_the_optimum(seed):
    rng = np.random.default_rng(100 + seed)
    for _ in range(25):
        n = int(rng.integers(20, 150))
        s = int(rng.integers(2, 9))
        F = random_table(rng, n, s)
        m = int(rng.integers(-(-(n - 1) // s) + 2, n))
        band = dp.feasible_band(n, m, s)
        exact = dp.solve_fixed(F, m, band=band)
        for slack in (0.0, 0.02, 0.5):
            pruned = dp.prune_band(F, m, band, exact.objective * (1 + slack))
            assert np.all(pruned.lo >= band.lo) and np.all(pruned.hi <= band.hi)
            sol = dp.solve_fixed(F, m, band=pruned)
            assert sol.objective == pytest.approx(exact.objective, rel=1e-12)


def test_lagrange_path_is_optimal_for_its_own_length():
    """A path that minimises cost + lam * steps is the cheapest of all paths with as many frames."""
    rng = np.random.default_rng(21)
    for _ in range(10):
        n, s = int(rng.integers(6, 12)), int(rng.integers(2, 5))
        F = random_table(rng, n, s)
        m = int(rng.integers(-(-(n - 1) // s) + 1, n + 1))
        path = dp.lagrange_path(F, m)
        check_warp(path, n, len(path), s)
        best, _ = dp.brute_force(F, len(path))
        assert dp.path_cost(F, path) == pytest.approx(best, rel=1e-12, abs=1e-12)
        # and the dual value never exceeds the optimum with exactly m frames
        opt, _ = dp.brute_force(F, m)
        for value, _lam in dp.lagrange_multipliers(F, m)[:5]:
            assert value <= opt + 1e-9
