"""``slitcli laser SEQ -o OUT``: the laser table of a whole sequence (DESIGN §12)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from slitcli.errors import SlitcliError
from slitcli.io.atomic import atomic_directory, write_csv_atomic, write_png_atomic
from slitcli.io.progress import progress_bar
from slitcli.io.sequence import StereoSequence, read_frame
from slitcli.laser.frame import LaserFrame, LaserGeometry, detect_laser
from slitcli.laser.overlay import draw_overlay
from slitcli.laser.params import LaserParams

TABLE_COLUMNS = ("frame", "u_px", "v_px", "strength", "x_m", "y_m", "range_m", "bearing_deg",
                 "in_band")
OVERLAY_DIR = "laser_overlay"


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
    }, columns=list(TABLE_COLUMNS))


def run_laser(seq_dir: str | Path, out_dir: str | Path, *, rig_path: str | Path | None = None,
              params: LaserParams | None = None, overlay: bool = False) -> Path:
    """Extract and triangulate the stripe in every left image of a sequence.

    Writes ``OUT/laser.csv`` (docs/laser.md) and, with ``overlay``, one Fig. 4-style
    PNG per frame in ``OUT/laser_overlay/``. Outputs appear only once every frame
    is done (temporary files renamed into place); on bad input nothing is left
    behind. Progress goes to stderr.

    Raises
    ------
    SlitcliError
        Missing or unreadable sequence, images or rig; images that do not match the rig.
    """
    params = LaserParams() if params is None else params
    seq = StereoSequence(seq_dir)
    rig = seq.rig(rig_path)
    if rig.raw is not None:
        raise SlitcliError(f"{rig_path or Path(seq_dir) / 'rig.yaml'}: the rig has a raw "
                           "(unrectified) calibration; `laser` reads rectified images, give "
                           "the rectified rig (raw: null)")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SlitcliError(f"{out}: exists and is not a folder; choose another output path")
    created = not out.exists()
    try:
        return _run(seq, rig, out, params, overlay)
    except BaseException:
        if created and out.is_dir() and not any(out.iterdir()):
            shutil.rmtree(out, ignore_errors=True)
        raise


def _run(seq: StereoSequence, rig, out: Path, params: LaserParams, overlay: bool) -> Path:
    geometry = LaserGeometry.from_rig(rig, params)
    tables: list[pd.DataFrame] = []
    previous: LaserFrame | None = None
    with progress_bar(len(seq), "laser") as bar:
        if overlay:
            with atomic_directory(out / OVERLAY_DIR, overwrite=True) as tmp:
                for ref in seq.refs:
                    frame = read_frame(ref, rig)
                    previous = detect_laser(frame.left_bgr, rig, params, previous=previous,
                                            geometry=geometry)
                    tables.append(laser_table(ref.index, previous))
                    img = draw_overlay(frame.left_bgr, previous, max_jump_px=params.max_jump_px,
                                       title=f"frame {ref.index} ({ref.name})")
                    write_png_atomic(tmp / f"{ref.name}.png", img)
                    bar.update(1)
                _write_table(out, tables)
        else:
            for ref in seq.refs:
                frame = read_frame(ref, rig)
                previous = detect_laser(frame.left_bgr, rig, params, previous=previous,
                                        geometry=geometry)
                tables.append(laser_table(ref.index, previous))
                bar.update(1)
            _write_table(out, tables)
    return out / "laser.csv"


def _write_table(out: Path, tables: list[pd.DataFrame]) -> None:
    table = pd.concat(tables, ignore_index=True) if tables else \
        pd.DataFrame(columns=list(TABLE_COLUMNS))
    write_csv_atomic(out / "laser.csv", table, float_format="%.6g")
