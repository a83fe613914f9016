"""Laser slit extraction from one colour image (paper §2.1.1, Eqs. 1-4).

Pipeline (docs/laser.md, "How the stripe is found"); every loop over pixels or
columns is compiled (:mod:`slitcli.laser.candidates`, :mod:`slitcli.laser.fit`,
:mod:`slitcli.laser.track`, :mod:`slitcli.laser.select`):

1. Background: a vertical morphological opening per channel (compiled,
   :func:`slitcli.laser.candidates.vertical_opening`); the contrast
   ``x - opening`` is the light a pixel adds above its surroundings. Noise sigma
   from the colour orthogonal to the surface's (texture cancels there).
2. Evidence per pixel (Eqs. 1-3) on the contrast: red chromaticity (Eq. 2), white
   rejection (Eq. 3), and the laser estimate with the surface colour removed.
3. Candidates per column: local maxima of the evidence and saturated red plateaus,
   each fitted with a Gaussian on the texture-cancelled red signal (generalised least
   squares over the colour channels, saturated samples left out, the sheet's width
   as a prior); faint ones again on the column averaged with its neighbours.
4. Eq. 4: per column the best valid candidate by red peak, continuity with the
   neighbouring columns and the previous frame, and narrowness; valid candidates
   are Gaussians of the laser's sheet thickness, above the clutter of their
   surroundings, not on an edge between two surfaces.
5. Segments: columns joined by small row steps (or along a steep stripe); short
   segments and columns whose running median brightness is below ``min_peak_dn``
   are dropped, dim end columns too; gaps are filled and fading ends carried on by
   fits at the rows the segment predicts; each row is finally smoothed along its
   segment (weighted quadratic over nine columns).

The kernels walk image columns (transposed views of the arrays).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from slitcli.laser import candidates, finish, fit, select, sheet
from slitcli.laser.params import LaserParams

#: candidates fitted per column
K_BEST = 2
#: every NOISE_STEP-th column estimates the noise
NOISE_STEP = 32
#: weak candidates (continuing a neighbour's row) need this share of noise_k
WEAK_SHARE = 0.6
#: columns a fading segment may be carried on past its end
EXTEND_COLS = 4
#: candidates are seeded at least this many noise sigmas of the evidence (whose noise
#: is EVIDENCE_GAIN times the per-channel noise on a grey surface) above zero
SEED_SIGMAS = 3.0
EVIDENCE_GAIN = 1.4


@dataclass(frozen=True)
class StripeColumns:
    """The stripe found in one image, per column.

    Attributes
    ----------
    v_px : ndarray, shape (W,)
        Sub-pixel stripe row (pixel centres at integers); NaN where there is no stripe.
    strength_dn : ndarray, shape (W,)
        Fitted peak of the stripe's red light above the surface (texture-cancelled),
        DN; NaN where none.
    saturated : ndarray, shape (W,) bool
        The stripe's red core is clipped (the fit used its flanks).
    noise_sigma_dn : float
        Image noise standard deviation per channel, estimated from the image, DN.
    threshold_dn : float
        The acceptance level ``max(min_peak_dn, noise_k x noise)`` whose
        ``seed_fraction`` seeds candidates, DN.
    """

    v_px: np.ndarray
    strength_dn: np.ndarray
    saturated: np.ndarray
    noise_sigma_dn: float
    threshold_dn: float


def chromaticity(bgr: np.ndarray) -> np.ndarray:
    """Relative intensities R, G, B of paper Eq. 1.

    Parameters
    ----------
    bgr : ndarray, shape (..., 3), BGR order
        Absolute intensities b, g, r, or contrasts (any numeric type).

    Returns
    -------
    rgb_chroma : ndarray, shape (..., 3), float64, RGB order
        ``R = r / (r + g + b)`` etc.; all zero where ``r + g + b <= 0``.
    """
    x = np.asarray(bgr, dtype=np.float64)[..., ::-1]
    s = x.sum(axis=-1, keepdims=True)
    return np.divide(x, s, out=np.zeros_like(x), where=s > 0)


def candidate_mask(bgr: np.ndarray, background_bgr: np.ndarray,
                   params: LaserParams) -> tuple[np.ndarray, np.ndarray]:
    """Paper Eqs. 1-3 per pixel, on the light it adds above its background (numpy form).

    The compiled extractor applies exactly these tests
    (:func:`slitcli.laser.candidates.evidence`); this form documents them and serves
    tests and users who want the mask.

    Parameters
    ----------
    bgr : ndarray, shape (..., 3), uint8, BGR
        The image.
    background_bgr : ndarray, shape (..., 3), uint8, BGR
        Its local background (the extractor uses a vertical morphological opening of
        ``background_window_px`` rows); at most ``bgr``.
    params : LaserParams

    Returns
    -------
    red : ndarray of bool, shape (...)
        On the contrast ``t = bgr - background``: Eq. 2 on its chromaticity (Eq. 1),
        ``R > min_th`` and ``R - max(G, B) > min_delta_th`` (false where ``sum(t) <=
        0``), and Eq. 3, white rejection, ``y > alpha max(t_g, t_b)`` with ``y`` the
        laser estimate: the contrast's red less the part its green and blue explain
        along the background's colour (:data:`slitcli.laser.candidates.LAM_DETECT` of it),
        scaled so that laser light ``(1, XT, XT)`` gives its red.
    saturated : ndarray of bool, shape (...)
        Red at or above ``saturation_dn``: exempt from Eqs. 2-3 (a clipped core turns
        white); the extractor needs a red neighbour to take such a pixel.
    """
    x = np.asarray(bgr, dtype=np.float64)
    b = np.asarray(background_bgr, dtype=np.float64)
    t = x - b
    c = chromaticity(t)
    red_c, wht_c = c[..., 0], np.maximum(c[..., 1], c[..., 2])
    eq2 = (red_c > params.min_th) & (red_c - wht_c > params.min_delta_th)
    k = b[..., ::-1] + 0.5  # background colour, RGB
    k2 = (k * k).sum(axis=-1)
    kl = k[..., 0] + fit.XT * (k[..., 1] + k[..., 2])
    lq = candidates.LAM_DETECT * kl
    inv = 1.0 / (fit.A_LASER * k2 - lq * kl)
    y = ((k2 - lq * k[..., 0]) * inv * t[..., 2] + (fit.XT * k2 - lq * k[..., 1]) * inv * t[..., 1]
         + (fit.XT * k2 - lq * k[..., 2]) * inv * t[..., 0])
    eq3 = y > params.alpha * np.maximum(t[..., 1], t[..., 0])
    saturated = np.asarray(bgr)[..., 2] >= params.saturation_dn
    return eq2 & eq3 & ~saturated, saturated


def extract_stripe(left_bgr: np.ndarray, params: LaserParams, *,
                   search_mask: np.ndarray | None = None,
                   previous_v_px: np.ndarray | None = None,
                   px_per_m: np.ndarray | None = None) -> StripeColumns:
    """Find the laser stripe in a colour image, one sub-pixel row per column (Eqs. 1-4).

    Parameters
    ----------
    left_bgr : ndarray, shape (H, W, 3), uint8, BGR
        The (rectified) left image.
    params : LaserParams
    search_mask : ndarray, shape (H, W) bool, optional
        Pixels where the stripe may lie (from the rig geometry,
        :class:`slitcli.laser.frame.LaserGeometry`); default everywhere.
    previous_v_px : ndarray, shape (W,), optional
        The previous frame's stripe rows (NaN none), for the continuity term.
    px_per_m : ndarray, shape (H, W), optional
        Image rows per metre of height on an upright surface where each pixel's ray
        meets the laser plane (:class:`~slitcli.laser.frame.LaserGeometry`); with it,
        candidates must match the laser's sheet thickness ``params.sheet_sigma_mm``.

    Returns
    -------
    StripeColumns
    """
    img = np.asarray(left_bgr)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError("left_bgr must be an (H, W, 3) uint8 BGR image")
    h, w = img.shape[:2]
    mask = np.ones((h, w), bool) if search_mask is None else \
        np.asarray(search_mask, dtype=bool)
    if mask.shape != (h, w):
        raise ValueError(f"search_mask is {mask.shape}, the image {(h, w)}")
    # rows above the search region (and the reach of the opening and of a fit window
    # beyond it) are left out
    first_row = finish.first_search_row(mask.T)
    if first_row < 0:
        nan = np.full(w, np.nan)
        return StripeColumns(nan, nan.copy(), np.zeros(w, bool), 0.0, params.min_peak_dn)
    r0 = max(first_row - params.background_window_px - fit.FIT_HALF, 0)
    # the kernels walk image columns: transposed, contiguous (W, H, 3) copies (one
    # column is one contiguous run of memory); the opening runs along the columns
    sub = img[r0:]
    img_t = cv2.transpose(sub)
    # (a vertical window mixes no channels: on the (rows, 3 W) one-channel view of the
    # image it is the same opening; along whole image rows at once it is vectorised,
    # and min and max are exact. Its one-channel transpose, (3 W, rows), holds each
    # column's channels as separate runs: half the time of the three-channel
    # transpose, and the evidence loads them without shuffles)
    flat = np.ascontiguousarray(sub.reshape(sub.shape[0], 3 * w))
    opened = np.empty_like(flat)
    candidates.vertical_opening(flat, params.background_window_px, opened)
    bg_t = cv2.transpose(opened)
    mask_t = mask.T[:, r0:]  # contiguous rows for LaserGeometry's (Fortran-order) masks
    sigma = candidates.noise_sigma(img_t, bg_t, NOISE_STEP)
    thr = max(params.min_peak_dn, params.noise_k * sigma)
    seed = max(params.seed_fraction * thr, SEED_SIGMAS * EVIDENCE_GAIN * sigma)
    max_run = math.ceil(3.0 * params.max_width_px)
    z_strong = params.noise_k
    # faint candidates are fitted again over three columns averaged (1, 2, 1) / 4:
    # noise 0.61 sigma
    sigma_avg = math.sqrt(0.375) * sigma
    use_sheet = px_per_m is not None and params.sheet_sigma_mm > 0
    sheet_m = params.sheet_sigma_mm * 1e-3 if use_sheet else 0.0
    g_map = np.asarray(px_per_m, dtype=np.float64)[r0:] if use_sheet else \
        np.full((1, 1), np.nan)
    g_map_t = g_map.T
    cand = np.empty((w, K_BEST, fit.N_FIELDS))
    cand_avg = np.empty_like(cand)
    args = (img_t, bg_t, mask_t, sigma, sigma_avg, seed, params.min_th, params.min_delta_th,
            params.alpha, params.saturation_dn, max_run, params.max_width_px / select.EQ_WIDTH,
            select.SUPPORT_Z, z_strong, g_map_t)
    candidates.column_candidates(*args, sheet_m, cand, cand_avg)
    if use_sheet:
        # the sheet's thickness is the rig's; where the frame shows it clearly (many
        # clean, strong columns agreeing) that value replaces the parameter
        mode_m, support, voters = sheet.sheet_mode(cand, g_map_t, params.max_width_px)
        if support >= sheet.MODE_SUPPORT and 2 * support >= voters and \
                abs(math.log(mode_m / sheet_m)) > math.log(1.0 + sheet.MODE_WINDOW):
            sheet_m = mode_m
            candidates.column_candidates(*args, sheet_m, cand, cand_avg)
    prev = np.empty(0) if previous_v_px is None else \
        np.asarray(previous_v_px, dtype=np.float64) - r0
    if prev.size not in (0, w):
        raise ValueError(f"previous_v_px has {prev.size} entries, the image {w} columns")
    # Eq. 4 per column, then the segments: joined, tracked past their ends where the
    # stripe fades (far or grazing surfaces), faint and dim-end columns dropped, gaps
    # filled by fits at the interpolated rows, rows smoothed; one compiled call
    v_px = np.empty(w)
    strength = np.empty(w)
    saturated = np.empty(w, bool)
    finish.finish_stripe(img_t, cand, cand_avg, prev, g_map, g_map_t, sheet_m, sigma,
                         sigma_avg, params.saturation_dn, params.max_width_px,
                         params.max_width_px / select.EQ_WIDTH, params.beta, params.gamma,
                         params.continuity_px, params.max_jump_px, z_strong,
                         WEAK_SHARE * z_strong, params.min_segment_cols, params.min_peak_dn,
                         r0, v_px, strength, saturated)
    return StripeColumns(v_px, strength, saturated, float(sigma), float(thr))
