"""Optimizing the timing curve (McCann et al. 2006, sec. 3.6), and an interactive session.

Variables: the spline's derivative coefficients ``w`` (see :mod:`retime.physics.timing.spline`), bounded
below by ``w_min`` (the curve never stops or runs backwards) and above by ``w_max``. The end point
p(T) = S holds by construction; a free duration is part of the same variables. What remains are
equality constraints, each a smooth function of ``w``:

* **keytimes** (point constraints): p(t*) = s*.

**Locked control points** need no constraint: the spline normalizes each piece between pinned
coefficients to its pinned span (:meth:`TimingSpline.coefficients`), so a lock holds exactly for every
``w`` and moving a locked point only changes that span.

Methods:

* ``"newton"`` (default): ``"lbfgs"``, then Newton's method on the banded problem from its answer
  (:mod:`retime.physics.timing.newton`), whose answer is kept when its objective is no worse; its stopping test is
  second order (no Newton step predicts a gain), which L-BFGS's (the gain over ten iterations)
  is not: L-BFGS stopped 0.1-1 source frames from the minimum, wherever the input's rounding led it;
* ``"gd"``: the paper's gradient descent (projected onto the bounds, Armijo backtracking);
* ``"lbfgs"``: quasi-Newton, a projected L-BFGS with little per-iteration overhead;
* ``"lbfgsb"``: SciPy's L-BFGS-B with the bounds (same idea, more overhead per iteration);
* ``"slsqp"``: SciPy's SLSQP, which takes the equality constraints directly.

``gd`` and ``lbfgs`` take the equality constraints through an augmented Lagrangian (outer updates of
the multipliers), which converges to them exactly; each outer step warm-starts from the last.

:class:`RetimingSession` keeps the current solution so that an editor can move, add, remove or lock
one control point, add or drop a keytime, and re-converge from where it was.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import math

import numpy as np
from numba import njit
from scipy.optimize import minimize

from ...blas import single_threaded_blas
from ...errors import RetimeError
from .newton import OBJECTIVE_FLOOR
from .objective import BakedObjective, ObjectiveWorkspace, evaluate, subsampled
from .spline import TimingSpline

OPTIMIZERS = ("newton", "lbfgs", "lbfgsb", "gd", "slsqp")
ZERO_OBJECTIVE = 1e-12  # an objective this small is 0 (its terms are squares and an l1 penalty) up to rounding
KKT_TOL = 1e-3  # converged: the Newton test met and kkt_residual below this (the relative objective change a
# relative change of one speed coefficient would still bring; a float32 copy of a clip then retimes
# within 0.1 source frame of the original, benchmarks/physics_converge.py)
QUICK_TOL = 5e-5  # the editor's quick stage: L-BFGS stops when ten iterations gain less than 10 x this
# (relative). On 16_16 at half duration, 20 + 30 one-point edits: 38-40 iterations and 24-26 ms median
# against 64-68 and 38-39 ms at 1e-5, the curve 2.1 source ms (max 4.6; 5.9) from the converged one
# against 1.6-1.8 (max 4.3; 4.6): a looser answer while the drag goes on; the polished objective after it
# the same (each edit within +-0.06%, both signs: nearby minima), the polish's time too
PREVIEW_STRIDE = 2  # the quick stage integrates on every 2nd sample (2 per source frame instead of 4): on
# 16_16 at half duration, 20 one-point edits, median 14.4 ms against 24.8 (all samples) and 9.6 (every 4th),
# the curve a median 2.12 source ms (max 5.28) from the converged one against 1.76 (6.38) and 2.64 (4.33)


@dataclass
class SolveInfo:
    method: str
    objective: float
    iterations: int
    evaluations: int
    seconds: float
    constraint_violation: float
    converged: bool  # "newton": its second-order test met and kkt_residual <= KKT_TOL; others: their own test
    message: str = ""  # why it stopped
    kkt_residual: float = float("nan")  # first-order optimality at the answer (see kkt_residual)
    lbfgs_objective: float = float("nan")  # "newton": the L-BFGS answer's objective, before the polish
    newton_iterations: int = 0  # "newton": the polish's iterations (included in iterations)


@dataclass
class Problem:
    """Objective + spline + constraints, and the evaluations' own workspace (the objective is shared,
    its wedge hints are this problem's: one problem, one thread)."""

    obj: BakedObjective
    spline: TimingSpline
    keytimes: list = field(default_factory=list)  # [(source_time, output_time)]
    w_min: float = 0.02
    w_max: float = 12.0
    gauge: float = 1e-3
    n_evals: int = 0
    workspace: ObjectiveWorkspace | None = None  # default: a new one for this problem

    def __post_init__(self):
        if self.workspace is None:
            self.workspace = ObjectiveWorkspace.for_objective(self.obj)

    def bounds(self):
        n = len(self.spline.w)
        return [(self.w_min, self.w_max)] * n

    @property
    def locks(self) -> dict:
        return self.spline.locks

    def fun(self, w):
        """Objective and gradient (plus a tiny gauge fixing the free scales of w, see TimingSpline.gauge)."""
        self.n_evals += 1
        val, g = evaluate(self.obj, self.spline, w, grad=True, workspace=self.workspace)
        if self.gauge > 0:
            gv, gg = self.spline.gauge(w)
            val += self.gauge * gv
            g = g + self.gauge * gg
        return val, g

    def value(self, w):
        return evaluate(self.obj, self.spline, w, grad=False, workspace=self.workspace)

    @property
    def n_eq(self):
        return len(self.keytimes)

    def eq(self, w):
        """Equality constraints g(w) (seconds) and their Jacobian (n_eq, n_w)."""
        sp = self.spline
        c = sp.coefficients(w)
        T = sp.duration_of(w)
        rows, jac = [], []
        for s_star, t_star in self.keytimes:
            tau = min(max(t_star / T, 0.0), 1.0)
            Nb, dN = _basis_at(sp, tau)
            val = float(Nb @ c) - s_star
            gT = -float(dN @ c) * tau / T if 0.0 < tau < 1.0 else 0.0
            rows.append(val)
            jac.append(sp.chain(Nb, gT, w))
        if not rows:
            return np.zeros(0), np.zeros((0, len(w)))
        return np.array(rows), np.array(jac)


def _basis_at(sp, tau):
    """Basis values and derivatives (d/dtau) of all coefficients at ``tau`` (span polynomials)."""
    m = int(np.clip(np.searchsorted(sp.breaks, tau, side="right") - 1, 0, len(sp.breaks) - 2))
    x = tau - sp.breaks[m]
    M = sp.span_matrices[m]
    powers = x ** np.arange(sp.support)
    Nb = np.zeros(sp.n_c)
    dN = np.zeros(sp.n_c)
    Nb[m:m + sp.support] = powers @ M
    dN[m:m + sp.support] = (np.arange(1, sp.support) * powers[:-1]) @ M[1:]
    return Nb, dN


# ------------------------------------------------------------------------------------------------
# Solvers
# ------------------------------------------------------------------------------------------------

def _scipy_lbfgsb_inner(fun, w0, bounds, max_iter, tol):
    res = minimize(fun, w0, jac=True, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": max_iter, "ftol": tol, "gtol": 1e-10, "maxcor": 20})
    return res.x, int(res.nit), res.success, str(res.message)


@njit(cache=True)
def _direction(g, free, S, Y, rho, count, head, xnorm):
    """-H g by the L-BFGS two-loop recursion over the variables off their bounds (circular memory:
    the newest pair at ``head - 1``)."""
    n = len(g)
    mem = S.shape[0]
    q = np.empty(n)
    for i in range(n):
        q[i] = g[i] if free[i] else 0.0
    alph = np.empty(mem)
    for t in range(count):
        k = (head - 1 - t) % mem
        a_ = 0.0
        for i in range(n):
            a_ += S[k, i] * q[i]
        a_ *= rho[k]
        alph[k] = a_
        for i in range(n):
            q[i] -= a_ * Y[k, i]
    if count > 0:
        k = (head - 1) % mem
        sy = 0.0
        yy = 0.0
        for i in range(n):
            sy += S[k, i] * Y[k, i]
            yy += Y[k, i] * Y[k, i]
        for i in range(n):
            q[i] *= sy / yy
    else:
        qn = math.sqrt(np.sum(q * q))
        sc = min(1.0, 0.1 * xnorm) / max(qn, 1e-300)
        for i in range(n):
            q[i] *= sc
    for t in range(count - 1, -1, -1):
        k = (head - 1 - t) % mem
        b_ = 0.0
        for i in range(n):
            b_ += Y[k, i] * q[i]
        b_ *= rho[k]
        for i in range(n):
            q[i] += S[k, i] * (alph[k] - b_)
    for i in range(n):
        q[i] = -q[i] if free[i] else 0.0
    return q


def _lbfgs_inner(fun, w0, bounds, max_iter, tol, memory=12):
    """Projected L-BFGS: the two-loop recursion (compiled) on the variables off their bounds, a
    projected backtracking (Armijo) line search, curvature pairs kept only when s.y > 0. The bounds
    (w_min <= w <= w_max) are rarely active, and this loop costs microseconds per iteration where
    SciPy's L-BFGS-B wrapper spends a quarter of a millisecond, which matters for an interactive
    re-convergence of a hundred iterations."""
    lo = np.array([b[0] for b in bounds], dtype=float)
    hi = np.array([b[1] for b in bounds], dtype=float)
    x = np.clip(np.asarray(w0, dtype=float), lo, hi)
    n = len(x)
    f, g = fun(x)
    S = np.zeros((memory, n))
    Y = np.zeros((memory, n))
    rho = np.zeros(memory)
    count = head = 0
    hist = [f]
    it = 0
    for it in range(1, max_iter + 1):
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        d = _direction(g, free, S, Y, rho, count, head, float(np.linalg.norm(x)))
        gd = float(g @ d)
        if gd >= 0:  # not a descent direction: restart from the projected gradient
            count = head = 0
            d = -np.where(free, g, 0.0)
            d *= min(1.0, 0.1 * np.linalg.norm(x)) / max(np.linalg.norm(d), 1e-300)
        step = 1.0
        for _ in range(40):
            xn = np.clip(x + step * d, lo, hi)
            fn, gn = fun(xn)
            if fn <= f + 1e-4 * float(g @ (xn - x)):
                break
            step *= 0.3
        else:
            return x, it, True, "line search cannot improve"
        s_ = xn - x
        y_ = gn - g
        sy = float(s_ @ y_)
        if sy > 1e-12 * np.linalg.norm(s_) * np.linalg.norm(y_):
            S[head], Y[head], rho[head] = s_, y_, 1.0 / sy
            head = (head + 1) % memory
            count = min(count + 1, memory)
        hist.append(fn)
        # converged when the last 10 iterations together gained less than 10 * tol (relative)
        done = len(hist) > 10 and hist[-11] - fn <= 10 * tol * max(1.0, abs(fn))
        x, f, g = xn, fn, gn
        if done:
            return x, it, True, "objective gained less than tol over 10 iterations"
        if np.max(np.abs(np.where(free, g, 0.0))) <= 1e-12:
            return x, it, True, "projected gradient below 1e-12"
    return x, it, False, "iteration limit"


def _gd_inner(fun, w0, bounds, max_iter, tol):
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    w = np.clip(w0, lo, hi)
    f, g = fun(w)
    step = 1.0 / max(np.linalg.norm(g), 1e-12)
    it = 0
    for it in range(1, max_iter + 1):
        while True:
            wn = np.clip(w - step * g, lo, hi)
            fn, gn = fun(wn)
            dec = float(g @ (w - wn))
            if fn <= f - 1e-4 * dec or step < 1e-16:
                break
            step *= 0.5
        converged = abs(f - fn) <= tol * max(1.0, abs(f))
        w, f, g = wn, fn, gn
        step *= 2.0
        if converged:
            return w, it, True, "objective gained less than tol in one iteration"
    return w, it, False, "iteration limit"


def solve(problem: Problem, w0=None, method="newton", max_iter=500, tol=1e-9, eq_tol=1e-6,
          max_seconds=None, newton_iter=300) -> tuple[np.ndarray, SolveInfo]:
    """Minimize the objective from ``w0`` (default: the spline's current w). ``newton_iter``: the
    Newton polish's iteration limit (method ``"newton"``)."""
    with single_threaded_blas():  # the quasi-Newton updates are tiny dense products
        if method != "newton":
            return _solve(problem, w0, method, max_iter, tol, eq_tol, max_seconds)
        t0 = time.perf_counter()
        w, first = _solve(problem, w0, "lbfgs", max_iter, tol, eq_tol, max_seconds)
        evals = first.evaluations
        left = None if max_seconds is None else max(0.0, max_seconds - (time.perf_counter() - t0))
        w_n, it, ok, msg, n_evals = polish(problem, w, eq_tol, newton_iter, left)
        val_n = problem.value(w_n)
        viol_n = float(np.max(np.abs(problem.eq(w_n)[0]))) if problem.n_eq else 0.0
        keep = val_n <= first.objective and viol_n <= max(eq_tol, first.constraint_violation)
        if keep:
            w = w_n
        else:
            # Newton standing still (the same curve, its gauge fixed, one rounding apart) confirms the
            # L-BFGS answer; a Newton answer truly above it does not
            same = abs(val_n - first.objective) <= 1e-12 * max(abs(first.objective), OBJECTIVE_FLOOR)
            ok = ok and same
            msg = f"{msg}; the L-BFGS answer is kept (Newton's objective {val_n:.9g} is not below it)"
        val, kkt = kkt_residual(problem, w)
        viol = float(np.max(np.abs(problem.eq(w)[0]))) if problem.n_eq else 0.0
        feasible = viol <= max(eq_tol, 1e-9) * 10
        # every term of the objective is non-negative, so one at rounding level is the global minimum
        # (a clip at its own natural timing), where no step can decrease it and the relative tests are noise
        at_zero = val <= ZERO_OBJECTIVE
        info = SolveInfo("newton", val, first.iterations + it, evals + n_evals, time.perf_counter() - t0, viol,
                         feasible and ((bool(ok) and kkt <= KKT_TOL) or at_zero), msg, kkt,
                         lbfgs_objective=first.objective, newton_iterations=it)
        return w, info


def polish(problem: Problem, w, eq_tol=1e-6, max_iter=300, max_seconds=None):
    """Newton's method from w on the banded (c, T) coordinates (:mod:`retime.physics.timing.newton`); keytimes by an
    augmented Lagrangian whose multipliers start at their least-squares values at w.
    (w, iterations, converged, message, evaluations)."""
    from .newton import BandedCoordinates, BandedObjective, newton_inner

    t0 = time.perf_counter()
    coords = BandedCoordinates(problem)
    z, c0 = coords.from_w(w)
    bounds = (problem.w_min, problem.w_max)
    mu = np.zeros(problem.n_eq)
    rho = 0.0
    if problem.n_eq:
        f0, g = problem.fun(w)
        J = problem.eq(w)[1]
        mu = np.linalg.lstsq(J.T, -g, rcond=None)[0]
        rho = 1e3 * max(1.0, abs(f0)) / max(problem.spline.S, 1e-3) ** 2
    iters = 0
    evals = 0
    ok, msg = False, ""
    deadline = None if max_seconds is None else t0 + max_seconds
    for _ in range(1 if not problem.n_eq else 20):
        fun = BandedObjective(coords, c0, mu, rho)
        z, _, it, ok, msg = newton_inner(fun, z, bounds, max_iter=max(1, max_iter - iters), deadline=deadline)
        iters += it
        evals += fun.evaluations
        if not problem.n_eq:
            break
        h = problem.eq(coords.to_w(z, c0))[0]
        if float(np.max(np.abs(h))) <= eq_tol and ok:
            break
        mu = mu + rho * h
        if iters >= max_iter or (deadline is not None and time.perf_counter() > deadline):
            ok = False
            break
    return coords.to_w(z, c0), iters, ok, msg, evals


def _solve(problem, w0, method, max_iter, tol, eq_tol, max_seconds):
    if method not in OPTIMIZERS:
        raise RetimeError(f"unknown optimizer {method!r} (use {', '.join(OPTIMIZERS)})")
    t0 = time.perf_counter()
    problem.n_evals = 0
    bounds = problem.bounds()
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    w = np.clip(np.asarray(problem.spline.w if w0 is None else w0, dtype=float), lo, hi)
    iters = 0
    ok = True
    msg = ""
    if method == "slsqp":
        cons = []
        if problem.n_eq:
            cons = [{"type": "eq", "fun": lambda x: problem.eq(x)[0], "jac": lambda x: problem.eq(x)[1]}]
        res = minimize(problem.fun, w, jac=True, method="SLSQP", bounds=bounds, constraints=cons,
                       options={"maxiter": max_iter, "ftol": tol})
        w, iters, ok, msg = np.clip(res.x, lo, hi), int(res.nit), bool(res.success), str(res.message)
    else:
        inner = {"lbfgs": _lbfgs_inner, "lbfgsb": _scipy_lbfgsb_inner, "gd": _gd_inner}[method]
        if problem.n_eq == 0:
            w, iters, ok, msg = inner(problem.fun, w, bounds, max_iter, tol)
        else:
            w, iters, ok, msg = _augmented_lagrangian(problem, w, bounds, inner, max_iter, tol, eq_tol,
                                                      t0, max_seconds)
    val, kkt = kkt_residual(problem, w)
    viol = float(np.max(np.abs(problem.eq(w)[0]))) if problem.n_eq else 0.0
    info = SolveInfo(method, val, iters, problem.n_evals, time.perf_counter() - t0, viol,
                     bool(ok) and viol <= max(eq_tol, 1e-9) * 10, msg, kkt)
    return w, info


def kkt_residual(problem: Problem, w) -> tuple[float, float]:
    """(E(w), the first-order optimality residual at w): max over the coefficients of
    |dL/dw_k| w_k / |E|, the relative change of the objective a relative change of one speed
    coefficient would still bring, where L is E plus the keytimes' least-squares multipliers times
    their residuals, and a coefficient held at its bound by the gradient counts 0 (relative to at least
    newton.OBJECTIVE_FLOOR: the original timing's objective is 0 up to rounding). Zero at a smooth
    constrained minimum whatever the objective's units; it stays large where the answer sits on a kink
    of the objective, which no gradient-based stop can see (benchmarks/physics_converge.py counts
    those)."""
    val, g = evaluate(problem.obj, problem.spline, w, grad=True, workspace=problem.workspace)
    held = ((w <= problem.w_min * (1 + 1e-9)) & (g > 0)) | ((w >= problem.w_max * (1 - 1e-9)) & (g < 0))
    free = ~held
    if problem.n_eq:
        J = problem.eq(w)[1]
        mu = np.linalg.lstsq(J[:, free].T, -g[free], rcond=None)[0]
        g = g + J.T @ mu
    r = np.where(free, np.abs(g) * np.abs(w), 0.0)
    return val, float(np.max(r, initial=0.0)) / max(abs(val), OBJECTIVE_FLOOR)


def _augmented_lagrangian(problem, w, bounds, inner, max_iter, tol, eq_tol, t0, max_seconds):
    m = problem.n_eq
    mu = np.zeros(m)
    f0, _ = problem.fun(w)
    S = problem.spline.S
    rho = 1e3 * max(1.0, abs(f0)) / max(S, 1e-3) ** 2
    iters = 0
    ok = False
    msg = ""
    last = np.inf
    for outer in range(30):
        def fun(x, mu=mu, rho=rho):
            f, g = problem.fun(x)
            h, J = problem.eq(x)
            return f + mu @ h + 0.5 * rho * h @ h, g + J.T @ (mu + rho * h)

        # loose inner solves while the multipliers are still far off, tight ones at the end
        w, it, ok_in, msg = inner(fun, w, bounds, max_iter, tol if last < 10 * eq_tol else max(tol, 1e-6))
        iters += it
        h, _ = problem.eq(w)
        viol = float(np.max(np.abs(h)))
        if viol <= eq_tol:
            ok = ok_in
            break
        mu = mu + rho * h
        if viol > 0.25 * last:
            rho *= 10.0
        last = viol
        if max_seconds is not None and time.perf_counter() - t0 > max_seconds:
            msg = "time limit"
            break
    return w, iters, ok, msg


# ------------------------------------------------------------------------------------------------
# Interactive session
# ------------------------------------------------------------------------------------------------

class RetimingSession:
    """The current timing curve of an interactive edit, re-converged after every change.

    Control points are the spline's (output time, source time) pairs (:meth:`control_points`);
    index 0 and the last one are the ends (source 0 and S) and cannot move vertically."""

    def __init__(self, problem: Problem, optimizer: str, fps=None):
        # optimizer: one of OPTIMIZERS, given by the caller (physics' default is Settings.optimizer, in the
        # front; this wing does not reach up for it)
        self.problem = problem
        self.optimizer = optimizer
        self.fps = fps
        self.history: list[SolveInfo] = []
        self._preview: Problem | None = None  # the quick stage's problem (see preview_problem)

    @property
    def spline(self) -> TimingSpline:
        return self.problem.spline

    @property
    def keytimes(self):
        return list(self.problem.keytimes)

    def control_points(self):
        t, s = self.spline.control_points()
        return [{"index": k, "output_time": float(t[k]), "source_time": float(s[k]),
                 "locked": k in self.spline.locks, "movable": 0 < k < len(s) - 1} for k in range(len(s))]

    def objective(self) -> float:
        return self.problem.value(self.spline.w)

    def move(self, index, source_time, lock=False):
        """Put control point ``index`` at ``source_time`` (clamped between its neighbours)."""
        sp = self.spline
        c = sp.coefficients()
        n = len(c)
        if not (0 < index < n - 1):
            raise RetimeError(f"control point {index} cannot move (0 and {n - 1} are the ends of the motion)")
        # stay between the nearest pinned neighbours (locks and ends), so that pieces keep positive spans
        idx, val = sp.pieces()
        below = max(v for k, v in zip(idx, val) if k < index)
        above = min(v for k, v in zip(idx, val) if k > index)
        gap = 1e-3 * sp.S
        s = float(np.clip(source_time, below + gap * (index - max(k for k in idx if k < index)),
                          above - gap * (min(k for k in idx if k > index) - index)))
        # change the curve only near the point: set its coefficient, keep the others
        c = c.copy()
        c[index] = s
        for k in range(index + 1, n):
            c[k] = max(c[k], c[k - 1] + 1e-6 * sp.S)
        for k in range(index - 1, -1, -1):
            c[k] = min(c[k], c[k + 1] - 1e-6 * sp.S)
        c[0], c[-1] = 0.0, sp.S
        sp.set_coefficients(c)
        if lock:
            sp.locks[index] = s  # exact from now on: the pieces on both sides meet it
        sp.w = np.clip(sp.w, self.problem.w_min, self.problem.w_max)
        return s

    def lock(self, index, locked=True):
        c = self.spline.coefficients()
        if not (0 <= index < len(c)):
            raise RetimeError(f"no control point {index}")
        if locked and 0 < index < len(c) - 1:
            self.spline.locks[index] = float(c[index])
        else:
            w_before = self.spline.coefficients()
            self.spline.locks.pop(index, None)
            self.spline.set_coefficients(w_before)  # same curve, one piece fewer

    def add(self, output_time):
        """Add a control point at ``output_time`` (the curve does not change); returns its index."""
        T = self.spline.duration
        if not (0 < output_time < T):
            raise RetimeError(f"output time {output_time:g} s is outside (0, {T:g}) s")
        sp = self.spline
        old = dict(sp.locks)
        old_c = sp.coefficients()
        sp.locks = {}
        sp.set_coefficients(old_c)
        sp.insert_knot(output_time / T)
        new_c = sp.coefficients()
        # a locked point keeps (nearly) its source time: re-lock the nearest new coefficient
        for k, v in old.items():
            j = int(np.argmin(np.abs(new_c - v)))
            if 0 < j < len(new_c) - 1:
                sp.locks[j] = float(new_c[j])
        self._rebake_spline()
        t, _ = self.spline.control_points()
        return int(np.argmin(np.abs(t - output_time)))

    def remove(self, index):
        c = self.spline.coefficients()
        n = len(c)
        if not (0 < index < n - 1) or len(self.spline.interior) == 0:
            raise RetimeError(f"control point {index} cannot be removed")
        sp = self.spline
        old = {k: v for k, v in sp.locks.items() if k != index}
        sp.locks = {}
        knot = int(np.clip(index - (sp.degree + 1) // 2, 0, len(sp.interior) - 1))  # the knot under its Greville point
        sp.remove_knot(knot, w_min=self.problem.w_min)
        new_c = sp.coefficients()
        for v in old.values():
            j = int(np.argmin(np.abs(new_c - v)))
            if 0 < j < len(new_c) - 1:
                sp.locks[j] = float(v)
        self._rebake_spline()

    def _rebake_spline(self):
        self.problem.spline.w = np.clip(self.problem.spline.w, self.problem.w_min, self.problem.w_max)

    def reconverge(self, max_iter=2000, tol=None, max_seconds=None, quick=False) -> SolveInfo:
        """Re-optimize from the current curve. ``quick``: the first stage alone (L-BFGS to ``tol``,
        default QUICK_TOL, the relative objective gain over ten iterations, on the objective integrated
        at half the density, :meth:`preview_problem`; the info's objective is the full one's), the
        editor's answer while a drag goes on: within a fraction of a source frame of the converged one, in milliseconds
        (``benchmarks/physics.py`` measures both on 16_16 at half duration). Otherwise the session's
        method to the end: with ``"newton"``, L-BFGS to ``tol`` (default 1e-9: Newton's polish from a
        loose L-BFGS stop crawls through hundreds of small steps) and the Newton polish."""
        method = "lbfgs" if quick and self.optimizer == "newton" else self.optimizer
        if tol is None:
            # the first stage alone is followed by the polish; a session's own method ends here
            tol = QUICK_TOL if method != self.optimizer else 1e-9 if method == "newton" else 1e-5
        problem = self.preview_problem() if method != self.optimizer else self.problem
        w, info = solve(problem, self.spline.w, method=method, max_iter=max_iter, tol=tol,
                        max_seconds=max_seconds)
        if method != self.optimizer:  # the first stage of the session's method: not its answer yet
            info.converged = False
            info.message = f"quick (first stage only): {info.message}"
            info.objective = self.problem.value(w)  # what the session reports is always the full objective
        self.spline.w = w
        self.history.append(info)
        return info

    def curve(self, fps=None):
        return self.spline.timing_curve(fps or self.fps or 120.0)

    def preview_problem(self) -> Problem:
        """The quick stage's problem: the session's objective on every PREVIEW_STRIDE-th sample, on
        the same spline and keytimes (its own workspace: the wedge hints follow its own samples)."""
        p = self.problem
        if self._preview is None:
            self._preview = Problem(subsampled(p.obj, PREVIEW_STRIDE), p.spline, keytimes=p.keytimes,
                                    w_min=p.w_min, w_max=p.w_max, gauge=p.gauge)
        self._preview.w_min, self._preview.w_max = p.w_min, p.w_max
        return self._preview
