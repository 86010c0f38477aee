"""A first run says it is compiling, and the compiler's time is reported apart from the method's."""
import numba
import numpy as np

from retime.jit import compile_watch


def test_a_compile_is_announced_and_timed(capsys):
    import io

    # a fresh kernel in a retime module name, so the watch counts it (and nothing cached can hide it)
    src = "def _twice(x):\n    return 2 * x\n"
    namespace = {"__name__": "retime._test_kernel"}
    exec(compile(src, "<retime-test>", "exec"), namespace)
    kernel = numba.njit(namespace["_twice"])
    stream = io.StringIO()
    with compile_watch(stream) as watch:
        assert kernel(np.float64(3.0)) == 6.0
    assert watch.kernels == 1 and watch.seconds > 0
    assert stream.getvalue().startswith("compiling retime's kernels (first run only")
    with compile_watch(io.StringIO()) as again:  # compiled now: nothing to say
        kernel(np.float64(4.0))
    assert again.kernels == 0 and again.seconds == 0


def test_physics_reports_compile_time_apart():
    from retime.data import bundled_path
    from retime.motion import load_motion
    from retime.physics import physics_warp

    r = physics_warp(load_motion(bundled_path("16_33.amc")).frames(slice(0, 90)), scale=0.8)
    assert "compile" in r.report["summary"]["timings"] and r.report["summary"]["timings"]["compile"] >= 0
