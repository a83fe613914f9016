"""Rows in bands over threads: how the compiled stereo kernels use the cores.

The compiled kernels release the GIL and each band of rows depends
only on read-only inputs, so plain threads run bands in parallel (no process pool, no
copies).
"""

from __future__ import annotations

import itertools
import os
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

from slitcli.errors import SlitcliError

#: environment variable: most threads a frame's kernels use (default: every core); the
#: workers of a process pool set it to 1 (slitcli.io.batch.single_thread_worker)
THREADS_ENV = "SLITCLI_THREADS"


def _setting() -> int | None:
    """``SLITCLI_THREADS`` as a whole number, None when unset; a value that is no
    positive whole number is a :class:`SlitcliError` naming the variable."""
    setting = os.environ.get(THREADS_ENV, "").strip()
    if not setting:
        return None
    try:
        wanted = int(setting)
    except ValueError:
        wanted = 0
    if wanted < 1:
        raise SlitcliError(f"{THREADS_ENV}={setting!r} is not a positive whole number of "
                           "threads; set it to 1 or more, or unset it for every core",
                           param=THREADS_ENV)
    return wanted


def check_thread_setting() -> None:
    """Raise :class:`SlitcliError` naming ``SLITCLI_THREADS`` when it is set to no
    positive whole number (the stereo parameter checks call this before a run writes
    anything; unlike :func:`thread_setting` it does not count the cores)."""
    _setting()


def thread_setting(cores: int | None = None) -> int:
    """Most threads a frame's kernels may use: ``SLITCLI_THREADS``, default the number of
    cores (``cores``, counted here when None). A value that is no positive whole number
    is a :class:`SlitcliError` naming the variable."""
    wanted = _setting()
    if wanted is None:
        wanted = cores if cores is not None else (os.cpu_count() or 1)
    return wanted


def kernel_threads() -> int:
    """Threads for the compiled kernels of one frame.

    At most ``SLITCLI_THREADS`` (default the number of cores; 1 in the workers of a
    process pool), and only cores that no other runnable task holds
    right now (Linux ``/proc/loadavg``; this thread is one of the runnable tasks). A
    band of rows handed to a core that another process holds waits for that core's
    time slice, and every kernel of the frame waits for its slowest band: measured on
    the 2-core development machine under a competing busy loop, a second thread made
    a frame slower, not faster (docs/notes/stereo-kernels.md). The cores are counted
    once a call (``os.cpu_count`` reads sysfs: 0.02-0.14 ms).
    """
    cores = os.cpu_count() or 1
    wanted = thread_setting(cores)
    if wanted <= 1:
        return 1
    try:
        with open("/proc/loadavg", encoding="ascii") as fh:
            running = int(fh.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return wanted
    free = cores - (running - 1)
    return max(1, min(wanted, free))


@contextmanager
def frame_pool(pool: ThreadPoolExecutor | None, threads: int
               ) -> Iterator[ThreadPoolExecutor | None]:
    """The helper threads of one frame that runs on ``threads`` threads: None for one
    thread; else the caller's ``pool`` (one per sequence, owned and shut down by the
    caller: starting and joining a thread pool costs about 0.5 ms, a twentieth of a
    320 x 240 frame), or, without one, a pool of ``threads - 1`` workers for this
    frame only, shut down when the frame ends."""
    if threads <= 1:
        yield None
    elif pool is not None:
        yield pool
    else:
        with ThreadPoolExecutor(max_workers=threads - 1) as own:
            yield own


#: bands per thread, taken one at a time by whichever thread is free: a thread that
#: another process delays holds up the frame by one band at most (a band costs a call,
#: ~20 us at 320x240: eight laser bands cost 5-9 % of its kernel's time, four half that)
BANDS_PER_THREAD = 2


def run_bands(fn: Callable[[int, int], object], n: int, threads: int, *, min_len: int,
              pool: ThreadPoolExecutor | None = None) -> None:
    """Call ``fn(i0, i1)`` over bands covering 0..n (rows or columns) on ``threads``
    threads: this one and ``threads - 1`` helpers from ``pool`` (new daemon threads
    without one). ``fn`` must release the GIL to run in parallel.

    There are ``BANDS_PER_THREAD`` bands a thread, each at least ``min_len`` long, taken
    one at a time by whichever thread is free, so a core that is busy with something
    else does not hold up the whole image; idle threads sleep (no spinning). This thread
    returns when every band is done, not when the helpers are: a helper that a busy
    machine starts late finds no band left and ends on its own. An exception of ``fn``
    is raised here once every band has ended.
    """
    bands = max(1, min(BANDS_PER_THREAD * threads, n // max(1, min_len)))
    if threads <= 1 or bands == 1:
        fn(0, n)
        return
    edges = [b * n // bands for b in range(bands + 1)]
    todo = itertools.pairwise(edges)
    lock = threading.Lock()
    finished = threading.Event()
    left = [bands]
    errors: list[BaseException] = []

    def work() -> None:
        while True:
            with lock:
                span = next(todo, None)
            if span is None:
                return
            try:
                fn(*span)
            except BaseException as exc:  # (raised again by the caller)
                errors.append(exc)
            with lock:
                left[0] -= 1
                if left[0] == 0:
                    finished.set()

    for _ in range(threads - 1):
        if pool is not None:
            pool.submit(work)
        else:
            threading.Thread(target=work, daemon=True).start()
    work()
    finished.wait()
    if errors:
        raise errors[0]


def run_row_bands(fn: Callable[[int, int], object], height: int,
                  pool: ThreadPoolExecutor | None, threads: int, *, min_rows: int = 8) -> None:
    """Call ``fn(y0, y1)`` over bands of rows covering 0..height with :func:`run_bands`
    on ``pool``'s threads; bands are at least ``min_rows`` rows (a band re-reads the
    window's rows above it). Without a pool the whole image is one band, run here.
    """
    if pool is None:
        fn(0, height)
        return
    run_bands(fn, height, threads, min_len=min_rows, pool=pool)


__all__ = ["BANDS_PER_THREAD", "THREADS_ENV", "check_thread_setting", "frame_pool",
           "kernel_threads", "run_bands", "run_row_bands", "thread_setting"]
