"""Compile every numba kernel once, at set-up, so that no command waits for the compiler.

slitcli's hot kernels are ``@njit(cache=True)`` functions: numba compiles each to
machine code for this processor on first use and keeps the result in ``__pycache__``
beside its source file (``*.nbi`` index + ``*.nbc`` code). Compiling all of them takes
about a minute of CPU; loading them back takes milliseconds each. :func:`warm_up` pays
that minute at set-up (``make venv`` runs ``slitcli warm-up``), on all cores, instead
of on a user's first ``slitcli detect``.

How the kernels are found
-------------------------
The warm-up does not list kernels or signatures: it runs the library's own pipelines
on a one-frame scene that it renders (render, laser, stereo with and without
semi-global aggregation, detect, the DWA simulation with moving obstacles), so every
kernel those pipelines call is compiled with exactly the argument types a user's run
gives it. A kernel added to any module is covered as soon as a pipeline calls it. The
jobs run in separate processes (one per core): numba compiles in one thread per process.

:func:`kernel_inventory` reads every ``@njit``/``@jit`` function from the package's
sources (no import); the report names the kernels no job reached. Those compile on
first use, and :func:`slitcli.compile_notice.announce_compiles` makes the command line
say so on stderr.

Cache validity
--------------
numba keys a cache entry on the source file's modification time and size, the
function's name and line, the argument types and this CPU. A fresh clone, an editable
install and CI all compile into the work tree's ``__pycache__`` after checkout, so the
entries stay valid until a kernel file is edited (``make`` then runs the warm-up again:
the Makefile's kernel stamp depends on every kernel source).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # only the warm-up itself needs these at run time
    import ast
    from concurrent.futures import Future

PACKAGE_DIR = Path(__file__).resolve().parent

# Decorator names that make a numba kernel (``njit``, ``numba.njit``, ``nb.jit(...)``).
_JIT_NAMES = frozenset({"njit", "jit"})


@dataclass(frozen=True)
class JobResult:
    """What one warm-up job did in its process.

    Attributes
    ----------
    name : str
        The job (``render``, ``laser``, ...).
    seconds : float
        Wall time of the job in its worker, including imports and cache loads.
    cpu_s : float
        CPU time of the worker process over the job.
    compiled : int
        Kernel signatures compiled (numba cache misses) by this job.
    error : str
        Empty, or why the job failed (its kernels, and those of the jobs that need it,
        then compile on first use).
    """

    name: str
    seconds: float
    cpu_s: float
    compiled: int
    error: str = ""


@dataclass(frozen=True)
class WarmupReport:
    """The warm-up's result.

    Attributes
    ----------
    kernels : tuple of str
        Every kernel in the package sources (:func:`kernel_inventory`).
    ready : tuple of str
        Kernels of ``kernels`` with valid entries in numba's cache after the jobs.
    not_reached : tuple of str
        Kernels of ``kernels`` that no job called: compiled on first use.
    compiled : int
        Kernel signatures compiled in this warm-up (0 when the cache was complete).
    jobs : mapping str -> JobResult
        Per job.
    wall_s : float
        Wall time of the whole warm-up.
    workers : int
        Worker processes used.
    """

    kernels: tuple[str, ...]
    ready: tuple[str, ...]
    not_reached: tuple[str, ...]
    compiled: int
    jobs: MappingProxyType[str, JobResult]
    wall_s: float
    workers: int

    @property
    def failed(self) -> tuple[str, ...]:
        """The jobs that failed or were skipped for a failed job they need."""
        return tuple(name for name, r in self.jobs.items() if r.error)

    def summary_line(self) -> str:
        """One line for the user."""
        line = (f"kernels ready: {len(self.kernels) - len(self.not_reached)} of "
                f"{len(self.kernels)} ({self.compiled} signatures compiled, "
                f"{self.wall_s:.1f} s on {self.workers} processes)")
        if self.failed:
            line += "; failed jobs: " + ", ".join(self.failed)
        if self.not_reached:
            line += "; compiled on first use: " + ", ".join(self.not_reached)
        return line


def _is_kernel(decorator: ast.expr) -> bool:
    """A ``@njit``/``@jit`` decorator of a function compiled on its own: one with
    ``inline="always"`` is compiled into its callers only and has no cache entry."""
    import ast

    node = decorator.func if isinstance(decorator, ast.Call) else decorator
    if isinstance(decorator, ast.Call) and any(
            k.arg == "inline" and isinstance(k.value, ast.Constant) and k.value.value == "always"
            for k in decorator.keywords):
        return False
    if isinstance(node, ast.Name):
        return node.id in _JIT_NAMES
    return isinstance(node, ast.Attribute) and node.attr in _JIT_NAMES


def kernel_inventory(package_dir: Path = PACKAGE_DIR) -> tuple[str, ...]:
    """Every ``@njit``/``@jit``-decorated function in the package's sources that numba
    compiles and caches on its own (``inline="always"`` ones live in their callers).

    Read from the source text (nothing is imported), so it is the list of kernels as
    the files stand now, whoever added them.

    Returns
    -------
    tuple of str
        ``slitcli.module.qualname``, sorted.
    """
    import ast

    found = []
    root = package_dir.parent
    for path in sorted(package_dir.rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        if "jit" not in text:
            continue
        module = ".".join(path.relative_to(root).with_suffix("").parts)
        tree = ast.parse(text, filename=str(path))
        stack: list[tuple[ast.AST, str]] = [(tree, "")]
        while stack:
            node, prefix = stack.pop()
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.FunctionDef | ast.ClassDef):
                    qual = f"{prefix}{child.name}"
                    if isinstance(child, ast.FunctionDef) and any(
                            _is_kernel(d) for d in child.decorator_list):
                        found.append(f"{module}.{qual}")
                    inner = "<locals>." if isinstance(child, ast.FunctionDef) else ""
                    stack.append((child, f"{qual}.{inner}"))
    return tuple(sorted(found))


# -------------------------------------------------------------------------------- the jobs
# A one-frame scene with the laser on two boxes (paper Fig. 4), textured surfaces and a
# webcam's sensor (noise, blooming, Bayer, JPEG), so that every stage of the pipelines
# (stripe found, stereo matched, obstacles fused) runs on an image like a real one.
_SCENE = {
    "slitcli_scene": 1, "name": "warm-up", "seed": 4, "image": {"camera": "webcam"},
    "floor": {"colour_rgb": [0.55, 0.5, 0.45], "texture": "noise", "scale_m": 0.03,
              "contrast": 0.5},
    "objects": [
        {"type": "box", "centre_xy_m": [0.75, 0.22], "size_m": [0.3, 0.34, 0.45],
         "surface": {"colour_rgb": [0.62, 0.6, 0.55], "texture": "noise", "scale_m": 0.02,
                     "contrast": 0.6}},
        {"type": "box", "centre_xy_m": [0.95, -0.22], "size_m": [0.3, 0.34, 0.55],
         "surface": {"colour_rgb": [0.5, 0.55, 0.6], "texture": "noise", "scale_m": 0.02,
                     "contrast": 0.6}},
        {"type": "wall", "from_xy_m": [2.6, -2.0], "to_xy_m": [2.6, 2.0], "height_m": 2.0,
         "surface": {"colour_rgb": [0.7, 0.68, 0.62], "texture": "noise", "scale_m": 0.04,
                     "contrast": 0.5}},
    ],
    "robot": {"start": [0.0, 0.0, 0.0], "motion": "static", "frames": 1},
}


def _job_render(work: Path) -> None:
    from slitcli.rig import paper_rig
    from slitcli.sim.scene import scene_from_dict
    from slitcli.sim.sequence import render_sequence

    render_sequence(scene_from_dict(_SCENE, "warm-up scene"), paper_rig(), work / "seq",
                    frames=1, overwrite=True)


def _job_laser(work: Path) -> None:
    from slitcli.laser.batch import run_laser

    run_laser(work / "seq", work / "laser", overlay=True)


def _job_stereo(work: Path) -> None:
    from slitcli.stereo.run import run_stereo

    run_stereo(work / "seq", work / "stereo")


def _job_sgm(work: Path) -> None:
    from slitcli.stereo.matcher import MatcherParams
    from slitcli.stereo.obstacles import ObstacleParams
    from slitcli.stereo.pipeline import StereoParams
    from slitcli.stereo.run import run_stereo

    # the options that call kernels of their own: semi-global aggregation, floor check
    params = StereoParams(matcher=MatcherParams(aggregation="sgm"),
                          obstacles=ObstacleParams(floor_check_ratio=0.5))
    run_stereo(work / "seq", work / "sgm", params=params)


def _job_detect(work: Path) -> None:
    from slitcli.detect import run_detect

    run_detect(work / "seq", work / "detect", save_images=True)


def _job_dwa(work: Path) -> None:
    from slitcli.dwa import DwaParams
    from slitcli.rig import paper_rig
    from slitcli.sim.loop import SimParams, simulate_dwa

    # moving obstacles: the planner's prediction kernels run too
    simulate_dwa(work / "dwa", paper_rig(), DwaParams(), SimParams(max_time_s=2.0),
                 scenario="dynamic", worlds=1, overwrite=True)


# name -> (function, jobs it needs first). Longest first among the ready ones.
JOBS: MappingProxyType[str, tuple[Callable[[Path], None], tuple[str, ...]]] = MappingProxyType({
    "render": (_job_render, ()),
    "laser": (_job_laser, ("render",)),
    "stereo": (_job_stereo, ("render",)),
    "dwa": (_job_dwa, ()),
    "stereo-sgm": (_job_sgm, ("render",)),
    "detect": (_job_detect, ("laser", "stereo")),
})


def cached_kernels(kernels: Iterable[str]) -> tuple[str, ...]:
    """The kernels of ``kernels`` (``module.qualname``) with machine code in numba's cache.

    Imports their modules. A kernel counts when its cache index holds an entry that is
    valid for its source file as it stands (numba drops the entries of an edited file),
    or when it is compiled in this process.
    """
    import importlib

    from numba.core.dispatcher import Dispatcher

    ready = []
    for name in kernels:
        module_name, _, qualname = name.rpartition(".")
        while module_name and module_name not in sys.modules:
            try:
                importlib.import_module(module_name)
                break
            except ImportError:  # a nested qualname: move its head back
                module_name, _, head = module_name.rpartition(".")
                qualname = f"{head}.{qualname}"
        value: Any = sys.modules.get(module_name)
        for part in qualname.split("."):
            value = getattr(value, part, None)
        if isinstance(value, Dispatcher) and _has_cache_entry(value):
            ready.append(name)
    return tuple(ready)


def _has_cache_entry(dispatcher: Any) -> bool:
    if dispatcher.overloads:
        return True
    # numba's own index reader: {} when the index is missing, of another numba version
    # or stale (the source file's mtime or size changed)
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    try:
        return bool(cache_file._load_index()) if cache_file is not None else False
    except Exception:  # an unreadable index is a cache miss to numba too
        return False


def _run_job(name: str, work: str) -> JobResult:
    """One job in a worker process: run it, count compiles, list the kernels it holds."""
    t0, c0 = time.perf_counter(), time.process_time()
    from numba.core import event

    compiled = [0]

    class _Count(event.Listener):
        def on_start(self, event_: Any) -> None:
            compiled[0] += 1

        def on_end(self, event_: Any) -> None:
            pass

    error = ""
    with event.install_listener("numba:compile", _Count()):
        try:
            JOBS[name][0](Path(work))
        except Exception as e:  # reported, not raised: a set-up step must not stop here
            error = f"{e.__class__.__name__}: {str(e).splitlines()[0] if str(e) else ''}"
    return JobResult(name, time.perf_counter() - t0, time.process_time() - c0, compiled[0],
                     error)


def compile_bytecode(package_dir: Path = PACKAGE_DIR) -> bool:
    """Write the package's Python bytecode (``__pycache__/*.pyc``) where it is missing or
    out of date; True when every module compiled.

    Python writes it on first import, except where ``PYTHONDONTWRITEBYTECODE`` is set
    (many CI and container images) or the folder is not writable: then every start
    compiles each imported module's source again, about 0.2 s of CPU for a one-frame
    ``slitcli detect`` (docs/notes/startup.md). Python reads existing bytecode whatever
    that setting, and checks it against the source's modification time and size, so an
    edited module is compiled from source until the next warm-up.
    """
    import compileall

    return bool(compileall.compile_dir(package_dir, quiet=2, workers=1))


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def _run_jobs(todo: list[str], workers: int, say: Callable[[str], None]) -> dict[str, JobResult]:
    """Run ``todo`` (in :data:`JOBS` order) on ``workers`` spawned processes, each job once
    the jobs it needs have finished; a job whose input job failed is skipped."""
    import tempfile
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from multiprocessing import get_context

    results: dict[str, JobResult] = {}
    with tempfile.TemporaryDirectory(prefix="slitcli-warmup-") as work, ProcessPoolExecutor(
            max_workers=workers, mp_context=get_context("spawn")) as pool:
        running: dict[Future[JobResult], str] = {}
        pending = list(todo)
        while pending or running:
            for name in list(pending):
                needs = [results.get(d) for d in JOBS[name][1]]
                if any(r is not None and r.error for r in needs):  # skipped with its input
                    pending.remove(name)
                    results[name] = JobResult(name, 0.0, 0.0, 0, "needs a job that failed")
                    say(f"warm-up {name}: skipped, {results[name].error}")
                elif all(r is not None for r in needs):
                    pending.remove(name)
                    running[pool.submit(_run_job, name, work)] = name
            if not running:
                continue
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for future in done:
                name = running.pop(future)
                result = future.result()
                results[name] = result
                if result.error:
                    say(f"warm-up {name}: failed ({result.error}); its kernels compile on "
                        "first use")
                else:
                    say(f"warm-up {name}: {result.compiled} signatures compiled, "
                        f"{result.seconds:.1f} s ({result.cpu_s:.1f} s CPU)")
    return results


def warm_up(*, workers: int | None = None, jobs: Iterable[str] | None = None,
            on_progress: Callable[[str], None] | None = None) -> WarmupReport:
    """Compile (or load) every kernel the pipelines use, in parallel processes.

    Parameters
    ----------
    workers : int, optional
        Worker processes (default: the cores available to this process).
    jobs : iterable of str, optional
        A subset of :data:`JOBS` (the jobs they need are added); default all.
    on_progress : callable, optional
        Called with one line per finished job.

    Returns
    -------
    WarmupReport
    """
    from slitcli.errors import SlitcliError

    n_workers = default_workers() if workers is None else workers
    if n_workers < 1:
        raise SlitcliError(f"`workers` = {n_workers}: give at least 1 worker process")
    wanted = set(JOBS if jobs is None else jobs)
    unknown = wanted - set(JOBS)
    if unknown:
        raise SlitcliError(f"`jobs`: unknown warm-up job(s) {', '.join(sorted(unknown))}; "
                           f"use some of {', '.join(JOBS)}")
    todo = [n for n in JOBS if n in wanted]
    while True:  # add the jobs the chosen ones need
        needed = {d for n in todo for d in JOBS[n][1]} - set(todo)
        if not needed:
            break
        todo = [n for n in JOBS if n in set(todo) | needed]
    say = on_progress or (lambda _line: None)
    t0 = time.perf_counter()
    compile_bytecode()
    results = _run_jobs(todo, min(n_workers, len(todo)), say)
    kernels = kernel_inventory()
    ready = cached_kernels(kernels)
    return WarmupReport(
        kernels=kernels, ready=ready,
        not_reached=tuple(k for k in kernels if k not in set(ready)),
        compiled=sum(r.compiled for r in results.values()),
        jobs=MappingProxyType(results), wall_s=time.perf_counter() - t0,
        workers=min(n_workers, len(todo)))


__all__ = ["JOBS", "JobResult", "WarmupReport", "cached_kernels", "compile_bytecode",
           "default_workers", "kernel_inventory", "warm_up"]
