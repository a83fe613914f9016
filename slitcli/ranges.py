"""Bearing bins: the one rule that maps a bearing to a range-table bin (DESIGN §6).

Every per-bearing table (laser, stereo, fused, ground truth) uses these bins. Bin
``k`` (an integer, absolute) is centred on ``k * bin_deg`` and holds the bearings in
``[(k - 1/2) bin_deg, (k + 1/2) bin_deg)``: a bearing exactly on a boundary belongs to
the bin on its left (the larger bearing). The bins of a rig are the ``k`` whose bins
lie at least half inside the left camera's horizontal field of view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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

    def index(self, bearing_deg: np.ndarray | float) -> np.ndarray:
        """Table bin of each bearing (int64, -1 outside the bins or not finite)."""
        b = np.asarray(bearing_deg, dtype=np.float64)
        finite = np.isfinite(b)
        k = absolute_bin(np.where(finite, b, 0.0), self.bin_deg) - self.first
        return np.where(finite & (k >= 0) & (k < len(self)), k, -1)

    def nearest(self, bearing_deg: np.ndarray, range_m: np.ndarray) -> np.ndarray:
        """Smallest finite range per bin, (B,) metres, NaN where a bin has none."""
        idx = self.index(bearing_deg)
        r = np.asarray(range_m, dtype=np.float64)
        ok = (idx >= 0) & np.isfinite(r)
        out = np.full(len(self), np.inf)
        np.minimum.at(out, idx[ok], r[ok])
        return np.where(np.isfinite(out), out, np.nan)


__all__ = ["BearingBins", "absolute_bin"]
