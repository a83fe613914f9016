"""Chunks of detection on a Dask cluster (``slitcli detect --cluster``, docs/cluster.md).

Dask's distributed scheduler is the engine: :func:`dask_client` starts a LocalCluster
of worker processes (``local:N``) or connects to a running scheduler
(``tcp://HOST:PORT``: SLURM through dask-jobqueue, Kubernetes through dask-kubernetes,
or ``dask scheduler`` / ``dask worker`` by hand), and :func:`dask_runner` sends the
chunks of :func:`slitcli.multi.run_detect_many` to it.

The client owns the output: it sets every input's batch up before any chunk runs and
assembles each table itself once its chunks are finished. A chunk task only writes its
frames' part files (atomically) into the batch, so a worker that dies loses at most its
frames in flight, and Dask's retry or a re-run recomputes only those. Inputs and outputs
must lie on a filesystem every worker sees under the same paths.

Dask is an optional extra (``pip install 'slitcli[cluster]'``); it is imported only when
a cluster is asked for.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from slitcli.errors import SlitcliError
from slitcli.multi import Chunk, ChunkResult, Submit, detect_chunk

INSTALL_HINT = "pip install 'slitcli[cluster]'"
_ADDRESS = re.compile(r"^(tcp|tls|ucx|inproc)://\S+$")
_LOCAL = re.compile(r"^local:(\d+)$")
MAX_LOCAL_WORKERS = 256


@dataclass(frozen=True)
class ClusterSpec:
    """Where chunks run: ``local_workers`` processes here, or the scheduler ``address``."""

    local_workers: int | None = None
    address: str | None = None


def parse_cluster(spec: str) -> ClusterSpec:
    """``local:N`` (N worker processes on this machine, 1-256) or a scheduler address
    (``tcp://HOST:PORT``, also ``tls://``)."""
    s = spec.strip()
    m = _LOCAL.match(s)
    if m:
        n = int(m.group(1))
        if not 1 <= n <= MAX_LOCAL_WORKERS:
            raise SlitcliError(f"`cluster` {spec!r}: give 1-{MAX_LOCAL_WORKERS} local workers",
                               param="cluster")
        return ClusterSpec(local_workers=n)
    if _ADDRESS.match(s):
        return ClusterSpec(address=s)
    raise SlitcliError(f"`cluster` {spec!r} is not understood; give local:N (N worker "
                       "processes here) or a scheduler address tcp://HOST:PORT",
                       param="cluster")


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise SlitcliError(f"`cluster` needs Dask, which is not installed; install it with "
                           f"{INSTALL_HINT}", param="cluster") from None
    return distributed


@contextmanager
def dask_client(spec: ClusterSpec, *, timeout_s: float = 10.0) -> Iterator[Any]:
    """A Dask client for ``spec``, closed on leaving (a LocalCluster's workers with it,
    also on errors and Ctrl-C).

    A LocalCluster runs one worker process per core asked for, one thread each
    (``processes=True, threads_per_worker=1``): detection holds the GIL in parts, and
    the processes are the parallelism; Dask's profiler is off in them. Its workers exit
    with this process, even when it is killed (each watches its parent).
    """
    distributed = _distributed()
    if spec.local_workers is not None:
        import dask

        # Dask's statistical profiler samples the worker thread's stack every 10 ms
        # while holding the GIL: it made a worker 2.6x slower per frame (docs/cluster.md)
        with dask.config.set({"distributed.worker.profile.enabled": False}):
            cluster = distributed.LocalCluster(
                n_workers=spec.local_workers, threads_per_worker=1, processes=True,
                dashboard_address=None, silence_logs=logging.ERROR)
        try:
            client = distributed.Client(cluster, timeout=f"{timeout_s}s")
            try:
                yield client
            finally:
                client.close()
        finally:
            cluster.close()
        return
    try:
        client = distributed.Client(spec.address, timeout=f"{timeout_s}s")
    except (OSError, TimeoutError) as e:
        raise SlitcliError(f"`cluster`: cannot reach the Dask scheduler at {spec.address} "
                           f"({e}); start one (`dask scheduler`) or check the address",
                           param="cluster") from None
    try:
        yield client
    finally:
        client.close()


def _chunk_task(source: Path, target: Path, kwargs: dict[str, Any], chunk: Chunk
                ) -> ChunkResult | tuple[str, str | tuple[str, ...] | None]:
    """One chunk on a worker: one thread for OpenCV and the kernels (the workers are the
    parallelism).

    A :class:`SlitcliError` comes back as its message and parameter names (pickling an
    exception keeps only its message)."""
    from slitcli.io.batch import single_thread_worker

    single_thread_worker()
    try:
        return detect_chunk(source, target, {**kwargs, "jobs": 1}, chunk)
    except SlitcliError as e:
        return str(e), e.param


def dask_runner(client: Any) -> Any:
    """A ``make_runner`` for :func:`slitcli.multi.run_detect_many` that runs the chunks
    on ``client``'s cluster, all submitted at once, results in order of completion."""
    distributed = _distributed()

    def make(sources: Sequence[Path], targets: Sequence[Path], kwargs: dict[str, Any]
             ) -> Submit:
        # workers may run elsewhere: give them absolute paths on the shared filesystem
        srcs = [Path(s).resolve() for s in sources]
        outs = [Path(t).resolve() for t in targets]
        kw = dict(kwargs)
        if kw.get("rig_path") is not None:
            kw["rig_path"] = Path(kw["rig_path"]).resolve()

        def run(chunks: list[Chunk]) -> Iterator[ChunkResult | tuple[Chunk, BaseException]]:
            futures = {client.submit(_chunk_task, srcs[c.input], outs[c.input], kw, c,
                                     pure=False): c for c in chunks}
            try:
                for f in distributed.as_completed(list(futures)):
                    if f.status == "error":
                        yield futures[f], f.exception()
                    elif isinstance(r := f.result(), ChunkResult):
                        yield r
                    else:
                        yield futures[f], SlitcliError(r[0], param=r[1])
            finally:
                # a client that stops early (error, Ctrl-C) takes its chunks back
                client.cancel(list(futures))
        return run
    return make


__all__ = ["INSTALL_HINT", "ClusterSpec", "dask_client", "dask_runner", "parse_cluster"]
