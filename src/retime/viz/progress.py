"""Progress bars for steps that take more than a second: tqdm on a terminal, silent otherwise."""

from __future__ import annotations

import sys

from tqdm import tqdm


def progress(total: int | None = None, desc: str = "", quiet: bool = False, **kwargs) -> tqdm:
    """A tqdm bar on stderr, disabled with ``quiet`` or when stderr is not a terminal.

    Use as a context manager and call ``.update(n)``.
    """
    disable = quiet or not _isatty(sys.stderr)
    return tqdm(total=total, desc=desc, disable=disable, leave=False, dynamic_ncols=True, **kwargs)


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except Exception:
        return False
