"""Time and peak memory of linear, guided (exact and heuristic) and physics on 1, 2, 5 and 10
minutes of 120 Hz motion, with the growth exponent of each (log-log slope against the number of
frames), and the cold-start figures: the first and second run of ``retime physics``, ``retime
guided`` and ``retime demo`` with an empty numba cache (``NUMBA_CACHE_DIR``), and optionally in a
fresh virtual environment after the README's install command (``--venv``).

Every measurement runs in its own process, so peaks do not mix; memory is the process's peak
resident set (what ``/usr/bin/time -v`` calls Maximum resident set size), and for physics also
the largest forked region worker. Times are wall and CPU (user + system, the process and its
workers): other work on the machine inflates the wall time, much less the CPU time.

The long captures are built in memory from CMU subject 13's long takes (``longclip.py``; needs
``../shared/data/cmu``). Kernels are compiled first (``retime.precompile``) so the table shows the
methods, not the compiler.

    python benchmarks/scaling.py                      # everything (physics at 10 minutes: minutes)
    python benchmarks/scaling.py --minutes 1,2 --methods guided,guided-fast --no-cold
    python benchmarks/scaling.py --cold-only --venv
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
SRC = ROOT / "src"
BENCHMARKED = ("linear", "guided", "guided-fast", "physics")
# issue 16's targets on this 2-core machine, printed beside the measurements
TARGETS = {("physics", 10): "2 GB, 180 s", ("guided", 10): "0.4 GB, 9 s"}
COLD_TARGETS = {"physics": 15.0, "guided": 5.0, "demo": 20.0}


# ------------------------------------------------------------------ one measurement (child process)
def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def measure_one(method: str, minutes: float) -> dict:
    sys.path.insert(0, str(SRC))
    sys.path.insert(0, str(HERE))
    from longclip import long_capture

    motion = long_capture(minutes)
    duration = motion.duration * 0.5
    base = _rss_mb()
    t0, c0 = time.perf_counter(), os.times()
    if method == "linear":
        from retime.warp import apply_timing, uniform_warp

        apply_timing(motion, uniform_warp(motion.duration, duration))
    elif method in ("guided", "guided-fast"):
        from retime.guided import guided_solve

        guided_solve(motion, duration=duration, fast=method == "guided-fast", quiet=True)
    elif method == "physics":
        from retime.physics.api import physics_warp

        r = physics_warp(motion, duration=duration)
        stages = {k: round(v, 2) for k, v in r.timings.items()}
    else:
        raise SystemExit(f"unknown method {method!r}")
    wall = time.perf_counter() - t0
    c1 = os.times()
    cpu = (c1.user - c0.user) + (c1.system - c0.system) + (c1.children_user - c0.children_user) \
        + (c1.children_system - c0.children_system)
    out = {"method": method, "minutes": minutes, "frames": motion.n_frames, "wall": wall, "cpu": cpu,
           "base_mb": base, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
           "worker_peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}
    if method == "physics":
        out["stages"] = stages
    return out


def run_child(method: str, minutes: float, timeout: float) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]),
               RETIME_MAX_MEMORY=os.environ.get("RETIME_MAX_MEMORY", "64G"))
    try:
        p = subprocess.run([sys.executable, __file__, "--one", method, str(minutes)], env=env, capture_output=True,
                           text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"method": method, "minutes": minutes, "error": f"over {timeout:.0f} s"}
    if p.returncode:
        tail = (p.stderr.strip().splitlines() or ["?"])[-1]
        return {"method": method, "minutes": minutes, "error": tail[:80]}
    return json.loads(p.stdout.strip().splitlines()[-1])


def slope(xs, ys):
    """Least-squares slope of log y against log x (None with fewer than two points)."""
    pts = [(math.log(x), math.log(y)) for x, y in zip(xs, ys) if x > 0 and y and y > 0]
    if len(pts) < 2:
        return None
    mx = sum(p[0] for p in pts) / len(pts)
    my = sum(p[1] for p in pts) / len(pts)
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx if sxx else None


def scaling_table(methods, minutes, physics_minutes, timeout):
    rows = {}
    for method in methods:
        sizes = physics_minutes if method == "physics" else minutes
        for mins in sizes:
            r = run_child(method, mins, timeout)
            rows[(method, mins)] = r
            if "error" in r:
                print(f"  {method:12s} {mins:4g} min: {r['error']}", flush=True)
            else:
                extra = f"  stages {r['stages']}" if "stages" in r else ""
                print(f"  {method:12s} {mins:4g} min {r['frames']:7,d} frames: {r['wall']:7.1f} s wall "
                      f"{r['cpu']:7.1f} s cpu, peak {r['peak_mb']:6.0f} MB (start {r['base_mb']:.0f} MB, "
                      f"workers {r['worker_peak_mb']:.0f} MB){extra}", flush=True)
    print("\nscaling (120 Hz source, output half as long; peak = the process's max RSS)")
    head = f"{'method':12s}" + "".join(f"{m:>22g} min" for m in sorted(set(minutes) | set(physics_minutes)))
    print(head + f"{'time exp':>10s}{'mem exp':>9s}   target at 10 min")
    for method in methods:
        sizes = sorted(set(physics_minutes if method == "physics" else minutes))
        cells, fr, ts, ms = [], [], [], []
        for mins in sorted(set(minutes) | set(physics_minutes)):
            r = rows.get((method, mins))
            if r is None or mins not in sizes:
                cells.append(f"{'':>26s}")
            elif "error" in r:
                cells.append(f"{r['error'][:24]:>26s}")
            else:
                cells.append(f"{r['wall']:8.1f}s/{r['cpu']:6.1f}cpu {r['peak_mb']:6.0f}MB")
                fr.append(r["frames"])
                ts.append(r["cpu"])
                ms.append(max(r["peak_mb"] - r["base_mb"], 1.0))
        st, sm = slope(fr, ts), slope(fr, ms)
        fmt = lambda v: f"{v:10.2f}" if v is not None else f"{'-':>10s}"
        print(f"{method:12s}" + "".join(cells) + fmt(st) + fmt(sm)[1:] + "   " + TARGETS.get((method, 10), ""))
    print("(exponents: slope of log CPU time and of log (peak - start) memory against log frames)")


# ------------------------------------------------------------------ cold start
def _timed(cmd, env, cwd):
    t0 = time.perf_counter()
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed: {p.stderr.strip()[-300:]}")
    return time.perf_counter() - t0, cpu


def cold_start(retime_cmd, env_extra=None, label="empty NUMBA_CACHE_DIR"):
    """First and second run of physics, guided and demo; a new empty numba cache per command."""
    clip = SRC / "retime" / "data" / "cmu" / "16_06.amc"
    print(f"\ncold start ({label}): first and second run, wall / CPU seconds")
    work = Path(tempfile.mkdtemp(prefix="retime-cold-"))
    cmds = {"physics": ["physics", str(clip), "--scale", "0.5", "-o", str(work / "p.bvh"), "--quiet"],
            "guided": ["guided", str(clip), "--scale", "0.5", "-o", str(work / "g.bvh"), "--quiet"],
            "demo": ["demo", "-o", str(work / "demo")]}
    for name, args in cmds.items():
        env = dict(os.environ, **(env_extra or {}))
        if env_extra is None:
            env["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="numba-", dir=work)
            env["PYTHONPATH"] = os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")])
        runs = []
        for _ in range(2):
            if name == "demo":
                subprocess.run(["rm", "-rf", str(work / "demo")])
            runs.append(_timed(retime_cmd + args, env, work))
        (w1, c1), (w2, c2) = runs
        print(f"  {name:8s} first {w1:6.1f} s / {c1:6.1f} s CPU   second {w2:5.1f} s / {c2:5.1f} s CPU"
              f"   (target first <= {COLD_TARGETS[name]:g} s)", flush=True)


def fresh_venv():
    """The README's install in a new virtual environment of a clean clone, then the cold starts."""
    tmp = Path(tempfile.mkdtemp(prefix="retime-venv-"))
    clone = tmp / "retime"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    subprocess.run([sys.executable, "-m", "venv", str(tmp / "venv")], check=True)
    py = tmp / "venv" / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "NUMBA_CACHE_DIR")}
    t0 = time.perf_counter()
    subprocess.run([str(py), "-m", "pip", "install", "-q", "-e", ".[test,editor,batch]"], cwd=clone, env=env,
                   check=True, capture_output=True)
    print(f"\nfresh venv: README install (pip install -e, kernels compiled by the build) {time.perf_counter() - t0:.0f} s")
    cold_start([str(tmp / "venv" / "bin" / "retime")], env_extra=env, label="fresh venv after the README install")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--minutes", default="1,2,5,10", help="sizes for linear and guided (default 1,2,5,10)")
    p.add_argument("--physics-minutes", default=None, help="sizes for physics (default: --minutes)")
    p.add_argument("--methods", default=",".join(BENCHMARKED), help=f"subset of {','.join(BENCHMARKED)}")
    p.add_argument("--timeout", type=float, default=1800.0, help="seconds per measurement")
    p.add_argument("--no-cold", action="store_true", help="skip the cold-start figures")
    p.add_argument("--cold-only", action="store_true", help="only the cold-start figures")
    p.add_argument("--venv", action="store_true", help="also the cold start in a fresh venv (a few minutes)")
    p.add_argument("--one", nargs=2, metavar=("METHOD", "MINUTES"), help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.one:
        print(json.dumps(measure_one(a.one[0], float(a.one[1]))))
        return
    if not a.cold_only:
        minutes = [float(x) for x in a.minutes.split(",")]
        pm = [float(x) for x in (a.physics_minutes or a.minutes).split(",")]
        methods = [m for m in a.methods.split(",") if m]
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
        subprocess.run([sys.executable, "-m", "retime.precompile"], env=env, check=True, capture_output=True)
        scaling_table(methods, minutes, pm, a.timeout)
    if not a.no_cold:
        cold_start([sys.executable, "-c", "import sys; from retime.cli import main; sys.exit(main())"])
        if a.venv:
            fresh_venv()


if __name__ == "__main__":
    main()
