"""No input is ever overwritten, and a command writes all its outputs or none (issue 12: 2 and 3)."""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from retime.cli import main
from retime.data import bundled_path
from retime.io_util import all_or_none, atomic_write


@pytest.fixture()
def amc(tmp_path):
    """16_06.amc with its 16.asf beside it, found automatically."""
    for name in ("16_06.amc", "16.asf"):
        shutil.copy(bundled_path(name), tmp_path / name)
    return tmp_path / "16_06.amc"


def _run(args, capsys):
    code = main([str(a) for a in args])
    err = capsys.readouterr().err
    return code, err


def _snapshot(folder):
    return {p.name: p.read_bytes() for p in Path(folder).iterdir() if p.is_file()}


@pytest.mark.parametrize("extra", [["--report", "{asf}"], ["--write-body", "{asf}"]])
def test_the_skeleton_found_beside_an_amc_is_never_an_output(amc, tmp_path, capsys, extra):
    before = _snapshot(tmp_path)
    args = ["physics", amc, "-o", tmp_path / "o.bvh"] + [e.format(asf=tmp_path / "16.asf") for e in extra]
    code, err = _run(args, capsys)
    assert code == 2 and "refusing to overwrite the input file" in err and "16.asf" in err
    assert _snapshot(tmp_path) == before  # nothing changed, nothing added


def test_an_input_given_as_output_is_refused(amc, tmp_path, capsys):
    contacts = tmp_path / "c.csv"
    contacts.write_text("point,first,last\nboth,0,406\n")
    before = _snapshot(tmp_path)
    code, err = _run(["physics", amc, "-o", tmp_path / "o.bvh", "--contacts", contacts, "--warp", contacts], capsys)
    assert code == 2 and "refusing to overwrite the input file" in err
    code, err = _run(["physics", amc, "-o", tmp_path / "o.bvh", "--warp", tmp_path / "w.csv",
                      "--report", tmp_path / "w.csv"], capsys)
    assert code == 2 and "two outputs" in err
    os.link(amc, tmp_path / "hard.bvh")  # a hard link to the input is the input
    code, err = _run(["linear", amc, "-o", tmp_path / "hard.bvh", "--scale", "0.5"], capsys)
    assert code == 2 and "refusing to overwrite" in err
    assert _snapshot(tmp_path) == dict(before, **{"hard.bvh": amc.read_bytes()})


def test_special_files_are_never_replaced(amc, tmp_path, capsys):
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    code, err = _run(["linear", amc, "-o", tmp_path / "o.bvh", "--scale", "0.5", "--warp", fifo], capsys)
    assert code == 2 and "not a regular file" in err
    assert Path(fifo).exists() and not Path(fifo).is_file() and not (tmp_path / "o.bvh").exists()


def test_a_missing_output_folder_is_found_before_any_work(amc, tmp_path, capsys, monkeypatch):
    import retime.physics.api as physics_api

    monkeypatch.setattr(physics_api, "physics_warp", lambda *a, **k: pytest.fail("solved before checking the outputs"))
    code, err = _run(["physics", amc, "-o", tmp_path / "o.bvh", "--report", tmp_path / "missing" / "r.json"], capsys)
    assert code == 2 and "does not exist" in err
    code, err = _run(["linear", amc, "-o", tmp_path / "x.bvh", "--scale", "0.5", "--warp",
                      tmp_path / "missing" / "w.csv"], capsys)
    assert code == 2 and not (tmp_path / "x.bvh").exists()


def test_outputs_commit_together_or_not_at_all(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    with pytest.raises(KeyboardInterrupt):
        with all_or_none():
            with atomic_write(a) as f:
                f.write("first")
            raise KeyboardInterrupt  # Ctrl-C between the two files
    assert list(tmp_path.iterdir()) == []
    with all_or_none():
        with atomic_write(a) as f:
            f.write("first")
        assert not a.exists()  # staged, not yet visible
        with atomic_write(b) as f:
            f.write("second")
    assert a.read_text() == "first" and b.read_text() == "second"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt"]  # no temporary file left


# The signal comes from inside the regions' solve, so the test does not depend on how fast the machine is (a
# sleep-then-signal test failed on a faster CI machine, whose solve had already finished). It is sent once,
# by the first chunk to start: in a forked worker (2 cores: the pool's terminate() must end it) or in the
# command's own process (1 core).
_SIGTERM_IN_SOLVE = """
import os, signal, sys
from retime.physics import regions
from retime.cli import main
solve_chunk = regions.RegionJob.solve
def sigterm_once_then_solve(job, *args, **kwargs):
    try:
        os.close(os.open(os.environ["SIGTERM_MARKER"], os.O_CREAT | os.O_EXCL))
    except FileExistsError:
        pass
    else:
        os.kill(os.getppid() if regions._WORKER_JOB is not None else os.getpid(), signal.SIGTERM)
    return solve_chunk(job, *args, **kwargs)
regions.RegionJob.solve = sigterm_once_then_solve
sys.exit(main())
"""


def test_sigterm_leaves_no_output_and_no_temporary_file(amc, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.run([sys.executable, "-c", _SIGTERM_IN_SOLVE, "physics", str(amc), "-o", str(out / "o.bvh"),
                           "--warp", str(out / "w.csv"), "--report", str(out / "r.json")],
                          capture_output=True, text=True, timeout=300,
                          env=dict(os.environ, SIGTERM_MARKER=str(tmp_path / "signalled")))
    assert (tmp_path / "signalled").exists()  # the signal came from inside the solve
    assert proc.returncode == 143, proc.stderr
    assert "terminated" in proc.stderr and "Traceback" not in proc.stderr
    assert list(out.iterdir()) == []  # no output, no temporary file
