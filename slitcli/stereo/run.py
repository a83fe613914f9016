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

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import asdict
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from slitcli.errors import SlitcliError
from slitcli.io.atomic import write_bytes_atomic
from slitcli.io.batch import FrameBatch, file_digest
from slitcli.io.sequence import FrameRef, StereoSequence, read_frame
from slitcli.rig import Rig
from slitcli.sim.sequence import encode_depth_png, encode_disparity_png
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.pipeline import (
    StereoFrameResult,
    StereoParams,
    check_stereo_params,
    process_stereo_pair,
)

OUTPUT_FOLDERS = ("disparity", "distance", "mask")
RANGES_FILE = "stereo_ranges.csv"
RANGES_HEADER = "frame,time_s,bearing_deg,stereo_range_m,stereo_has_features,obstacle_px,feature_px"


def encode_mask_png(obstacle_mask: np.ndarray) -> np.ndarray:
    """uint8, 255 = obstacle pixel."""
    return np.where(obstacle_mask, np.uint8(255), np.uint8(0))


def _png_bytes(path: Path, image: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise SlitcliError(f"{path}: OpenCV could not encode the image as PNG")
    return buf.tobytes()


def check_sequence_sizes(seq: StereoSequence, rig: Rig) -> None:
    """Check every pair's image sizes (from the file headers) before anything is written.

    Raises
    ------
    SlitcliError
        Naming the first image whose size differs from its partner or from the rig.
    """
    from PIL import Image, UnidentifiedImageError

    want = tuple(rig.raw.image_size_px if rig.raw is not None else rig.image_size_px)
    key = "raw.image_size_px" if rig.raw is not None else "image_size_px"
    for ref in seq.refs:
        sizes = []
        for path in (ref.left_path, ref.right_path):
            try:
                with Image.open(path) as im:
                    sizes.append(tuple(im.size))
            except (OSError, UnidentifiedImageError):
                raise SlitcliError(f"{path}: unreadable image (not a valid PNG or JPEG); "
                                   "re-export or remove it") from None
        (lw, lh), (rw, rh) = sizes
        if (lw, lh) != (rw, rh):
            raise SlitcliError(f"{ref.right_path}: size {rw}x{rh} differs from the left "
                               f"image's {lw}x{lh}; left and right images must have the "
                               "same size")
        if (lw, lh) != want:
            raise SlitcliError(f"{ref.left_path}: size {lw}x{lh} does not match the rig's "
                               f"{key} {want[0]}x{want[1]}; use the rig these images were "
                               "taken with (--rig)")


def _ranges_rows(ref: FrameRef, res: StereoFrameResult) -> str:
    table = pd.DataFrame({
        "frame": ref.index,
        "time_s": ref.time_s,
        "bearing_deg": res.bearing_deg,
        "stereo_range_m": res.range_m,
        "stereo_has_features": res.has_features.astype(int),
        "obstacle_px": res.obstacle_px,
        "feature_px": res.feature_px,
    })
    return table.to_csv(index=False, header=False, float_format="%.6g", na_rep="",
                        lineterminator="\n")


def _write_frame(out: Path, batch: FrameBatch, ref: FrameRef, res: StereoFrameResult) -> None:
    """The three PNGs of a frame, then its part file (which marks it finished)."""
    name = ref.name + ".png"
    for sub, img in (("disparity", encode_disparity_png(res.disparity_px)),
                     ("distance", encode_depth_png(res.depth_m)),
                     ("mask", encode_mask_png(res.obstacle_mask))):
        target = out / sub / name
        write_bytes_atomic(target, _png_bytes(target, img))
    write_bytes_atomic(batch.part_path(ref.index, "stereo"), _ranges_rows(ref, res).encode())


def run_stereo(seq_dir: str | Path, out: str | Path, *, rig_path: str | Path | None = None,
               params: StereoParams | None = None, overwrite: bool = False,
               on_frame: Callable[[int, int], None] | None = None) -> dict:
    """Run the stereo pipeline over a sequence folder and write the DESIGN §12 folders.

    Parameters
    ----------
    seq_dir : path
        Sequence folder (``left/``, ``right/``, optional ``times.csv``, ``rig.yaml``).
    out : path
        Output folder (created; a folder holding results of other settings is refused
        unless ``overwrite``).
    rig_path : path, optional
        Rig file; default the sequence's ``rig.yaml``, else the paper rig.
    params : StereoParams, optional
    overwrite : bool
        Replace results made with other settings.
    on_frame : callable(done, total), optional
        Progress callback, called once per frame (also for skipped frames).

    Returns
    -------
    dict with ``frames``, ``computed`` (frames processed in this run), ``skipped`` and
    ``valid_fraction`` (mean fraction of valid disparity pixels of the computed frames).

    Raises
    ------
    SlitcliError
        Missing or unpaired frames, sizes that differ between left and right or from
        the rig, impossible parameters; raised before anything is written.
    """
    p = StereoParams() if params is None else params
    seq = StereoSequence(seq_dir)
    rig = seq.rig(rig_path)
    check_stereo_params(rig, p)
    check_sequence_sizes(seq, rig)
    out = Path(out)
    manifest = {
        "command": "stereo",
        "params": asdict(p),
        "rig": rig.to_dict(),
        "inputs": [[r.name, file_digest(r.left_path), file_digest(r.right_path)]
                   for r in seq.refs],
    }
    batch = FrameBatch(out, "stereo", manifest, overwrite=overwrite)
    for sub in OUTPUT_FOLDERS:
        (out / sub).mkdir(parents=True, exist_ok=True)
    n = len(seq.refs)
    todo = [ref for ref in seq.refs if not (
        batch.is_done(ref.index, ("stereo",))
        and all((out / sub / f"{ref.name}.png").exists() for sub in OUTPUT_FOLDERS))]
    skipped = n - len(todo)
    if on_frame is not None and skipped:
        on_frame(skipped, n)
    valid: list[float] = []
    geometry = StereoGeometry.for_rig(rig, p.obstacles.bin_width_deg)
    # reading the next pair and encoding / writing the last frame's PNGs run on a
    # helper thread (OpenCV releases the GIL) while this thread matches
    with ThreadPoolExecutor(max_workers=1) as io_pool:
        reads = deque(io_pool.submit(read_frame, ref, rig) for ref in todo[:2])
        writes: deque[Future] = deque()
        for k, ref in enumerate(todo):
            frame = reads.popleft().result()
            if k + 2 < len(todo):
                reads.append(io_pool.submit(read_frame, todo[k + 2], rig))
            res = process_stereo_pair(frame.left_bgr, frame.right_bgr, rig, p, geometry=geometry)
            writes.append(io_pool.submit(_write_frame, out, batch, ref, res))
            while len(writes) > 1:
                writes.popleft().result()
                if on_frame is not None:
                    on_frame(skipped + k, n)
            valid.append(float(np.isfinite(res.disparity_px).mean()))
        while writes:
            writes.popleft().result()
    if on_frame is not None and todo:
        on_frame(n, n)
    computed = len(todo)
    batch.assemble(n, "stereo", out / RANGES_FILE, RANGES_HEADER)
    return {"frames": n, "computed": computed, "skipped": skipped,
            "valid_fraction": float(np.mean(valid)) if valid else float("nan")}
