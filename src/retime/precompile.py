"""Compile retime's numba kernels ahead of time, into numba's own cache.

A first run otherwise spends most of its time in the compiler (about 50 s for ``retime physics``
on this 2-core machine, 40 s for the demo). The build runs this module (``setup.py``'s build step,
so ``pip install -e .`` and a wheel build both do), and anyone can run it by hand::

    python -m retime.precompile            # or: python -m retime.precompile guided

It compiles by running the methods themselves on a bundled clip: guided (exact and heuristic) and
physics (fixed and free duration, with and without changed gravity, and the check of a walk,
which times it on one foot), so every kernel gets
exactly the signatures and compiler settings of a real run (it calls `guided_solve` and
`physics_warp`, which `retime.method.solve` calls too; physics on one process, so that the pool
does not compile the region kernels once per worker).
numba stores the machine code beside each source file (``__pycache__``, or ``NUMBA_CACHE_DIR``)
keyed by a hash of the source, the Python and numba versions and this CPU; a run whose key
differs (another CPU, an edited file) compiles as before, so a stale cache can cost time, never
a wrong answer.
"""
from __future__ import annotations

import sys
import time

from .data import bundled_path

CLIP = "16_06.amc"
WALK = "16_15.amc"
WIDE_BAND_CLIP = "131_01.bvh"  # 8 s: at --scale 0.6 its refinement prunes (16_06 is searched whole)


def _runs(motion):
    """The method calls whose kernels a first run needs: (label, callable)."""
    from .guided import guided_solve
    from .motion import load_motion
    from .physics.api import physics_warp
    from .physics.check import check_clip
    from .physics.regions import RegionOptions

    d = motion.duration * 0.5

    def physics(**kw):
        # one process: a forked pool would compile the region kernels once per worker
        return physics_warp(motion, region_options=RegionOptions(workers=1), **kw)

    def wide_band():
        # a band wide enough that the steady refinement bounds its search first (retime.guided.steady:
        # the relaxation's kernels), as most clips longer than a few seconds are
        return guided_solve(load_motion(bundled_path(WIDE_BAND_CLIP)), scale=0.6, quiet=True)

    return [
        ("guided", lambda: guided_solve(motion, duration=d, quiet=True)),
        ("guided, a wide band", wide_band),
        ("guided --fast", lambda: guided_solve(motion, duration=d, fast=True, quiet=True)),
        ("physics", lambda: physics(duration=d)),
        ("physics, free duration", lambda: physics()),
        ("physics, changed gravity", lambda: physics(duration=d, gravity=(0.0, -4.9, 0.0))),
        # a walk has no flight to time it: the check times it on one foot (physics.stance_rate's kernel)
        ("physics check, a walk", lambda: check_clip(load_motion(bundled_path(WALK)))),
    ]


def _threaded_objective():
    """The objective's threaded evaluation, which clips of 20,000 samples and more use (over ~40 s
    of 120 Hz motion), compiled for the signature of the serial one just compiled: a long clip
    passes the same types."""
    import numba

    from .physics.timing import objective

    for sig in objective._evaluate.signatures:
        objective._evaluate_par.compile((numba.types.int64,) + tuple(sig))


def precompile(say=sys.stderr, methods=("guided", "physics")) -> int:
    """Run the methods once (see the module docstring); return the number of kernels compiled.
    ``methods``: the runs whose label starts with one of these."""
    from .jit import compile_watch
    from .motion import load_motion

    motion = load_motion(bundled_path(CLIP))
    t0 = time.perf_counter()
    with compile_watch(say) as watch:
        for label, run in _runs(motion):
            if label.startswith(tuple(methods)):
                run()
        if "physics" in methods:
            _threaded_objective()
    if say is not None:
        say.write(f"retime's kernels are compiled and cached ({time.perf_counter() - t0:.0f} s)\n")
    return watch.kernels


if __name__ == "__main__":
    precompile(methods=tuple(sys.argv[1:]) or ("guided", "physics"))
