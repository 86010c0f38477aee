"""Foot contacts: detection on real clips, contact files and the friction-cone basis."""
import numpy as np
import pytest

from retime.data import bundled_path
from retime.errors import FormatError, RetimeError
from retime.motion import load_motion
from retime.physics.model.body import default_body
from retime.physics.model.contacts import (CONTACT_POINTS, at_samples, detect_contacts, friction_edges, load_contacts,
                                     read_contacts, write_contacts)
from retime.physics.model.dynamics import dynamics_terms


def runs(state):
    s = np.concatenate([[False], state, [False]]).astype(int)
    d = np.diff(s)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1))


def test_jump_flight_has_no_contact(jump):
    body = default_body(jump.skeleton, motion=jump)
    c = detect_contacts(jump, body)
    assert c.shape == (jump.n_frames, 4)
    flight = runs(~c.any(axis=1))
    assert len(flight) == 1  # one flight phase
    first, last = flight[0]
    peak = int(np.argmax(jump.root_positions[:, 1]))
    assert first < peak < last
    assert 0.3 < (last - first + 1) / jump.fps < 0.6  # a forward jump of a few tenths of a second
    # standing before and after: every point down
    assert c[:100].all() and c[-60:].all()
    # the feet leave the ground after the jump starts (root rising) and land before the end
    assert first > 150 and last < jump.n_frames - 60


def test_walk_always_touches_and_alternates():
    walk = load_motion(bundled_path("16_16.amc"))
    c = detect_contacts(walk, default_body(walk.skeleton, motion=walk))
    assert c.any(axis=1).all()  # walking never flies
    for p in range(4):
        assert len(runs(c[:, p])) >= 3  # steps
    left, right = c[:, :2].any(1), c[:, 2:].any(1)
    assert (left & ~right).sum() > 50 and (right & ~left).sum() > 50  # single support both sides
    # heel strikes before the toe lands, the heel lifts before the toe
    for heel, toe in ((0, 1), (2, 3)):
        for a, b in runs(c[:, heel])[1:-1]:
            toe_run = [r for r in runs(c[:, toe]) if r[0] <= b and r[1] >= a][0]
            assert a <= toe_run[0] and b <= toe_run[1]


def test_contact_file_round_trip_and_aliases(tmp_path, jump):
    c = np.zeros((50, 4), dtype=bool)
    c[0:10, 0] = c[5:20, 1] = c[30:50, 2] = c[40:45, 3] = True
    path = tmp_path / "contacts.csv"
    write_contacts(path, c)
    assert np.array_equal(read_contacts(path, 50), c)
    path.write_text("# jump\npoint,first,last\nleft,0,9   # both left points\nright_toe,3,3\n", encoding="utf-8")
    got = read_contacts(path, 20)
    assert got[:10, :2].all() and not got[10:, :2].any()
    assert got[3, 3] and got[:, 3].sum() == 1 and not got[:, 2].any()


@pytest.mark.parametrize("text, message", [
    ("point,first,last\nleft_knee,0,3\n", "unknown contact point 'left_knee'"),
    ("left_heel,0,99\n", "outside the motion's 0..19"),
    ("left_heel,5,2\n", "outside"),
    ("left_heel,a,2\n", "whole numbers"),
    ("left_heel,1\n", "expected 'point,first,last'"),
    ("# nothing\n", "no contact ranges"),
])
def test_contact_file_errors(tmp_path, text, message):
    path = tmp_path / "c.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FormatError, match=message) as e:
        read_contacts(path, 20)
    assert str(path) in str(e.value)


def test_contact_overrides(jump):
    body = default_body(jump.skeleton, motion=jump)
    with pytest.raises(RetimeError, match="shape"):
        load_contacts(np.ones((3, 4), bool), jump, body)
    with pytest.raises(FormatError, match="no such contact file"):
        load_contacts("/nonexistent/contacts.csv", jump, body)
    state = np.zeros((jump.n_frames, 4), bool)
    state[:, 0] = True
    d = dynamics_terms(jump.frames(slice(0, 40)), contacts=state[:40], reference=False).combine()
    assert d.contact[:, 0].all() and not d.contact[:, 1:].any()
    assert np.any(d.N[:, :, :8] != 0) and np.all(d.N[:, :, 8:] == 0)


def test_friction_pyramid_is_inscribed():
    for mu in (0.0, 0.5, 1.3):
        E = friction_edges(mu)
        assert np.allclose(np.linalg.norm(E, axis=1), 1)
        tangential = np.linalg.norm(E[:, [0, 2]], axis=1)
        assert np.allclose(tangential, mu * E[:, 1])  # each edge lies on the cone's surface
        assert np.allclose(E.sum(axis=0)[[0, 2]], 0)  # symmetric about the normal


def test_basis_forces_map_to_root_wrench(jump):
    """Pushing along every edge of every corner in contact gives the root a force equal to the sum
    of those (world) forces, and a moment about the root from where they act."""
    terms = dynamics_terms(jump.frames(slice(0, 30)), reference=False)
    mu = 0.5
    d = terms.combine(friction=mu)
    kin = terms.kinematics(terms.path(terms.smoothing), slice(None))  # the root's world frame
    E = friction_edges(mu)
    corner_point = np.array([0, 0, 1, 1, 2, 2, 3, 3])
    for i in (0, 15, 29):
        lam = np.ones(32)
        on = d.contact[i][corner_point]
        world = np.zeros(3)
        moment = np.zeros(3)
        for c in range(8):
            if on[c]:
                f = E.sum(axis=0)
                world += f
                moment += np.cross(d.corners[i, c] - kin.o[i, 0], f)
        assert np.array_equal(kin.o[i, 0], terms.root_origin[i])
        R = kin.R[i, 0]
        gen = d.N[i] @ lam
        assert np.allclose(gen[:3], R.T @ world)
        assert np.allclose(gen[3:6], R.T @ moment)


def test_contact_at_samples_uses_nearest_frame():
    c = np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]], bool)
    times = np.array([0.0, 0.2, 0.5, 0.75, 1.0, 1.4, 2.0]) / 10.0
    got = at_samples(c, 10.0, times)
    assert [int(np.argmax(r)) for r in got] == [0, 0, 1, 1, 1, 1, 2]
    assert len(CONTACT_POINTS) == 4
