"""Compile numba kernels with the SLP vectoriser switched on.

numba leaves LLVM's SLP vectoriser off by default (``NUMBA_SLP_VECTORIZE=0``); the kNN and DP
kernels are written as groups of independent scalar updates that it packs into AVX vectors
(about 4x faster here). :func:`compiled` compiles one signature of a dispatcher with it on
(or loads it from numba's cache) and restores the setting.
"""

from __future__ import annotations

import threading

import numba

_lock = threading.Lock()
_done: set = set()


def compiled(dispatcher, signature):
    """The dispatcher, with ``signature`` compiled (SLP on) before its first call."""
    key = (id(dispatcher), str(signature))
    if key in _done:
        return dispatcher
    with _lock:
        if key not in _done:
            prev = numba.config.SLP_VECTORIZE
            numba.config.SLP_VECTORIZE = 1
            try:
                dispatcher.compile(signature)
            finally:
                numba.config.SLP_VECTORIZE = prev
            _done.add(key)
    return dispatcher


_blas_libs = None


def _blas_controllers():
    global _blas_libs
    if _blas_libs is None:
        try:
            from threadpoolctl import ThreadpoolController

            _blas_libs = [c for c in ThreadpoolController().lib_controllers if c.user_api == "blas"]
        except Exception:  # threadpoolctl missing or unable to inspect: leave BLAS alone
            _blas_libs = []
    return _blas_libs


class single_threaded_blas:
    """Context manager: BLAS on one thread inside.

    OpenBLAS worker threads spin for a long time after each call; on a 2-core machine they then
    compete with the numba kernels that run right after a matrix product and halve their speed.
    The products here are small enough that one thread is as fast.
    """

    def __enter__(self):
        self._saved = [(c, c.num_threads) for c in _blas_controllers()]
        for c, _ in self._saved:
            c.set_num_threads(1)
        return self

    def __exit__(self, *exc):
        for c, nt in self._saved:
            c.set_num_threads(nt)
        return False
