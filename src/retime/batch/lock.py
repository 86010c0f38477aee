"""OUTDIR/.retime-batch.lock: one batch at a time writes a folder. The lock is an flock on that
file, which the system releases when its process ends however it ends (a killed run leaves no
stale lock, only the file, which the next run takes over); the file names the run holding it,
for the message the next one prints."""
from __future__ import annotations

import fcntl
import json
import os
import socket
import time
from pathlib import Path

from ..errors import RetimeError
from .layout import LOCK_NAME


class FolderLock:
    def __init__(self, outdir: Path):
        self.path = outdir / LOCK_NAME
        self.fd: int | None = None

    def acquire(self) -> None:
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            except OSError as e:
                raise RetimeError(f"{self.path.parent}: cannot write in this folder ({e.strerror}); "
                                  "choose another -o") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = _read_holder(fd)
                os.close(fd)
                raise RetimeError(f"{self.path.parent}: another retime batch ({holder}) is writing in this folder; "
                                  "wait for it to finish or choose another -o") from None
            if _same_inode(fd, self.path):  # not a file the previous holder removed as we opened it
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                                 "started": time.strftime("%Y-%m-%d %H:%M:%S %Z")}).encode())
        os.fsync(fd)
        self.fd = fd

    def started_ns(self) -> int:
        """When this run took the lock, by the folder's clock (which also stamps the clips' outputs)."""
        return os.fstat(self.fd).st_mtime_ns

    def release(self) -> None:
        if self.fd is None:
            return
        try:
            os.unlink(self.path)  # while still holding it: a run that opens it next sees a new file
        except OSError:
            pass
        os.close(self.fd)
        self.fd = None

    def __enter__(self):
        self.acquire()
        return self

    def __exit__(self, *exc):
        self.release()


def _read_holder(fd: int) -> str:
    try:
        data = json.loads(os.pread(fd, 4096, 0) or b"{}")
        return f"pid {int(data['pid'])} on {data['host']}, started {data['started']}"
    except (OSError, ValueError, KeyError, TypeError):
        return "its pid unknown"


def _same_inode(fd: int, path: Path) -> bool:
    try:
        return os.stat(path).st_ino == os.fstat(fd).st_ino
    except OSError:
        return False
