"""Fusion of laser and stereo ranges per bearing bin (paper Eq. 11, DESIGN §7).

Inputs and outputs are per bearing bin (sensor frame, metres); NaN means "no return".

Paper mode (Eq. 11 as read in DESIGN §7), per bin:

1. stereo has no features there (neither its flag nor a return) -> the laser range
   (which may be "no return");
2. the laser returns nearer than its maximum range -> ``min(laser, stereo)``;
3. no laser return -> the stereo range, but not closer than the laser's maximum range:
   ``max(laser_max_range, stereo)``. This trusts the laser's negative reading, which is
   wrong for an obstacle that overhangs the laser sheet (a table top, a shelf): the
   robot then believes the obstacle is at least ``laser_max_range`` away.

Conservative mode: the plain minimum of the two returns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slitcli.errors import SlitcliError

FUSION_MODES = ("paper", "conservative")
SOURCE_NONE, SOURCE_LASER, SOURCE_STEREO = "none", "laser", "stereo"


@dataclass(frozen=True)
class FusionParams:
    """How laser and stereo ranges are combined.

    ``laser_max_range_m`` is the paper's max_Distance (the laser's active band ends
    there); stereo returns beyond ``stereo_max_range_m`` are ignored.
    """

    mode: str = "paper"
    laser_max_range_m: float = 1.0
    stereo_max_range_m: float = 3.0

    def __post_init__(self) -> None:
        if self.mode not in FUSION_MODES:
            raise SlitcliError(f"--fusion {self.mode!r} is unknown; use one of "
                               f"{', '.join(FUSION_MODES)}")
        if not self.laser_max_range_m > 0 or not self.stereo_max_range_m > 0:
            raise SlitcliError("fusion ranges must be positive; check the rig's "
                               "laser.max_range_m and stereo.max_range_m")


@dataclass(frozen=True)
class FusedRanges:
    """Fused range per bin (metres, NaN = free) and where it came from
    (``laser``, ``stereo`` or ``none``)."""

    range_m: np.ndarray
    source: np.ndarray


def fuse(laser_range_m: np.ndarray, stereo_range_m: np.ndarray,
         stereo_has_features: np.ndarray, params: FusionParams) -> FusedRanges:
    """Combine laser and stereo ranges per bearing bin (paper Eq. 11).

    Parameters
    ----------
    laser_range_m, stereo_range_m : ndarray, shape (B,)
        Nearest return per bin, metres; NaN = no return.
    stereo_has_features : ndarray of bool, shape (B,)
        Whether stereo saw enough texture in the bin to be trusted at all.
    params : FusionParams

    Returns
    -------
    FusedRanges
    """
    laser = np.asarray(laser_range_m, dtype=float)
    stereo = np.asarray(stereo_range_m, dtype=float)
    # a stereo return needs matched texture, so a bin with one has features even when the
    # bin holds too few textured pixels for the stereo flag (e.g. the edge bins)
    feat = np.asarray(stereo_has_features, dtype=bool) | np.isfinite(stereo)
    stereo = np.where(stereo <= params.stereo_max_range_m, stereo, np.nan)
    has_l, has_s = np.isfinite(laser), np.isfinite(stereo)
    nearer_stereo = has_s & (~has_l | (stereo < laser))
    min_rng = np.where(nearer_stereo, stereo, laser)
    min_src = np.where(nearer_stereo, SOURCE_STEREO, np.where(has_l, SOURCE_LASER, SOURCE_NONE))
    if params.mode == "conservative":
        return FusedRanges(min_rng, min_src.astype(object))
    laser_in_band = has_l & (laser < params.laser_max_range_m)
    beyond = np.where(has_s, np.maximum(stereo, params.laser_max_range_m), np.nan)
    rng = np.where(~feat, laser, np.where(laser_in_band, min_rng, beyond))
    src = np.where(~feat, np.where(has_l, SOURCE_LASER, SOURCE_NONE),
                   np.where(laser_in_band, min_src,
                            np.where(has_s, SOURCE_STEREO, SOURCE_NONE)))
    return FusedRanges(rng, src.astype(object))
