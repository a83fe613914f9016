"""Fusion of laser and stereo ranges per bearing bin (paper Eq. 11, DESIGN §7).

Inputs and outputs are per bearing bin (sensor frame, metres); NaN means "no return".

Paper mode (Eq. 11 as read in DESIGN §7), per bin:

1. stereo has no features there (neither its flag nor a return) -> the laser range
   (which may be "no return");
2. the laser returns nearer than its maximum range -> ``min(laser, stereo)``, except
   that a stereo return nearer by at most ``same_surface_px`` of disparity is the
   same surface as the laser's, and the laser's range is kept: inside its band the
   laser is the precise sensor (well under 1 %), while a bin's stereo range, a low
   percentile of its points, sits up to about 1.6 px short of it (measured on the
   evaluation renders; docs/detect.md). Without this, a textureless obstacle whose
   silhouette or laser stripe gives stereo a few matches takes the stereo range;
3. no laser return -> the stereo range, but not closer than the laser's maximum range:
   ``max(laser_max_range, stereo)`` (here: not closer than the laser certifies the bin
   free, at most its maximum range; below). This trusts the laser's negative reading, which is
   wrong for an obstacle that overhangs the laser sheet (a table top, a shelf): the
   robot then believes the obstacle is at least ``laser_max_range`` away.

Rule 3 reads the paper's "no laser return" (a return beyond the band counts as none:
the stripe is too faint there to trust) as "the obstacle is beyond the laser's reach".
That reading needs a laser that could have been seen: with the laser off, blocked, too
weak for the exposure, or a camera too noisy or grey, there is no return anywhere and
silence means nothing. So the laser certifies free space only as far as this frame
shows it can see (:func:`laser_reach_m`):

* a stripe seen at range ``r`` with peak ``s`` (DN) would, on the same surface at range
  ``r'``, peak at ``s (r / r')**p`` at least, ``p`` the steepest plausible fall-off of
  the stripe's brightness with range (``falloff_exponent``; light spread along the fan
  gives 1, an unresolved stripe's shrinking image width another 1, so 2 for a real
  laser; the renderer uses 4). It is found with near certainty where that peak
  exceeds the extractor's seed level by ``certain_z`` noise sigmas (``required``). So
  the column certifies a reach ``r (s / required)**(1/p)``;
* a bin takes the smaller of the largest reaches on either side of it, its own columns
  included (one side at the edges of the view): the stripe was seen on both sides with
  enough signal to be seen here. The largest, because a weak column (a segment's end,
  a grazing or dark face) tells of its surface, not of the laser and the camera;
* a bin's own return beyond the band shows directly that the sheet passed through to
  that range;
* no stripe in the frame (the extractor also drops frames whose longest stripe
  segment is too short to be the laser's): nothing is certified.

Silence then moves a stereo return out to ``min(reach, laser_max_range)`` only when it
lies nearer than that; elsewhere stereo's range stands (the conservative choice where
the laser cannot tell). A steeper ``p`` credits the laser with less reach: the error
errs towards keeping stereo. The certified range per bin is returned
(:attr:`FusedRanges.laser_free_m`; ``ranges.csv``'s ``laser_free_m``).

Three more cases where the paper's reading does not hold, and what this module does:

* the stereo return lies nearer than the laser can see at that bearing (the stripe
  of an obstacle there would fall below the image; ``laser_sight_m``): the laser's
  silence says nothing, so the stereo range is kept as it is;
* the bin is next to one with a laser return in the band: the lit object's edge can
  enter this bin by less than one stripe column, so the silence is a matter of pixel
  resolution, not of reach, and the stereo range is kept;
* stereo sees the obstacle reach down to the sheet (:func:`stereo_reaches_sheet`:
  points of its near surface at the sheet's height): the sheet then falls on it, and
  the silence is the laser's miss (a face turned steeply away, dim under a codec),
  not free space, so the stereo range is kept. An overhang above the sheet shows no
  such points and is still moved out, as the paper's reading has it.

Conservative mode: the plain minimum of the two returns.

Before the bins, the stripe's own columns are checked against stereo
(:func:`stripe_depth_agrees`, both modes): laser light lies on the surface it lights,
so where stereo sees that pixel's surface clearly farther than the laser plane (a red
blob of texture on the floor below the sheet, through a codec's chroma), the piece of
stripe is not the laser's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import KW_ONLY, dataclass
from typing import TYPE_CHECKING

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.ranges import bin_median, bin_min, median_of_finite

if TYPE_CHECKING:
    from slitcli.rig import Rig

FUSION_MODES = ("paper", "conservative")
SOURCE_NONE, SOURCE_LASER, SOURCE_STEREO = "none", "laser", "stereo"


@dataclass(frozen=True)
class FusionParams:
    """How laser and stereo ranges are combined.

    ``laser_max_range_m`` is the paper's max_Distance (the laser's active band ends
    there); stereo returns beyond ``stereo_max_range_m`` are ignored. In paper mode a
    stereo return at most ``same_surface_px`` of disparity nearer than an in-band
    laser return is taken as the same surface (the laser's range is kept);
    ``focal_baseline_px_m`` is the rig's f x B (disparity = f B / range; the paper
    rig's 250 px x 0.088 m by default, :class:`slitcli.detect.Detector` sets it from
    the rig).

    The laser's silence certifies free space only as far as the frame shows the
    stripe can be seen (:func:`laser_reach_m`): ``falloff_exponent`` is the steepest
    fall-off of the stripe's peak with range assumed (peak ~ range**-p; unitless),
    ``certain_z`` how many noise sigmas above the extractor's seed level a stripe's
    peak must be to be found with near certainty (unitless; 3: one miss in 740).

    The stripe's depth check (:func:`stripe_depth_agrees`; ``depth_check`` False: none):
    a piece of stripe is dropped where, over at least ``depth_columns`` of its columns
    with a stereo disparity, stereo's disparity is the median ``depth_share`` (unitless,
    of the laser plane's) and ``depth_px`` (pixels) smaller than the laser plane's at
    those pixels; the frame's longest piece always stays.

    The sheet check (:func:`stereo_reaches_sheet`; ``sheet_check`` False: none): the
    laser's silence does not move a stereo return out where at least ``sheet_min_px``
    points of the bin's nearest stereo surface (within ``sheet_near_share`` of its
    range, unitless) lie at most ``sheet_tolerance_m`` (metres) above the sheet.
    """

    mode: str = "paper"
    laser_max_range_m: float = 1.0
    stereo_max_range_m: float = 3.0
    _: KW_ONLY
    same_surface_px: float = 2.0
    focal_baseline_px_m: float = 22.0
    falloff_exponent: float = 4.0
    certain_z: float = 3.0
    depth_check: bool = True
    depth_share: float = 0.05
    depth_px: float = 0.5
    depth_columns: int = 3
    sheet_check: bool = True
    sheet_tolerance_m: float = 0.08
    sheet_near_share: float = 0.05
    sheet_min_px: int = 3

    def __post_init__(self) -> None:
        if self.mode not in FUSION_MODES:
            raise SlitcliError(f"`mode` {self.mode!r} is unknown; use one of "
                               f"{', '.join(FUSION_MODES)}", param="mode")
        if not self.laser_max_range_m > 0 or not self.stereo_max_range_m > 0:
            raise SlitcliError("fusion ranges must be positive; check the rig's "
                               "laser.max_range_m and stereo.max_range_m")
        if not self.same_surface_px >= 0 or not self.focal_baseline_px_m > 0:
            raise SlitcliError("fusion needs same_surface_px >= 0 and a positive focal "
                               "length x baseline; check the rig's left.fx_px and baseline_m")
        if not (0.0 < self.depth_share < 1.0 and self.depth_px >= 0.0
                and self.depth_columns >= 1):
            raise SlitcliError(f"fusion needs 0 < depth_share < 1, depth_px >= 0 and "
                               f"depth_columns >= 1, got {self.depth_share}, "
                               f"{self.depth_px} and {self.depth_columns}",
                               param=("depth_share", "depth_px", "depth_columns"))
        if not (self.sheet_tolerance_m > 0 and self.sheet_near_share >= 0
                and self.sheet_min_px >= 1):
            raise SlitcliError(f"fusion needs sheet_tolerance_m > 0, sheet_near_share >= 0 "
                               f"and sheet_min_px >= 1, got {self.sheet_tolerance_m}, "
                               f"{self.sheet_near_share} and {self.sheet_min_px}",
                               param=("sheet_tolerance_m", "sheet_near_share",
                                      "sheet_min_px"))
        if not self.falloff_exponent > 0 or not self.certain_z >= 0:
            raise SlitcliError(f"fusion needs falloff_exponent > 0 and certain_z >= 0, got "
                               f"{self.falloff_exponent} and {self.certain_z}",
                               param=("falloff_exponent", "certain_z"))


@dataclass(frozen=True)
class FusedRanges:
    """Fused range per bin (metres, NaN = free), where it came from (``laser``,
    ``stereo`` or ``none``) and how far the laser's silence certified free space in the
    bin (``laser_free_m``, metres, at most the laser's maximum range; NaN: the laser
    certified nothing there). All (B,)."""

    range_m: np.ndarray
    source: np.ndarray
    laser_free_m: np.ndarray


def laser_reach_m(column_bin: np.ndarray, column_range_m: np.ndarray,
                  column_strength_dn: np.ndarray, threshold_dn: float, noise_sigma_dn: float,
                  n_bins: int, params: FusionParams) -> np.ndarray:
    """How far the laser could have seen an obstacle at each bearing bin in this frame.

    A stripe column at range ``r`` with peak ``s`` certifies the reach
    ``r (s / required)**(1/p)``, ``required = threshold_dn + certain_z noise_sigma_dn``
    and ``p = falloff_exponent`` (module docstring): out to there a stripe on the same
    surface would still be found. Each bin takes the smaller of the largest reaches of
    the stripe columns on either side of it, its own included (the one side at the
    edges of the view). No stripe column at all: NaN everywhere.

    Parameters
    ----------
    column_bin : ndarray of int, shape (W,)
        Table bin of each image column's stripe point (-1: none or outside the bins).
    column_range_m, column_strength_dn : ndarray, shape (W,)
        Stripe range (metres, sensor frame) and peak (DN) per column; NaN: no stripe.
    threshold_dn, noise_sigma_dn : float
        The extractor's seed level and noise of its evidence in this frame, DN.
    n_bins : int
    params : FusionParams

    Returns
    -------
    ndarray, shape (n_bins,)
        Reach per bin, metres (not capped at the laser's band); NaN: nothing seen.
    """
    rng = np.asarray(column_range_m, dtype=float)
    strength = np.asarray(column_strength_dn, dtype=float)
    required = float(threshold_dn) + params.certain_z * float(noise_sigma_dn)
    with np.errstate(invalid="ignore", divide="ignore"):
        reach = rng * (np.maximum(strength, 0.0) / required) ** (1.0 / params.falloff_exponent)
    # largest reach per bin: the smallest negative reach
    own = -bin_min(column_bin, -reach, n_bins)
    # the strongest evidence on each side (a weak column at a segment's end or on a
    # grazing face says something about that surface, not about the laser and camera)
    from_below = np.fmax.accumulate(own)
    from_above = np.fmax.accumulate(own[::-1])[::-1]
    return np.fmin(from_below, from_above)


def stereo_reaches_sheet(points_sensor_xyz: np.ndarray, obstacle_mask: np.ndarray,
                         bin_of_bearing: Callable[[np.ndarray], np.ndarray],
                         stereo_range_m: np.ndarray, rig: Rig,
                         params: FusionParams) -> np.ndarray:
    """Which bins' nearest stereo obstacle reaches down to the laser sheet.

    The laser sheet lies at a known height; an obstacle that stands in it is lit by it,
    whatever its colour or angle, and one that overhangs it (a table top, a shelf) is
    not. Stereo sees which: a bin's nearest surface (its obstacle points within
    ``sheet_near_share`` of the bin's stereo range, plus 2 cm) reaches the sheet where
    at least ``sheet_min_px`` of those points lie at most ``sheet_tolerance_m`` above
    the sheet's height there (the plane ``n . X = d`` in the sensor frame, solved for
    the height at the point's ground position). Stereo's obstacle points start above
    the floor's margin and its noise (slitcli.stereo.obstacles), and the first rows
    above an object's base are often trimmed or invalid: the lowest points of objects
    standing on the floor lie 6-10 cm up at 0.85-1 m through the camera model's
    ``webcam`` preset, so the default tolerance is 8 cm above a sheet 5 cm up; an
    overhang starts higher (15 cm or more in the evaluation scenes). An obstacle below
    the sheet is kept too: the laser passes over it, so its silence clears nothing
    there. Only points up to 10 % beyond the laser's maximum range are looked at: nearer
    ones alone can meet the paper fusion's silence rule.

    Parameters
    ----------
    points_sensor_xyz : ndarray, shape (H, W, 3), float
        Stereo points, sensor frame (x forward, y left, z up), metres.
    obstacle_mask : ndarray, shape (H, W), bool
        Stereo's obstacle pixels.
    bin_of_bearing : callable
        Table bin of each bearing, degrees -> int (-1 outside;
        :meth:`slitcli.ranges.BearingBins.index`).
    stereo_range_m : ndarray, shape (B,)
        Stereo's range per bin, metres (NaN none).
    rig : Rig
        Its laser plane (:meth:`~slitcli.rig.Rig.laser_plane_sensor`).
    params : FusionParams

    Returns
    -------
    ndarray, shape (B,), bool
    """
    stereo = np.asarray(stereo_range_m, dtype=float)
    out = np.zeros(stereo.shape[0], bool)
    n, d = rig.laser_plane_sensor()
    if abs(n[2]) < 1e-6:
        return out  # a vertical sheet has no height to reach
    pts = np.asarray(points_sensor_xyz)
    near = np.asarray(obstacle_mask, bool) & (pts[..., 0] <= 1.1 * params.laser_max_range_m)
    x, y, z = (pts[..., i][near].astype(float) for i in range(3))
    # the height test first: few obstacle points lie at the sheet's height
    at = z - (d - n[0] * x - n[1] * y) / n[2] <= params.sheet_tolerance_m
    x, y = x[at], y[at]
    b = np.asarray(bin_of_bearing(np.degrees(np.arctan2(y, x))))
    inside = b >= 0
    r_bin = stereo[np.where(inside, b, 0)]
    with np.errstate(invalid="ignore"):
        on = inside & (np.hypot(x, y) <= r_bin * (1.0 + params.sheet_near_share) + 0.02)
    count = np.bincount(b[on], minlength=stereo.shape[0])
    return count[:stereo.shape[0]] >= params.sheet_min_px


def stripe_depth_agrees(v_px: np.ndarray, disparity_px: np.ndarray, rig: Rig,
                        cols: np.ndarray, piece: np.ndarray,
                        params: FusionParams) -> np.ndarray:
    """Which stripe columns lie on a piece whose light is where stereo sees the surface.

    Laser light lies on the surface it lights: at a stripe pixel, the surface stereo
    sees is at the laser plane's depth, and its disparity is the plane's,
    ``d_laser = f B / Z``, ``Z`` the depth where the pixel's ray meets the plane (left
    camera frame). Light on a surface farther than the plane is not the laser's: in
    practice reddish texture on the floor below the sheet, which a codec's chroma
    makes into a short red stripe. Per column, stereo's disparity is the median of the
    valid ones in the stripe's row and two rows either side (the surface just above and
    below the light); per piece, over its columns with one, the medians of
    ``d_stereo / d_laser`` and ``d_stereo - d_laser``. A piece with at least
    ``params.depth_columns`` such columns whose ratio is below ``1 - depth_share`` and
    whose difference is below ``-depth_px`` is dropped. Stereo nearer than the plane
    drops nothing (a foreground's disparity spreads past its edge by a window), nor
    does a piece stereo cannot see (plain surfaces). The frame's longest piece (most
    found columns; the laser's, as a rule) always stays: where stereo and the laser
    plane disagree on the whole stripe the rig's calibration is in question, and a
    false piece kept errs towards an obstacle, a true one dropped towards free space.

    Parameters
    ----------
    v_px : ndarray, shape (W,)
        Stripe row per column of the rectified left image, px (NaN none).
    disparity_px : ndarray, shape (H, W), float
        Stereo disparity of the same image, px (NaN invalid).
    rig : Rig
        The rectified rig (intrinsics, baseline, laser plane).
    cols, piece : ndarray, shape (N,), int
        The found columns and their pieces (:func:`slitcli.laser.choose.stripe_pieces`).
    params : FusionParams

    Returns
    -------
    keep : ndarray, shape (W,), bool
        False in the columns of the pieces stereo contradicts and where nothing was
        found.
    """
    keep = np.zeros(np.asarray(v_px).shape[0], bool)
    if cols.size == 0:
        return keep
    v = np.asarray(v_px, dtype=float)[cols]
    z = rig.intersect_laser_plane(rig.pixel_rays_cam(cols, v))[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        d_laser = rig.left.fx_px * rig.baseline_m / z
    disp = np.asarray(disparity_px)
    rows = np.clip(np.rint(v).astype(np.intp)[None, :] + np.arange(-2, 3)[:, None], 0,
                   disp.shape[0] - 1)
    d_stereo = median_of_finite(disp[rows, cols[None, :]], axis=0)
    n_pieces = int(piece[-1]) + 1
    ratio, n = bin_median(piece, d_stereo / d_laser, n_pieces)
    seen = n >= params.depth_columns
    keep[cols] = True
    if not seen.any():
        return keep
    diff, _ = bin_median(piece, d_stereo - d_laser, n_pieces)
    with np.errstate(invalid="ignore"):
        wrong = seen & (ratio < 1.0 - params.depth_share) & (diff < -params.depth_px)
    length = np.bincount(piece, minlength=n_pieces)
    wrong[np.argmax(length)] = False
    keep[cols] = ~wrong[piece]
    return keep


def fuse(laser_range_m: np.ndarray, stereo_range_m: np.ndarray,
         stereo_has_features: np.ndarray, params: FusionParams, *,
         laser_sight_m: np.ndarray | None = None,
         laser_reach_m: np.ndarray | None = None,
         stereo_at_sheet: np.ndarray | None = None) -> FusedRanges:
    """Combine laser and stereo ranges per bearing bin (paper Eq. 11).

    Parameters
    ----------
    laser_range_m, stereo_range_m : ndarray, shape (B,)
        Nearest return per bin, metres; NaN = no return. Bins are adjacent in bearing
        order (neighbours in the array are neighbours in the field of view).
    stereo_has_features : ndarray of bool, shape (B,)
        Whether stereo saw enough texture in the bin to be trusted at all.
    params : FusionParams
    laser_sight_m : ndarray, shape (B,), optional
        Nearest range at which the laser stripe is inside the image at each bin's
        bearing (:func:`slitcli.laser.laser_sight_range_m`); None: everywhere.
    laser_reach_m : ndarray, shape (B,), optional
        How far the laser could have seen an obstacle in each bin this frame
        (:func:`laser_reach_m`; NaN: not at all). None: to its maximum range in every
        bin (the paper's reading, for callers without the stripe's evidence).
    stereo_at_sheet : ndarray of bool, shape (B,), optional
        Bins whose stereo obstacle reaches down to the sheet (:func:`stereo_reaches_sheet`):
        the laser's silence does not move their stereo return out. None: none.

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
    reach = (np.full_like(laser, params.laser_max_range_m) if laser_reach_m is None
             else np.asarray(laser_reach_m, dtype=float))
    # a bin's own return shows the sheet passed through to it; never beyond the band
    seen = np.fmax(reach, laser)
    free = np.where(np.isfinite(seen), np.minimum(seen, params.laser_max_range_m), np.nan)
    min_rng, min_src = _nearest(laser, stereo)
    if params.mode == "conservative":
        return FusedRanges(min_rng, min_src, free)
    laser_in_band = has_l & (laser < params.laser_max_range_m)
    with np.errstate(divide="ignore", invalid="ignore"):
        stereo_nearer_px = params.focal_baseline_px_m * (1.0 / stereo - 1.0 / laser)
    same_surface = laser_in_band & has_s & (stereo_nearer_px <= params.same_surface_px)
    band_rng = np.where(same_surface, laser, min_rng)
    band_src = np.where(same_surface, SOURCE_LASER, min_src)
    sight = (np.zeros_like(stereo) if laser_sight_m is None
             else np.asarray(laser_sight_m, dtype=float))
    beside_lit = np.zeros_like(laser_in_band)
    beside_lit[1:] |= laser_in_band[:-1]
    beside_lit[:-1] |= laser_in_band[1:]
    with np.errstate(invalid="ignore"):
        trust_silence = has_s & (stereo >= sight) & ~beside_lit & (stereo < free)
    if stereo_at_sheet is not None:
        trust_silence &= ~np.asarray(stereo_at_sheet, dtype=bool)
    silent_rng = np.where(trust_silence, free, stereo)
    silent_src = np.where(has_s, SOURCE_STEREO, SOURCE_NONE)
    rng = np.where(~feat, laser, np.where(laser_in_band, band_rng, silent_rng))
    src = np.where(~feat, np.where(has_l, SOURCE_LASER, SOURCE_NONE),
                   np.where(laser_in_band, band_src, silent_src))
    return FusedRanges(rng, src.astype(object), free)


def _nearest(laser: np.ndarray, stereo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per bin, the nearer of two returns (NaN = none) and its source name."""
    has_l, has_s = np.isfinite(laser), np.isfinite(stereo)
    nearer_stereo = has_s & (~has_l | (stereo < laser))
    rng = np.where(nearer_stereo, stereo, laser)
    src = np.where(nearer_stereo, SOURCE_STEREO, np.where(has_l, SOURCE_LASER, SOURCE_NONE))
    return rng, src.astype(object)
