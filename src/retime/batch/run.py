"""The Dask driver: clips as tasks, each running the single-clip work in-process on a worker through
:func:`retime.method.solve` and :mod:`retime.outputs` (the code the single-clip commands run, so a
batch's outputs are byte for byte the command's), gathered as they complete. Quick clips (linear,
guided) travel a few to a task, so that the scheduler's round trip is paid once for them. A worker
that dies costs only its task, which the scheduler runs again elsewhere (retries)."""
from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import time
from concurrent.futures import CancelledError
from dataclasses import dataclass, replace
from pathlib import Path

from ..errors import RetimeError
from ..method import Request
from .jobs import Clip, check_inputs_kept, with_absolute_paths
from .manifest import Manifest, clip_hash
from .layout import INDEX_NAME, SUMMARY_NAME
from .lock import FolderLock
from .summary import clip_row, read_warp, write_index_html, write_summary_csv

MANIFEST_SAVE_INTERVAL = 1.0  # seconds: often enough for Ctrl-C to keep what finished, rarely enough for 10^4 clips
#: methods whose clips take well under a second: several small clips travel in one task, so that the
#: scheduler's round trip (~10 ms) is paid once for them
QUICK_METHODS = ("linear", "guided")
MAX_GROUP = 8  # clips per task at most
TASKS_PER_WORKER = 4  # a task holds at most 1/(this x workers) of the batch's bytes, so the last ones still spread


@dataclass(frozen=True)
class Task:
    """One clip's work as a worker gets it (pickled): the method, the input file, the request (its
    settings included; None for check) and where its outputs go. A guided reference travels as its
    path and is read on the worker."""

    method: str
    motion: Path
    outputs: dict
    request: Request | None = None
    reference: Path | None = None


def clip_task(clip: Clip, method: str, outputs: dict[str, Path], gravity_scale: float | None = None) -> Task:
    """What makes this clip's outputs: the request the single-clip command would make of its options."""
    if method == "check":
        return Task(method, clip.motion, outputs)
    from ..method import settings_type

    options = {}
    if method == "guided":
        options.update(clip.guided_options())
    if method == "physics" and gravity_scale is not None:
        options["gravity_scale"] = gravity_scale
    settings = settings_type(method)(**options)
    request = Request(clip.duration, clip.scale if clip.duration is None else None, clip.keytimes, settings)
    return Task(method, clip.motion, outputs, request, clip.reference)


def task_groups(todo: list[int], method: str, workers: int, sizes: dict[int, int]) -> list[list[int]]:
    """``todo`` as the tasks the scheduler gets, longest first (``sizes``: each clip's input in bytes,
    which grows with its frames): the longest-processing-time order, so that no long clip starts
    last while the other workers idle. For the quick methods consecutive clips share a task while
    together they hold at most 1/(TASKS_PER_WORKER x workers) of the bytes (and MAX_GROUP clips)."""
    order = sorted(todo, key=lambda i: (-sizes.get(i, 0), i))
    if method not in QUICK_METHODS:
        return [[i] for i in order]
    budget = sum(sizes.get(i, 0) for i in order) / (TASKS_PER_WORKER * max(1, workers))
    groups: list[list[int]] = []
    held = 0
    for i in order:
        size = sizes.get(i, 0)
        if groups and len(groups[-1]) < MAX_GROUP and held + size <= budget:
            groups[-1].append(i)
            held += size
        else:
            groups.append([i])
            held = size
    return groups


def input_sizes(clips: list[Clip], todo: list[int]) -> dict[int, int]:
    """Each clip's input file size in bytes (0 when it cannot be read: it fails quickly)."""
    out = {}
    for i in todo:
        try:
            out[i] = clips[i].motion.stat().st_size
        except OSError:
            out[i] = 0
    return out


# ---------------------------------------------------------------------------------------- on a worker
def prepare_worker() -> None:
    """Once per worker before the tasks: the physics import (which loads or compiles its numba
    functions) paid up front rather than inside the first clip's seconds."""
    __import__("retime.physics.api")


def run_tasks(tasks: list[Task]) -> list[dict]:
    """Clips on a worker, one after the other (see :func:`run_task`)."""
    import numba

    # clips run side by side, a worker per core: numba's parallel kernels (guided's scores, long physics
    # clips' objective) would put two threads on each core, and a busy core stalls each parallel call
    # (6x on this machine); their results do not depend on the thread count. Thread-local, so per task.
    numba.set_num_threads(1)
    return [run_task(task) for task in tasks]


def run_task(task: Task) -> dict:
    """One clip: read, retime (or check) and write its outputs, which appear together or not at all.
    Never raises for the clip's own failures; those come back as {'status': 'failed', 'error': one
    line}, worded as the single-clip command says them."""
    from ..io_util import all_or_none

    start = time.perf_counter()
    try:
        with all_or_none():
            _run(task)
        error = ""
    except RetimeError as e:
        error = f"retime {task.method}: error: {e}"
    except OSError as e:  # e.g. a full disk
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        error = f"retime {task.method}: error: {where}{e.strerror or e}"
    except Exception as e:  # a bug in retime: recorded, and the batch goes on
        error = f"{type(e).__name__}: {e}"
    seconds = time.perf_counter() - start
    return {"status": "failed" if error else "done", "error": error.splitlines()[0] if error else "",
            "seconds": seconds}


def _run(task: Task) -> None:
    from ..method import solve
    from ..motion import load_motion
    from ..outputs import write_check, write_retiming

    motion = load_motion(task.motion)
    out = task.outputs
    if task.method == "check":
        from ..physics.check import check_clip

        if motion.n_frames < 4:
            raise RetimeError(f"{task.motion}: checking needs at least 4 frames, the motion has {motion.n_frames}")
        write_check(check_clip(motion), out["report"], out["plot"], title=str(task.motion))
        return  # not physical is a verdict, not a failure
    request = task.request
    if task.reference is not None:
        request = replace(request, settings=replace(request.settings, reference=load_motion(task.reference)))
    result = solve(task.method, motion, request)
    write_retiming(task.method, motion, result, out["bvh"], out["warp"], out.get("report"), source=task.motion)


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
    # the workers start with SIGINT ignored (a disposition that survives exec; a handler would not):
    # a terminal's Ctrl-C reaches the whole process group, and this process alone stops the batch
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if _on_main_thread() else None
    try:
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.CRITICAL)
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
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


def _on_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


class _Stop:
    """SIGINT and SIGTERM stop the batch: the first raises KeyboardInterrupt where the driver is, until
    :meth:`hold`; later ones, and any after it, are only noted, so that the summary of what is on disk
    is still written."""

    def __init__(self):
        self.signal: int | None = None
        self.previous = {}
        self.raising = True

    def __enter__(self):
        if _on_main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self.previous[signum] = signal.signal(signum, self._handle)
        return self

    def _handle(self, signum, frame):
        if self.signal is None:
            self.signal = signum
            if self.raising:
                raise KeyboardInterrupt

    def hold(self) -> None:
        """The clips are over: from here a signal must not cut off the summary (the cluster's closing
        and the summary of a large batch take seconds)."""
        self.raising = False

    def __exit__(self, *exc):
        for signum, handler in self.previous.items():
            signal.signal(signum, handler)

    @property
    def exit_code(self) -> int:
        return 128 + (self.signal or signal.SIGINT)

    @property
    def how(self) -> str:
        return "terminated" if self.signal == signal.SIGTERM else "interrupted"


@contextlib.contextmanager
def _quiet_dask_logs():
    """The driver's Dask client logs a lost scheduler or a cancelled task as tracebacks; the batch
    says what happened in its rows and one line. Dask's config gives its loggers levels of their own
    (distributed.client: warning), so each is quietened, not only their parent.

    A local cluster's workers log too: a stopped batch closes the scheduler while a worker may be
    mid-heartbeat, and its ERROR traceback followed the batch's one line (a race CI met once).
    ``silence_logs`` reaches only the nanny's logger in a worker process, so the workers get Dask's
    logging level in their environment before they are spawned (restarts included); a clip's own
    failure still reaches its row through the task's exception."""
    import dask
    import distributed  # noqa: F401 (its loggers exist once it is imported)

    names = [n for n in list(logging.root.manager.loggerDict) if n == "distributed" or n.startswith("distributed.")]
    loggers = [logging.getLogger(n) for n in names]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        with dask.config.set({"distributed.nanny.pre-spawn-environ.DASK_LOGGING__DISTRIBUTED": "critical"}):
            yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _writable_folders(outputs: list[dict[str, Path]]) -> None:
    """Every clip's output folder, made and checked writable before any clip runs."""
    for folder in sorted({p.parent for paths in outputs for p in paths.values()}):
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RetimeError(f"{folder}: cannot make this output folder ({e.strerror}); choose another -o") from None
        if not os.access(folder, os.W_OK):
            raise RetimeError(f"{folder}: cannot write in this output folder (permission denied); choose another -o")


def run_batch(clips: list[Clip], outdir: Path, method: str, *, gravity_scale: float | None = None,
              scheduler: str | None = None, workers: int | None = None, force: bool = False,
              quiet: bool = False, skipped: tuple[tuple[str, str], ...] = ()) -> int:
    """Run the clips; ``skipped`` are inputs found but not readable as clips (input, reason), listed
    as failed rows."""
    outdir = Path(outdir)
    check_inputs_kept(clips, outdir, method)  # before anything is written
    try:
        outdir.mkdir(parents=True, exist_ok=True)  # a bad OUTDIR fails here, before a cluster starts
    except OSError as e:
        raise RetimeError(f"{outdir}: cannot make the output folder ({e.strerror}); choose another -o") from None
    with FolderLock(outdir) as lock, _Stop() as stop, _quiet_dask_logs():
        try:
            return _run_locked(clips, outdir, method, lock, stop, gravity_scale=gravity_scale, scheduler=scheduler,
                               workers=workers, force=force, quiet=quiet, skipped=skipped)
        except KeyboardInterrupt:  # reading the inputs or starting the cluster; a later stop leaves a summary
            print(f"retime batch: {stop.how} while starting; no output written", file=sys.stderr)
            return stop.exit_code


def _run_locked(clips, outdir, method, lock, stop, *, gravity_scale, scheduler, workers, force, quiet, skipped):
    manifest = Manifest(outdir)
    manifest.claim(method)
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
    _writable_folders([outputs[i] for i in todo])

    client = cluster = None
    if todo:  # before any output file: an unreachable scheduler leaves none behind
        client, cluster = _connect(scheduler, workers)
    lost = None
    try:
        if todo:
            _compute(client, clips, outputs, digests, todo, results, manifest, method, gravity_scale, quiet,
                     scheduler)
    except KeyboardInterrupt:
        pass
    except SchedulerLost as e:
        lost = str(e)
    except Exception as e:  # the client failed some other way: say so, and still keep what finished
        lost = f"the Dask client failed ({type(e).__name__}: {e})".splitlines()[0]
    finally:
        stop.hold()
        _close(client, cluster)  # a local cluster's workers are gone after this: the disk is final
    if stop.signal is not None or lost is not None:
        unfinished = "interrupted before it finished" if lost is None else f"not run: {lost}"
        _read_back_from_disk(clips, outputs, digests, todo, results, manifest, lock.started_ns(), unfinished)
    manifest.save()
    curves = [read_warp(outputs[i]["warp"]) if results[i]["status"] != "failed" and "warp" in outputs[i] else None
              for i in range(len(clips))]  # each warp file read once, for the row and the page
    rows = [clip_row(shown[i], **results[i], outputs=outputs[i], curve=curves[i]) for i in range(len(clips))]
    rows += [clip_row(text, "failed", reason, None, {}) for text, reason in skipped]
    curves += [None] * len(skipped)
    if method == "check":  # the library ranked from least to most physical (failed clips last)
        order = sorted(range(len(rows)), key=lambda i: (rows[i]["status"] == "failed",
                                                        -float(rows[i]["off_share"] or 0.0)))
        rows, curves = [rows[i] for i in order], [curves[i] for i in order]
    write_summary_csv(rows, outdir / SUMMARY_NAME)
    # the skipped inputs' rows follow the clips' and have no plot
    plots = [outputs[i].get("plot") if i < len(outputs) else None for i in order] if method == "check" else None
    write_index_html(rows, curves, outdir / INDEX_NAME, title=f"retime batch: {method}", method=method, plots=plots)
    if stop.signal is not None:
        print(f"retime batch: {stop.how}; finished clips kept (see summary.csv)", file=sys.stderr)
        return stop.exit_code
    failed = sum(r["status"] == "failed" for r in rows)
    if lost is not None:
        print(f"retime batch: {lost}; {failed} of {len(rows)} clips not done (see {outdir / SUMMARY_NAME})",
              file=sys.stderr)
        return 1
    if not quiet:
        counts = {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped")}
        print(f"wrote {outdir / SUMMARY_NAME} and index.html: {counts['done']} done, {counts['skipped']} skipped, "
              f"{failed} failed")
    if failed:
        print(f"{failed} of {len(rows)} clips failed (see {outdir / SUMMARY_NAME})", file=sys.stderr)
        return 1
    return 0


def _read_back_from_disk(clips, outputs, digests, todo, results, manifest, started_ns, unfinished) -> None:
    """After a stop, the clips whose results never came back: a clip whose every output was written
    during this run finished (its worker wrote them as one transaction) and is recorded; any
    other is unfinished, and its manifest entry, if any, still describes the older outputs there."""
    for i in todo:
        if i in results:
            continue
        if all(_written_since(p, started_ns) for p in outputs[i].values()):
            results[i] = {"status": "done", "error": "", "seconds": None}
            manifest.record(clips[i], digests[i], 0.0)
        else:
            older = any(p.exists() for p in outputs[i].values())
            results[i] = {"status": "failed", "seconds": None,
                          "error": unfinished + ("; the outputs there are from an earlier run" if older else "")}


def _written_since(path: Path, started_ns: int) -> bool:
    try:
        return path.stat().st_mtime_ns >= started_ns
    except OSError:
        return False


class SchedulerLost(Exception):
    """The scheduler went away mid-batch: the clips not finished by then did not run."""


def _compute(client, clips, outputs, digests, todo, results, manifest, method, gravity_scale, quiet, scheduler):
    from distributed import as_completed
    from distributed.comm.core import CommClosedError
    from tqdm import tqdm

    futures = []
    try:
        if not quiet:
            print(f"dashboard: {client.dashboard_link}", flush=True)
        if scheduler and not client.scheduler_info().get("workers"):
            print(f"retime batch: no worker has joined the scheduler at {scheduler} yet; waiting "
                  f"(start one with: dask worker {scheduler})", file=sys.stderr, flush=True)
        client.run(prepare_worker)
        index_of = {}
        workers = max(1, len(client.scheduler_info().get("workers", {})))
        for group in task_groups(todo, method, workers, input_sizes(clips, todo)):
            tasks = [clip_task(clips[i], method, outputs[i], gravity_scale) for i in group]
            future = client.submit(run_tasks, tasks, pure=False, retries=2)
            index_of[future.key] = group
            futures.append(future)
        counts = {"done": 0, "failed": 0}
        last_save = -MANIFEST_SAVE_INTERVAL  # the first finished clip is recorded at once
        with tqdm(total=len(todo), unit="clip", file=sys.stderr, disable=quiet) as bar:
            for future in as_completed(futures):
                group = index_of[future.key]
                try:
                    done = future.result()
                except (CancelledError, CommClosedError):  # not by us (that is a KeyboardInterrupt): the
                    # scheduler went away; what its workers wrote before is read back from the disk
                    raise SchedulerLost(f"the Dask scheduler at {scheduler or 'the local cluster'} was lost") from None
                except Exception as e:  # the task itself failed: a worker died more often than retries
                    failed = {"status": "failed", "error": f"{type(e).__name__}: {e}".splitlines()[0], "seconds": None}
                    done = [failed] * len(group)
                for i, result in zip(group, done):
                    results[i] = result
                    if result["status"] == "done":
                        manifest.record(clips[i], digests[i], result["seconds"])
                    else:
                        manifest.forget(clips[i])
                    counts[result["status"]] += 1
                bar.set_postfix(counts, refresh=False)
                bar.update(len(group))
                if time.monotonic() - last_save >= MANIFEST_SAVE_INTERVAL:
                    manifest.save()
                    last_save = time.monotonic()
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel([f for f in futures if not f.done()])
        raise
