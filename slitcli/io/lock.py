"""One slitcli run per output folder: an exclusive lock on ``OUT/.slitcli/lock``.

Two runs writing into one folder would mix their results (a table assembled from parts
of both settings) or delete each other's files. Every command that writes into ``OUT``
takes :func:`lock_output` first and holds it for the whole run; a second process is
refused with an error naming the holder's pid.

The lock is ``flock(2)`` on an open file: the kernel releases it when the holder exits
in any way (also ``kill -9``), so a stale lock file never blocks a later run. The file
keeps the holder's pid only for the message. Within one process the lock is re-entrant
(a library caller may run two batches on one folder one after the other).
"""

from __future__ import annotations

import fcntl
import os
import time
from pathlib import Path
from typing import IO

from slitcli.errors import SlitcliError

LOCK_DIR = ".slitcli"
LOCK_NAME = "lock"


class OutputLock:
    """An acquired run lock; :meth:`release` (or process exit) frees it.

    Attributes
    ----------
    path : Path
        The lock file, ``OUT/.slitcli/lock``.
    acquired_s : float
        ``time.time()`` when the lock was taken: temporary files older than this were
        left by an earlier run (:func:`slitcli.io.batch.sweep_temp`).
    """

    def __init__(self, path: Path, handle: IO[str] | None, acquired_s: float) -> None:
        self.path = path
        self._handle = handle
        self.acquired_s = acquired_s

    def release(self) -> None:
        """Free the lock (idempotent); the lock file stays, empty of meaning."""
        if self._handle is not None:
            self._handle.close()  # closing the descriptor drops the flock
            self._handle = None

    def __enter__(self) -> OutputLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def lock_output(out: str | Path, *, shown: str | Path | None = None) -> OutputLock:
    """Take the exclusive run lock of output folder ``out`` (created if missing).

    ``shown`` is the folder named in the message when it is not ``out`` (a command that
    works in a staging folder for ``shown``).

    Raises
    ------
    SlitcliError
        Another process holds the lock (the message names its pid), or the folder
        cannot be created.
    """
    out = Path(out)
    path = out / LOCK_DIR / LOCK_NAME
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle = open(path, "a+")  # held open for the whole run
    except OSError as e:
        raise SlitcliError(f"{out}: cannot create the output folder ({e.strerror}); check the "
                           "path and permissions") from None
    try:
        fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        holder = handle.read().strip()
        handle.close()
        if holder == str(os.getpid()):
            # this process holds it already (the kernel refuses a second descriptor)
            return OutputLock(path, None, time.time())
        pid = holder if holder.isdigit() else "(unknown)"
        raise SlitcliError(f"{out if shown is None else shown}: is in use by slitcli pid {pid}; "
                           "wait for it or choose "
                           "another folder") from None
    handle.seek(0)
    handle.truncate()
    handle.write(str(os.getpid()))
    handle.flush()
    return OutputLock(path, handle, time.time())


def is_lock_entry(out: Path, entry: Path, command: str | None = None) -> bool:
    """Whether ``entry`` (a child of ``out``) is only the lock's own folder: the lock
    file and nothing else (a fresh folder holding just this is still empty); with
    ``command``, also that command's working folder of a run stopped before it wrote
    its manifest (killed between taking the lock and recording its settings: it holds
    no results)."""
    if entry.name != LOCK_DIR or not entry.is_dir():
        return False
    return all(p.name == LOCK_NAME or (p.name == command and p.is_dir()
                                       and not (p / "manifest.json").exists())
               for p in entry.iterdir())


__all__ = ["OutputLock", "is_lock_entry", "lock_output"]
