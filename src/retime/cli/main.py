"""The ``retime`` program: the parser of every command, and ``main``, which runs one and turns a
``RetimeError`` into one line and exit code 2."""
from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading

from ..errors import RetimeError
from ..io_util import all_or_none

COMMANDS = ["info", "convert", "linear", "edit", "plot", "render", "apply", "demo", "guided", "physics", "check", "batch"]


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (what is wrong, where to look) and exit code 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="retime",
        description="Change the timing of character motion (BVH, ASF/AMC) without touching its poses.",
        epilog="Run 'retime COMMAND --help' for a command's options and an example.",
    )
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"retime {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"{__package__}.{name}").register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        if args.command in ("edit", "batch"):  # a server, a batch: their outputs commit one by one
            return int(args.func(args) or 0)
        # Python lets only the main thread set handlers: run from another thread (a Dask task, a
        # notebook's worker) the process's own SIGTERM handling stays, and the transaction holds anyway
        on_main = threading.current_thread() is threading.main_thread()
        previous = signal.signal(signal.SIGTERM, _terminate) if on_main else None
        try:
            with all_or_none():  # the command's outputs appear together, or none of them
                return int(args.func(args) or 0)
        finally:
            if on_main:
                signal.signal(signal.SIGTERM, previous)
    except Terminated:
        print(f"retime {args.command}: terminated; no output written", file=sys.stderr)
        return 143
    except RetimeError as e:
        print(f"retime {args.command}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. 'retime info X | head': the reader left, nothing to report
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # Python's documented recipe
        return 0
    except OSError as e:  # e.g. an output folder without write permission, a full disk
        where = f"{e.filename}: " if getattr(e, "filename", None) else ""
        print(f"retime {args.command}: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"retime {args.command}: interrupted; no output written", file=sys.stderr)
        return 130


class Terminated(BaseException):
    """SIGTERM: raised in the main thread so that every output in progress is removed."""


def _terminate(signum, frame):
    raise Terminated()
