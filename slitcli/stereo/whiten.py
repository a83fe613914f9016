"""The images a noisy colour pair is matched on: each view's channels weighted for the
texture's signal-to-noise ratio, optionally low-passed down to the noise the matcher's
thresholds were set at (``colour_whiten``, ``noise_smoothing``; docs/stereo.md).

:func:`noise_whitened_pair` builds them from the luma pass's matches (the pair's
noise per channel and level, slitcli.stereo.noise); :func:`smoothed_filters` runs the
filter chain after a match on low-passed images. slitcli.stereo.matcher.match_nssd
calls both.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from slitcli.stereo.cost import colour_matching_image, smooth_image, smoothing_sigma_px
from slitcli.stereo.filters import DISPARITY_FILTERS, FilterInputs, run_disparity_filters
from slitcli.stereo.noise import estimate_channel_noise, estimate_match_noise
from slitcli.stereo.reasons import Reason

if TYPE_CHECKING:
    from slitcli.stereo.matcher import MatcherParams


@dataclass(frozen=True)
class WhitenedPair:
    """The images a noisy colour pair is matched on (:func:`noise_whitened_pair`).

    ``left``, ``right``: float32 (H, W), DN, what the cost is computed on;
    ``sharp_left``, ``sharp_right``: the same before the low-pass (the same arrays
    when ``smoothing_px`` is 0); ``smoothing_px``: the low-pass's Gaussian sigma, px.
    """

    left: np.ndarray
    right: np.ndarray
    sharp_left: np.ndarray
    sharp_right: np.ndarray
    smoothing_px: float


def noise_whitened_pair(left_bgr: np.ndarray, right_bgr: np.ndarray, left_grey: np.ndarray,
                        right_grey: np.ndarray, disparity_px: np.ndarray, valid: np.ndarray,
                        params: MatcherParams) -> WhitenedPair | None:
    """The images to match a noisy colour pair on, or None where its luma will do.

    The matcher was set up on pairs with 2 DN of independent noise per colour channel
    (the renderer's default; their luma's noise reads 1.3-1.8 DN in the estimate of
    slitcli.stereo.noise). Where the luma pair's noise, estimated from the luma pass's
    matches, exceeds ``colour_whiten_min_noise_dn``:

    1. each view becomes the texture-to-noise weighted combination of its colour
       channels (slitcli.stereo.cost.colour_matching_image) under each channel's noise
       by level, estimated at the same matches (slitcli.stereo.noise.
       estimate_channel_noise): a camera's noise differs by channel and level, and a
       coloured surface's texture lives in its bright channels, which luma may weight
       little;
    2. with ``noise_smoothing``, the combination's noise and lag-1 correlations are
       estimated at the same matches and it is low-passed by the least Gaussian that
       brings its noise down to ``support_noise_ref_dn`` (the noise the thresholds
       were set at; slitcli.stereo.cost.smoothing_sigma_px), at most a quarter of the
       window's smaller side (the window must still hold several of the texture's
       cycles).

    Parameters
    ----------
    left_bgr, right_bgr : ndarray, uint8, shape (H, W, 3)
    left_grey, right_grey : ndarray, shape (H, W)
        The luma pair the first pass matched.
    disparity_px, valid : ndarray, shape (H, W)
        The luma pass's winners and which of them passed its tests.
    params : MatcherParams

    Returns
    -------
    WhitenedPair or None
    """
    grey_noise = estimate_match_noise(left_grey, right_grey, disparity_px, valid)
    if grey_noise.sigma_dn <= params.colour_whiten_min_noise_dn:
        return None
    channels = estimate_channel_noise(left_bgr, right_bgr, disparity_px, valid)
    if channels is None:
        return None
    ww, wh = params.window_w_px, params.window_h_px
    cl = colour_matching_image(left_bgr, ww, wh, channels)
    cr = colour_matching_image(right_bgr, ww, wh, channels)
    if not params.noise_smoothing:
        return WhitenedPair(cl, cr, cl, cr, 0.0)
    noise = estimate_match_noise(cl, cr, disparity_px, valid)
    if noise.sigma_dn <= 0:
        noise = grey_noise  # too few usable matches on the combination: the luma's
    sigma = smoothing_sigma_px(noise.sigma_dn, noise.rho_x, noise.rho_y, noise.rho_diag,
                               params.support_noise_ref_dn, 0.25 * min(ww, wh))
    if sigma <= 0:
        return WhitenedPair(cl, cr, cl, cr, 0.0)
    return WhitenedPair(smooth_image(cl, sigma), smooth_image(cr, sigma), cl, cr, sigma)


def smoothed_filters(white: WhitenedPair, pl: np.ndarray, params: MatcherParams,
                      disp: np.ndarray, reason: np.ndarray, rdisp: np.ndarray,
                      pool: ThreadPoolExecutor | None, threads: int) -> None:
    """The filter chain after a match on low-passed images (``noise_smoothing``).

    The support tests run on the low-passed images the match was made on (at the
    reference noise their thresholds were set at); the depth-edge test, whose evidence
    is a one-pixel-wide column, runs on the sharp whitened images (the low-pass would
    blur the edge it looks for); then speckle. The window, low-passed, carries a
    surface's disparity up to ``m + 3 sigma`` columns past its silhouette (m the
    window's half width), and on a noisy background few of the pixels just past that
    band are valid: the depth-edge test looks for the farther surface's valid pixels
    ``boundary_radius_px`` beyond the band.

    That test still misses most of the carried pixels: under the noise that called
    for the low-pass, a one-pixel column's residual has no clear minimum at any
    disparity (through the ``robot`` preset the sharp column residuals of carried
    pixels lie at 15-110 DN^2 both at their own and at the true disparity, against
    58 DN^2 of noise), so the test decides by chance. The low-passed support blocks
    (half width r) see a surface's texture up to about ``r + 2 sigma`` columns past
    its silhouette (the Gaussian's weight beyond 2 sigma is 2 %), on either side of
    it, and the farther surface's pixels as close to the step have the band the other
    camera does not see in their footprint. So where a valid run ends across invalid
    pixels on a surface at another disparity (:func:`trim_depth_steps`), its last
    ``r + ceil(smoothing_edge_sigmas x sigma)`` pixels are not trusted.
    """
    support = replace(params, boundary_ratio=0.0)
    run_disparity_filters(FilterInputs(white.left, white.right, pl, support, disp, reason,
                                       rdisp, pool, threads), DISPARITY_FILTERS[:2])
    reach = (params.boundary_radius_px + params.window_w_px // 2
             + math.ceil(3.0 * white.smoothing_px))
    edges = replace(params, support_min_zncc=0.0, boundary_radius_px=reach)
    sharp = FilterInputs(white.sharp_left, white.sharp_right, pl, edges, disp, reason, rdisp,
                         pool, threads)
    run_disparity_filters(sharp, DISPARITY_FILTERS[1:2])
    trim = params.support_radius_px + math.ceil(params.smoothing_edge_sigmas
                                                * white.smoothing_px)
    trim_depth_steps(disp, reason, trim, params.boundary_step_px)
    run_disparity_filters(sharp, DISPARITY_FILTERS[2:])


def trim_depth_steps(disparity_px: np.ndarray, reason: np.ndarray, reach_px: int,
                     step_px: float) -> None:
    """Invalidate (``Reason.BOUNDARY``) the last ``reach_px`` pixels of each row's valid
    runs that end at a depth step, in place (:func:`smoothed_filters` says why).

    A run ends at a depth step when, across the invalid pixels beside its end, the first
    valid pixel of the row differs from the run's end pixel by more than ``step_px``
    (either way: the nearer surface's disparity is carried onto the farther one, and the
    farther one's footprint holds the band the other camera does not see). A run whose
    gap reaches the image border, or ends on the same surface (a hole), keeps its end.

    Parameters
    ----------
    disparity_px : ndarray, float32, shape (H, W)
        Winner disparities (read where ``reason`` is VALID).
    reason : ndarray, uint8, shape (H, W)
        Reason codes, updated in place.
    reach_px : int
        Pixels cut from a run's end (0: nothing).
    step_px : float
        Least disparity difference across the gap that makes a depth step, px.
    """
    if reach_px <= 0:
        return
    h, w = reason.shape
    valid = reason == Reason.VALID
    cols = np.arange(w, dtype=np.int32)
    # the first valid column at or after / at or before every pixel (w / -1: none)
    next_valid = np.minimum.accumulate(np.where(valid, cols, w)[:, ::-1], axis=1)[:, ::-1]
    prev_valid = np.maximum.accumulate(np.where(valid, cols, -1), axis=1)
    cut = np.zeros((h, w), bool)
    # run ends (a valid pixel before an invalid one) and run starts, with the first
    # valid pixel across their gaps; the image border is no gap
    ys, xs = np.nonzero(valid[:, :-1] & ~valid[:, 1:])
    _cut_steps(cut, valid, disparity_px, ys, xs, next_valid[ys, xs + 1] if len(ys) else xs,
               w, reach_px, step_px, -1)
    ys, xs = np.nonzero(valid[:, 1:] & ~valid[:, :-1])
    xs = xs + 1
    _cut_steps(cut, valid, disparity_px, ys, xs, prev_valid[ys, xs - 1] if len(ys) else xs,
               w, reach_px, step_px, 1)
    reason[cut] = Reason.BOUNDARY


def _cut_steps(cut: np.ndarray, valid: np.ndarray, disparity_px: np.ndarray, ys: np.ndarray,
               xs: np.ndarray, across: np.ndarray, width: int, reach_px: int,
               step_px: float, inward: int) -> None:
    """Mark in ``cut`` the ``reach_px`` pixels from run ends (``ys``, ``xs``) inward
    (``inward`` +-1 column) where the first valid pixel across the gap (``across``;
    -1 or ``width``: none) differs by more than ``step_px``."""
    ok = (across >= 0) & (across < width)
    ys, xs, across = ys[ok], xs[ok], across[ok]
    step = np.abs(disparity_px[ys, across] - disparity_px[ys, xs]) > step_px
    ys, xs = ys[step], xs[step]
    alive = np.ones(len(ys), bool)
    for k in range(reach_px):      # along the run, while it lasts
        x = xs + inward * k
        alive &= (x >= 0) & (x < width)
        alive[alive] &= valid[ys[alive], x[alive]]
        cut[ys[alive], x[alive]] = True


__all__ = ["WhitenedPair", "noise_whitened_pair", "smoothed_filters", "trim_depth_steps"]
