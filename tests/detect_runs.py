"""Small real detection runs for the export and report tests (test helper).

The first ``n`` frames of the bundled corridor sequence are detected with
``run_detect`` (a folder run with ``--save-images``, or a ROS bag run), so the tests
read exactly the files ``slitcli detect`` writes.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from slitcli.detect import run_detect
from slitcli.io.sequence import read_image

ROOT = Path(__file__).resolve().parent.parent
CORRIDOR = ROOT / "sample_data" / "sequences" / "corridor"


def corridor_subset(folder: Path, n: int, *, times: bool = True) -> Path:
    """A sequence folder with the corridor's first ``n`` frames (and its rig)."""
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
        for i in range(n):
            shutil.copy(CORRIDOR / side / f"{i:06d}.png", folder / side / f"{i:06d}.png")
    shutil.copy(CORRIDOR / "rig.yaml", folder / "rig.yaml")
    if times:
        t = pd.read_csv(CORRIDOR / "times.csv").iloc[:n]
        t.to_csv(folder / "times.csv", index=False)
    return folder


def folder_run(tmp: Path, n: int, *, save_images: bool = True, times: bool = True
               ) -> tuple[Path, Path]:
    """Detect ``n`` corridor frames; returns (sequence folder, detect output)."""
    seq = corridor_subset(tmp / "seq", n, times=times)
    out = tmp / "det"
    run_detect(seq, out, save_images=save_images)
    return seq, out


def bag_run(tmp: Path, n: int, *, ros: int = 2) -> tuple[Path, Path, np.ndarray]:
    """Detect ``n`` corridor frames from a bag; returns (bag, output, left stamps ns)."""
    from bagwriter import write_bag

    frames = [(read_image(CORRIDOR / "left" / f"{i:06d}.png"),
               read_image(CORRIDOR / "right" / f"{i:06d}.png")) for i in range(n)]
    t0_ns, dt_ns = 1_700_000_000_123_456_789, 200_000_000
    bag = write_bag(tmp / ("in.bag" if ros == 1 else "inbag"), frames, ros=ros, t0_ns=t0_ns,
                    dt_ns=dt_ns)
    out = tmp / "bagdet"
    run_detect(bag, out, rig_path=CORRIDOR / "rig.yaml")
    return bag, out, t0_ns + dt_ns * np.arange(n, dtype=np.int64)
