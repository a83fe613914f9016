"""A finished detection run, read from its files (docs/detect.md).

The report and the ROS export read only what ``slitcli detect`` writes: ``ranges.csv``
(schema 2), the optional ``laser.csv`` and ``mask/``, and the manifest in
``.slitcli/detect/manifest.json`` (the rig, the input's kind and frames). Nothing here
runs detection. :func:`left_images` is the one place that reads the input's frames
again (for the overlay video and the exported images).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from slitcli.errors import SlitcliError
from slitcli.rig import Rig, rig_from_dict

RANGES_COLUMNS = ("frame", "time_s", "bearing_deg", "laser_range_m", "stereo_range_m",
                  "stereo_has_features", "fused_range_m", "fused_source")
SOURCES = ("laser", "stereo", "none")
MANIFEST = Path(".slitcli") / "detect" / "manifest.json"
# where the run's input was (written by detect beside the manifest, not part of its identity)
SOURCE = Path(".slitcli") / "detect" / "source.json"


@dataclass(frozen=True)
class DetectRun:
    """The range table of a run as arrays, with what the manifest says about it.

    Attributes
    ----------
    folder : Path
        The run's output folder (``DETECT_OUT``).
    frames : ndarray (F,) int64
        Frame indices, ascending.
    time_s : ndarray (F,) float64
        Frame times, seconds; NaN where ``ranges.csv`` has none.
    bearing_deg : ndarray (B,) float64
        Bin centres, sensor frame, positive left, ascending (right to left).
    bin_deg : float
        Bin width, degrees.
    laser_range_m, stereo_range_m, fused_range_m : ndarray (F, B) float64
        Horizontal ranges from the sensor origin, metres; NaN = no return.
    fused_source : ndarray (F, B) int8
        Index into :data:`SOURCES` (0 laser, 1 stereo, 2 none).
    manifest : dict
        The detect manifest (arguments, rig, input description).
    rig : Rig
        The rig the run used.
    """

    folder: Path
    frames: np.ndarray
    time_s: np.ndarray
    bearing_deg: np.ndarray
    bin_deg: float
    laser_range_m: np.ndarray
    stereo_range_m: np.ndarray
    fused_range_m: np.ndarray
    fused_source: np.ndarray
    manifest: dict[str, Any]
    rig: Rig

    @property
    def n_frames(self) -> int:
        return int(self.frames.size)

    @property
    def input_kind(self) -> str:
        """``folder`` or ``bag`` (as the manifest records it)."""
        return str(self.manifest.get("input", {}).get("kind", "folder"))

    def frame_names(self) -> list[str]:
        """The file stem of each frame's images in ``mask/``, ``distance/``...

        A folder run names them after the input images, a bag run ``000000``, ``000001``...
        """
        names = self.manifest.get("input", {}).get("names")
        if isinstance(names, list) and len(names) == self.n_frames:
            return [str(n) for n in names]
        return [f"{int(i):06d}" for i in self.frames]

    def recorded_source(self) -> Path | None:
        """The input path the manifest records, if it records one."""
        try:
            where = json.loads((self.folder / SOURCE).read_text())
        except (OSError, ValueError):
            return None
        path = where.get("path") if isinstance(where, dict) else None
        return Path(path) if isinstance(path, str) else None


def load_run(folder: str | Path) -> DetectRun:
    """Read ``folder/ranges.csv`` and the detect manifest.

    Raises
    ------
    SlitcliError
        The folder is not a finished ``slitcli detect`` output, or its table is malformed.
    """
    out = Path(folder)
    table = out / "ranges.csv"
    if not out.is_dir():
        raise SlitcliError(f"{out}: not found; give the output folder of `slitcli detect`")
    if not table.is_file():
        raise SlitcliError(f"{table}: not found; give the output folder of a finished "
                           "`slitcli detect` run (it writes ranges.csv at the end)")
    manifest = _read_manifest(out / MANIFEST)
    try:
        rig = rig_from_dict(manifest.get("rig"), f"{out / MANIFEST}: rig")
    except SlitcliError as e:
        raise SlitcliError(f"{out / MANIFEST}: holds no readable rig ({e}); re-run "
                           "`slitcli detect`") from None
    try:
        t = pd.read_csv(table, dtype={"fused_source": str}, keep_default_na=False,
                        na_values=[""])
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError):
        raise SlitcliError(f"{table}: not a ranges.csv table (docs/detect.md); re-run "
                           "`slitcli detect`") from None
    missing = [c for c in RANGES_COLUMNS if c not in t.columns]
    if missing:
        raise SlitcliError(f"{table}: columns {', '.join(missing)} missing (schema in "
                           "docs/detect.md); re-run `slitcli detect`")
    return _arrays(out, t, manifest, rig)


def _read_manifest(path: Path) -> dict[str, Any]:
    try:
        m = json.loads(path.read_text())
    except FileNotFoundError:
        raise SlitcliError(f"{path}: not found; the folder was not written by `slitcli "
                           "detect` (it keeps its manifest there)") from None
    except (OSError, json.JSONDecodeError, UnicodeDecodeError):
        raise SlitcliError(f"{path}: unreadable manifest; re-run `slitcli detect`") from None
    if not isinstance(m, dict) or m.get("command") != "detect":
        raise SlitcliError(f"{path}: not a detect manifest; give the output folder of "
                           "`slitcli detect`")
    return m


def _arrays(out: Path, t: pd.DataFrame, manifest: dict[str, Any], rig: Rig) -> DetectRun:
    table = out / "ranges.csv"
    if t.empty:
        raise SlitcliError(f"{table}: has no rows; the run holds no frames")
    try:
        frame = t["frame"].to_numpy(dtype=np.int64)
        bearing = t["bearing_deg"].to_numpy(dtype=np.float64)
        ranges = {c: t[c].to_numpy(dtype=np.float64)
                  for c in ("time_s", "laser_range_m", "stereo_range_m", "fused_range_m")}
    except (ValueError, TypeError):
        raise SlitcliError(f"{table}: a number column holds text; re-run `slitcli detect`") \
            from None
    frames, f_idx = np.unique(frame, return_inverse=True)
    bearings, b_idx = np.unique(bearing, return_inverse=True)
    n_f, n_b = frames.size, bearings.size
    if len(t) != n_f * n_b or np.unique(f_idx * n_b + b_idx).size != len(t):
        raise SlitcliError(f"{table}: every frame must have one row per bearing bin "
                           f"({n_f} frames x {n_b} bins != {len(t)} rows); re-run "
                           "`slitcli detect`")
    steps = np.diff(bearings)
    bin_deg = float(np.median(steps)) if steps.size else float(
        manifest.get("params", {}).get("bin_deg", 1.0))
    if steps.size and np.max(np.abs(steps - bin_deg)) > 1e-3 * bin_deg:
        raise SlitcliError(f"{table}: the bearings are not evenly spaced; a scan needs "
                           "contiguous bins of one width")
    src = t["fused_source"].fillna("none").to_numpy(dtype=str)
    code = np.full(len(t), -1, dtype=np.int8)
    for k, name in enumerate(SOURCES):
        code[src == name] = k
    if (code < 0).any():
        bad = src[code < 0][0]
        raise SlitcliError(f"{table}: fused_source {bad!r} is not one of "
                           f"{', '.join(SOURCES)}")

    def grid(values: np.ndarray, fill: float | int) -> np.ndarray:
        g = np.full((n_f, n_b), fill, dtype=values.dtype)
        g[f_idx, b_idx] = values
        g.setflags(write=False)
        return g

    times = np.full(n_f, np.nan)
    times[f_idx] = ranges["time_s"]
    for a in (frames, times, bearings):
        a.setflags(write=False)
    return DetectRun(out, frames, times, bearings, bin_deg,
                     grid(ranges["laser_range_m"], np.nan), grid(ranges["stereo_range_m"],
                                                                 np.nan),
                     grid(ranges["fused_range_m"], np.nan), grid(code, 2), manifest, rig)


def stereo_min_range_m(run: DetectRun) -> float:
    """Nearest range the matcher can see: ``f B / d_max`` (Eq. 8), metres.

    ``d_max`` is the largest disparity searched (``min_disparity_px + num_disparities``
    from the run's parameters); 0 if the manifest does not say.
    """
    m = run.manifest.get("params", {}).get("stereo", {}).get("matcher", {})
    try:
        d_max = float(m.get("min_disparity_px", 0)) + float(m["num_disparities"])
    except (KeyError, TypeError, ValueError):
        return 0.0
    return run.rig.focal_px * run.rig.baseline_m / d_max if d_max > 0 else 0.0


def frame_times_s(run: DetectRun, period_s: float) -> tuple[np.ndarray, bool]:
    """Each frame's time in seconds, and whether it came from the run's own times.

    When any frame has no time (empty ``time_s``), or the times do not increase, every
    frame gets ``frame index x period_s`` instead, so a player sees an even clock.
    """
    t = run.time_s
    if t.size and np.isfinite(t).all() and (t.size == 1 or (np.diff(t) > 0).all()):
        return t, True
    return run.frames.astype(np.float64) * period_s, False


def left_images(run: DetectRun, source: str | Path | None = None
                ) -> Iterator[tuple[int, np.ndarray]]:
    """The run's left images, rectified, in frame order: ``(frame, left_bgr)``.

    This is the only function that reads the input again; it follows the manifest's
    input kind (a sequence folder, or a ROS bag with the recorded topics).

    Parameters
    ----------
    run : DetectRun
    source : path, optional
        The input the run was made from (a sequence folder or a bag); default: the path
        the manifest records.

    Yields
    ------
    frame : int
    left_bgr : ndarray (H, W, 3) uint8
        Rectified with the rig when it carries a raw calibration.
    """
    from slitcli.calibrate.rectify import RectificationMaps, rectify_pair

    src = resolve_source(run, source)
    maps = RectificationMaps.for_rig(run.rig) if run.rig.raw is not None else None
    for index, left in _raw_left_images(run, src):
        if maps is None:
            yield index, left
        else:
            yield index, rectify_pair(run.rig, left, maps=maps)[0]


def resolve_source(run: DetectRun, source: str | Path | None) -> Path:
    """The input path: ``source`` if given, else the manifest's; checked to exist."""
    src = Path(source) if source is not None else run.recorded_source()
    if src is None:
        raise SlitcliError(f"{run.folder / MANIFEST}: does not record the input's path; "
                           "give the sequence folder or bag the run was made from (`source`)",
                           param="source")
    if not src.exists():
        raise SlitcliError(f"{src}: the run's input is not there; give the sequence folder "
                           "or bag the run was made from (`source`)",
                           param="source")
    return src


def _open_source(run: DetectRun, src: Path):  # -> slitcli.io.frames.FrameSource
    from slitcli.io.frames import open_frames

    inp = run.manifest.get("input", {})
    frames = open_frames(src, left_topic=str(inp.get("left_topic", "/stereo/left/image_raw")),
                         right_topic=str(inp.get("right_topic", "/stereo/right/image_raw")),
                         max_dt_s=float(inp.get("max_dt_s", 0.01)))
    _check_count(run, src, len(frames))
    if frames.manifest() != inp:
        raise SlitcliError(f"{src}: its images are not the ones the run was made from "
                           "(other names or stamps); give the run's own input (`source`)",
                           param="source")
    return frames


def _raw_left_images(run: DetectRun, src: Path) -> Iterator[tuple[int, np.ndarray]]:
    frames = _open_source(run, src)
    skip = set(range(len(frames))) - set(run.frames.tolist())
    for fr in frames.frames(None, skip=skip):
        yield fr.index, fr.left_bgr


def _check_count(run: DetectRun, src: Path, n: int) -> None:
    recorded = run.manifest.get("input", {}).get("frames")
    if isinstance(recorded, int) and recorded != n:
        raise SlitcliError(f"{src}: holds {n} frames, the run was made from {recorded}; give "
                           "the run's own input (`source`)",
                           param="source")


def bag_stamps_ns(run: DetectRun, source: str | Path | None) -> np.ndarray | None:
    """The left image stamps (ns) of a bag run, read again from the bag; None otherwise.

    ``ranges.csv`` keeps times to 6 significant digits, too coarse for epoch stamps;
    the bag has them exactly. None for a folder run or when the bag is not at hand.
    """
    if run.input_kind != "bag":
        return None
    src = Path(source) if source is not None else run.recorded_source()
    if src is None or not src.exists():
        return None
    return _open_source(run, src).pairs.left_ns[run.frames]

