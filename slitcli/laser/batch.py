"""``slitcli laser SRC -o OUT``: the laser table of a whole sequence or bag."""

from __future__ import annotations

import shutil
import time
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pandas as pd

from slitcli.errors import SlitcliError
from slitcli.io.atomic import atomic_directory, write_csv_atomic, write_png_atomic
from slitcli.io.frames import (
    DEFAULT_LEFT_TOPIC,
    DEFAULT_MAX_DT_S,
    DEFAULT_RIGHT_TOPIC,
    BadFrame,
    FrameSource,
    open_frames,
)
from slitcli.io.progress import Progress, RunSummary, no_laser_note
from slitcli.laser.frame import LaserFrame, LaserGeometry, detect_laser
from slitcli.laser.params import LaserParams
from slitcli.ranges import FLOAT_FORMAT, LASER
from slitcli.rig import Rig

TABLE_COLUMNS = LASER.columns
OVERLAY_DIR = "laser_overlay"
SKIPPED_FILE = "skipped_frames.csv"


def laser_table(frame_index: int, frame: LaserFrame) -> pd.DataFrame:
    """The laser.csv rows of one frame: one row per column with a stripe."""
    f = frame.found
    return pd.DataFrame({
        "frame": np.full(int(f.sum()), frame_index, dtype=np.int64),
        "u_px": frame.u_px[f].astype(np.int64),
        "v_px": frame.v_px[f],
        "strength": frame.strength_dn[f],
        "x_m": frame.x_m[f],
        "y_m": frame.y_m[f],
        "range_m": frame.range_m[f],
        "bearing_deg": frame.bearing_deg[f],
        "in_band": frame.in_band[f].astype(np.int64),
    }, columns=list(LASER.columns))


def run_laser(source: str | Path, out_dir: str | Path, *, rig_path: str | Path | None = None,
              params: LaserParams | None = None, overlay: bool = False,
              left_topic: str = DEFAULT_LEFT_TOPIC, right_topic: str = DEFAULT_RIGHT_TOPIC,
              max_dt_s: float = DEFAULT_MAX_DT_S, on_bad_frame: str = "stop",
              on_progress: Progress | None = None) -> RunSummary:
    """Extract and triangulate the stripe in every left image of a sequence or bag.

    Writes ``OUT/laser.csv`` (docs/laser.md) and, with ``overlay``, one Fig. 4-style
    PNG per frame in ``OUT/laser_overlay/``. Raw pairs (a rig with a ``raw`` block) are
    rectified first. Each frame's stripe depends on its own image only
    (:mod:`slitcli.io.frames`: the previous-frame rule). Outputs appear only once every
    frame is done (temporary files renamed into place); on bad input nothing is left
    behind. Progress: ``on_progress(done, total)``. A frame that cannot be read stops
    the run (``on_bad_frame="stop"``, the error names the file) or is skipped
    (``"skip"``: no rows; listed in ``OUT/skipped_frames.csv`` and the summary).

    Raises
    ------
    SlitcliError
        Missing or unreadable sequence, images or rig; images that do not match the rig.
    """
    t0 = time.perf_counter()
    params = LaserParams() if params is None else params
    src = open_frames(source, left_topic=left_topic, right_topic=right_topic,
                      max_dt_s=max_dt_s)
    rig = src.rig(rig_path)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SlitcliError(f"{out}: exists and is not a folder; choose another output path")
    created = not out.exists()
    try:
        path, bad = _run(src, rig, out, params, overlay, on_bad_frame, on_progress)
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            shutil.rmtree(out, ignore_errors=True)
        raise
    table = pd.read_csv(path, usecols=["frame"])
    outputs = (path, out / OVERLAY_DIR) if overlay else (path,)
    read = len(src) - len(bad)
    notes = src.notes() + no_laser_note(read - table["frame"].nunique(), read)
    skipped_csv = out / SKIPPED_FILE
    if bad:
        write_csv_atomic(skipped_csv, pd.DataFrame(
            [(b.index, b.name, b.reason) for b in bad], columns=["frame", "name", "reason"]))
        outputs += (skipped_csv,)
        notes += (f"{len(bad)} frame(s) could not be read and were skipped (no rows): "
                  f"{skipped_csv}",)
    else:
        skipped_csv.unlink(missing_ok=True)
    return RunSummary("laser", len(src), 0, time.perf_counter() - t0, outputs,
                      MappingProxyType({"stripe_columns": len(table),
                                        "skipped_frames": len(bad)}), notes)


def _run(src: FrameSource, rig: Rig, out: Path, params: LaserParams, overlay: bool,
         on_bad_frame: str, on_progress: Progress | None) -> tuple[Path, list[BadFrame]]:
    rect = replace(rig, raw=None)
    geometry = LaserGeometry.from_rig(rect, params)
    tables: list[pd.DataFrame] = []
    bad: list[BadFrame] = []
    n = len(src)
    if on_progress is not None:
        on_progress(0, n)
    with atomic_directory(out / OVERLAY_DIR, overwrite=True) if overlay else \
            nullcontext() as tmp_overlay:
        for k, frame in enumerate(src.frames(rig, rectify=True, on_bad=on_bad_frame)):
            if isinstance(frame, BadFrame):
                bad.append(frame)
                continue
            stripe = detect_laser(frame.left_bgr, rect, params, geometry=geometry)
            tables.append(laser_table(frame.index, stripe))
            if tmp_overlay is not None:
                from slitcli.laser.overlay import draw_overlay

                img = draw_overlay(frame.left_bgr, stripe, max_jump_px=params.max_jump_px,
                                   title=f"frame {frame.index} ({frame.name})")
                write_png_atomic(tmp_overlay / f"{frame.name}.png", img)
            if on_progress is not None:
                on_progress(k + 1, n)
        table = pd.concat(tables, ignore_index=True) if tables else \
            pd.DataFrame(columns=list(LASER.columns))
        write_csv_atomic(out / LASER.file, table, float_format=FLOAT_FORMAT)
    return out / LASER.file, bad
