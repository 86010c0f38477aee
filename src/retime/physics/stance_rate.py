"""Stance rate: how many times too slow a clip plays, from its single-support frames (no flight needed).

Played ``k`` times too slow, every velocity is ``1/k`` and every acceleration ``1/k^2`` of the real
one, so the root's wrench at a uniform rate ``r`` is ``r^2 b + c`` (:mod:`.dynamics`: ``b`` the
path's velocity terms, ``c`` gravity's). On one foot the contact force must supply it through
friction-cone forces at that foot's sole corners: a centre of pressure inside the sole, with the
whole body's angular momentum accounted for (the inverted pendulum / ZMP relation, McCann et al.
2006's contact model). Too fast a clip asks the foot for accelerations its sole cannot give; too
slow a clip lets the centre of mass hang where the foot cannot hold it. The rate ``r*`` at which the
least residual wrench (non-negative least squares on the root rows, per frame) is smallest, RMS over
the single-support frames, estimates ``k``.

Double-support frames are left out (two feet explain nearly any rate), and so are frames near a
flight. Measured on the real walks and the run without fittable flights in ../shared/data:
``r*`` 0.92-1.13 on the captures as they are, 0.71-0.96 with Frame Time x0.8 and 1.11-1.35 with
x1.25 (``benchmarks/check_verdicts.py``): a weaker cue than a flight's parabola, which stays the
primary estimate wherever a flight is measured.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.ndimage import binary_dilation

from .constants import G
from .dynamics import RIDGE, _nnls_gram, _nonzero_columns

RATES = np.exp(np.linspace(np.log(0.5), np.log(2.0), 31))  # the uniform rates tried (log-spaced)
MIN_SINGLE_S = 0.3  # single-support time (s) below this says nothing about the rate


@dataclass
class StanceRate:
    time_factor: float | None  # how many times too slow the clip plays (None: not measured)
    seconds: float  # single-support time the estimate rests on
    residual: np.ndarray  # (len(RATES),) RMS residual wrench per rate, body weights (1 m lever for moments)

    @property
    def contrast(self) -> float:
        """Residual at the clip's own rate over the least residual (1: the clip's rate is the best)."""
        if self.time_factor is None or not self.residual.size:
            return 1.0
        at_one = float(np.interp(0.0, np.log(RATES), self.residual))
        return at_one / max(float(self.residual.min()), 1e-12)


@njit(cache=True)
def _residuals(A, b, c, rates, ridge, out):
    """out[k, i]: the norm of ``w - A x`` for the least-squares ``x >= 0`` at w = rates[k]^2 b[i] + c[i]
    (A (n, 6, K) the root rows of the contact basis of frame i)."""
    n, R, K = A.shape
    cols = np.empty(K, dtype=np.int64)
    for i in range(n):
        m = _nonzero_columns(A[i], cols)
        G = np.zeros((m, m))
        for a in range(m):
            for bb in range(m):
                acc = 0.0
                for r in range(R):
                    acc += A[i, r, cols[a]] * A[i, r, cols[bb]]
                G[a, bb] = acc
        scale = 0.0
        for a in range(m):
            scale += G[a, a]
        scale = scale / m if m else 1.0
        for a in range(m):
            G[a, a] += ridge * scale
        h = np.empty(m)
        w = np.empty(R)
        for k in range(len(rates)):
            for r in range(R):
                w[r] = rates[k] * rates[k] * b[i, r] + c[i, r]
            for a in range(m):
                acc = 0.0
                for r in range(R):
                    acc += A[i, r, cols[a]] * w[r]
                h[a] = acc
            x = _nnls_gram(G, h, 1e-10 * scale) if m else h
            acc = 0.0
            for r in range(R):
                e = w[r]
                for a in range(m):
                    e -= A[i, r, cols[a]] * x[a]
                acc += e * e
            out[k, i] = np.sqrt(acc)


def single_support(contact, fps: float, smoothing: float) -> np.ndarray:
    """(F,) bool: exactly one foot in contact, and no flight within two smoothing widths (the
    path's low-pass smears a flight's fall into the frames around it)."""
    contact = np.asarray(contact, dtype=bool)
    left, right = contact[:, :2].any(axis=1), contact[:, 2:].any(axis=1)
    stance = left | right
    near_flight = binary_dilation(~stance, iterations=max(1, int(round(2 * smoothing * fps)))) if (~stance).any() \
        else np.zeros(len(stance), bool)
    return (left ^ right) & ~near_flight


def stance_rate(terms, pd0=None) -> StanceRate:
    """The :class:`StanceRate` of a clip from its dynamics ``terms`` (``pd0``: their standard
    combination, made when not given)."""
    pd0 = terms.combine() if pd0 is None else pd0
    spf = int(terms.samples_per_frame)
    nr = int(pd0.n_root)
    use = np.zeros(pd0.n_samples, bool)
    use[::spf] = single_support(np.asarray(pd0.contact)[::spf], float(terms.fps), float(terms.smoothing))
    seconds = float(use.sum()) / float(terms.fps)
    empty = StanceRate(None, seconds, np.zeros(0))
    if nr == 0 or seconds < MIN_SINGLE_S:
        return empty
    N = pd0.N
    index = N.row_index()[:nr]
    if (index < 0).any():
        return empty
    # a chunk of samples at a time, as the contact basis is made: a long capture's single-support
    # frames never sit in memory at once
    b = np.asarray(pd0.b)[:, :nr]
    c = np.asarray(pd0.c)[:, :nr]
    squares = np.zeros(len(RATES))
    for part, values in N.chunks():
        pick = np.flatnonzero(use[part])
        if not len(pick):
            continue
        out = np.zeros((len(RATES), len(pick)))
        rows = pick + part.start
        _residuals(np.ascontiguousarray(values[pick][:, index]), np.ascontiguousarray(b[rows]),
                   np.ascontiguousarray(c[rows]), RATES, float(RIDGE), out)
        squares += (out ** 2).sum(axis=1)
    bw = float(pd0.total_mass) * G
    rms = np.sqrt(squares / int(use.sum())) / bw
    return StanceRate(_minimum(rms), seconds, rms)


def _minimum(residual) -> float | None:
    """The rate of the least residual, refined by a parabola through its neighbours in log rate; None
    when it lies at the end of :data:`RATES` (the rate is off by more than they span, or the
    residual does not depend on it)."""
    k = int(np.argmin(residual))
    if k == 0 or k == len(residual) - 1:
        return None
    y0, y1, y2 = residual[k - 1:k + 2]
    curvature = y0 - 2 * y1 + y2
    step = 0.5 * (y0 - y2) / curvature if curvature > 0 else 0.0
    dlog = float(np.log(RATES[1] / RATES[0]))
    return float(np.exp(np.log(RATES[k]) + step * dlog))
