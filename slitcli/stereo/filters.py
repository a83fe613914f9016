"""The disparity post-filters: a declared chain of named steps, run after any matcher.

A matcher (the local Eq. 10 winner-take-all, or semi-global aggregation over the same
cost) picks each pixel's disparity and applies the tests that need the whole cost
curve (the window's texture energy, uniqueness, left-right consistency, the subpixel
parabola). Everything after that reads only the images and the two disparity maps, so
it is one chain, :data:`DISPARITY_FILTERS`, the same whatever the aggregation:

1. ``texture``: without a prefilter, the window's standard deviation must reach
   ``texture_min_dn`` (with a prefilter the matcher tests the window energy itself);
2. ``support_and_depth_edges``: the local, one-sided and cross support and the
   depth-edge two-hypothesis test (slitcli.stereo._boundary, one compiled pass), with
   the local matcher under the pair's noise model (``support_noise``: the noise level
   and correlation estimated from the winner step's matches, slitcli.stereo.noise);
3. ``speckle``: small disconnected regions (cv2.filterSpeckles' regions), then every
   rejected pixel becomes NaN (always runs).

Each step writes its :class:`~slitcli.stereo.reasons.Reason` on the valid pixels it
rejects and never touches a pixel already rejected.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from slitcli.stereo.bands import run_row_bands
from slitcli.stereo.reasons import Reason

if TYPE_CHECKING:
    from slitcli.stereo.matcher import MatcherParams


def window_std_dn(image_q: np.ndarray, window_w_px: int, window_h_px: int) -> np.ndarray:
    """Standard deviation of ``image_q`` (1/4 DN units unless unprefiltered) per window.

    Returns float32 (H, W) in DN; windows are clipped at the image border.
    """
    f = np.asarray(image_q, dtype=np.float32)
    k = (int(window_w_px), int(window_h_px))
    mean = cv2.boxFilter(f, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT_101)
    mean_sq = cv2.boxFilter(f * f, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT_101)
    return np.sqrt(np.maximum(mean_sq - mean * mean, 0.0))


@dataclass(frozen=True)
class FilterInputs:
    """What the disparity filters read and write for one frame.

    ``left_grey``, ``right_grey``: the rectified pair (H, W), DN; ``left_q``: the
    image the cost was computed on (prefiltered, 1/4 DN, or grey without a prefilter).
    ``disparity_px`` (H, W) float32 and ``invalid_reason`` (H, W) uint8 are updated in
    place; ``right_disparity_px`` (H, W) float32 is the right view's winner (from the
    same costs), read by the depth-edge test. ``pool``/``threads``: the frame's threads.
    """

    left_grey: np.ndarray
    right_grey: np.ndarray
    left_q: np.ndarray
    params: MatcherParams
    disparity_px: np.ndarray
    invalid_reason: np.ndarray
    right_disparity_px: np.ndarray
    pool: ThreadPoolExecutor | None
    threads: int


@dataclass(frozen=True)
class DisparityFilter:
    """One named step of :data:`DISPARITY_FILTERS` (see the module notes)."""

    name: str
    reasons: tuple[Reason, ...]
    summary: str
    enabled: Callable[[MatcherParams], bool]
    run: Callable[[FilterInputs], None]


def _texture(x: FilterInputs) -> None:
    p = x.params
    texture_ok = window_std_dn(x.left_q, p.window_w_px, p.window_h_px) >= p.texture_min_dn
    r = x.invalid_reason
    r[(r == Reason.VALID) & ~texture_ok] = Reason.TEXTURE


def _support(x: FilterInputs) -> None:
    from slitcli.stereo import _boundary

    p = x.params
    gl = np.asarray(x.left_grey, np.float32)
    gr = np.asarray(x.right_grey, np.float32)
    tol = float(p.lr_max_diff_px) if p.lr_max_diff_px >= 0 else 1.0
    args = (float(p.support_min_zncc), float(p.support_side_min_zncc),
            float(p.support_cross_min_zncc), float(p.support_strong_zncc),
            int(p.support_radius_px), int(p.window_h_px // 2), tol, float(p.boundary_ratio),
            float(p.boundary_step_px), int(p.boundary_radius_px),
            float(p.boundary_noise_dn) ** 2, *_support_noise(x))
    d, rd, r = x.disparity_px, x.right_disparity_px, x.invalid_reason
    run_row_bands(lambda y0, y1: _boundary.post_rows(gl, gr, d, rd, *args, y0, y1, r),
                  gl.shape[0], x.pool, x.threads)


def _support_noise(x: FilterInputs) -> tuple[float, float, float]:
    """The support correlations' noise model (``support_noise``): the pair's noise
    variance per pixel (DN^2), that times the variance factor of a support block
    (both estimated from the winner step's valid matches, slitcli.stereo.noise), and
    the share of the noise energy beyond ``support_noise_ref_dn`` (the thresholds hold
    at that noise); (0, 0, 0) = plain correlations."""
    from slitcli.stereo.noise import estimate_match_noise

    p = x.params
    if not p.support_noise or p.aggregation != "none":
        return 0.0, 0.0, 0.0
    noise = estimate_match_noise(x.left_grey, x.right_grey, x.disparity_px,
                                 x.invalid_reason == Reason.VALID)
    k = 2 * int(p.support_radius_px) + 1
    nv = noise.sigma_dn ** 2
    if nv <= p.support_noise_ref_dn ** 2:
        return 0.0, 0.0, 0.0
    return nv, nv * noise.variance_factor(k, k), 1.0 - p.support_noise_ref_dn ** 2 / nv


def _speckle(x: FilterInputs) -> None:
    from slitcli.stereo import _kernel

    p = x.params
    # speckle regions as cv2.filterSpeckles finds them on 1/16 px, then NaN = invalid
    _kernel.speckle_finish(x.disparity_px, x.invalid_reason, int(p.speckle_window_px),
                           max(1, math.ceil(p.speckle_range_px * 16.0)), int(Reason.SPECKLE))


#: The disparity post-filters, in the order every Eq. 10 matcher runs them.
DISPARITY_FILTERS: tuple[DisparityFilter, ...] = (
    DisparityFilter("texture", (Reason.TEXTURE,),
                    "window standard deviation below texture_min_dn (prefilter 'none' "
                    "only: with a prefilter the matcher tests the window energy)",
                    lambda p: p.texture_min_dn > 0 and p.prefilter == "none", _texture),
    DisparityFilter("support_and_depth_edges", (Reason.SUPPORT, Reason.BOUNDARY),
                    "local / one-sided / cross support (support_*_zncc) and the depth-edge "
                    "test (boundary_ratio)",
                    lambda p: p.support_min_zncc != 0 or p.boundary_ratio > 0, _support),
    DisparityFilter("speckle", (Reason.SPECKLE,),
                    "regions of at most speckle_window_px pixels within speckle_range_px; "
                    "then every rejected pixel becomes NaN (always runs)",
                    lambda p: True, _speckle),
)


def run_disparity_filters(inputs: FilterInputs,
                          chain: tuple[DisparityFilter, ...] = DISPARITY_FILTERS) -> None:
    """Run the enabled steps of ``chain`` in order, in place on ``inputs``."""
    for step in chain:
        if step.enabled(inputs.params):
            step.run(inputs)


__all__ = ["DISPARITY_FILTERS", "DisparityFilter", "FilterInputs", "run_disparity_filters",
           "window_std_dn"]
