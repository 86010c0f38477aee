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
    """argparse, but a usage error is one line (what is wrong, where to look) and exit code 2, and an
    option is only its whole name: an abbreviation (``--scal`` for ``--scale``) would change meaning the
    day another option starting the same way is added."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)  # the subcommands' parsers are made by this class too
        super().__init__(*args, **kwargs)

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def unrecognized(extra: list[str], parser: argparse.ArgumentParser) -> str:
    """The error for arguments ``parser`` does not know, with the closest option to a misspelt one."""
    import difflib

    message = f"unrecognized arguments: {' '.join(extra)}"
    options = [o for action in parser._actions for o in action.option_strings]
    for word in extra:
        if word.startswith("--"):
            close = difflib.get_close_matches(word.split("=", 1)[0], options, n=1, cutoff=0.7)
            if close:
                return f"{message}; did you mean {close[0]}?"
    return message


def parse(parser: argparse.ArgumentParser, argv=None) -> argparse.Namespace:
    """``parser.parse_args``, but an unknown argument is reported by the subcommand's parser, which
    points to its own --help (``retime linear --help``, not ``retime --help``) and suggests a close match."""
    args, extra = parser.parse_known_args(argv)
    if extra:
        subcommands = next((a.choices for a in parser._actions if isinstance(a, argparse._SubParsersAction)), {})
        command = subcommands.get(getattr(args, "command", None), parser)
        command.error(unrecognized(extra, command))
    return args


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
    for name, command in sub.choices.items():
        if name != "demo":  # the demo's --clip takes a bundled clip's name itself
            command.epilog = with_bundled_note(command.epilog)
    return parser


def with_bundled_note(epilog: str | None) -> str | None:
    """An epilog whose examples name bundled clips (``16_06.amc``), with where those are: a command reads a
    path, and the name alone is found only in the folder that holds the clip."""
    import re

    from ..data import CMU_DIR

    named = sorted({m for m in re.findall(r"\b[\w.]+\.(?:amc|bvh)\b", epilog or "") if (CMU_DIR / m).is_file()})
    if not named:
        return epilog
    import textwrap

    clips = ", ".join(named)
    note = (f"({clips} {'is a clip' if len(named) == 1 else 'are clips'} bundled with retime: give the path, "
            f"src/retime/data/cmu/{named[0]} in a clone, or the one python3 -c \"from retime.data import "
            f"bundled_path; print(bundled_path('{named[0]}'))\" prints.)")
    return f"{epilog}\n\n{textwrap.fill(note, width=100, break_on_hyphens=False)}"


def main(argv=None) -> int:
    parser = build_parser()
    args = parse(parser, argv)
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
