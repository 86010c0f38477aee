"""Local score (kNN) of guided time warping against explicit brute-force computations."""
import numpy as np
import pytest

from retime.errors import RetimeError
from retime.guided.features import FeatureWeights, reference_features, triple_features
from retime.guided.score import all_triples, score_table, score_table_bruteforce, table_width


def walk(rng, n, d, step=0.02):
    return np.cumsum(rng.normal(size=(n, d)) * step, axis=0)


def explicit_scores(x, z, coeffs, s, k, stride=1):
    """Independent computation: every triple's feature, every distance, full sort."""
    zf = reference_features(z, coeffs, stride)
    n = x.shape[0]
    out = np.full((n, s, table_width(s)), np.inf)
    for j in range(n):
        for d in range(1, s + 1):
            for e in range(1, s + 1):
                i, kk = j - d, j + e
                if i < 0 or kk >= n:
                    continue
                y = triple_features(x, [i], [j], [kk], coeffs)[0]
                dist = np.sort(np.sqrt(((zf - y) ** 2).sum(axis=1)))
                out[j, d - 1, e - 1] = dist[: min(k, len(dist))].mean()
    return out


@pytest.mark.parametrize("n,r,s,k,stride", [(30, 25, 4, 3, 1), (26, 18, 8, 1, 1), (22, 30, 5, 4, 1),
                                            (20, 9, 3, 3, 2), (24, 40, 11, 2, 3), (12, 3, 2, 3, 1)])
def test_exact_knn_matches_explicit_search(n, r, s, k, stride):
    rng = np.random.default_rng(n * 100 + r)
    x, z = walk(rng, n, 12), walk(rng, r, 12)
    coeffs = FeatureWeights(1.0, 0.15, 0.02).coefficients(30.0)
    F = score_table(x, z, coeffs, s, k, ref_stride=stride)
    E = explicit_scores(x, z, coeffs, s, k, stride)
    assert F.shape == E.shape
    assert np.array_equal(np.isfinite(F), np.isfinite(E))
    fin = np.isfinite(E)
    np.testing.assert_allclose(F[fin], E[fin], rtol=1e-9, atol=1e-9)
    # the plain NumPy reference implementation agrees too
    B = score_table_bruteforce(x, z, coeffs, s, k, ref_stride=stride)
    np.testing.assert_allclose(B[fin], E[fin], rtol=1e-9, atol=1e-9)


def test_identity_triples_score_zero_with_one_neighbour():
    """With the input as its own reference, the triple (j-1, j, j+1) is a reference feature: f = 0."""
    rng = np.random.default_rng(5)
    x = walk(rng, 40, 9)
    F = score_table(x, x, FeatureWeights().coefficients(30.0), 4, 1)
    assert np.allclose(F[1:-1, 0, 0], 0.0, atol=1e-6)
    assert np.all(F[1:-1, 1:, :4][np.isfinite(F[1:-1, 1:, :4])] > 0)


def test_mask_and_blocks():
    rng = np.random.default_rng(7)
    x, z = walk(rng, 60, 6), walk(rng, 50, 6)
    co = FeatureWeights().coefficients(30.0)
    full = score_table(x, z, co, 5, 3)
    mask = rng.random((60, 5)) < 0.4
    part = score_table(x, z, co, 5, 3, mask=mask)
    sel = np.broadcast_to(mask[:, :, None], full.shape)
    assert np.array_equal(part[sel], full[sel])
    assert np.all(np.isinf(part[~sel]))
    # tiny blocks (many matrix products) give the same table
    small = score_table(x, z, co, 5, 3, block_bytes=1)
    assert np.array_equal(np.isfinite(small), np.isfinite(full))
    np.testing.assert_allclose(small[np.isfinite(full)], full[np.isfinite(full)], rtol=1e-12)


def test_approximate_search_bounds():
    rng = np.random.default_rng(11)
    x, z = walk(rng, 40, 8), walk(rng, 60, 8)
    co = FeatureWeights().coefficients(30.0)
    exact = score_table(x, z, co, 4, 3)
    fin = np.isfinite(exact)
    same = score_table(x, z, co, 4, 3, method="approx", eps=0.0)
    np.testing.assert_allclose(same[fin], exact[fin], rtol=1e-9, atol=1e-12)
    loose = score_table(x, z, co, 4, 3, method="approx", eps=0.5)
    assert np.all(loose[fin] >= exact[fin] - 1e-9)
    assert np.all(loose[fin] <= 1.5 * exact[fin] + 1e-9)


def test_feature_is_linear_in_frames():
    rng = np.random.default_rng(2)
    x = walk(rng, 10, 5)
    a, b, c = co = FeatureWeights(2.0, 0.3, 0.05).coefficients(24.0)
    y = triple_features(x, [1], [3], [7], co)[0]
    D = x.shape[1]
    np.testing.assert_allclose(y[:D], a * x[3])
    np.testing.assert_allclose(y[D:2 * D], 0.3 * (x[7] - x[1]) * 24.0 / 2)  # m/s over two output steps
    np.testing.assert_allclose(y[2 * D:], 0.05 * (x[7] - 2 * x[3] + x[1]) * 24.0 ** 2)
    i, j, k, d, e = all_triples(10, 3)
    assert np.all((j - i == d) & (k - j == e) & (i >= 0) & (k < 10))


def test_bad_inputs():
    co = FeatureWeights().coefficients(30.0)
    with pytest.raises(RetimeError, match="at least 3"):
        score_table(np.zeros((5, 3)), np.zeros((2, 3)), co, 2)
    with pytest.raises(RetimeError, match="same D"):
        score_table(np.zeros((5, 3)), np.zeros((5, 4)), co, 2)
    with pytest.raises(RetimeError, match="NaN"):
        score_table(np.full((5, 3), np.nan), np.zeros((5, 3)), co, 2)
    with pytest.raises(RetimeError):
        FeatureWeights(-1.0)
