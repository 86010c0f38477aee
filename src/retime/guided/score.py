"""Local score of guided time warping (Hsu et al. 2007, eq. 2).

``f(i, j, k)`` is the mean Euclidean distance from the feature vector of the
frame triple ``(i, j, k)`` (see :mod:`retime.guided.features`) to its ``K``
nearest reference feature vectors.

Score table layout: ``F[j, d-1, e-1] = f(j-d, j, j+e)`` for ``1 <= d, e <= s``
(``s`` = skip limit), shape ``(n, s, S8)`` with ``S8 = 8 * ceil(s / 8)`` (the DP reads
eight ``e`` at a time); entries whose frames fall outside the input, that were not asked
for, or with ``e > s`` are ``inf``. This is the weight of the graph edge from vertex
``(j-d, j)`` to vertex ``(j, j+e)`` of section 3.3.

Exact method. The feature of a triple is linear in the three frames, so with
``G = X Z^T`` (dot products of every input pose with every reference pose) the
squared distance to reference feature ``r`` is::

    |y|^2 + |z_r|^2 - 2 (PI[i, r] + PJ[j, r] + PK[k, r])

where ``PI``, ``PJ``, ``PK`` are three-tap filters of ``G`` along ``r`` and
``|y|^2`` comes from a band of the input's own Gram matrix. One matrix product
(done by BLAS, in blocks of input frames to bound memory) replaces all
``D``-dimensional work; the ``n s^2 R`` distances then cost one multiply-add
each, and a compiled kernel keeps the exact ``K`` smallest per triple.

Approximate method: a KD-tree (SciPy ``cKDTree``) over the reference features,
queried with relative error ``eps`` (each returned distance is at most
``1 + eps`` times the true one), as the paper does for large references.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numba import njit, prange

from retime.errors import RetimeError
from retime.blas import single_threaded_blas
from retime.guided._jit import compiled
from retime.guided.features import reference_features, triple_features

INF = np.inf
_CHUNK = 1024  # references per chunk in the exact kNN kernel (a multiple of 8)


@njit(cache=True, inline="always")
def _base_row(zz, pi, pj, base):
    """base[r] = |z_r|^2 - 2 (PI[i, r] + PJ[j, r]) for the vertex (i, j)."""
    for r in range(zz.shape[0]):
        base[r] = zz[r] - 2.0 * (pi[r] + pj[r])


@njit(cache=True, inline="always")
def _mean_root(H, i, j, d, e, a2, b2, c2, top, K):
    """Mean over q < K of sqrt(|y|^2 + top[q]) for the triple (i, j, k = j+1+e), i = j - d.

    |y|^2 = a2 |x_j|^2 + b2 |x_k - x_i|^2 + c2 |x_k - 2 x_j + x_i|^2 from the Gram band H.
    """
    k = j + 1 + e
    hi = H[i, 0]
    hj = H[j, 0]
    hk = H[k, 0]
    hik = H[i, d + e + 1]  # x_i . x_k (gap d + e + 1)
    yy = (a2 * hj + b2 * (hi + hk - 2.0 * hik)
          + c2 * (hk + 4.0 * hj + hi - 4.0 * H[j, e + 1] - 4.0 * H[i, d] + 2.0 * hik))
    acc = 0.0
    for q in range(K):
        v = yy + top[q]
        acc += math.sqrt(v) if v > 0.0 else 0.0
    return acc / K


@njit(cache=True, parallel=True, fastmath={"nsz", "contract"})
def _knn3_kernel(PI, PJ, PK, zz, H, t0, j0, j1, n, s, K, a2, b2, c2, mask, out):
    """Exact K <= 3 smallest distances for every triple with middle frame j in [j0, j1).

    For a vertex (i, j): ``base[r] = |z_r|^2 - 2 (PI[i, r] + PJ[j, r])`` and, for each
    k = j+1+e, ``v[r] = base[r] - 2 PK[k, r]`` is the squared distance minus |y|^2. Eight
    references at a time go through a branch-free sorted-insertion network (per lane the three
    smallest so far: c = min(c, max(b, v)); b = min(b, max(a, v)); a = min(a, v)), which the
    SLP vectoriser turns into AVX min/max; the 24 lane survivors are merged at the end.
    References are taken in chunks of _CHUNK so that the s base rows and s PK rows of a middle
    frame stay in the L2 cache while its s^2 triples are scanned (the network state of each
    triple is kept between chunks). Arrays are padded to Rp references (zz with inf).
    Unsigned indices in the inner loop keep numba from emitting negative-index fix-ups (with
    slices ``bd[q:q + 8]`` the clamping of the slice bounds cost 8% of the kernel).
    """
    Rp = PK.shape[1]
    for j in prange(j0, j1):
        ne = min(s, n - 1 - j)
        if ne <= 0:
            continue
        state = np.full((s, ne, 24), INF)
        base = np.empty((s, min(_CHUNK, Rp)))
        top = np.empty(3)
        rj = j - t0
        pj = PJ[rj]
        for r0 in range(0, Rp, _CHUNK):
            L = min(_CHUNK, Rp - r0)
            for d in range(1, s + 1):
                i = j - d
                if i < 0:
                    break
                if not mask[j, d - 1]:
                    continue
                zc = zz[r0:r0 + L]
                pic = PI[i - t0, r0:r0 + L]
                pjc = pj[r0:r0 + L]
                bd = base[d - 1]
                for q in range(L):
                    u = np.uint64(q)  # vectorised (with signed indices it stayed scalar: 20% of the kernel)
                    bd[u] = zc[u] - 2.0 * (pic[u] + pjc[u])
                for e in range(ne):
                    row = PK[rj + 1 + e, r0:r0 + L]
                    st = state[d - 1, e]
                    a0 = st[0]
                    a1 = st[1]
                    a2x = st[2]
                    a3 = st[3]
                    a4 = st[4]
                    a5 = st[5]
                    a6 = st[6]
                    a7 = st[7]
                    b0 = st[8]
                    b1 = st[9]
                    b2x = st[10]
                    b3 = st[11]
                    b4 = st[12]
                    b5 = st[13]
                    b6 = st[14]
                    b7 = st[15]
                    c0 = st[16]
                    c1 = st[17]
                    c2x = st[18]
                    c3 = st[19]
                    c4 = st[20]
                    c5 = st[21]
                    c6 = st[22]
                    c7 = st[23]
                    for g in range(L // 8):
                        q = np.uint64(8 * g)  # unsigned: no negative-index fix-ups
                        v0 = bd[q] - 2.0 * row[q]
                        v1 = bd[q + np.uint64(1)] - 2.0 * row[q + np.uint64(1)]
                        v2 = bd[q + np.uint64(2)] - 2.0 * row[q + np.uint64(2)]
                        v3 = bd[q + np.uint64(3)] - 2.0 * row[q + np.uint64(3)]
                        v4 = bd[q + np.uint64(4)] - 2.0 * row[q + np.uint64(4)]
                        v5 = bd[q + np.uint64(5)] - 2.0 * row[q + np.uint64(5)]
                        v6 = bd[q + np.uint64(6)] - 2.0 * row[q + np.uint64(6)]
                        v7 = bd[q + np.uint64(7)] - 2.0 * row[q + np.uint64(7)]
                        # sorted insertion network: c = min(c, max(b, v)); b = min(b, max(a, v)); a = min(a, v)
                        t0_ = b0 if b0 > v0 else v0; c0 = t0_ if t0_ < c0 else c0
                        t1_ = b1 if b1 > v1 else v1; c1 = t1_ if t1_ < c1 else c1
                        t2_ = b2x if b2x > v2 else v2; c2x = t2_ if t2_ < c2x else c2x
                        t3_ = b3 if b3 > v3 else v3; c3 = t3_ if t3_ < c3 else c3
                        t4_ = b4 if b4 > v4 else v4; c4 = t4_ if t4_ < c4 else c4
                        t5_ = b5 if b5 > v5 else v5; c5 = t5_ if t5_ < c5 else c5
                        t6_ = b6 if b6 > v6 else v6; c6 = t6_ if t6_ < c6 else c6
                        t7_ = b7 if b7 > v7 else v7; c7 = t7_ if t7_ < c7 else c7
                        u0 = a0 if a0 > v0 else v0; b0 = u0 if u0 < b0 else b0
                        u1 = a1 if a1 > v1 else v1; b1 = u1 if u1 < b1 else b1
                        u2 = a2x if a2x > v2 else v2; b2x = u2 if u2 < b2x else b2x
                        u3 = a3 if a3 > v3 else v3; b3 = u3 if u3 < b3 else b3
                        u4 = a4 if a4 > v4 else v4; b4 = u4 if u4 < b4 else b4
                        u5 = a5 if a5 > v5 else v5; b5 = u5 if u5 < b5 else b5
                        u6 = a6 if a6 > v6 else v6; b6 = u6 if u6 < b6 else b6
                        u7 = a7 if a7 > v7 else v7; b7 = u7 if u7 < b7 else b7
                        a0 = v0 if v0 < a0 else a0
                        a1 = v1 if v1 < a1 else a1
                        a2x = v2 if v2 < a2x else a2x
                        a3 = v3 if v3 < a3 else a3
                        a4 = v4 if v4 < a4 else a4
                        a5 = v5 if v5 < a5 else a5
                        a6 = v6 if v6 < a6 else a6
                        a7 = v7 if v7 < a7 else a7
                    st[0] = a0
                    st[1] = a1
                    st[2] = a2x
                    st[3] = a3
                    st[4] = a4
                    st[5] = a5
                    st[6] = a6
                    st[7] = a7
                    st[8] = b0
                    st[9] = b1
                    st[10] = b2x
                    st[11] = b3
                    st[12] = b4
                    st[13] = b5
                    st[14] = b6
                    st[15] = b7
                    st[16] = c0
                    st[17] = c1
                    st[18] = c2x
                    st[19] = c3
                    st[20] = c4
                    st[21] = c5
                    st[22] = c6
                    st[23] = c7
        for d in range(1, s + 1):
            i = j - d
            if i < 0:
                break
            if not mask[j, d - 1]:
                continue
            for e in range(ne):
                st = state[d - 1, e]
                m1 = m2 = m3 = INF
                for q in range(24):
                    v = st[q]
                    if v < m3:
                        if v < m2:
                            m3 = m2
                            if v < m1:
                                m2 = m1
                                m1 = v
                            else:
                                m2 = v
                        else:
                            m3 = v
                top[0] = m1
                top[1] = m2
                top[2] = m3
                out[j, d - 1, e] = _mean_root(H, i, j, d, e, a2, b2, c2, top, K)


@njit(cache=True, parallel=True)
def _knn_kernel(PI, PJ, PK, zz, H, t0, j0, j1, n, s, K, a2, b2, c2, mask, out):
    """Same as :func:`_knn3_kernel` for any K (sorted insertion with a branch)."""
    R = zz.shape[0]
    for j in prange(j0, j1):
        ne = min(s, n - 1 - j)
        if ne <= 0:
            continue
        base = np.empty(R)
        top = np.empty(K)
        rj = j - t0
        for d in range(1, s + 1):
            i = j - d
            if i < 0:
                break
            if not mask[j, d - 1]:
                continue
            _base_row(zz, PI[i - t0], PJ[rj], base)
            for e in range(ne):
                row = PK[rj + 1 + e]
                for q in range(K):
                    top[q] = INF
                for r in range(R):
                    v = base[r] - 2.0 * row[r]
                    if v < top[K - 1]:
                        q = K - 1
                        while q > 0 and top[q - 1] > v:
                            top[q] = top[q - 1]
                            q -= 1
                        top[q] = v
                out[j, d - 1, e] = _mean_root(H, i, j, d, e, a2, b2, c2, top, K)


@njit(cache=True, parallel=True)
def _projections(G, st, a2, b2, c2, PI, PJ, PK):
    """Three-tap filters of G along references: the per-frame parts of y . z_r.

    Reference feature r is made of reference frames (r, r + st, r + 2 st).
    """
    rows = G.shape[0]
    R = G.shape[1] - 2 * st
    for t in prange(rows):
        g = G[t]
        pi = PI[t]
        pj = PJ[t]
        pk = PK[t]
        for r in range(R):
            g0 = g[r]
            g1 = g[r + st]
            g2 = g[r + 2 * st]
            V = g2 - g0
            A = g2 - 2.0 * g1 + g0
            pi[r] = c2 * A - b2 * V
            pj[r] = a2 * g1 - 2.0 * c2 * A
            pk[r] = b2 * V + c2 * A


_F8_2 = numba.float64[:, ::1]
_KNN_SIG = numba.void(
    _F8_2, _F8_2, _F8_2, numba.float64[::1], _F8_2, numba.int64, numba.int64, numba.int64,
    numba.int64, numba.int64, numba.int64, numba.float64, numba.float64, numba.float64,
    numba.boolean[:, ::1], numba.float64[:, :, ::1])


@njit(cache=True)
def _gram_band(x, width):
    """H[t, delta] = x_t . x_{t+delta} for delta = 0..width (0 past the end)."""
    n, D = x.shape
    H = np.zeros((n, width + 1))
    for t in range(n):
        xt = x[t]
        for delta in range(min(width + 1, n - t)):
            xu = x[t + delta]
            acc = 0.0
            for c in range(D):
                acc += xt[c] * xu[c]
            H[t, delta] = acc
    return H


@njit(cache=True)
def _reference_norms(z, st, a, b, c):
    """|z_r|^2 of the reference features (frames r, r + st, r + 2 st), without building them."""
    R = z.shape[0] - 2 * st
    D = z.shape[1]
    out = np.empty(R)
    for r in range(R):
        p = 0.0
        v = 0.0
        w = 0.0
        for q in range(D):
            z0 = z[r, q]
            z1 = z[r + st, q]
            z2 = z[r + 2 * st, q]
            p += z1 * z1
            v += (z2 - z0) * (z2 - z0)
            w += (z2 - 2.0 * z1 + z0) * (z2 - 2.0 * z1 + z0)
        out[r] = a * a * p + b * b * v + c * c * w
    return out


def _check(x, z, s, k, st=1):
    x = np.ascontiguousarray(x, dtype=np.float64)
    z = np.ascontiguousarray(z, dtype=np.float64)
    if x.ndim != 2 or z.ndim != 2 or x.shape[1] != z.shape[1]:
        raise RetimeError(f"input poses {x.shape} and reference poses {z.shape} must be (frames, D) with the same D")
    if z.shape[0] < 2 * st + 1:
        raise RetimeError(f"the reference has {z.shape[0]} frames at the analysis rate; it needs at least {2 * st + 1}")
    if int(s) < 1:
        raise RetimeError(f"the skip limit must be at least 1 (got {s})")
    if int(k) < 1:
        raise RetimeError(f"the number of neighbours must be at least 1 (got {k})")
    if not (np.isfinite(x).all() and np.isfinite(z).all()):
        raise RetimeError("poses contain NaN or infinite values")
    return x, z, int(s), int(k)


def table_width(s: int) -> int:
    """Last dimension of a score table: s rounded up to a multiple of 8."""
    return 8 * ((int(s) + 7) // 8)


def effective_k(k: int, r: int, st: int = 1) -> int:
    """Neighbours actually used: at most the number of reference features (r - 2 st)."""
    return max(1, min(int(k), int(r) - 2 * int(st)))


def score_table(x, z, coeffs, s, k=3, mask=None, method="exact", eps=0.0, ref_stride=1, block_bytes=96 << 20):
    """Local scores of all frame triples with gaps <= s.

    x: (n, D) input poses at the analysis rate (already low-passed);
    z: (r, D) reference poses at the same rate; coeffs: ``FeatureWeights.coefficients(fps)``;
    mask: optional (n, s) bool, ``mask[j, d-1]`` = scores with vertex (j-d, j) are wanted;
    ref_stride: reference features come from frames (r - st, r, r + st) (every r: a reference
    played at 1/st of the analysis rate, all phases kept).
    Returns F (n, s, table_width(s)) float64, see the module docstring for the layout.
    """
    st = int(ref_stride)
    x, z, s, k = _check(x, z, s, k, st)
    n, r = x.shape[0], z.shape[0]
    K = effective_k(k, r, st)
    if mask is None:
        mask = np.ones((n, s), dtype=np.bool_)
    else:
        mask = np.ascontiguousarray(mask, dtype=np.bool_)
        if mask.shape != (n, s):
            raise ValueError(f"mask shape {mask.shape} != {(n, s)}")
    if method == "approx":
        return _score_table_kdtree(x, z, coeffs, s, K, mask, eps, st)
    if method != "exact":
        raise RetimeError(f"unknown kNN method {method!r} (use 'exact' or 'approx')")
    out = np.full((n, s, table_width(s)), INF)
    # Centre on the reference's mean pose: distances do not change, rounding does.
    mu = z.mean(axis=0)
    xc = x - mu
    zc = z - mu
    a, b, c = coeffs
    a2, b2, c2 = a * a, b * b, c * c
    R = r - 2 * st
    zz = _reference_norms(zc, st, a, b, c)
    H = _gram_band(xc, 2 * s)
    kernel = compiled(_knn3_kernel if K <= 3 else _knn_kernel, _KNN_SIG)
    Rp = 8 * ((R + 7) // 8)  # PK rows padded to whole groups of eight references
    rows = int(min(n + 2 * s, max(64, block_bytes // (8 * (r + 3 * Rp)))))
    step = max(1, rows - 2 * s)
    zt = np.ascontiguousarray(zc.T)
    G = np.empty((rows, r))
    PI = np.empty((rows, Rp))
    PJ = np.empty((rows, Rp))
    PK = np.empty((rows, Rp))
    for P_ in (PI, PJ, PK):
        P_[:, R:] = 0.0
    zzp = np.full(Rp, INF)
    zzp[:R] = zz
    blocks = []
    j0 = 0
    while j0 < n:
        j1 = min(n, j0 + step)
        blocks.append((j0, j1, max(0, j0 - s), min(n, j1 + s)))
        j0 = j1

    def product(b):  # G = X Z^T of block b's frames (BLAS releases the GIL)
        t0, t1 = blocks[b][2:]
        np.matmul(xc[t0:t1], zt, out=G[:t1 - t0])

    def project(b):  # block b's projections of its product (G is then free again)
        t0, t1 = blocks[b][2:]
        _projections(G[:t1 - t0], st, a2, b2, c2, PI, PJ, PK)

    def knn(b):
        j0, j1, t0, _ = blocks[b]
        # small dynamic chunks: a thread that the OS preempts does not hold up the other
        with numba.parallel_chunksize(max(1, (j1 - j0) // (16 * numba.get_num_threads()))):
            kernel(PI, PJ, PK, zzp, H, t0, j0, j1, n, s, K, a2, b2, c2, mask, out)

    with single_threaded_blas():
        if len(blocks) == 1:  # nothing to overlap: a worker thread would only add its start and hand-offs
            product(0)
            project(0)
            knn(0)
            return out
        with ThreadPoolExecutor(max_workers=1) as pool:
            # the next block's matrix product (one BLAS thread) runs while the kNN kernel scans this
            # block. Blocks and products are the same as one after the other, so every bit is.
            pending = pool.submit(product, 0)
            for b in range(len(blocks)):
                pending.result()
                project(b)
                if b + 1 < len(blocks):
                    pending = pool.submit(product, b + 1)
                knn(b)
    return out


def all_triples(n, s, mask=None):
    """Index arrays (i, j, k, d, e) of all triples with gaps 1..s inside 0..n-1 (mask over (j, d-1))."""
    j, d, e = np.meshgrid(np.arange(n), np.arange(1, s + 1), np.arange(1, s + 1), indexing="ij")
    i, k = j - d, j + e
    ok = (i >= 0) & (k < n)
    if mask is not None:
        ok &= mask[j, d - 1]
    return i[ok], j[ok], k[ok], d[ok], e[ok]


def _score_table_kdtree(x, z, coeffs, s, K, mask, eps, st=1, chunk=200_000):
    from scipy.spatial import cKDTree

    n = x.shape[0]
    mu = z.mean(axis=0)
    xc, zc = x - mu, z - mu
    tree = cKDTree(reference_features(zc, coeffs, st))
    out = np.full((n, s, table_width(s)), INF)
    i, j, k, d, e = all_triples(n, s, mask)
    for c0 in range(0, len(i), chunk):
        sl = slice(c0, c0 + chunk)
        y = triple_features(xc, i[sl], j[sl], k[sl], coeffs)
        dist, _ = tree.query(y, k=K, eps=float(eps), workers=-1)
        dist = np.asarray(dist).reshape(len(y), -1)
        out[j[sl], d[sl] - 1, e[sl] - 1] = dist.mean(axis=1)
    return out


def score_table_bruteforce(x, z, coeffs, s, k=3, ref_stride=1):
    """Plain NumPy reference implementation: explicit feature vectors, all distances, sort.

    Same layout and meaning as :func:`score_table`. Used by tests and the benchmark.
    """
    st = int(ref_stride)
    x, z, s, k = _check(x, z, s, k, st)
    n, r = x.shape[0], z.shape[0]
    K = effective_k(k, r, st)
    zf = reference_features(z, coeffs, st)
    out = np.full((n, s, table_width(s)), INF)
    i, j, kk, d, e = all_triples(n, s)
    chunk = max(1, int(4e7 // max(1, zf.shape[0] * zf.shape[1])))
    for c0 in range(0, len(i), chunk):
        sl = slice(c0, c0 + chunk)
        y = triple_features(x, i[sl], j[sl], kk[sl], coeffs)
        dist = np.sqrt(((y[:, None, :] - zf[None, :, :]) ** 2).sum(axis=2))
        part = np.partition(dist, K - 1, axis=1)[:, :K] if K < dist.shape[1] else dist
        out[j[sl], d[sl] - 1, e[sl] - 1] = part.mean(axis=1)
    return out


