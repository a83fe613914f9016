"""One stereo frame end to end: rectify, match (Eq. 10), reproject (Eq. 8), obstacles.

:func:`process_stereo_pair` is the per-frame API that ``slitcli stereo``, ``detect``
(fusion) and the closed-loop simulator call.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import KW_ONLY, dataclass, field

import numpy as np

from slitcli.calibrate.rectify import rectify_pair
from slitcli.errors import SlitcliError
from slitcli.rig import Rig
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.matcher import MatcherParams, compute_disparity, to_grey, with_rig_ground
from slitcli.stereo.obstacles import (
    MaskInputs,
    ObstacleParams,
    apply_mask_filters,
    bearing_ranges,
    bins_check,
    obstacle_points,
)
from slitcli.stereo.sgm import SgmWorkspace


@dataclass(frozen=True)
class StereoParams:
    """Matcher and obstacle parameters of the stereo pipeline."""

    _: KW_ONLY
    matcher: MatcherParams = field(default_factory=MatcherParams)
    obstacles: ObstacleParams = field(default_factory=ObstacleParams)


@dataclass(frozen=True)
class StereoFrameResult:
    """Everything stereo tells about one frame (left rectified image, sensor frame).

    Attributes
    ----------
    disparity_px : (H, W) float32
        Disparity in pixels, NaN = invalid (never filled in).
    invalid_reason : (H, W) uint8
        0 valid, else the filter that rejected the pixel (docs/stereo.md).
    depth_m : (H, W) float32
        Depth along the optical axis ``D = W f / d`` (Eq. 8), metres, NaN = invalid.
    points_sensor_xyz : (H, W, 3) float32
        Reprojected points in the sensor frame, metres, NaN = invalid.
    obstacle_mask : (H, W) bool
        Valid pixels that see an obstacle (above the floor, below the robot's top,
        within the stereo range).
    bearing_deg, range_m, has_features, obstacle_px, feature_px : (B,)
        Per bearing bin (DESIGN §6): centre (deg, positive left), nearest obstacle
        range (m, NaN = none), enough valid non-floor pixels, and the pixel counts.
    """

    disparity_px: np.ndarray
    invalid_reason: np.ndarray
    depth_m: np.ndarray
    points_sensor_xyz: np.ndarray
    obstacle_mask: np.ndarray
    bearing_deg: np.ndarray
    range_m: np.ndarray
    has_features: np.ndarray
    obstacle_px: np.ndarray
    feature_px: np.ndarray


def check_stereo_params(rig: Rig, params: StereoParams) -> None:
    """Raise :class:`SlitcliError` if the parameters cannot work with this rig."""
    from slitcli.stereo.matcher import check_matcher_params

    check_matcher_params(params.matcher, image_width_px=rig.width_px)
    if params.matcher.window_h_px > rig.height_px:
        raise SlitcliError(f"`window_h_px` {params.matcher.window_h_px} is taller than the "
                           f"image ({rig.height_px} px); use a smaller odd window",
                           param="window_h_px")
    bins_check(rig, params.obstacles)


def process_stereo_pair(left_bgr: np.ndarray, right_bgr: np.ndarray, rig: Rig,
                        params: StereoParams | None = None, *,
                        geometry: StereoGeometry | None = None,
                        pool: ThreadPoolExecutor | None = None,
                        workspace: SgmWorkspace | None = None) -> StereoFrameResult:
    """Disparity, distance image, obstacle mask and ranges per bearing of one pair.

    Parameters
    ----------
    left_bgr, right_bgr : ndarray, uint8, (H, W, 3)
        The stereo pair: rectified images of size ``rig.image_size_px``, or raw images
        of size ``rig.raw.image_size_px`` when the rig carries a raw calibration (they
        are rectified first).
    rig : Rig
    params : StereoParams, optional
    geometry : StereoGeometry, optional
        ``StereoGeometry.for_rig(rig, params.obstacles.bin_width_deg)``, built once per
        rig by callers that process many frames (and that check the parameters once
        with :func:`check_stereo_params`); built, and the parameters checked, here
        when None.
    pool : ThreadPoolExecutor, optional
        The matcher's helper threads, held by a caller that processes a sequence
        (slitcli.stereo.matcher.compute_disparity); the frame makes its own when None.
    workspace : SgmWorkspace, optional
        Memory for SGM's cost volumes held by such a caller (slitcli.stereo.sgm); the
        frame allocates its own when None.

    Returns
    -------
    StereoFrameResult

    Raises
    ------
    SlitcliError
        Mismatched image sizes, sizes that differ from the rig, impossible parameters.
    """
    p = StereoParams() if params is None else params
    if left_bgr.shape != right_bgr.shape:
        raise SlitcliError(f"left image {left_bgr.shape[1]}x{left_bgr.shape[0]} and right "
                           f"image {right_bgr.shape[1]}x{right_bgr.shape[0]} differ in size; "
                           "a stereo pair needs two images of the same size")
    if geometry is None:
        check_stereo_params(rig, p)
        geometry = StereoGeometry.for_rig(rig, p.obstacles.bin_width_deg)
    else:
        # built once per run by a caller that checked the parameters then
        geometry.check_for(rig, p.obstacles.bin_width_deg)
    left, right = rectify_pair(rig, left_bgr, right_bgr, maps=geometry.rectification)
    # grey once per frame: the matcher and the mask filters read the same grey pair
    left_grey, right_grey = to_grey(left), to_grey(right)
    # SGM's windows sheared by the ground's disparity gradient where the rig sees ground
    # (or the pair's ground, with sgm_ground 'pair' / 'check': compute_disparity)
    # with colour_whiten the colour pair: a noisy camera's pair is matched on its
    # noise-whitened channels (slitcli.stereo.whiten.noise_whitened_pair)
    colour = p.matcher.colour_whiten
    disp = compute_disparity(left if colour else left_grey, right if colour else right_grey,
                             with_rig_ground(p.matcher, geometry), pool=pool,
                             workspace=workspace)
    depth, pts, obstacle, feature = obstacle_points(disp.disparity_px, geometry, p.obstacles)
    inputs = MaskInputs(left_grey, right_grey, disp.disparity_px, geometry)
    obstacle = apply_mask_filters(obstacle, inputs, p.obstacles)
    br = bearing_ranges(pts, obstacle, feature, geometry, p.obstacles)
    return StereoFrameResult(disp.disparity_px, disp.invalid_reason, depth, pts, obstacle,
                             br.bearing_deg, br.range_m, br.has_features, br.obstacle_px,
                             br.feature_px)
