"""Foundation speed: loading + forward kinematics of a long CMU clip, and resampling a long motion.

Targets (issue 2, on a 2-core machine):
  - load 13_29.amc (4,592 frames, with 13.asf) and run forward kinematics: under 0.5 s
  - apply_timing on 5,000 frames x 31 joints: under 50 ms

Usage: python3 benchmarks/io.py [--repeat N] [--data DIR]
13_29.amc is not bundled; it is looked for in --data, $RETIME_CMU_DATA or ../shared/data/cmu. Without it
that figure is skipped with a message (the resampling figure uses a synthetic motion and always runs).
Prints the best of N runs (default 5) and the target; exits 1 if a measured figure misses its target.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from retime.motion import Motion, Skeleton, forward_kinematics, load_motion
from retime.warp import TimingCurve, apply_timing

LOAD_TARGET_S = 0.5
RESAMPLE_TARGET_S = 0.050


def best_of(fn, repeat):
    """Best wall-clock time (the figure the targets are about), the best CPU time of this process (the
    same unless other programs compete for the cores) and the last result."""
    times, cpu = [], []
    result = None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        result = fn()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(times), min(cpu), result


def find_clip(name, data):
    here = Path(__file__).resolve().parent
    candidates = [Path(d) for d in (data, os.environ.get("RETIME_CMU_DATA")) if d]
    candidates += [here.parent.parent / "shared" / "data" / "cmu", here.parent / "data" / "cmu", Path("/work/shared/data/cmu")]
    for folder in candidates:
        if (folder / name).exists():
            return folder / name
    return None


def bench_load(repeat, data):
    path = find_clip("13_29.amc", data)
    if path is None:
        print("load+FK 13_29.amc    skipped: 13_29.amc not found (give --data DIR holding 13_29.amc and 13.asf)")
        return True

    def run():
        m = load_motion(path)
        forward_kinematics(m)
        return m

    seconds, cpu, m = best_of(run, repeat)
    ok = seconds < LOAD_TARGET_S
    print(f"load+FK 13_29.amc    {seconds * 1000:7.1f} ms (cpu {cpu * 1000:6.1f} ms)   target < {LOAD_TARGET_S * 1000:.0f} ms   "
          f"({m.n_frames} frames x {m.skeleton.n_joints} joints)  {'ok' if ok else 'MISSED'}")
    return ok


def synthetic_motion(n_frames=5000, n_joints=31, fps=120.0):
    rng = np.random.default_rng(0)
    sk = Skeleton(names=[f"j{k}" for k in range(n_joints)], parents=np.arange(-1, n_joints - 1),
                  offsets=rng.normal(size=(n_joints, 3)), channels=[["Zrotation", "Xrotation", "Yrotation"]] * n_joints)
    # smooth random rotations: integrate small random angular velocities
    rotvec = np.cumsum(rng.normal(scale=0.02, size=(n_frames, n_joints, 3)), axis=0)
    rot = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_quat().reshape(n_frames, n_joints, 4)
    tr = np.broadcast_to(sk.offsets, (n_frames, n_joints, 3)).copy()
    tr[:, 0] = np.cumsum(rng.normal(scale=0.01, size=(n_frames, 3)), axis=0)
    return Motion(sk, rot, tr, fps)


def bench_resample(repeat):
    m = synthetic_motion()
    # a non-uniform warp whose output also has 5,000 frames: fractional source times everywhere
    knots = np.linspace(0.0, m.duration, 12)
    source = m.duration * (knots / m.duration) ** 1.3
    curve = TimingCurve(knots, source, kind="pchip")
    seconds, cpu, out = best_of(lambda: apply_timing(m, curve), repeat)
    ok = seconds < RESAMPLE_TARGET_S
    print(f"apply_timing         {seconds * 1000:7.1f} ms (cpu {cpu * 1000:6.1f} ms)   target < {RESAMPLE_TARGET_S * 1000:.0f} ms   "
          f"({m.n_frames} -> {out.n_frames} frames x {m.skeleton.n_joints} joints, slerp)  {'ok' if ok else 'MISSED'}")
    return ok


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--repeat", type=int, default=5, help="runs per figure; the best is printed (default 5)")
    p.add_argument("--data", help="folder holding 13_29.amc and 13.asf")
    args = p.parse_args(argv)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"retime foundation benchmark (best of {args.repeat}, {os.cpu_count()} cpus, load average {load:.1f})")
    if load > (os.cpu_count() or 1):
        print("note: other programs are using the cores; wall-clock figures are inflated (see cpu)")
    ok = bench_load(args.repeat, args.data)
    ok = bench_resample(args.repeat) and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
