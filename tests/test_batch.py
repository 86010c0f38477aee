"""retime batch: clips on Dask distributed through the single-clip commands.

Most tests use the linear method (fast); guided and physics run on one or two 60-frame clips."""
from __future__ import annotations

import csv
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from retime.batch.jobs import Defaults, find_clips
from retime.errors import RetimeError
from retime.cli import main

RETIME = "import sys; from retime.cli import main; sys.exit(main(sys.argv[1:]))"  # the CLI in a subprocess
DATA = Path(__file__).resolve().parents[1] / "src" / "retime" / "data" / "cmu"


def exit_code(argv) -> int:
    """main()'s exit code; argparse's usage errors leave by SystemExit."""
    try:
        return main(argv)
    except SystemExit as e:
        return e.code


def rows(outdir: Path) -> dict[str, dict]:
    with open(outdir / "summary.csv", newline="", encoding="utf-8") as f:
        return {Path(r["input"]).name: r for r in csv.DictReader(f)}


@pytest.fixture(scope="module")
def short_bvh(tmp_path_factory) -> Path:
    """16_15.bvh cut to 60 frames: half a second of motion, quick for every method."""
    from retime.motion import load_motion, save_bvh

    path = tmp_path_factory.mktemp("clip") / "short.bvh"
    save_bvh(load_motion(DATA / "16_15.bvh").frames(slice(0, 60)), path)
    return path


@pytest.fixture
def good_folder(tmp_path, short_bvh) -> Path:
    folder = tmp_path / "in"
    (folder / "cmu").mkdir(parents=True)
    shutil.copy(short_bvh, folder / "short.bvh")
    shutil.copy(DATA / "16_33.amc", folder / "cmu" / "16_33.amc")
    shutil.copy(DATA / "16.asf", folder / "cmu" / "16.asf")
    return folder


# ------------------------------------------------------------------------- finding clips (no Dask)
def test_folders_mirror_and_jobs_files_override(tmp_path, good_folder, short_bvh):
    (good_folder / "cmu" / "notes.txt").write_text("not a motion")
    jobs = tmp_path / "jobs.toml"
    jobs.write_text('[[clip]]\nmotion = "in/short.bvh"\nduration = 0.3\nkeytimes = "0.2=0.1;0.4=0.25"\n'
                    '[[clip]]\nmotion = "in/cmu/16_33.amc"\n')
    clips = find_clips([str(good_folder)], Defaults(scale=0.5), outdir=good_folder / "out")
    (good_folder / "out").mkdir()
    shutil.copy(good_folder / "short.bvh", good_folder / "out" / "short.bvh")  # last run's output: not an input
    assert find_clips([str(good_folder)], Defaults(scale=0.5), outdir=good_folder / "out") == clips
    assert len(find_clips([str(good_folder)], Defaults(), outdir=tmp_path)) == 3  # OUTDIR above: all walked
    assert [str(c.name) for c in clips] == ["cmu/16_33", "short"]
    assert all(c.scale == 0.5 for c in clips)
    first, second = find_clips([str(jobs)], Defaults(scale=0.5))
    assert (first.duration, first.scale, first.keytimes) == (0.3, None, ((0.2, 0.1), (0.4, 0.25)))
    assert str(first.name) == "in/short" and second.scale == 0.5
    shutil.copy(short_bvh, good_folder / "cmu" / "16_33.bvh")  # X.bvh beside X.amc: both kept, named apart
    assert [str(c.name) for c in find_clips([str(good_folder / "cmu")], Defaults())] == ["16_33.amc", "16_33.bvh"]
    with pytest.raises(RetimeError, match="would both write short.bvh"):
        find_clips([str(short_bvh), str(good_folder / "short.bvh")], Defaults())
    table = tmp_path / "jobs.csv"
    table.write_text("motion,scale,keytimes\nin/short.bvh,0.7,\nin/cmu/16_33.amc,,1=0.9\n")
    a, b = find_clips([str(table)], Defaults(duration=1.0))
    assert (a.scale, a.duration) == (0.7, None) and (b.duration, b.keytimes) == (1.0, ((1.0, 0.9),))


@pytest.mark.parametrize("argv, message", [
    (["batch", "{empty}", "-o", "{out}", "--method", "linear", "--scale", "2"], "no clips found"),
    (["batch", "{empty}", "-o", "{out}", "--method", "fast", "--scale", "2"], "invalid choice"),
    (["batch", "{jobs}", "-o", "{out}", "--method", "linear"], "line 2: scale 'x' is not a number"),
    (["batch", "{empty}/none.bvh", "-o", "{out}", "--method", "linear"], "no such file or folder"),
    (["batch", "{good}", "-o", "{out}", "--method", "linear", "--reference", "{good}/short.bvh"], "guided"),
    (["batch", "{good}", "-o", "{out}", "--method", "linear"], "say how to retime"),
    (["batch", "{good}", "-o", "{good}", "--method", "linear", "--scale", "2"], "is also the output folder"),
])
def test_bad_arguments_are_one_line_and_exit_2(tmp_path, good_folder, capsys, argv, message):
    (tmp_path / "empty").mkdir()
    (tmp_path / "jobs.csv").write_text("motion,scale\nin/short.bvh,x\n")
    names = {"empty": tmp_path / "empty", "out": tmp_path / "out", "jobs": tmp_path / "jobs.csv", "good": good_folder}
    assert exit_code([a.format(**names) for a in argv]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------------- on a local cluster
def test_mixed_folder_good_clips_done_bad_ones_named(tmp_path, good_folder, short_bvh, capsys):
    distributed = pytest.importorskip("distributed")  # noqa: F841
    (good_folder / "bad.bvh").write_text("this is not a motion file\n")
    text = short_bvh.read_bytes()
    (good_folder / "cmu" / "truncated.bvh").write_bytes(text[: len(text) // 3])
    out = tmp_path / "out"
    code = main(["batch", str(good_folder), "-o", str(out), "--method", "linear", "--scale", "0.5",
                 "--workers", "2", "--quiet"])
    assert code == 1
    assert capsys.readouterr().err.strip() == f"2 of 4 clips failed (see {out / 'summary.csv'})"
    table = rows(out)
    assert {n: r["status"] for n, r in table.items()} == {
        "short.bvh": "done", "16_33.amc": "done", "bad.bvh": "failed", "truncated.bvh": "failed"}
    assert table["bad.bvh"]["error"].startswith("retime linear: error: ") and "bad.bvh" in table["bad.bvh"]["error"]
    assert "truncated" in table["truncated.bvh"]["error"]
    assert float(table["16_33.amc"]["output_duration"]) == pytest.approx(float(table["16_33.amc"]["source_duration"]) / 2, abs=0.01)
    for name in ("short.bvh", "short.csv", "cmu/16_33.bvh", "cmu/16_33.csv", "index.html", ".retime-batch.json"):
        assert (out / name).is_file(), name
    assert not (out / "bad.bvh").exists() and not list(out.rglob("*.tmp"))
    page = (out / "index.html").read_text()
    assert page.count("<polyline") == 2 and "<script>" in page and "src=" not in page

    # the same clip through the single-clip command: the same bytes
    single = tmp_path / "single"
    single.mkdir()
    assert main(["linear", str(good_folder / "cmu" / "16_33.amc"), "-o", str(single / "a.bvh"),
                 "--warp", str(single / "a.csv"), "--scale", "0.5"]) == 0
    assert (single / "a.bvh").read_bytes() == (out / "cmu" / "16_33.bvh").read_bytes()
    assert (single / "a.csv").read_bytes() == (out / "cmu" / "16_33.csv").read_bytes()


def test_resume_skips_finished_clips_and_force_recomputes(tmp_path, good_folder, monkeypatch):
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    argv = ["batch", str(good_folder), "-o", str(out), "--method", "linear", "--duration", "0.4", "--quiet"]
    assert main(argv + ["--workers", "2"]) == 0
    assert {r["status"] for r in rows(out).values()} == {"done"}
    stamp = (out / "short.bvh").stat().st_mtime_ns

    import retime.batch.run as batch_run

    with monkeypatch.context() as m:
        m.setattr(batch_run, "_connect", lambda *a: pytest.fail("a cluster was started with nothing to run"))
        assert main(argv) == 0  # nothing to run: no cluster either
    assert {r["status"] for r in rows(out).values()} == {"skipped"}
    assert rows(out)["short.bvh"]["output_duration"] == "0.4"
    assert (out / "short.bvh").stat().st_mtime_ns == stamp

    (good_folder / "short.bvh").write_bytes((good_folder / "short.bvh").read_bytes() + b"\n")  # an edited input
    (out / "cmu" / "16_33.csv").unlink()  # a lost output
    assert main(argv + ["--workers", "2"]) == 0
    assert {n: r["status"] for n, r in rows(out).items()} == {"short.bvh": "done", "16_33.amc": "done"}
    assert main(argv) == 0 and {r["status"] for r in rows(out).values()} == {"skipped"}
    assert main(argv + ["--workers", "2", "--force"]) == 0
    assert {r["status"] for r in rows(out).values()} == {"done"}


def test_guided_jobs_file_matches_the_single_clip_command(tmp_path, short_bvh):
    pytest.importorskip("distributed")
    shutil.copy(short_bvh, tmp_path / "a.bvh")
    shutil.copy(short_bvh, tmp_path / "b.bvh")
    jobs = tmp_path / "jobs.csv"
    jobs.write_text("motion,duration,scale,keytimes,reference\na.bvh,0.3,,,\nb.bvh,,0.7,0.2=0.2,a.bvh\n")
    out = tmp_path / "out"
    assert main(["batch", str(jobs), "-o", str(out), "--method", "guided", "--workers", "2", "--quiet"]) == 0
    single = tmp_path / "single"
    single.mkdir()
    for name, extra in (("a", ["--duration", "0.3"]), ("b", ["--scale", "0.7", "--keytime", "0.2=0.2",
                                                             "--reference", str(tmp_path / "a.bvh")])):
        assert main(["guided", str(tmp_path / f"{name}.bvh"), "-o", str(single / f"{name}.bvh"),
                     "--warp", str(single / f"{name}.csv"), "--quiet"] + extra) == 0
        for suffix in (".bvh", ".csv"):
            assert (single / f"{name}{suffix}").read_bytes() == (out / f"{name}{suffix}").read_bytes()


# ------------------------------------------------------------------------ a real scheduler and workers
def copies(clip: Path, folder: Path, n: int) -> Path:
    """A folder of n copies of a clip: enough work to interrupt a batch in its middle."""
    folder.mkdir()
    for i in range(n):
        shutil.copy(clip, folder / f"clip{i:02d}.bvh")
    return folder


def _wait_for(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


@pytest.fixture
def scheduler(tmp_path):
    """A `dask scheduler` and two `dask worker` processes (one thread each, no nanny: a killed
    worker stays dead) on loopback; yields (address, worker processes); all terminated after."""
    pytest.importorskip("distributed")
    file = tmp_path / "scheduler.json"
    logs = open(tmp_path / "dask.log", "wb")
    env = {**os.environ, "DASK_DISTRIBUTED__WORKER__DAEMON": "False"}
    processes = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                   "--port", "0", "--dashboard-address", ":0", "--scheduler-file", str(file)],
                                  stdout=logs, stderr=logs, env=env)]
    try:
        _wait_for(file.exists, 30, "the scheduler file")
        address = json.loads(file.read_text())["address"]
        workers = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(file),
                                     "--nthreads", "1", "--no-nanny", "--host", "127.0.0.1", "--dashboard-address", ":0"],
                                    stdout=logs, stderr=logs, env=env) for _ in range(2)]
        processes += workers
        from distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=30)
        yield address, workers
    finally:
        for p in reversed(processes):
            p.terminate()
        for p in processes:
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        logs.close()


def test_batch_on_a_running_scheduler_with_physics(tmp_path, good_folder, short_bvh, scheduler):
    address, _ = scheduler
    out = tmp_path / "out"
    code = main(["batch", str(good_folder / "short.bvh"), "-o", str(out), "--method", "physics", "--scale", "0.8",
                 "--scheduler", address, "--quiet"])
    assert code == 0
    row = rows(out)["short.bvh"]
    report = json.loads((out / "short.json").read_text())["summary"]
    assert row["status"] == "done" and float(row["feasible_fraction"]) == pytest.approx(report["feasible_fraction"])
    assert row["source_physical"] == str(report["source_check"]["physical"]).lower()
    assert float(row["least_duration"]) == pytest.approx(report["least_duration"], rel=1e-5)
    single = tmp_path / "single"
    single.mkdir()
    assert main(["physics", str(good_folder / "short.bvh"), "-o", str(single / "s.bvh"), "--warp",
                 str(single / "s.csv"), "--report", str(single / "s.json"), "--scale", "0.8", "--quiet"]) == 0
    assert (single / "s.bvh").read_bytes() == (out / "short.bvh").read_bytes()
    assert (single / "s.csv").read_bytes() == (out / "short.csv").read_bytes()
    assert json.loads((single / "s.json").read_text())["frames"] == json.loads((out / "short.json").read_text())["frames"]
    # the README: the report is the single command's but for its run times (its regions included)
    reports = [json.loads(path.read_text()) for path in (single / "s.json", out / "short.json")]
    for report in reports:
        del report["summary"]["timings"], report["summary"]["optimizer"]["seconds"]
    assert reports[0] == reports[1] and reports[0]["regions"]


def test_a_worker_killed_mid_batch_costs_only_its_task(tmp_path, short_bvh, scheduler):
    address, workers = scheduler
    n = 16
    folder = copies(short_bvh, tmp_path / "in", n)
    out = tmp_path / "out"
    batch = subprocess.Popen([sys.executable, "-c", RETIME, "batch", str(folder), "-o", str(out), "--method",
                              "guided", "--scale", "0.6", "--scheduler", address, "--quiet"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _wait_for(lambda: batch.poll() is not None or any(out.glob("clip*.csv")), 60, "the first finished clip")
        finished_before_kill = len(list(out.glob("clip*.csv")))
        os.kill(workers[0].pid, signal.SIGKILL)
        stdout, stderr = batch.communicate(timeout=120)
    finally:
        if batch.poll() is None:
            batch.kill()
    assert finished_before_kill < n, "every clip finished before the kill: the test proved nothing"
    assert batch.returncode == 0, stderr.decode()
    assert {r["status"] for r in rows(out).values()} == {"done"} and len(rows(out)) == n
    assert len(list(out.glob("clip*.bvh"))) == n


def test_ctrl_c_keeps_finished_clips_and_exits_130(tmp_path, short_bvh):
    pytest.importorskip("distributed")
    n = 120  # enough that a loaded machine is still busy when the Ctrl-C comes
    folder = copies(short_bvh, tmp_path / "in", n)
    out = tmp_path / "out"
    argv = [sys.executable, "-c", RETIME, "batch", str(folder), "-o", str(out), "--method", "guided", "--scale", "0.6",
            "--workers", "2", "--quiet"]
    batch = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        manifest = out / ".retime-batch.json"  # first saved once a clip has finished
        _wait_for(lambda: batch.poll() is not None or manifest.exists(), 60, "the first recorded clip")
        batch.send_signal(signal.SIGINT)
        _, stderr = batch.communicate(timeout=60)
    finally:
        if batch.poll() is None:
            batch.kill()
    assert batch.returncode == 130, stderr.decode()
    assert stderr.decode().strip().splitlines()[-1] == "retime batch: interrupted; finished clips kept (see summary.csv)"
    table = rows(out)
    done = {name for name, r in table.items() if r["status"] == "done"}
    assert len(table) == n and 0 < len(done) < n
    assert {r["error"] for r in table.values() if r["status"] == "failed"} == {"interrupted before it finished"}
    recorded = json.loads((out / ".retime-batch.json").read_text())["clips"]
    assert {f"{name}.bvh" for name in recorded} == done
    # the next run skips what finished and computes the rest
    assert main(argv[3:-1] + ["--quiet"]) == 0
    assert {name for name, r in rows(out).items() if r["status"] == "skipped"} == done


def test_check_batch_ranks_the_library_from_least_to_most_physical(tmp_path):
    pytest.importorskip("distributed")
    from retime.motion import load_motion, save_bvh
    from retime.warp import apply_timing, scale_warp

    folder = tmp_path / "in"
    folder.mkdir()
    jump = load_motion(DATA / "16_06.amc")
    save_bvh(jump, folder / "jump.bvh")
    save_bvh(apply_timing(jump, scale_warp(jump.duration, 0.5, jump.fps)), folder / "fast.bvh")  # twice as fast
    (folder / "broken.bvh").write_text("HIERARCHY\n")
    out = tmp_path / "out"
    code = main(["batch", str(folder), "-o", str(out), "--method", "check", "--workers", "1", "--quiet"])
    assert code == 1  # the broken file; a clip that is not physical is a verdict, not a failure
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        table = list(csv.DictReader(f))
    assert [Path(r["input"]).name for r in table] == ["fast.bvh", "jump.bvh", "broken.bvh"]  # least physical first
    assert [r["source_physical"] for r in table[:2]] == ["false", "true"]
    assert float(table[0]["off_share"]) > float(table[1]["off_share"])
    assert (out / "fast.json").is_file() and (out / "fast.png").is_file() and not (out / "fast.bvh").exists()
    # the page: no column that no clip fills (no curves, durations or flights), a caption about the verdict,
    # and each clip's plot linked with a thumbnail
    page = (out / "index.html").read_text()
    headers = re.findall(r"<th>(.*?)</th>", page)
    assert headers == ["input", "status", "error", "source physical", "off share", "seconds", "plot"]
    assert "least to most physical" in page and "Timing:" not in page and "<svg" not in page
    assert re.findall(r'<a href="([^"]+)"><img src="\1"', page) == ["fast.png", "jump.png"]
    assert exit_code(["batch", str(folder), "-o", str(out), "--method", "check", "--scale", "0.5"]) == 2


def test_tasks_run_longest_first_and_group_only_quick_clips():
    """The scheduler gets the longest clips first (so none starts last on an idle cluster); linear and
    guided clips share tasks up to a byte budget (the batch's bytes over 4 tasks per worker) and
    MAX_GROUP clips; physics and check clips each get their own task."""
    from retime.batch.run import MAX_GROUP, TASKS_PER_WORKER, task_groups

    sizes = {i: s for i, s in enumerate([50, 4000, 120, 900, 30, 30, 2500, 60, 70, 10, 10, 10, 10, 10, 10, 10, 10])}
    todo = list(sizes)
    for workers in (1, 2, 3):
        groups = task_groups(todo, "guided", workers, sizes)
        flat = [i for g in groups for i in g]
        assert sorted(flat) == todo  # every clip once
        assert [sizes[i] for i in flat] == sorted(sizes.values(), reverse=True)  # longest first
        budget = sum(sizes.values()) / (TASKS_PER_WORKER * workers)
        assert all(len(g) == 1 or (sum(sizes[i] for i in g) <= budget and len(g) <= MAX_GROUP) for g in groups)
        assert len(groups) < len(todo)  # the small ones do share
    assert task_groups(todo, "physics", 2, sizes) == [[i] for i in sorted(todo, key=lambda i: (-sizes[i], i))]
    assert task_groups(todo, "check", 2, sizes) == task_groups(todo, "physics", 2, sizes)
