"""The editor as users run it (uvicorn on the main thread, with its signal handlers) under
concurrent physics sessions: every session answers, and Ctrl-C stops it within seconds, solves
included. Before the fix, 16 sessions switching to physics at once got 1 to 5 answers, then the
editor hung for good (a fork from a solver thread inherited uvicorn's SIGTERM handler)."""
from __future__ import annotations

import concurrent.futures
import signal
import time

from _editor_support import require
from test_editor_cli import read_url, start

require("fastapi", "pip install 'retime[editor]'")
httpx = require("httpx", "pip install 'retime[test]'")

from retime.data import bundled_path  # noqa: E402


def _physics_session(url, gravity):
    with httpx.Client(base_url=url, timeout=240) as client:
        sid = client.post("/api/session", json={}).json()["session"]
        r = client.post(f"/api/session/{sid}/edit", json={"ops": [
            {"op": "params", "method": "physics", "values": {"gravity": gravity}},
            {"op": "method", "method": "physics"}]})
        return r.status_code, r.json()


def test_concurrent_physics_sessions_all_answer_and_ctrl_c_stops(tmp_path):
    clip = bundled_path("16_33.amc")  # the shortest bundled clip: 285 frames
    proc = start(["edit", str(clip), "--no-browser", "-o", str(tmp_path)], tmp_path)
    try:
        url, _, _ = read_url(proc)
        gravities = [9.81 * (0.5 + 0.07 * k) for k in range(16)]  # each its own regions
        with concurrent.futures.ThreadPoolExecutor(len(gravities)) as pool:
            answers = list(pool.map(lambda g: _physics_session(url, g), gravities, timeout=600))
        assert [code for code, _ in answers] == [200] * len(gravities), answers
        assert all(body["method"] == "physics" for _, body in answers), [b.get("method") for _, b in answers]
        # solves in flight when Ctrl-C comes: the regions of new settings
        pool = concurrent.futures.ThreadPoolExecutor(4)
        pending = [pool.submit(_physics_session, url, g) for g in (2.1, 3.3, 4.7, 5.9)]
        time.sleep(0.5)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=15)
        assert time.monotonic() - t0 < 10
        assert proc.returncode == 0
        for f in pending:
            try:
                f.result(timeout=10)
            except (httpx.HTTPError, ValueError):  # cut off by the stop
                pass
        pool.shutdown()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
