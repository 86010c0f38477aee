"""Physics in bounded memory: the contact basis kept on its own rows, and dynamics computed in
chunks, give the same numbers as the dense, all-at-once computation, and keep only per-sample
arrays of bounded width."""
import numpy as np
import pytest

from retime.physics.model import dynamics
from retime.physics.model.contact_basis import ComputedContactBasis, ContactBasis
from retime.physics.model.contacts import compact_contact_basis, corner_jacobians, friction_edges
from retime.physics.model.dynamics import DynamicsTerms, PathDynamics, dynamics_terms
from retime.physics.model.tree import kinematics, project, wrenches


@pytest.fixture(scope="module")
def terms(walk):
    return dynamics_terms(walk.frames(slice(0, 300)))


def _arrays(obj, seen=None):
    """Every NumPy array reachable from obj's attributes (one level of containers)."""
    seen = set() if seen is None else seen
    out = []
    values = obj.__dict__.values() if hasattr(obj, "__dict__") else obj
    for v in values:
        if id(v) in seen:
            continue
        seen.add(id(v))
        if isinstance(v, np.ndarray):
            out.append(v)
        elif isinstance(v, (ContactBasis, PathDynamics)):
            out += _arrays(v, seen)
        elif isinstance(v, (tuple, list)) and len(v) < 10:
            out += _arrays(v, seen)
        elif isinstance(v, dict):
            out += _arrays(list(v.values()), seen)
    return out


def test_contact_basis_is_the_dense_basis(terms):
    d = terms.combine()
    dense = np.asarray(d.N)
    assert dense.shape == d.N.shape
    # rows outside the basis's rows are zero, and each frame matrix is the dense array's slice
    other = np.setdiff1d(np.arange(d.N.nv), d.N.rows)
    assert np.all(dense[:, other] == 0) and np.any(dense[:, d.N.rows] != 0)
    for i in (0, 100, 299):
        assert np.array_equal(d.N[i], dense[i])
    # N @ lambda on the rows equals the dense product, bit for bit
    lam = np.random.default_rng(0).uniform(0, 50, (len(dense), dense.shape[2]))
    assert np.array_equal(d.N.forces(lam), np.einsum("nvk,nk->nv", dense, lam))
    # and a dense array given to PathDynamics is kept on its nonzero rows
    again = ContactBasis.from_dense(dense)
    assert np.array_equal(again.rows, d.N.rows) and np.array_equal(again.values, d.N.values)
    act = np.array([3, 7, 40, 80])
    assert np.array_equal(d.N.rows_dense(act), dense[:, act])


def test_chunked_dynamics_equal_one_pass(terms, monkeypatch):
    """Chunks of 7 samples give the arrays of one pass over all samples, bit for bit, and those equal
    the projection of the whole path's wrenches (the computation before chunking)."""
    g = np.array([0.0, -4.0, 0.5])
    masses = {"lfemur": 2.0}
    whole = DynamicsTerms(**{k: v for k, v in terms.__dict__.items() if not k.startswith("_")})
    monkeypatch.setattr(dynamics, "CHUNK_SAMPLES", 10 ** 9)
    one = whole.combine(gravity=g, mass_factors=masses, friction=0.7)
    small = DynamicsTerms(**{k: v for k, v in terms.__dict__.items() if not k.startswith("_")})
    monkeypatch.setattr(dynamics, "CHUNK_SAMPLES", 7)
    chunked = small.combine(gravity=g, mass_factors=masses, friction=0.7)
    for name in ("a", "b", "c", "b_noise"):
        assert np.array_equal(getattr(one, name), getattr(chunked, name)), name
    assert np.array_equal(one.N.values, chunked.N.values)
    # the same as the wrenches of the whole path projected at once
    path = terms.path(terms.smoothing)
    kin = kinematics(terms.shape, path.root_pos, path.quats, path.qd, path.qdd)
    coef = np.zeros((3, 5))
    coef[0, 0] = coef[1, 1] = 1.0
    coef[2, 2:] = g
    abc = project(terms.tree, kin.R, kin.o, wrenches(terms.tree, kin), terms.factors(masses), coef)
    assert np.array_equal(abc[:, 1], chunked.b) and np.array_equal(abc[:, 2], chunked.c)
    # and the contact basis made a chunk at a time is the one of the whole path's corner Jacobians
    _, jt = corner_jacobians(terms.tree, terms.body, terms.skeleton, kin.R, kin.o)
    assert np.array_equal(compact_contact_basis(jt, friction_edges(0.7), terms.contact), chunked.N.values)
    assert np.array_equal(chunked.N[123], np.asarray(one.N)[123])


def test_recombining_the_same_parameters_reuses_the_arrays(terms):
    a = terms.combine()
    b = terms.combine()
    assert np.shares_memory(a.b, b.b) and a.N is b.N
    other = terms.combine(gravity=(0.0, -2.0, 0.0))
    assert not np.shares_memory(other.c, a.c) and not np.array_equal(other.c, a.c)
    assert np.shares_memory(terms.combine().c, a.c)  # the standard parameters stay cached beside one other


def test_memory_per_sample_is_bounded(walk):
    """What the terms and one PathDynamics keep is per-sample arrays of a few rows of nv, the
    basis on its own rows, and nothing per body and sample (the per-body wrenches and frames were
    20 KB a sample: 1.5 GB for a 10-minute capture at 120 Hz)."""
    terms = dynamics_terms(walk.frames(slice(0, 300)))
    d = terms.combine()
    n, nv = len(terms.times), terms.tree.nv
    buffers = {}
    for x in _arrays(terms) + _arrays(d):
        if x is terms.rotations:  # the motion's own
            continue
        while x.base is not None:  # a view (a, b and c of one array) counts once
            x = x.base
        buffers[id(x)] = x
    per_sample = sum(x.nbytes for x in buffers.values() if x.ndim and len(x) == n) / n
    # a, b, c, b_noise, tau_ref (5 rows of nv), lambda_ref, corners, root path and origin, com, times, the
    # smoothed path's root and rotations (N is made from them when read); and contact states
    nb = terms.rotations.shape[1]
    bound = 8 * (5 * nv + 32 + 24 + 3 + 3 + 3 + 1 + 3 + 4 * nb) + 4
    assert per_sample <= bound, (per_sample, bound)
    assert isinstance(d.N, ComputedContactBasis) and d.N.values.shape[1] < nv / 2  # legs' and root's rows


def test_computed_basis_pickles_without_its_chunks(terms):
    """A computed basis travels (a result sent between processes) without its kept chunks or lock,
    and makes the same values on the other side."""
    import pickle

    N = terms.combine().N
    again = pickle.loads(pickle.dumps(N))
    assert again._kept == {} and np.array_equal(again[17], N[17]) and np.array_equal(again.values, N.values)
