"""Rigid-body trees: per-body Newton-Euler wrenches and joint-space projection, compiled with numba.

A :class:`TreeModel` is a kinematic tree of rigid bodies, one per joint (body ``j`` moves with joint
``j``), every parent before its children. Joint types:

* ``FREE``: a free-flying root (6 DOFs, unactuated in a character). Generalized coordinates follow
  Pinocchio's ``JointModelFreeFlyer``: velocity ``(v, w)`` = linear velocity of the joint origin and
  angular velocity, **both in the body frame**; acceleration = their time derivative (Pinocchio's
  spatial acceleration, so the classical origin acceleration is ``R (a_lin + w x v)``).
  Generalized force rows: force then moment about the joint origin, in the body frame.
* ``SPHERICAL``: a ball joint (3 DOFs); velocity = angular velocity of the child relative to the
  parent, in the child frame (Pinocchio's ``JointModelSpherical``); force rows = moment about the
  joint centre in the child frame.
* ``FIXED``: no DOF; the local rotation is still read from the configuration (constant in mocap).

Each joint sits at ``offsets[j]`` in its parent's frame (or in the world for a parentless joint
other than ``FREE``; a ``FREE`` root is placed by its configuration alone), with no extra rotation, as in a BVH/ASF skeleton. Body ``j`` has ``mass[j]``,
centre of mass ``com[j]`` in the joint frame and ``inertia[j]`` (3x3, about the centre of mass, in the
joint frame). SI units throughout.

Why not just call Pinocchio's RNEA: changing a segment's mass must not rerun the dynamics (McCann et
al. 2006, sec. 3.1), so the kernels return, per sample and per *term*, the wrench each body needs
(force, and moment about the world origin, in world coordinates):

* term 0 ``a``: velocity 0, acceleration ``q'``, no gravity          -> coefficient of p''
* term 1 ``b``: velocity ``q'``, acceleration ``q''``, no gravity     -> coefficient of p'^2
* terms 2-4: gravity along +x, +y, +z with unit size, at rest         -> c = sum_k g_k c_k

Generalized forces are linear in these wrenches and in each body's inertial parameters, so a mass
factor per body and any gravity vector recombine them (:func:`project`) in a fraction of the time.
The kernels also run chains of a thousand links, which Pinocchio's ``Data`` (nv^3-sized buffers)
cannot allocate. ``tests/_pinocchio_ref.py`` builds the same model in Pinocchio; the tests check
:func:`generalized_forces` against ``pinocchio.rnea`` and the contact map against Pinocchio's frame
Jacobians.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ..constants import STANDARD_GRAVITY

FREE, SPHERICAL, FIXED = 0, 1, 2
N_TERMS = 5  # a, b, gravity x, gravity y, gravity z
JOINT_DOFS = {FREE: 6, SPHERICAL: 3, FIXED: 0}


@dataclass
class TreeModel:
    names: list[str]
    parents: np.ndarray  # (nb,) int, -1 for a joint attached to the world
    jtype: np.ndarray  # (nb,) FREE / SPHERICAL / FIXED
    offsets: np.ndarray  # (nb, 3) joint position in the parent frame, metres
    mass: np.ndarray  # (nb,) kg
    com: np.ndarray  # (nb, 3) centre of mass in the joint frame, metres
    inertia: np.ndarray  # (nb, 3, 3) about the centre of mass, joint frame, kg m^2
    vidx: np.ndarray = field(init=False)  # (nb,) first velocity index of each joint (-1 if FIXED)
    nv: int = field(init=False)
    _dof_names: list[str] | None = field(init=False, default=None, repr=False)

    def __post_init__(self):
        self.parents = np.ascontiguousarray(self.parents, dtype=np.int64)
        self.jtype = np.ascontiguousarray(self.jtype, dtype=np.int64)
        self.offsets = np.ascontiguousarray(self.offsets, dtype=float).reshape(-1, 3)
        self.mass = np.ascontiguousarray(self.mass, dtype=float)
        self.com = np.ascontiguousarray(self.com, dtype=float).reshape(-1, 3)
        self.inertia = np.ascontiguousarray(self.inertia, dtype=float).reshape(-1, 3, 3)
        nb = len(self.parents)
        if np.any(self.parents >= np.arange(nb)):
            raise ValueError("every parent must come before its children")
        if np.any(self.jtype[1:] == FREE) or (nb and self.jtype[0] == FREE and self.parents[0] >= 0):
            raise ValueError("only a parentless first joint can be FREE")
        for arr, shape in ((self.jtype, (nb,)), (self.offsets, (nb, 3)), (self.mass, (nb,)), (self.com, (nb, 3)),
                           (self.inertia, (nb, 3, 3))):
            if arr.shape != shape:
                raise ValueError(f"expected shape {shape}, got {arr.shape}")
        dofs = np.select([self.jtype == FREE, self.jtype == SPHERICAL], [6, 3], 0).astype(np.int64)
        start = np.concatenate([[0], np.cumsum(dofs)[:-1]])
        self.vidx = np.where(dofs > 0, start, -1).astype(np.int64)
        self.nv = int(dofs.sum())

    @property
    def n_bodies(self) -> int:
        return len(self.parents)

    @property
    def n_root(self) -> int:
        """Number of unactuated rows (6 for a free-floating root, else 0)."""
        return 6 if self.jtype[0] == FREE else 0

    @property
    def dof_names(self) -> list[str]:
        if self._dof_names is None:
            self._dof_names = self._make_dof_names()
        return self._dof_names

    def _make_dof_names(self) -> list[str]:
        out = []
        for name, t in zip(self.names, self.jtype):
            if t == FREE:
                out += [f"{name}:{a}" for a in ("fx", "fy", "fz", "mx", "my", "mz")]
            elif t == SPHERICAL:
                out += [f"{name}:{a}" for a in ("x", "y", "z")]
        return out

    def total_mass(self) -> float:
        return float(self.mass.sum())


# ---------------------------------------------------------------------------------------------
# numba kernels, one thread each (on a busy 2-core machine numba's parallel launches cost more than they save)

@njit(cache=True)
def _mv(R, v, out):
    for r in range(3):
        out[r] = R[r, 0] * v[0] + R[r, 1] * v[1] + R[r, 2] * v[2]


@njit(cache=True)
def _mtv(R, v, out):
    for r in range(3):
        out[r] = R[0, r] * v[0] + R[1, r] * v[1] + R[2, r] * v[2]


@njit(cache=True)
def _cross(a, b, out):
    x = a[1] * b[2] - a[2] * b[1]
    y = a[2] * b[0] - a[0] * b[2]
    z = a[0] * b[1] - a[1] * b[0]
    out[0] = x
    out[1] = y
    out[2] = z


@njit(cache=True)
def _quat_matrix(q, out):
    x, y, z, w = q[0], q[1], q[2], q[3]
    s = 2.0 / (x * x + y * y + z * z + w * w)
    out[0, 0] = 1 - s * (y * y + z * z)
    out[0, 1] = s * (x * y - w * z)
    out[0, 2] = s * (x * z + w * y)
    out[1, 0] = s * (x * y + w * z)
    out[1, 1] = 1 - s * (x * x + z * z)
    out[1, 2] = s * (y * z - w * x)
    out[2, 0] = s * (x * z - w * y)
    out[2, 1] = s * (y * z + w * x)
    out[2, 2] = 1 - s * (x * x + y * y)


@njit(cache=True)
def _kinematics(parents, jtype, vidx, offsets, root_pos, quats, qd, qdd, R, o, w, dw, ddo, dwa, ddoa):
    """World frames R (n, nb, 3, 3), o (n, nb, 3); for term b (velocity q', acceleration q'') the
    angular velocity w, angular acceleration dw and origin acceleration ddo; for term a (velocity 0,
    acceleration q') dwa and ddoa. All (n, nb, 3), world coordinates."""
    n = quats.shape[0]
    nb = parents.shape[0]
    Rl = np.empty((3, 3))
    for i in range(n):
        t1 = np.empty(3)
        t2 = np.empty(3)
        t3 = np.empty(3)
        d = np.empty(3)
        for j in range(nb):
            p = parents[j]
            t = jtype[j]
            k = vidx[j]
            Rj = R[i, j]
            _quat_matrix(quats[i, j], Rl)
            if p < 0:
                for a in range(3):
                    for b in range(3):
                        Rj[a, b] = Rl[a, b]
                    w[i, j, a] = 0.0
                    dw[i, j, a] = 0.0
                    ddo[i, j, a] = 0.0
                    dwa[i, j, a] = 0.0
                    ddoa[i, j, a] = 0.0
                if t == FREE:
                    for a in range(3):
                        o[i, j, a] = root_pos[i, a]
                    # term b: classical origin acceleration R (a_lin + w_b x v_lin)
                    _cross(qd[i, k + 3:k + 6], qd[i, k:k + 3], t1)
                    for a in range(3):
                        t1[a] += qdd[i, k + a]
                    _mv(Rj, t1, ddo[i, j])
                    _mv(Rj, qd[i, k + 3:k + 6], w[i, j])
                    _mv(Rj, qdd[i, k + 3:k + 6], dw[i, j])
                    # term a: velocity zero, acceleration q'
                    _mv(Rj, qd[i, k:k + 3], ddoa[i, j])
                    _mv(Rj, qd[i, k + 3:k + 6], dwa[i, j])
                else:
                    for a in range(3):
                        o[i, j, a] = offsets[j, a]
                    if t == SPHERICAL:
                        _mv(Rj, qd[i, k:k + 3], w[i, j])
                        _mv(Rj, qdd[i, k:k + 3], dw[i, j])
                        _mv(Rj, qd[i, k:k + 3], dwa[i, j])
            else:
                Rp = R[i, p]
                _mv(Rp, offsets[j], d)
                for a in range(3):
                    o[i, j, a] = o[i, p, a] + d[a]
                for a in range(3):
                    for b in range(3):
                        Rj[a, b] = Rp[a, 0] * Rl[0, b] + Rp[a, 1] * Rl[1, b] + Rp[a, 2] * Rl[2, b]
                _cross(dw[i, p], d, t1)
                _cross(w[i, p], d, t2)
                _cross(w[i, p], t2, t3)
                for a in range(3):
                    ddo[i, j, a] = ddo[i, p, a] + t1[a] + t3[a]
                _cross(dwa[i, p], d, t1)
                for a in range(3):
                    ddoa[i, j, a] = ddoa[i, p, a] + t1[a]
                if t == SPHERICAL:
                    _mv(Rj, qd[i, k:k + 3], t1)  # relative angular velocity, world
                    _mv(Rj, qdd[i, k:k + 3], t2)
                    _cross(w[i, p], t1, t3)
                    for a in range(3):
                        w[i, j, a] = w[i, p, a] + t1[a]
                        dw[i, j, a] = dw[i, p, a] + t2[a] + t3[a]
                        dwa[i, j, a] = dwa[i, p, a] + t1[a]
                else:
                    for a in range(3):
                        w[i, j, a] = w[i, p, a]
                        dw[i, j, a] = dw[i, p, a]
                        dwa[i, j, a] = dwa[i, p, a]


@njit(cache=True)
def _wrenches(mass, com, inertia, R, o, w, dw, ddo, dwa, ddoa, W):
    """Per-body wrenches W (n, 5, nb, 6) of terms a, b and unit gravity x/y/z: [force, moment about
    the world origin] that the body needs, world coordinates."""
    n = R.shape[0]
    nb = R.shape[1]
    t1 = np.empty(3)
    t2 = np.empty(3)
    t3 = np.empty(3)
    r = np.empty(3)
    c = np.empty(3)
    F = np.empty(3)
    Nm = np.empty(3)
    wl = np.empty(3)
    al = np.empty(3)
    for i in range(n):
        for j in range(nb):
            Rj = R[i, j]
            Ij = inertia[j]
            m = mass[j]
            _mv(Rj, com[j], r)
            for a in range(3):
                c[a] = o[i, j, a] + r[a]
            # term a: F = m (ddoa + dwa x r), N = R I R^T dwa
            _cross(dwa[i, j], r, t1)
            for a in range(3):
                F[a] = m * (ddoa[i, j, a] + t1[a])
            _mtv(Rj, dwa[i, j], al)
            _mv(Ij, al, t2)
            _mv(Rj, t2, Nm)
            _cross(c, F, t2)
            for a in range(3):
                W[i, 0, j, a] = F[a]
                W[i, 0, j, 3 + a] = Nm[a] + t2[a]
            # term b: F = m (ddo + dw x r + w x (w x r)), N = R (I al + wl x I wl)
            _cross(dw[i, j], r, t1)
            _cross(w[i, j], r, t2)
            _cross(w[i, j], t2, t3)
            for a in range(3):
                F[a] = m * (ddo[i, j, a] + t1[a] + t3[a])
            _mtv(Rj, w[i, j], wl)
            _mtv(Rj, dw[i, j], al)
            _mv(Ij, wl, t1)
            _cross(wl, t1, t2)
            _mv(Ij, al, t1)
            for a in range(3):
                t1[a] += t2[a]
            _mv(Rj, t1, Nm)
            _cross(c, F, t3)
            for a in range(3):
                W[i, 1, j, a] = F[a]
                W[i, 1, j, 3 + a] = Nm[a] + t3[a]
            # gravity along each world axis: the joints must hold -m e_k at the centre of mass
            for g in range(3):
                for a in range(3):
                    F[a] = 0.0
                F[g] = -m
                _cross(c, F, t1)
                for a in range(3):
                    W[i, 2 + g, j, a] = F[a]
                    W[i, 2 + g, j, 3 + a] = t1[a]


@njit(cache=True)
def _project(parents, jtype, vidx, nv, R, o, W, coef, factors, out):
    """Generalized forces out (n, T, nv) of the wrench combinations sum_k coef[t, k] W[:, k]
    (W (n, K, nb, 6)), each body's scaled by factors (nb,)."""
    n = W.shape[0]
    K = W.shape[1]
    nb = W.shape[2]
    T = coef.shape[0]
    # nonzero coefficients only
    nz = np.zeros(T, dtype=np.int64)
    nzk = np.zeros((T, K), dtype=np.int64)
    nzc = np.zeros((T, K))
    for t in range(T):
        for k in range(K):
            if coef[t, k] != 0.0:
                nzk[t, nz[t]] = k
                nzc[t, nz[t]] = coef[t, k]
                nz[t] += 1
    S = np.empty((T, nb, 6))
    m = np.empty(3)
    for i in range(n):
        for t in range(T):
            for j in range(nb):
                f = factors[j]
                for a in range(6):
                    S[t, j, a] = 0.0
                for q in range(nz[t]):
                    c = nzc[t, q] * f
                    k = nzk[t, q]
                    for a in range(6):
                        S[t, j, a] += c * W[i, k, j, a]
        for j in range(nb - 1, -1, -1):
            p = parents[j]
            if p >= 0:
                for t in range(T):
                    for a in range(6):
                        S[t, p, a] += S[t, j, a]
        for j in range(nb):
            tj = jtype[j]
            if tj == FIXED:
                continue
            k = vidx[j]
            Rj = R[i, j]
            oj = o[i, j]
            for t in range(T):
                Fx, Fy, Fz = S[t, j, 0], S[t, j, 1], S[t, j, 2]
                m[0] = S[t, j, 3] - (oj[1] * Fz - oj[2] * Fy)
                m[1] = S[t, j, 4] - (oj[2] * Fx - oj[0] * Fz)
                m[2] = S[t, j, 5] - (oj[0] * Fy - oj[1] * Fx)
                if tj == FREE:
                    for a in range(3):
                        out[i, t, k + a] = Rj[0, a] * Fx + Rj[1, a] * Fy + Rj[2, a] * Fz
                        out[i, t, k + 3 + a] = Rj[0, a] * m[0] + Rj[1, a] * m[1] + Rj[2, a] * m[2]
                else:
                    for a in range(3):
                        out[i, t, k + a] = Rj[0, a] * m[0] + Rj[1, a] * m[1] + Rj[2, a] * m[2]


@njit(cache=True)
def _points_jt(parents, jtype, vidx, R, o, body, x, dirs, rowmap, out):
    """J^T of point forces: out (n, R, P*E) for points x (n, P, 3) on bodies body (P,), directions
    dirs (P, E, 3) in world coordinates; velocity row k goes to out row rowmap[k]."""
    n = x.shape[0]
    P = x.shape[1]
    E = dirs.shape[1]
    for i in range(n):
        arm = np.empty(3)
        mom = np.empty(3)
        for pt in range(P):
            j = body[pt]
            while j >= 0:
                tj = jtype[j]
                if tj != FIXED:
                    k = vidx[j]
                    Rj = R[i, j]
                    for a in range(3):
                        arm[a] = x[i, pt, a] - o[i, j, a]
                    for e in range(E):
                        col = pt * E + e
                        dv = dirs[pt, e]
                        _cross(arm, dv, mom)
                        if tj == FREE:
                            for a in range(3):
                                out[i, rowmap[k + a], col] = Rj[0, a] * dv[0] + Rj[1, a] * dv[1] + Rj[2, a] * dv[2]
                                out[i, rowmap[k + 3 + a], col] = Rj[0, a] * mom[0] + Rj[1, a] * mom[1] + Rj[2, a] * mom[2]
                        else:
                            for a in range(3):
                                out[i, rowmap[k + a], col] = Rj[0, a] * mom[0] + Rj[1, a] * mom[1] + Rj[2, a] * mom[2]
                j = parents[j]


# ---------------------------------------------------------------------------------------------
# Python entry points


def _config_arrays(tree, root_pos, quats, qd, qdd):
    n = quats.shape[0]
    if quats.shape[1:] != (tree.n_bodies, 4):
        raise ValueError(f"quats must have shape (n, {tree.n_bodies}, 4), got {quats.shape}")
    if qd.shape != (n, tree.nv) or qdd.shape != (n, tree.nv):
        raise ValueError(f"velocities must have shape ({n}, {tree.nv})")
    root_pos = np.zeros((n, 3)) if root_pos is None else np.ascontiguousarray(root_pos, dtype=float)
    quats = np.ascontiguousarray(quats, dtype=float)
    return root_pos, quats, np.ascontiguousarray(qd, dtype=float), np.ascontiguousarray(qdd, dtype=float)


@dataclass
class Kinematics:
    """World frames and the motion terms of every body along a path (see :func:`kinematics`)."""

    R: np.ndarray  # (n, nb, 3, 3)
    o: np.ndarray  # (n, nb, 3)
    w: np.ndarray  # (n, nb, 3) angular velocity, term b
    dw: np.ndarray  # angular acceleration, term b
    ddo: np.ndarray  # joint origin acceleration, term b
    dwa: np.ndarray  # angular acceleration, term a
    ddoa: np.ndarray  # joint origin acceleration, term a


def kinematics(tree: TreeModel, root_pos, quats, qd, qdd) -> Kinematics:
    """Forward kinematics of samples along a path (no masses needed).

    root_pos (n, 3) world position of a FREE root (ignored otherwise, may be None); quats (n, nb, 4)
    local joint rotations (x, y, z, w); qd, qdd (n, nv) path velocity q' and acceleration q''.
    Term b moves with velocity q' and acceleration q''; term a with velocity 0 and acceleration q'.
    """
    root_pos, quats, qd, qdd = _config_arrays(tree, root_pos, quats, qd, qdd)
    n, nb = quats.shape[:2]
    R = np.empty((n, nb, 3, 3))
    o, w, dw, ddo, dwa, ddoa = (np.empty((n, nb, 3)) for _ in range(6))
    _kinematics(tree.parents, tree.jtype, tree.vidx, tree.offsets, root_pos, quats, qd, qdd, R, o, w, dw, ddo, dwa, ddoa)
    return Kinematics(R, o, w, dw, ddo, dwa, ddoa)


def wrenches(tree: TreeModel, kin: Kinematics) -> np.ndarray:
    """W (n, 5, nb, 6): for each term (a, b, gravity x/y/z) the wrench [force, moment about the
    world origin] each body needs, in world coordinates, with the tree's inertial parameters."""
    n, nb = kin.R.shape[:2]
    W = np.empty((n, N_TERMS, nb, 6))
    _wrenches(tree.mass, tree.com, tree.inertia, kin.R, kin.o, kin.w, kin.dw, kin.ddo, kin.dwa, kin.ddoa, W)
    return W


def body_wrenches(tree: TreeModel, root_pos, quats, qd, qdd):
    """(R, o, W): :func:`kinematics` then :func:`wrenches`."""
    kin = kinematics(tree, root_pos, quats, qd, qdd)
    return kin.R, kin.o, wrenches(tree, kin)


def project(tree: TreeModel, R, o, W, factors=None, coef=None):
    """Generalized forces (n, T, nv) of wrenches W (n, K, nb, 6), each body's scaled by factors[j]:
    of W itself (T = K), or of the combinations sum_k coef[t, k] W[:, k] (coef (T, K))."""
    factors = np.ones(tree.n_bodies) if factors is None else np.ascontiguousarray(factors, dtype=float)
    coef = np.eye(W.shape[1]) if coef is None else np.ascontiguousarray(coef, dtype=float)
    out = np.zeros((W.shape[0], coef.shape[0], tree.nv))
    _project(tree.parents, tree.jtype, tree.vidx, tree.nv, R, o, np.ascontiguousarray(W), coef, factors, out)
    return out


def support_rows(tree: TreeModel, bodies) -> np.ndarray:
    """Velocity rows (sorted) of the joints that move any of ``bodies``: the only rows where forces
    on those bodies show up."""
    rows = set()
    for j in bodies:
        j = int(j)
        while j >= 0:
            t = int(tree.jtype[j])
            if t != FIXED:
                rows.update(range(tree.vidx[j], tree.vidx[j] + JOINT_DOFS[t]))
            j = int(tree.parents[j])
    return np.array(sorted(rows), dtype=np.int64)


def points_jacobian_transpose(tree: TreeModel, R, o, body, points, dirs, rows=None):
    """Generalized forces (n, nv, P*E) of unit forces along dirs (P, E, 3) (world) applied at world
    points (n, P, 3) fixed to bodies body (P,); column pt*E + e. Equals J_pt^T d with J_pt the
    LOCAL_WORLD_ALIGNED linear Jacobian of the point (Eq. 10 of McCann et al.). With ``rows``
    (e.g. :func:`support_rows`) only those rows are returned: (n, len(rows), P*E)."""
    points = np.ascontiguousarray(points, dtype=float)
    dirs = np.ascontiguousarray(np.broadcast_to(dirs, (points.shape[1],) + np.shape(dirs)[-2:]), dtype=float)
    body = np.asarray(body, dtype=np.int64)
    rows = np.arange(tree.nv) if rows is None else np.asarray(rows, dtype=np.int64)
    rowmap = np.full(tree.nv, -1, dtype=np.int64)
    rowmap[rows] = np.arange(len(rows))
    if np.any(rowmap[support_rows(tree, body)] < 0):
        raise ValueError("rows must include every support row of the bodies")
    out = np.zeros((points.shape[0], len(rows), points.shape[1] * dirs.shape[1]))
    _points_jt(tree.parents, tree.jtype, tree.vidx, R, o, body, points, dirs, rowmap, out)
    return out


def generalized_forces(tree: TreeModel, root_pos, quats, qd, qdd, gravity=STANDARD_GRAVITY):
    """Inverse dynamics tau = M(q) qdd + C(q, qd) qd + g(q) (n, nv), the same as ``pinocchio.rnea``."""
    R, o, W = body_wrenches(tree, root_pos, quats, qd, qdd)
    total = W[:, 1] + np.einsum("ntbs,t->nbs", W[:, 2:], np.asarray(gravity, dtype=float))
    return project(tree, R, o, total[:, None])[:, 0]
