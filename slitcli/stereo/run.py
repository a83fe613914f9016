"""``slitcli stereo``: a stereo sequence to disparity, distance and obstacle-mask images.

For every frame of a sequence folder (DESIGN §12) this writes, named like the input
frame (``NAME.png`` for ``left/NAME.png`` or ``left/NAME.jpg``):

- ``OUT/disparity/NAME.png``: uint16, disparity_px x 256, 0 = invalid (KITTI);
- ``OUT/distance/NAME.png``: uint16, depth along the optical axis in mm, 0 = invalid
  (ROS 16UC1);
- ``OUT/mask/NAME.png``: uint8, 255 = obstacle pixel, 0 = floor / free / invalid;

and ``OUT/stereo_ranges.csv`` (nearest obstacle per bearing bin and frame). Every file
is written to a temporary name and renamed; a manifest in ``OUT/.slitcli/stereo/`` lets
a re-run skip the frames already finished (docs/stereo.md). All input is checked
before anything is written.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import asdict
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pandas as pd

from slitcli.io.atomic import write_bytes_atomic
from slitcli.io.batch import FrameBatch, frame_identity
from slitcli.io.frames import (
    DEFAULT_LEFT_TOPIC,
    DEFAULT_MAX_DT_S,
    DEFAULT_RIGHT_TOPIC,
    BadFrame,
    FolderFrames,
    FrameInfo,
    FrameSource,
    open_frames,
)
from slitcli.io.png import encode_depth_png, encode_disparity_png, encode_mask_png, png_bytes
from slitcli.io.progress import Progress, RunSummary
from slitcli.io.sequence import StereoFrame
from slitcli.ranges import STEREO_RANGES, csv_rows, format_time_s
from slitcli.rig import Rig
from slitcli.stereo.bands import thread_setting
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.pipeline import (
    StereoFrameResult,
    StereoParams,
    check_stereo_params,
    process_stereo_pair,
)
from slitcli.stereo.sgm import SgmWorkspace

OUTPUT_FOLDERS = ("disparity", "distance", "mask")
RANGES_FILE = STEREO_RANGES.file
RANGES_HEADER = STEREO_RANGES.header
SKIPPED_FILE = "skipped_frames.csv"


def _ranges_rows(ref: FrameInfo, res: StereoFrameResult) -> str:
    table = pd.DataFrame({
        "frame": ref.index,
        "time_s": format_time_s(ref.time_s),
        "bearing_deg": res.bearing_deg,
        "stereo_range_m": res.range_m,
        "stereo_has_features": res.has_features.astype(int),
        "obstacle_px": res.obstacle_px,
        "feature_px": res.feature_px,
    }, columns=list(STEREO_RANGES.columns))
    return csv_rows(table)


def _write_frame(out: Path, batch: FrameBatch, ref: FrameInfo, res: StereoFrameResult) -> None:
    """The three PNGs of a frame, then its part file (which marks it finished)."""
    name = ref.name + ".png"
    for sub, img in (("disparity", encode_disparity_png(res.disparity_px)),
                     ("distance", encode_depth_png(res.depth_m)),
                     ("mask", encode_mask_png(res.obstacle_mask))):
        target = out / sub / name
        write_bytes_atomic(target, png_bytes(target, img))
    write_bytes_atomic(batch.part_path(ref.index, "stereo"), _ranges_rows(ref, res).encode())


def _match_all(src: FrameSource, rig: Rig, p: StereoParams, out: Path, batch: FrameBatch,
               done: frozenset[int], on_bad_frame: str, on_progress: Progress | None
               ) -> list[float]:
    """Match every frame not in ``done`` and write its files; the valid-pixel fractions."""
    n, skipped = len(src), len(done)
    valid: list[float] = []
    geometry = StereoGeometry.for_rig(rig, p.obstacles.bin_width_deg)

    def readable() -> Iterator[StereoFrame]:
        for f in src.frames(rig, skip=done, on_bad=on_bad_frame):
            if isinstance(f, BadFrame):  # recorded; no images, no rows
                batch.mark_skipped(f.index, f.name, f.reason, ("stereo",))
            else:
                yield f

    frames = readable()
    # reading the next pair and encoding / writing the last frame's PNGs run on a
    # helper thread (OpenCV releases the GIL) while this thread matches; the matcher's
    # helper threads are one pool for the whole run (a frame still uses only the cores
    # free at that moment; a pool per frame cost ~0.5 ms to start and join)
    helpers = thread_setting() - 1
    workspace = SgmWorkspace()  # SGM's cost volumes, one buffer for the run
    with ThreadPoolExecutor(max_workers=1) as io_pool, \
            ThreadPoolExecutor(max_workers=helpers) if helpers > 0 else nullcontext() as pool:
        reads = deque(io_pool.submit(next, frames, None) for _ in range(2))
        writes: deque[Future] = deque()
        k = 0
        while (frame := reads.popleft().result()) is not None:
            reads.append(io_pool.submit(next, frames, None))
            batch.clear_skipped(frame.index)
            res = process_stereo_pair(frame.left_bgr, frame.right_bgr, rig, p, geometry=geometry,
                                      pool=pool, workspace=workspace)
            writes.append(io_pool.submit(_write_frame, out, batch, src.info[frame.index], res))
            while len(writes) > 1:
                writes.popleft().result()
                if on_progress is not None:
                    on_progress(skipped + k, n)
            valid.append(float(np.isfinite(res.disparity_px).mean()))
            k += 1
        while writes:
            writes.popleft().result()
    return valid


def run_stereo(seq_dir: str | Path, out: str | Path, *, rig_path: str | Path | None = None,
               params: StereoParams | None = None, overwrite: bool = False,
               left_topic: str = DEFAULT_LEFT_TOPIC, right_topic: str = DEFAULT_RIGHT_TOPIC,
               max_dt_s: float = DEFAULT_MAX_DT_S, on_bad_frame: str = "stop",
               on_progress: Progress | None = None) -> RunSummary:
    """Run the stereo pipeline over a sequence folder or bag and write the image folders.

    Parameters
    ----------
    seq_dir : path
        Sequence folder (``left/``, ``right/``, optional ``times.csv``, ``rig.yaml``) or
        a ROS bag (:func:`slitcli.io.frames.open_frames`).
    out : path
        Output folder (created; a folder holding results of other settings is refused
        unless ``overwrite``).
    rig_path : path, optional
        Rig file; default the sequence's ``rig.yaml``, else the paper rig.
    params : StereoParams, optional
    overwrite : bool
        Replace results made with other settings.
    left_topic, right_topic, max_dt_s
        Bag topics and pairing tolerance (seconds).
    on_bad_frame : {"stop", "skip"}
        A frame that cannot be read stops the run (the error names the file) or is
        skipped (listed in ``OUT/skipped_frames.csv``; a re-run tries it again).
    on_progress : callable(done, total), optional
        Progress callback.

    Returns
    -------
    RunSummary
        ``counts["valid_fraction"]``: mean fraction of valid disparity pixels of the
        frames computed in this run.

    Raises
    ------
    SlitcliError
        Missing or unpaired frames, sizes that differ between left and right or from
        the rig, impossible parameters; raised before anything is written.
    """
    t0 = time.perf_counter()
    p = StereoParams() if params is None else params
    src = open_frames(seq_dir, left_topic=left_topic, right_topic=right_topic,
                      max_dt_s=max_dt_s)
    rig = src.rig(rig_path)
    check_stereo_params(rig, p)
    if isinstance(src, FolderFrames):
        src.check_sizes(rig)
    out = Path(out)
    manifest = {
        "command": "stereo",
        "params": asdict(p),
        "rig": rig.to_dict(),
        "input": src.manifest(),
    }
    batch = FrameBatch(out, "stereo", manifest, overwrite=overwrite, subfolders=OUTPUT_FOLDERS)
    for sub in OUTPUT_FOLDERS:
        (out / sub).mkdir(parents=True, exist_ok=True)
    n = len(src)
    # a finished frame is kept while its input (bytes, name, time) is unchanged
    kept = batch.resume([frame_identity(src, i) for i in range(n)], ("stereo",))
    done = frozenset(i for i in kept if all((out / sub / f"{src.info[i].name}.png").exists()
                                            for sub in OUTPUT_FOLDERS))
    skipped = len(done)
    if on_progress is not None:
        on_progress(skipped, n)
    valid = _match_all(src, rig, p, out, batch, done, on_bad_frame, on_progress)
    if on_progress is not None:
        on_progress(n, n)
    batch.assemble(n, "stereo", out / RANGES_FILE, RANGES_HEADER)
    outputs: tuple[Path, ...] = (out / RANGES_FILE,)
    notes = src.notes()
    bad = batch.write_skipped(n, out / SKIPPED_FILE)
    if bad:
        outputs += (out / SKIPPED_FILE,)
        notes += (f"{bad} frame(s) could not be read and were skipped (no images, no rows): "
                  f"{out / SKIPPED_FILE}",)
    return RunSummary("stereo", n, skipped, time.perf_counter() - t0, outputs,
                      MappingProxyType({"valid_fraction": float(np.mean(valid)) if valid
                                        else float("nan"), "skipped_frames": bad}), notes)
