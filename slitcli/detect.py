"""Obstacle detection per frame and over whole sequences (paper §2, DESIGN §6-7).

:class:`Detector` turns one rectified stereo pair into a per-bearing range table:
the laser stripe (Eqs. 1-7) and the Eq. 10 stereo matcher are each reduced to the
nearest range per bearing bin, then fused (Eq. 11). :func:`run_detect` runs it over a
sequence folder or a ROS bag, resumably and in parallel, and writes ``ranges.csv``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd

from slitcli.calibrate.rectify import RectificationMaps, rectify_pair
from slitcli.errors import SlitcliError
from slitcli.fusion import FusedRanges, FusionParams, fuse
from slitcli.io.atomic import write_png_atomic, write_text_atomic
from slitcli.io.bags import BagPairs
from slitcli.io.batch import FrameBatch, run_pool, single_thread_worker
from slitcli.io.sequence import StereoSequence, read_image
from slitcli.laser import (
    LaserFrame,
    LaserGeometry,
    LaserParams,
    detect_laser,
    laser_sight_range_m,
    laser_table,
)
from slitcli.laser import bearing_bin_centres_deg as laser_bins_centres
from slitcli.laser import nearest_range_per_bin as laser_bins
from slitcli.laser.frame import EdgeParams, segment_edges
from slitcli.rig import Rig
from slitcli.sim.sequence import encode_depth_png, encode_disparity_png
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.pipeline import (
    StereoFrameResult,
    StereoParams,
    check_stereo_params,
    process_stereo_pair,
)

RANGE_COLUMNS = ("frame", "time_s", "bearing_deg", "laser_range_m", "stereo_range_m",
                 "stereo_has_features", "fused_range_m", "fused_source")
LASER_COLUMNS = ("frame", "u_px", "v_px", "strength", "x_m", "y_m", "range_m", "bearing_deg",
                 "in_band")
FLOAT_FORMAT = "%.6g"


@dataclass(frozen=True, kw_only=True)
class DetectParams:
    """Everything that defines a detection run besides the rig and the input.

    ``bin_deg`` is the bearing bin width of the range table; it overrides the stereo
    obstacle parameters' own bin width so both sensors share the bins.
    """

    laser: LaserParams = field(default_factory=LaserParams)
    edges: EdgeParams = field(default_factory=EdgeParams)
    stereo: StereoParams = field(default_factory=StereoParams)
    fusion_mode: str = "paper"
    bin_deg: float = 1.0

    def __post_init__(self) -> None:
        if not 0.05 <= self.bin_deg <= 10.0:
            raise SlitcliError(f"--bin-deg {self.bin_deg} is out of range; give 0.05-10 degrees")
        FusionParams(mode=self.fusion_mode)  # validates the mode


@dataclass(frozen=True)
class FrameDetection:
    """The result of one stereo pair.

    ``bearing_deg`` (B,) are the bin centres (sensor frame, positive left); the range
    arrays (B,) are metres with NaN for no return.
    """

    laser: LaserFrame
    stereo: StereoFrameResult
    bearing_deg: np.ndarray
    laser_range_m: np.ndarray
    stereo_range_m: np.ndarray
    stereo_has_features: np.ndarray
    fused: FusedRanges

    def table(self, frame: int, time_s: float) -> pd.DataFrame:
        """The range-table rows of this frame (DESIGN §12 columns)."""
        return pd.DataFrame({
            "frame": frame, "time_s": time_s, "bearing_deg": self.bearing_deg,
            "laser_range_m": self.laser_range_m, "stereo_range_m": self.stereo_range_m,
            "stereo_has_features": self.stereo_has_features.astype(np.int64),
            "fused_range_m": self.fused.range_m, "fused_source": self.fused.source,
        }, columns=list(RANGE_COLUMNS))


class Detector:
    """Detection for one rig and parameter set, reusable across frames (paper §2).

    Examples
    --------
    >>> det = Detector(paper_rig())                         # doctest: +SKIP
    >>> result = det(left_bgr, right_bgr)                    # doctest: +SKIP
    >>> result.fused.range_m                                 # nearest obstacle per bin
    """

    def __init__(self, rig: Rig, params: DetectParams | None = None) -> None:
        p = DetectParams() if params is None else params
        stereo = replace(p.stereo, obstacles=replace(p.stereo.obstacles,
                                                     bin_width_deg=p.bin_deg))
        self.params = replace(p, stereo=stereo)
        self.rig = rig
        # after rectification the images are described by the rig without its raw block
        self.rectified_rig = replace(rig, raw=None)
        check_stereo_params(self.rectified_rig, self.params.stereo)
        self._rectification = RectificationMaps.for_rig(rig) if rig.raw is not None else None
        self._stereo_geometry = StereoGeometry.for_rig(self.rectified_rig, p.bin_deg)
        self.fusion = FusionParams(
            mode=p.fusion_mode, laser_max_range_m=rig.laser.max_range_m,
            stereo_max_range_m=rig.stereo.max_range_m,
            focal_baseline_px_m=self.rectified_rig.left.fx_px * rig.baseline_m)
        self._laser_geometry = LaserGeometry.from_rig(self.rectified_rig, self.params.laser)
        self._laser_sight_m = laser_sight_range_m(
            self.rectified_rig, laser_bins_centres(self.rectified_rig, self.params.bin_deg))

    def laser(self, left_rect_bgr: np.ndarray, previous: LaserFrame | None = None
              ) -> LaserFrame:
        """The laser stripe of a rectified left image (Eqs. 1-7)."""
        return detect_laser(left_rect_bgr, self.rectified_rig, self.params.laser,
                            previous=previous, geometry=self._laser_geometry)

    def __call__(self, left_bgr: np.ndarray, right_bgr: np.ndarray, *,
                 previous_left_bgr: np.ndarray | None = None) -> FrameDetection:
        """Detect obstacles in one stereo pair (raw pairs are rectified with ``rig.raw``).

        ``previous_left_bgr`` feeds the laser's frame-to-frame continuity term (Eq. 4).
        The previous stripe is re-extracted from it without a prior of its own, so a
        frame's result depends on two images only: batches stay parallel and resumable.
        """
        left, right = rectify_pair(self.rig, left_bgr, right_bgr, maps=self._rectification)
        prev = None
        if previous_left_bgr is not None:
            prev_left, _ = rectify_pair(self.rig, previous_left_bgr, maps=self._rectification)
            prev = self.laser(prev_left)
        las = self.laser(left, prev)
        st = process_stereo_pair(left, right, self.rectified_rig, self.params.stereo,
                                 geometry=self._stereo_geometry)
        edges = segment_edges(las, self.rectified_rig, self.params.edges)
        lb = laser_bins(las, self.rectified_rig, bin_deg=self.params.bin_deg, edges=edges)
        fused = fuse(lb.range_m, st.range_m, st.has_features, self.fusion,
                     laser_sight_m=self._laser_sight_m)
        return FrameDetection(las, st, lb.bearing_deg, lb.range_m, st.range_m,
                              st.has_features, fused)


# ---------------------------------------------------------------------------- batch
@dataclass(frozen=True)
class _Task:
    index: int
    name: str
    time_s: float
    left_bgr: np.ndarray
    right_bgr: np.ndarray
    previous_left_bgr: np.ndarray | None


def _csv_rows(df: pd.DataFrame) -> str:
    return df.to_csv(header=False, index=False, float_format=FLOAT_FORMAT, na_rep="",
                     lineterminator="\n")


def _work(detector: Detector, batch: FrameBatch, save_images: bool, task: _Task) -> int:
    """Detect one frame and write its parts (and images); returns the frame index."""
    res = detector(task.left_bgr, task.right_bgr, previous_left_bgr=task.previous_left_bgr)
    if save_images:
        name = f"{task.name}.png"
        out = batch.out
        write_png_atomic(out / "disparity" / name, encode_disparity_png(res.stereo.disparity_px))
        write_png_atomic(out / "distance" / name, encode_depth_png(res.stereo.depth_m))
        write_png_atomic(out / "mask" / name, (res.stereo.obstacle_mask * 255).astype(np.uint8))
        table = laser_table(task.index, res.laser)
        write_text_atomic(batch.part_path(task.index, "laser"), _csv_rows(table))
    # the rows part goes last: its presence marks the frame as finished
    write_text_atomic(batch.part_path(task.index), _csv_rows(res.table(task.index,
                                                                        task.time_s)))
    return task.index


def _folder_tasks(seq: StereoSequence, rig: Rig, skip: Callable[[int], bool]
                  ) -> Iterator[_Task]:
    from slitcli.io.sequence import read_frame

    for ref in seq.refs:
        if skip(ref.index):
            continue
        fr = read_frame(ref, rig)
        prev = None
        if ref.index > 0:
            prev = read_image(seq.refs[ref.index - 1].left_path)
        yield _Task(ref.index, ref.name, ref.time_s, fr.left_bgr, fr.right_bgr, prev)


def _bag_tasks(pairs: BagPairs, rig: Rig, skip: Callable[[int], bool]) -> Iterator[_Task]:
    from slitcli.io.bags import bag_frames

    n = len(pairs)
    # a finished frame is still decoded when the next one needs it as the laser prior
    undecoded = {i for i in range(n) if skip(i) and (i + 1 >= n or skip(i + 1))}
    prev = None
    for fr in bag_frames(pairs, skip=undecoded):
        if isinstance(fr, int):
            prev = None
            continue
        want = (rig.raw.image_size_px if rig.raw is not None else rig.image_size_px)
        if (fr.left_bgr.shape[1], fr.left_bgr.shape[0]) != tuple(want):
            raise SlitcliError(f"{pairs.path}: images are {fr.left_bgr.shape[1]}x"
                               f"{fr.left_bgr.shape[0]}, the rig's are {want[0]}x{want[1]}; "
                               "give the rig of this camera with --rig")
        if not skip(fr.index):
            yield _Task(fr.index, fr.name, fr.time_s, fr.left_bgr, fr.right_bgr,
                        prev if fr.index > 0 else None)
        prev = fr.left_bgr


@dataclass(frozen=True)
class DetectSummary:
    frames: int
    resumed: int
    laser_bins: int
    stereo_bins: int
    seconds: float
    table: Path

    def line(self) -> str:
        done = self.frames - self.resumed
        rate = done / self.seconds if self.seconds > 0 and done else float("nan")
        return (f"detect: {self.frames} frames ({self.resumed} already done), "
                f"{self.laser_bins} bins ranged by the laser, {self.stereo_bins} by stereo, "
                f"{rate:.1f} frames/s -> {self.table}")


def run_detect(source: str | Path, out: str | Path, *, rig_path: str | Path | None = None,
               params: DetectParams | None = None, jobs: int = 1, save_images: bool = False,
               overwrite: bool = False, left_topic: str = "/stereo/left/image_raw",
               right_topic: str = "/stereo/right/image_raw", max_dt_s: float = 0.01,
               on_frame: Callable[[], None] | None = None,
               on_total: Callable[[int], None] | None = None) -> DetectSummary:
    """Detect obstacles in every frame of a sequence folder or ROS bag.

    Writes ``OUT/ranges.csv`` (docs/detect.md) and with ``save_images`` also
    ``OUT/disparity/``, ``OUT/distance/``, ``OUT/mask/`` and ``OUT/laser.csv``. The run
    resumes where an earlier one with the same settings stopped; ``jobs`` processes
    give the same bytes as one.
    """
    from slitcli.io.bags import is_bag, pair_bag

    t0 = time.perf_counter()
    params = DetectParams() if params is None else params
    src = Path(source)
    if is_bag(src):
        pairs = pair_bag(src, left_topic, right_topic, max_dt_s)
        if rig_path is None:
            raise SlitcliError(f"{src}: a bag carries no rig; give the camera's rig with --rig")
        from slitcli.rig import load_rig

        rig = load_rig(rig_path)
        n = len(pairs)
        ident = {"kind": "bag", "frames": n, "left_topic": left_topic,
                 "right_topic": right_topic, "max_dt_s": max_dt_s,
                 "stamps": int(np.bitwise_xor.reduce(pairs.left_ns))}
        seq = None
    else:
        seq = StereoSequence(src)
        rig = seq.rig(rig_path)
        n = len(seq)
        ident = {"kind": "folder", "frames": n,
                 "names": [r.name for r in seq.refs],
                 "bytes": int(sum(r.left_path.stat().st_size + r.right_path.stat().st_size
                                  for r in seq.refs))}
    manifest = {"command": "detect", "format": 1, "input": ident, "rig": rig.to_dict(),
                "params": _jsonable(asdict(params)), "save_images": save_images}
    batch = FrameBatch(Path(out), "detect", manifest, overwrite=overwrite)
    kinds = ("rows", "laser") if save_images else ("rows",)
    if save_images:
        for sub in ("disparity", "distance", "mask"):
            (batch.out / sub).mkdir(exist_ok=True)
    finished = {i for i in range(n) if batch.is_done(i, kinds)}
    if on_total is not None:
        on_total(n - len(finished))
    detector = Detector(rig, params)
    tasks = (_folder_tasks(seq, rig, finished.__contains__) if seq is not None
             else _bag_tasks(pairs, rig, finished.__contains__))
    from functools import partial

    for _ in run_pool(tasks, partial(_work, detector, batch, save_images), jobs=jobs,
                      initializer=single_thread_worker if jobs > 1 else None):
        if on_frame is not None:
            on_frame()
    table = batch.out / "ranges.csv"
    batch.assemble(n, "rows", table, ",".join(RANGE_COLUMNS))
    if save_images:
        batch.assemble(n, "laser", batch.out / "laser.csv", ",".join(LASER_COLUMNS))
    counts = pd.read_csv(table, usecols=["fused_source"])["fused_source"].value_counts()
    return DetectSummary(n, len(finished), int(counts.get("laser", 0)),
                         int(counts.get("stereo", 0)), time.perf_counter() - t0, table)


def _jsonable(d: object) -> object:
    if isinstance(d, dict):
        return {k: _jsonable(v) for k, v in d.items()}
    if isinstance(d, list | tuple):
        return [_jsonable(v) for v in d]
    if isinstance(d, float) and not math.isfinite(d):
        return str(d)
    return d


__all__ = ["RANGE_COLUMNS", "DetectParams", "DetectSummary", "Detector", "FrameDetection",
           "run_detect"]
