"""End-to-end `slitcli detect` throughput and memory at 320x240.

Throughput: the Eq. 10 (nssd) pipeline and the BM pipeline over the same frames in the
same run. Memory: peak RSS of a detect process over 100 and 1000 frames (hard links to
the bundled frames, so the inputs cost no disk), which must stay flat.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"


def _sequence(n: int, folder: Path) -> Path:
    names = sorted(p.name for p in (BUNDLED / "left").iterdir())
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
        for i in range(n):
            os.link(BUNDLED / side / names[i % len(names)], folder / side / f"{i:06d}.png")
    shutil.copy(BUNDLED / "rig.yaml", folder / "rig.yaml")
    return folder


def _detect(seq: Path, out: Path, matcher: str, jobs: int = 1) -> float:
    if out.exists():
        shutil.rmtree(out)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "slitcli", "detect", str(seq), "-o", str(out),
                    "--matcher", matcher, "--jobs", str(jobs)], check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def _peak_rss_mb(seq: Path, out: Path) -> float:
    code = ("import resource, sys; from slitcli.cli import main; sys.argv=['slitcli','detect',"
            f"{str(seq)!r},'-o',{str(out)!r}]\n"
            "try:\n    main()\nexcept SystemExit:\n    pass\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)")
    res = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True)
    return int(res.stdout.strip().splitlines()[-1]) / 1024.0


def bench(timer) -> list[dict]:
    from slitcli.detect import Detector, DetectParams
    from slitcli.io.sequence import StereoSequence
    from slitcli.rig import load_rig
    from slitcli.stereo.matcher import MatcherParams
    from slitcli.stereo.pipeline import StereoParams

    rows = []
    seq = StereoSequence(BUNDLED)
    rig = load_rig(BUNDLED / "rig.yaml")
    frames = list(seq.frames(rig))
    per = {}
    for matcher in ("nssd", "bm"):
        det = Detector(rig, DetectParams(stereo=StereoParams(matcher=MatcherParams(matcher))))
        k = iter(range(10**9))

        def one(det=det, k=k) -> None:
            f = frames[next(k) % len(frames)]
            det(f.left_bgr, f.right_bgr)

        per[matcher] = timer(one, runs=31)
        rows.append({"name": f"detect per frame, {matcher} (320x240, in process)",
                     **per[matcher], "note": f"{1 / per[matcher]['median_s']:.1f} frames/s"})
    rows.append({"name": "detect nssd / bm per-frame time", "ratio":
                 per["nssd"]["median_s"] / per["bm"]["median_s"],
                 "note": f"ratio {per['nssd']['median_s'] / per['bm']['median_s']:.2f}"})
    with tempfile.TemporaryDirectory() as tmp:
        t = Path(tmp)
        s60 = _sequence(60, t / "s60")
        for matcher in ("nssd", "bm"):
            for jobs in (1, 2):
                secs = _detect(s60, t / f"o_{matcher}_{jobs}", matcher, jobs)
                rows.append({"name": f"slitcli detect 60 frames, {matcher}, --jobs {jobs} "
                                     "(whole command)", "median_s": secs, "min_s": secs,
                             "runs": 1, "note": f"{60 / secs:.1f} frames/s incl. start-up"})
        mem = {}
        for n in (100, 1000):
            seq_n = _sequence(n, t / f"s{n}")
            mem[n] = _peak_rss_mb(seq_n, t / f"m{n}")
            rows.append({"name": f"detect peak memory, {n} frames", "note":
                         f"{mem[n]:.0f} MB peak RSS"})
        rows.append({"name": "detect memory 1000 / 100 frames", "ratio": mem[1000] / mem[100],
                     "note": f"ratio {mem[1000] / mem[100]:.2f} (flat = 1)"})
    return rows
