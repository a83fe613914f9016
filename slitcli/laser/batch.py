"""``slitcli laser SRC -o OUT``: the laser table of a whole sequence or bag."""

from __future__ import annotations

import os
import shutil
import time
from dataclasses import asdict, replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pandas as pd

from slitcli.errors import SlitcliError
from slitcli.io.atomic import atomic_directory, write_png_atomic, write_text_atomic
from slitcli.io.batch import FrameBatch, frame_identity, manifest_value
from slitcli.io.frames import (
    DEFAULT_LEFT_TOPIC,
    DEFAULT_MAX_DT_S,
    DEFAULT_RIGHT_TOPIC,
    BadFrame,
    FolderFrames,
    FrameSource,
    open_frames,
)
from slitcli.io.progress import Progress, RunSummary
from slitcli.laser.diagnose import absence_notes, is_grey
from slitcli.laser.frame import LaserFrame, LaserGeometry, detect_laser
from slitcli.laser.params import LaserParams
from slitcli.ranges import LASER, csv_rows
from slitcli.stereo.bands import thread_setting

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
    (:mod:`slitcli.io.frames`: the previous-frame rule). The run is resumable like
    ``detect`` (:class:`slitcli.io.batch.FrameBatch` in ``OUT/.slitcli/laser/``): a re-run
    after an interruption computes only the frames not finished, and gives the same
    bytes; a re-run with other settings replaces the results. ``laser.csv`` and
    ``laser_overlay/`` appear only once every frame is done. Progress:
    ``on_progress(done, total)``. A frame that cannot be read stops the run
    (``on_bad_frame="stop"``, the error names the file; finished frames are kept for the
    resume) or is skipped (``"skip"``: no rows; listed in ``OUT/skipped_frames.csv`` and
    the summary).

    Raises
    ------
    SlitcliError
        Missing or unreadable sequence, images or rig; images that do not match the rig;
        another run in ``OUT``.
    """
    t0 = time.perf_counter()
    params = LaserParams() if params is None else params
    src = open_frames(source, left_topic=left_topic, right_topic=right_topic,
                      max_dt_s=max_dt_s)
    rig = src.rig(rig_path)
    if isinstance(src, FolderFrames) and on_bad_frame == "stop":
        src.check_sizes(rig)  # before anything is written
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SlitcliError(f"{out}: exists and is not a folder; choose another output path")
    rect = replace(rig, raw=None)
    geometry = LaserGeometry.from_rig(rect, params)  # checks the parameters
    # the candidates' threads (SLITCLI_THREADS): a bad setting is refused before anything is
    # written
    thread_setting()
    manifest = {"command": "laser", "format": 1, "input": src.manifest(), "rig": rig.to_dict(),
                "params": manifest_value(asdict(params)), "overlay": overlay}
    # laser writes only its own named outputs, so OUT may hold others; a re-run with
    # other settings replaces its results (as it always did)
    batch = FrameBatch(out, "laser", manifest, overwrite=True, shared=True)
    n = len(src)
    staged = batch.dir / OVERLAY_DIR
    if overlay:
        staged.mkdir(exist_ok=True)
    done = batch.resume([frame_identity(src, i) for i in range(n)], ("laser",))
    if overlay:
        done = frozenset(i for i in done if (staged / f"{src.info[i].name}.png").exists())
    if on_progress is not None:
        on_progress(len(done), n)
    k = len(done)
    for frame in src.frames(rig, rectify=True, skip=done, on_bad=on_bad_frame):
        if isinstance(frame, BadFrame):
            batch.mark_skipped(frame.index, frame.name, frame.reason, ("laser",))
            continue
        batch.clear_skipped(frame.index)
        stripe = detect_laser(frame.left_bgr, rect, params, geometry=geometry)
        if overlay:
            from slitcli.laser.overlay import draw_overlay

            img = draw_overlay(frame.left_bgr, stripe, max_jump_px=params.max_jump_px,
                               title=f"frame {frame.index} ({frame.name})")
            write_png_atomic(staged / f"{frame.name}.png", img)
        # the rows part goes last: its presence marks the frame as finished
        write_text_atomic(batch.part_path(frame.index, "laser"),
                          csv_rows(laser_table(frame.index, stripe)))
        k += 1
        if on_progress is not None:
            on_progress(k, n)
    return _finish(batch, src, params, overlay, len(done), t0)


def _finish(batch: FrameBatch, src: FrameSource, params: LaserParams, overlay: bool,
            resumed: int, t0: float) -> RunSummary:
    """Publish a whole run's outputs once every frame is done (``laser.csv``, the
    overlays, the skipped frames) and say what the user should know (frames without
    a stripe, and why where the images tell)."""
    n, out = len(src), batch.out
    if overlay:
        _publish_overlays(out / OVERLAY_DIR, batch.dir / OVERLAY_DIR,
                          [src.info[i].name for i in range(n) if not batch.is_skipped(i)])
    path = out / LASER.file
    batch.assemble(n, "laser", path, LASER.header)
    bad = batch.write_skipped(n, out / SKIPPED_FILE)
    table = pd.read_csv(path, usecols=["frame"])
    outputs = (path, out / OVERLAY_DIR) if overlay else (path,)
    read = [i for i in range(n) if not batch.is_skipped(i)]
    per_frame = table["frame"].value_counts().reindex(read, fill_value=0).to_numpy()
    notes = src.notes() + absence_notes(
        per_frame, lambda pos: grey_frames(src, [read[p] for p in pos]), search=params.search)
    if bad:
        outputs += (out / SKIPPED_FILE,)
        notes += (f"{bad} frame(s) could not be read and were skipped (no rows): "
                  f"{out / SKIPPED_FILE}",)
    return RunSummary("laser", n, resumed, time.perf_counter() - t0, outputs,
                      MappingProxyType({"stripe_columns": len(table),
                                        "skipped_frames": bad}), notes)


def grey_frames(src: FrameSource, indices: list[int]) -> list[bool]:
    """Whether the left images of frames ``indices`` (sorted) of a source are grey
    (:func:`~slitcli.laser.diagnose.is_grey`); a frame that cannot be read counts as
    not grey."""
    want = set(indices)
    grey = dict.fromkeys(indices, False)
    for f in src.frames(skip=frozenset(range(len(src))) - want, on_bad="skip"):
        if not isinstance(f, BadFrame):
            grey[f.index] = is_grey(f.left_bgr)
    return [grey[i] for i in indices]


def _publish_overlays(target: Path, staged: Path, names: list[str]) -> None:
    """Make ``target`` hold exactly the staged overlays of ``names``, in one rename.

    The staged files stay (hard links share their bytes, so this costs no space), so a
    finished run re-run with the same settings computes nothing.
    """
    with atomic_directory(target, overwrite=True) as tmp:
        for name in names:
            src, dst = staged / f"{name}.png", tmp / f"{name}.png"
            try:
                os.link(src, dst)
            except OSError:  # a file system without hard links
                shutil.copyfile(src, dst)

