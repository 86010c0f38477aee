"""The ``retime`` command line. Each command lives in its own module with ``register(subparsers)``;
:mod:`.main` builds the parser and runs a command."""
from .main import build_parser, main

__all__ = ["main", "build_parser"]
