"""Newton's method on the banded problem: the polish after L-BFGS (issue 24).

The objective is a sum over source samples, each of which reads the coefficients of one span of
the timing spline, c_m..c_{m+b} (b = the spline's degree, 4 for the quartic; :attr:`BandedCoordinates.band` is
:attr:`TimingSpline.band`), and the duration T. In the coordinates (c, T) -- the interior
coefficients that are not pinned (ends, locks), plus T when the duration is free -- its Hessian is
therefore **banded** (half-bandwidth b) with one dense row and column for T: an arrowhead. (In the
optimizer's w, each c is a normalized cumulative sum of all of them, so the same Hessian is dense.)

* **Hessian:** exact, in one pass over the samples (:func:`retime.physics.timing.objective.hessian_c`:
  per sample the 6 x 6 block of its span's coefficients and T, J^T (d2h) J plus the first derivatives
  times the second derivatives of p' and p'', with the spline inverse's implicit-function terms; the
  keytimes' terms in :func:`_keytime_hessian`). It costs about one gradient, where the central
  differences of the gradient with graph colouring it replaces (the coefficients ``k = r (mod 2 b
  + 1)`` stepped together; now the tests' reference, tests/_hessian_reference.py) took 2 x 9 (2 x 10 with a
  free duration) for the quartic.
* **Step:** Newton with a shift (H + (s0 + sigma) I, s0 the least of 0, 1e-12 x 4^k of the largest
  curvature that makes the Cholesky succeed, :func:`definite_shift`; Cholesky of the band by
  :func:`scipy.linalg.cholesky_banded`, the T column by its Schur complement), sigma a
  Levenberg-Marquardt parameter raised while a step does not give a quarter of the decrease its
  model predicts (after up to four halvings along the same direction have not given an Armijo
  decrease either: the penalty is C1, its curvature jumps where a sample crosses a region's
  boundary, and the full step overshoots such a jump more often than its direction is wrong) and
  lowered after a step that does. The objective is stiff (the exact penalty's
  curvature alpha / delta at a region's boundary; the Hessian's eigenvalues run from 1 to 1e8) and not
  convex, so the shift and sigma do the globalization; the polish starts from L-BFGS's answer.
  (Before: a damping of the diagonal plus its mean, H + lambda (|diag H| + mean), which on an
  indefinite Hessian stuck at lambda ~ 1e-2, a shift of 1e-2 of the stiffest curvature on the flat
  directions, and crawled to the 300-iteration limit.)
* **Stop:** converged when the (nearly unshifted) step's predicted gain is below 1e-11 of the
  objective, or ten steps together gained less than 1e-10 of it (creeping along a direction of
  almost no curvature); :func:`retime.physics.timing.optimize.solve` also asks the KKT residual.
* **Bounds** (``w_min <= w <= w_max``: each increment c_{k+1} - c_k within w d_k T) by step
  truncation: a step that would leave them is shortened to stay inside (fraction to the boundary).
  A step that a bound blocks entirely ends the polish ("a speed bound blocks the step").
* **Keytimes** p(t*) = s* by the augmented Lagrangian, as in :mod:`retime.physics.timing.optimize`: their residuals
  read five coefficients (and T), so the penalty keeps the band.
* **The torque term's kinks** at the fan's rays are mollified in the objective itself
  (:data:`retime.physics.timing.objective.FAN_BLEND`); without that neither L-BFGS nor Newton converged.
* **The l1 penalty's kink** is the smooth equivalent the objective already uses,
  ``alpha (sqrt(d^2 + delta^2) - delta)`` with ``delta`` = 1e-3 body weights of residual force
  (:mod:`retime.physics.timing.objective`): quadratic within a thousandth of a body weight of the region, linear beyond;
  a residual force below a thousandth of a body weight is below anything a capture resolves.

``w`` maps to (c, T) and back exactly (w_k = (c_{k+1} - c_k) / (d_k T), which also satisfies the
speed-scale gauge of :meth:`retime.physics.timing.spline.TimingSpline.gauge`), so the polish returns the same kind of
answer as L-BFGS.
"""
from __future__ import annotations

import math
import time

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded, LinAlgError

from .objective import evaluate_c, hessian_c

STALL_ITERATIONS = 10
BACKTRACKS = 4
BISECTIONS = 6
STALL_GAIN = 1e-10
ROUNDING = 1e-14  # a relative change of the objective below this is its summation's rounding, not a gain
OBJECTIVE_FLOOR = 1e-6  # relative tests are relative to at least this: an objective of 1e-18 (the original
# timing, which costs nothing) has no relative digits left to gain


class BandedCoordinates:
    """The (c, T) coordinates of a problem's spline: z = (c at ``free`` indices [, T])."""

    def __init__(self, problem):
        sp = problem.spline
        self.problem = problem
        self.spline = sp
        idx, _ = sp.pieces()
        pinned = set(idx)
        self.free = np.array([k for k in range(sp.n_c) if k not in pinned], dtype=np.int64)
        self.free_T = sp.free
        self.n = len(self.free) + (1 if self.free_T else 0)
        self.band = sp.band  # the Hessian's half-bandwidth: a sample reads c_m .. c_{m + band}

    def from_w(self, w):
        sp = self.spline
        c = sp.coefficients(w)
        T = sp.duration_of(w)
        z = c[self.free]
        return (np.r_[z, T] if self.free_T else z.copy()), c

    def coefficients(self, z, c_template):
        c = c_template.copy()
        c[self.free] = z[:len(self.free)]
        T = float(z[-1]) if self.free_T else self.spline.fixed_T
        return c, T

    def to_w(self, z, c_template):
        c, T = self.coefficients(z, c_template)
        return np.diff(c) / (self.spline.d * T)


def _keytime_terms(problem, c, T, mu, rho):
    """Augmented-Lagrangian value mu h + rho/2 h^2 of the keytimes and its gradient in (c, T)."""
    from .optimize import _basis_at

    sp = problem.spline
    val = 0.0
    gc = np.zeros(len(c))
    gT = 0.0
    for j, (s_star, t_star) in enumerate(problem.keytimes):
        tau = min(max(t_star / T, 0.0), 1.0)
        Nb, dN = _basis_at(sp, tau)
        h = float(Nb @ c) - s_star
        dh_dT = -float(dN @ c) * tau / T if (0.0 < tau < 1.0 and sp.free) else 0.0
        lam = mu[j] + rho * h
        val += mu[j] * h + 0.5 * rho * h * h
        gc += lam * Nb
        gT += lam * dh_dT
    return val, gc, gT


class BandedObjective:
    """F(z) = E(c, T) (+ the keytimes' augmented Lagrangian) and its gradient in z."""

    def __init__(self, coords: BandedCoordinates, c_template, mu=None, rho=0.0):
        self.coords = coords
        self.c0 = c_template
        self.mu = np.zeros(coords.problem.n_eq) if mu is None else mu
        self.rho = rho
        self.evaluations = 0

    def __call__(self, z):
        co, pr = self.coords, self.coords.problem
        c, T = co.coefficients(z, self.c0)
        self.evaluations += 1
        val, gc, gT = evaluate_c(pr.obj, pr.spline, c, T, grad=True, workspace=pr.workspace)
        if pr.n_eq:
            kv, kc, kT = _keytime_terms(pr, c, T, self.mu, self.rho)
            val += kv
            gc = gc + kc
            gT += kT
        g = gc[co.free]
        return val, (np.r_[g, gT] if co.free_T else g)


    def hessian(self, z):
        """(ab, col, corner): the exact Hessian of F at z (:func:`retime.physics.timing.objective.hessian_c`,
        one pass over the samples, plus the keytimes' terms) in the upper form of :func:`scipy.linalg.solveh_banded` (``ab``), the T column and its corner."""
        co, pr = self.coords, self.coords.problem
        c, T = co.coefficients(z, self.c0)
        hb, hcol, corner = hessian_c(pr.obj, pr.spline, c, T, workspace=pr.workspace)
        if pr.n_eq:
            corner += _keytime_hessian(pr, c, T, self.mu, self.rho, hb, hcol)
        return free_band(hb, co.free, co.band), (hcol[co.free] if co.free_T else None), \
            (corner if co.free_T else None)


def free_band(hb, free, band):
    """The upper band form (:func:`scipy.linalg.solveh_banded`) of the Hessian among the coefficients
    ``free`` (increasing), from hb[k, o] = H[k, k + o] over all coefficients: pinned coefficients drop
    out, so two free ones ``off`` apart in z may be nearer than ``band`` in c, never farther."""
    n = len(free)
    ab = np.zeros((band + 1, n))
    for off in range(band + 1):
        gap = free[off:] - free[:n - off]
        ab[band - off, off:] = np.where(gap <= band, hb[free[:n - off], np.minimum(gap, band)], 0.0)
    return ab


def _keytime_hessian(problem, c, T, mu, rho, hb, hcol):
    """Add the keytimes' augmented-Lagrangian Hessian rho dh dh^T + (mu + rho h) d2h in (c, T) into hb
    and hcol; returns its d2/dT2. h = N(tau) c - s* is linear in c; tau = t* / T moves with a free T."""
    from .optimize import _basis_at

    sp = problem.spline
    corner = 0.0
    for j, (s_star, t_star) in enumerate(problem.keytimes):
        tau = min(max(t_star / T, 0.0), 1.0)
        Nb, dN = _basis_at(sp, tau)
        lo, d2N = _basis_second_at(sp, tau)
        inner = 0.0 < tau < 1.0 and sp.free
        h = float(Nb @ c) - s_star
        lam = mu[j] + rho * h
        hT = -float(dN @ c) * tau / T if inner else 0.0
        # d2h / dc dT = -N'(tau) tau / T; d2h / dT2 = N''(tau) c (tau / T)^2 + 2 N'(tau) c tau / T^2
        hcT = -dN * tau / T if inner else np.zeros_like(Nb)
        hTT = (float(d2N @ c) * (tau / T) ** 2 + 2.0 * float(dN @ c) * tau / T ** 2) if inner else 0.0
        for off in range(hb.shape[1]):
            hb[lo:lo + sp.support - off, off] += rho * Nb[lo:lo + sp.support - off] * Nb[lo + off:lo + sp.support]
        hcol += rho * Nb * hT + lam * hcT
        corner += rho * hT * hT + lam * hTT
    return corner


def _basis_second_at(sp, tau):
    """(m, d2N): the span of ``tau`` (its basis functions are m .. m + band) and the second derivatives
    (d2/dtau2) of all basis functions there (span polynomials, as optimize._basis_at)."""
    m = int(np.clip(np.searchsorted(sp.breaks, tau, side="right") - 1, 0, len(sp.breaks) - 2))
    x = tau - sp.breaks[m]
    r = np.arange(sp.support)
    out = np.zeros(sp.n_c)
    out[m:m + sp.support] = (r * (r - 1) * x ** np.maximum(r - 2, 0)) @ sp.span_matrices[m]
    return m, out


def solve_arrowhead(ab, col, corner, g, shift):
    """Solve (H + shift I) x = -g for the banded + T-arrow H; None if that is not positive definite."""
    n_c = ab.shape[1]
    A = ab.copy()
    A[-1] = A[-1] + shift  # the diagonal: the upper form's last row
    try:
        cb = cholesky_banded(A, lower=False)
    except LinAlgError:
        return None
    if col is None:
        return -cho_solve_banded((cb, False), g)
    gc, gT = g[:n_c], g[n_c]
    Ainv_g = cho_solve_banded((cb, False), gc)
    Ainv_b = cho_solve_banded((cb, False), col)
    schur = corner + shift - float(col @ Ainv_b)
    if not schur > 0:
        return None
    y = -(gT - float(col @ Ainv_g)) / schur
    x = -Ainv_g - Ainv_b * y
    return np.r_[x, y]


def definite_shift(ab, col, corner, tiny=1e-12):
    """(s0, scale): nearly the least shift s0 that makes H + s0 I positive definite (0, or tiny scale 4^k
    refined by bisection; its Cholesky, with the T arrow's Schur complement, succeeds: Nocedal & Wright's
    "Cholesky with added multiple of the identity", O(n) a try where an eigenvalue of the band costs
    O(n^2)), and scale, a bound on H's largest eigenvalue (the largest absolute row sum, Gershgorin)."""
    n_c = ab.shape[1]
    band = ab.shape[0] - 1
    rows = np.abs(ab[band]).copy()
    for off in range(1, band + 1):
        rows[off:] += np.abs(ab[band - off, off:])
        rows[:-off] += np.abs(ab[band - off, off:])
    last = 0.0  # the T row's sum
    if col is not None:
        rows += np.abs(col)
        last = abs(corner) + float(np.sum(np.abs(col)))
    scale = max(float(np.max(rows, initial=0.0)), last, 1e-300)
    probe = np.zeros(n_c + (col is not None))
    if solve_arrowhead(ab, col, corner, probe, 0.0) is not None:
        return 0.0, scale
    lo, hi = 0.0, tiny * scale
    while solve_arrowhead(ab, col, corner, probe, hi) is None and hi <= scale:
        lo, hi = hi, 4.0 * hi
    for _ in range(BISECTIONS if lo > 0.0 else 0):  # to within a factor 4^(1/2^BISECTIONS) of the least
        mid = math.sqrt(lo * hi)
        if solve_arrowhead(ab, col, corner, probe, mid) is None:
            lo = mid
        else:
            hi = mid
    return hi, scale


def _feasible_fraction(coords, z, dz, c0, w_min, w_max):
    """The largest step fraction in (0, 1] (halving) that keeps every speed within the bounds."""
    for k in range(30):
        t = 0.5 ** k
        w = coords.to_w(z + t * dz, c0)  # the bounds are on these
        if np.all(w >= w_min) and np.all(w <= w_max) and np.all(np.isfinite(w)):
            return t
    return 0.0


def newton_inner(fun, z, w_bounds, max_iter=100, gain_tol=1e-11, deadline=None, log=None):
    """Newton on ``fun`` (a :class:`BandedObjective`) from z, with a shift of the identity and a
    Levenberg-Marquardt parameter on top: the step solves (H + (s0 + sigma scale) I) dz = -g, where s0
    makes the shifted Hessian positive definite (:func:`definite_shift`, within a factor 4 of the
    least such shift, -lambda_min) and sigma grows tenfold while a step fails (not positive definite
    with the T arrow, or less than a quarter of the model's decrease, and four halvings along it no
    Armijo decrease) and shrinks tenfold after one that works, a trust region in all but name. A
    shift of the identity, not of the diagonal: the curvatures run from 1 to 1e8, and a damping that
    scales with the diagonal (plus its mean, as before) held the flat directions still and crawled
    for hundreds of iterations on an indefinite Hessian. (z, F, iterations, converged, message).
    Converged: at a positive definite Hessian (s0 at most 1e-9 of the largest curvature), the Newton
    step's predicted gain is below ``gain_tol`` (relative)."""
    coords, c0 = fun.coords, fun.c0
    w_min, w_max = w_bounds
    f, g = fun(z)
    sigma = 1e-12  # relative to lambda_max
    it = 0
    history = [f]
    for it in range(1, max_iter + 1):
        if deadline is not None and time.perf_counter() > deadline:
            return z, f, it - 1, False, "time limit"
        ab, col, corner = fun.hessian(z)
        floor, scale = definite_shift(ab, col, corner)
        definite = floor <= 1e-9 * scale
        first = True
        while True:
            dz = solve_arrowhead(ab, col, corner, g, floor + sigma * scale)
            if dz is None:  # not positive definite with the T arrow at this shift
                sigma = max(10.0 * sigma, 1e-12)
                first = False
                if sigma > 1e6:
                    return z, f, it, False, "the Hessian stays indefinite"
                continue
            predicted = -(g @ dz) - 0.5 * _quad(ab, col, corner, dz)  # the model's decrease
            if first and definite and sigma <= 1e-6 and predicted <= gain_tol * max(abs(f), OBJECTIVE_FLOOR):
                return z, f, it, True, f"Newton step's predicted gain below {gain_tol:g} (relative)"
            t = _feasible_fraction(coords, z, dz, c0, w_min, w_max)
            if t == 0.0:
                return z, f, it, False, "a speed bound blocks the step"
            dz = t * dz
            fn, gn = fun(z + dz)
            if fn < f and (f - fn) >= 0.25 * t * predicted:
                break
            # the model overshoots where the curvature jumps (a sample crossing a region's boundary):
            # backtrack along the Newton direction (Armijo) before turning it towards the gradient
            slope = -float(g @ dz)
            for _ in range(BACKTRACKS):
                dz = 0.5 * dz
                slope *= 0.5
                fn, gn = fun(z + dz)
                if fn <= f - 1e-4 * slope:
                    break
            else:
                fn = np.inf
            if fn < f:
                break
            if predicted <= ROUNDING * max(abs(f), OBJECTIVE_FLOOR):
                # the steps short enough for the model to hold promise less than evaluating f can
                # resolve: nothing left to gain that could be measured (optimize.solve still asks the
                # KKT residual before it says converged)
                return z, f, it, True, "no step gains more than the objective's rounding"
            sigma = max(10.0 * sigma, 1e-12)
            first = False
            if sigma > 1e6:
                return z, f, it, False, "no step decreases the objective"
        if log is not None:
            log(it, fn, predicted, f - fn, sigma, t)
        z, f, g = z + dz, fn, gn
        sigma = max(sigma / 10.0, 1e-12)
        history.append(f)
        if len(history) > STALL_ITERATIONS and history[-STALL_ITERATIONS - 1] - f <= STALL_GAIN * max(abs(f), OBJECTIVE_FLOOR):
            # creeping along a direction of almost no curvature: what is left is below any tolerance
            # a timing needs (converged still asks the KKT residual, see optimize.solve)
            return z, f, it, True, f"objective gained less than {STALL_GAIN:g} (relative) over {STALL_ITERATIONS} Newton iterations"
    return z, f, it, False, "iteration limit"


def _quad(ab, col, corner, x):
    """x^T H x for the banded + arrow H."""
    n_c = ab.shape[1]
    xc = x[:n_c]
    band = ab.shape[0] - 1
    tot = float(np.sum(ab[band] * xc * xc))
    for off in range(1, band + 1):
        tot += 2.0 * float(np.sum(ab[band - off, off:] * xc[off:] * xc[:-off]))
    if col is not None:
        tot += 2.0 * x[-1] * float(col @ xc) + corner * x[-1] ** 2
    return tot
