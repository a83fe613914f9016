"""Rows in bands over threads: how the compiled stereo kernels use the cores.

The compiled kernels release the GIL and each band of rows depends
only on read-only inputs, so plain threads run bands in parallel (no process pool, no
copies).
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

from slitcli.errors import SlitcliError

#: environment variable: most threads a frame's kernels use (default: every core); the
#: workers of a process pool set it to 1 (slitcli.io.batch.single_thread_worker)
THREADS_ENV = "SLITCLI_THREADS"


def thread_setting() -> int:
    """Most threads a frame's kernels may use: ``SLITCLI_THREADS``, default the number of
    cores. A value that is no positive whole number is a :class:`SlitcliError` naming the
    variable (the stereo parameter checks call this before a run writes anything)."""
    setting = os.environ.get(THREADS_ENV, "").strip()
    try:
        wanted = int(setting) if setting else (os.cpu_count() or 1)
    except ValueError:
        wanted = 0
    if wanted < 1:
        raise SlitcliError(f"{THREADS_ENV}={setting!r} is not a positive whole number of "
                           "threads; set it to 1 or more, or unset it for every core",
                           param=THREADS_ENV)
    return wanted


def kernel_threads() -> int:
    """Threads for the compiled kernels of one frame.

    At most ``SLITCLI_THREADS`` (default the number of cores; 1 in the workers of a
    process pool), and only cores that no other runnable task holds
    right now (Linux ``/proc/loadavg``; this thread is one of the runnable tasks). A
    band of rows handed to a core that another process holds waits for that core's
    time slice, and every kernel of the frame waits for its slowest band: measured on
    the 2-core development machine under a competing busy loop, a second thread made
    a frame slower, not faster (docs/notes/stereo-kernels.md).
    """
    wanted = thread_setting()
    if wanted <= 1:
        return 1
    try:
        with open("/proc/loadavg", encoding="ascii") as fh:
            running = int(fh.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return wanted
    free = (os.cpu_count() or wanted) - (running - 1)
    return max(1, min(wanted, free))


def run_row_bands(fn: Callable[[int, int], object], height: int,
                  pool: ThreadPoolExecutor | None, threads: int, *, min_rows: int = 8) -> None:
    """Call ``fn(y0, y1)`` over bands of rows covering 0..height.

    The compiled kernels release the GIL, so the threads of ``pool`` run them in
    parallel with this one. There are twice as many bands as ``threads``, taken one
    at a time by whichever thread is free (this one included), so a core that is busy
    with something else does not hold up the whole image; idle threads sleep (no
    spinning). Bands are at least ``min_rows`` rows (a band re-reads the window's rows
    above it). Without a pool the whole image is one band, run here.
    """
    bands = max(1, min(2 * threads, height // max(1, min_rows)))
    if pool is None or bands == 1:
        fn(0, height)
        return
    edges = [b * height // bands for b in range(bands + 1)]
    todo = itertools.pairwise(edges)
    lock = threading.Lock()

    def work() -> None:
        while True:
            with lock:
                band = next(todo, None)
            if band is None:
                return
            fn(*band)

    helpers = [pool.submit(work) for _ in range(threads - 1)]
    work()
    for f in helpers:
        f.result()


__all__ = ["THREADS_ENV", "kernel_threads", "run_row_bands", "thread_setting"]
