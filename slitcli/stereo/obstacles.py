"""From disparity to distance image, obstacle mask and nearest obstacle range per bearing.

Every valid pixel is reprojected with Eq. 8 (depth along the optical axis
``D = W f / d``) to a point in the left camera frame, then moved to the sensor frame
(x forward, y left, z up, origin on the floor below the left camera) with the rig's
tilt, roll and height. The paper's Eq. 9 (``Z = D H cos(theta)``) is garbled
(DESIGN §5); this is the exact form.

A point is an obstacle point when it stands above the floor and below the top of the
robot and lies within the stereo range. The floor test allows for the disparity
noise: a pixel is floor when ``z < floor_margin_m + 2 sigma_z``, where
``sigma_z = |dz/dd| disparity_sigma_px`` is how far the point's height moves for a
disparity error of ``disparity_sigma_px``: a point moves along its ray by
``D^2 / (f W)`` of depth per pixel of disparity, so ``|dz/dd| = |r_z| D^2 / (f W)``
with ``r_z`` the sensor-z component of the pixel's ray (scaled to unit depth).

Per bearing bin (bins of DESIGN §6, shared with the ground truth and the range table)
the nearest obstacle range is a low percentile of the horizontal ranges
``hypot(x, y)`` of the bin's obstacle points, once the bin holds
``min_obstacle_px`` of them (a single wrong pixel cannot make an obstacle), and
``has_features`` says whether stereo saw enough valid, non-floor pixels in that
direction to be trusted (fusion falls back to the laser where it did not).

Before the bins are filled, obstacle runs are cut back to the object's silhouette where
they end on a plain background (:func:`trim_silhouettes`): a matching window that still
holds a textured object's edge matches the plain pixels beside it at the object's
disparity, which carries the object up to half a window past its silhouette (and
the prefilter's local mean half its size farther: 8 px with the defaults), often across
a bearing-bin boundary (a phantom obstacle in a free bin). The silhouette is the
outermost intensity step within that reach; the plain pixels beyond it carry no
evidence of their own. Where the camera's blur (read from the pair's noise,
:func:`blur_edge_reach_px`) carries an object's texture a column past its silhouette,
runs that end beside an unmatched pixel also lose that column (:func:`trim_blur_edges`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import KW_ONLY, dataclass

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.ranges import BearingBins
from slitcli.rig import Rig
from slitcli.stereo.geometry import StereoGeometry

RANGE_STEP_M = 0.002  # histogram cell of the per-bin range percentile


@dataclass(frozen=True)
class ObstacleParams:
    """How obstacle points and per-bearing ranges are drawn from a disparity image.

    ``max_range_m`` of None uses the rig's ``stereo.max_range_m`` (the paper's 3 m).
    ``floor_check_ratio`` 0 (the default) leaves :func:`floor_check` off; 0.5 is the
    ratio it was tuned with. Off because, measured against the renderer's truth on the
    sample scenes and 16 random textureless scenes (26 frames), it removed 2594 obstacle
    pixels of which 2198 were right (disparity within 1 px and truly an obstacle) and
    396 wrong: it removes more right pixels than wrong ones.
    ``blur_edge_min_snr`` (0 = always, inf = never) and ``blur_edge_block_w_px`` x
    ``blur_edge_block_h_px`` (the matcher's one-sided support block, columns x rows)
    set :func:`blur_edge_reach_px`.
    """

    _: KW_ONLY
    floor_margin_m: float = 0.05
    disparity_sigma_px: float = 0.25
    robot_height_m: float = 0.8
    max_range_m: float | None = None
    bin_width_deg: float = 1.0
    range_percentile: float = 10.0
    surface_gap_px: float = 2.0
    min_obstacle_px: int = 8
    min_feature_px: int = 20
    silhouette_reach_px: int = 8
    silhouette_step_dn: float = 8.0
    silhouette_same_px: float = 1.0
    floor_check_ratio: float = 0.0
    floor_check_half_px: int = 2
    floor_check_min_px: float = 1.0
    blur_edge_min_snr: float = 1.0
    blur_edge_block_w_px: int = 3
    blur_edge_block_h_px: int = 9

    def __post_init__(self) -> None:
        if not self.floor_margin_m >= 0 or not self.disparity_sigma_px >= 0:
            raise SlitcliError("`floor_margin_m` and `disparity_sigma_px` must be >= 0",
                               param=("floor_margin_m", "disparity_sigma_px"))
        if not self.robot_height_m > self.floor_margin_m:
            raise SlitcliError(f"`robot_height_m` {self.robot_height_m} m must be above "
                               f"`floor_margin_m` {self.floor_margin_m} m",
                               param=("robot_height_m", "floor_margin_m"))
        if self.max_range_m is not None and not self.max_range_m > 0:
            raise SlitcliError(f"`max_range_m` {self.max_range_m} must be > 0 m",
                               param="max_range_m")
        if not 0 < self.bin_width_deg <= 45:
            raise SlitcliError(f"`bin_width_deg` {self.bin_width_deg} must be in (0, 45] deg",
                               param="bin_width_deg")
        if not 0 <= self.range_percentile <= 100:
            raise SlitcliError(f"`range_percentile` {self.range_percentile} must be in "
                               "[0, 100]", param="range_percentile")
        if not self.surface_gap_px >= 0:
            raise SlitcliError(f"the surface gap {self.surface_gap_px} px must be >= 0")
        if self.min_obstacle_px < 1 or self.min_feature_px < 1:
            raise SlitcliError("`min_obstacle_px` and `min_feature_px` must be >= 1",
                               param=("min_obstacle_px", "min_feature_px"))
        if (self.silhouette_reach_px < 0 or not self.silhouette_step_dn >= 0
                or not self.silhouette_same_px >= 0):
            raise SlitcliError("the silhouette reach (px), step (DN) and same-surface "
                               "tolerance (px) must be >= 0")
        if (not self.floor_check_ratio >= 0 or self.floor_check_half_px < 0
                or not self.floor_check_min_px >= 0):
            raise SlitcliError("the floor check's ratio, half height (px) and disparity step "
                               "(px) must be >= 0")
        if (not self.blur_edge_min_snr >= 0 or self.blur_edge_block_w_px < 1
                or self.blur_edge_block_h_px < 1):
            raise SlitcliError("`blur_edge_min_snr` must be >= 0 and the blur-edge block "
                               "sizes >= 1 px", param=("blur_edge_min_snr",
                                                       "blur_edge_block_w_px",
                                                       "blur_edge_block_h_px"))


@dataclass(frozen=True)
class BearingRanges:
    """Nearest obstacle per bearing bin (sensor frame; bearing positive to the left).

    Attributes
    ----------
    bearing_deg : (B,) float
        Bin centres, degrees (multiples of the bin width).
    range_m : (B,) float
        Nearest obstacle range (horizontal distance from the sensor origin), metres;
        NaN where the bin holds fewer than ``min_obstacle_px`` obstacle points.
    has_features : (B,) bool
        At least ``min_feature_px`` valid non-floor pixels in the bin.
    obstacle_px, feature_px : (B,) int
        Obstacle points and valid non-floor pixels per bin.
    """

    bearing_deg: np.ndarray
    range_m: np.ndarray
    has_features: np.ndarray
    obstacle_px: np.ndarray
    feature_px: np.ndarray


def bearing_bin_centres_deg(rig: Rig, bin_width_deg: float = 1.0) -> np.ndarray:
    """Bin centres over the left camera's horizontal field of view (DESIGN §6).

    The same bins as the ground truth (:meth:`slitcli.rig.Rig.bearing_bins`):
    multiples of ``bin_width_deg`` whose bins lie at least half inside the view.
    """
    return rig.bearing_bins(bin_width_deg)[0]


def depth_from_disparity(disparity_px: np.ndarray, rig: Rig) -> np.ndarray:
    """Depth along the optical axis, ``D = W f / d`` (paper Eq. 8), float32 (H, W), metres.

    NaN where the disparity is NaN or not positive.
    """
    d = np.asarray(disparity_px, dtype=np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = np.float32(rig.baseline_m * rig.focal_px) / d
    return np.where(d > 0, depth, np.float32(np.nan)).astype(np.float32)


def obstacle_points(disparity_px: np.ndarray, geometry: StereoGeometry,
                    params: ObstacleParams
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Depth, sensor-frame points and the obstacle / feature masks of a disparity image.

    Parameters
    ----------
    disparity_px : (H, W) float
        Disparity of the rectified left image (NaN = invalid); (W, H) must be the
        rig's ``image_size_px``.
    geometry : StereoGeometry
        The rig's per-pixel geometry.
    params : ObstacleParams

    Returns
    -------
    depth_m : (H, W) float32
        Eq. 8 depth, NaN where invalid.
    points_sensor_xyz : (H, W, 3) float32
        Sensor-frame points, metres, NaN where invalid.
    obstacle_mask : (H, W) bool
        Valid, not floor (see the module notes), below ``robot_height_m``, in front of
        the sensor and with a horizontal range within the stereo range.
    feature_mask : (H, W) bool
        Valid and not floor.
    """
    from slitcli.stereo import _kernel

    geo = geometry
    rig = geometry.rig
    d = np.ascontiguousarray(disparity_px, dtype=np.float32)
    h, w = d.shape
    depth = np.empty((h, w), np.float32)
    pts = np.empty((h, w, 3), np.float32)
    obstacle = np.empty((h, w), np.bool_)
    feature = np.empty((h, w), np.bool_)
    max_r = rig.stereo.max_range_m if params.max_range_m is None else params.max_range_m
    _kernel.reproject(d, geo.rays_sensor_xyz, float(rig.focal_px * rig.baseline_m),
                      float(rig.mount.height_m), float(params.floor_margin_m),
                      float(2.0 * params.disparity_sigma_px), float(params.robot_height_m),
                      float(max_r), depth, pts, obstacle, feature)
    return depth, pts, obstacle, feature


def trim_silhouettes(obstacle_mask: np.ndarray, left_grey: np.ndarray,
                     disparity_px: np.ndarray, params: ObstacleParams) -> np.ndarray:
    """Obstacle mask with each row's runs cut back to the silhouette on plain backgrounds.

    A run of obstacle pixels that ends next to a pixel without disparity keeps only the
    pixels up to the outermost step of more than ``silhouette_step_dn`` between two
    horizontal neighbours of ``left_grey`` within ``silhouette_reach_px`` of its end
    (half the matching window by default: how far window fattening reaches), provided
    the cut pixels carry the disparity of the pixel inside the step (within
    ``silhouette_same_px``: the same surface spilling on). A run without such a step is
    kept (its edge is not visible in the image), as is a run that meets the image border
    or a pixel with a disparity, and a run that changes depth at the step (a plain
    object's matched rim in front of a textured surface is the object, not a spill).

    Parameters
    ----------
    obstacle_mask : (H, W) bool
        From :func:`obstacle_points`; not modified.
    left_grey : (H, W) uint8 or float
        The rectified left image, grey, DN.
    disparity_px : (H, W) float
        The disparity image (NaN = invalid).
    params : ObstacleParams
        ``silhouette_reach_px = 0`` returns a copy of the mask unchanged.

    Returns
    -------
    obstacle_mask : (H, W) bool
    """
    from slitcli.stereo import _kernel

    out = np.empty_like(obstacle_mask, dtype=np.bool_)
    if params.silhouette_reach_px == 0:
        out[...] = obstacle_mask
        return out
    _kernel.trim_silhouettes(np.ascontiguousarray(obstacle_mask, dtype=np.bool_),
                             np.ascontiguousarray(left_grey, dtype=np.float32),
                             np.ascontiguousarray(disparity_px, dtype=np.float32),
                             int(params.silhouette_reach_px), float(params.silhouette_step_dn),
                             float(params.silhouette_same_px), out)
    return out


def floor_check(obstacle_mask: np.ndarray, left_grey: np.ndarray, right_grey: np.ndarray,
                disparity_px: np.ndarray, geometry: StereoGeometry,
                params: ObstacleParams) -> np.ndarray:
    """Obstacle mask without the pixels that the floor explains better than their match.

    Window fattening gives the floor beside an object's edge the object's disparity
    (up to half a window), and the point then stands above the floor at the object's
    range: one column more of object, across a bin boundary when the edge lies near one
    (the bundled corridor's phantom at 6 deg: 6 of its 8 points). On a plain background
    the silhouette trim removes such pixels; on the textured floor it cannot find the
    silhouette. But below the horizon the floor's own disparity at every pixel is known
    from the rig (``StereoGeometry.floor_disparity_px``), so the pixel's own evidence
    can be asked: its
    one-pixel-wide column of ``2 floor_check_half_px + 1`` rows (narrow, so that the
    object beside it does not take part) is compared with the right image at its
    disparity and at the floor's, each row at its own floor disparity (zero-mean SSD,
    linear interpolation along the row).
    Where the floor's residual is below ``floor_check_ratio`` times its own, the pixel
    is floor. Only pixels within ``silhouette_reach_px`` columns (half the matching
    window: how far fattening reaches) of the end of their row's obstacle run are
    asked, and pixels whose disparity lies within ``floor_check_min_px`` of the floor's
    are left to the floor test of :func:`obstacle_points`. The narrow column is weak
    evidence: on the evaluation scenes about two in three of the pixels it removes
    carry a disparity within 1 px of the truth (docs/detect.md); the bins' percentile
    does not feel them, a bin made only of fattened pixels does.

    Parameters
    ----------
    obstacle_mask : (H, W) bool
        Not modified.
    left_grey, right_grey : (H, W) uint8 or float
        The rectified pair, grey, DN.
    disparity_px : (H, W) float
        The disparity image (NaN = invalid).
    geometry : StereoGeometry
        The rig's per-pixel geometry (its floor disparity).
    params : ObstacleParams
        ``floor_check_ratio = 0`` returns a copy of the mask unchanged.

    Returns
    -------
    obstacle_mask : (H, W) bool
    """
    from slitcli.stereo import _kernel

    out = np.empty_like(obstacle_mask, dtype=np.bool_)
    if params.floor_check_ratio == 0:
        out[...] = obstacle_mask
        return out
    _kernel.floor_check(np.ascontiguousarray(obstacle_mask, dtype=np.bool_),
                        np.ascontiguousarray(left_grey, dtype=np.float32),
                        np.ascontiguousarray(right_grey, dtype=np.float32),
                        np.ascontiguousarray(disparity_px, dtype=np.float32),
                        geometry.floor_disparity_px, int(params.floor_check_half_px),
                        float(params.floor_check_ratio), float(params.floor_check_min_px),
                        int(params.silhouette_reach_px), out)
    return out


def neighbour_light_share(rho: float) -> float:
    """Share ``w`` of a pixel's light that a symmetric 3-tap kernel ``(w, 1 - 2w, w)``
    (bilinear demosaicing, a slight lens blur) passes to each horizontal neighbour, from
    the lag-1 correlation ``rho`` such a kernel gives white noise:
    ``rho = 2 w (1 - 2w) / ((1 - 2w)^2 + 2 w^2)``, solved for its smaller root (``rho``
    clipped to [0, 1/sqrt 2], the most such a kernel gives, at w = 0.29)."""
    r = min(max(float(rho), 0.0), math.sqrt(0.5))
    a, b = 6.0 * r + 4.0, 4.0 * r + 2.0
    return (b - math.sqrt(max(b * b - 4.0 * a * r, 0.0))) / (2.0 * a)


def blur_edge_reach_px(left_grey: np.ndarray, right_grey: np.ndarray,
                       disparity_px: np.ndarray, params: ObstacleParams) -> int:
    """How many columns past a silhouette the camera's blur carries an object's match.

    A camera that spreads each pixel's light over its neighbours spreads a textured
    object's edge into the first column of the surface beside it, and that light moves
    with the object: the support tests (one-sided blocks included) then find the
    object's texture, at the object's disparity, a column past its silhouette, and
    where the next bearing bin starts there, the object appears in a bin it does not
    reach (the phantoms of the ``webcam`` renders). The spread is read from the pair's
    noise, which passes through the same interpolation (slitcli.stereo.noise): its
    lag-1 correlation along x gives the share ``w`` of light a column passes on
    (:func:`neighbour_light_share`). The tail is ``w s`` of texture, ``s`` the median
    standard deviation of the support blocks (``blur_edge_block_w_px`` x
    ``blur_edge_block_h_px``, n pixels) at matched pixels; summed over a block it
    stands above the block's noise by ``T = w s sqrt(n / VF) / sigma`` (VF the noise's
    variance factor). Where ``T`` reaches ``blur_edge_min_snr`` (1: the tail holds
    more of a block's energy than its noise) the tail can carry a match, and the reach
    is the kernel's, 1 column; else 0.
    Through the camera presets (sample scenes, every frame): ``webcam`` T = 1.37-1.74,
    ``robot`` 0.62-0.94 (its noise hides the tail), plain renders 0-0.51 (one frame of
    24 random plain scenes 1.04).

    Returns
    -------
    int
        0 or 1 (columns).
    """
    from slitcli.stereo.filters import window_std_dn
    from slitcli.stereo.noise import MIN_SAMPLES, estimate_match_noise

    valid = np.isfinite(disparity_px)
    if params.blur_edge_min_snr == np.inf or np.count_nonzero(valid) < MIN_SAMPLES:
        return 0
    noise = estimate_match_noise(left_grey, right_grey, disparity_px, valid)
    if noise.samples == 0 or not noise.sigma_dn > 0:
        return 0
    share = neighbour_light_share(noise.rho_x)
    if share == 0.0:
        return 0
    bw, bh = params.blur_edge_block_w_px, params.blur_edge_block_h_px
    grey = np.asarray(left_grey, np.float32)
    # the median of every third row and column: its sampling error is far below the
    # gate's margins, at a tenth of the cost
    texture = float(np.median(window_std_dn(grey, bw, bh)[::3, ::3][valid[::3, ::3]]))
    snr = (share * texture
           * math.sqrt(bw * bh / noise.variance_factor(bw, bh)) / noise.sigma_dn)
    return 1 if snr >= params.blur_edge_min_snr else 0


def trim_blur_edges(obstacle_mask: np.ndarray, disparity_px: np.ndarray,
                    reach_px: int) -> np.ndarray:
    """Obstacle mask without the last ``reach_px`` pixels of each row's runs where they
    end beside an unmatched pixel (:func:`blur_edge_reach_px`: the blur's tail).

    Runs that end on the image border, beside unmatched pixels that reach it (the band
    the right camera cannot see), or beside a matched pixel keep their ends (there the
    depth-edge test and the silhouette trim decide). A hole in the object's own surface
    counts as unmatched: keeping such ends (where the first matched pixel beyond the
    hole has the end's disparity) gave more phantoms on the ``webcam`` renders (28
    against 15 of 534 free bins) for 3 detected bins. ``obstacle_mask`` (H, W) bool is
    not modified.
    """
    mask = np.array(obstacle_mask, dtype=np.bool_, copy=True)
    if int(reach_px) <= 0:
        return mask
    matched = np.isfinite(disparity_px)
    unmatched = ~matched
    # pixels with nothing matched between them and the row's left / right end
    width = mask.shape[1]
    first = np.where(matched.any(axis=1), matched.argmax(axis=1), width)
    last = width - 1 - matched[:, ::-1].argmax(axis=1)
    cols = np.arange(width)
    keep = (cols <= first[:, None]) | (cols >= last[:, None])
    for _ in range(int(reach_px)):
        end = np.zeros_like(mask)
        end[:, :-1] |= mask[:, :-1] & unmatched[:, 1:]
        end[:, 1:] |= mask[:, 1:] & unmatched[:, :-1]
        end &= ~keep
        mask &= ~end
        unmatched = unmatched | end
    return mask


def bearing_ranges(points_sensor_xyz: np.ndarray, obstacle_mask: np.ndarray,
                   feature_mask: np.ndarray, geometry: StereoGeometry, params: ObstacleParams
                   ) -> BearingRanges:
    """Nearest obstacle range and ``has_features`` per bearing bin.

    The ``range_percentile`` of a bin's obstacle ranges is read from a histogram of
    ``RANGE_STEP_M`` cells (so it is exact to half a cell, 1 mm), which keeps this
    O(pixels) with no sort (compiled, slitcli.stereo._kernel.bin_percentile).

    A near object often fills only part of a bin, before a background that supplies
    most of the bin's points. The bin's percentile then lands on the object only once
    the object holds that share of the points, and when it does it lies deep inside
    the object's own spread of ranges (a face seen at a grazing angle spans 10 cm in
    1 degree at 1.4 m): the rank is diluted by the background's count. So the
    percentile is taken again over the surface the bin's percentile lies on (the
    points whose disparities, ``f W / r``, follow each other without a step of more
    than ``surface_gap_px``; Eq. 8), and the nearer of the two is the bin's range. The
    rule admits no point that the plain percentile would not have reached: the object
    still needs its share of the bin, only its range is read from its own points.

    Parameters
    ----------
    points_sensor_xyz : (H, W, 3) float
        Sensor-frame points of the pixels (NaN where invalid).
    obstacle_mask, feature_mask : (H, W) bool
        From :func:`obstacle_points`.
    geometry : StereoGeometry
        The rig's geometry; its bins (``geometry.pixel_bin``, the one bin rule of
        :mod:`slitcli.ranges`) must have ``params.bin_width_deg``.
    """
    from slitcli.stereo import _kernel

    geometry.check_for(geometry.rig, params.bin_width_deg)
    rig = geometry.rig
    centres, bin_idx = geometry.bins.centres_deg, geometry.pixel_bin
    nb = centres.size
    range_m = np.full(nb, np.nan)
    obstacle_px = np.zeros(nb, np.int64)
    feature_px = np.zeros(nb, np.int64)
    max_r = rig.stereo.max_range_m if params.max_range_m is None else params.max_range_m
    _kernel.bin_percentile(np.ascontiguousarray(points_sensor_xyz, dtype=np.float32),
                           np.ascontiguousarray(obstacle_mask),
                           np.ascontiguousarray(feature_mask), bin_idx, nb, RANGE_STEP_M,
                           float(max_r), float(params.range_percentile),
                           float(rig.focal_px * rig.baseline_m), float(params.surface_gap_px),
                           range_m, obstacle_px, feature_px)
    range_m[obstacle_px < params.min_obstacle_px] = np.nan
    return BearingRanges(np.array(centres), range_m, feature_px >= params.min_feature_px,
                         obstacle_px, feature_px)


@dataclass(frozen=True)
class MaskInputs:
    """What the obstacle-mask filters read besides the mask (none is modified).

    ``left_grey``, ``right_grey``: the rectified pair, grey (H, W), DN;
    ``disparity_px``: (H, W) float32, NaN = invalid; ``geometry``: the rig's.
    """

    left_grey: np.ndarray
    right_grey: np.ndarray
    disparity_px: np.ndarray
    geometry: StereoGeometry


@dataclass(frozen=True)
class MaskFilter:
    """One named step of the obstacle-mask chain: ``apply(mask, inputs, params)``
    returns a new (H, W) bool mask, a subset of ``mask``; ``summary`` says what it
    removes (docs/stereo.md)."""

    name: str
    summary: str
    apply: Callable[[np.ndarray, MaskInputs, ObstacleParams], np.ndarray]


def _silhouette_step(mask: np.ndarray, x: MaskInputs, p: ObstacleParams) -> np.ndarray:
    return trim_silhouettes(mask, x.left_grey, x.disparity_px, p)


def _blur_step(mask: np.ndarray, x: MaskInputs, p: ObstacleParams) -> np.ndarray:
    reach = blur_edge_reach_px(x.left_grey, x.right_grey, x.disparity_px, p)
    return trim_blur_edges(mask, x.disparity_px, reach) if reach else mask


def _floor_step(mask: np.ndarray, x: MaskInputs, p: ObstacleParams) -> np.ndarray:
    return floor_check(mask, x.left_grey, x.right_grey, x.disparity_px, x.geometry, p)


#: The obstacle-mask post-filters, in the order the pipeline runs them.
MASK_FILTERS: tuple[MaskFilter, ...] = (
    MaskFilter("silhouette_trim", "obstacle runs that end on a plain background are cut "
               "back to the object's silhouette (window fattening); off with "
               "silhouette_reach_px = 0", _silhouette_step),
    MaskFilter("blur_edges", "the last column of obstacle runs that end beside an "
               "unmatched pixel, where the camera's blur carries an object's texture a "
               "column past its silhouette (blur_edge_reach_px; never with "
               "blur_edge_min_snr = inf)", _blur_step),
    MaskFilter("floor_check", "pixels near the end of an obstacle run that the floor's "
               "own disparity explains better than their match; off with "
               "floor_check_ratio = 0 (the default)", _floor_step),
)


def apply_mask_filters(obstacle_mask: np.ndarray, inputs: MaskInputs,
                       params: ObstacleParams,
                       chain: tuple[MaskFilter, ...] = MASK_FILTERS) -> np.ndarray:
    """Run the mask filters of ``chain`` in order; returns the final (H, W) bool mask."""
    mask = obstacle_mask
    for step in chain:
        mask = step.apply(mask, inputs, params)
    return mask


def bins_check(rig: Rig, params: ObstacleParams) -> None:
    """Raise if the field of view holds no whole bearing bin."""
    if len(BearingBins.for_rig(rig, params.bin_width_deg)) == 0:
        hfov = rig.fov_deg()[0]
        raise SlitcliError(f"`bin_width_deg` {params.bin_width_deg} deg leaves no bearing bin "
                           f"in the {hfov:.1f} deg field of view; use narrower bins",
                           param="bin_width_deg")


__all__ = [
    "MASK_FILTERS",
    "BearingRanges",
    "MaskFilter",
    "MaskInputs",
    "ObstacleParams",
    "apply_mask_filters",
    "bearing_bin_centres_deg",
    "bearing_ranges",
    "bins_check",
    "blur_edge_reach_px",
    "depth_from_disparity",
    "floor_check",
    "neighbour_light_share",
    "obstacle_points",
    "trim_blur_edges",
    "trim_silhouettes",
]
