"""The editor's physics adapter (McCann §3.6 interaction) on a short clip: hold, lock, release, keytimes."""
from __future__ import annotations

import numpy as np
import pytest

from retime.data import bundled_path
from retime.editor.methods import ADAPTERS, Clip
from retime.editor.sessions import Session
from retime.motion import load_motion


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    if ADAPTERS["physics"].availability(None) is not None:
        pytest.skip(ADAPTERS["physics"].availability(None))
    m = load_motion(bundled_path("16_06.amc"))
    clip = Clip("jump", m.frames(slice(0, 160)))  # 1.3 s: quick dynamics and regions
    s = Session("t", clip, tmp_path_factory.mktemp("out"), m.fps)
    s.apply([{"op": "method", "method": "physics"}])
    s.solve_now()
    return s


def test_points_are_the_spline_and_the_curve_passes_through_them(session):
    sol = session.solution
    assert sol.info["converged"]
    pts = session.points
    assert len(pts) > 8 and pts[0].t == 0 and pts[-1].s == pytest.approx(session.source_duration)
    assert np.all(np.diff([p.t for p in pts]) > 0) and np.all(np.diff([p.s for p in pts]) > 0)



def test_strip_agrees_with_the_curve_tested_as_any_curve(session):
    """The strip's feasible frames (shade 1) are the physics spline's frames in their region; the same
    test on the curve alone (p', p'' by differences of its samples, as the demo tests any curve)
    agrees on nearly every frame, and the fraction shown is the strip's."""
    from retime.physics.regions.feasibility import curve_feasibility

    sol = session.solution
    feas = np.asarray(sol.feasibility)
    assert feas.shape == (sol.curve.n_frames(session.fps),)
    assert sol.info["feasible_fraction"] == pytest.approx(np.mean(feas == 1.0), abs=1e-4)
    shared = session.adapter("physics").rs.shared
    other = curve_feasibility(sol.curve, shared.dynamics, shared.regions, session.fps)
    assert np.mean(other.inside == (feas == 1.0)) >= 0.95
    # outside the region the shade falls with the residual
    out = ~other.inside & (feas < 1.0)
    order = np.argsort(other.residual[out])
    assert np.all(np.diff(feas[out][order]) <= 0.05)


def test_hold_lock_release(session):
    k, j = 3, 7
    locked_s = session.points[k].s
    session.apply([{"op": "lock", "index": k, "locked": True}])
    session.solve_now()
    assert session.points[k].locked and session.points[k].s == pytest.approx(locked_s, abs=1e-5)
    base = session.solution.info["objective"]
    # hold point j away from the optimum: it stays where the user holds it, the others adapt
    target = session.points[j].s + 0.3 * (session.points[j + 1].s - session.points[j].s)
    others = [p.s for p in session.points]
    session.apply([{"op": "move", "index": j, "t": 0, "s": target, "hold": True}])
    held = session.solve_now()
    assert session.points[j].s == pytest.approx(target, abs=1e-5)
    assert session.points[k].s == pytest.approx(locked_s, abs=1e-5)
    assert held.info["objective"] >= base - 1e-9  # a constraint cannot do better than the optimum
    assert not np.allclose([p.s for p in session.points], others, atol=1e-6)
    # let go: the optimizer pulls the point back ("fights" the user), the lock still holds
    session.apply([{"op": "release", "index": j}])
    free = session.solve_now()
    assert free.info["objective"] <= held.info["objective"] + 1e-9
    assert abs(session.points[j].s - target) > 1e-4
    assert session.points[k].s == pytest.approx(locked_s, abs=1e-5)


def test_locked_points_become_keytimes_and_come_back(session):
    k = next(i for i, p in enumerate(session.points) if p.locked and 0 < i < len(session.points) - 1)
    t, s = session.points[k].t, session.points[k].s
    session.apply([{"op": "params", "method": "physics", "values": {"gravity": 12.0}}])  # rebuild
    sol = session.solve_now()
    assert (pytest.approx(s), pytest.approx(t)) == tuple(sol.keytimes[0])
    assert sol.curve(t) == pytest.approx(s, abs=2e-3)  # the keytime holds (augmented Lagrangian tolerance)
    session.apply([{"op": "method", "method": "linear"}])
    lin = session.solve_now()
    back = [p for p in session.points[1:-1] if p.locked]
    assert len(back) == 1 and back[0].t == pytest.approx(t) and back[0].s == pytest.approx(s)
    assert lin.curve(t) == pytest.approx(s, abs=1e-9)
