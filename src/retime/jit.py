"""Compilation shown as such: the first run compiles retime's numba kernels (cached afterwards), and
that time is the compiler's, not the method's.

:func:`compile_watch` listens to numba's compile events. The first retime kernel that compiles
prints one line ("compiling retime's kernels (first run only)..."), each further one a dot, and
the watch's ``seconds`` is the wall time spent compiling retime's kernels (outermost only), which
callers subtract from their own timings.
"""
from __future__ import annotations

import contextlib
import os
import sys
import threading
import time


class CompileWatch:
    def __init__(self, say=None):
        self.say = say  # None: silent; else a stream
        self.seconds = 0.0
        self.kernels = 0
        self._depth = 0
        self._t0 = 0.0
        self._thread = threading.get_ident()
        self._pid = os.getpid()  # a forked pool's workers inherit the listener: they stay quiet

    def _ours(self, event) -> bool:
        data = event.data or {}
        dispatcher = data.get("dispatcher")
        module = getattr(getattr(dispatcher, "py_func", None), "__module__", "") or ""
        return module.startswith("retime.") and threading.get_ident() == self._thread and os.getpid() == self._pid

    def on_start(self, event):
        if not self._ours(event):
            return
        if self._depth == 0:
            self._t0 = time.perf_counter()
            if self.say is not None:
                if self.kernels == 0:
                    self.say.write("compiling retime's kernels (first run only; cached afterwards) ")
                self.say.write(".")
                self.say.flush()
            self.kernels += 1
        self._depth += 1

    def on_end(self, event):
        if not self._ours(event):
            return
        self._depth -= 1
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._t0


@contextlib.contextmanager
def compile_watch(say=None):
    """Yield a :class:`CompileWatch` for the block (``say``: a stream for the notice, e.g. stderr)."""
    try:
        from numba.core import event
    except ImportError:  # no numba event API: nothing to watch
        yield CompileWatch()
        return
    watch = CompileWatch(say)

    class _Listener(event.Listener):
        def on_start(self, ev):
            watch.on_start(ev)

        def on_end(self, ev):
            watch.on_end(ev)

    with event.install_listener("numba:compile", _Listener()):
        yield watch
    if say is not None and watch.kernels:
        say.write(f" {watch.kernels} kernel(s) in {watch.seconds:.1f} s\n")
        say.flush()


def stderr_if(show: bool):
    return sys.stderr if show else None
