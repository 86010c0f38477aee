"""The contact basis N (n, nv, K) of every sample, stored on the rows that can be nonzero.

``N = J^T P`` (:mod:`.contacts`) has nonzero rows only where a force at a sole corner shows up:
the root's and the legs' (30 of a CMU skeleton's 90). The dense array was the largest one physics
kept (23 KB per sample, 1.7 GB for a 10-minute capture at 120 Hz); :class:`ContactBasis` keeps
``values`` (n, R, K) on ``rows`` (R,) and gives each sample's dense (nv, K) matrix on demand, so
every consumer sees the same numbers as before. :class:`ComputedContactBasis` stores nothing per
sample: it makes the values of a few hundred samples at a time from the path when they are read.
"""
from __future__ import annotations

import threading

import numpy as np


CHUNK = 256  # samples a computed basis makes at a time (and keeps the last few of)


class ContactBasis:
    """N (n, nv, K) as ``values`` (n, R, K) on the sorted velocity ``rows`` (R,); zero elsewhere.

    ``N[i]`` is sample i's dense (nv, K) matrix; :meth:`forces` is N @ lambda for every sample;
    :meth:`chunks` gives the values a slice of samples at a time (what compiled kernels read).
    ``np.asarray(N)`` builds the whole dense array (tests and small clips only)."""

    def __init__(self, values, rows, nv: int):
        self.values = np.ascontiguousarray(values, dtype=float)
        self.rows = np.ascontiguousarray(rows, dtype=np.int64)
        self.nv = int(nv)
        if self.values.ndim != 3 or self.values.shape[1] != len(self.rows):
            raise ValueError(f"values {self.values.shape} do not match {len(self.rows)} rows")

    @classmethod
    def from_dense(cls, N) -> ContactBasis:
        """The basis of a dense (n, nv, K) array, on its rows that are nonzero in any sample."""
        N = np.asarray(N, dtype=float)
        rows = np.flatnonzero(np.any(N != 0.0, axis=(0, 2)))
        return cls(N[:, rows, :], rows, N.shape[1])

    @property
    def n_samples(self) -> int:
        return self.values.shape[0]

    @property
    def n_columns(self) -> int:
        return self.values.shape[2]

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.n_samples, self.nv, self.n_columns

    def chunk(self, k: int) -> np.ndarray:
        """The values (m, R, K) of samples k * CHUNK to (k + 1) * CHUNK."""
        return self.values[k * CHUNK:(k + 1) * CHUNK]

    def chunks(self):
        """(slice of samples, their values (m, R, K)) covering every sample, in order."""
        for k in range(-(-self.n_samples // CHUNK)):
            yield slice(k * CHUNK, min(self.n_samples, (k + 1) * CHUNK)), self.chunk(k)

    def frame(self, i: int) -> np.ndarray:
        """Sample i's dense (nv, K) matrix (a new array)."""
        if not -self.n_samples <= i < self.n_samples:
            raise IndexError(f"sample {i} of {self.n_samples}")
        i %= self.n_samples
        out = np.zeros((self.nv, self.n_columns))
        out[self.rows] = self.chunk(i // CHUNK)[i % CHUNK]
        return out

    def __getitem__(self, key):
        if isinstance(key, (int, np.integer)):
            return self.frame(int(key))
        return np.asarray(self)[key]

    def __array__(self, dtype=None, copy=None):
        out = np.zeros(self.shape)
        for part, values in self.chunks():
            out[part, self.rows] = values
        return out if dtype is None else out.astype(dtype)

    def forces(self, lam) -> np.ndarray:
        """Generalized forces N @ lambda (n, nv) of contact forces ``lam`` (n, K)."""
        lam = np.asarray(lam, dtype=float)
        out = np.zeros((self.n_samples, self.nv))
        for part, values in self.chunks():
            out[part, self.rows] = np.einsum("nrk,nk->nr", values, lam[part])
        return out

    def row_index(self) -> np.ndarray:
        """(nv,) position of each velocity row in the values (-1: a row that is always zero)."""
        index = np.full(self.nv, -1, dtype=np.int64)
        index[self.rows] = np.arange(len(self.rows))
        return index

    def rows_dense(self, rows) -> np.ndarray:
        """N[:, rows, :] (n, len(rows), K) as one dense array."""
        index = self.row_index()[np.asarray(rows, dtype=np.int64)]
        out = np.zeros((self.n_samples, len(index), self.n_columns))
        keep = index >= 0
        for part, values in self.chunks():
            out[part, keep] = values[:, index[keep]]
        return out


class ComputedContactBasis(ContactBasis):
    """A :class:`ContactBasis` whose values are computed a chunk at a time when asked, by
    ``compute(slice) -> (m, R, K)``, and the last few chunks kept: the contact basis of a long
    capture (7.7 KB a sample stored, 550 MB for 10 minutes at 120 Hz) then costs what its source
    costs (the smoothed path's rotations, 1 KB a sample). Every reader goes through chunks, in
    order of samples, so each chunk is made about once per pass."""

    KEEP = 4

    def __init__(self, compute, n_samples: int, rows, nv: int, n_columns: int):
        self.compute = compute
        self._n = int(n_samples)
        self._k = int(n_columns)
        self.rows = np.ascontiguousarray(rows, dtype=np.int64)
        self.nv = int(nv)
        self._kept: dict[int, np.ndarray] = {}
        self._lock = threading.Lock()  # the editor's threads share a setting's dynamics

    @property
    def values(self) -> np.ndarray:
        """All values (n, R, K) at once (tests and small clips only)."""
        return np.concatenate([v for _, v in self.chunks()]) if self._n else \
            np.zeros((0, len(self.rows), self._k))

    @property
    def n_samples(self) -> int:
        return self._n

    @property
    def n_columns(self) -> int:
        return self._k

    def chunk(self, k: int) -> np.ndarray:
        with self._lock:
            values = self._kept.get(k)
        if values is None:
            values = self.compute(slice(k * CHUNK, min(self._n, (k + 1) * CHUNK)))
            with self._lock:
                while len(self._kept) >= self.KEEP:
                    self._kept.pop(next(iter(self._kept)))
                self._kept[k] = values
        return values

    def __getstate__(self):
        state = dict(self.__dict__)
        state["_kept"], state["_lock"] = {}, None
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()


def as_contact_basis(N) -> ContactBasis:
    """N as a :class:`ContactBasis` (a dense array is compacted on its nonzero rows)."""
    return N if isinstance(N, ContactBasis) else ContactBasis.from_dense(N)
