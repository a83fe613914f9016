"""Disparity from a rectified pair: the paper's normalised SSD (Eq. 10) and OpenCV matchers.

The default matcher (``nssd``) is the paper's correlation stereo (Small Vision System
style). For a left pixel (x, y) and a disparity d it compares the window
``(2m+1) x (2n+1)`` around (x, y) in the left image with the window around
(x - d, y) in the right image:

    C(x, y, d) = sum (P_l - P_r)^2 / ( sqrt(sum P_l^2) * sqrt(sum P_r^2) )     (Eq. 10)

The paper writes ``P_r(x + d)``; with the right camera at ``+baseline_m`` along x
(DESIGN §2) a point seen at column x in the left image appears at x - d in the
right one, so this module uses ``x - d`` and disparities are positive.

Where the window leaves the columns both images have (the left border for large d,
the right border), the sums run over the part that both images cover, so a pixel
at column u can still be matched at every disparity d <= u (OpenCV's StereoBM
instead drops its ``num_disparities - 1`` leftmost columns).

After winner-take-all the disparity is refined to subpixel by a parabola through
the costs at d - 1, d, d + 1 (Eq. 10 is a normalised sum of squares, locally
quadratic in the shift, so the parabola is its natural model). Validity filters,
all optional and each measured in docs/notes/stereo-kernels.md:

- prefilter: ``mean`` (subtract the local mean and clip, as StereoBM's
  normalised-response prefilter), ``xsobel`` (horizontal derivative, clipped) or
  ``log`` (Laplacian of Gaussian), or ``none``;
- texture: the window's RMS in the matched (prefiltered, zero-mean) image, or the
  window's standard deviation without a prefilter, must reach ``texture_min_dn``;
- uniqueness: no disparity further than 1 px from the winner may cost less than
  ``(1 + uniqueness_ratio)`` times the winner's cost;
- left-right consistency from the same cost values: the right pixel x - d must
  pick (within ``lr_max_diff_px``) the same disparity when it looks for its own
  best left match along the same costs, so no second full match is run;
- local support: the winning disparity must also hold for the pixel's own close
  neighbourhood: the zero-mean normalised correlation of the ``(2 r + 1)^2`` grey
  windows (r = ``support_radius_px``) of the left image and of the right image warped
  by the winning disparities (bilinear) must reach ``support_min_zncc``. A 9 x 9 window still
  matches a textureless pixel next to an edge or a textured neighbour (and often
  gives it the neighbour's disparity); this check keeps only pixels whose own
  surroundings carry the match. Next to a pixel whose correlation is below
  ``support_side_min_zncc``, the block of ``2 r + 1`` columns by the window's height
  centred one column towards that pixel must reach it too, at the pixel's own
  disparity: a
  textureless pixel beside a textured surface passes the centred block on the
  strength of that texture alone;
- cross support (``support_cross_min_zncc``): unless its own correlation reaches
  ``support_strong_zncc``, the ``(2 r + 1)^2`` blocks just above and just below the
  pixel, or just left and right of it, must both correlate at the pixel's own
  disparity: a textureless pixel within half a window of an edge or of the laser
  stripe sees that texture on one side only;
- noise model of the support tests (``support_noise``, local matcher only): the pair's
  noise level and lag-1 correlation are estimated from the winner step's matches
  (slitcli.stereo.noise); a block whose energy exceeds noise alone's 99 % bound has
  its noise energy taken off, so the correlations above are those of the signals and
  the thresholds hold through a camera's demosaiced, compressed, signal-dependent noise;
  the depth-edge test compares its two residuals less that noise. Only the noise beyond
  ``support_noise_ref_dn`` is taken off (the thresholds were set at that noise);
- noisy colour cameras (``colour_whiten``, off by default; local matcher only): a
  colour pair whose luma noise exceeds ``colour_whiten_min_noise_dn`` is matched again
  on each view's channels weighted for the texture's signal-to-noise ratio under each
  channel's noise by level, estimated from the luma pass's matches
  (slitcli.stereo.whiten); with ``noise_smoothing`` those images are also
  low-passed down to ``support_noise_ref_dn`` of noise, the depth-edge test then
  running on the sharp ones, and valid runs that end at a depth step lose the
  low-pass's reach, ``support_radius_px + ceil(smoothing_edge_sigmas x sigma)``
  pixels (slitcli.stereo.whiten.trim_depth_steps; docs/stereo.md);
- depth edges (``boundary_ratio``): the window carries the disparity of the more
  textured side of a depth edge up to half a window past it. Where a valid neighbour
  within ``boundary_radius_px`` columns lies more than ``boundary_step_px`` farther,
  the pixel's own one-pixel-wide, window-tall grey column is compared with the right
  image at its own disparity and at the neighbour's; so is the right-image column
  its match lands on, with the disparities of the right view's neighbours. If the
  farther surface explains either column with less than ``boundary_ratio`` of the
  residual, the pixel is invalid (slitcli.stereo._boundary);
- speckle removal: connected regions of at most ``speckle_window_px`` pixels
  whose disparities differ by at most ``speckle_range_px`` are removed.

Invalid pixels are NaN in ``disparity_px`` and carry a reason code; they are never
filled in.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import KW_ONLY, dataclass, field, replace
from typing import TYPE_CHECKING

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.stereo.bands import (
    check_thread_setting,
    frame_pool,
    kernel_threads,
)
from slitcli.stereo.cost import DisparityResult, prefilter_image, to_grey
from slitcli.stereo.filters import FilterInputs, run_disparity_filters
from slitcli.stereo.ground import GROUND_SOURCES, GroundFitParams
from slitcli.stereo.reasons import Reason
from slitcli.stereo.whiten import noise_whitened_pair, smoothed_filters

if TYPE_CHECKING:
    from slitcli.stereo.geometry import StereoGeometry
    from slitcli.stereo.sgm import SgmWorkspace

MATCHERS = ("nssd", "bm", "sgbm")
AGGREGATIONS = ("none", "sgm")
PREFILTERS = ("none", "mean", "xsobel", "log")
SUBPIXEL = ("parabola", "none")
SGM_SUBPIXEL = ("cost", "sums")



@dataclass(frozen=True)
class MatcherParams:
    """Parameters of the disparity matcher (units in the names; DN = grey level 0-255).

    ``window_w_px`` x ``window_h_px`` is the correlation window (2m+1) x (2n+1) of
    Eq. 10; disparities searched are ``min_disparity_px .. min_disparity_px +
    num_disparities - 1``. A filter is off when its parameter is 0 (``texture_min_dn``,
    ``uniqueness_ratio``, ``support_min_zncc``, ``boundary_ratio``,
    ``speckle_window_px``) or negative (``lr_max_diff_px``). The depth-edge test
    compares grey-level columns ``window_h_px`` tall; residuals at or below
    ``boundary_noise_dn`` (RMS, DN) are taken as sensor noise and carry no evidence.
    ``colour_whiten`` / ``colour_whiten_min_noise_dn`` (DN of the luma pair's noise) and
    ``noise_smoothing``: a noisy colour pair's matching images (:func:`match_nssd`);
    ``smoothing_edge_sigmas``: how many of the low-pass's sigmas (beyond the support
    block) a surface's disparity is cut back at a depth step (slitcli.stereo.whiten).
    """

    matcher: str = "nssd"
    num_disparities: int = 48
    min_disparity_px: int = 0
    window_w_px: int = 9
    window_h_px: int = 9
    _: KW_ONLY
    prefilter: str = "mean"
    prefilter_size_px: int = 9
    prefilter_cap_dn: float = 15.0
    log_sigma_px: float = 1.0
    texture_min_dn: float = 1.0
    uniqueness_ratio: float = 0.15
    lr_max_diff_px: int = 1
    support_radius_px: int = 1
    support_min_zncc: float = 0.2
    support_side_min_zncc: float = 0.45
    support_cross_min_zncc: float = 0.4
    support_strong_zncc: float = 0.95
    support_noise: bool = True
    support_noise_ref_dn: float = 1.5
    colour_whiten: bool = False
    colour_whiten_min_noise_dn: float = 2.0
    noise_smoothing: bool = False
    smoothing_edge_sigmas: float = 2.0
    boundary_ratio: float = 0.5
    boundary_step_px: float = 1.0
    boundary_radius_px: int = 5
    boundary_noise_dn: float = 2.8
    subpixel: str = "parabola"
    speckle_window_px: int = 100
    speckle_range_px: float = 2.0
    aggregation: str = "none"
    sgm_paths: int = 4
    sgm_p1: float = 0.4
    sgm_p2: float = 3.0
    sgm_p2_edge_dn: float = 16.0
    sgm_window_px: int = 7
    sgm_texture_min_dn: float = 0.0
    sgm_subpixel: str = "cost"
    sgm_bracket_px: int = 32
    sgm_bracket_tol_px: float = 1.0
    sgm_bracket_span_px: float = 1.0
    sgm_ground_px_per_row: float | None = None
    sgm_ground_horizon_row_px: float | None = None
    sgm_ground_band_px: float | None = None
    sgm_ground_tilt_tol_deg: float = 1.0
    sgm_ground: str = "auto"
    sgm_ground_fit: GroundFitParams = field(default_factory=GroundFitParams)

    def __post_init__(self) -> None:
        check_matcher_params(self)


def check_matcher_params(p: MatcherParams, image_width_px: int | None = None) -> None:
    """Raise :class:`SlitcliError` naming the option for impossible parameters (with
    ``image_width_px``, also for a window or disparity range the image cannot hold)."""
    _check_names(p)
    check_thread_setting()  # the environment's thread count, before a run writes anything
    _check_sgm(p)
    _check_sizes(p)
    _check_filters(p)
    _check_opencv(p)
    if image_width_px is not None:
        _check_image(p, image_width_px)



def _check_names(p: MatcherParams) -> None:
    """The matcher, prefilter and aggregation are known ones."""
    if p.matcher not in MATCHERS:
        raise SlitcliError(f"`matcher` {p.matcher!r} is unknown; use one of "
                           f"{', '.join(MATCHERS)}", param="matcher")
    if p.prefilter not in PREFILTERS:
        raise SlitcliError(f"`prefilter` {p.prefilter!r} is unknown; use one of "
                           f"{', '.join(PREFILTERS)}", param="prefilter")
    if p.aggregation not in AGGREGATIONS:
        raise SlitcliError(f"`aggregation` {p.aggregation!r} is unknown; use one of "
                           f"{', '.join(AGGREGATIONS)}", param="aggregation")


def _check_sgm(p: MatcherParams) -> None:
    """Semi-global aggregation's own settings, and that it aggregates the Eq. 10 cost."""
    if p.aggregation == "sgm" and p.matcher != "nssd":
        raise SlitcliError(f"`aggregation` 'sgm' aggregates the Eq. 10 cost of `matcher` "
                           f"'nssd', not {p.matcher!r}; use `matcher` 'nssd' or "
                           "`aggregation` 'none'", param=("aggregation", "matcher"))
    if p.aggregation == "sgm" and not 2 <= p.num_disparities <= 512:
        raise SlitcliError(f"`num_disparities` {p.num_disparities}: `aggregation` 'sgm' needs "
                           "at least 2 disparities and searches at most 512",
                           param=("num_disparities", "aggregation"))
    if p.sgm_paths not in (4, 8):
        raise SlitcliError(f"sgm_paths {p.sgm_paths} must be 4 or 8")
    if not 0 <= p.sgm_p1 <= p.sgm_p2 <= 8.0:
        raise SlitcliError(f"sgm_p1 {p.sgm_p1} and sgm_p2 {p.sgm_p2} must satisfy "
                           "0 <= sgm_p1 <= sgm_p2 <= 8 (Eq. 10 cost units)")
    if p.sgm_bracket_px < 0 or p.sgm_bracket_tol_px < 0:
        raise SlitcliError(f"sgm_bracket_px {p.sgm_bracket_px} and sgm_bracket_tol_px "
                           f"{p.sgm_bracket_tol_px} must be >= 0 (0 px reach = off)")
    if not isinstance(p.sgm_window_px, int | np.integer) or p.sgm_window_px < 0 or \
            (p.sgm_window_px > 0 and p.sgm_window_px % 2 == 0):
        raise SlitcliError(f"sgm_window_px {p.sgm_window_px} must be 0 (the window_w_px x "
                           "window_h_px window) or an odd number of pixels, e.g. 5",
                           param="sgm_window_px")
    if not p.sgm_texture_min_dn >= 0:
        raise SlitcliError(f"sgm_texture_min_dn {p.sgm_texture_min_dn} must be >= 0 DN "
                           "(0 = no window texture test under SGM)",
                           param="sgm_texture_min_dn")
    if p.sgm_subpixel not in SGM_SUBPIXEL:
        raise SlitcliError(f"sgm_subpixel {p.sgm_subpixel!r} is unknown; use one of "
                           f"{', '.join(SGM_SUBPIXEL)}", param="sgm_subpixel")
    g = p.sgm_ground_px_per_row
    if g is not None and not (math.isfinite(g) and 0 <= g <= 2.0):
        raise SlitcliError(f"sgm_ground_px_per_row {g} must lie in 0..2 px of disparity per "
                           "image row (0 = fronto-parallel windows, None = from the rig)",
                           param="sgm_ground_px_per_row")
    b = p.sgm_ground_band_px
    if b is not None and not (math.isfinite(b) and b >= 0):
        raise SlitcliError(f"sgm_ground_band_px {b} must be >= 0 px or None (from the rig)",
                           param="sgm_ground_band_px")
    if not 0 <= p.sgm_ground_tilt_tol_deg <= 10:
        raise SlitcliError(f"sgm_ground_tilt_tol_deg {p.sgm_ground_tilt_tol_deg} must lie in "
                           "0..10 deg", param="sgm_ground_tilt_tol_deg")
    if p.sgm_ground not in GROUND_SOURCES:
        raise SlitcliError(f"sgm_ground {p.sgm_ground!r} is unknown; use one of "
                           f"{', '.join(GROUND_SOURCES)}", param="sgm_ground")
    if not isinstance(p.sgm_ground_fit, GroundFitParams):
        raise SlitcliError("sgm_ground_fit must be a slitcli.stereo.ground.GroundFitParams",
                           param="sgm_ground_fit")
    v = p.sgm_ground_horizon_row_px
    if v is not None and not math.isfinite(v):
        raise SlitcliError(f"sgm_ground_horizon_row_px {v} must be a finite row (px) or None "
                           "(from the rig)", param="sgm_ground_horizon_row_px")
    if not 0 <= p.sgm_p2_edge_dn <= 255:
        raise SlitcliError(f"sgm_p2_edge_dn {p.sgm_p2_edge_dn} must lie in 0..255 DN "
                           "(0 = a constant sgm_p2)")


def _check_sizes(p: MatcherParams) -> None:
    """Subpixel mode, disparity count, window and prefilter sizes."""
    if p.subpixel not in SUBPIXEL:
        raise SlitcliError(f"`subpixel` {p.subpixel!r} is unknown; use one of "
                           f"{', '.join(SUBPIXEL)}", param="subpixel")
    if not isinstance(p.num_disparities, int | np.integer) or p.num_disparities <= 0:
        raise SlitcliError(f"`num_disparities` {p.num_disparities} must be a positive whole "
                           "number of pixels (e.g. 48)", param="num_disparities")
    for name, dim, w in (("window_w_px", "width", p.window_w_px),
                         ("window_h_px", "height", p.window_h_px)):
        if not isinstance(w, int | np.integer) or w < 1 or w % 2 == 0:
            raise SlitcliError(f"`{name}` {w}: the window {dim} must be an odd number of "
                               "pixels >= 1 (2m+1 of Eq. 10), e.g. 9", param=name)
    if p.prefilter_size_px < 3 or p.prefilter_size_px % 2 == 0:
        raise SlitcliError(f"`prefilter_size_px` {p.prefilter_size_px} must be odd and >= 3",
                           param="prefilter_size_px")
    if not p.prefilter_cap_dn > 0:
        raise SlitcliError(f"`prefilter_cap_dn` {p.prefilter_cap_dn} must be > 0 DN",
                           param="prefilter_cap_dn")
    if not p.log_sigma_px > 0:
        raise SlitcliError(f"log_sigma_px {p.log_sigma_px} must be > 0 px")


def _check_filters(p: MatcherParams) -> None:
    """The validity filters' thresholds (0 = off where the option says so)."""
    if not p.texture_min_dn >= 0:
        raise SlitcliError(f"`texture_min_dn` {p.texture_min_dn} must be >= 0 DN (0 = off)",
                           param="texture_min_dn")
    if not p.uniqueness_ratio >= 0:
        raise SlitcliError(f"`uniqueness_ratio` {p.uniqueness_ratio} must be >= 0 (0 = off)",
                           param="uniqueness_ratio")
    if p.support_radius_px < 1 or not -1.0 <= p.support_min_zncc <= 1.0 or \
            not -1.0 <= p.support_side_min_zncc <= 1.0 or \
            not -1.0 <= p.support_cross_min_zncc <= 1.0 or \
            not -1.0 <= p.support_strong_zncc <= 1.0:
        raise SlitcliError("`support_radius_px` must be >= 1 px and `support_min_zncc`, "
                           "`support_side_min_zncc`, `support_cross_min_zncc`, "
                           "`support_strong_zncc` in [-1, 1] (0 = off)",
                           param=("support_radius_px", "support_min_zncc",
                                  "support_side_min_zncc", "support_cross_min_zncc",
                                  "support_strong_zncc"))
    if not (math.isfinite(p.support_noise_ref_dn) and p.support_noise_ref_dn >= 0):
        raise SlitcliError(f"support_noise_ref_dn {p.support_noise_ref_dn} must be >= 0 DN",
                           param="support_noise_ref_dn")
    if p.noise_smoothing and not p.colour_whiten:
        raise SlitcliError("noise_smoothing low-passes the whitened colour images: it needs "
                           "colour_whiten True", param=("noise_smoothing", "colour_whiten"))
    if not (math.isfinite(p.smoothing_edge_sigmas) and 0 <= p.smoothing_edge_sigmas <= 6):
        raise SlitcliError(f"smoothing_edge_sigmas {p.smoothing_edge_sigmas} must lie in 0..6 "
                           "(sigmas of the noise_smoothing low-pass)",
                           param="smoothing_edge_sigmas")
    if not (math.isfinite(p.colour_whiten_min_noise_dn) and p.colour_whiten_min_noise_dn >= 0):
        raise SlitcliError(f"colour_whiten_min_noise_dn {p.colour_whiten_min_noise_dn} must be "
                           ">= 0 DN", param="colour_whiten_min_noise_dn")
    if not 0 <= p.boundary_ratio < 1:
        raise SlitcliError(f"`boundary_ratio` {p.boundary_ratio} must be in [0, 1) (0 = off)",
                           param="boundary_ratio")
    if not p.boundary_step_px > 0 or not p.boundary_noise_dn >= 0 or p.boundary_radius_px < 1:
        raise SlitcliError("boundary_step_px must be > 0 px, boundary_noise_dn >= 0 DN and "
                           "boundary_radius_px >= 1 px")
    if p.speckle_window_px < 0 or not p.speckle_range_px >= 0:
        raise SlitcliError("`speckle_window_px` and `speckle_range_px` must be >= 0 (0 = off)",
                           param=("speckle_window_px", "speckle_range_px"))


def _check_opencv(p: MatcherParams) -> None:
    """What OpenCV's StereoBM / StereoSGBM need of the disparities and window."""
    if p.matcher in ("bm", "sgbm"):
        if p.num_disparities % 16:
            raise SlitcliError(f"`num_disparities` {p.num_disparities} must be a multiple of "
                               f"16 for `matcher` {p.matcher} (OpenCV); e.g. 48 or 64",
                               param=("num_disparities", "matcher"))
        if p.window_w_px != p.window_h_px:
            raise SlitcliError(f"`window_w_px` {p.window_w_px} and `window_h_px` "
                               f"{p.window_h_px}: `matcher` {p.matcher} needs a square "
                               "window; make them equal",
                               param=("window_w_px", "window_h_px", "matcher"))
        if p.matcher == "bm" and not 5 <= p.window_w_px <= 255:
            raise SlitcliError(f"`window_w_px` {p.window_w_px}: `matcher` bm needs 5..255 px",
                               param=("window_w_px", "matcher"))


def _check_image(p: MatcherParams, image_width_px: int) -> None:
    """A window and disparity range that an image ``image_width_px`` wide holds."""
    if p.aggregation == "sgm" and p.sgm_window_px > image_width_px:
        raise SlitcliError(f"sgm_window_px {p.sgm_window_px} is wider than the image "
                           f"({image_width_px} px); use a smaller odd window",
                           param="sgm_window_px")
    if p.window_w_px > image_width_px:
        raise SlitcliError(f"`window_w_px` {p.window_w_px} is wider than the image "
                           f"({image_width_px} px); use a smaller odd window",
                           param="window_w_px")
    if p.min_disparity_px + p.num_disparities > image_width_px or \
            p.min_disparity_px <= -image_width_px:
        raise SlitcliError(f"`num_disparities` {p.num_disparities} (from "
                           f"`min_disparity_px` {p.min_disparity_px} px) exceeds the "
                           f"image width {image_width_px} px; use fewer disparities",
                           param=("num_disparities", "min_disparity_px"))


def match_nssd(left_grey: np.ndarray, right_grey: np.ndarray,
               params: MatcherParams, pool: ThreadPoolExecutor | None = None, *,
               left_bgr: np.ndarray | None = None, right_bgr: np.ndarray | None = None
               ) -> DisparityResult:
    """The paper's matcher: Eq. 10 cost, winner-take-all, subpixel, validity filters.

    Parameters
    ----------
    left_grey, right_grey : ndarray, uint8, shape (H, W)
        Rectified grey images (right camera at +baseline along x).
    params : MatcherParams
    pool : ThreadPoolExecutor, optional
        Helper threads held by the caller for a whole sequence (see
        :func:`compute_disparity`).
    left_bgr, right_bgr : ndarray, uint8, shape (H, W, 3), optional
        The colour pair the grey pair was made from. With ``colour_whiten``, a pair
        whose luma noise (estimated from the luma pass's matches) exceeds
        ``colour_whiten_min_noise_dn`` is matched again on its noise-whitened images
        (slitcli.stereo.whiten.noise_whitened_pair), and filtered on them.

    Returns
    -------
    DisparityResult
    """
    from slitcli.stereo._nssd import winners

    h, w = left_grey.shape
    disp = np.empty((h, w), np.float32)
    cost = np.empty((h, w), np.float32)
    reason = np.empty((h, w), np.uint8)
    rdisp = np.empty((h, w), np.float32)
    threads = kernel_threads()
    with frame_pool(pool, threads) as pool:
        pl, pr = _prefiltered_pair(left_grey, right_grey, params, pool)
        winners(pl, pr, params, pool, threads, disp, cost, reason, rdisp)
        white = None
        if params.colour_whiten and left_bgr is not None and right_bgr is not None:
            white = noise_whitened_pair(left_bgr, right_bgr, left_grey, right_grey,
                                        disp, reason == Reason.VALID, params)
        if white is None:
            run_disparity_filters(FilterInputs(left_grey, right_grey, pl, params, disp,
                                               reason, rdisp, pool, threads))
            return DisparityResult(disp, reason, cost)
        pl, pr = _prefiltered_pair(white.left, white.right, params, pool)
        winners(pl, pr, params, pool, threads, disp, cost, reason, rdisp)
        if white.smoothing_px == 0:
            run_disparity_filters(FilterInputs(white.left, white.right, pl, params, disp,
                                               reason, rdisp, pool, threads))
        else:
            smoothed_filters(white, pl, params, disp, reason, rdisp, pool, threads)
    return DisparityResult(disp, reason, cost)


def _prefiltered_pair(left_grey: np.ndarray, right_grey: np.ndarray, params: MatcherParams,
                      pool: ThreadPoolExecutor | None) -> tuple[np.ndarray, np.ndarray]:
    """Both views prefiltered (the right one on a helper thread when there is one)."""
    if pool is None:
        return prefilter_image(left_grey, params), prefilter_image(right_grey, params)
    right_job = pool.submit(prefilter_image, right_grey, params)
    return prefilter_image(left_grey, params), right_job.result()


def match_opencv(left_grey: np.ndarray, right_grey: np.ndarray,
                 params: MatcherParams) -> DisparityResult:
    """OpenCV's StereoBM (``bm``) or StereoSGBM (``sgbm``) behind the same interface.

    The shared parameters map onto OpenCV's: ``uniqueness_ratio`` x 100 ->
    ``uniquenessRatio`` (percent), ``lr_max_diff_px`` -> ``disp12MaxDiff``,
    ``speckle_*`` -> ``speckleWindowSize`` / ``speckleRange``, ``prefilter_cap_dn`` ->
    ``preFilterCap`` and, for BM, ``texture_min_dn`` -> ``textureThreshold`` (a sum
    of absolute prefiltered values over the window: 0.8 x std x window area). SGBM
    uses P1 = 8 w^2 and P2 = 32 w^2.
    """
    w = params.window_w_px
    common = dict(minDisparity=int(params.min_disparity_px),
                  numDisparities=int(params.num_disparities), blockSize=int(w))
    lr = int(params.lr_max_diff_px) if params.lr_max_diff_px >= 0 else -1
    cap = int(min(63, max(1, round(params.prefilter_cap_dn))))
    if params.matcher == "bm":
        st = cv2.StereoBM_create(numDisparities=int(params.num_disparities), blockSize=int(w))
        st.setMinDisparity(int(params.min_disparity_px))
        st.setTextureThreshold(round(0.8 * params.texture_min_dn * w * w))
        st.setPreFilterCap(cap)
    else:
        st = cv2.StereoSGBM_create(**common, P1=8 * w * w, P2=32 * w * w,
                                   mode=cv2.STEREO_SGBM_MODE_SGBM)
        st.setPreFilterCap(cap)
    st.setUniquenessRatio(round(100 * params.uniqueness_ratio))
    st.setDisp12MaxDiff(lr)
    st.setSpeckleWindowSize(int(params.speckle_window_px))
    st.setSpeckleRange(math.ceil(params.speckle_range_px) if params.speckle_window_px
                       else 0)
    raw = st.compute(np.ascontiguousarray(left_grey), np.ascontiguousarray(right_grey))
    valid = raw >= params.min_disparity_px * 16
    disp = np.where(valid, raw.astype(np.float32) / 16.0, np.float32(np.nan))
    reason = np.where(valid, Reason.VALID, Reason.OPENCV).astype(np.uint8)
    return DisparityResult(disp.astype(np.float32), reason)


def with_rig_ground(params: MatcherParams, geometry: StereoGeometry) -> MatcherParams:
    """``params`` with the ground's disparity gradient, horizon row and band from the rig.

    SGM's window is sheared by the ground plane's disparity gradient below the horizon
    (``sgm_ground_px_per_row``, ``sgm_ground_horizon_row_px``) for the disparities
    within ``sgm_ground_band_px`` of the ground's; where they are None (the defaults)
    the rig says where the ground is: the gradient and horizon from its floor
    disparities (:func:`slitcli.stereo.cost.ground_shear_from_floor`), the band from
    how far a tilt error of ``sgm_ground_tilt_tol_deg`` moves the floor's disparity
    (``f W / h`` px per radian at the horizon: 0.6 px per degree for the paper rig,
    4 px for KITTI's). Values set explicitly stay; so do the local matcher's, and
    those with ``sgm_ground`` 'pair' (the pair's ground, found in
    :func:`compute_disparity`) or 'off'.

    Parameters
    ----------
    params : MatcherParams
    geometry : StereoGeometry
        The rig's (``floor_disparity_px``, 0 above the horizon, and the rig itself).
    """
    from slitcli.stereo.cost import ground_shear_from_floor

    if params.aggregation != "sgm" or params.sgm_ground in ("pair", "off"):
        return params
    grad, horizon = ground_shear_from_floor(geometry.floor_disparity_px)
    rig = geometry.rig
    band = (rig.focal_px * rig.baseline_m / rig.mount.height_m
            * math.radians(params.sgm_ground_tilt_tol_deg))
    return replace(params, sgm_ground_px_per_row=_given(params.sgm_ground_px_per_row, grad),
                   sgm_ground_horizon_row_px=_given(params.sgm_ground_horizon_row_px, horizon),
                   sgm_ground_band_px=_given(params.sgm_ground_band_px, band))


def _given(value: float | None, default: float) -> float:
    return default if value is None else value


def compute_disparity(left: np.ndarray, right: np.ndarray,
                      params: MatcherParams | None = None, *,
                      pool: ThreadPoolExecutor | None = None,
                      workspace: SgmWorkspace | None = None) -> DisparityResult:
    """Disparity of a rectified pair with the chosen matcher.

    Parameters
    ----------
    left, right : ndarray, uint8, shape (H, W, 3) BGR or (H, W) grey
        Rectified images of the same size.
    params : MatcherParams, optional
        Defaults to ``MatcherParams()`` (the paper's Eq. 10 matcher with filters).
        With ``aggregation`` 'sgm' and no ground given (``sgm_ground_px_per_row``
        None, no rig here), ``sgm_ground`` 'auto' shears SGM's window by the ground
        estimated from the pair (slitcli.stereo.ground.estimate_ground), if any.
    pool : ThreadPoolExecutor, optional
        Helper threads (at least one worker) for the Eq. 10 matchers, held by a caller
        that matches a sequence of frames and shuts it down after the last one: a frame
        still uses only the cores free right now (``SLITCLI_THREADS``, the load), but
        does not start and join threads of its own (about 0.5 ms a frame). Without one
        a frame that uses a second core makes its own pool.
    workspace : SgmWorkspace, optional
        Memory for SGM's cost volumes (``aggregation`` 'sgm'), held by such a caller
        across its frames (slitcli.stereo.sgm.SgmWorkspace); without one each frame
        allocates its own.

    Raises
    ------
    SlitcliError
        For images of different sizes or parameters impossible for this image size.
    """
    p = MatcherParams() if params is None else params
    lg, rg = to_grey(left), to_grey(right)
    if lg.shape != rg.shape:
        raise SlitcliError(f"left image {lg.shape[1]}x{lg.shape[0]} and right image "
                           f"{rg.shape[1]}x{rg.shape[0]} differ in size; give a rectified "
                           "pair of the same size")
    check_matcher_params(p, image_width_px=lg.shape[1])
    if p.window_h_px > lg.shape[0]:
        raise SlitcliError(f"`window_h_px` {p.window_h_px} is taller than the image "
                           f"({lg.shape[0]} px); use a smaller odd window",
                           param="window_h_px")
    if p.matcher == "nssd" and p.aggregation == "sgm":
        from slitcli.stereo.sgm import match_sgm

        # no rig's ground (or sgm_ground 'pair'): match_sgm takes it from the pair
        return match_sgm(lg, rg, p, pool, workspace=workspace)
    if p.matcher == "nssd":
        colour = np.ndim(left) == 3
        return match_nssd(lg, rg, p, pool, left_bgr=left if colour else None,
                          right_bgr=right if colour else None)
    return match_opencv(lg, rg, p)
