"""Mutation fuzzing of every command over every file kind it reads (issue 12: 7), and of batch layouts
and jobs files (issue 22). Each run must end with exit 0, or exit 2 and one line on stderr; never a
traceback, never an output left behind after a failure, never a changed input. Seeded (failures
reproduce) and bounded in time."""
from __future__ import annotations

import io
import time
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import numpy as np
import pytest

from _foundation_ref import mutate
from retime.cli import main
from retime.data import bundled_path
from retime.motion import load_motion, save_bvh

BUDGET_S = 6.0  # seconds per kind of file (at most 400 cases each; the suite keeps to ~10 minutes)


def _cut_bvh(frames=12):
    m = load_motion(bundled_path("16_15.bvh")).frames(slice(0, frames))
    buf = Path("/dev/shm" if Path("/dev/shm").is_dir() else "/tmp") / f"retime-fuzz-{frames}.bvh"
    save_bvh(m, buf)
    text = buf.read_text()
    buf.unlink()
    return text


@pytest.fixture(scope="module")
def seeds(tmp_path_factory):
    root = tmp_path_factory.mktemp("seeds")
    bvh = root / "a.bvh"
    bvh.write_text(_cut_bvh())
    warp = root / "w.csv"
    report = root / "r.json"
    assert main(["physics", str(bvh), "-o", str(root / "p.bvh"), "--scale", "0.8", "--warp", str(warp),
                 "--report", str(report), "--quiet"]) == 0
    npy = root / "s.npy"
    np.save(npy, np.random.default_rng(0).normal(size=(12, 3)))
    sig = root / "s.csv"
    sig.write_text("time,x\n" + "\n".join(f"{k / 120:.6f},{np.sin(k):.4f}" for k in range(12)) + "\n")
    contacts = root / "c.csv"
    contacts.write_text("point,first,last\nleft,0,11\nright_toe,2,9\n")
    amc_lines = bundled_path("16_15.amc").read_text().splitlines()
    amc = root / "16_15.amc"
    amc.write_text("\n".join(amc_lines[: amc_lines.index("9")]) + "\n")
    (root / "16.asf").write_text(bundled_path("16.asf").read_text())
    return {"bvh": bvh, "warp": warp, "report": report, "npy": npy, "signal": sig, "contacts": contacts,
            "amc": amc, "asf": root / "16.asf"}


# kind -> (the seed the mutation replaces, command lines: {in} the mutated file, {s:NAME} another seed, {out} a folder)
CASES = {
    "bvh": ("bvh", [["info", "{in}"], ["convert", "{in}", "{out}/c.bvh"],
                    ["linear", "{in}", "-o", "{out}/l.bvh", "--scale", "0.5", "--warp", "{out}/l.csv"],
                    ["guided", "{in}", "-o", "{out}/g.bvh", "--scale", "0.7", "--fast", "--quiet"]]),
    "amc": ("amc", [["info", "{in}"], ["linear", "{in}", "-o", "{out}/l.bvh", "--scale", "0.5"]]),
    "asf": ("asf", [["info", "{s:amc}", "--asf", "{in}"], ["convert", "{s:amc}", "{out}/c.bvh", "--asf", "{in}"]]),
    "warp": ("warp", [["apply", "{in}", "{s:signal}", "-o", "{out}/o.csv"], ["plot", "{in}", "-o", "{out}/p.png"]]),
    "report": ("report", [["plot", "--regions", "{in}", "-o", "{out}/r.png"]]),
    "npy": ("npy", [["apply", "{s:warp}", "{in}", "-o", "{out}/o.npy", "--fit"]]),
    "contacts": ("contacts", [["physics", "{s:bvh}", "-o", "{out}/p.bvh", "--contacts", "{in}", "--scale", "0.8",
                               "--quiet"]]),
}


def _mutated_bytes(kind, data: bytes, rng) -> bytes:
    if kind == "npy":  # binary: flip, cut or insert bytes
        b = bytearray(data)
        for _ in range(int(rng.integers(1, 4))):
            op = int(rng.integers(0, 3))
            i = int(rng.integers(0, len(b))) if b else 0
            if op == 0:
                b = b[:i]
            elif op == 1 and b:
                b[i] = int(rng.integers(0, 256))
            else:
                b[i:i] = bytes(rng.integers(0, 256, size=int(rng.integers(1, 8))).tolist())
        return bytes(b)
    return mutate(data.decode("utf-8", "replace"), rng).encode("utf-8", "replace")


def _run(argv):
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse
            code = e.code
    return code, err.getvalue()


@pytest.mark.parametrize("kind", list(CASES))
def test_mutated_inputs_fail_cleanly(kind, seeds, tmp_path):
    seed_name, commands = CASES[kind]
    original = seeds[seed_name].read_bytes()
    rng = np.random.default_rng(sum(map(ord, kind)))
    deadline = time.monotonic() + BUDGET_S
    runs = 0
    while time.monotonic() < deadline and runs < 400:
        work = tmp_path / f"case{runs}"
        work.mkdir()
        mutated = work / seeds[seed_name].name
        data = _mutated_bytes(kind, original, rng)
        mutated.write_bytes(data)
        if kind == "amc":
            (work / "16.asf").write_bytes(seeds["asf"].read_bytes())
        out = work / "out"
        out.mkdir()
        for cmd in commands:
            argv = [a.replace("{in}", str(mutated)).replace("{out}", str(out)) for a in cmd]
            argv = [str(seeds[a[3:-1]]) if a.startswith("{s:") else a for a in argv]
            code, err = _run(argv)
            what = f"{kind} case {runs}: retime {' '.join(argv)}"
            assert code in (0, 2), (what, code, err)
            assert "Traceback" not in err, (what, err)
            if code == 2:
                assert len([ln for ln in err.splitlines() if ln.strip()]) == 1, (what, err)
                assert list(out.iterdir()) == [], (what, sorted(p.name for p in out.iterdir()))
            assert mutated.read_bytes() == data, what  # the input is never changed
            for p in list(out.iterdir()):
                p.unlink()
        runs += 1
    assert runs >= 5


# ------------------------------------------------------------------ batch: jobs files and layouts (issue 22)
# Clips run in this process (run_task, as a worker runs them) instead of on a Dask cluster, so that a few
# hundred layouts fit the budget; the cluster, its signals and its failures are tests/test_batch*.py's.
BATCH_BUDGET_S = 10.0
NAMES = ["a.bvh", "b.bvh", "summary.bvh", ".retime-batch.bvh", "index.bvh", "jobs.bvh", "x.bvh"]


@pytest.fixture
def inline_batch(monkeypatch):
    import retime.batch.run as batch_run

    def compute(client, clips, outputs, digests, todo, results, manifest, method, gravity_scale, *_):
        for i in todo:
            results[i] = batch_run.run_task(batch_run.clip_task(clips[i], method, outputs[i], gravity_scale))
            if results[i]["status"] == "done":
                manifest.record(clips[i], digests[i], 0.0)
            else:
                manifest.forget(clips[i])

    monkeypatch.setattr(batch_run, "_connect", lambda scheduler, workers: (None, None))
    monkeypatch.setattr(batch_run, "_compute", compute)


def _layout(root: Path, rng, bvh_text: str) -> tuple[list[str], Path, list[Path]]:
    """A random tree of clips (subfolders, names like the batch's files, X.amc beside X.bvh, symlinks to
    inputs, dangling and looping ones, jobs files naming clips and references), an OUTDIR inside, equal
    to or above the inputs, or apart; returns (the batch's inputs, OUTDIR, the files it must not change)."""
    inp = root / "in"
    (inp / "sub").mkdir(parents=True)
    files = []
    for name in rng.choice(NAMES, size=int(rng.integers(1, 5)), replace=False):
        folder = inp / "sub" if rng.random() < 0.3 else inp
        (folder / name).write_text(bvh_text)
        files.append(folder / name)
    if rng.random() < 0.4:  # X.amc beside X.bvh
        (inp / "16.asf").write_text(bundled_path("16.asf").read_text())
        amc = bundled_path("16_15.amc").read_text().splitlines()
        (inp / "x.amc").write_text("\n".join(amc[: amc.index("9")]) + "\n")
        files += [inp / "16.asf", inp / "x.amc"]
    kind = int(rng.integers(0, 3))
    if kind == 0 and rng.random() < 0.5:  # symlinks among the inputs
        (inp / "link.bvh").symlink_to(files[0])
        (inp / "dangling.bvh").symlink_to(inp / "gone.bvh")
    if kind == 1:  # a jobs file beside the clips, a reference among them
        motions = [f for f in files if f.suffix in (".bvh", ".amc")]
        rows = ["motion,scale,reference"]
        for f in motions[: int(rng.integers(1, len(motions) + 1))]:
            ref = motions[int(rng.integers(0, len(motions)))].relative_to(inp) if rng.random() < 0.3 else ""
            rows.append(f"{f.relative_to(inp)},{rng.choice(['0.5', '2', ''])},{ref}")
        jobs = inp / rng.choice(["jobs.csv", "summary.csv"])
        jobs.write_text("\n".join(rows) + "\n")
        files.append(jobs)
        inputs = [str(jobs)]
    else:
        inputs = [str(inp)] if rng.random() < 0.6 else [str(f) for f in files if f.suffix in (".bvh", ".amc")]
    outdir = [root / "out", inp, inp / "out", root, inp / "sub"][int(rng.integers(0, 5))]
    return inputs, outdir, files


def test_batch_layouts_and_jobs_files_never_lose_data(tmp_path, inline_batch):
    """Whatever the layout (OUTDIR inside, equal to or above the inputs; colliding names; a mutated
    jobs file): exit 0, 1 or 2 with one line; no input, reference or jobs file changed; after a refusal
    no batch file written; after a run, a summary with one row per clip and every 'done' clip's outputs."""
    import csv

    from retime.batch.jobs import Defaults, find_clips

    bvh_text = _cut_bvh()
    rng = np.random.default_rng(22)
    codes: dict[int, int] = {}
    deadline = time.monotonic() + BATCH_BUDGET_S
    runs = 0
    while time.monotonic() < deadline and runs < 300:
        root = tmp_path / f"case{runs}"
        inputs, outdir, files = _layout(root, rng, bvh_text)
        jobs = [Path(i) for i in inputs if i.endswith(".csv")]
        if jobs and rng.random() < 0.5:
            jobs[0].write_text(mutate(jobs[0].read_text(), rng))
        before = {f: f.read_bytes() for f in files}
        argv = ["batch", *inputs, "-o", str(outdir), "--method", "linear", "--scale", "0.5", "--quiet"]
        code, err = _run(argv)
        what = f"case {runs}: retime {' '.join(argv)}\n" + "\n".join(
            f"  {p.relative_to(root)}" for p in sorted(root.rglob("*")))
        assert code in (0, 1, 2), (what, code, err)
        assert "Traceback" not in err, (what, err)
        for f, data in before.items():
            assert f.read_bytes() == data, (what, f"{f} changed")
        summary = outdir / "summary.csv"
        if code == 2:
            assert len([ln for ln in err.splitlines() if ln.strip()]) == 1, (what, err)
            assert summary not in before and not summary.exists() or summary in before, what
        else:
            with open(summary, newline="", encoding="utf-8") as f:
                table = list(csv.DictReader(f))
            skipped = []
            clips = find_clips(inputs, Defaults(scale=0.5), outdir=outdir, skipped=skipped)
            assert len(table) == len(clips) + len(skipped), what  # rows: the clips in order, then the skipped
            for row, clip in zip(table, clips):
                assert row["status"] in ("done", "failed"), (what, row)
                outputs = clip.outputs(outdir, "linear").values()
                assert row["status"] != "done" or all(p.is_file() for p in outputs), (what, row)
            assert (code == 1) == any(r["status"] == "failed" for r in table), what
        codes[code] = codes.get(code, 0) + 1
        runs += 1
    print(f"batch fuzz: {runs} layouts, exit codes {codes}")
    assert runs >= 10 and len(codes) >= 2, codes  # both refusals and runs were tried
