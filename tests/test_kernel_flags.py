"""Every compiled kernel gives the same bits whether it was just compiled or loaded from numba's
cache. With ``fastmath=True`` (which lets LLVM reassociate sums) the physics objective did not: a
freshly compiled run of 16_16 at half duration wrote another BVH than every later, cached run (numba
issue 10617). Reassociation is the flag that lets the compiler pick the summation order, so no
kernel may ask for it; ``nsz`` and ``contract`` are kept where they were (the guided kernels, whose
output was measured identical fresh and cached)."""
from __future__ import annotations

import importlib
import pkgutil

import pytest

numba = pytest.importorskip("numba")

import retime  # noqa: E402

ALLOWED = {"nsz", "contract"}


def _dispatchers():
    for info in pkgutil.walk_packages(retime.__path__, "retime."):
        if info.name.endswith("__main__") or any(part in info.name for part in (".blender", ".editor", ".batch")):
            continue
        try:
            module = importlib.import_module(info.name)
        except ImportError:  # an optional front end's dependency
            continue
        for name, value in vars(module).items():
            if isinstance(value, numba.core.registry.CPUDispatcher) and value.py_func.__module__ == info.name:
                yield f"{info.name}.{name}", value


def test_no_kernel_lets_the_compiler_choose_the_summation_order():
    kernels = dict(_dispatchers())
    assert len(kernels) > 20  # the walk really found retime's kernels (physics, guided, regions)
    bad = {}
    for name, kernel in kernels.items():
        flags = kernel.targetoptions.get("fastmath", False)
        flags = {"fast"} if flags is True else set(flags or ())
        if not flags <= ALLOWED:
            bad[name] = sorted(flags)
    assert not bad, f"kernels whose fastmath flags reassociate: {bad}"
