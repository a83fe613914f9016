"""Resumable, parallel batches over frames.

A batch keeps its state in ``OUT/.slitcli/<name>/``: ``manifest.json`` (the arguments,
rig and input that define the results, and the slitcli version that made them) and one
part file per finished frame, each written atomically. A re-run with the same manifest
skips the finished frames (also after ``kill -9``); a different manifest is refused
unless ``overwrite``. The final table is assembled from the parts in frame order, so it
is byte-identical whatever the number of workers and however often the run was
interrupted.

A batch holds the folder's run lock (:mod:`slitcli.io.lock`) from its start to the end
of the process (or :meth:`FrameBatch.close`): a second run on the same ``OUT`` is
refused. It keeps a finished frame only while that frame's input identity
(:func:`frame_identity`: its bytes, name and time) is unchanged, so an edited, swapped or
replaced frame is computed again and the others are kept. Worker processes die with the
run (:func:`run_pool`).
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import math
import multiprocessing
import os
import shutil
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from functools import partial
from pathlib import Path
from typing import Any

from slitcli import __version__
from slitcli.errors import SlitcliError
from slitcli.io.atomic import sweep_temp, write_text_atomic
from slitcli.io.lock import OutputLock, is_lock_entry, lock_output

WORKER_WATCH_S = 0.5
"""How often a worker process checks that the run that started it is still alive, s."""


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes (for manifests)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def frame_identity(source: Any, index: int) -> str:
    """What frame ``index``'s results depend on in ``source`` (a
    :class:`slitcli.io.frames.FrameSource`): the source's digest of the frame's input
    (image bytes, or bag stamps), its output name and its time (``times.csv`` is part of
    every table), as one SHA-256 hex string."""
    info = source.info[index]
    h = hashlib.sha256()
    for part in (source.frame_digest(index), info.name, repr(float(info.time_s))):
        h.update(part.encode("utf-8", "surrogateescape") + b"\0")
    return h.hexdigest()


def max_jobs() -> int:
    """The largest ``jobs``: two worker processes per CPU (more only costs memory, about
    250 MB a worker, without speed)."""
    return 2 * (os.cpu_count() or 1)


def check_jobs(jobs: int) -> None:
    """Raise :class:`SlitcliError` (``jobs``) unless 1 <= jobs <= :func:`max_jobs`."""
    if isinstance(jobs, bool) or not isinstance(jobs, int) or not 1 <= jobs <= max_jobs():
        raise SlitcliError(f"`jobs` {jobs!r} is out of range; give 1 to {max_jobs()} (two per "
                           "CPU of this machine)", param="jobs")


def manifest_value(d: object) -> object:
    """``d`` (dicts, lists, tuples, numbers, strings) as JSON-able values for a manifest:
    tuples become lists and non-finite floats strings (JSON has no inf or NaN)."""
    if isinstance(d, dict):
        return {k: manifest_value(v) for k, v in d.items()}
    if isinstance(d, list | tuple):
        return [manifest_value(v) for v in d]
    if isinstance(d, float) and not math.isfinite(d):
        return str(d)
    return d


def sweep_output(out: Path, *subfolders: str | Path) -> list[Path]:
    """Remove slitcli's stale temporary names (:func:`slitcli.io.atomic.sweep_temp`:
    ``.slitcli-<pid>-<hex>.tmp`` of a process that is gone) in ``out``, its
    ``.slitcli`` state folder at any depth (a command may stage outputs in a folder of
    its own there) and the given output ``subfolders``; nothing else."""
    out = Path(out)
    folders = [out, *(out / s for s in subfolders)]
    state = out / ".slitcli"
    if state.is_dir():
        # a temporary folder is swept whole, not walked into
        folders += [state, *(d for d in state.rglob("*") if d.is_dir()
                             and not any(x.startswith(".slitcli-")
                                                 for x in d.relative_to(state).parts))]
    removed: list[Path] = []
    for f in folders:
        removed += sweep_temp(f)
    return removed


class FrameBatch:
    """State of one resumable batch in ``out/.slitcli/<name>/``.

    Parameters
    ----------
    out : path
        The command's output folder.
    name : str
        The command (``detect``, ``stereo``...).
    manifest : dict
        JSON-able description of everything the results depend on.
    overwrite : bool
        Discard earlier results made with a different manifest.
    subfolders : tuple of str
        The command's output folders in ``out`` (swept of stale temporaries).
    shared : bool
        ``out`` may hold other files (the command writes only its own named outputs):
        a folder not written by this command is not refused.
    hold_lock : bool
        Take the folder's run lock and sweep stale temporaries (default). False for a
        chunk computed on a cluster worker, whose client holds the lock for the run.

    Raises
    ------
    SlitcliError
        Another process runs in ``out`` (naming its pid); results of other settings
        without ``overwrite``; a foreign non-empty folder.
    """

    def __init__(self, out: Path, name: str, manifest: dict[str, Any], *,
                 overwrite: bool = False, subfolders: tuple[str, ...] = (),
                 shared: bool = False, hold_lock: bool = True) -> None:
        self.out = Path(out)
        self.dir = self.out / ".slitcli" / name
        self.parts = self.dir / "parts"
        if self.out.exists() and not self.out.is_dir():
            raise SlitcliError(f"{self.out}: exists and is not a folder; choose another "
                               "output path")
        foreign = None if shared or not self.out.is_dir() or (self.dir / "manifest.json").exists() \
            else next((e for e in self.out.iterdir() if not is_lock_entry(self.out, e, name)),
                      None)
        if foreign is not None and not overwrite:  # refused before the lock file is made
            raise SlitcliError(f"{self.out}: is not empty (it holds {foreign.name}) and was not "
                               f"written by slitcli {name}; choose another output folder or "
                               "pass `overwrite`", param="overwrite")
        # held until the process ends or close(): one run per folder at a time
        if hold_lock:
            self.lock = lock_output(self.out)
            sweep_output(self.out, *subfolders)
        else:  # a chunk of a run whose client holds the lock (and swept the folder)
            self.lock = OutputLock(self.out / ".slitcli" / "lock", None, time.time())
        # another slitcli version may compute other results from the same arguments
        manifest = {**manifest, "slitcli_version": __version__}
        self.manifest = manifest
        path = self.dir / "manifest.json"
        self.fresh = True
        # fresh: no results of an earlier run are kept (none, or discarded)
        if not path.exists() and self.dir.exists():
            # a run stopped before it recorded its settings: nothing in it can be trusted
            shutil.rmtree(self.dir)
        if path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError):
                old = None
            if old != manifest:
                if not overwrite:
                    changed = _changed_keys(old, manifest)
                    self.lock.release()
                    raise SlitcliError(
                        f"{self.out}: holds {name} results made with other settings "
                        f"(changed: {changed}); pass `overwrite` to replace them or choose "
                        "another output folder", param="overwrite")
                shutil.rmtree(self.dir)
            else:
                self.fresh = False
        try:
            self.parts.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise SlitcliError(f"{self.out}: cannot create the output folder ({e.strerror}); "
                               "check the path and permissions") from None
        write_text_atomic(path, json.dumps(manifest, indent=1, sort_keys=True))

    def __getstate__(self) -> dict[str, Any]:
        # a worker process writes parts but does not hold the run's lock
        return {k: v for k, v in self.__dict__.items() if k != "lock"}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.lock = OutputLock(self.out / ".slitcli" / "lock", None, time.time())

    def close(self) -> None:
        """Release the folder's run lock (also released when the process ends)."""
        self.lock.release()

    def __enter__(self) -> FrameBatch:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def resume(self, identities: list[str] | dict[int, str], kinds: Iterable[str]
               ) -> frozenset[int]:
        """The frames finished by an earlier run whose input is unchanged.

        ``identities[i]`` is frame i's :func:`frame_identity`. A frame whose identity
        differs from the recorded one loses its parts of ``kinds`` first (so a kill
        before its new parts are complete never passes old results off as new), then
        the new identity is recorded.
        """
        kinds = tuple(kinds)
        done = []
        pairs = identities.items() if isinstance(identities, dict) else enumerate(identities)
        for i, ident in pairs:
            part = self.part_path(i, "input")
            try:
                old = part.read_text()
            except OSError:
                old = None
            if old != ident:
                for k in kinds:
                    self.part_path(i, k).unlink(missing_ok=True)
                write_text_atomic(part, ident)
            elif self.is_done(i, kinds) and not self.is_skipped(i):
                done.append(i)
        return frozenset(done)

    def part_path(self, frame: int, kind: str = "rows") -> Path:
        return self.parts / f"{frame:06d}.{kind}.csv"

    def is_done(self, frame: int, kinds: Iterable[str] = ("rows",)) -> bool:
        return all(self.part_path(frame, k).exists() for k in kinds)

    def mark_skipped(self, frame: int, name: str, reason: str, kinds: Iterable[str]) -> None:
        """Record a frame that could not be read: empty parts of ``kinds`` (so the table
        assembles) and why. A skipped frame is not finished: a re-run tries it again."""
        for k in kinds:
            write_text_atomic(self.part_path(frame, k), "")
        write_text_atomic(self.part_path(frame, "skipped"), json.dumps([frame, name, reason]))

    def is_skipped(self, frame: int) -> bool:
        return self.part_path(frame, "skipped").exists()

    def clear_skipped(self, frame: int) -> None:
        self.part_path(frame, "skipped").unlink(missing_ok=True)

    def write_skipped(self, n_frames: int, target: Path) -> int:
        """Write ``target`` (frame,name,reason) listing the skipped frames, if any (an old
        list is removed when none is left); returns how many."""
        from slitcli.io.atomic import write_csv_atomic

        rows = [json.loads(self.part_path(i, "skipped").read_text())
                for i in range(n_frames) if self.is_skipped(i)]
        if rows:
            import pandas as pd

            write_csv_atomic(target, pd.DataFrame(rows, columns=["frame", "name", "reason"]))
        else:
            target.unlink(missing_ok=True)
        return len(rows)

    def assemble(self, n_frames: int, kind: str, target: Path, header: str) -> None:
        """Concatenate the parts of frames 0..n-1 (each without header) into ``target``."""
        chunks = [header.rstrip("\n") + "\n"]
        for i in range(n_frames):
            chunks.append(self.part_path(i, kind).read_text())
        write_text_atomic(target, "".join(chunks))


def _changed_keys(old: Any, new: dict[str, Any]) -> str:
    if not isinstance(old, dict):
        return "unreadable manifest"
    keys = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    return ", ".join(keys) or "format"


def _die_with(run_pid: int, parent_pid: int) -> None:
    """Watchdog of a worker: exit at once when the run or the worker's parent is gone."""
    while True:
        time.sleep(WORKER_WATCH_S)
        if os.getppid() != parent_pid or not _alive(run_pid):
            os._exit(1)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _worker_start(run_pid: int, initializer: Callable[[], None] | None) -> None:
    """Pool initializer: tie the worker's life to the run's, then ``initializer``.

    A worker blocked on its task queue would outlive a run killed with SIGKILL, holding
    the caller's stdout and stderr (``slitcli detect | tee log`` would never end). On
    Linux the kernel kills it when its parent, the run, exits (``PR_SET_PDEATHSIG``);
    everywhere a watchdog thread ends it within ``WORKER_WATCH_S`` of the run's end.
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass  # the watchdog still covers it
    parent = os.getppid()
    if parent != run_pid or not _alive(run_pid):  # the run ended before the line above
        os._exit(1)
    threading.Thread(target=_die_with, args=(run_pid, parent), daemon=True,
                     name="slitcli-watchdog").start()
    # Ctrl-C and SIGTERM go to the run, which shuts the pool down; a worker stopped
    # mid-frame by the terminal's SIGINT would only print a traceback
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if initializer is not None:
        initializer()


def run_pool(tasks: Iterable[Any], work: Callable[[Any], Any], *, jobs: int,
             initializer: Callable[[], None] | None = None) -> Iterator[Any]:
    """Apply ``work`` to every task, in order, with ``jobs`` processes.

    At most ``2 * jobs`` tasks are in flight, so a long sequence streams through with
    flat memory. With ``jobs == 1`` everything runs in this process. Worker processes
    end with this process, however it ends (:func:`_worker_start`).
    """
    check_jobs(jobs)
    if jobs == 1:
        if initializer is not None:
            initializer()
        for t in tasks:
            yield work(t)
        return
    # spawn, not fork: this process may already run threads (OpenCV, the stereo kernels'
    # pool, compiled libraries), and a child forked while one holds a lock waits forever.
    # Not forkserver either: its server and a worker it forked while this process was killed
    # keep each other alive (each holds the other's pipe), holding stdout and stderr;
    # spawned workers are this process's children, which PR_SET_PDEATHSIG can tie to it
    ctx = multiprocessing.get_context("spawn")
    start = partial(_worker_start, os.getpid(), initializer)
    with ProcessPoolExecutor(max_workers=jobs, initializer=start, mp_context=ctx) as pool:
        inflight: deque[Future] = deque()
        try:
            for t in tasks:
                inflight.append(pool.submit(work, t))
                if len(inflight) >= 2 * jobs:
                    yield inflight.popleft().result()
            while inflight:
                yield inflight.popleft().result()
        except BaseException:
            # an error or Ctrl-C: queued frames are not started (the resume does them)
            pool.shutdown(wait=True, cancel_futures=True)
            raise


def single_thread_worker() -> None:
    """Pool initializer: one thread for OpenCV and for the compiled kernels per worker
    process (the pool is the parallelism; nested threads would oversubscribe the cores)."""
    import cv2

    from slitcli.stereo.bands import THREADS_ENV

    cv2.setNumThreads(1)
    os.environ[THREADS_ENV] = "1"
