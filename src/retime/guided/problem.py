"""A guided time warping problem on a discrete grid, and its exact solution.

:class:`WarpProblem` holds the input poses on the search grid (one row per candidate input
frame), the reference poses at the analysis rate, the number of output frames (or ``None``
for a free duration) and the fixed frames (keytimes). It knows how to score triples
(:mod:`retime.guided.score`) and to solve exactly (:mod:`retime.guided.dp`); the
coarse-to-fine heuristic (:mod:`retime.guided.heuristic`) builds a smaller problem from it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from retime.errors import RetimeError
from retime.guided import dp
from retime.guided.features import FeatureWeights
from retime.guided.score import score_table


@dataclass
class WarpProblem:
    x: np.ndarray  # (n, D) input poses on the search grid, low-passed
    z: np.ndarray  # (r, D) reference poses at the analysis rate, low-passed
    fps: float  # output frames per second (the analysis rate)
    m: int | None  # output frames; None = free duration
    fixed: dict  # output position -> grid frame (keytimes)
    s: int  # skip limit (grid frames per output step; the default is guided.method.Settings')
    k: int  # nearest neighbours
    weights: FeatureWeights = field(default_factory=FeatureWeights)
    knn: str = "exact"  # or "approx"
    eps: float = 0.0  # relative error bound of the approximate search
    ref_stride: int = 1  # reference features from frames (r - st, r, r + st)

    @property
    def n(self) -> int:
        return int(self.x.shape[0])

    @property
    def r(self) -> int:
        return int(self.z.shape[0])

    def coefficients(self):
        return self.weights.coefficients(self.fps)

    def band(self) -> dp.Band:
        return dp.feasible_band(self.n, self.m, self.s, self.fixed)

    def scores(self, mask=None) -> np.ndarray:
        return score_table(self.x, self.z, self.coefficients(), self.s, self.k, mask=mask,
                           method=self.knn, eps=self.eps, ref_stride=self.ref_stride)


def band_mask(band: dp.Band, n: int, s: int) -> np.ndarray:
    """(n, s) bool: vertex (j-d, j) can occur with j at some position of the band."""
    return _band_mask(band.lo, band.hi, n, s)


@njit(cache=True)
def _band_mask(lo, hi, n, s):
    mask = np.zeros((n, s), dtype=np.bool_)
    for p in range(1, lo.shape[0]):
        for j in range(lo[p], hi[p] + 1):
            for d in range(1, s + 1):
                i = j - d
                if i < lo[p - 1]:
                    break
                if i <= hi[p - 1]:
                    mask[j, d - 1] = True
    return mask


@dataclass
class SolveStats:
    objective_s: float = 0.0  # scoring (kNN) time
    optimization_s: float = 0.0  # DP time (including bounds and pruning)
    states: int = 0  # DP vertex-position pairs
    pruned_states: int | None = None  # after Lagrangian pruning (exact solver on big problems)
    extra: dict = field(default_factory=dict)


def solve_exact(problem: WarpProblem, F=None, upper_bound=None, stats: SolveStats | None = None, lagrange=None):
    """Globally optimal warp (frames, objective). ``F``: precomputed score table.

    With ``upper_bound`` (the cost of any feasible warp, e.g. the heuristic's) the band is first
    pruned with Lagrangian bounds (:func:`retime.guided.dp.prune_band`); the result is still exact.
    """
    stats = stats if stats is not None else SolveStats()
    if F is None:
        t0 = time.perf_counter()
        F = problem.scores()
        stats.objective_s += time.perf_counter() - t0
    t0 = time.perf_counter()
    if problem.m is None:
        if problem.fixed:
            raise RetimeError("keytimes need a fixed output duration; drop --free or the keytimes")
        sol = dp.solve_free(F)
    else:
        band = problem.band()
        stats.states = band.n_states(problem.s)
        if upper_bound is not None and np.isfinite(upper_bound):
            band = dp.prune_band(F, problem.m, band, upper_bound, hist=lagrange)
            stats.pruned_states = band.n_states(problem.s)
        sol = dp.solve_fixed(F, problem.m, band=band)
    stats.optimization_s += time.perf_counter() - t0
    return sol, F, stats
