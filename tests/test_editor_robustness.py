"""The editor under malformed messages, concurrent exports and a full disk (issue 12: 3, 4, 5)."""
from __future__ import annotations

import concurrent.futures
import errno
import json

import pytest

from _editor_support import require

require("fastapi", "pip install 'retime[editor]'")
httpx = require("httpx", "pip install 'retime[test]'")
ws_client = require("websockets.sync.client", "pip install websockets")

from retime.data import bundled_path  # noqa: E402
from retime.editor.server import BackgroundServer, create_app, load_clip  # noqa: E402

DEEP = "[" * 30000 + "]" * 30000
STORES = []


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    outdir = tmp_path_factory.mktemp("out")
    app = create_app(load_clip(bundled_path("16_33.amc")), outdir)
    STORES.append(getattr(app, "app", app).state.store)  # the session store behind the loopback guard
    with BackgroundServer(app) as url:
        yield url, outdir


def _session(client):
    return client.post("/api/session", json={}).json()["session"]


def _live(url):
    """A new session's live websocket."""
    with httpx.Client(base_url=url, timeout=20) as client:
        sid = _session(client)
    return ws_client.connect(url.replace("http", "ws") + f"/api/session/{sid}/live",
                             additional_headers={"Origin": url}, max_size=None)


def _final_duration(ws, seq):
    """The duration of the final solution answering edit ``seq``."""
    while True:
        msg = json.loads(ws.recv(timeout=30))
        if msg["type"] == "solution" and msg.get("seq") == seq and msg["final"]:
            return msg["duration"]


@pytest.mark.parametrize("body", [{"ops": [{"op": ["move"]}]}, {"ops": [{"op": "move", "index": "x", "t": 1, "s": 1}]},
                                  {"ops": [{"op": "method", "method": ["linear"]}]}, {"ops": "nope"}])
def test_edits_of_the_wrong_shape_are_400(served, body):
    with httpx.Client(base_url=served[0], timeout=20) as client:
        sid = _session(client)
        r = client.post(f"/api/session/{sid}/edit", json=body)
        assert r.status_code == 400 and "error" in r.json(), r.text


def test_json_nested_thousands_deep_is_400(served):
    with httpx.Client(base_url=served[0], timeout=20) as client:
        sid = _session(client)
        r = client.post(f"/api/session/{sid}/edit", content=DEEP, headers={"content-type": "application/json"})
        assert r.status_code == 400, r.text


def test_the_live_connection_survives_bad_messages(served):
    with _live(served[0]) as ws:
        for bad in (b"\x00\x01binary", DEEP, json.dumps({"seq": 1, "ops": [{"op": ["x"]}]}),
                    json.dumps({"seq": 2, "ops": [{"op": "move", "index": [], "t": 0, "s": 0}]})):
            ws.send(bad)
        errors = 0
        while errors < 4:  # each bad message is answered, in order, and the socket stays open
            msg = json.loads(ws.recv(timeout=20))
            errors += msg["type"] == "error"
        ws.send(json.dumps({"seq": 9, "ops": [{"op": "duration", "duration": 1.5}]}))
        assert abs(_final_duration(ws, 9) - 1.5) < 0.05


def test_concurrent_exports_never_share_a_name(served):
    url, outdir = served
    with httpx.Client(base_url=url, timeout=60) as client:
        sids = [_session(client) for _ in range(8)]

        def export(sid):
            with httpx.Client(base_url=url, timeout=60) as c:
                return sid, c.post(f"/api/session/{sid}/export", json={}).json()

        with concurrent.futures.ThreadPoolExecutor(8) as pool:
            results = list(pool.map(export, sids))
        names = [f["name"] for _, r in results for f in r["files"]]
        assert len(names) == 16 and len(set(names)) == 16
        for sid, r in results:  # every link serves the file its own session wrote
            for f in r["files"]:
                got = client.get(f"/api/session/{sid}/files/{f['name']}")
                assert got.status_code == 200 and len(got.content) == f["bytes"] > 0


def test_a_full_disk_leaves_no_half_export(served, monkeypatch):
    url, outdir = served
    before = sorted(p.name for p in outdir.iterdir())

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    with httpx.Client(base_url=url, timeout=60) as client:
        sid = _session(client)
        import retime.warp as warp_mod

        monkeypatch.setattr(warp_mod.TimingCurve, "to_csv", lambda self, path, fps: full())
        r = client.post(f"/api/session/{sid}/export", json={})
        assert r.status_code == 400 and "No space left" in r.json()["error"], r.text
    assert sorted(p.name for p in outdir.iterdir()) == before  # no BVH without its CSV, no placeholder


def test_the_edit_history_keeps_only_edit_fields(served):
    url, _ = served
    with httpx.Client(base_url=url, timeout=20) as client:
        sid = _session(client)
        junk = "x" * 20_000
        r = client.post(f"/api/session/{sid}/edit", json={"ops": [{"op": "duration", "duration": 1.2, "junk": junk}]})
        assert r.status_code == 200, r.text
    log = served_session(sid).op_log
    assert all("junk" not in op and "junk" not in op.get("values", {}) for _, op in log)


def served_session(sid):
    return next(store.sessions[sid] for store in STORES if sid in store.sessions)


def test_a_solve_whose_page_has_gone_stops():
    from retime.physics.api import prepare
    from retime.physics.regions import Cancelled
    from retime.motion import load_motion

    asked = []

    def gone():
        asked.append(1)
        return len(asked) > 5  # the page closes while the regions are computed

    with pytest.raises(Cancelled):
        prepare(load_motion(bundled_path("16_33.amc")), cancel=gone)
    assert len(asked) == 6  # stopped at the next frame, not at the end


HUGE = 10 ** 400  # a JSON integer no float holds (float() raises OverflowError)


@pytest.mark.parametrize("op", [{"op": "params", "method": "physics", "values": {"gravity": HUGE}},
                                {"op": "move", "index": 1, "t": HUGE, "s": 0.5},
                                {"op": "duration", "duration": HUGE}])
def test_a_400_digit_number_is_400_over_http(served, op):
    with httpx.Client(base_url=served[0], timeout=20) as client:
        sid = _session(client)
        r = client.post(f"/api/session/{sid}/edit", content=json.dumps({"ops": [op]}),
                        headers={"content-type": "application/json"})
        assert r.status_code == 400 and "finite" in r.json()["error"], r.text


def test_a_400_digit_number_over_the_websocket_is_an_error_and_the_next_edit_lands(served):
    with _live(served[0]) as ws:
        ws.send(json.dumps({"seq": 1, "ops": [{"op": "params", "method": "physics", "values": {"gravity": HUGE}}]}))
        while True:
            msg = json.loads(ws.recv(timeout=20))
            if msg["type"] == "error":
                assert msg["seq"] == 1 and "too large" in msg["message"], msg
                break
        ws.send(json.dumps({"seq": 2, "ops": [{"op": "duration", "duration": 1.5}]}))
        assert abs(_final_duration(ws, 2) - 1.5) < 0.05
