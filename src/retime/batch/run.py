"""The Dask driver: one task per clip, each running the single-clip command in-process on a worker
(so a batch's outputs are byte for byte the command's), gathered as they complete. A worker that
dies costs only its task, which the scheduler runs again elsewhere (retries)."""
from __future__ import annotations

import contextlib
import io
import logging
import os
import sys
import time
from pathlib import Path

from ..errors import RetimeError
from .jobs import Clip, with_absolute_paths
from .manifest import Manifest, clip_hash
from .summary import clip_row, read_warp, write_index_html, write_summary_csv

MANIFEST_SAVE_INTERVAL = 1.0  # seconds: often enough for Ctrl-C to keep what finished, rarely enough for 10^4 clips


def clip_argv(clip: Clip, method: str, outputs: dict[str, Path], gravity_scale: float | None = None) -> list[str]:
    """The single-clip command line that makes this clip's outputs."""
    if method == "check":
        return ["check", str(clip.motion), "--report", str(outputs["report"]), "--plot", str(outputs["plot"])]
    argv = [method, str(clip.motion), "-o", str(outputs["bvh"]), "--warp", str(outputs["warp"])]
    if clip.duration is not None:
        argv += ["--duration", repr(clip.duration)]
    elif clip.scale is not None:
        argv += ["--scale", repr(clip.scale)]
    for src, dst in clip.keytimes:
        argv += ["--keytime", f"{src!r}={dst!r}"]
    if clip.reference is not None:
        argv += ["--reference", str(clip.reference)]
    if clip.blend is not None:
        argv += ["--blend", repr(clip.blend)]
    if method == "physics":
        argv += ["--report", str(outputs["report"])]
        if gravity_scale is not None:
            argv += ["--gravity-scale", repr(gravity_scale)]
    if method in ("guided", "physics"):  # linear has no progress output to silence
        argv.append("--quiet")
    return argv


# ---------------------------------------------------------------------------------------- on a worker
def prepare_worker() -> None:
    """Once per worker before the tasks: the physics import (which loads or compiles its numba
    functions) paid up front rather than inside the first clip's seconds."""
    __import__("retime.physics.api")


def _error_line(stderr: str, returncode) -> str:
    lines = [line.strip() for line in stderr.splitlines() if line.strip()]
    errors = [line for line in lines if ": error:" in line]
    if errors:
        return errors[-1]
    return lines[-1] if lines else f"exit code {returncode}"


def run_clip(argv: list[str]) -> dict:
    """One clip, on a worker: ``retime.cli.main(argv)`` with its output captured. Never raises for
    the clip's own failures; those come back as {'status': 'failed', 'error': one line}."""
    import numba

    from ..cli import main

    # clips run side by side, a worker per core: numba's parallel kernels (guided's scores, long physics
    # clips' objective) would put two threads on each core, and a busy core stalls each parallel call
    # (6x on this machine); their results do not depend on the thread count. Thread-local, so per task.
    numba.set_num_threads(1)
    start = time.perf_counter()
    out, err = io.StringIO(), io.StringIO()
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                code = main(argv)
            except SystemExit as e:  # argparse rejecting an option
                code = e.code
    except Exception as e:  # a bug in retime: recorded, and the batch goes on
        return {"status": "failed", "error": f"{type(e).__name__}: {e}".splitlines()[0],
                "seconds": time.perf_counter() - start}
    seconds = time.perf_counter() - start
    if code == 0 or (argv[0] == "check" and code == 1):  # check's 1 is a verdict (not physical), not a failure
        return {"status": "done", "error": "", "seconds": seconds}
    return {"status": "failed", "error": _error_line(err.getvalue(), code), "seconds": seconds}


# ------------------------------------------------------------------------------------------ driver
def _connect(scheduler: str | None, workers: int | None):
    """A client on the given scheduler, or on an embedded local cluster (one process per worker)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise RetimeError("needs Dask distributed: pip install 'retime[batch]'") from None
    if scheduler:
        try:
            return Client(scheduler, timeout="20s"), None
        except (OSError, TimeoutError, ValueError) as e:
            raise RetimeError(f"cannot reach the Dask scheduler at {scheduler}: {e}".splitlines()[0]) from None
    cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    try:
        return Client(cluster), cluster
    except BaseException:
        cluster.close()
        raise


def _close(client, cluster) -> None:
    for thing in (client, cluster):
        if thing is not None:
            with contextlib.suppress(Exception):
                thing.close()


def run_batch(clips: list[Clip], outdir: Path, method: str, *, gravity_scale: float | None = None,
              scheduler: str | None = None, workers: int | None = None, force: bool = False,
              quiet: bool = False) -> int:
    outdir = Path(outdir)
    manifest = Manifest(outdir)
    options = {"gravity_scale": gravity_scale}
    shown = [str(c.motion) for c in clips]  # as the user named them
    clips = [with_absolute_paths(c) for c in clips]
    outputs = [c.outputs(outdir.absolute(), method) for c in clips]
    digests = [clip_hash(c, method, options) for c in clips]
    results: dict[int, dict] = {}
    for i, clip in enumerate(clips):
        if not force and manifest.is_current(clip, digests[i], outputs[i]):
            results[i] = {"status": "skipped", "error": "", "seconds": None}
    todo = [i for i in range(len(clips)) if i not in results]

    outdir.mkdir(parents=True, exist_ok=True)  # a bad OUTDIR fails here, before a cluster starts
    client = cluster = None
    try:
        if todo:  # before any output file: an unreachable scheduler leaves none behind
            client, cluster = _connect(scheduler, workers)
    except KeyboardInterrupt:
        print("retime batch: interrupted while starting; no output written", file=sys.stderr)
        return 130
    unfinished, stopped = "interrupted before it finished", None
    try:
        for i in todo:
            next(iter(outputs[i].values())).parent.mkdir(parents=True, exist_ok=True)
        if todo:
            _compute(client, clips, outputs, digests, todo, results, manifest, method, gravity_scale, quiet)
    except KeyboardInterrupt:
        stopped = KeyboardInterrupt
    except Exception as e:  # e.g. the scheduler gone: say so, and still keep what finished
        stopped = RetimeError(f"the batch stopped: {type(e).__name__}: {e}".splitlines()[0])
        unfinished = f"not run: {stopped}"
    finally:
        _close(client, cluster)
    for i in range(len(clips)):
        if i not in results:
            results[i] = {"status": "failed", "error": unfinished, "seconds": None}
    manifest.save()
    curves = [read_warp(outputs[i]["warp"]) if results[i]["status"] != "failed" and "warp" in outputs[i] else None
              for i in range(len(clips))]  # each warp file read once, for the row and the page
    rows = [clip_row(shown[i], **results[i], outputs=outputs[i], curve=curves[i]) for i in range(len(clips))]
    if method == "check":  # the library ranked from least to most physical (failed clips last)
        order = sorted(range(len(rows)), key=lambda i: (rows[i]["status"] == "failed",
                                                        -float(rows[i]["off_share"] or 0.0)))
        rows, curves = [rows[i] for i in order], [curves[i] for i in order]
    write_summary_csv(rows, outdir / "summary.csv")
    write_index_html(rows, curves, outdir / "index.html", title=f"retime batch: {method}")
    if isinstance(stopped, RetimeError):
        raise stopped
    if stopped is KeyboardInterrupt:
        print("retime batch: interrupted; finished clips kept (see summary.csv)", file=sys.stderr)
        return 130
    failed = sum(r["status"] == "failed" for r in rows)
    if not quiet:
        counts = {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped")}
        print(f"wrote {outdir / 'summary.csv'} and index.html: {counts['done']} done, {counts['skipped']} skipped, "
              f"{failed} failed")
    if failed:
        print(f"{failed} of {len(rows)} clips failed (see {outdir / 'summary.csv'})", file=sys.stderr)
        return 1
    return 0


def _compute(client, clips, outputs, digests, todo, results, manifest, method, gravity_scale, quiet):
    from distributed import as_completed
    from tqdm import tqdm

    futures = []
    try:
        if not quiet:
            print(f"dashboard: {client.dashboard_link}", flush=True)
        client.run(prepare_worker)
        index_of = {}
        for i in todo:
            future = client.submit(run_clip, clip_argv(clips[i], method, outputs[i], gravity_scale),
                                   pure=False, retries=2)
            index_of[future.key] = i
            futures.append(future)
        counts = {"done": 0, "failed": 0}
        last_save = -MANIFEST_SAVE_INTERVAL  # the first finished clip is recorded at once
        with tqdm(total=len(todo), unit="clip", file=sys.stderr, disable=quiet) as bar:
            for future in as_completed(futures):
                i = index_of[future.key]
                try:
                    result = future.result()
                except Exception as e:  # the task itself failed: a worker died more often than retries
                    result = {"status": "failed", "error": f"{type(e).__name__}: {e}".splitlines()[0], "seconds": None}
                results[i] = result
                if result["status"] == "done":
                    manifest.record(clips[i], digests[i], result["seconds"])
                else:
                    manifest.forget(clips[i])
                counts[result["status"]] += 1
                bar.set_postfix(counts, refresh=False)
                bar.update(1)
                if time.monotonic() - last_save >= MANIFEST_SAVE_INTERVAL:
                    manifest.save()
                    last_save = time.monotonic()
    except KeyboardInterrupt:
        with contextlib.suppress(Exception):
            client.cancel([f for f in futures if not f.done()])
        raise
