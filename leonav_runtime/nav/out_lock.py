"""One writer per `leonav nav` output folder: an exclusive lock held while a run writes.

`lock_out_dir(OUT)` takes `fcntl.flock(LOCK_EX | LOCK_NB)` on `OUT/.leonav-nav.lock` and writes
its pid there; a second holder (another process, or another open in this one) gets a one-line
`UserInputError` naming OUT and the holder's pid. The kernel drops a flock when its process
dies, so a lock file a killed run left never blocks. `release()` (or leaving the `with`)
removes the file while still holding the lock, then unlocks.
"""
from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

from leonav_runtime.common.errors import UserInputError

LOCK_NAME = ".leonav-nav.lock"


class OutDirLock:
    """The held lock of one output folder (see module doc); use `lock_out_dir`."""

    def __init__(self, folder: Path, fd: int) -> None:
        self.folder = folder
        self.path = folder / LOCK_NAME
        self._fd: int | None = fd

    def release(self) -> None:
        """Remove the lock file and unlock (once; later calls do nothing)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.path)     # before unlocking, so no one can lock this file and lose it
        except FileNotFoundError:
            pass
        os.close(self._fd)           # closing drops the flock
        self._fd = None

    def __enter__(self) -> "OutDirLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def lock_out_dir(folder: str | Path) -> OutDirLock:
    """Lock `folder` (created if missing) for one writer, or raise `UserInputError` if another holds it."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / LOCK_NAME
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise UserInputError(f"--out {folder}: cannot lock {path} ({exc.strerror}); expected a "
                                     "local folder that supports file locks") from None
            pid = _holder_pid(path)
            raise UserInputError(f"--out {folder}: another `leonav nav` run ({f'pid {pid}' if pid else 'pid unknown'}) "
                                 "is writing this folder; wait for it to end or give another --out") from None
        # The holder may have released (and removed the file) between our open and our lock: then
        # this lock is on a file no one else sees; start again with the one at `path`.
        try:
            st, own = os.stat(path), os.fstat(fd)
            same = (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino)
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:        # the pid is for the message of a refused second run: a full disk must not stop this one
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
    except OSError:
        pass
    return OutDirLock(folder, fd)


def _holder_pid(path: Path) -> int | None:
    """The pid the holder wrote (None if it has not yet, or the file is gone)."""
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None
