"""``retime edit``: the interactive timing editor in the browser."""
from __future__ import annotations

import argparse
import socket
import sys
import threading
import webbrowser
from pathlib import Path

from ..errors import RetimeError
from .common import add_frame_args, frame_kwargs, positive_float


def register(sub):
    p = sub.add_parser(
        "edit", help="interactive timing editor in the browser (drag, add, lock control points; live re-optimization)",
        description="Start a local web editor for MOTION's timing. It listens on 127.0.0.1 only, reads only the "
                    "files given here and writes exports (retimed BVH and warp CSV) only into the output folder.",
        epilog="examples:\n  retime edit 16_06.amc\n"
               "  retime edit walk.bvh --reference limp.bvh --port 8765 --no-browser -o edits/",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("motion", metavar="MOTION", help="motion to retime (.bvh, or .amc with its .asf beside it)")
    p.add_argument("--reference", metavar="REF", help="reference motion for guided time warping (same skeleton)")
    p.add_argument("--asf", metavar="SKELETON.asf", help="skeleton for an .amc file (default: X.asf beside X_NN.amc)")
    p.add_argument("--fps", type=positive_float, metavar="HZ", help="frame rate of AMC input (default 120)")
    add_frame_args(p)
    p.add_argument("--port", type=_port, default=0, metavar="P", help="port on 127.0.0.1 (default: a free one)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser; just print the URL")
    p.add_argument("-o", "--outdir", metavar="OUTDIR", default=None,
                   help="folder for exports (default: ./retime-edits; created if missing)")
    p.set_defaults(func=run)


def _port(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"port must be a whole number, got {text!r}") from None
    if not 0 <= v <= 65535:
        raise argparse.ArgumentTypeError(f"port must be 0..65535, got {v}")
    return v


def bind_loopback(port: int) -> socket.socket:
    """A listening socket on 127.0.0.1 (port 0: the system picks a free one)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(("127.0.0.1", port))
    except OSError as e:
        sock.close()
        raise RetimeError(f"cannot listen on 127.0.0.1:{port} ({e.strerror}); choose another --port or leave it out") from None
    sock.listen(128)
    sock.set_inheritable(True)
    return sock


def run(args):
    try:
        from ..editor.server import create_app, load_clip, make_uvicorn_server  # noqa: PLC0415
    except ImportError as e:
        raise RetimeError(f"the editor needs extra packages ({e.name} is missing): pip install 'retime[editor]'") from None
    outdir = Path(args.outdir) if args.outdir else Path("retime-edits")
    clip = load_clip(args.motion, args.reference, fps=args.fps, asf=args.asf, **frame_kwargs(args))
    try:
        outdir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise RetimeError(f"{outdir}: cannot create the output folder ({e.strerror})") from None
    app = create_app(clip, outdir)
    sock = bind_loopback(args.port)
    port = sock.getsockname()[1]
    url = f"http://127.0.0.1:{port}/"
    server = make_uvicorn_server(app)
    print(f"retime edit: {clip.name} ({clip.motion.n_frames} frames at {clip.motion.fps:g} Hz) at {url}", flush=True)
    print(f"retime edit: exports go to {outdir.resolve()}; press Ctrl-C to stop", flush=True)
    if not args.no_browser:
        if _has_display():
            threading.Timer(0.5, _open_browser, args=(url,)).start()
        else:
            print("retime edit: no display here; open the URL in a browser (ssh -L works too)", flush=True)
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        pass
    finally:
        sock.close()
    print("retime edit: stopped", file=sys.stderr, flush=True)
    return 0


def _has_display():
    """A graphical browser can open here (not, e.g., an ssh session without X, where Python's
    webbrowser would start a text browser inside this terminal)."""
    import os  # noqa: PLC0415

    if sys.platform in ("darwin", "win32") or os.environ.get("BROWSER"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _open_browser(url):
    try:
        webbrowser.open(url)
    except Exception:  # no browser here: the URL is printed above
        pass
