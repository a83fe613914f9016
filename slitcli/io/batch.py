"""Resumable, parallel batches over frames.

A batch keeps its state in ``OUT/.slitcli/<name>/``: ``manifest.json`` (the arguments,
rig and input that define the results, and the slitcli version that made them) and one
part file per finished frame, each written atomically. A re-run with the same manifest
skips the finished frames (also after ``kill -9``); a different manifest is refused
unless ``overwrite``. The final table is assembled from the parts in frame order, so it
is byte-identical whatever the number of workers and however often the run was
interrupted.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import shutil
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any

from slitcli import __version__
from slitcli.errors import SlitcliError
from slitcli.io.atomic import write_text_atomic


def file_digest(path: Path) -> str:
    """SHA-256 of a file's bytes (for manifests)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


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
    """

    def __init__(self, out: Path, name: str, manifest: dict[str, Any], *,
                 overwrite: bool = False) -> None:
        self.out = Path(out)
        self.dir = self.out / ".slitcli" / name
        self.parts = self.dir / "parts"
        # another slitcli version may compute other results from the same arguments
        manifest = {**manifest, "slitcli_version": __version__}
        self.manifest = manifest
        path = self.dir / "manifest.json"
        if path.exists():
            try:
                old = json.loads(path.read_text())
            except (OSError, json.JSONDecodeError):
                old = None
            if old != manifest:
                if not overwrite:
                    changed = _changed_keys(old, manifest)
                    raise SlitcliError(
                        f"{self.out}: holds {name} results made with other settings "
                        f"(changed: {changed}); pass `overwrite` to replace them or choose "
                        "another output folder", param="overwrite")
                shutil.rmtree(self.dir)
        elif self.out.exists() and any(self.out.iterdir()) and not overwrite:
            existing = next(iter(self.out.iterdir())).name
            raise SlitcliError(f"{self.out}: is not empty (it holds {existing}) and was not "
                               f"written by slitcli {name}; choose another output folder or "
                               "pass `overwrite`", param="overwrite")
        try:
            self.parts.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise SlitcliError(f"{self.out}: cannot create the output folder ({e.strerror}); "
                               "check the path and permissions") from None
        write_text_atomic(path, json.dumps(manifest, indent=1, sort_keys=True))

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


def run_pool(tasks: Iterable[Any], work: Callable[[Any], Any], *, jobs: int,
             initializer: Callable[[], None] | None = None) -> Iterator[Any]:
    """Apply ``work`` to every task, in order, with ``jobs`` processes.

    At most ``2 * jobs`` tasks are in flight, so a long sequence streams through with
    flat memory. With ``jobs == 1`` everything runs in this process.
    """
    if jobs < 1:
        raise SlitcliError(f"`jobs` {jobs} must be at least 1", param="jobs")
    if jobs == 1:
        if initializer is not None:
            initializer()
        for t in tasks:
            yield work(t)
        return
    # forkserver, not fork: this process may already run threads (OpenCV, the stereo
    # kernels' pool, numba), and a child forked while one holds a lock waits forever
    ctx = multiprocessing.get_context("forkserver")
    with ProcessPoolExecutor(max_workers=jobs, initializer=initializer, mp_context=ctx) as pool:
        inflight: deque[Future] = deque()
        for t in tasks:
            inflight.append(pool.submit(work, t))
            if len(inflight) >= 2 * jobs:
                yield inflight.popleft().result()
        while inflight:
            yield inflight.popleft().result()


def single_thread_worker() -> None:
    """Pool initializer: one OpenCV/numba thread per worker process (the pool is the
    parallelism; nested threads would oversubscribe the cores)."""
    import cv2
    import numba

    cv2.setNumThreads(1)
    numba.set_num_threads(1)
