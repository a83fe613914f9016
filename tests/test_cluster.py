"""`slitcli detect --cluster`: a Dask LocalCluster of 2 worker processes (slitcli.cluster)."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import psutil
import pytest
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.cluster import dask_client, dask_runner, parse_cluster
from slitcli.detect import run_detect
from slitcli.errors import SlitcliError
from slitcli.multi import run_detect_many

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"


def _sequence(folder: Path, n: int, offset: int) -> Path:
    """``n`` frames of the bundled rendered corridor, starting at frame ``offset``."""
    names = sorted(p.name for p in (BUNDLED / "left").iterdir())
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
        for i in range(n):
            os.link(BUNDLED / side / names[(i + offset) % len(names)],
                    folder / side / f"{i:04d}.png")
    shutil.copy(BUNDLED / "rig.yaml", folder / "rig.yaml")
    return folder


@pytest.fixture(scope="module")
def four(tmp_path_factory):
    base = tmp_path_factory.mktemp("cl")
    seqs = [_sequence(base / "in" / f"s{k}", n, k) for k, n in enumerate((2, 3, 5, 1))]
    for s in seqs:
        run_detect(s, base / "ref" / s.name)
    return seqs, base / "ref"


def _alive(pids: list[int]) -> list[int]:
    return [p for p in pids if psutil.pid_exists(p)
            and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]


def test_local_cluster_gives_the_serial_tables_and_leaves_no_worker(four, tmp_path):
    seqs, ref = four
    out = tmp_path / "out"
    with dask_client(parse_cluster("local:2")) as client:
        pids = list(client.run(os.getpid).values())
        assert len(pids) == 2 and os.getpid() not in pids
        s = run_detect_many(seqs, out, chunk_frames=2, make_runner=dask_runner(client))
    assert s.failed == (), s.failed
    for q in seqs:
        assert (out / q.name / "ranges.csv").read_bytes() == \
            (ref / q.name / "ranges.csv").read_bytes()
    assert s.chunks == 1 + 2 + 3 + 1 and s.computed == 11
    deadline = time.monotonic() + 20
    while _alive(pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _alive(pids) == []


def test_cluster_closes_on_errors(tmp_path):
    with pytest.raises(RuntimeError), dask_client(parse_cluster("local:2")) as client:
        pids = list(client.run(os.getpid).values())
        raise RuntimeError("the caller failed")
    deadline = time.monotonic() + 20
    while _alive(pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _alive(pids) == []


def _marked(mark: str) -> list[psutil.Process]:
    found = []
    for p in psutil.process_iter():
        try:
            if p.environ().get("SLITCLI_TEST_MARK") == mark:
                found.append(p)
        except (psutil.Error, OSError):
            continue
    return found


def test_kill_the_client_then_rerun_keeps_finished_chunks(tmp_path):
    # chunk bookkeeping after a kill: the frames' content (seed 0) does not enter it
    seq = _sequence(tmp_path / "long", 48, 0)
    full = tmp_path / "full"
    run_detect(seq, full)
    out = tmp_path / "out"
    mark = uuid.uuid4().hex
    cmd = [sys.executable, "-m", "slitcli", "detect", str(seq), "-o", str(out),
           "--cluster", "local:2", "--chunk-frames", "4"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "SLITCLI_TEST_MARK": mark})
    done = 0
    for line in proc.stderr:  # "detect: 0/1 inputs, F/48 frames done"
        if "frames done" in line:
            done = int(line.split(",")[1].split("/")[0])
            if done >= 8:
                break
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert 8 <= done < 48 and not (out / "ranges.csv").exists()
    # the client is gone: so are its nannies and workers
    deadline = time.monotonic() + 30
    while _marked(mark) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert _marked(mark) == []
    res = CliRunner().invoke(cli, ["detect", str(seq), "-o", str(out), "--cluster", "local:2",
                                   "--chunk-frames", "4"])
    assert res.exit_code == 0, res.output
    m = re.search(r"\((\d+) computed, (\d+) of 12 chunks kept", res.output)
    computed, kept = int(m.group(1)), int(m.group(2))
    # every chunk reported done before the kill is kept, and nothing is computed twice
    assert kept >= done // 4 and computed <= 48 - 4 * kept
    assert (out / "ranges.csv").read_bytes() == (full / "ranges.csv").read_bytes()


def test_cluster_options_are_checked(tmp_path, monkeypatch):
    for bad in ("local:0", "local", "http://x:1", "4"):
        with pytest.raises(SlitcliError, match="cluster"):
            parse_cluster(bad)
    assert parse_cluster("tcp://head:8786").address == "tcp://head:8786"
    res = CliRunner().invoke(cli, ["detect", str(BUNDLED), "-o", str(tmp_path / "a"),
                                   "--cluster", "tcp://127.0.0.1:1"])
    assert res.exit_code == 2 and "--cluster" in res.stderr and "Traceback" not in res.stderr
    # without Dask the option says how to install it
    monkeypatch.setitem(sys.modules, "distributed", None)
    res = CliRunner().invoke(cli, ["detect", str(BUNDLED), "-o", str(tmp_path / "b"),
                                   "--cluster", "local:2"])
    assert res.exit_code == 2 and "pip install 'slitcli[cluster]'" in res.stderr
    assert not (tmp_path / "b").exists()


def test_an_unreadable_input_fails_alone_on_the_cluster(four, tmp_path):
    seqs, ref = four
    bad = tmp_path / "bad"
    shutil.copytree(seqs[1], bad)
    # the frame is broken after the client opened the input: the worker finds it
    def break_frame(p):
        (bad / "left" / "0001.png").write_bytes(b"not a png")
        return p

    with dask_client(parse_cluster("local:2")) as client:
        make = dask_runner(client)

        def runner(srcs, targets, kwargs):
            run = make(srcs, targets, kwargs)
            return lambda chunks: run(break_frame(chunks))

        s = run_detect_many([seqs[0], bad], tmp_path / "out", make_runner=runner)
    assert [p.name for p, _ in s.failed] == ["bad"]
    assert "0001.png" in s.failed[0][1]
    assert (tmp_path / "out" / seqs[0].name / "ranges.csv").read_bytes() == \
        (ref / seqs[0].name / "ranges.csv").read_bytes()
