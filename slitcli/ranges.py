"""Bearing bins, the per-frame range table and the column schemas of every table.

The bin rule (stated once, used by every sensor and by the ground truth)
-------------------------------------------------------------------------
Bin ``k`` (an integer, absolute) is centred on ``k * bin_deg`` and holds the bearings
in ``[(k - 1/2) bin_deg, (k + 1/2) bin_deg)``: a bearing exactly on a boundary belongs
to the bin on its left (the larger bearing), ``k = floor(b / bin_deg + 1/2)``
(:func:`absolute_bin`). The bins of a rig are the ``k`` whose bins lie at least half
inside the left camera's horizontal field of view (:class:`BearingBins`).

The range table
---------------
:class:`RangeTable` is one frame's per-bearing ranges (laser, stereo, fused); its rows
are the ``ranges.csv`` rows. :data:`TABLES` lists the columns of every CSV file the
tool writes (docs/detect.md and the other pages document them).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas is imported where rows are made, not at start-up
    import pandas as pd


def absolute_bin(bearing_deg: np.ndarray | float, bin_deg: float) -> np.ndarray:
    """Absolute bin index ``k`` of each bearing: ``floor(b / bin_deg + 1/2)``.

    Parameters
    ----------
    bearing_deg : ndarray or float
        Bearings, sensor frame, positive left, degrees. Must be finite.
    bin_deg : float
        Bin width, degrees.

    Returns
    -------
    ndarray of int64, same shape as ``bearing_deg``
    """
    return np.floor(np.asarray(bearing_deg, dtype=np.float64) / bin_deg + 0.5).astype(np.int64)


def boundary_deg(lower_bin: np.ndarray | int, bin_deg: float) -> np.ndarray:
    """Bearing of the boundary between absolute bins ``k`` and ``k + 1``, degrees
    (``(k + 1/2) bin_deg``; it belongs to bin ``k + 1``)."""
    return (np.asarray(lower_bin, dtype=np.float64) + 0.5) * bin_deg


def bin_min(index: np.ndarray, values: np.ndarray, n_bins: int) -> np.ndarray:
    """Smallest finite value per bin, (n_bins,), NaN where a bin has none.

    ``index`` holds table bins (``-1`` or out of range: ignored), same shape as
    ``values``.
    """
    idx = np.asarray(index, dtype=np.int64).ravel()
    v = np.asarray(values, dtype=np.float64).ravel()
    ok = (idx >= 0) & (idx < n_bins) & np.isfinite(v)
    out = np.full(n_bins, np.inf)
    np.minimum.at(out, idx[ok], v[ok])
    return np.where(np.isfinite(out), out, np.nan)


def bin_median(index: np.ndarray, values: np.ndarray, n_bins: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Median of the finite values per bin, (n_bins,), NaN where a bin has none, and how
    many finite values each bin holds, (n_bins,) int.

    ``index`` holds table bins (``-1`` or out of range: ignored), same shape as
    ``values``.
    """
    idx = np.asarray(index, dtype=np.int64).ravel()
    v = np.asarray(values, dtype=np.float64).ravel()
    ok = (idx >= 0) & (idx < n_bins) & np.isfinite(v)
    idx, v = idx[ok], v[ok]
    order = np.lexsort((v, idx))
    idx, v = idx[order], v[order]
    count = np.bincount(idx, minlength=n_bins)
    start = np.concatenate(([0], np.cumsum(count)[:-1]))
    med = np.full(n_bins, np.nan)
    has = count > 0
    med[has] = 0.5 * (v[start[has] + (count[has] - 1) // 2] + v[start[has] + count[has] // 2])
    return med, count


def median_of_finite(values: np.ndarray, axis: int = 0) -> np.ndarray:
    """Median of the finite entries of ``values`` along ``axis``, NaN where there are none
    (``np.nanmedian`` without its per-call overhead and its warning per empty slice:
    sorting puts NaN last)."""
    a = np.moveaxis(np.asarray(values, dtype=np.float64), axis, 0)
    srt = np.sort(a, axis=0)
    n = np.isfinite(a).sum(axis=0)
    last = max(a.shape[0] - 1, 0)
    lo = np.take_along_axis(srt, np.clip((n - 1) // 2, 0, last)[None], axis=0)[0]
    hi = np.take_along_axis(srt, np.clip(n // 2, 0, last)[None], axis=0)[0]
    return np.where(n > 0, 0.5 * (lo + hi), np.nan)


def bin_count(index: np.ndarray, n_bins: int, weights: np.ndarray | None = None
              ) -> np.ndarray:
    """Number of entries (or sum of ``weights``) per bin, (n_bins,)."""
    idx = np.asarray(index, dtype=np.int64).ravel()
    ok = (idx >= 0) & (idx < n_bins)
    w = None if weights is None else np.asarray(weights, dtype=np.float64).ravel()[ok]
    out = np.bincount(idx[ok], weights=w, minlength=n_bins)
    return out if weights is not None else out.astype(np.int64)


@dataclass(frozen=True)
class BearingBins:
    """The bearing bins of one rig and bin width.

    ``centres_deg`` (B,) ascending (right to left); ``first`` is the absolute index of
    bin 0, so absolute bin ``k`` is table bin ``k - first``.
    """

    centres_deg: np.ndarray
    bin_deg: float
    first: int

    @classmethod
    def for_rig(cls, rig: object, bin_deg: float) -> BearingBins:
        """The bins of ``rig`` (:meth:`slitcli.rig.Rig.bearing_bins`)."""
        centres = rig.bearing_bins(bin_deg)[0]  # type: ignore[attr-defined]
        first = round(float(centres[0]) / bin_deg) if centres.size else 0
        centres = np.array(centres, dtype=np.float64)
        centres.setflags(write=False)
        return cls(centres, float(bin_deg), int(first))

    def __len__(self) -> int:
        return int(self.centres_deg.size)

    @property
    def lower_deg(self) -> np.ndarray:
        """Lower wedge limits (B,), degrees (inclusive)."""
        return self.centres_deg - self.bin_deg / 2

    @property
    def upper_deg(self) -> np.ndarray:
        """Upper wedge limits (B,), degrees (exclusive)."""
        return self.centres_deg + self.bin_deg / 2

    def table_bin(self, absolute: np.ndarray | int) -> np.ndarray:
        """Table bin of absolute bins (int64, -1 outside the rig's bins)."""
        k = np.asarray(absolute, dtype=np.int64) - self.first
        return np.where((k >= 0) & (k < len(self)), k, -1)

    def index(self, bearing_deg: np.ndarray | float) -> np.ndarray:
        """Table bin of each bearing (int64, -1 outside the bins or not finite)."""
        b = np.asarray(bearing_deg, dtype=np.float64)
        finite = np.isfinite(b)
        k = self.table_bin(absolute_bin(np.where(finite, b, 0.0), self.bin_deg))
        return np.where(finite, k, -1)

    def nearest(self, bearing_deg: np.ndarray, range_m: np.ndarray) -> np.ndarray:
        """Smallest finite range per bin, (B,) metres, NaN where a bin has none."""
        return bin_min(self.index(bearing_deg), range_m, len(self))

    def count(self, bearing_deg: np.ndarray) -> np.ndarray:
        """Number of finite bearings per bin, (B,)."""
        return bin_count(self.index(bearing_deg), len(self))


# ------------------------------------------------------------------ the range table
FUSED_SOURCES = ("laser", "stereo", "none")


@dataclass(frozen=True)
class RangeTable:
    """One frame's nearest obstacle per bearing bin, per sensor and fused (paper Eq. 11).

    Every array has shape (B,), one entry per bin of :class:`BearingBins`. Ranges are
    horizontal distances in the sensor frame (metres) from the point on the floor below
    the left camera; NaN means no return.

    Attributes
    ----------
    bearing_deg : bin centres, positive left, degrees, ascending.
    laser_range_m : nearest laser point in the bin (Eqs. 1-7).
    stereo_range_m : nearest stereo obstacle point in the bin (Eqs. 8-10).
    stereo_has_features : bool, the bin holds enough textured pixels for stereo to
        speak (a stereo "no return" there means free space).
    fused_range_m : the fused range (Eq. 11).
    fused_source : str, which sensor gave it (``laser``, ``stereo`` or ``none``).
    laser_free_m : how far the laser's silence certified the bin free of obstacles on
        its sheet (at most its maximum range; :func:`slitcli.fusion.laser_reach_m`);
        NaN: the laser certified nothing there (no stripe seen: laser off, too dim,
        grey images). None: NaN everywhere.
    """

    bearing_deg: np.ndarray
    laser_range_m: np.ndarray
    stereo_range_m: np.ndarray
    stereo_has_features: np.ndarray
    fused_range_m: np.ndarray
    fused_source: np.ndarray
    laser_free_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = np.shape(self.bearing_deg)
        if self.laser_free_m is None:
            object.__setattr__(self, "laser_free_m", np.full(n, np.nan))
        for name in ("laser_range_m", "stereo_range_m", "stereo_has_features",
                     "fused_range_m", "fused_source", "laser_free_m"):
            if np.shape(getattr(self, name)) != n:
                raise ValueError(f"RangeTable.{name} has shape {np.shape(getattr(self, name))},"
                                 f" bearing_deg {n}")

    def __len__(self) -> int:
        return int(np.size(self.bearing_deg))

    def rows(self, frame: int, time_s: float) -> pd.DataFrame:
        """The ``ranges.csv`` rows of this frame (:data:`RANGES` columns)."""
        import pandas as pd

        return pd.DataFrame({
            "frame": np.full(len(self), frame, dtype=np.int64),
            "time_s": format_time_s(time_s), "bearing_deg": self.bearing_deg,
            "laser_range_m": self.laser_range_m, "stereo_range_m": self.stereo_range_m,
            "stereo_has_features": np.asarray(self.stereo_has_features).astype(np.int64),
            "fused_range_m": self.fused_range_m, "fused_source": self.fused_source,
            "laser_free_m": self.laser_free_m,
        }, columns=list(RANGES.columns))

    def csv_rows(self, frame: int, time_s: float) -> str:
        """The ``ranges.csv`` rows of this frame as CSV text without header: the bytes of
        ``csv_rows(self.rows(frame, time_s))``, without importing pandas (a one-frame
        ``slitcli detect`` would spend a third of its start-up importing it)."""
        n = len(self)
        return format_csv_rows((
            np.full(n, frame, dtype=np.int64), np.full(n, format_time_s(time_s), dtype=object),
            np.asarray(self.bearing_deg), np.asarray(self.laser_range_m),
            np.asarray(self.stereo_range_m),
            np.asarray(self.stereo_has_features).astype(np.int64),
            np.asarray(self.fused_range_m), np.asarray(self.fused_source),
            np.asarray(self.laser_free_m)))


# ------------------------------------------------------------------ table schemas
@dataclass(frozen=True)
class TableSchema:
    """The columns of one CSV file the tool writes, in order (``file``: its usual name)."""

    file: str
    columns: tuple[str, ...]

    @property
    def header(self) -> str:
        """The header line (no newline)."""
        return ",".join(self.columns)


RANGES = TableSchema("ranges.csv", (
    "frame", "time_s", "bearing_deg", "laser_range_m", "stereo_range_m",
    "stereo_has_features", "fused_range_m", "fused_source", "laser_free_m"))
LASER = TableSchema("laser.csv", (
    "frame", "u_px", "v_px", "strength", "x_m", "y_m", "range_m", "bearing_deg", "in_band"))
STEREO_RANGES = TableSchema("stereo_ranges.csv", (
    "frame", "time_s", "bearing_deg", "stereo_range_m", "stereo_has_features",
    "obstacle_px", "feature_px"))
TIMES = TableSchema("times.csv", ("frame", "time_s"))
TRUTH_RANGES = TableSchema("gt/ranges.csv", ("frame", "time_s", "bearing_deg", "range_m"))
TRUTH_LASER = TableSchema("gt/laser.csv", (
    "frame", "u_px", "v_px", "strength", "x_m", "y_m", "range_m", "bearing_deg"))
TRUTH_LASER_RANGES = TableSchema("gt/laser_ranges.csv", (
    "frame", "time_s", "bearing_deg", "laser_true_m"))
TRUTH_POSES = TableSchema("gt/poses.csv", ("frame", "time_s", "x_m", "y_m", "yaw_deg"))
DWA_COMMANDS = TableSchema("cmds.csv", (
    "frame", "time_s", "x_m", "y_m", "heading_deg", "goal_distance_m", "v_mps", "w_dps",
    "status", "d_collision_m", "n_points"))
SIM_TRAJECTORY = TableSchema("trajectory.csv", (
    "t_s", "x_m", "y_m", "heading_deg", "v_mps", "w_dps", "nearest_obstacle_m"))
SIM_METRICS = TableSchema("metrics.csv", (
    "case", "initial_distance_m", "sensing_range_m", "reached_goal", "collided",
    "min_clearance_m", "time_to_goal_s", "path_length_m", "outcome"))

TABLES: Mapping[str, TableSchema] = MappingProxyType({
    t.file: t for t in (RANGES, LASER, STEREO_RANGES, TIMES, TRUTH_RANGES, TRUTH_LASER,
                        TRUTH_LASER_RANGES, TRUTH_POSES, DWA_COMMANDS, SIM_TRAJECTORY,
                        SIM_METRICS)})

# The range columns of a range table that a planner can drive on.
RANGE_VALUE_COLUMNS = ("laser_range_m", "stereo_range_m", "fused_range_m")

# Measured values keep 6 significant digits (micrometres at metres, far below any
# sensor's resolution); times keep every digit of their stamp (format_time_s).
FLOAT_FORMAT = "%.6g"


def format_time_s(time_s: float) -> str:
    """A time in seconds at full precision: the shortest decimal that reads back as the
    same float, at most 9 decimals (nanoseconds); empty for NaN.

    ``%.6g`` would print a wall-clock stamp of 1.76e9 s as ``1.76e+09`` and erase every
    step between frames.
    """
    t = float(time_s)
    if not np.isfinite(t):
        return ""
    return np.format_float_positional(t, precision=9, unique=True, trim="-")


TIME_COLUMNS = ("time_s", "t_s", "time_to_goal_s")


def times_as_text(table: pd.DataFrame, columns: tuple[str, ...] = TIME_COLUMNS) -> pd.DataFrame:
    """A copy of ``table`` whose time columns (those of ``columns`` it has) are text at
    full precision (:func:`format_time_s`), for writing with a float format that would
    round them."""
    out = table.copy()
    for col in columns:
        if col in out.columns:
            out[col] = [format_time_s(t) for t in out[col].to_numpy(dtype=float)]
    return out


def csv_rows(table: pd.DataFrame) -> str:
    """Rows of a table as CSV text without header (``FLOAT_FORMAT``, empty for NaN)."""
    return table.to_csv(header=False, index=False, float_format=FLOAT_FORMAT, na_rep="",
                        lineterminator="\n")


def _cells(values: np.ndarray) -> list[str]:
    """One column's cells as pandas' ``to_csv`` writes them with ``FLOAT_FORMAT`` and an
    empty ``na_rep``: floats through the format (NaN empty, inf as ``inf``), integers
    and booleans as Python prints them, other objects with ``str`` (None and NaN empty)."""
    a = np.asarray(values).ravel()
    if a.dtype.kind == "f":
        return ["" if v != v else FLOAT_FORMAT % v for v in a.tolist()]
    if a.dtype.kind in "iub":
        return [str(v) for v in a.tolist()]
    return ["" if v is None or (isinstance(v, float) and v != v) else str(v)
            for v in a.tolist()]


def format_csv_rows(columns: Sequence[np.ndarray]) -> str:
    """Rows of equal-length columns as CSV text without header, the same bytes as
    :func:`csv_rows` of a DataFrame of those columns (``FLOAT_FORMAT``, empty for NaN,
    ``\\n`` line ends, fields quoted only where the text needs it), without pandas."""
    cells = [_cells(c) for c in columns]
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(zip(*cells, strict=True))
    return buf.getvalue()


__all__ = ["DWA_COMMANDS", "FLOAT_FORMAT", "FUSED_SOURCES", "LASER", "RANGES",
           "RANGE_VALUE_COLUMNS", "SIM_METRICS", "SIM_TRAJECTORY", "STEREO_RANGES", "TABLES",
           "TIMES", "TRUTH_LASER", "TRUTH_LASER_RANGES", "TRUTH_POSES", "TRUTH_RANGES",
           "BearingBins", "RangeTable", "TableSchema", "absolute_bin", "bin_count", "bin_min",
           "boundary_deg", "csv_rows", "format_csv_rows", "format_time_s", "times_as_text"]
