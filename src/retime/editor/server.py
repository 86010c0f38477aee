"""The editor's web server: FastAPI over uvicorn, a websocket for the live loop, loopback only.

Security model: the server reads only the motion (and reference) it was started with and the
front-end files bundled in ``static/``, which are read once at start and served by name from a
table, so no request can name a path; it writes only into the output folder, under names it makes
itself, and serves back only the files a session exported. Sessions are reached by unguessable ids.
Requests are bounded in size (413), Host and Origin headers must be loopback (DNS rebinding and
cross-site requests are refused), and every error is a JSON ``{"error": message}`` the page shows.
"""
from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import json
import logging
import mimetypes
import os
import threading
import time
from pathlib import Path

import numpy as np
from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from ..errors import RetimeError
from ..motion.frame import to_y_up
from ..motion import end_site_positions, forward_kinematics, load_motion
from .insight import ClipInsight
from .methods import Clip, method_catalog
from .sessions import SessionStore

log = logging.getLogger("retime.editor")

STATIC_DIR = Path(__file__).resolve().parent / "static"
MAX_BODY = 64 * 1024  # bytes of one HTTP request body
MAX_WS_MESSAGE = 64 * 1024  # bytes of one websocket message
LOOPBACK_HOSTS = ("127.0.0.1", "localhost")

SECURITY_HEADERS = [
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
    (b"cross-origin-resource-policy", b"same-origin"),
    (b"content-security-policy",
     b"default-src 'self'; connect-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "
     b"script-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'; form-action 'none'"),
]


def load_clip(motion_path, reference_path=None, fps=None, asf=None, up=None, units=None, angles=None) -> Clip:
    """Read the files the editor works on (the only files it ever reads besides its own)."""
    motion = load_motion(motion_path, fps=fps, asf=asf, up=up, units=units, angles=angles)
    if motion.n_frames < 3:
        raise RetimeError(f"{motion_path}: {motion.n_frames} frame(s) have no timing to edit")
    reference = None
    if reference_path is not None:
        reference = load_motion(reference_path, fps=fps, up=up, units=units, angles=angles)
        diff = motion.skeleton.same_structure(reference.skeleton)
        if diff:
            raise RetimeError(f"{reference_path}: the reference's skeleton differs from the motion's "
                              f"(joints {', '.join(diff[:5])}); guided warping needs the same skeleton")
    return Clip(Path(motion_path).stem, motion, reference, Path(reference_path).stem if reference_path else None)


def skeleton_payload(clip: Clip):
    """Joint and end-site positions (F, J+E, 3) in metres as float32 bytes, plus the bone list."""
    m = clip.motion
    pos, ori = forward_kinematics(m)
    ends = end_site_positions(m, pos, ori)
    allpos = to_y_up(np.concatenate([pos, ends], axis=1) * m.skeleton.meters_per_unit, m.skeleton)
    parents = [int(p) for p in m.skeleton.parents] + [int(j) for j, _ in m.skeleton.end_sites]
    names = list(m.skeleton.names) + [f"{m.skeleton.names[j]}_end" for j, _ in m.skeleton.end_sites]
    return allpos.astype("<f4").tobytes(), {"parents": parents, "names": names, "n_points": len(parents)}


# -- small pure-ASGI middlewares -------------------------------------------------------------------
class Guard:
    """Loopback Host/Origin, body size limit, and security headers, for HTTP and websockets."""

    def __init__(self, app, allowed_hosts=LOOPBACK_HOSTS, max_body=MAX_BODY):
        self.app, self.allowed_hosts, self.max_body = app, tuple(allowed_hosts), max_body

    def _host_ok(self, value: str | None) -> bool:
        if not value:
            return False
        host = value.strip().lower()
        if host.startswith("["):
            host = host[: host.find("]") + 1]
        elif ":" in host:
            host = host.rsplit(":", 1)[0]
        return host in self.allowed_hosts

    def _origin_ok(self, origin: str | None, host: str | None) -> bool:
        """Same origin only: the page's own scheme-less host:port (another local server's page, on
        another port, is a different origin and is refused too)."""
        if origin is None:
            return True  # not a browser cross-site request (curl, tests); browsers always send Origin
        if "://" not in origin:
            return False
        scheme, rest = origin.split("://", 1)
        netloc = rest.split("/", 1)[0].lower()
        return scheme == "http" and self._host_ok(netloc) and netloc == (host or "").strip().lower()

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope.get("headers", [])}
        if not self._host_ok(headers.get("host")):
            return await _refuse(scope, receive, send, 400, "bad Host header: the editor answers only on 127.0.0.1")
        if not self._origin_ok(headers.get("origin"), headers.get("host")) and (scope["type"] == "websocket" or scope.get("method") != "GET"):
            return await _refuse(scope, receive, send, 403, "cross-site request refused: open the editor's own page")
        if scope["type"] == "websocket":
            return await self.app(scope, receive, send)

        length = headers.get("content-length")
        if length is not None:
            try:
                too_big = int(length) > self.max_body
            except ValueError:
                return await _refuse(scope, receive, send, 400, "bad Content-Length header")
            if too_big:
                return await _refuse(scope, receive, send, 413, _too_large(int(length), self.max_body))
        received = 0
        started = False

        async def limited_receive():
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_body:
                    raise _BodyTooLarge(received)
            return message

        async def send_with_headers(message):
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                message = dict(message)
                message["headers"] = list(message.get("headers", [])) + SECURITY_HEADERS
            await send(message)

        try:
            await self.app(scope, limited_receive, send_with_headers)
        except _BodyTooLarge as e:
            if not started:
                await _refuse(scope, receive, send, 413, _too_large(e.args[0], self.max_body))
        except Exception as e:  # already answered as JSON by the app's handler, or answer here
            if not started:
                log.exception("internal error")
                await _refuse(scope, receive, send, 500, f"internal error ({type(e).__name__}); the editor is still running")


class _BodyTooLarge(Exception):
    pass


class _Closed(Exception):
    """The event loop is gone (server stopping): a solve thread just ends."""


def _too_large(n, limit):
    return f"request too large ({n} bytes; the editor accepts at most {limit // 1024} KiB)"


async def _refuse(scope, receive, send, status, message):
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008, "reason": message[:120]})
        return
    body = json.dumps({"error": message}).encode()
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                            (b"connection", b"close")] + SECURITY_HEADERS})
    await send({"type": "http.response.body", "body": body})


def _read_static(static_dir: Path):
    """Front-end files by name (read once; requests only ever look names up in this table)."""
    table = {}
    if static_dir.is_dir():
        for path in sorted(static_dir.iterdir()):
            if path.is_file() and not path.name.startswith(".") and not path.name.endswith(".map"):
                kind = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
                if kind.startswith("text/") or kind in ("application/javascript", "image/svg+xml"):
                    kind += "; charset=utf-8"
                table[path.name] = (path.read_bytes(), kind)
    return table


# -- the application --------------------------------------------------------------------------------
def create_app(clip: Clip, outdir, *, static_dir=STATIC_DIR, allowed_hosts=LOOPBACK_HOSTS, max_body=MAX_BODY,
               max_sessions=64, workers=None) -> FastAPI:
    outdir = Path(outdir).resolve()
    if not outdir.is_dir():
        raise RetimeError(f"{outdir}: output folder does not exist")
    store = SessionStore(clip, outdir, clip.motion.fps, max_sessions=max_sessions)
    static = _read_static(Path(static_dir))
    positions_bytes, skeleton = skeleton_payload(clip)
    insight = ClipInsight(clip.motion)
    executor = concurrent.futures.ThreadPoolExecutor(max_workers=workers or min(8, (os.cpu_count() or 2) * 2),
                                                     thread_name_prefix="retime-solve")

    @contextlib.asynccontextmanager
    async def lifespan(app):
        yield
        store.stopping.set()  # running solves stop at their next check (between frames of the regions)
        executor.shutdown(wait=False, cancel_futures=True)

    app = FastAPI(title="retime edit", docs_url=None, redoc_url=None, openapi_url=None, lifespan=lifespan)
    app.state.store = store
    app.state.executor = executor

    # -- errors: always JSON with a readable message ----------------------------------------------
    @app.exception_handler(RetimeError)
    async def _retime_error(request, exc):
        return JSONResponse({"error": str(exc)}, status_code=400)

    @app.exception_handler(_BodyTooLarge)
    async def _too_large_error(request, exc):
        return JSONResponse({"error": _too_large(exc.args[0], max_body)}, status_code=413)

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request, exc):
        return JSONResponse({"error": str(exc.detail)}, status_code=exc.status_code)

    @app.exception_handler(RequestValidationError)
    async def _validation_error(request, exc):
        first = exc.errors()[0] if exc.errors() else {}
        return JSONResponse({"error": f"bad request: {first.get('msg', 'invalid input')}"}, status_code=422)

    @app.exception_handler(Exception)
    async def _internal_error(request, exc):
        log.exception("internal error")
        return JSONResponse({"error": f"internal error ({type(exc).__name__}: {exc}); the editor is still running"},
                            status_code=500)

    def session_or_404(sid):
        session = store.get(sid)
        if session is None:
            raise StarletteHTTPException(404, "no such session (it may have expired): reload the page")
        return session

    async def json_body(request: Request):
        kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if kind != "application/json":
            raise StarletteHTTPException(415, "send JSON (Content-Type: application/json)")
        raw = await request.body()
        if not raw:
            return {}
        try:
            return json.loads(raw)
        except (ValueError, UnicodeDecodeError, RecursionError):  # RecursionError: JSON nested thousands deep
            raise StarletteHTTPException(400, "the request body is not valid JSON (or is nested too deep)") from None

    async def in_thread(fn, *args):
        return await asyncio.get_running_loop().run_in_executor(executor, fn, *args)

    # -- page -------------------------------------------------------------------------------------
    @app.get("/", include_in_schema=False)
    async def index():
        if "index.html" not in static:
            return HTMLResponse("<h1>retime edit</h1><p>The front end is not built: run <code>npm ci && npm run build</code> "
                                "in web/.</p>", status_code=500)
        body, kind = static["index.html"]
        return Response(body, media_type=kind, headers={"cache-control": "no-cache"})

    @app.get("/assets/{name}", include_in_schema=False)
    async def asset(name: str):
        item = static.get(name)
        if item is None or name == "index.html":
            raise StarletteHTTPException(404, "not found")
        return Response(item[0], media_type=item[1], headers={"cache-control": "no-cache"})

    # -- API ----------------------------------------------------------------------------------------
    def clip_info():
        m = clip.motion
        return {"name": clip.name, "fps": m.fps, "n_frames": m.n_frames, "duration": m.duration,
                "reference": clip.reference_name, "skeleton": skeleton, "outdir": str(outdir)}

    def session_state(session, solution):
        return {"session": session.id, "clip": clip_info(), "methods": method_catalog(clip),
                "method": session.method, "params": session.params, "solution": solution}

    @app.post("/api/session")
    async def new_session(request: Request):
        await json_body(request)
        session = store.create()
        sol = await in_thread(session.solve_now)
        return session_state(session, session.solution_json(sol))

    @app.get("/api/session/{sid}")
    async def get_session(sid: str):
        session = session_or_404(sid)
        sol = await in_thread(session.solve_now)
        return session_state(session, session.solution_json(sol))

    @app.get("/api/session/{sid}/positions")
    async def positions(sid: str):
        session_or_404(sid)
        return Response(positions_bytes, media_type="application/octet-stream",
                        headers={"cache-control": "no-store"})

    @app.get("/api/session/{sid}/check")
    async def check(sid: str):
        session_or_404(sid)
        return await in_thread(insight.payload)

    @app.post("/api/session/{sid}/edit")
    async def edit(sid: str, request: Request):
        session = session_or_404(sid)
        body = await json_body(request)
        ops = body.get("ops") if isinstance(body, dict) else None
        if ops is None:
            raise RetimeError("send {\"ops\": [ ... edits ... ]}")

        def work():
            apply_edits(session, ops)
            return session.solution_json(session.solve_now(), seq=body.get("seq"))

        return await in_thread(work)

    @app.post("/api/session/{sid}/export")
    async def export(sid: str, request: Request):
        session = session_or_404(sid)
        await json_body(request)
        result = await in_thread(session.export)
        for f in result["files"]:
            f["url"] = f"/api/session/{sid}/files/{f['name']}"
        return result

    @app.get("/api/session/{sid}/files/{name}")
    async def download(sid: str, name: str):
        session = session_or_404(sid)
        path = session.exports.get(name)  # only files this session wrote; never a path from the request
        if path is None or not path.is_file():
            raise StarletteHTTPException(404, "no such exported file in this session")
        kind = "text/csv" if path.suffix == ".csv" else "application/octet-stream"
        return FileResponse(path, media_type=kind, filename=path.name)

    @app.websocket("/api/session/{sid}/live")
    async def live(ws: WebSocket, sid: str):
        await ws.accept()
        session = store.get(sid)
        if session is None:
            await ws.send_text(json.dumps({"type": "error", "message": "no such session (it may have expired): reload the page"}))
            await ws.close(code=1008)
            return
        await LiveLoop(session, ws, executor).run()

    return Guard(app, allowed_hosts=allowed_hosts, max_body=max_body) if allowed_hosts else app


def apply_edits(session, ops):
    """Apply edits from a page; an edit of the wrong shape (a list where a name belongs, ...) is a
    RetimeError (400, or an error message on the socket), never a crash of the connection."""
    try:
        return session.apply(ops)
    except RetimeError:
        raise
    except (TypeError, ValueError, KeyError, AttributeError, IndexError, RecursionError) as e:
        raise RetimeError(f"bad edit: a field has the wrong type or shape ({type(e).__name__})") from None


class LiveLoop:
    """One websocket: edits in, solutions out. A newer edit cancels the solve of an older one."""

    def __init__(self, session, ws, executor):
        self.session, self.ws, self.executor = session, ws, executor
        self.wake = asyncio.Event()
        self.seq = None
        self.send_lock = asyncio.Lock()
        self.gone = threading.Event()  # the page closed its socket

    async def send(self, obj):
        async with self.send_lock:
            await self.ws.send_text(json.dumps(obj, allow_nan=False))

    async def run(self):
        solver = asyncio.create_task(self.solver())
        try:
            while True:
                message = await self.ws.receive()
                if message["type"] == "websocket.disconnect":
                    break
                text = message.get("text")
                if text is None:  # a binary frame
                    await self.send({"type": "error", "message": "send edits as JSON text, not binary"})
                    continue
                await self.handle(text)
        except WebSocketDisconnect:
            pass
        except RuntimeError:  # socket closed under us
            pass
        finally:
            self.gone.set()
            solver.cancel()

    async def handle(self, text):
        if len(text) > MAX_WS_MESSAGE:
            await self.send({"type": "error", "message": _too_large(len(text), MAX_WS_MESSAGE)})
            return
        try:
            msg = json.loads(text)
        except (ValueError, RecursionError):
            await self.send({"type": "error", "message": "message is not valid JSON (or is nested too deep)"})
            return
        seq = msg.get("seq") if isinstance(msg, dict) else None
        if not isinstance(seq, (int, type(None))) or isinstance(seq, bool):
            seq = None
        try:
            if not isinstance(msg, dict) or "ops" not in msg:
                raise RetimeError("send {\"seq\": N, \"ops\": [ ... edits ... ]}")
            apply_edits(self.session, msg["ops"])
        except Exception as e:  # a RetimeError, or a bug: either way the page hears of it and the socket stays
            if not isinstance(e, RetimeError):
                log.exception("edit failed")
            message = str(e) if isinstance(e, RetimeError) else f"internal error ({type(e).__name__}); the editor is still running"
            await self.send({"type": "error", "seq": seq, "message": message})
            self.seq = seq
            self.wake.set()  # send the unchanged state so the page puts points back
            return
        self.seq = seq
        self.wake.set()

    async def solver(self):
        loop = asyncio.get_running_loop()
        while True:
            await self.wake.wait()
            self.wake.clear()
            session, seq = self.session, self.seq
            snap = session.snapshot()
            queue: asyncio.Queue = asyncio.Queue()

            def put(item):
                try:
                    loop.call_soon_threadsafe(queue.put_nowait, item)
                except RuntimeError:  # the server is shutting down
                    raise _Closed() from None

            def status(message):
                put({"type": "status", "seq": seq, "message": message})

            def run():
                t0 = time.perf_counter()
                try:
                    for sol in session.solve(snap, status=status, gone=self.gone.is_set):
                        payload = session.solution_json(sol, snap, seq)
                        payload["info"]["solve_ms"] = round((time.perf_counter() - t0) * 1000, 2)
                        put(payload)
                except _Closed:
                    return
                except RetimeError as e:
                    put({"type": "error", "seq": seq, "message": str(e)})
                except Exception as e:  # a bug in a method must not kill the page
                    log.exception("solve failed")
                    put({"type": "error", "seq": seq, "message": f"internal error in {snap.method} ({type(e).__name__}: {e})"})
                with contextlib.suppress(_Closed):
                    put(None)

            future = loop.run_in_executor(self.executor, run)
            while (item := await queue.get()) is not None:
                if item["type"] != "solution" or session.version == snap.version:
                    await self.send(item)
            await future


def make_uvicorn_server(app):
    """A uvicorn server for the app, with the websocket message size bounded."""
    import uvicorn  # noqa: PLC0415

    ws = "websockets-sansio" if "websockets-sansio" in getattr(uvicorn.config, "WS_PROTOCOLS", {}) else "auto"
    config = uvicorn.Config(app, log_level="warning", ws_max_size=MAX_WS_MESSAGE, ws=ws, server_header=False,
                            timeout_graceful_shutdown=2)
    return uvicorn.Server(config)


class BackgroundServer:
    """Run the editor on a free loopback port in a thread (tests, benchmarks, notebooks).

    >>> with BackgroundServer(create_app(clip, outdir)) as url: ...
    """

    def __init__(self, app, port=0):
        import socket  # noqa: PLC0415
        import threading  # noqa: PLC0415

        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", port))
        self.sock.listen(256)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}"
        self.server = make_uvicorn_server(app)
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]}, daemon=True)

    def __enter__(self):
        self.thread.start()
        deadline = time.monotonic() + 10
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("the editor server did not start")
            time.sleep(0.01)
        return self.url

    def __exit__(self, *exc):
        self.server.should_exit = True
        self.thread.join(timeout=10)
        self.sock.close()
