"""Benchmark chains (McCann et al. 2006, Fig. 12: C10, C100, C1000): ``n`` links joined by ball
joints (3 DOFs each), the first hinged to the world at the origin, hanging along -y at rest.

Each link is a uniform rod of ``link_length`` (0.1 m) and ``link_mass`` (1 kg) with radius 2 cm.
The path is smooth and deterministic: joint k's rotation vector is
``amplitude * sin(2 pi f_a t + phase)`` per axis, with frequencies between 0.3 and 1.2 Hz and phases
drawn from ``seed``; it is sampled at ``fps`` and then goes through the same spline path and
dynamics code as a character (:mod:`retime.physics.model.path`, :mod:`retime.physics.model.tree`). The chains
have a fixed base, no contacts and no unactuated rows (``n_root == 0``); torque limits come from the
original motion like a character's (margin 1.5, floor 2 N m).

Pinocchio cannot allocate ``Data`` for C1000 (its buffers grow like nv^3), which is why the dynamics
are our own numba kernels; the tests compare them with Pinocchio on C10.
"""
from __future__ import annotations

import functools
import time

import numpy as np

from retime.physics.model.dynamics import DynamicsTerms, torque_limits
from retime.physics.model.path import sample_times
from retime.physics.model.tree import SPHERICAL, TreeModel

CASES = {"C10": 10, "C100": 100, "C1000": 1000}


@functools.lru_cache(maxsize=8)
def chain_tree(n_links: int, link_length=0.1, link_mass=1.0, radius=0.02) -> TreeModel:
    """The chain's tree (cached: do not modify it)."""
    L, m = float(link_length), float(link_mass)
    offsets = np.zeros((n_links, 3))
    offsets[1:, 1] = -L
    I_perp = m * (3 * radius ** 2 + L ** 2) / 12.0
    inertia = np.diag([I_perp, 0.5 * m * radius ** 2, I_perp])
    return TreeModel(names=[f"link{k}" for k in range(n_links)], parents=np.arange(n_links) - 1,
                     jtype=np.full(n_links, SPHERICAL), offsets=offsets, mass=np.full(n_links, m),
                     com=np.tile([0.0, -L / 2, 0.0], (n_links, 1)), inertia=np.tile(inertia, (n_links, 1, 1)))


def chain_path(n_links: int, n_frames=100, fps=30.0, amplitude=0.3, seed=0) -> np.ndarray:
    """Local joint rotations (n_frames, n_links, 4), (x, y, z, w)."""
    rng = np.random.default_rng(seed)
    freq = rng.uniform(0.3, 1.2, size=(n_links, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(n_links, 3))
    t = np.arange(n_frames)[:, None, None] / fps
    rv = amplitude * np.sin(2 * np.pi * freq * t + phase)  # (F, L, 3)
    angle = np.linalg.norm(rv, axis=-1, keepdims=True)
    axis = rv / np.maximum(angle, 1e-12)
    return np.concatenate([axis * np.sin(angle / 2), np.cos(angle / 2)], axis=-1)


def chain_terms(n_links: int, n_frames=100, fps=30.0, samples_per_frame=1, smoothing=0.0, seed=0,
                reference=True, quats=None) -> DynamicsTerms:
    """Dynamics terms of a chain along its path (``quats``, default :func:`chain_path`);
    ``combine(gravity)`` gives its PathDynamics."""
    tree = chain_tree(n_links)
    quats = chain_path(n_links, n_frames, fps, seed=seed) if quats is None else quats
    n_frames = len(quats)
    times = sample_times(n_frames, fps, samples_per_frame)
    n = len(times)
    terms = DynamicsTerms(tree=tree, body=None, times=times, fps=fps, samples_per_frame=int(samples_per_frame),
                          rotations=np.asarray(quats, dtype=float), contact=np.zeros((n, 0), dtype=bool),
                          smoothing=smoothing)
    if reference:
        d = terms.combine(with_reference=False)
        terms.tau_ref = d.b + d.c
        terms.lambda_ref = np.zeros((n, 0))
        terms.tau_limit = torque_limits(tree, None, terms.tau_ref)
    return terms
