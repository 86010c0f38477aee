"""retime batch throughput on Dask distributed: clips per second over every clip in
../shared/data (guided and physics, --scale 0.7), on a local cluster of 1 and of 2 workers, and
the per-task overhead (an empty task's round trip through the scheduler).

    python3 benchmarks/batch.py            # the shared data set (skipped when absent)
    python3 benchmarks/batch.py DIR ...    # any folders or files
    python3 benchmarks/batch.py --methods guided --one-per-task   # one method; a clip per task (no grouping)

Each throughput is the wall time from the first submission to the last result, on a warmed
cluster (started, the physics imported on every worker), so cluster start-up is not counted.
Failed clips count as processed: a batch pays for them too.
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

from retime.batch.jobs import Defaults, find_clips, with_absolute_paths
import retime.batch.run as batch_run
from retime.batch.run import clip_task, input_sizes, prepare_worker, run_tasks

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
ROUND_TRIPS = 200


def _nothing():
    return None


def throughput(client, clips, method: str, outdir: Path, workers: int) -> tuple[float, list[str], dict]:
    """Clips per second as ``retime batch`` submits them (tasks of :func:`retime.batch.run.task_groups`),
    the failures, and each clip's own seconds (by index)."""
    from distributed import as_completed

    tasks = []
    for clip in clips:
        outputs = clip.outputs(outdir, method)
        outputs["bvh"].parent.mkdir(parents=True, exist_ok=True)
        tasks.append(clip_task(clip, method, outputs))
    todo = list(range(len(tasks)))
    start = time.perf_counter()
    groups = batch_run.task_groups(todo, method, workers, input_sizes(clips, todo))
    futures = {client.submit(run_tasks, [tasks[i] for i in group], pure=False, retries=2): group for group in groups}
    seconds, errors = {}, []
    for future in as_completed(futures):
        for i, r in zip(futures[future], future.result()):
            seconds[i] = r["seconds"]
            if r["status"] != "done":
                errors.append(r["error"])
    rate = len(clips) / (time.perf_counter() - start)
    return rate, errors, seconds


def makespan(seconds: dict, order: list[int], workers: int) -> float:
    """The wall time of clips of these ``seconds`` handed out in ``order`` to the first free worker."""
    free = [0.0] * workers
    for i in order:
        k = free.index(min(free))
        free[k] += seconds[i]
    return max(free)


def round_trip_ms(client) -> float:
    """Median of sequential submit-and-gather of an empty task: the floor of a clip's cost."""
    client.submit(_nothing, pure=False).result()
    times = []
    for _ in range(ROUND_TRIPS):
        t = time.perf_counter()
        client.submit(_nothing, pure=False).result()
        times.append(time.perf_counter() - t)
    return statistics.median(times) * 1e3


def main(argv) -> int:
    import argparse

    ap = argparse.ArgumentParser(description="retime batch throughput")
    ap.add_argument("inputs", nargs="*")
    ap.add_argument("--methods", default="guided,physics")
    ap.add_argument("--one-per-task", action="store_true",
                    help="a clip per task in the clips' order, as before tasks were grouped and ordered")
    args = ap.parse_args(argv)
    if args.one_per_task:
        batch_run.task_groups = lambda todo, method, workers, sizes: [[i] for i in todo]
    inputs = args.inputs or ([str(DATA)] if DATA.is_dir() else [])
    if not inputs:
        print(f"skipped: no data at {DATA} (give folders or files)")
        return 0
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        print("skipped: Dask distributed is not installed (pip install -e '.[batch]')")
        return 0
    clips = [with_absolute_paths(c) for c in find_clips(inputs, Defaults(scale=0.7))]
    print(f"{len(clips)} clips from {', '.join(inputs)}; --scale 0.7")
    print(f"{'workers':>7}  {'method':<8}  {'clips/s':>8}  {'failed':>6}  {'empty task':>10}")
    errors, alone = {}, {}
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                          silence_logs=40) as cluster, Client(cluster) as client:
            client.run(prepare_worker)
            overhead = round_trip_ms(client)
            for method in args.methods.split(","):
                with tempfile.TemporaryDirectory() as tmp:
                    rate, failed, seconds = throughput(client, clips, method, Path(tmp), workers)
                errors.update(dict.fromkeys(failed))
                if workers == 1:
                    alone[method] = seconds
                print(f"{workers:>7}  {method:<8}  {rate:>8.2f}  {len(failed):>6}  {overhead:>8.2f} ms", flush=True)
    for error in errors:
        print(f"failed: {error}")
    # what the order alone allows on 2 workers, from each clip's seconds on 1 (no overhead, no contention)
    sizes = input_sizes(clips, list(range(len(clips))))
    for method, seconds in alone.items():
        total = sum(seconds.values())
        fifo = makespan(seconds, sorted(seconds), 2)
        longest = makespan(seconds, sorted(seconds, key=lambda i: (-sizes[i], i)), 2)
        print(f"{method}: the clips' own {total:.1f} s on 2 workers in the clips' order could reach "
              f"{total / fifo:.2f}x, longest first {total / longest:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
