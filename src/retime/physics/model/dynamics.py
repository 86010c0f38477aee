"""Path dynamics (McCann et al. 2006, sec. 3.1-3.2): joint torques along the motion's path as a
linear function of the retiming.

Along the source path q(s), a retiming p(t) gives q_dot = q' p_dot and
q_ddot = q'' p_dot^2 + q' p_ddot (Eq. 2-4), so inverse dynamics becomes, per source sample i
(Eq. 5-6, 11)::

    tau_i = a_i * p_ddot + b_i * p_dot^2 + c_i - N_i @ lambda,     lambda >= 0

with ``a = M(q) q'``, ``b = M(q) q'' + C(q, q') q'``, ``c = g(q)`` (the generalized gravity force,
``c = sum_k gravity_k * c_k``) and ``N = J^T P`` the friction-cone basis of the feet in contact
(:mod:`retime.physics.model.contacts`). The original timing is ``(p_ddot, p_dot^2) = (0, 1)``.

Conventions (all SI: metres, kg, seconds, N, N m):

* generalized coordinates: a free-floating root first (6 rows: force then moment about the root
  joint, in the root's frame, Pinocchio's free-flyer convention), then 3 rows per ball joint
  (moment about the joint centre in the joint's frame) in skeleton order; skeleton joints without
  rotation DOFs (CMU's ``lhipjoint``) are fixed and have no rows. ``dof_names`` names every row.
* the root rows are unactuated: a physical timing needs them to be 0 (``tau_lo = tau_hi = 0`` there);
  ``n_root`` says how many there are (0 for the fixed-base benchmark chains).
* samples are the motion's frames, and with ``samples_per_frame = k`` also ``k - 1`` evenly spaced
  times between frames; ``times`` are source times in seconds. Contact states at a sample are those
  of the nearest frame.
* the path is smoothed for dynamics by a Gaussian of ``smoothing`` seconds (see
  :mod:`retime.physics.model.path`); the poses written out are never changed.

Memory grows with what later stages read per sample, not with the bodies: :func:`dynamics_terms`
keeps the path and the body, and :meth:`DynamicsTerms.combine` computes, for each gravity and set
of mass factors, the wrench each body needs for the ``a``, ``b`` and unit-gravity terms
(:mod:`retime.physics.model.tree`) a chunk of samples at a time, and keeps only their projection
(torques are linear in every body's inertial parameters and in gravity). N is made from the sole
corners' Jacobians when it is read (:class:`~retime.physics.model.contact_basis.ComputedContactBasis`).

Torque limits, when the body file gives none, come from the original motion (as in the paper):
reference contact forces ``lambda_ref >= 0`` are fitted per sample to the original timing by
non-negative least squares, weighting the root rows 100 times the joint rows (so the contact forces
explain the root wrench first, then spare the joints), plus a tiny ridge; ``tau_ref = b + c -
N lambda_ref``; the limit of each joint axis is ``torque_margin * max_i |tau_ref| + torque_floor``.
``tau_ref`` (original parameters) is kept as the torques of the original motion.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy.ndimage import uniform_filter1d

from ...errors import RetimeError
from ...limits import check_memory
from ...motion.conform import bind_pose_frames, conformed
from ...motion.feet import skeleton_limbs
from .body import Body, centre_of_mass, load_body, skeleton_tree
from ..constants import DEFAULT_SMOOTHING, STANDARD_GRAVITY, G
from .contact_basis import ComputedContactBasis, ContactBasis, as_contact_basis
from .contacts import (CONTACT_POINTS, EDGES_PER_CORNER, at_samples, compact_contact_basis, corner_jacobians,
                       corner_positions, corner_rows, friction_edges, load_contacts)
from .path import PathSamples, path_samples, sample_times
from .tree import SPHERICAL, TreeModel, kinematics, project, wrenches

NOISE_BAND = 0.1  # seconds: the wider low-pass whose difference bounds the capture's acceleration noise
NOISE_CAP = 0.02  # body weights (per unit p'^2): the most of that difference taken as noise
ROOT_WEIGHT = 100.0
RIDGE = 1e-9


@dataclass
class PathDynamics:
    """Per source sample: tau = a * p_ddot + b * p_dot^2 + c - N @ lambda (see the module docstring)."""

    times: np.ndarray  # (n,) source times, seconds
    a: np.ndarray  # (n, nv) coefficient of p_ddot:  M(q) q'
    b: np.ndarray  # (n, nv) coefficient of p_dot^2: M(q) q'' + C(q, q') q'
    c: np.ndarray  # (n, nv) constant: gravity generalized force g(q)
    N: ContactBasis  # (n, nv, K) contact basis J^T P, K = 16 per foot; zero columns when not in contact
    contact: np.ndarray  # (n, 4) bool: left_heel, left_toe, right_heel, right_toe
    tau_lo: np.ndarray  # (nv,) lower torque limits (0 on root rows)
    tau_hi: np.ndarray  # (nv,) upper torque limits (0 on root rows)
    n_root: int = 6  # unactuated rows at the start (6 free-floating root, 0 fixed base)
    dof_names: list[str] = field(default_factory=list)
    contact_names: tuple[str, ...] = CONTACT_POINTS
    total_mass: float = 0.0  # kg, with the mass factors applied
    gravity: np.ndarray = field(default_factory=lambda: np.array(STANDARD_GRAVITY))
    friction: float = 0.5
    fps: float = 0.0  # frame rate of the source motion
    samples_per_frame: int = 1
    tau_ref: np.ndarray | None = None  # (n, nv) torques of the original timing (original physics)
    lambda_ref: np.ndarray | None = None  # (n, K) the contact forces behind tau_ref
    corners: np.ndarray | None = None  # (n, 8, 3) world positions of the sole corners
    b_noise: np.ndarray | None = None  # (n, nv) capture-noise band of b on the root rows in stance (see combine)

    def __post_init__(self):
        self.N = as_contact_basis(self.N)  # a dense (n, nv, K) array is kept on its nonzero rows

    @property
    def n_samples(self) -> int:
        return len(self.times)

    @property
    def nv(self) -> int:
        return self.a.shape[1]

    def torques(self, pdd, pd2, lam=None) -> np.ndarray:
        """tau (n, nv) for per-sample p_ddot and p_dot^2 (scalars or (n,)) and contact forces (n, K)."""
        pdd = np.broadcast_to(np.asarray(pdd, dtype=float), (self.n_samples,))[:, None]
        pd2 = np.broadcast_to(np.asarray(pd2, dtype=float), (self.n_samples,))[:, None]
        tau = self.a * pdd + self.b * pd2 + self.c
        if lam is not None:
            tau = tau - self.N.forces(lam)
        return tau


_CACHE_LOCK = threading.Lock()
CHUNK_SAMPLES = 2048  # samples per pass of kinematics and wrenches: their arrays (10 KB a sample) stay small


@dataclass
class DynamicsTerms:
    """The path and the body, from which :meth:`combine` computes :class:`PathDynamics` for any
    gravity, mass factors, friction and torque-limit scale.

    Nothing per body and sample is kept: each new set of parameters runs kinematics, wrenches and
    their projection again, in chunks of :data:`CHUNK_SAMPLES` (about 1.3 s per minute of 120 Hz
    motion), and keeps only the combined arrays. Keeping the per-body wrenches instead (the
    paper's polynomial trick) held 20 KB per sample: 1.5 GB for a 10-minute capture."""

    tree: TreeModel  # the inertial tree (the body's)
    body: Body | None
    times: np.ndarray  # (n,) source times of the samples
    fps: float
    samples_per_frame: int
    rotations: np.ndarray  # (F, nb, 4) local joint rotations at the frames, as the dynamics see them
    contact: np.ndarray  # (n, 4)
    root_pos: np.ndarray | None = None  # (F, 3) the floating base's world position, metres (None: fixed base)
    shape: TreeModel | None = None  # the kinematic tree of the path (None: ``tree``)
    skeleton: object = None  # for the sole corners (None: no contacts)
    smoothing: float = DEFAULT_SMOOTHING
    noise_band: float | None = None  # seconds (see dynamics_terms; None, or not above smoothing: no band)
    corner_rows: np.ndarray | None = None  # (R,) velocity rows a sole corner's force shows up on
    corners: np.ndarray | None = None  # (n, 8, 3) world positions of the sole corners
    sole_path: tuple | None = None  # (root (n, 3), rotations (n, nb, 4)) of the smoothed path, for N
    root_origin: np.ndarray | None = None  # (n, 3) world position of the root joint (smoothed path)
    com: np.ndarray | None = None  # (n, 3) world centre of mass (smoothed path)
    friction: float = 0.5
    tau_limit: np.ndarray | None = None  # (nv,) symmetric limits at torque scale 1
    tau_ref: np.ndarray | None = None
    lambda_ref: np.ndarray | None = None
    bind_pose_frames: int = 0  # leading frames held at the first real pose (see bind_pose_frames)
    conform_notes: list = field(default_factory=list)  # what conforming the motion did (dummy root, stretch)
    conform_warnings: list = field(default_factory=list)  # those of the notes that are warnings (bones made rigid)

    def joint_torque_limits(self, torque_scale=1.0) -> dict[str, np.ndarray]:
        """{joint: (3,) symmetric limit, N m} of every ball joint, e.g. for ``write_body``."""
        if self.tau_limit is None:
            return {}
        out = {}
        for j, name in enumerate(self.tree.names):
            if self.tree.jtype[j] == SPHERICAL:
                k = self.tree.vidx[j]
                out[name] = self.tau_limit[k:k + 3] * torque_scale
        return out

    def factors(self, mass_factors) -> np.ndarray:
        if self.body is not None:
            return self.body.mass_factor_array(mass_factors)
        if mass_factors is None:
            return np.ones(self.tree.n_bodies)
        if isinstance(mass_factors, dict):
            out = np.ones(self.tree.n_bodies)
            for k, v in mass_factors.items():
                out[self.tree.names.index(k)] = float(v)
            return out
        return np.asarray(mass_factors, dtype=float)

    @property
    def kinematic_tree(self) -> TreeModel:
        """The tree the path moves (the skeleton's; a fixed-base chain's own tree)."""
        return self.shape or self.tree

    def path(self, smoothing) -> PathSamples:
        """The path sampled at ``times``, low-passed at ``smoothing`` seconds."""
        shape = self.kinematic_tree
        return path_samples(self.fps, self.root_pos, self.rotations, shape.jtype, shape.vidx, shape.nv,
                            times=self.times, smoothing=smoothing)

    def chunks(self):
        """Slices of :data:`CHUNK_SAMPLES` samples covering all samples."""
        n = len(self.times)
        return [slice(k, min(n, k + CHUNK_SAMPLES)) for k in range(0, n, CHUNK_SAMPLES)]

    def kinematics(self, path: PathSamples, part: slice):
        return kinematics(self.kinematic_tree, path.root_pos[part], path.quats[part], path.qd[part],
                          path.qdd[part])

    def _generalized(self, f, coef):
        """abc (n, 3, nv) for mass factors f and the gravity in ``coef``, in chunks of the path."""
        path = self.path(self.smoothing)
        abc = np.empty((len(self.times), coef.shape[0], self.tree.nv))
        for part in self.chunks():
            kin = self.kinematics(path, part)
            abc[part] = project(self.tree, kin.R, kin.o, wrenches(self.tree, kin), f, coef)
        return abc

    def contact_basis(self, mu) -> ContactBasis:
        """N for friction mu: made from the path's sole corners when read (see ComputedContactBasis)."""
        n = len(self.times)
        if self.corner_rows is None:
            return ContactBasis(np.zeros((n, 0, 0)), np.zeros(0, dtype=np.int64), self.tree.nv)
        return ComputedContactBasis(SoleBasis(self, friction_edges(mu)), n, self.corner_rows, self.tree.nv,
                                    8 * EDGES_PER_CORNER)

    def _wide_b(self, f):
        """b (n, nv) of the path low-passed at noise_band (see NOISE_BAND)."""
        path = self.path(self.noise_band)
        out = np.empty((len(self.times), self.tree.nv))
        for part in self.chunks():
            kin = self.kinematics(path, part)
            W = np.ascontiguousarray(wrenches(self.tree, kin)[:, 1:2])
            out[part] = project(self.tree, kin.R, kin.o, W, f, np.ones((1, 1)))[:, 0]
        return out

    def _noise(self, abc, b_wide, f):
        """The capture-noise band of b on the root rows in stance (see NOISE_BAND)."""
        b_noise = np.zeros_like(b_wide)
        nr = self.tree.n_root
        # in flight only gravity acts and the parabola is known well: no noise budget there
        stance = np.asarray(self.contact, dtype=bool).any(axis=1)
        # capped: near a takeoff or landing the wider low-pass blurs real impacts, not noise
        cap = NOISE_CAP * float(np.dot(f, self.tree.mass)) * G
        diff = np.minimum(np.abs(abc[:, 1, :nr] - b_wide[:, :nr]), cap)
        # a noise level is a local statistic: the RMS over +-NOISE_BAND (a single difference can
        # cross zero where the noise is large)
        win = max(1, int(round(NOISE_BAND * self.fps * self.samples_per_frame)))
        # (the running sum of the filter leaves rounding residues, slightly negative, beside large values)
        rms = np.sqrt(np.maximum(uniform_filter1d(diff ** 2, 2 * win + 1, axis=0, mode="constant"), 0.0))
        b_noise[stance, :nr] = np.minimum(rms[stance], cap)
        return b_noise

    def _arrays(self, g, f, mu):
        """(abc, N, b_noise) for gravity g, mass factors f and friction mu, cached: physics asks for
        the standard parameters and its own, the editor a few settings in turn."""
        key = (tuple(g), tuple(f), mu)
        with _CACHE_LOCK:  # the editor's threads share one motion's terms
            cache = self.__dict__.setdefault("_combined", {})
            found = cache.get(key)
        if found is None:
            coef = np.zeros((3, 5))
            coef[0, 0] = coef[1, 1] = 1.0
            coef[2, 2:] = g
            abc = self._generalized(f, coef)
            N = self.contact_basis(mu)
            b_noise = None
            if self.noise_band and self.noise_band > self.smoothing and self.tree.n_root:
                b_noise = self._noise(abc, self._wide_b(f), f)
            found = (abc, N, b_noise)
            with _CACHE_LOCK:
                while len(cache) >= 2:  # the standard parameters and the latest others
                    cache.pop(next(iter(cache)))
                cache[key] = found
        return found

    def combine(self, gravity=STANDARD_GRAVITY, mass_factors=None, friction=None, torque_scale=1.0,
                with_reference=True) -> PathDynamics:
        """PathDynamics for a gravity vector (m/s^2), segment mass factors ({name: factor} or (nb,)),
        friction coefficient (default the body's) and a torque-limit scale. The returned arrays are
        shared with later calls of the same parameters: treat them as read-only."""
        g = np.asarray(gravity, dtype=float).reshape(3)
        if not np.all(np.isfinite(g)):
            raise RetimeError(f"gravity must be three finite numbers, got {gravity}")
        if not (torque_scale > 0):
            raise RetimeError(f"torque-limit scale must be positive, got {torque_scale}")
        f = self.factors(mass_factors)
        mu = self.friction if friction is None else float(friction)
        abc, N, b_noise = self._arrays(g, f, mu)
        n_root = self.tree.n_root
        hi = np.zeros(self.tree.nv) if self.tau_limit is None else self.tau_limit * torque_scale
        hi[:n_root] = 0.0
        return PathDynamics(
            times=self.times, a=abc[:, 0], b=abc[:, 1], c=abc[:, 2], N=N,
            contact=self.contact, tau_lo=-hi, tau_hi=hi.copy(), n_root=n_root, dof_names=self.tree.dof_names,
            total_mass=float(np.dot(f, self.tree.mass)), gravity=g, friction=mu, fps=self.fps,
            samples_per_frame=self.samples_per_frame,
            tau_ref=self.tau_ref if with_reference else None,
            lambda_ref=self.lambda_ref if with_reference else None, corners=self.corners, b_noise=b_noise)


@njit(cache=True)
def _solve_subset(G, h, idx, m, out, L, y):
    """out[idx[:m]] = solution of G[idx, idx] x = h[idx] by Cholesky (G positive definite)."""
    for a in range(m):
        for b in range(a + 1):
            acc = G[idx[a], idx[b]]
            for c in range(b):
                acc -= L[a, c] * L[b, c]
            if a == b:
                L[a, a] = np.sqrt(max(acc, 1e-300))
            else:
                L[a, b] = acc / L[b, b]
    for a in range(m):
        acc = h[idx[a]]
        for c in range(a):
            acc -= L[a, c] * y[c]
        y[a] = acc / L[a, a]
    for a in range(m - 1, -1, -1):
        acc = y[a]
        for c in range(a + 1, m):
            acc -= L[c, a] * y[c]
        y[a] = acc / L[a, a]
    for a in range(len(out)):
        out[a] = 0.0
    for a in range(m):
        out[idx[a]] = y[a]


@njit(cache=True)
def _nnls_gram(G, h, tol):
    """min 0.5 x'Gx - h'x subject to x >= 0 for positive definite G (Lawson-Hanson active set)."""
    k = len(h)
    x = np.zeros(k)
    s = np.zeros(k)
    grad = np.empty(k)
    passive = np.zeros(k, dtype=np.bool_)
    idx = np.empty(k, dtype=np.int64)
    L = np.zeros((k, k))
    y = np.empty(k)
    for _ in range(3 * k + 10):
        for a in range(k):
            acc = h[a]
            for b in range(k):
                acc -= G[a, b] * x[b]
            grad[a] = acc
        best = -1
        top = tol
        for j in range(k):
            if not passive[j] and grad[j] > top:
                top = grad[j]
                best = j
        if best < 0:
            break
        passive[best] = True
        for _inner in range(3 * k + 10):
            m = 0
            for j in range(k):
                if passive[j]:
                    idx[m] = j
                    m += 1
            _solve_subset(G, h, idx, m, s, L, y)
            feasible = True
            for a in range(m):
                if s[idx[a]] <= 0.0:
                    feasible = False
            if feasible:
                for j in range(k):
                    x[j] = s[j]
                break
            alpha = 1.0
            for a in range(m):
                j = idx[a]
                if s[j] <= 0 and x[j] - s[j] > 0:
                    alpha = min(alpha, x[j] / (x[j] - s[j]))
            for j in range(k):
                x[j] += alpha * (s[j] - x[j])
            for a in range(m):
                j = idx[a]
                if x[j] <= 1e-12 * (1.0 + abs(s[j])):
                    passive[j] = False
                    x[j] = 0.0
    return x


@njit(cache=True)
def _nonzero_columns(Ni, cols):
    """Stores in ``cols`` the columns of one sample's ``Ni`` (R, K) that have a nonzero entry (the
    sole corners in contact) and returns how many there are."""
    m = 0
    for k in range(Ni.shape[1]):
        for r in range(Ni.shape[0]):
            if Ni[r, k] != 0.0:
                cols[m] = k
                m += 1
                break
    return m


@njit(cache=True)
def _reference_forces(w, N, rows, weight, ridge, lam):
    """N (n, R, K) on velocity rows ``rows`` (sorted; the other rows are zero and add nothing)."""
    n, nr, K = N.shape
    cols = np.zeros(K, dtype=np.int64)
    for i in range(n):
        m = _nonzero_columns(N[i], cols)
        if m == 0:
            continue
        G = np.zeros((m, m))
        h = np.zeros(m)
        for r in range(nr):
            v = rows[r]
            w2 = weight[v] * weight[v]
            for a in range(m):
                na = N[i, r, cols[a]] * w2
                h[a] += na * w[i, v]
                for b in range(a + 1):
                    G[a, b] += na * N[i, r, cols[b]]
        scale = 0.0
        for a in range(m):
            scale += G[a, a]
            for b in range(a):
                G[b, a] = G[a, b]
        scale /= m
        for a in range(m):
            G[a, a] += ridge * scale
        x = _nnls_gram(G, h, 1e-10 * scale)
        for a in range(m):
            lam[i, cols[a]] = x[a]


def reference_forces(w, N, n_root, root_weight=ROOT_WEIGHT, ridge=RIDGE):
    """Contact forces lambda (n, K) >= 0 that best explain generalized forces w (n, nv): least
    squares with root rows weighted ``root_weight`` and joint rows 1, plus a ridge of ``ridge``
    times the mean diagonal of the normal matrix (non-negative least squares, per sample)."""
    N = as_contact_basis(N)
    n, nv, K = N.shape
    lam = np.zeros((n, K))
    if K == 0:
        return lam
    weight = np.ones(nv)
    weight[:n_root] = root_weight
    w = np.ascontiguousarray(w)
    for part, values in N.chunks():
        _reference_forces(w[part], values, N.rows, weight, float(ridge), lam[part])
    return lam


def torque_limits(tree: TreeModel, body: Body | None, tau_ref, margin=None, floor=None) -> np.ndarray:
    """Symmetric limits (nv,): the body's explicit ones, else margin * max |tau_ref| + floor, but at
    least the joint's strength (:meth:`Body.strength`)."""
    margin = (body.torque_margin if body is not None else 1.5) if margin is None else margin
    floor = (body.torque_floor if body is not None else 2.0) if floor is None else floor
    hi = margin * np.abs(tau_ref).max(axis=0) + floor
    if body is not None:
        strength = dict(zip(body.names, body.strength()))
        for j, k in enumerate(tree.vidx):
            if k >= 0 and int(tree.jtype[j]) == SPHERICAL:
                hi[k:k + 3] = np.maximum(hi[k:k + 3], strength.get(tree.names[j], 0.0))
        for name, lim in body.torque_limits.items():
            j = tree.names.index(name)
            if tree.vidx[j] >= 0:
                k = tree.vidx[j]
                hi[k:k + 3] = lim
    hi[:tree.n_root] = 0.0
    return hi


# peak memory of a physics retiming per source frame and joint, with a margin: a 10-minute capture at
# 120 Hz (72,001 frames, 31 joints) peaks 1.32 GB above its start (benchmarks/scaling.py), 590 bytes
BYTES_PER_FRAME_JOINT = 1_000


def dynamics_terms(motion, body=None, samples_per_frame=1, contacts=None, smoothing=DEFAULT_SMOOTHING,
                   reference=True, noise_band=NOISE_BAND) -> DynamicsTerms:
    """Path dynamics terms of ``motion`` (see the module docstring). ``body``: None (defaults), a
    :class:`~retime.physics.model.body.Body` or a TOML body file; ``contacts``: None (detect), a contact
    file or an (F, 4) bool array; ``reference=False`` skips the reference forces and default limits.

    ``noise_band`` (seconds, > ``smoothing``; None or 0: off): the path is also low-passed at this
    width, and :meth:`DynamicsTerms.combine` reports per sample how much the root rows' p'^2
    coefficient ``b`` differs between the two (``PathDynamics.b_noise``: the RMS over +-noise_band
    of the capped differences, zero in flight). Captured accelerations are
    only known to about that much: twice-differentiated marker noise and the slow sway of a still
    stance look alike, and played k times faster both grow k^2-fold (see :mod:`retime.physics.regions`)."""
    check_memory(BYTES_PER_FRAME_JOINT * motion.n_frames * motion.skeleton.n_joints * max(1, int(samples_per_frame)),
                 f"physics on {motion.n_frames:,} frames")
    if body is None:  # no legs is refused before the conform, whose dummy-root walk is slow on a long chain
        skeleton_limbs(motion.skeleton)
    conf = conformed(motion)
    motion = conf.motion
    sk = motion.skeleton
    spf = int(samples_per_frame)
    times = sample_times(motion.n_frames, motion.fps, spf)
    shape = skeleton_tree(sk)
    held = bind_pose_frames(motion)
    root_pos, rotations = motion.root_positions * sk.meters_per_unit, motion.rotations
    if held:  # the dynamics see the first real pose instead (the poses written out are untouched)
        root_pos, rotations = root_pos.copy(), rotations.copy()
        root_pos[:held], rotations[:held] = root_pos[held], rotations[held]
    path = path_samples(motion.fps, root_pos, rotations, shape.jtype, shape.vidx, shape.nv, times=times,
                        smoothing=smoothing)
    frames = frame_kinematics(shape, path, spf)  # world frames at the motion's frames (of the smoothed path)
    body = load_body(body, sk, motion, frames)
    tree = body.tree(sk)
    contact = at_samples(load_contacts(contacts, motion, body, frames), motion.fps, times)
    del frames
    terms = DynamicsTerms(tree=tree, body=body, times=times, fps=motion.fps, samples_per_frame=spf,
                          rotations=rotations, contact=contact, root_pos=root_pos, shape=shape, skeleton=sk,
                          smoothing=smoothing, noise_band=noise_band,
                          corner_rows=corner_rows(tree, body, sk),
                          friction=body.friction, bind_pose_frames=held, conform_notes=conf.notes(),
                          conform_warnings=conf.warnings())
    terms.corners, terms.root_origin, terms.com = body_points(terms, path)
    terms.sole_path = (np.array(path.root_pos), path.quats)
    del path
    if reference:
        add_reference(terms)
    return terms


@dataclass
class SoleBasis:
    """The contact basis values (m, R, K) of a slice of samples, from the sole corners' world
    positions and Jacobians along the smoothed path (``terms.sole_path``) and the friction pyramid's
    ``edges``: what :class:`ComputedContactBasis` calls."""

    terms: DynamicsTerms
    edges: np.ndarray

    def __call__(self, part: slice) -> np.ndarray:
        t = self.terms
        root, quats = t.sole_path
        still = np.zeros((len(quats[part]), t.kinematic_tree.nv))  # world frames do not depend on velocities
        kin = kinematics(t.kinematic_tree, root[part], quats[part], still, still)
        _, jt = corner_jacobians(t.tree, t.body, t.skeleton, kin.R, kin.o)
        return compact_contact_basis(jt, self.edges, t.contact[part])


def frame_kinematics(shape: TreeModel, path: PathSamples, spf: int):
    """(o (F, nb, 3), R (F, nb, 3, 3)): world joint frames at every ``spf``-th sample, in chunks."""
    idx = np.arange(0, len(path.times), spf)
    o = np.empty((len(idx), shape.n_bodies, 3))
    R = np.empty((len(idx), shape.n_bodies, 3, 3))
    for k in range(0, len(idx), CHUNK_SAMPLES):
        part = idx[k:k + CHUNK_SAMPLES]
        kin = kinematics(shape, path.root_pos[part], path.quats[part], path.qd[part], path.qdd[part])
        o[k:k + len(part)], R[k:k + len(part)] = kin.o, kin.R
    return o, R


def body_points(terms: DynamicsTerms, path: PathSamples):
    """Per sample of the path: the sole corners (n, 8, 3), the root joint (n, 3) and the centre of
    mass (n, 3), in world coordinates."""
    n = len(terms.times)
    corners, root, com = np.empty((n, 8, 3)), np.empty((n, 3)), np.empty((n, 3))
    for part in terms.chunks():
        kin = terms.kinematics(path, part)
        corners[part] = corner_positions(terms.body, terms.skeleton, kin.R, kin.o)
        root[part] = kin.o[:, 0]
        com[part] = centre_of_mass(terms.body, kin.R, kin.o)
    return corners, root, com


def add_reference(terms: DynamicsTerms) -> None:
    """Fill terms.tau_ref / lambda_ref / tau_limit from the original timing at standard physics."""
    d = terms.combine(with_reference=False)
    w = d.b + d.c
    lam = reference_forces(w, d.N, d.n_root)
    terms.lambda_ref = lam
    terms.tau_ref = w - d.N.forces(lam)
    terms.tau_limit = torque_limits(terms.tree, terms.body, terms.tau_ref)


def path_dynamics(motion, body=None, gravity=STANDARD_GRAVITY, mass_factors=None, samples_per_frame=1,
                  contacts=None, smoothing=DEFAULT_SMOOTHING, friction=None, torque_scale=1.0) -> PathDynamics:
    """One-shot :func:`dynamics_terms` followed by :meth:`DynamicsTerms.combine`."""
    terms = dynamics_terms(motion, body, samples_per_frame=samples_per_frame, contacts=contacts, smoothing=smoothing)
    return terms.combine(gravity=gravity, mass_factors=mass_factors, friction=friction, torque_scale=torque_scale)
