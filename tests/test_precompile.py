"""The build's precompile step fills numba's cache with what a run loads: afterwards a run in the
same cache compiles nothing and gives the same answer."""
import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parent.parent / "src"


def _run(args, cache):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, timeout=600)


def test_a_precompiled_cache_is_loaded_not_recompiled(tmp_path):
    from retime.data import bundled_path

    cache = tmp_path / "numba"
    warm = _run(["-m", "retime.precompile", "guided"], cache)
    assert warm.returncode == 0, warm.stderr
    assert "compiling retime's kernels" in warm.stderr  # an empty cache: it did compile
    assert any(cache.rglob("score._knn3_kernel-*.nbi"))
    clip = str(bundled_path("16_06.amc"))
    cli = "from retime.cli import main; import sys; sys.exit(main(sys.argv[1:]))"
    out = _run(["-c", cli, "guided", clip, "--scale", "0.5", "-o", str(tmp_path / "g.bvh"),
                "--warp", str(tmp_path / "g.csv")], cache)
    assert out.returncode == 0, out.stderr
    assert "compiling" not in out.stderr, out.stderr  # every kernel came from the cache
    # a longer clip, whose steady refinement bounds its search first (other kernels), too
    wide = _run(["-c", cli, "guided", str(bundled_path("131_01.bvh")), "--scale", "0.6", "-o",
                 str(tmp_path / "w.bvh")], cache)
    assert wide.returncode == 0, wide.stderr
    assert "compiling" not in wide.stderr, wide.stderr
    # and the same answer as compiling afresh in this process
    from retime.guided import guided_solve
    from retime.motion import load_motion
    import numpy as np

    m = load_motion(clip)
    curve = guided_solve(m, duration=m.duration * 0.5, quiet=True).curve
    rows = np.loadtxt(tmp_path / "g.csv", delimiter=",", skiprows=1)
    assert np.allclose(rows[:, 1], curve(rows[:, 0]), atol=1e-9)
