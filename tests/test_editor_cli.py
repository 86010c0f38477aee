"""`retime edit`: loopback only, a free port, prints the URL, clean stop on Ctrl-C, readable errors."""
from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from _editor_support import require  # noqa: E402

require("fastapi", "pip install 'retime[editor]'")
require("uvicorn", "pip install 'retime[editor]'")
httpx = require("httpx", "pip install 'retime[test]'")

from retime.data import bundled_path  # noqa: E402

CLI = [sys.executable, "-c", "import sys; from retime.cli import main; sys.exit(main())"]


def start(args, cwd):
    return subprocess.Popen(CLI + args, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "BROWSER")})


def read_url(proc, timeout=30):
    deadline = time.monotonic() + timeout
    lines = []
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        m = re.search(r"(http://127\.0\.0\.1:(\d+)/)", line)
        if m:
            return m.group(1), int(m.group(2)), lines
    proc.kill()
    raise AssertionError(f"no URL printed: {lines} {proc.stderr.read()}")


def listening_addresses(port):
    """Local addresses of sockets listening on ``port`` (Linux /proc), or None if unknown."""
    found = []
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            rows = Path(name).read_text().splitlines()[1:]
        except OSError:
            return None
        for row in rows:
            f = row.split()
            addr, p = f[1].split(":")
            if int(p, 16) == port and f[3] == "0A":  # LISTEN
                found.append(addr)
    return found


def test_edit_serves_on_loopback_and_stops_on_ctrl_c(tmp_path):
    out = tmp_path / "edits"
    proc = start(["edit", str(bundled_path("16_06.amc")), "-o", str(out)], tmp_path)  # no display: no browser
    try:
        url, port, lines = read_url(proc)
        assert "no display" in proc.stdout.readline() + proc.stdout.readline()
        assert out.is_dir()  # created
        r = httpx.get(url, timeout=10)
        assert r.status_code == 200 and "retime edit" in r.text
        s = httpx.post(url + "api/session", json={}, timeout=10).json()
        assert s["clip"]["name"] == "16_06"
        addrs = listening_addresses(port)
        if addrs is not None:
            assert addrs == ["0100007F"], addrs  # 127.0.0.1 only, no 0.0.0.0 and no IPv6 wildcard
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=15)
        assert code == 0
        assert "stopped" in proc.stderr.read()
        with pytest.raises(OSError):
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
    finally:
        if proc.poll() is None:
            proc.kill()


def test_edit_takes_a_given_port_and_refuses_a_busy_one(tmp_path):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        r = subprocess.run(CLI + ["edit", str(bundled_path("16_06.amc")), "--no-browser", "--port", str(port),
                                  "-o", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert f"127.0.0.1:{port}" in r.stderr and "Traceback" not in r.stderr


def test_edit_bad_input_is_one_line(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT x\n{\n")
    r = subprocess.run(CLI + ["edit", str(bad), "--no-browser", "-o", str(tmp_path)], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert str(bad) in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = subprocess.run(CLI + ["edit", str(bundled_path("16_06.amc")), "--reference", str(bundled_path("131_01.bvh")),
                              "--no-browser", "-o", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "skeleton differs" in r.stderr
    r = subprocess.run(CLI + ["edit", "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "retime edit 16_06.amc" in r.stdout and "127.0.0.1" in r.stdout
