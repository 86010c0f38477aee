"""Physics-based retiming (McCann, Pollard, Srinivasa 2006): the timing that keeps a motion physically
plausible for a body under a new duration, keytimes, gravity or masses.

Entry points: :func:`retime.physics.method.solve` (the method contract of :mod:`retime.method`),
:func:`physics_warp` (the same with every option as an argument) and :func:`check_clip` (how
physical a clip is as captured, ``retime check``).

Symbols, one meaning each, everywhere in this package (McCann et al.'s notation):

=========  ===================================================================================
t          output time (s), 0..T; T the output duration
s          source time (s), 0..S; S the source duration
p          the timing: s = p(t) (a :class:`retime.warp.TimingCurve`; here a :class:`.timing.spline.TimingSpline`)
p'         playback speed ds/dt (1: as captured)
p''        playback acceleration d2s/dt2
u, v       the timing at a frame as a point of the plane: u = p'', v = p'^2
q          generalized coordinates of the body; q', q'' their derivatives in *source* time
a, b, c    path dynamics per source frame (:mod:`.model.dynamics`): the generalized forces a timing needs
           are tau = a u + b v + c - N lambda (a: the q' term, b: the q'' and velocity term, c: gravity)
N          the contact map J^T P (Eq. 11): one column per basis force of the friction pyramids
lambda     basis force magnitudes (>= 0), one per column of N (``lam`` in code)
region     the (u, v) for which some lambda keeps every tau within its bounds: a convex polygon per
           frame (:mod:`.regions`); *feasible* = inside it up to :data:`.regions.feasibility.IN_REGION_TOL`
=========  ===================================================================================

:mod:`.api`, :mod:`.method`, :mod:`.check` and :mod:`.report` are the front, over three wings:
:mod:`.model` (the body and its path dynamics), :mod:`.regions` (the feasible regions: the region
set is the package itself) and :mod:`.timing` (the timing spline and its optimization).

Modules, in the order the method runs: :mod:`.model.body` (segments, soles, limits), :mod:`.model.contacts`
(when each foot touches the floor), :mod:`.model.path` and :mod:`.model.tree` (derivatives and rigid-body
kernels), :mod:`.model.dynamics` (a, b, c, N per frame), :mod:`.regions` (feasible polygons),
:mod:`.timing.objective` (Eq. 14 baked per frame), :mod:`.timing.globalstart` and :mod:`.timing.optimize` (the timing
spline, :mod:`.timing.spline`), :mod:`.regions.feasibility` and :mod:`.report` (what the result says);
:mod:`.api` runs them in order and :mod:`.method` puts them behind the contract. :mod:`.check`
(with :mod:`.plausibility` and :mod:`.check_forces`: the feet's forces and the centre of mass per
frame) is ``retime check``.
"""

__all__ = ["physics_warp", "PhysicsResult", "check_clip", "ClipCheck"]

_LAZY = {"physics_warp": "api", "PhysicsResult": "api", "check_clip": "check", "ClipCheck": "check"}


def __getattr__(name):
    # imported on first use: the compiled kernels load only when a caller needs them
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
