"""BLAS on one thread around small dense products.

OpenBLAS worker threads spin for a long time after each call; on a 2-core machine they then compete
with the numba kernels that run right after a matrix product (guided's scores, physics' quasi-Newton
updates) and halve their speed. The products there are small enough that one thread is as fast.
"""
from __future__ import annotations

import functools


@functools.lru_cache(maxsize=1)
def _controller():
    from threadpoolctl import ThreadpoolController  # inspects the loaded BLAS libraries: once

    return ThreadpoolController()


def single_threaded_blas():
    """A context manager: BLAS on one thread inside; its thread count is restored on exit."""
    return _controller().limit(limits=1, user_api="blas")
