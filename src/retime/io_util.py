"""Atomic output files: a reader never sees a half-written file, a failure leaves nothing behind.

* :func:`atomic_write` writes a temporary file beside the output and renames it over the output
  only when the writing succeeded. An output that is a symlink is written through: the file it
  points to is replaced (atomically, beside it), never the link itself.
* :func:`all_or_none` makes a command's outputs one transaction: every :func:`atomic_write` inside
  it only stages its file, and they are renamed into place together at the end (with SIGINT and
  SIGTERM held off for those few renames), or all removed on any failure.
* :func:`check_outputs` is run before any work: each output's folder exists, it is not a folder,
  not an existing device, FIFO or other special file, not one of the files the command reads (by
  path, symlink or hard link) and not another of its outputs.
"""
import contextlib
import contextvars
import os
import signal
import tempfile
from pathlib import Path

from .errors import RetimeError


def file_keys(path) -> list:
    """What names the file at ``path`` whichever way it is reached: its resolved path (symlinks) and,
    when it exists, its device and inode (hard links, bind mounts). Two paths are one file when they
    share a key; a set of inputs is a dict by these keys."""
    path = Path(path)
    keys = [Path(os.path.realpath(path))]  # not Path.resolve(), which raises on a symlink loop
    try:
        st = path.stat()
    except OSError:
        return keys
    return keys + [(st.st_dev, st.st_ino)]


def _same_file(a: Path, b: Path) -> bool:
    return not set(file_keys(a)).isdisjoint(file_keys(b))


def check_not_input(output, *inputs):
    """Refuse to write over one of the command's input files."""
    out = Path(output)
    for path in inputs:
        if path is not None and _same_file(Path(path), out):
            raise RetimeError(f"{output}: refusing to overwrite the input file {path}; choose another output path")


def write_target(path: Path) -> Path:
    """The file a write to ``path`` replaces: ``path`` itself, or the file its symlink points to (a
    rename over the link would replace the link and leave its target as it was)."""
    if not path.is_symlink():
        return path
    target = Path(os.path.realpath(path))
    if target.is_symlink():  # realpath stops inside a loop
        raise RetimeError(f"{path}: is a symlink that loops; give a file name for the output")
    return target


def _output_folder(path: Path) -> Path:
    """The folder ``path`` will be written in, checked to exist; ``path`` must not be a folder."""
    target = write_target(path)
    if target != path:
        if not target.parent.is_dir():
            raise RetimeError(f"{path}: is a symlink to {target}, whose folder does not exist")
        path = target
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise RetimeError(f"{path}: output folder {directory} does not exist; create it first")
    if path.is_dir():
        raise RetimeError(f"{path}: is a folder; give a file name for the output")
    return directory


def check_outputs(outputs, inputs=()):
    """Check a command's outputs before any work (see the module docstring). ``outputs`` and
    ``inputs`` may hold None (an option not given)."""
    seen = []
    for output in outputs:
        if output is None:
            continue
        path = Path(output)
        directory = _output_folder(path)
        if path.exists() and not path.is_file():
            raise RetimeError(f"{output}: exists and is not a regular file (a device, FIFO or socket); "
                              "retime only replaces regular files")
        if not os.access(directory, os.W_OK):
            raise RetimeError(f"{output}: cannot write in the folder {directory} (permission denied)")
        check_not_input(output, *inputs)
        for other in seen:
            if _same_file(Path(other), path):
                raise RetimeError(f"{output}: given for two outputs; choose a different file for each")
        seen.append(output)


class _Transaction:
    def __init__(self):
        self.staged: list[tuple[str, Path]] = []

    def commit(self):
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
        try:
            done = []
            try:
                for tmp, path in self.staged:
                    os.replace(tmp, path)
                    done.append(path)
            except BaseException:
                for path in done:  # a rename failed: take back the ones made
                    with contextlib.suppress(OSError):
                        os.unlink(path)
                raise
            self.staged = []
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)

    def abort(self):
        for tmp, _ in self.staged:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        self.staged = []


_TRANSACTION: contextvars.ContextVar = contextvars.ContextVar("retime_outputs", default=None)


@contextlib.contextmanager
def all_or_none():
    """Every :func:`atomic_write` inside commits together at the end, or none does."""
    tx = _Transaction()
    token = _TRANSACTION.set(tx)
    try:
        yield tx
        tx.commit()
    except BaseException:
        tx.abort()
        raise
    finally:
        _TRANSACTION.reset(token)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_write(path, mode="w", newline=None):
    """Open a temporary file beside ``path``; rename it over ``path`` only if the block succeeds."""
    path = write_target(Path(path))
    directory = _output_folder(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        if "b" in mode:
            f = os.fdopen(fd, mode)
        else:
            f = os.fdopen(fd, mode, encoding="utf-8", newline=newline)
        with f:
            yield f
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual permissions
        tx = _TRANSACTION.get()
        if tx is not None:
            tx.staged.append((tmp, path))  # renamed with the command's other outputs
            return
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
