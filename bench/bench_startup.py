"""Start-up of the command line: `slitcli --help` and a warm one-frame `slitcli detect`.

Prints the median wall and CPU (user + sys) time of each over N runs, then the CPU
breakdown of one warm detect measured inside the process (numpy, numba's import, the
first kernel call, which loads numba's registries, the other kernels' cache loads,
pandas, OpenCV, the rest). Run after the set-up (the kernels warmed up):

    .venv/bin/python bench/bench_startup.py [SEQ] [--runs 7]

SEQ is a sequence folder whose first frame is used (default: the bundled corridor).
Wall times depend on the machine's load; CPU times much less (docs/notes/startup.md).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SLITCLI = Path(sys.executable).parent / "slitcli"

_BREAKDOWN = r'''
import sys, time
T = time.process_time
t0 = T(); import numpy; t_numpy = T() - t0
t0 = T(); import numba; t_numba = T() - t0
from numba.core import dispatcher
orig = dispatcher.Dispatcher._compile_for_args
spent = [0.0, 0.0, 0]
def timed(self, *a, **k):
    t = T(); r = orig(self, *a, **k); spent[0 if spent[2] == 0 else 1] += T() - t; spent[2] += 1
    return r
dispatcher.Dispatcher._compile_for_args = timed
t0 = T(); import pandas; t_pandas = T() - t0
t0 = T(); import cv2; t_cv2 = T() - t0
sys.argv = ["slitcli", "detect", sys.argv[1], "-o", sys.argv[2]]
from slitcli.cli import main
t0 = T()
try:
    main()
except SystemExit:
    pass
t_cmd = T() - t0
rest = t_cmd - spent[0] - spent[1]
print(f"{t_numpy} {t_numba} {spent[0]} {spent[2] - 1} {spent[1]} {t_pandas} {t_cv2} {rest}")
'''


def _one_frame(seq: Path, where: Path) -> Path:
    """A copy of the first frame of ``seq`` as a one-frame sequence folder."""
    one = where / "one"
    for side in ("left", "right"):
        first = sorted((seq / side).iterdir())[0]
        (one / side).mkdir(parents=True)
        shutil.copy(first, one / side / first.name)
    if (seq / "rig.yaml").exists():
        shutil.copy(seq / "rig.yaml", one / "rig.yaml")
    (one / "times.csv").write_text("frame,time_s\n0,0\n")
    return one


def _timed(cmd: list[str]) -> tuple[float, float]:
    before = os.times()
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = os.times()
    cpu = (after.children_user - before.children_user
           + after.children_system - before.children_system)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("seq", nargs="?", type=Path,
                    default=ROOT / "sample_data" / "sequences" / "corridor")
    ap.add_argument("--runs", type=int, default=7)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        one = _one_frame(args.seq, Path(tmp))
        cases = {"slitcli --help": lambda i: [str(SLITCLI), "--help"],
                 "slitcli detect (1 frame, warm)":
                     lambda i: [str(SLITCLI), "detect", str(one), "-o", f"{tmp}/out{i}"]}
        for name, make in cases.items():
            _timed(make(-1))  # a first run fills the OS's file cache
            runs = [_timed(make(i)) for i in range(args.runs)]
            print(f"{name:32s} wall median {statistics.median(w for w, _ in runs):.3f} s, "
                  f"CPU median {statistics.median(c for _, c in runs):.3f} s "
                  f"({args.runs} runs)")
        rows = []
        for i in range(3):
            out = subprocess.run([sys.executable, "-c", _BREAKDOWN, str(one), f"{tmp}/bd{i}"],
                                 check=True, capture_output=True, text=True).stdout
            rows.append([float(x) for x in out.split()[-8:]])
    med = [statistics.median(r[k] for r in rows) for k in range(8)]
    print(f"warm detect CPU breakdown (median of 3): numpy {med[0]:.3f} s, numba import "
          f"{med[1]:.3f} s, first kernel call (numba's registries + its cache load) "
          f"{med[2]:.3f} s, {med[3]:.0f} more cache loads {med[4]:.3f} s, pandas "
          f"{med[5]:.3f} s, cv2 {med[6]:.3f} s, the rest (slitcli modules, I/O, the frame's "
          f"work) {med[7]:.3f} s")


if __name__ == "__main__":
    main()
