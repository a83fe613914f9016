"""Obstacle detection per frame and over whole sequences (paper §2, DESIGN §6-7).

:class:`Detector` turns one stereo pair into a per-bearing range table
(:class:`slitcli.ranges.RangeTable`): the laser stripe (Eqs. 1-7) and the Eq. 10 stereo
matcher are each reduced to the nearest range per bearing bin, then fused (Eq. 11).
:func:`run_detect` runs it over any frame source (:func:`slitcli.io.frames.open_frames`:
a sequence folder or a ROS bag), resumably and in parallel, and writes ``ranges.csv``.
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from operator import itemgetter
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pandas as pd

from slitcli.calibrate.rectify import RectificationMaps, rectify_pair
from slitcli.colour_order import blue_line_z, check_colour_order
from slitcli.errors import SlitcliError
from slitcli.fusion import (
    FusedRanges,
    FusionParams,
    fuse,
    laser_reach_m,
    stereo_reaches_sheet,
    stripe_depth_agrees,
)
from slitcli.io.atomic import write_bytes_atomic, write_text_atomic
from slitcli.io.batch import (
    FrameBatch,
    check_jobs,
    frame_identity,
    manifest_value,
    run_pool,
    single_thread_worker,
)
from slitcli.io.frames import (
    DEFAULT_LEFT_TOPIC,
    DEFAULT_MAX_DT_S,
    DEFAULT_RIGHT_TOPIC,
    BadFrame,
    FrameInfo,
    FrameSource,
    open_frames,
)
from slitcli.io.png import encode_depth_png, encode_disparity_png, encode_mask_png, png_bytes
from slitcli.io.progress import Progress, RunSummary
from slitcli.laser.choose import MAX_GAP, stripe_pieces
from slitcli.laser.diagnose import absence_notes
from slitcli.laser.frame import (
    EdgeParams,
    LaserFrame,
    LaserGeometry,
    detect_laser,
    laser_sight_range_m,
    nearest_range_per_bin,
    segment_edges,
)
from slitcli.laser.params import LaserParams
from slitcli.ranges import LASER, RANGES, BearingBins, RangeTable, csv_rows
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

COLOUR_ORDERS = ("bgr", "rgb")
COLOUR_CHECKS = ("every", "once", "off")
SKIPPED_FILE = "skipped_frames.csv"


IMAGE_FOLDERS = ("disparity", "distance", "mask", "disparity_preview", "distance_preview")


@dataclass(frozen=True, kw_only=True)
class DetectParams:
    """Everything that defines a detection run besides the rig and the input.

    ``bin_deg`` is the bearing bin width of the range table; it overrides the stereo
    obstacle parameters' own bin width so both sensors share the bins.
    ``laser_depth_check``: pieces of stripe whose pixels stereo sees clearly farther
    than the laser plane are dropped before the bins
    (:func:`slitcli.fusion.stripe_depth_agrees`). ``stereo_sheet_check``: the paper
    fusion's silence rule leaves a stereo return where stereo sees the obstacle reach
    down to the laser sheet (:func:`slitcli.fusion.stereo_reaches_sheet`).
    """

    laser: LaserParams = field(default_factory=LaserParams)
    edges: EdgeParams = field(default_factory=EdgeParams)
    stereo: StereoParams = field(default_factory=StereoParams)
    fusion_mode: str = "paper"
    bin_deg: float = 1.0
    laser_depth_check: bool = True
    stereo_sheet_check: bool = True

    def __post_init__(self) -> None:
        if not 0.05 <= self.bin_deg <= 10.0:
            raise SlitcliError(f"`bin_deg` {self.bin_deg} is out of range; give 0.05-10 degrees",
                               param="bin_deg")
        FusionParams(mode=self.fusion_mode)  # validates the mode
        if not isinstance(self.laser_depth_check, bool):
            raise SlitcliError(f"`laser_depth_check` is {self.laser_depth_check!r}; give "
                               "true or false", param="laser_depth_check")
        if not isinstance(self.stereo_sheet_check, bool):
            raise SlitcliError(f"`stereo_sheet_check` is {self.stereo_sheet_check!r}; give "
                               "true or false", param="stereo_sheet_check")


@dataclass(frozen=True)
class FrameDetection:
    """The result of one stereo pair.

    ``ranges`` is the frame's range table (:class:`slitcli.ranges.RangeTable`: per
    bearing bin the laser, stereo and fused ranges, metres, NaN for no return);
    ``laser`` and ``stereo`` hold everything each sensor found (stripe rows and
    points; disparity, depth and obstacle images), ``fused`` the fusion's details.
    """

    laser: LaserFrame
    stereo: StereoFrameResult
    fused: FusedRanges
    ranges: RangeTable

    @property
    def bearing_deg(self) -> np.ndarray:
        """Bin centres (B,), degrees, positive left."""
        return self.ranges.bearing_deg

    @property
    def laser_range_m(self) -> np.ndarray:
        return self.ranges.laser_range_m

    @property
    def stereo_range_m(self) -> np.ndarray:
        return self.ranges.stereo_range_m

    @property
    def stereo_has_features(self) -> np.ndarray:
        return self.ranges.stereo_has_features

    def table(self, frame: int, time_s: float) -> pd.DataFrame:
        """The ``ranges.csv`` rows of this frame (:data:`slitcli.ranges.RANGES`)."""
        return self.ranges.rows(frame, time_s)


class Detector:
    """Detection for one rig and parameter set, reusable across frames (paper §2).

    Parameters are checked once, here; the rig's geometry (laser search region, bins,
    laser sight) is computed once, here.

    Parameters
    ----------
    rig : Rig
        The camera rig. With a ``raw`` calibration, pairs are rectified first.
    params : DetectParams, optional
        Default: the paper's settings.
    colour_order : {"bgr", "rgb"}
        Channel order of the images passed in (OpenCV reads BGR; most other readers
        RGB).
    colour_check : {"every", "once", "off"}
        When the laser finds almost nothing in a frame, look for the stripe with red
        and blue swapped and raise :class:`SlitcliError` (``colour_order``) if it is
        there (:func:`check_colour_order`; it costs a second laser extraction).
        ``"every"`` (default) checks every such frame: images may come from anywhere.
        ``"once"`` is for one source whose channel order cannot change between frames
        (a sequence, a bag, the simulator): frames are checked until one settles the
        order (a stripe of at least 16 columns found as given, or the error), then no
        more. ``"off"`` never checks.

    Examples
    --------
    >>> det = Detector(paper_rig())                         # doctest: +SKIP
    >>> result = det(left_bgr, right_bgr)                    # doctest: +SKIP
    >>> result.ranges.fused_range_m                          # nearest obstacle per bin
    """

    def __init__(self, rig: Rig, params: DetectParams | None = None, *,
                 colour_order: str = "bgr", colour_check: str = "every") -> None:
        if colour_order not in COLOUR_ORDERS:
            raise SlitcliError(f"`colour_order` {colour_order!r} is unknown; use 'bgr' or 'rgb'",
                               param="colour_order")
        if colour_check not in COLOUR_CHECKS:
            raise SlitcliError(f"`colour_check` {colour_check!r} is unknown; use 'every', "
                               "'once' or 'off'", param="colour_check")
        p = DetectParams() if params is None else params
        stereo = replace(p.stereo, obstacles=replace(p.stereo.obstacles,
                                                     bin_width_deg=p.bin_deg))
        self.params = replace(p, stereo=stereo)
        self.rig = rig
        self.colour_order = colour_order
        self.colour_check = colour_check
        # "once": set when a frame has shown the stripe in the given order; it only
        # ends the checks (never changes a result), so frames stay independent
        self._colour_settled = colour_check == "off"
        # after rectification the images are described by the rig without its raw block
        self.rectified_rig = replace(rig, raw=None)
        check_stereo_params(self.rectified_rig, self.params.stereo)
        self._rectification = RectificationMaps.for_rig(rig) if rig.raw is not None else None
        self._stereo_geometry = StereoGeometry.for_rig(self.rectified_rig, p.bin_deg)
        self.fusion = FusionParams(
            mode=p.fusion_mode, laser_max_range_m=rig.laser.max_range_m,
            stereo_max_range_m=rig.stereo.max_range_m,
            focal_baseline_px_m=self.rectified_rig.left.fx_px * rig.baseline_m,
            depth_check=p.laser_depth_check, sheet_check=p.stereo_sheet_check)
        self.bins = BearingBins.for_rig(self.rectified_rig, self.params.bin_deg)
        self._laser_geometry = LaserGeometry.from_rig(self.rectified_rig, self.params.laser)
        self._laser_sight_m = laser_sight_range_m(self.rectified_rig, self.bins.centres_deg)

    def prepare(self, left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Check a pair, put it in BGR order and rectify it (once per frame)."""
        want = self.rig.raw.image_size_px if self.rig.raw is not None else \
            self.rig.image_size_px
        for name, img in (("left_bgr", left), ("right_bgr", right)):
            a = np.asarray(img)
            if a.ndim != 3 or a.shape[2] != 3 or a.dtype != np.uint8:
                raise SlitcliError(f"`{name}` is {a.dtype} of shape {a.shape}; give a colour "
                                   "image, uint8, shape (H, W, 3)", param=name)
            if (a.shape[1], a.shape[0]) != tuple(want):
                raise SlitcliError(f"`{name}` is {a.shape[1]}x{a.shape[0]}, the rig's images "
                                   f"are {want[0]}x{want[1]}; give the rig of this camera (`rig`)",
                                   param=(name, "rig"))
        if self.colour_order == "rgb":
            left, right = left[..., ::-1], right[..., ::-1]
        return rectify_pair(self.rig, np.ascontiguousarray(left), np.ascontiguousarray(right),
                            maps=self._rectification)

    def laser(self, left_rect_bgr: np.ndarray) -> LaserFrame:
        """The laser stripe of a rectified left image (Eqs. 1-7), checked for colour order."""
        las = detect_laser(left_rect_bgr, self.rectified_rig, self.params.laser,
                           geometry=self._laser_geometry)
        if not self._colour_settled:
            settled = check_colour_order(left_rect_bgr, las, self.rectified_rig,
                                         self.params.laser, geometry=self._laser_geometry)
            self._colour_settled = settled and self.colour_check == "once"
        return las

    def __call__(self, left_bgr: np.ndarray, right_bgr: np.ndarray, *,
                 pool: ThreadPoolExecutor | None = None,
                 workspace: SgmWorkspace | None = None) -> FrameDetection:
        """Detect obstacles in one stereo pair (raw pairs are rectified with ``rig.raw``).

        ``pool``: helper threads for the stereo kernels, held by the caller for a
        sequence (:func:`slitcli.stereo.bands.frame_pool`); without one, a frame that
        runs on several cores starts its own. ``workspace``: memory for SGM's cost
        volumes held by such a caller (:class:`slitcli.stereo.sgm.SgmWorkspace`).

        A frame's result depends on this pair only (docs/api.md: the previous-frame
        rule), so frames may be processed in any order, resumed or in parallel.
        """
        left, right = self.prepare(left_bgr, right_bgr)
        las = self.laser(left)
        st = process_stereo_pair(left, right, self.rectified_rig, self.params.stereo,
                                 geometry=self._stereo_geometry, pool=pool,
                                 workspace=workspace)
        if self.fusion.depth_check:
            cols, piece = stripe_pieces(las.v_px, MAX_GAP, self.params.laser.max_jump_px)
            keep = stripe_depth_agrees(las.v_px, st.disparity_px, self.rectified_rig, cols,
                                       piece, self.fusion)
            las = las.without(las.found & ~keep)
        edges = segment_edges(las, self.rectified_rig, self.params.edges)
        lb = nearest_range_per_bin(las, self.rectified_rig, bin_deg=self.params.bin_deg,
                                   edges=edges)
        reach = laser_reach_m(self.bins.index(las.bearing_deg), las.range_m, las.strength_dn,
                              las.threshold_dn, las.noise_sigma_dn, len(self.bins), self.fusion)
        at_sheet = None
        if self.fusion.sheet_check and self.fusion.mode == "paper":
            at_sheet = stereo_reaches_sheet(st.points_sensor_xyz, st.obstacle_mask,
                                            self.bins.index, st.range_m, self.rectified_rig,
                                            self.fusion)
        fused = fuse(lb.range_m, st.range_m, st.has_features, self.fusion,
                     laser_sight_m=self._laser_sight_m, laser_reach_m=reach,
                     stereo_at_sheet=at_sheet)
        table = RangeTable(self.bins.centres_deg, lb.range_m, st.range_m, st.has_features,
                           fused.range_m, fused.source, fused.laser_free_m)
        return FrameDetection(las, st, fused, table)


# ---------------------------------------------------------------------------- batch
@dataclass(frozen=True)
class _Task:
    info: FrameInfo
    left_bgr: np.ndarray
    right_bgr: np.ndarray


def _work(detector: Detector, batch: FrameBatch, save_images: bool, task: _Task, *,
          pool: ThreadPoolExecutor | None = None,
          workspace: SgmWorkspace | None = None) -> int:
    """Detect one frame and write its parts (and images); returns the frame index."""
    res = detector(task.left_bgr, task.right_bgr, pool=pool, workspace=workspace)
    i = task.info.index
    if save_images:
        name = f"{task.info.name}.png"
        from slitcli.report.preview import disparity_preview, distance_preview

        m = detector.params.stereo.matcher
        previews = (
            ("disparity_preview", disparity_preview(
                res.stereo.disparity_px,
                max_disparity_px=m.min_disparity_px + m.num_disparities)),
            ("distance_preview", distance_preview(
                res.stereo.depth_m, max_range_m=detector.rig.stereo.max_range_m)))
        for sub, img in (("disparity", encode_disparity_png(res.stereo.disparity_px)),
                         ("distance", encode_depth_png(res.stereo.depth_m)),
                         ("mask", encode_mask_png(res.stereo.obstacle_mask)), *previews):
            target = batch.out / sub / name
            write_bytes_atomic(target, png_bytes(target, img))
        # pandas (laser_table's DataFrame) only with --save-images
        from slitcli.laser.batch import laser_table

        write_text_atomic(batch.part_path(i, "laser"), csv_rows(laser_table(i, res.laser)))
    # the rows part goes last: its presence marks the frame as finished
    write_text_atomic(batch.part_path(i), res.ranges.csv_rows(i, task.info.time_s))
    return i


def run_detect(source: str | Path, out: str | Path, *, rig_path: str | Path | None = None,
               params: DetectParams | None = None, jobs: int = 1, save_images: bool = False,
               overwrite: bool = False, left_topic: str = DEFAULT_LEFT_TOPIC,
               right_topic: str = DEFAULT_RIGHT_TOPIC, max_dt_s: float = DEFAULT_MAX_DT_S,
               on_bad_frame: str = "stop", on_progress: Progress | None = None,
               frames: range | None = None, lock: bool = True) -> RunSummary:
    """Detect obstacles in every frame of a sequence folder or ROS bag.

    Writes ``OUT/ranges.csv`` (docs/detect.md) and with ``save_images`` also
    ``OUT/disparity/``, ``OUT/distance/``, ``OUT/mask/`` and ``OUT/laser.csv``. The run
    resumes where an earlier one with the same settings stopped; ``jobs`` processes
    give the same bytes as one. Progress: ``on_progress(done, total)``.

    A frame that cannot be read stops the run (``on_bad_frame="stop"``: the error names
    the file; finished frames are kept for the resume) or is skipped (``"skip"``: no
    rows, listed in ``OUT/skipped_frames.csv`` and in the summary; a re-run tries it
    again).

    ``lock=False`` leaves OUT's run lock and temporaries to a caller that holds the lock
    (the client of a cluster run, :mod:`slitcli.multi`).

    ``frames`` (a ``range`` of frame numbers, step 1) computes only those frames' parts
    and writes no table: one chunk of a run split over many workers
    (:mod:`slitcli.cluster`); a later call without ``frames`` finds them finished and
    assembles the table, byte-identical to a run in one piece.

    Returns
    -------
    RunSummary
        ``counts``: ``laser_bins`` and ``stereo_bins`` (bins whose fused range came from
        each sensor). For a chunk: ``frames`` and ``resumed`` of the chunk, no outputs.
    """
    t0 = time.perf_counter()
    params = DetectParams() if params is None else params
    check_jobs(jobs)
    src = open_frames(source, left_topic=left_topic, right_topic=right_topic,
                      max_dt_s=max_dt_s)
    rig = src.rig(rig_path)
    # checks every parameter before anything is written; one source, one channel order:
    # its colour order is checked until a frame shows the stripe
    detector = Detector(rig, params, colour_check="once")
    n = len(src)
    todo = range(n) if frames is None else frames
    if todo.step != 1 or not 0 <= todo.start <= todo.stop <= n:
        raise SlitcliError(f"`frames` {todo} is not a sub-range of the input's {n} frames",
                           param="frames")
    batch = _open_batch(source, out, src, rig, params, save_images, overwrite, lock)
    kinds = ("rows", "laser") if save_images else ("rows",)
    # a finished frame is kept while its input (bytes, name, time) is unchanged
    finished = batch.resume({i: frame_identity(src, i) for i in todo}, kinds)
    done = len(finished)
    if on_progress is not None:
        on_progress(done, len(todo))
    # frames outside the chunk are neither decoded nor computed
    skip = finished if frames is None else finished | (frozenset(range(n)) - set(todo))

    def tasks() -> Iterator[_Task]:
        for f in src.frames(rig, skip=skip, on_bad=on_bad_frame):
            if isinstance(f, BadFrame):
                batch.mark_skipped(f.index, f.name, f.reason, kinds)
                continue
            batch.clear_skipped(f.index)
            yield _Task(src.info[f.index], f.left_bgr, f.right_bgr)

    # in one process the stereo kernels' helper threads are one pool for the run (a pool
    # per frame costs ~0.5 ms to start and join); process workers run on one thread
    helpers = thread_setting() - 1 if jobs == 1 else 0
    with ThreadPoolExecutor(max_workers=helpers) if helpers > 0 else nullcontext() as pool:
        # SGM's volumes too are held for the run (process workers: one per frame)
        work = partial(_work, detector, batch, save_images, pool=pool,
                       workspace=SgmWorkspace() if jobs == 1 else None)
        for _ in run_pool(tasks(), work, jobs=jobs,
                          initializer=single_thread_worker if jobs > 1 else None):
            done += 1
            if on_progress is not None:
                on_progress(done, len(todo))
    if frames is not None:
        return RunSummary("detect", len(todo), len(finished), time.perf_counter() - t0, ())
    if on_progress is not None:
        on_progress(n, n)
    return _finish(batch, src, params, save_images, len(finished), t0)


def _open_batch(source: str | Path, out: str | Path, src: FrameSource, rig: Rig,
                params: DetectParams, save_images: bool, overwrite: bool,
                lock: bool) -> FrameBatch:
    """The run's working folder in ``out`` (its settings: the input, rig and parameters,
    so that a re-run with the same ones resumes), with the image folders when
    ``save_images``."""
    manifest = {"command": "detect", "format": 4, "input": src.manifest(), "rig": rig.to_dict(),
                "params": manifest_value(asdict(params)), "save_images": save_images}
    subs = IMAGE_FOLDERS if save_images else ()
    batch = FrameBatch(Path(out), "detect", manifest, overwrite=overwrite, subfolders=subs,
                       hold_lock=lock)
    # where the input lies, for `slitcli report`; not part of the identity, so a moved
    # input still resumes
    write_text_atomic(batch.dir / "source.json",
                      json.dumps({"path": str(Path(source).resolve())}))
    if save_images:
        for sub in IMAGE_FOLDERS:
            (batch.out / sub).mkdir(exist_ok=True)
    return batch


def _finish(batch: FrameBatch, src: FrameSource, params: DetectParams, save_images: bool,
            resumed: int, t0: float) -> RunSummary:
    """Assemble a whole run's tables from its finished frames, count the bins each sensor
    ranged and say what the user should know (skipped frames, frames without a stripe)."""
    n = len(src)
    table = batch.out / RANGES.file
    batch.assemble(n, "rows", table, RANGES.header)
    outputs: tuple[Path, ...] = (table,)
    notes = src.notes()
    skipped = batch.write_skipped(n, batch.out / SKIPPED_FILE)
    if skipped:
        outputs += (batch.out / SKIPPED_FILE,)
        notes += (f"{skipped} frame(s) could not be read and were skipped (no rows): "
                  f"{batch.out / SKIPPED_FILE}",)
    if save_images:
        batch.assemble(n, "laser", batch.out / LASER.file, LASER.header)
        outputs += (batch.out / LASER.file,)
    counts, frame_ids, lit = _table_counts(table)
    # most frames without a laser bin: say so, and why where the images tell
    notes += absence_notes(lit, lambda pos: _grey_frames(src, [int(frame_ids[p]) for p in pos]),
                           search=params.laser.search)
    return RunSummary("detect", n, resumed, time.perf_counter() - t0, outputs,
                      MappingProxyType({"laser_bins": counts.get("laser", 0),
                                        "stereo_bins": counts.get("stereo", 0),
                                        "skipped_frames": skipped}), notes)


def _table_counts(table: Path) -> tuple[dict[str, int], np.ndarray, np.ndarray]:
    """From a finished ``ranges.csv``: rows per ``fused_source`` value, and per frame with
    rows (ascending frame number) its number and its count of laser ranges.

    Read with the csv module, not pandas: a one-frame run would spend a third of its
    start-up importing pandas for these counts. The table is the one this run just
    assembled (:data:`slitcli.ranges.RANGES` columns; an empty cell is no return).
    """
    with open(table, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    frame, laser, source = (np.array(list(map(itemgetter(header.index(c)), rows)), dtype=str)
                            for c in ("frame", "laser_range_m", "fused_source"))
    names, per_name = np.unique(source, return_counts=True)
    frame_ids, row_frame = np.unique(frame.astype(np.int64), return_inverse=True)
    lit = np.bincount(row_frame, weights=laser != "", minlength=frame_ids.size).astype(np.int64)
    return dict(zip(names.tolist(), per_name.tolist(), strict=True)), frame_ids, lit


def _grey_frames(src: FrameSource, indices: list[int]) -> list[bool]:
    """:func:`slitcli.laser.batch.grey_frames`, imported only when a warning needs it
    (``laser.batch`` brings pandas)."""
    from slitcli.laser.batch import grey_frames

    return grey_frames(src, indices)


def summary_line(summary: RunSummary) -> str:
    """The line ``slitcli detect`` prints."""
    c = summary.counts
    return summary.line(f"{c['laser_bins']} bins ranged by the laser, "
                        f"{c['stereo_bins']} by stereo")



__all__ = ["COLOUR_CHECKS", "COLOUR_ORDERS", "DetectParams", "Detector", "FrameDetection",
           "blue_line_z", "check_colour_order", "run_detect", "summary_line"]
