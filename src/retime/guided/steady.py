"""The steady objective of guided time warping: sub-frame steps, a convex cost of speed changes.

The paper's warp keeps whole grid frames, so between keytimes it can only play at 1x, 2x, 3x ...
of the grid, and its score grows linearly with the speed error: on a steady motion blocks at 1x and
2x cost what a uniform 1.67x would, and the search plays a walk in blocks of speed (a limp).

Here the discrete warp is refined on a finer source grid, in the spirit of GDTW (Deriso & Boyd
2019, time warping with a slope regulariser). Each segment between fixed frames (the ends and
keytimes), ``M`` output steps over ``N`` grid frames, gets ``L`` points per *mean step* ``N / M``
(``L`` from :data:`FINE`, chosen so that an allowed step comes nearest the original speed): the
uniform warp, one step of ``L`` points at every output frame, is exactly representable whatever the
average speed, and a step of ``k`` points plays ``k / L`` times the segment's mean speed. The refined
warp minimises::

    sum_p  c(t_p, v_p)  +  |A(t_p, v_p) - A(t_p, v_{p-1})|  +  lam rho(log v_p - log v_{p-1})
           +  pace lam (log v_p - log v*(t_p))^2

with ``rho(x) = |x| + x^2``, over every step, the first and the last included (the ends are warped
like any other frame). ``c(t, v)`` is the paper's local score of playing around grid time ``t`` at
``v`` grid frames per output frame: the steady triple ``F[j, v-1, v-1]``, linear in ``t`` and ``v``
between whole values; its kink at the original speed keeps a flight at exactly its speed.
``A(t, v)`` is the integral over speed from 1 to v of ``a(t, u)``, the table's own price of a change
of speed by one grid frame per output frame around speed u (:func:`change_costs`): high where the
body moves fast, low where it stands still; a change is priced at every speed it passes through.
``rho`` is strictly convex, so of two warps with the same scores the
steadier wins (a walk plays uniformly), and it charges a change the same sudden or spread out: a
short excursion (a run's 0.1 s flight) is not worth its two changes, a long one (a jump's flight)
is. The last term (:func:`pace_penalties`, in the step table) pulls every step to one steady speed
v*, or in a jump's flight to its natural speed: c alone would play what barely moves (standing, a
slow turn) faster, so a walk whose pace changes would play in blocks. ``lam`` is ``steadiness`` times the median score of the segment's frames played uniformly: the
penalty is measured against what the reference objects to in the uniform warp, independent of the
feature scale and of the clip.

The dynamic programme over (fine position, last step) is exact for this objective within its band:
the whole feasible band when it is small, else a corridor about the relaxation's warp, re-centred on
its own result while that touches the corridor's edge. Its inner minimum, over the previous step
for every step at once, is over a Monge matrix (both change penalties are convex functions of a
difference of two sorted sequences), so its minimisers are monotone and a divide-and-conquer
search finds them exactly reading O(K log K) of the K^2 entries (K step choices). It first bounds
the optimum below by a Lagrangian relaxation of the step count (a price per step, any number of
steps: one pass over the fine positions, :func:`_priced_to_go`), which bounds what is left from
every state; the price by cutting-plane steps on the dual, and the bounds of two prices, either
side of the step count, taken together. The search then drops a state whose cost so far plus what
is left exceeds a bound just above the dual value (the duality gap is 0.003-0.1 % here); a warp
found within that bound is the optimum, else the bound goes up until one is. So it stays exact
and reads a small part of the band.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit


INF = np.inf
#: fine grid points per mean step of a segment: the count in this range that puts an allowed step
#: nearest the natural speed (10 makes both 1x and the mean exact at --scale 0.6 and 1.5)
FINE = range(8, 13)
#: at most this many transitions (positions x steps x steps) per output frame in the whole band; above it
#: the refinement searches a corridor
FULL_BAND_STATES = 4_000_000
#: corridor half-width around the discrete warp, in grid frames
CORRIDOR = 24
#: with at most this many step choices the inner minimum reads every pair (no monotone search)
DIRECT_STEPS = 12
#: the search reads every pair of a row's live steps and landing steps when they are at most this
#: many times the step choices (the monotone search reads about K log K)
DIRECT_PAIRS = 4
#: at most about this many rows (fine positions) of the step scores set the price search's scale
SCALE_ROWS = 128
#: the price search starts within +- this many lam (the change penalty's weight): a step's price is
#: of its order (V1-V8: -1.5 to 0.6 lam; a wider start costs cuts, a narrower one doublings)
FIRST_PRICE_WIDTH = 2.0
#: cuts of the price range of the relaxation without change penalties (the first guess)
SCORE_PRICE_ITERATIONS = 8
#: relaxations to find the step price of the search's bound (more until their prices lie on both
#: sides of the step count and two follow)
RELAXATIONS = 4
#: at most this many in all, and as many to centre the corridors of a wide band
WIDE_RELAXATIONS = 10
#: the price search ends when the bound is within this fraction of the objective's scale of the
#: best a price can give
PRICE_TOLERANCE = 1e-5
#: the first search bounds the objective this far (a fraction of its scale) above the dual value,
#: the next ones DEEPEN_FACTOR times further each, until a warp lies within the bound (it is then optimal)
DEEPEN_START = 2e-6
DEEPEN_FACTOR = 4.0
DEEPEN_ROUNDS = 10


@dataclass
class SteadyWarp:
    frames: np.ndarray  # (m,) fractional grid frames at the output frames
    objective: float  # the steady objective of that warp
    kept: int = 0  # segments left as the whole-frame warp (no steady warp within the step limits)


def _fill_gaps(D):
    """Each column's inf entries (triples off the clip, or not scored) from the nearest finite row
    (the earlier of two as near; a column with no finite entry is left as it is). All columns at once."""
    n = D.shape[0]
    ok = np.isfinite(D)
    if ok.all():
        return D
    rows = np.arange(n)[:, None]
    before = np.maximum.accumulate(np.where(ok, rows, -1), axis=0)  # the last finite row at or above
    after = np.minimum.accumulate(np.where(ok, rows, n)[::-1], axis=0)[::-1]  # the first at or below
    use_before = (after == n) | ((before >= 0) & (rows - before <= after - rows))
    source = np.where(use_before, before, after)
    filled = ok.any(axis=0)
    cols = np.arange(D.shape[1])[None, :]
    D[:, filled] = D[np.clip(source, 0, n - 1), np.broadcast_to(cols, D.shape)][:, filled]
    return D


def speed_costs(F) -> np.ndarray:
    """(n, s) cost of playing around grid frame j at v grid frames per output frame: F[j, v-1, v-1].

    Where the triple (j - v, j, j + v) leaves the clip or was not scored, the nearest scored frame's
    cost at that speed stands in (the ends play like their neighbours)."""
    v = np.arange(F.shape[1])
    return _fill_gaps(np.ascontiguousarray(F[:, v, v]))


def change_costs(F) -> np.ndarray:
    """(n, s) the table's own cost of a speed change of one grid frame around grid frame j between
    speeds v and v + 1 (column v - 1): the mean of the two unequal triples (j - v, j, j + v + 1),
    (j - v - 1, j, j + v) less the mean of the two steady ones, at least 0 (the last column repeats
    the one before). High where the body moves fast (a flight), low where it stands still."""
    n, s = F.shape[0], F.shape[1]
    S = np.zeros((n, s))
    if s < 2:
        return S
    c = np.arange(s - 1)
    with np.errstate(invalid="ignore"):
        S[:, :-1] = 0.5 * (F[:, c, c + 1] + F[:, c + 1, c]) - 0.5 * (F[:, c, c] + F[:, c + 1, c + 1])
    S[:, :-1][np.isnan(S[:, :-1])] = np.inf
    S[:, -1] = S[:, -2]
    return np.maximum(_fill_gaps(S), 0.0)


@njit(cache=True)
def _fill_column_gaps(T):
    """:func:`_fill_gaps` in place (its compiled twin): each column's entries that are not finite
    from the nearest finite row, the earlier of two as near; a column with none is left as it is."""
    n, m = T.shape
    before = np.empty(n, dtype=np.int64)  # the last finite row at or above
    for c in range(m):
        last = -1
        for j in range(n):
            last = j if np.isfinite(T[j, c]) else last
            before[j] = last
        if last < 0:
            continue
        after = n  # the first finite row at or below (rows below were filled, from finite rows only)
        for j in range(n - 1, -1, -1):
            if np.isfinite(T[j, c]):
                after = j
                continue
            b = before[j]
            T[j, c] = T[b if after == n or (b >= 0 and j - b <= after - j) else after, c]


@njit(cache=True)
def _speed_tables(F):
    """(:func:`speed_costs`, :func:`change_costs`) of F in one pass, the same sums (their compiled
    twin: the two NumPy functions, with their gathers and masks, were a tenth of a V1 refinement)."""
    n, s = F.shape[0], F.shape[1]
    D = np.empty((n, s))
    S = np.zeros((n, s))
    for j in range(n):
        for v in range(s):
            D[j, v] = F[j, v, v]
    _fill_column_gaps(D)
    if s < 2:
        return D, S
    for j in range(n):
        for c in range(s - 1):
            x = 0.5 * (F[j, c, c + 1] + F[j, c + 1, c]) - 0.5 * (F[j, c, c] + F[j, c + 1, c + 1])
            S[j, c] = INF if np.isnan(x) else x
        S[j, s - 1] = S[j, s - 2]
    _fill_column_gaps(S)
    for j in range(n):
        for c in range(s):
            S[j, c] = max(S[j, c], 0.0)
    return D, S


def penalty_weight(D, a0: int, a1: int, mean_step: float, steadiness: float) -> float:
    """lam of a segment (grid frames a0..a1): ``steadiness`` times the median of c over its frames
    played at the mean step (their mean if that is 0; 1 if the reference objects to nothing)."""
    uniform = _uniform_costs(D, int(a0), int(a1), float(mean_step))
    uniform = uniform[np.isfinite(uniform)]
    scale = float(np.median(uniform)) if uniform.size else 0.0
    if not scale > 0:
        scale = float(uniform.mean()) if uniform.size else 0.0
    return float(steadiness) * (scale if scale > 0 else 1.0)


@njit(cache=True)
def _bilinear(T, t, v):
    """T (n, s) at grid time t and speed v (column v - 1), linear between whole values, clamped."""
    n, s = T.shape
    t = min(max(t, 0.0), n - 1.0)
    v = min(max(v, 1.0), float(s))
    j0 = min(int(t), n - 2) if n > 1 else 0
    ft = t - j0 if n > 1 else 0.0
    c0 = min(int(v) - 1, s - 2) if s > 1 else 0
    fv = v - 1.0 - c0 if s > 1 else 0.0
    j1 = min(j0 + 1, n - 1)
    c1 = min(c0 + 1, s - 1)
    a = T[j0, c0] * (1.0 - fv) + T[j0, c1] * fv
    b = T[j1, c0] * (1.0 - fv) + T[j1, c1] * fv
    return a * (1.0 - ft) + b * ft


@njit(cache=True)
def _uniform_costs(D, a0, a1, v):
    """c at grid frames a0..a1 played at speed v."""
    out = np.empty(a1 - a0 + 1)
    for j in range(a0, a1 + 1):
        out[j - a0] = _bilinear(D, float(j), v)
    return out


@njit(cache=True)
def _fine_band(lb, ub, kmin, kmax):
    """Positions reachable from the start and able to reach the end with steps of kmin..kmax."""
    m = lb.shape[0]
    lo = lb.copy()
    hi = ub.copy()
    for p in range(1, m):
        lo[p] = max(lo[p], lo[p - 1] + kmin)
        hi[p] = min(hi[p], hi[p - 1] + kmax)
    for p in range(m - 2, -1, -1):
        lo[p] = max(lo[p], lo[p + 1] - kmax)
        hi[p] = min(hi[p], hi[p + 1] - kmin)
    return lo, hi


@njit(cache=True)
def _change_integrals(S):
    """(n, s) the integral over speed from 1 to c + 1 of a(j, u) du at every grid frame j (column c):
    a (the change-cost table's row, linear between whole speeds) summed cell by cell, once, so that
    :func:`_step_tables` reads a change's price instead of summing the cells again."""
    n, s = S.shape
    P = np.zeros((n, s))
    for j in range(n):
        for c in range(1, s):
            P[j, c] = P[j, c - 1] + 0.5 * (S[j, c - 1] + S[j, c])
    return P


@njit(cache=True)
def _step_tables(D, S, a0, h, n_fine, kmin, kmax):
    """The scores of the steps by fine position q, (n_fine + 1, K) each: ``c`` of the step of
    kmin + b fine points that ends at q, and ``A(t, v)`` of that step's speed at q, where a change
    from the step before it happens. They depend on the position and the step alone, not on the
    output frame, so the search reads them instead of interpolating them again at every output
    frame whose band holds q.

    A(t, v) is the integral over speed from 1 to v of a(t, u) du: a (the change-cost table S at grid
    time t, linear between whole speeds, constant beyond the last) summed over the speeds a change
    passes through, so that |A(t, v') - A(t, v)| prices a change from v to v' one grid frame per
    output frame at a time, each at its own speed. It is linear in the table, so at a fractional t
    it is the two neighbouring rows' integrals interpolated."""
    n, s = S.shape
    K = kmax - kmin + 1
    P = _change_integrals(S)
    cost_into = np.empty((n_fine + 1, K))
    level = np.empty((n_fine + 1, K))
    # c = D at the step's middle and speed, as _bilinear reads it (the speed's columns once per step)
    col0 = np.empty(K, dtype=np.int64)
    col_w = np.empty(K)
    # and A's whole speed at or below the step's speed (at most the last) and the fraction beyond it
    whole = np.empty(K, dtype=np.int64)
    beyond = np.empty(K)
    for b in range(K):
        v = min(max((kmin + b) * h, 1.0), float(s))
        col0[b] = min(int(v) - 1, s - 2) if s > 1 else 0
        col_w[b] = v - 1.0 - col0[b] if s > 1 else 0.0
        v = max((kmin + b) * h, 1.0)
        whole[b] = min(int(v), s)
        beyond[b] = v - whole[b]
    # both are linear in t between grid rows: each row's value at every step's speed once (the rows
    # the segment's steps reach), then per entry one interpolation between two rows, the same sums
    first = min(max(int(math.floor(a0 - 0.5 * kmax * h)) - 1, 0), n - 1)
    last = min(max(int(math.ceil(a0 + n_fine * h)) + 1, first), n - 1)
    at_speed = np.empty((last - first + 1, K))  # D at row i and the step's speed
    integral = np.empty((last - first + 1, K))  # A at row j and the step's speed
    for i in range(first, last + 1):
        for b in range(K):
            c0, fv = col0[b], col_w[b]
            c1 = min(c0 + 1, s - 1)
            at_speed[i - first, b] = D[i, c0] * (1.0 - fv) + D[i, c1] * fv
            c, x = whole[b], beyond[b]
            at = P[i, c - 1] + x * S[i, c - 1]  # the integral to v
            if c < s:  # a linear between speeds c and c + 1 (beyond the last speed a constant)
                at += 0.5 * x * x * (S[i, c] - S[i, c - 1])
            integral[i - first, b] = at
    # a step's middle, q - (kmin + b) / 2 fine points, depends on 2 q - b alone: its grid rows and
    # weight once per value (the same floating-point sums as per entry)
    off = K - 1
    rows0 = np.empty(2 * n_fine + K, dtype=np.int64)
    rows1 = np.empty(2 * n_fine + K, dtype=np.int64)
    frac = np.empty(2 * n_fine + K)
    for mm in range(2 * n_fine + K):
        tc = min(max(a0 + (0.5 * (mm - off - kmin)) * h, 0.0), n - 1.0)
        i0 = min(int(tc), n - 2) if n > 1 else 0
        frac[mm] = tc - i0 if n > 1 else 0.0
        rows0[mm] = i0 - first
        rows1[mm] = min(i0 + 1, n - 1) - first
    for q in range(n_fine + 1):
        t = min(max(a0 + q * h, 0.0), n - 1.0)  # the triple's middle frame is q
        j0 = min(int(t), n - 2) if n > 1 else 0
        ft = t - j0 if n > 1 else 0.0
        j1 = min(j0 + 1, n - 1)
        A0, A1 = integral[j0 - first], integral[j1 - first]
        for b in range(K):
            mm = 2 * q - b + off
            fc = frac[mm]
            cost_into[q, b] = at_speed[rows0[mm], b] * (1.0 - fc) + at_speed[rows1[mm], b] * fc
            level[q, b] = A0[b] * (1.0 - ft) + A1[b] * ft
    return cost_into, level


@njit(cache=True)
def change_penalties(kmin, kmax, lam):
    """(K, K) lam rho(log of the ratio) of a step of kmin + b fine points after one of kmin + a, by [b, a]."""
    K = kmax - kmin + 1
    rho = np.empty((K, K))
    for b in range(K):
        for a in range(K):
            x = math.log((kmin + b) / (kmin + a))
            rho[b, a] = lam * (abs(x) + x * x)
    return rho


@njit(cache=True, inline="always")
def _first_min(row, rho, level, b, a0, a1):
    """(min over a in a0..a1 of row[a] + rho[b, a] + |level[b] - level[a]|, its first minimiser or -1)."""
    best = INF
    at = -1
    lb = level[b]
    for a in range(a0, a1 + 1):
        v = row[a] + rho[b, a] + abs(lb - level[a])
        if v < best:
            best = v
            at = a
    return best, at


@njit(cache=True)
def _monotone_min(row, rho, level, b0, b1, val, arg, stack):
    """For b in b0..b1: val[b] = min over a of row[a] + rho[b, a] + |level[b] - level[a]|, arg[b] the
    first minimiser (-1 where every entry is inf).

    The matrix is Monge: rho is a convex function of the difference of two sorted sequences (the
    log steps), and so is |level[b] - level[a]| (level never decreases with the step, a >= 0), so
    C[b, a] + C[b', a'] <= C[b, a'] + C[b', a] for b < b', a < a', and adding row[a] keeps that.
    So the first minimiser never decreases with b, and divide and conquer finds them all exactly
    reading O(K log K) entries instead of K^2: the middle row's minimiser splits the columns that
    the rows above and below it need search."""
    K = row.shape[0]
    if K <= DIRECT_STEPS:  # few steps: reading them all costs less than the search's bookkeeping
        for b in range(b0, b1 + 1):
            val[b], arg[b] = _first_min(row, rho, level, b, 0, K - 1)
        return
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = b0, b1, 0, K - 1
    top = 1
    while top > 0:
        top -= 1
        lo_b, hi_b, lo_a, hi_a = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        b = (lo_b + hi_b) // 2
        val[b], at = _first_min(row, rho, level, b, lo_a, hi_a)
        arg[b] = at
        if at < 0:  # no finite entry in these columns: none in any row's share of them either
            at_lo, at_hi = lo_a, hi_a
        else:
            at_lo, at_hi = at, at
        if lo_b < b:
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = lo_b, b - 1, lo_a, at_hi
            top += 1
        if b < hi_b:
            stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = b + 1, hi_b, at_lo, hi_a
            top += 1


@njit(cache=True)
def _steps_ahead(cost_into, kmin, kmax):
    """(n_fine + 1, K) ``cost_into`` by where a step starts: [q, b] is the score of the step of
    kmin + b fine points from q (inf past the end). The relaxations read a position's every step
    from one row of it, where ``cost_into`` holds them on a diagonal (one memory line each)."""
    n_fine = cost_into.shape[0] - 1
    K = kmax - kmin + 1
    ahead = np.full((n_fine + 1, K), INF)
    for q in range(n_fine + 1):
        for b in range(min(K, n_fine - q - kmin + 1)):
            ahead[q, b] = cost_into[q + kmin + b, b]
    return ahead


@njit(cache=True, inline="always")
def _priced_row(ahead, B, price, q, kmin, r):
    """r[b]: the relaxation's cost of the step of kmin + b fine points from q and the best from
    where it lands (inf past the end). Returns whether any is finite."""
    n_fine = ahead.shape[0] - 1
    reach = False
    for b in range(r.shape[0]):
        qn = q + kmin + b
        r[b] = ahead[q, b] + price + B[qn, b] if qn <= n_fine else INF
        reach = reach or r[b] < INF
    return reach


@njit(cache=True)
def _priced_to_go(ahead, level, rho, kmin, kmax, price):
    """The segment's warps with any number of steps, each step charged ``price`` more (a Lagrangian
    relaxation of the step count; the band is implied by the count, so it goes too). ahead:
    :func:`_steps_ahead`.

    Returns B (n_fine + 1, K): B[q, a] the least such cost from fine position q, where a step of
    kmin + a ended, to the end; and from the start (whose first step has no change to pay) the
    least cost, its number of steps and its fine positions. Any warp of the segment that is at q
    after p of its M steps, last step kmin + a, costs at least B[q, a] - price (M - p) from there.

    The minimum over the next step reads, for every last step, only the next steps that can still
    lower some entry (after the same step and the cheapest one, a next step whose cost is not below
    the largest entry cannot: the change penalties are >= 0; about a quarter of them on V1), four at
    a time, so that the inner loop runs over the last steps without a reduction (the compiler
    vectorises it): faster here than the monotone search's K log K, whose bookkeeping does not
    vectorise. Each entry is the sum :func:`_first_min` forms and a minimum is exact in any order,
    so B is the same to the bit as reading every pair.
    No table of choices is kept: the best warp is traced forward afterwards, each step the first
    whose entry equals B (the monotone search's choice)."""
    n_fine = ahead.shape[0] - 1
    K = kmax - kmin + 1
    B = np.full((n_fine + 1, K), INF)
    B[n_fine, :] = 0.0
    r = np.empty(K)
    rho_by_next = np.ascontiguousarray(rho.T)  # [b, a]: rho[a, b], the change from a to b as _first_min reads it
    reached = np.empty(K, dtype=np.int64)  # a position's next steps that land on a finite cost
    for q in range(n_fine - kmin, -1, -1):
        if not _priced_row(ahead, B, price, q, kmin, r):
            continue
        lq = level[q]
        best = B[q]
        # the entries of the same step (no change: r[a] exactly) and of the cheapest next step first;
        # then only the next steps that can still lower some entry: one whose r[b] is not below the
        # largest entry so far cannot (the change penalties are >= 0), so skipping it leaves B the same
        cheapest = 0
        for b in range(K):
            best[b] = r[b]
            cheapest = b if r[b] < r[cheapest] else cheapest
        rc, lc, hc = r[cheapest], lq[cheapest], rho_by_next[cheapest]
        ceiling = -INF
        for a in range(K):
            v = rc + hc[a] + abs(lq[a] - lc)
            best[a] = v if v < best[a] else best[a]
            ceiling = max(ceiling, best[a])
        n_reach = 0
        for b in range(K):
            if r[b] < ceiling and b != cheapest:
                reached[n_reach] = b
                n_reach += 1
        i = 0
        while i + 3 < n_reach:  # four next steps per pass over the last steps: a quarter of the loads and stores of B
            b1, b2, b3, b4 = reached[i], reached[i + 1], reached[i + 2], reached[i + 3]
            r1, r2, r3, r4 = r[b1], r[b2], r[b3], r[b4]
            l1, l2, l3, l4 = lq[b1], lq[b2], lq[b3], lq[b4]
            h1, h2, h3, h4 = rho_by_next[b1], rho_by_next[b2], rho_by_next[b3], rho_by_next[b4]
            for a in range(K):
                la = lq[a]
                v1 = r1 + h1[a] + abs(la - l1)
                v2 = r2 + h2[a] + abs(la - l2)
                v3 = r3 + h3[a] + abs(la - l3)
                v4 = r4 + h4[a] + abs(la - l4)
                v1 = v1 if v1 < v2 else v2
                v3 = v3 if v3 < v4 else v4
                v1 = v1 if v1 < v3 else v3
                best[a] = v1 if v1 < best[a] else best[a]
            i += 4
        for j in range(i, n_reach):
            b = reached[j]
            rb, lb, rh = r[b], lq[b], rho_by_next[b]
            for a in range(K):
                v = rb + rh[a] + abs(lq[a] - lb)
                best[a] = v if v < best[a] else best[a]
    total = INF
    first = -1
    for b in range(K):
        if kmin + b <= n_fine:
            v = ahead[0, b] + price + B[kmin + b, b]
            if v < total:
                total = v
                first = b
    if first < 0:
        return B, total, 0, np.zeros(1, dtype=np.int64)
    path = [0, kmin + first]
    q = kmin + first
    a = first
    while q < n_fine:
        _priced_row(ahead, B, price, q, kmin, r)
        _, a = _first_min(r, rho, level[q], a, 0, K - 1)
        q += kmin + a
        path.append(q)
    return B, total, len(path) - 1, np.array(path, dtype=np.int64)


@njit(cache=True, inline="always")
def _bound(to_go, shift, q, a):
    """The bound on what is left from state (q, a): the largest of the relaxations' to_go[r, q, a]
    less their prices of the steps left (``shift``)."""
    best = to_go[0, q, a] - shift[0]
    for r in range(1, to_go.shape[0]):
        best = max(best, to_go[r, q, a] - shift[r])
    return best


@njit(cache=True)
def _segment_dp(cost_into, level, rho, lo, hi, kmin, kmax, to_go, prices, upper):
    """Exact minimiser over the band of the steady objective for one segment.

    Fine position q is grid time a0 + q h; a step of k fine points plays k h grid frames per output
    frame; cost_into, level: :func:`_step_tables`; rho: :func:`change_penalties`. Each
    state (fine position, last step) of the previous output frame hands on to the states one step
    further, all steps at once by :func:`_monotone_min`. to_go (R, n_fine + 1, K), prices (R,):
    :func:`_priced_to_go`'s bounds at R step prices, and the prices (one price below the best and
    one above bound a state from either side: too few steps left for its position, or too many);
    upper: at least the objective of some warp in the band (inf if none is
    known, or a margin for rounding). A state whose cost so far plus the bound on what is left
    exceeds ``upper`` lies on no optimal warp and hands nothing on; those of an optimal warp always
    do, so the result stays exact. Returns (fine positions (m,), objective)."""
    m = lo.shape[0]
    K = kmax - kmin + 1
    offs = np.zeros(m + 1, dtype=np.int64)
    for p in range(m):
        offs[p + 1] = offs[p] + (hi[p] - lo[p] + 1) * K
    bp = np.empty(offs[m], dtype=np.int16)  # read only along the optimal warp, whose entries are written
    wmax = 1
    for p in range(m):
        wmax = max(wmax, hi[p] - lo[p] + 1)
    # the rows (fine positions) of the previous and the current output frame; a row is valid only if
    # its stamp is that frame (else all inf), so that no frame clears the whole band
    prev = np.empty((wmax, K))
    cur = np.empty((wmax, K))
    prev_stamp = np.full(wmax, -1, dtype=np.int64)
    cur_stamp = np.full(wmax, -1, dtype=np.int64)
    prev_least = np.empty(wmax)  # a valid row's least entry
    cur_least = np.empty(wmax)
    R = to_go.shape[0]
    least_to_go = np.empty((R, to_go.shape[1]))
    for r in range(R):
        for q in range(to_go.shape[1]):
            least_to_go[r, q] = to_go[r, q].min()
    shift = np.empty(R)  # the prices of the steps left after a state of the previous row
    after = np.empty(R)  # and after one of this row
    val = np.empty(K)
    arg = np.empty(K, dtype=np.int64)
    stack = np.empty((2 * K + 2, 4), dtype=np.int64)
    alive = np.empty(K)
    live = np.empty(K, dtype=np.int64)  # a row's steps that can still lie on a warp beating the bound
    lands = np.empty(K, dtype=np.int64)  # the steps from it whose states can too
    # position 1: the first step, from fine position 0, has no predecessor to change from
    prev_first, prev_last = wmax, -1  # the valid rows lie in prev_first..prev_last
    for q in range(lo[1], hi[1] + 1):
        k = q - lo[0]
        if kmin <= k <= kmax:
            w = q - lo[1]
            prev[w, :] = INF
            prev[w, k - kmin] = cost_into[q, k - kmin]
            prev_stamp[w] = 1
            prev_least[w] = cost_into[q, k - kmin]
            prev_first, prev_last = min(prev_first, w), max(prev_last, w)
    for p in range(2, m):
        for r in range(R):
            shift[r] = prices[r] * (m - p)
            after[r] = prices[r] * (m - 1 - p)
        cur_first, cur_last = wmax, -1
        for wp in range(prev_first, prev_last + 1):
            qp = lo[p - 1] + wp
            if prev_stamp[wp] != p - 1:
                continue  # no warp reaches this position
            row_bound = least_to_go[0, qp] - shift[0]
            for r in range(1, R):
                row_bound = max(row_bound, least_to_go[r, qp] - shift[r])
            if not prev_least[wp] + row_bound <= upper:
                continue  # no warp through it can beat the bound
            row = prev[wp]
            n_live = 0
            least = INF
            for a in range(K):
                if row[a] < INF and row[a] + _bound(to_go, shift, qp, a) <= upper:
                    live[n_live] = a
                    n_live += 1
                    least = min(least, row[a])
            # the steps that land in this output frame's band, in a state that the least cost so far
            # (every change costs at least 0) can bring within the bound
            n_lands = 0
            for b in range(max(0, lo[p] - qp - kmin), min(K - 1, hi[p] - qp - kmin) + 1):
                q = qp + kmin + b
                if least + cost_into[q, b] + _bound(to_go, after, q, b) <= upper:
                    lands[n_lands] = b
                    n_lands += 1
            if n_lands == 0:
                continue
            if n_live * n_lands <= DIRECT_PAIRS * K:  # few pairs: read them all
                lq = level[qp]
                for i in range(n_lands):
                    b = lands[i]
                    best = INF
                    at = -1
                    for j in range(n_live):
                        a = live[j]
                        v = row[a] + rho[b, a] + abs(lq[b] - lq[a])
                        if v < best:
                            best = v
                            at = a
                    val[b] = best
                    arg[b] = at
            else:
                alive[:] = INF
                for j in range(n_live):
                    alive[live[j]] = row[live[j]]
                _monotone_min(alive, rho, level[qp], lands[0], lands[n_lands - 1], val, arg, stack)
            for i in range(n_lands):
                b = lands[i]
                q = qp + kmin + b
                v = val[b] + cost_into[q, b]
                if arg[b] < 0 or not v + _bound(to_go, after, q, b) <= upper:
                    continue
                w = q - lo[p]
                if cur_stamp[w] != p:
                    cur[w, :] = INF
                    cur_stamp[w] = p
                    cur_least[w] = INF
                    cur_first, cur_last = min(cur_first, w), max(cur_last, w)
                cur[w, b] = v  # (a state is reached from one previous position only)
                cur_least[w] = min(cur_least[w], v)
                bp[offs[p] + w * K + b] = arg[b]
        prev, cur = cur, prev
        prev_stamp, cur_stamp = cur_stamp, prev_stamp
        prev_least, cur_least = cur_least, prev_least
        prev_first, prev_last = cur_first, cur_last
    last = hi[m - 1] - lo[m - 1]
    best = INF
    bb = -1
    if prev_stamp[last] == m - 1:
        for b in range(K):
            if prev[last, b] < best:
                best = prev[last, b]
                bb = b
    q_out = np.empty(m, dtype=np.int64)
    q_out[0] = lo[0]
    q_out[m - 1] = hi[m - 1]
    if bb < 0:
        return q_out, INF
    q = hi[m - 1]
    b = bb
    for p in range(m - 1, 1, -1):
        a = bp[offs[p] + (q - lo[p]) * K + b]
        q = q - (kmin + b)
        q_out[p - 1] = q
        b = a
    return q_out, best


def segment_dp_numpy(cost_into, level, rho, lo, hi, kmin, kmax):
    """:func:`_segment_dp`'s plain NumPy twin: every (previous step, step) pair of every state,
    vectorised per output frame, no monotone search. For the parity tests."""
    m = len(lo)
    K = kmax - kmin + 1
    steps = kmin + np.arange(K)
    prev = np.full((hi[1] - lo[1] + 1, K), np.inf)
    q1 = np.arange(lo[1], hi[1] + 1)
    ok = (q1 - lo[0] >= kmin) & (q1 - lo[0] <= kmax)
    prev[ok, (q1 - lo[0] - kmin)[ok]] = cost_into[q1[ok], (q1 - lo[0] - kmin)[ok]]
    back = []
    for p in range(2, m):
        q = np.arange(lo[p], hi[p] + 1)[:, None]
        qp = q - steps[None, :]  # (W, K): where each step came from
        inside = (qp >= lo[p - 1]) & (qp <= hi[p - 1])
        rows = prev[np.clip(qp - lo[p - 1], 0, prev.shape[0] - 1)]  # (W, K_b, K_a)
        lev = level[np.clip(qp, 0, len(level) - 1)]  # (W, K_b, K_a): the levels where each step starts
        own = lev[:, np.arange(K), np.arange(K)]  # (W, K_b): the step's own level there
        total = rows + rho[None] + np.abs(own[:, :, None] - lev)
        total[~inside] = np.inf
        a = np.argmin(total, axis=2)
        best = np.take_along_axis(total, a[:, :, None], axis=2)[:, :, 0]
        prev = np.where(np.isfinite(best), best + cost_into[q[:, 0]][:, :K], np.inf)
        back.append(np.where(np.isfinite(best), a, -1))
    b = int(np.argmin(prev[hi[m - 1] - lo[m - 1]]))
    obj = float(prev[hi[m - 1] - lo[m - 1], b])
    out = [int(hi[m - 1])]
    q = int(hi[m - 1])
    for p in range(m - 1, 1, -1):
        a = int(back[p - 2][q - lo[p], b])
        q -= kmin + b
        out.append(q)
        b = a
    out.append(int(lo[0]))
    return np.array(out[::-1]), obj


def priced_to_go_numpy(cost_into, level, rho, kmin, kmax, price):
    """:func:`_priced_to_go`'s plain NumPy twin (from ``cost_into`` itself, each position's (last
    step, next step) pairs as one array, the first minimiser by argmin). For the parity tests."""
    n_fine = cost_into.shape[0] - 1
    K = kmax - kmin + 1
    B = np.full((n_fine + 1, K), np.inf)
    B[n_fine] = 0.0
    nxt = np.zeros((n_fine + 1, K), dtype=np.int64)
    b = np.arange(K)

    def row(q):  # the cost of each next step from q and the best from where it lands
        qn = q + kmin + b
        inside = qn <= n_fine
        r = np.full(K, np.inf)
        r[inside] = cost_into[qn[inside], b[inside]] + price + B[qn[inside], b[inside]]
        return r

    for q in range(n_fine - kmin, -1, -1):
        r = row(q)
        if not np.isfinite(r).any():
            continue
        total = r[None, :] + rho + np.abs(level[q][:, None] - level[q][None, :])  # [last a, next b]
        nxt[q] = np.argmin(total, axis=1)
        B[q] = total[b, nxt[q]]
    start = row(0)
    first = int(np.argmin(start))
    if not np.isfinite(start[first]):
        return B, np.inf, 0, np.zeros(1, dtype=np.int64)
    path, a = [0, kmin + first], first
    while path[-1] < n_fine:
        a = int(nxt[path[-1], a])
        path.append(path[-1] + kmin + a)
    return B, float(start[first]), len(path) - 1, np.array(path)


@njit(cache=True)
def _priced_scores(ahead, kmin, kmax, price):
    """(least cost, its number of steps) of :func:`_priced_to_go`'s relaxation without the change
    penalties: K times cheaper, and its best price is near that of the whole relaxation."""
    n_fine = ahead.shape[0] - 1
    K = kmax - kmin + 1
    B = np.full(n_fine + 1, INF)
    steps = np.zeros(n_fine + 1, dtype=np.int64)
    B[n_fine] = 0.0
    for q in range(n_fine - kmin, -1, -1):
        last = min(K, n_fine - q - kmin + 1)
        # the least first, in four independent chains (a minimum is exact in any order), then its
        # first step: the one the plain scan keeps (it takes only a strictly smaller value)
        m0 = m1 = m2 = m3 = INF
        b = 0
        while b + 3 < last:
            at = ahead[q, b:b + 4]
            ends = B[q + kmin + b:q + kmin + b + 4]
            v0, v1, v2, v3 = at[0] + price + ends[0], at[1] + price + ends[1], at[2] + price + ends[2], at[3] + price + ends[3]
            m0 = v0 if v0 < m0 else m0
            m1 = v1 if v1 < m1 else m1
            m2 = v2 if v2 < m2 else m2
            m3 = v3 if v3 < m3 else m3
            b += 4
        for j in range(b, last):
            v = ahead[q, j] + price + B[q + kmin + j]
            m0 = v if v < m0 else m0
        least = min(min(m0, m1), min(m2, m3))
        if least < INF:
            for b in range(last):
                if ahead[q, b] + price + B[q + kmin + b] == least:
                    B[q] = least
                    steps[q] = steps[q + kmin + b] + 1
                    break
    return B[0], steps[0]


@njit(cache=True)
def _finite_median_max(T):
    """(median, largest) of T's finite entries, as np.median and max of them give (inf, inf if
    there is none): one pass, no boolean mask of the table (a third of a V1 refinement's overhead)."""
    flat = T.ravel()
    finite = np.empty(flat.shape[0])
    n = 0
    for x in flat:
        if np.isfinite(x):
            finite[n] = x
            n += 1
    if n == 0:
        return INF, INF
    return np.median(finite[:n]), finite[:n].max()


def finite_median_max_numpy(T):
    """:func:`_finite_median_max`'s plain NumPy twin. For the parity tests."""
    finite = T[np.isfinite(T)]
    return (float(np.median(finite)), float(finite.max())) if finite.size else (INF, INF)


def _bisect_price(count_at, M, lo, hi, top, iterations):
    """Narrow the price range [lo, hi] about the price at which ``count_at`` (a step count that falls
    as the price rises; None where there is no warp) gives M: widened first (doubling) until its ends'
    counts hold M or a price reaches +-top, then ``iterations`` times cut, alternately at the linear
    guess and in half (the count falls in jumps, so each alone can stall). Returns (lo, hi), or
    (p, p) once a price p gives M."""
    width = hi - lo
    hi_count, lo_count = count_at(hi), None
    while hi_count is not None and hi_count > M and hi < top:
        lo, lo_count = hi, hi_count  # still too many steps at this price: dearer
        width *= 2.0
        hi = lo + width
        hi_count = count_at(hi)
    if hi_count is not None and lo_count is None:
        lo_count = count_at(lo)
        while lo_count is not None and lo_count < M and lo > -top:
            hi, hi_count = lo, lo_count
            width *= 2.0
            lo = hi - width
            lo_count = count_at(lo)
    for end, count in ((hi, hi_count), (lo, lo_count)):
        if count == M:
            return end, end  # (the middle of the range would throw this price away)
    for i in range(int(iterations) if hi_count is not None and lo_count is not None else 0):
        if hi_count >= M or lo_count <= M:
            break  # the range could not be widened to hold M
        t = (lo_count - M) / (lo_count - hi_count) if i % 2 == 0 else 0.5
        price = lo + (hi - lo) * min(max(t, 0.05), 0.95)
        count = count_at(price)
        if count == M:
            return price, price  # (the middle of the range would throw this price away)
        if count is None:
            break
        if count > M:
            lo, lo_count = price, count
        else:
            hi, hi_count = price, count
    return lo, hi


def _next_price(history, M, spread, slope):
    """The next step price to relax at, from the (price, count, dual value) triples tried so far: where
    the two nearest prices on either side of M steps say the dual value peaks (its supergradients,
    count - M, cross), kept inside their range; from one side, a secant step on the count (``slope``,
    the scores' count per unit price, until two prices are known)."""
    below, above = _nearest_either_side(history, M)
    if below is not None and above is not None:
        pa, pb = below[0], above[0]
        peak, _ = _supergradients_cross(below, above, M)
        return min(max(peak, pa + 0.05 * (pb - pa)), pb - 0.05 * (pb - pa))
    price, count = history[-1][0], history[-1][1]
    if len(history) >= 2 and history[-2][1] != count:
        slope = (count - history[-2][1]) / (price - history[-2][0])
    step = (M - count) / slope if slope < 0 else 0.0  # (the count falls as the price rises)
    # towards M, by at least a tenth of the spread and at most twice it, or twice the last step
    # (a first guess far off is left in a few steps)
    longest = 2.0 * max(spread, abs(price - history[-2][0]) if len(history) >= 2 else 0.0)
    direction = 1.0 if count > M else -1.0
    return price + direction * min(max(abs(step), 0.1 * spread), longest)


def _nearest_either_side(history, M):
    """Of the (price, count, dual value) tried, the highest price with more than M steps and the
    lowest with fewer (None where there is none)."""
    return (max((h for h in history if h[1] > M), default=None),
            min((h for h in history if h[1] < M), default=None))


def _dual_ceiling(history, M):
    """The most the dual value can reach (its supergradient lines at the nearest prices either side
    of M steps, where they cross), or inf while the prices do not bracket M."""
    below, above = _nearest_either_side(history, M)
    if below is None or above is None:
        return math.inf
    return _supergradients_cross(below, above, M)[1]


def _supergradients_cross(below, above, M):
    """(price, dual value) where the dual's supergradient lines at two (price, count, dual value)
    triples, one with more than M steps and one with fewer, cross."""
    (pa, ca, da), (pb, cb, db) = below, above
    peak = (db - da + (ca - M) * pa - (cb - M) * pb) / (ca - cb)
    return peak, da + (ca - M) * (peak - pa)


def step_price(cost_into, level, rho, kmin, kmax, M, relaxations=RELAXATIONS, tolerance=PRICE_TOLERANCE,
               first_width=None):
    """The step price of :func:`_priced_to_go` whose bound is best (its dual value, the relaxation's
    least cost less price M, is the largest; at most the optimum whatever the price). The price at
    which the relaxation without change penalties (:func:`_priced_scores`, K times cheaper) takes M
    steps is the first guess; then ``relaxations`` relaxations (more while they do not lie on
    both sides of M steps, or the last two did not follow that, up to WIDE_RELAXATIONS), each at
    the price where the
    dual's supergradients say it peaks (:func:`_next_price`), ending when a relaxation takes M steps
    (its warp is then optimal) or the dual value is within ``tolerance`` (times the objective's
    scale) of the most it can reach. Returns (prices (R,), their bounds B (R, n_fine + 1, K): the
    best price's, and the nearest price's on the other side of M steps (its bound is the larger
    where a state has too few steps left for its position, or too many), the best relaxation's warp
    as fine positions or None if it has no finite cost, the dual value (-inf if none), the scale).
    ``first_width``: the scores' price search starts within +-first_width (default: the scale's)."""
    # the scale from evenly spaced rows (it sets where the price search starts and how close it
    # must come, not what is optimal; the whole table's median took a fifth of a V1 refinement)
    median, largest = _finite_median_max(np.ascontiguousarray(cost_into[::max(1, len(cost_into) // SCALE_ROWS)]))
    width = 4.0 * float(median) + 1e-6 if np.isfinite(largest) else 1.0
    top = 4.0 * float(largest) + 1.0 if np.isfinite(largest) else 1.0
    scale = 0.25 * width * M  # about the objective of M steps at the median score
    ahead = _steps_ahead(cost_into, kmin, kmax)

    def scores_count(price):
        total, count = _priced_scores(ahead, kmin, kmax, price)
        return int(count) if np.isfinite(total) else None

    start = width if first_width is None else first_width
    lo, hi = _bisect_price(scores_count, M, -start, start, top, SCORE_PRICE_ITERATIONS)
    price = 0.5 * (lo + hi)
    spread = 0.25 * abs(price) + 0.01 * width

    def count_slope(at=price):
        """How fast the count falls with the price: the scores' count half a spread either side."""
        fewer, more = scores_count(at + 0.5 * spread), scores_count(at - 0.5 * spread)
        return (fewer - more) / spread if fewer is not None and more is not None and fewer < more else -M / spread

    best, history, bounds, bracketed_at, slope = None, [], {}, None, None
    while True:
        B, total, count, path = _priced_to_go(ahead, level, rho, kmin, kmax, price)
        if not np.isfinite(total):
            break  # no warp at all (whatever the price)
        dual = total - price * M
        if best is None or dual > best[0]:
            best = (dual, price, int(count), path)
        history.append((price, int(count), dual))
        bounds[price] = B
        keep = {best[1], *[h[0] for h in _nearest_either_side(history, M) if h is not None]}
        bounds = {k: v for k, v in bounds.items() if k in keep}  # (a long clip's bounds are large)
        if count == M or _dual_ceiling(history, M) - best[0] <= tolerance * scale:
            break
        # a bound from one side of M steps only is weak: the search goes on to bracket M, and then
        # for two more prices at least
        if bracketed_at is None and None not in _nearest_either_side(history, M):
            bracketed_at = len(history)
        if len(history) >= max(relaxations, WIDE_RELAXATIONS) or (
                bracketed_at is not None and len(history) >= max(relaxations, bracketed_at + 2)):
            break
        slope = count_slope() if slope is None else slope  # (not needed when the first price gives M steps)
        price = _next_price(history, M, spread, slope)
    if best is None:
        return np.zeros(1), np.zeros((1, cost_into.shape[0], kmax - kmin + 1)), None, -math.inf, scale
    prices = [best[1]]
    other = [h for h in _nearest_either_side(history, M) if h is not None and (h[1] - M) * (best[2] - M) < 0]
    prices += [other[0][0]] if other else []
    to_go = bounds[best[1]][None] if len(prices) == 1 else np.stack([bounds[x] for x in prices])  # (no copy of one)
    return np.array(prices), to_go, best[3], best[0], scale


def step_range(N, M, L, s):
    """(kmin, kmax): the fine steps, L points per mean step of N grid frames over M output frames,
    that play between one grid frame and the skip limit ``s`` per output frame (as the DP's)."""
    h = N / (M * L)  # grid frames per fine point
    return max(1, math.ceil(1.0 / h - 1e-9)), math.floor(s / h + 1e-9)


def points_per_step(N, M, natural, s=None, choices=FINE) -> int:
    """Fine points per mean step (N grid frames / M steps) whose allowed steps (:func:`step_range`,
    skip limit ``s``; no upper limit if None) come nearest the natural speed (``natural`` grid frames
    per output frame), the smallest of equals. The natural speed of a compression is one grid frame
    per output frame, the slowest step allowed: 6.05 points a step would leave 7 (1.16x) the nearest."""
    def miss(L):
        x = natural * M * L / N
        kmin, kmax = step_range(N, M, L, s if s is not None else N)  # no step passes the whole segment
        return abs(x - min(max(round(x), kmin), kmax) if kmin <= kmax else math.inf)
    return min(choices, key=lambda L: (round(miss(L), 9), L))


def bounded_search(cost_into, level, rho, lo, hi, kmin, kmax, to_go, prices, dual, unit, tight=False,
                   known=math.inf):
    """The best warp in the band lo..hi, searched by :func:`_segment_dp` with the bounds ``to_go`` at
    ``prices`` (:func:`step_price`); ``known``: the objective of a warp in the band, or inf.

    The dual value ``dual`` bounds the objective below, and the optimum is usually just above it:
    searched first with the bound ``unit`` above the dual value (at the dual value itself if
    ``tight``: the price's relaxation has an optimal warp), the search drops nearly every state; a
    warp found within the bound is the optimum (an optimal warp's states are never dropped). Else
    the bound goes DEEPEN_FACTOR times further up (a warp found above it bounds it too) until one
    is. Returns (fine positions, objective)."""
    gap = 0.0 if tight else unit

    def margin(upper):  # rounding in the bound (far below this) must not cut the optimum
        return 1e-9 * (abs(upper) + np.abs(prices).max() * len(lo) + 1.0)

    def solve(upper):
        return _segment_dp(cost_into, level, rho, lo, hi, kmin, kmax, to_go, prices, upper + margin(upper))

    for _ in range(DEEPEN_ROUNDS if np.isfinite(dual) else 0):
        trial = dual + gap
        if trial >= known:
            break
        q, obj = solve(trial)
        # within the bound but for rounding (at the dual value itself, the optimum found is that
        # value plus rounding): no better warp can have been dropped
        if obj <= trial + 0.5 * margin(trial):
            return q, obj
        known = min(known, obj)
        gap = max(gap * DEEPEN_FACTOR, unit)
    return solve(known)


def path_objective(cost_into, level, rho, q, kmin):
    """The steady objective of the warp at fine positions ``q`` (from 0, steps of kmin + b points),
    summed in the order :func:`_segment_dp` sums it (each step's change, then its score), so that
    the same warp gives the same value to the bit."""
    b = np.diff(q) - kmin  # each step's column
    n = len(b)
    at = level[q[1:-1]]  # the levels where each change happens
    terms = np.empty(3 * n - 2)
    terms[0] = cost_into[q[1], b[0]]
    terms[1::3] = rho[b[1:], b[:-1]]
    terms[2::3] = np.abs(at[np.arange(n - 1), b[1:]] - at[np.arange(n - 1), b[:-1]])
    terms[3::3] = cost_into[q[2:], b[1:]]
    return float(np.add.accumulate(terms)[-1])  # left to right, as the search adds


def pace_penalties(grounded, a0, h, n_fine, kmin, kmax, fine, natural, weight):
    """(n_fine + 1, K) ``weight`` (log(k / k*))^2 for the step of k fine points that ends at q: a
    strictly convex pull towards one steady step k* where grid time a0 + q h is on the ground
    (``grounded``, per grid frame, linear between frames), towards the natural speed (k* = ``natural``
    / h) in a flight. The ground's k* is what is left once the flights play at their natural speed
    (the segment's mean step ``fine`` if it has none), so a flight costs the ground nothing. A walk
    plays at one speed even where its own pace changes (the reference's score would play its
    standing and turning faster); a jump's flight keeps its speed. (The refinement adds it to the
    step scores by :func:`_add_pace`, without building the table.)"""
    log_steps, target = pace_targets(grounded, a0, h, n_fine, kmin, kmax, fine, natural)
    return weight * (log_steps[None, :] - target[:, None]) ** 2


def pace_targets(grounded, a0, h, n_fine, kmin, kmax, fine, natural):
    """(log k of the steps kmin..kmax, log k* at every fine position) of :func:`pace_penalties`."""
    t = np.clip(a0 + np.arange(n_fine + 1) * h, 0.0, len(grounded) - 1.0)
    on_ground = np.interp(t, np.arange(len(grounded)), np.asarray(grounded, dtype=float))
    flying = float(np.sum(1.0 - on_ground[1:]))  # fine points in flight
    ground_steps = n_fine / fine - flying * h / natural
    steady = (n_fine - flying) / ground_steps if ground_steps > 0 else float(kmax)
    steady = min(max(steady, float(kmin)), float(kmax))
    target = on_ground * math.log(steady) + (1.0 - on_ground) * math.log(natural / h)
    return np.log(np.arange(kmin, kmax + 1, dtype=float)), target


@njit(cache=True)
def _add_pace(cost_into, log_steps, target, weight):
    """cost_into += :func:`pace_penalties` (from :func:`pace_targets`), in place, in one pass: the
    same sums as NumPy's, without the (n_fine + 1, K) temporaries (a tenth of a V1 refinement)."""
    for q in range(cost_into.shape[0]):
        for b in range(cost_into.shape[1]):
            d = log_steps[b] - target[q]
            cost_into[q, b] += weight * (d * d)


def _refine_segment(D, S, y, a0, a1, s, steadiness, natural, corridor, grounded, pace, max_passes=8):
    """The steady warp of one segment (grid frames a0 -> a1 over len(y) - 1 steps) near path y:
    (fractional grid frames, objective). ``grounded`` (per grid frame, or None: all) and ``pace``: the
    pull of grounded steps to the mean speed, in units of lam (:func:`pace_penalties`)."""
    M = len(y) - 1
    N = a1 - a0
    fine = points_per_step(N, M, natural, s)
    h = N / (M * fine)  # grid frames per fine point
    kmin, kmax = step_range(N, M, fine, s)
    if not kmin <= fine <= kmax:  # no fine steps between 1 and s grid frames: the caller keeps y
        return None, math.inf
    lam = penalty_weight(D, a0, a1, N / M, steadiness)
    lb = np.zeros(M + 1, dtype=np.int64)
    ub = np.full(M + 1, M * fine, dtype=np.int64)
    ub[0] = 0
    lb[-1] = M * fine
    lo, hi = _fine_band(lb, ub, kmin, kmax)
    K = kmax - kmin + 1
    cost_into, level = _step_tables(D, S, float(a0), h, M * fine, kmin, kmax)
    if pace > 0:
        _add_pace(cost_into, *pace_targets(np.ones(D.shape[0]) if grounded is None else grounded, a0, h, M * fine,
                                           kmin, kmax, fine, natural), float(pace) * lam)
    rho = change_penalties(kmin, kmax, float(lam))

    wide = int((hi - lo + 1).max()) * K * K > FULL_BAND_STATES
    # a band searched in corridors needs the relaxation's warp as their centre: at the price where
    # it takes M steps it is the optimum, so the price search goes on to that price
    prices, to_go, priced_path, dual, scale = step_price(cost_into, level, rho, kmin, kmax, M,
                                                         *((WIDE_RELAXATIONS, 0.0) if wide else ()),
                                                         first_width=FIRST_PRICE_WIDTH * lam)
    # a relaxation's warp with M steps is optimal: its objective is the dual value
    exact_price = priced_path is not None and len(priced_path) == M + 1

    def solve_bounded(blo, bhi, known=math.inf):
        return bounded_search(cost_into, level, rho, blo, bhi, kmin, kmax, to_go, prices, dual,
                              DEEPEN_START * scale, exact_price, known)

    def around(centre, radius):
        """The band cut to ``radius`` fine points about fine positions ``centre`` (None: no warp in it)."""
        blo, bhi = _fine_band(np.maximum(lo, np.floor(centre - radius).astype(np.int64)),
                              np.minimum(hi, np.ceil(centre + radius).astype(np.int64)), kmin, kmax)
        return None if np.any(blo > bhi) else (blo, bhi)

    if not wide:
        if exact_price:  # the relaxation's warp is the optimum: no search needed
            q = priced_path
            obj = path_objective(cost_into, level, rho, q, kmin)
        else:
            q, obj = solve_bounded(lo, hi)
        return (a0 + q * h, float(obj)) if np.isfinite(obj) else (None, math.inf)
    # a band too wide to search at once: corridors, the first about the relaxation's warp (stretched
    # to M steps: at the best price its step count is M or near it), else the whole-frame warp's
    if priced_path is not None:
        centre = np.interp(np.linspace(0.0, len(priced_path) - 1, M + 1), np.arange(len(priced_path)), priced_path)
    else:
        centre = (np.asarray(y, dtype=float) - a0) / h
    obj = math.inf
    radius = corridor / h
    for _ in range(max_passes):
        band = around(centre, radius)
        blo, bhi = band if band is not None else (lo, hi)  # the corridor holds no warp: the whole band
        # the last warp found lies in this corridor (it is centred on it): its objective bounds this one's
        q, obj = solve_bounded(blo, bhi, obj if band is not None else math.inf)
        touches = np.any(((q == blo) & (blo > lo)) | ((q == bhi) & (bhi < hi)))
        if not touches or not np.isfinite(obj):
            break
        centre = q.astype(float)
    if not np.isfinite(obj):  # no warp with a finite score (a clip too short or too broken for it)
        return None, math.inf
    return a0 + q * h, float(obj)


def steady_warp(F, frames, fixed_positions, steadiness: float, natural=1.0,
                corridor: int = CORRIDOR, grounded=None, *, pace: float) -> SteadyWarp:
    """The steady warp near the discrete warp ``frames`` (grid frames at the output frames).

    F: the score table; fixed_positions: output positions that keep their grid
    frame (both ends and the keytimes); natural: grid frames per output frame at the original
    speed (the upsampling), one number or one per output position (a segment takes its first's).
    ``pace`` has no default here: its default is ``Settings.pace`` (a benchmark that left it out
    timed the objective without the pull)."""
    frames = np.asarray(frames, dtype=np.int64)
    m = len(frames)
    D, S = _speed_tables(np.ascontiguousarray(F, dtype=np.float64))
    cuts = sorted({0, m - 1, *[int(p) for p in fixed_positions if 0 <= int(p) < m]})
    natural = np.broadcast_to(np.asarray(natural, dtype=float), (m,))
    out = np.empty(m)
    total, kept = 0.0, 0
    for p0, p1 in zip(cuts, cuts[1:]):
        part, obj = _refine_segment(D, S, frames[p0:p1 + 1], int(frames[p0]), int(frames[p1]), F.shape[1], steadiness,
                                    float(natural[p0]), int(corridor), grounded, float(pace))
        if part is None:  # the whole-frame warp stands for this segment (said by the caller)
            part, obj, kept = frames[p0:p1 + 1].astype(float), 0.0, kept + 1
        out[p0:p1 + 1] = part
        total += obj
    return SteadyWarp(out, total, kept)
