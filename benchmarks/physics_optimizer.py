"""Where the physics optimizer's seconds go (issue 24), on the long capture of ``longclip.py`` or on
any clip: the L-BFGS stage (iterations, objective evaluations), then Newton's polish split into its
exact Hessians (one pass over the samples each), its trial steps (evaluations), its banded Cholesky
factorizations and solves (the shift search among them), and the rest. Output at half duration, as
``scaling.py`` runs physics; the problem (dynamics, regions, baked objective, grid start) is built
first and not timed.

    python3 benchmarks/physics_optimizer.py --minutes 1          # the 1-minute capture
    python3 benchmarks/physics_optimizer.py --clip src/retime/data/cmu/16_06.amc
    python3 benchmarks/physics_optimizer.py --minutes 10 --shared /path/to/shared/data/cmu
"""
from __future__ import annotations

import argparse
import sys
import time
from contextlib import contextmanager
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "src"))
sys.path.insert(0, str(HERE))


class Ledger:
    """Calls and seconds per account; evaluations are charged to the account open when they run."""

    def __init__(self):
        self.calls: dict[str, int] = {}
        self.seconds: dict[str, float] = {}
        self.account = "L-BFGS stage (and KKT checks): evaluations"

    def charge(self, name, seconds):
        self.calls[name] = self.calls.get(name, 0) + 1
        self.seconds[name] = self.seconds.get(name, 0.0) + seconds

    def timed(self, fn, name=None):
        def wrapper(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.charge(name or self.account, time.perf_counter() - t0)
        return wrapper

    @contextmanager
    def account_of(self, name):
        before, self.account = self.account, name
        try:
            yield
        finally:
            self.account = before


def instrument(ledger: Ledger):
    """Wrap the optimizer's evaluations, Hessians and banded solves with the ledger's timers."""
    from retime.physics.timing import newton, optimize

    optimize.evaluate = ledger.timed(optimize.evaluate)
    newton.evaluate_c = ledger.timed(newton.evaluate_c)
    newton.hessian_c = ledger.timed(newton.hessian_c, "Newton: exact Hessians (one pass each)")
    newton.solve_arrowhead = ledger.timed(newton.solve_arrowhead, "Newton: banded Cholesky + solves (all)")
    newton.definite_shift = ledger.timed(newton.definite_shift, "Newton: of which the shift search")
    polish = optimize.polish

    def polish_accounted(*args, **kwargs):
        with ledger.account_of("Newton: trial steps' evaluations"):
            return polish(*args, **kwargs)

    optimize.polish = polish_accounted


def build_problem(motion, scale=0.5):
    """The physics method's problem for ``motion`` at ``scale`` times its duration, with the default
    Settings (regions, baked objective, grid start): (problem, settings)."""
    from retime.physics.api import conformed_gravity, make_problem, prepare
    from retime.physics.method import Settings

    s = Settings()
    _, _, _, obj = prepare(motion, conformed_gravity(motion, None), s)
    return make_problem(obj, motion.duration, scale * motion.duration, (), s.knot_spacing, s.w_min, s.w_max,
                        start=s.start), s


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=1.0, help="length of the long capture (default 1)")
    ap.add_argument("--clip", help="a motion file instead of the long capture")
    ap.add_argument("--shared", help="the CMU folder with 13_29 and 13_17 (default: longclip.SHARED)")
    args = ap.parse_args(argv)
    from retime.motion import load_motion
    from retime.physics.timing.optimize import solve

    if args.clip:
        motion = load_motion(args.clip)
        name = Path(args.clip).name
    else:
        from longclip import SHARED, long_capture

        motion = long_capture(args.minutes, Path(args.shared) if args.shared else SHARED)
        name = f"{args.minutes:g}-minute capture"
    t0 = time.perf_counter()
    problem, s = build_problem(motion)
    print(f"{name}: {motion.n_frames} frames, {len(problem.spline.w)} spline coefficients, "
          f"{len(problem.obj.arrays.s)} samples; problem built in {time.perf_counter() - t0:.1f} s", flush=True)
    ledger = Ledger()
    instrument(ledger)
    t0 = time.perf_counter()
    _, info = solve(problem, method=s.optimizer, max_iter=s.max_iter, tol=1e-9)
    total = time.perf_counter() - t0
    print(f"optimizer {total:.1f} s: {info.iterations} iterations ({info.iterations - info.newton_iterations} "
          f"L-BFGS, {info.newton_iterations} Newton), converged {info.converged}, kkt {info.kkt_residual:.2g}, "
          f"objective {info.objective:.10g} (L-BFGS's {info.lbfgs_objective:.10g}); stopped: {info.message}")
    for key in sorted(ledger.seconds, key=lambda k: -ledger.seconds[k]):
        print(f"  {key:48s} {ledger.calls[key]:7d} calls {ledger.seconds[key]:8.2f} s "
              f"{100 * ledger.seconds[key] / total:5.1f}%")
    rest = total - sum(v for k, v in ledger.seconds.items() if "of which" not in k)
    print(f"  {'the rest (L-BFGS and Newton arithmetic, Python)':48s} {'':13s} {rest:8.2f} s {100 * rest / total:5.1f}%")
    return 0


if __name__ == "__main__":
    sys.exit(main())
