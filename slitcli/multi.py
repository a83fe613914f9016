"""Detection over many recordings: one output folder per input, serially or on a cluster.

:func:`run_detect_many` takes any mix of sequence folders and ROS bags. With one input
it writes exactly what :func:`slitcli.detect.run_detect` writes (``OUT/ranges.csv``);
with several, ``OUT/<input name>/`` per input (:func:`output_names`) and
``OUT/index.csv`` (:data:`INDEX_COLUMNS`).

The work is split into chunks: per input, and with ``chunk_frames`` into runs of that
many frames. A chunk computes its frames' parts in the input's resumable batch
(``run_detect(..., frames=range)``); once every chunk of an input is finished, the
table is assembled from the parts in frame order. So the table is byte-identical
whatever the chunking, the number of workers and the interruptions, and a re-run after
a kill keeps every finished frame. Chunks run in this process, or on a Dask cluster
(:mod:`slitcli.cluster`) whose workers see the same filesystem.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from slitcli.errors import SlitcliError
from slitcli.io.atomic import write_text_atomic
from slitcli.io.progress import RunSummary

INDEX_FILE = "index.csv"
#: ``OUT/index.csv``: one row per input, in the order given.
INDEX_COLUMNS = ("input", "output", "frames", "resumed", "status", "seconds", "message")
_MARK = Path(".slitcli") / "many.json"


@dataclass(frozen=True)
class Chunk:
    """Frames ``frames`` of input number ``input`` (an index into the inputs)."""

    input: int
    frames: range


@dataclass(frozen=True)
class ChunkResult:
    """What a chunk did: frames computed, frames found finished, worker seconds."""

    chunk: Chunk
    computed: int
    resumed: int
    seconds: float


@dataclass(frozen=True)
class ManyProgress:
    """Progress of a run over many inputs: inputs and frames finished, of how many."""

    inputs_done: int
    inputs: int
    frames_done: int
    frames: int
    chunks_resumed: int = 0


@dataclass(frozen=True)
class ManySummary:
    """What :func:`run_detect_many` did.

    ``per_input`` holds each input's :class:`RunSummary` (None where it failed),
    ``chunks_resumed`` the chunks whose frames were all finished by an earlier run
    (not computed again), ``failed`` the inputs that could not be read, with why.
    """

    inputs: tuple[Path, ...]
    outputs: tuple[Path, ...]
    per_input: tuple[RunSummary | None, ...]
    frames: int
    computed: int
    chunks: int
    chunks_resumed: int
    seconds: float
    failed: tuple[tuple[Path, str], ...] = ()
    index: Path | None = None
    notes: tuple[str, ...] = field(default=())


def read_inputs_file(path: str | Path) -> list[Path]:
    """The inputs listed in a text file, one per line (``#`` comments and blank lines
    ignored; relative paths are relative to the file's folder)."""
    p = Path(path)
    try:
        lines = p.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise SlitcliError(f"{p}: cannot read this list of inputs (`inputs`: {e}); give a "
                           "text file with one sequence folder or bag per line",
                           param="inputs") from None
    out = []
    for line in lines:
        s = line.split("#", 1)[0].strip()
        if s:
            q = Path(s).expanduser()
            out.append(q if q.is_absolute() else p.parent / q)
    if not out:
        raise SlitcliError(f"{p}: lists no inputs (`inputs`); give one sequence folder or bag "
                           "per line",
                           param="inputs")
    return out


def output_names(sources: Sequence[str | Path]) -> list[str]:
    """One output folder name per input: its file or folder name without ``.bag``; a
    name taken by an earlier input gets ``-2``, ``-3``... (first come, first named, so
    the same list always gives the same names)."""
    used: set[str] = set()
    names = []
    for s in sources:
        p = Path(s).resolve()
        base = (p.stem if p.suffix.lower() == ".bag" else p.name) or "input"
        name, k = base, 1
        while name in used:
            k += 1
            name = f"{base}-{k}"
        used.add(name)
        names.append(name)
    return names


def plan_chunks(n_frames: Sequence[int], chunk_frames: int | None) -> list[Chunk]:
    """Chunks of at most ``chunk_frames`` frames per input (None: one per input), in
    input order; an input with no frames gets one empty chunk."""
    if chunk_frames is not None and chunk_frames < 1:
        raise SlitcliError(f"`chunk_frames` {chunk_frames} must be at least 1",
                           param="chunk_frames")
    chunks = []
    for i, n in enumerate(n_frames):
        k = max(n, 1) if chunk_frames is None else chunk_frames
        chunks += [Chunk(i, range(a, min(a + k, n))) for a in range(0, max(n, 1), k)]
    return chunks


def detect_chunk(source: Path, target: Path, kwargs: dict[str, Any], chunk: Chunk
                 ) -> ChunkResult:
    """Compute one chunk's frames in ``target``'s batch (run on a worker or here)."""
    from slitcli.detect import run_detect

    # the client holds the run lock; a worker in another process must not wait for it
    s = run_detect(source, target, frames=chunk.frames, overwrite=False, lock=False,
                   **kwargs)
    return ChunkResult(chunk, s.computed, s.resumed, s.seconds)


Submit = Callable[[list[Chunk]], Iterator[ChunkResult | tuple[Chunk, BaseException]]]


def serial_runner(sources: Sequence[Path], targets: Sequence[Path], kwargs: dict[str, Any]
                  ) -> Submit:
    """Run chunks one after another in this process (``kwargs['jobs']`` processes each)."""
    def run(chunks: list[Chunk]) -> Iterator[ChunkResult | tuple[Chunk, BaseException]]:
        for c in chunks:
            try:
                yield detect_chunk(sources[c.input], targets[c.input], kwargs, c)
            except SlitcliError as e:
                yield c, e
    return run


def _check_out(out: Path, sources: list[Path], names: list[str], overwrite: bool) -> None:
    """OUT must be empty, or a many-input output of slitcli; remember the inputs."""
    mark = out / _MARK
    if out.exists() and not out.is_dir():
        raise SlitcliError(f"{out}: is a file; give a folder for the outputs", param="out")
    if out.exists() and any(out.iterdir()) and not mark.exists() and not overwrite:
        existing = next(iter(out.iterdir())).name
        raise SlitcliError(f"{out}: is not empty (it holds {existing}) and was not written by "
                           "slitcli detect over many inputs; choose another output folder or "
                           "pass `overwrite`", param="overwrite")
    try:
        mark.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SlitcliError(f"{out}: cannot create the output folder ({e.strerror}); check "
                           "the path and permissions", param="out") from None
    write_text_atomic(mark, json.dumps({"inputs": [str(s) for s in sources], "names": names},
                                       indent=1))


def _write_index(path: Path, rows: list[tuple[object, ...]]) -> None:
    import pandas as pd

    from slitcli.io.atomic import write_csv_atomic

    write_csv_atomic(path, pd.DataFrame(rows, columns=list(INDEX_COLUMNS)),
                     float_format="%.3f")


def _prepare(srcs: list[Path], targets: list[Path], overwrite: bool, kwargs: dict[str, Any]
             ) -> tuple[list[int], dict[int, str]]:
    """Open every input and set its batch up, before any chunk runs: bad inputs fail
    fast, and the workers find the batches made (they never overwrite). Returns the
    frame counts and the errors by input (one input: its error is raised)."""
    from slitcli.detect import run_detect
    from slitcli.io.frames import (
        DEFAULT_LEFT_TOPIC,
        DEFAULT_MAX_DT_S,
        DEFAULT_RIGHT_TOPIC,
        open_frames,
    )

    open_kw = {"left_topic": kwargs.get("left_topic", DEFAULT_LEFT_TOPIC),
               "right_topic": kwargs.get("right_topic", DEFAULT_RIGHT_TOPIC),
               "max_dt_s": kwargs.get("max_dt_s", DEFAULT_MAX_DT_S)}
    n_frames: list[int] = []
    errors: dict[int, str] = {}
    for i, (s, t) in enumerate(zip(srcs, targets, strict=True)):
        try:
            n_frames.append(len(open_frames(s, **open_kw)))
            run_detect(s, t, frames=range(0), overwrite=overwrite, **kwargs)
        except SlitcliError as e:
            if len(srcs) == 1:
                raise
            n_frames += [0] * (i + 1 - len(n_frames))
            errors[i] = str(e)
    return n_frames, errors


def run_detect_many(sources: Sequence[str | Path], out: str | Path, *,
                    chunk_frames: int | None = None,
                    make_runner: Callable[[list[Path], list[Path], dict[str, Any]], Submit]
                    | None = None,
                    on_progress: Callable[[ManyProgress], None] | None = None,
                    overwrite: bool = False, **kwargs: Any) -> ManySummary:
    """Detect obstacles in many sequence folders and bags.

    Parameters
    ----------
    sources : sequence of path
        Sequence folders and ROS bags, any mix; each at most once.
    out : path
        One input: the output folder itself (``OUT/ranges.csv``, as ``run_detect``).
        Several: ``OUT/<name>/`` per input (:func:`output_names`) and ``OUT/index.csv``.
    chunk_frames : int, optional
        Split each input into chunks of this many frames (default: one chunk per input).
    make_runner : callable, optional
        ``make_runner(sources, targets, kwargs)`` returns how chunks run (default
        :func:`serial_runner`; :func:`slitcli.cluster.dask_runner` for a cluster).
    on_progress : callable, optional
        Called with a :class:`ManyProgress` at the start and after every chunk.
    overwrite : bool
        Replace results made with other settings.
    **kwargs
        The settings of :func:`slitcli.detect.run_detect` (``rig_path``, ``params``,
        ``jobs``, ``save_images``, topics, ``max_dt_s``, ``on_bad_frame``).

    Returns
    -------
    ManySummary
        A single input whose reading fails raises :class:`SlitcliError`; with several,
        the failed ones are listed (``failed``, and ``status`` in index.csv) and the
        others finish.
    """
    from slitcli.detect import run_detect

    t0 = time.perf_counter()
    srcs = _distinct_inputs(sources)
    out = Path(out)
    single = len(srcs) == 1
    names = output_names(srcs)
    if not single:
        _check_out(out, srcs, names, overwrite)
    targets = [out] if single else [out / n for n in names]
    n_frames, errors = _prepare(srcs, targets, overwrite, kwargs)
    chunks = [c for c in plan_chunks(n_frames, chunk_frames) if c.input not in errors]
    tally = _Tally(len(srcs), sum(n for i, n in enumerate(n_frames) if i not in errors),
                   errors, on_progress)
    for c in chunks:
        tally.left[c.input] += 1

    def finish(i: int) -> RunSummary:
        # every frame is finished: this assembles the table from the parts
        return run_detect(srcs[i], targets[i], overwrite=False, **kwargs)

    tally.report()
    run = (make_runner or serial_runner)(srcs, targets, {**kwargs})
    for r in run(chunks):
        tally.take(r, single, finish)
    index = None
    if not single:
        index = out / INDEX_FILE
        _write_index(index, [
            (str(s), names[i], n_frames[i], tally.resumed[i],
             "failed" if i in errors else "done", tally.worker_s[i], errors.get(i, ""))
            for i, s in enumerate(srcs)])
    outputs = tuple(t for i, t in enumerate(targets) if i not in errors)
    notes = tuple(n for s in tally.summaries if s is not None for n in s.notes)
    return ManySummary(tuple(srcs), outputs, tuple(tally.summaries), tally.total,
                       tally.computed, len(chunks), tally.chunks_resumed,
                       time.perf_counter() - t0,
                       tuple((srcs[i], m) for i, m in sorted(errors.items())), index, notes)


def _distinct_inputs(sources: Sequence[str | Path]) -> list[Path]:
    """The inputs as paths; none, or one given twice (as another spelling of the same
    path too), is an error."""
    srcs = [Path(s) for s in sources]
    if not srcs:
        raise SlitcliError("no inputs given; give sequence folders or bags", param="sources")
    seen: set[Path] = set()
    for s in srcs:
        if s.resolve() in seen:
            raise SlitcliError(f"{s}: is given twice; give each input once", param="sources")
        seen.add(s.resolve())
    return srcs


class _Tally:
    """What the chunks of a many-input run have done so far: per input (chunks left,
    frames resumed, worker seconds, its summary once assembled, its error) and in all
    (for :class:`ManyProgress`)."""

    def __init__(self, n_inputs: int, total: int, errors: dict[int, str],
                 on_progress: Callable[[ManyProgress], None] | None) -> None:
        self.n_inputs, self.total, self.errors = n_inputs, total, errors
        self.on_progress = on_progress
        self.left = {i: 0 for i in range(n_inputs) if i not in errors}
        self.worker_s = dict.fromkeys(range(n_inputs), 0.0)
        self.resumed = dict.fromkeys(range(n_inputs), 0)
        self.summaries: list[RunSummary | None] = [None] * n_inputs
        self.frames_done = self.computed = self.chunks_resumed = 0
        self.inputs_done = len(errors)

    def report(self) -> None:
        if self.on_progress is not None:
            self.on_progress(ManyProgress(self.inputs_done, self.n_inputs, self.frames_done,
                                          self.total, self.chunks_resumed))

    def take(self, r: ChunkResult | tuple[Chunk, BaseException], single: bool,
             finish: Callable[[int], RunSummary]) -> None:
        """Count one chunk's result (or its failure); the last chunk of an input
        assembles that input's table (``finish``). A single input's failure, and any
        that is not a :class:`SlitcliError`, is raised; with several inputs the
        input is marked failed and the others go on."""
        if isinstance(r, tuple):
            c, e = r
            if single or not isinstance(e, SlitcliError):
                raise e
            if c.input not in self.errors:
                self.errors[c.input] = str(e)
                self.inputs_done += 1
                self.report()
            return
        i = r.chunk.input
        self.frames_done += len(r.chunk.frames)
        self.computed += r.computed
        self.resumed[i] += r.resumed
        self.worker_s[i] += r.seconds
        self.chunks_resumed += r.computed == 0 and len(r.chunk.frames) > 0
        self.left[i] -= 1
        if self.left[i] == 0 and i not in self.errors:
            try:
                self.summaries[i] = summary = finish(i)
            except SlitcliError as e:
                if single:
                    raise
                self.errors[i] = str(e)
            else:
                self.worker_s[i] += summary.seconds
            self.inputs_done += 1
        self.report()


def summary_line(s: ManySummary) -> str:
    """The line ``slitcli detect`` prints for many inputs (or a chunked single one)."""
    line = (f"detect: {len(s.inputs) - len(s.failed)}/{len(s.inputs)} inputs, {s.frames} "
            f"frames ({s.computed} computed, {s.chunks_resumed} of {s.chunks} chunks kept "
            f"from an earlier run) in {s.seconds:.1f} s")
    if s.index is not None:
        line += f"; index: {s.index}"
    return line


__all__ = ["INDEX_COLUMNS", "Chunk", "ChunkResult", "ManyProgress", "ManySummary",
           "detect_chunk", "output_names", "plan_chunks", "read_inputs_file",
           "run_detect_many", "serial_runner", "summary_line"]
