"""`slitcli detect --cluster local:2` against `--jobs 1`, measured side by side.

Also the issue 25 checks on the same data: 4 sequences on local:2 give the serial
tables byte for byte; a 200-frame sequence in chunks of 50 too; a client killed
mid-run and run again gives the same table and keeps its finished chunks. And the
terms of the speed model (docs/cluster.md): per-frame time and the scheduler's
overhead per task.

Standalone: ``python bench/bench_cluster.py [FOLDER_OF_SEQUENCES]`` (default: 4
rendered sample scenes, 12 frames each, and the bundled corridor tiled to 200 frames).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"


def _tiled(n: int, folder: Path) -> Path:
    names = sorted(p.name for p in (BUNDLED / "left").iterdir())
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
        for i in range(n):
            os.link(BUNDLED / side / names[i % len(names)], folder / side / f"{i:06d}.png")
    shutil.copy(BUNDLED / "rig.yaml", folder / "rig.yaml")
    return folder


def _rendered(base: Path, frames: int) -> list[Path]:
    from slitcli.rig import paper_rig
    from slitcli.sim.scene import load_scene
    from slitcli.sim.sequence import render_sequence

    out = []
    for name in ("corridor", "distractors", "overhang", "fig4"):
        out.append(base / name)
        render_sequence(load_scene(ROOT / "sample_data" / f"{name}.yaml"), paper_rig(),
                        out[-1], frames=frames)
    return out


def _cli(*args: object) -> tuple[float, str]:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "slitcli", "detect", *map(str, args)],
                       check=True, capture_output=True, text=True)
    return time.perf_counter() - t0, r.stdout


def _same(a: Path, b: Path) -> bool:
    return a.read_bytes() == b.read_bytes()


def _task_overhead_s(n_tasks: int = 400) -> float:
    """Scheduler round trip per task on local:2: no-op tasks, submitted at once."""
    from slitcli.cluster import dask_client, parse_cluster

    with dask_client(parse_cluster("local:2")) as client:
        client.gather(client.map(abs, range(-8, 0), pure=False))  # warm
        t0 = time.perf_counter()
        client.gather(client.map(abs, range(-n_tasks, 0), pure=False))
        return (time.perf_counter() - t0) / n_tasks


def _kill_and_resume(seq: Path, ref: Path, tmp: Path) -> dict:
    out = tmp / "killed"
    cmd = [sys.executable, "-m", "slitcli", "detect", str(seq), "-o", str(out), "--cluster",
           "local:2", "--chunk-frames", "50"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    done = 0
    for line in proc.stderr:
        m = re.search(r", (\d+)/\d+ frames done", line)
        if m and int(m.group(1)) > 0:
            done = int(m.group(1))
            break
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    parts = len(list((out / ".slitcli" / "detect" / "parts").glob("*.rows.csv")))
    _, line = _cli(seq, "-o", out, "--cluster", "local:2", "--chunk-frames", "50")
    m = re.search(r"\((\d+) computed, (\d+) of (\d+) chunks kept", line)
    return {"frames_reported_before_kill": done, "frame_parts_on_disk_at_kill": parts,
            "computed_on_rerun": int(m.group(1)), "chunks_kept": int(m.group(2)),
            "chunks": int(m.group(3)), "identical": _same(out / "ranges.csv", ref)}


def bench(timer: object = None, folder: Path | None = None) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        seqs = (sorted(p for p in folder.iterdir() if p.is_dir()) if folder
                else _rendered(tmp / "four", 12))
        serial_s, _ = _cli(*seqs, "-o", tmp / "s4", "--jobs", "1")
        cl_s, _ = _cli(*seqs, "-o", tmp / "c4", "--cluster", "local:2")
        names = [p.name for p in (tmp / "s4").iterdir() if p.is_dir() and p.name[0] != "."]
        same4 = all(_same(tmp / "s4" / n / "ranges.csv", tmp / "c4" / n / "ranges.csv")
                    for n in names)
        rows.append({"name": "4 sequences: local:2 vs --jobs 1", "serial_s": serial_s,
                     "cluster_s": cl_s, "ratio": serial_s / cl_s, "identical": same4,
                     "sequences": len(names)})
        long = _tiled(200, tmp / "long")
        t = {"serial": [], "cluster": []}
        for rep in range(2):  # alternate, so both see the same load from other jobs
            s, _ = _cli(long, "-o", tmp / f"ls{rep}", "--jobs", "1")
            c, _ = _cli(long, "-o", tmp / f"lc{rep}", "--cluster", "local:2",
                        "--chunk-frames", "50")
            t["serial"].append(s)
            t["cluster"].append(c)
        ref = tmp / "ls0" / "ranges.csv"
        same = all(_same(ref, tmp / f"l{k}{r}" / "ranges.csv") for k in "sc" for r in range(2))
        s, c = min(t["serial"]), min(t["cluster"])
        rows.append({"name": "200 frames: local:2 chunks of 50 vs --jobs 1",
                     "serial_s": s, "cluster_s": c, "ratio": s / c, "identical": same,
                     "per_frame_serial_s": s / 200, "runs": 2, "times_s": t})
        rows.append({"name": "scheduler overhead per task, local:2",
                     "overhead_s": _task_overhead_s()})
        rows.append({"name": "kill the client mid-run, re-run",
                     **_kill_and_resume(long, ref, tmp)})
    return rows


if __name__ == "__main__":
    import json

    arg = Path(sys.argv[1]) if len(sys.argv) > 1 else None
    print(json.dumps(bench(folder=arg), indent=1, default=str))
