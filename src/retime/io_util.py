"""Atomic output files: a reader never sees a half-written file, a failure leaves nothing behind."""
import contextlib
import os
import tempfile
from pathlib import Path

from .errors import RetimeError


def check_not_input(output, *inputs):
    """Refuse to write over one of the command's input files."""
    out = Path(output).resolve()
    for path in inputs:
        if path is not None and Path(path).resolve() == out:
            raise RetimeError(f"{output}: refusing to overwrite the input file; choose another output path")


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_write(path, mode="w", newline=None):
    """Open a temporary file beside ``path``; rename it over ``path`` only if the block succeeds."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise RetimeError(f"{path}: output folder {directory} does not exist")
    if path.is_dir():
        raise RetimeError(f"{path}: is a folder; give a file name for the output")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        if "b" in mode:
            f = os.fdopen(fd, mode)
        else:
            f = os.fdopen(fd, mode, encoding="utf-8", newline=newline)
        with f:
            yield f
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual permissions
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
