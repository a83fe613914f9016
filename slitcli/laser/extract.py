"""Laser stripe extraction from one colour image (paper §2.1.1, Eqs. 1-4).

The stripe model (docs/laser.md, "How the stripe is found"), its terms estimated on
each image, in the paper's steps:

1. Evidence (:mod:`.evidence`): background by a vertical opening, the laser evidence
   of every pixel with the surface colour removed, the noise of the evidence and of
   each channel measured robustly on the image.
2. Profile (:mod:`.profile`): a Gaussian across the column with a relative model
   error; clipped cores fitted on their flanks or centred on their plateau.
3. Candidates (:mod:`.candidates`): seeds per column (evidence maxima, clipped runs
   with red flanks), fitted, judged against the local noise.
4. Choice along the stripe (:mod:`.choose`): the tests of the model (width, shape,
   significance, the laser's colour estimated on the frame, the sheet's thickness),
   Eq. 4 per column, segments, rows smoothed along them.
5. Geometry (:mod:`.frame`): triangulation.

``method="paper"`` replaces steps 1-4 by the paper's literal per-pixel rules
(:mod:`.paper`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import cv2
import numpy as np

from slitcli.laser import candidates, choose, evidence, judge, luma, paper
from slitcli.laser.params import LaserParams
from slitcli.laser.profile import F_NCORE, F_POS, F_TG, F_TR, F_WIDTH, F_Z, N_FIELDS

#: candidates kept per column
K_BEST = 3
#: weights of the average along the stripe (over columns; the transposed evidence's
#: rows), and the noise it leaves of white noise: sqrt(70) / 16
AVG_KERNEL = (np.array([1.0, 4.0, 6.0, 4.0, 1.0], np.float32) / 16.0)[:, None]
AVG_NOISE = math.sqrt(70.0) / 16.0


@dataclass(frozen=True)
class StripeColumns:
    """The stripe found in one image, per column.

    Attributes
    ----------
    v_px : ndarray, shape (W,)
        Sub-pixel stripe row (pixel centres at integers); NaN where there is no stripe.
    strength_dn : ndarray, shape (W,)
        Fitted peak of the laser evidence above the surface, DN; NaN where none.
    saturated : ndarray, shape (W,) bool
        The stripe's core is clipped (centred on its flanks or plateau).
    noise_sigma_dn : float
        Noise sigma of the laser evidence, measured on the image, DN.
    threshold_dn : float
        Seed level ``seed_z x noise_sigma_dn``, DN.
    channel_sigma_dn : ndarray, shape (3,)
        Noise sigma of the red, green and blue channels, DN.
    laser_rgb : ndarray, shape (3,) or None
        The laser's colour (red 1) as the frame shows it, when enough columns show it.
    """

    v_px: np.ndarray
    strength_dn: np.ndarray
    saturated: np.ndarray
    noise_sigma_dn: float
    threshold_dn: float
    channel_sigma_dn: np.ndarray
    laser_rgb: np.ndarray | None = None


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


def background_window_px(params: LaserParams, height_px: int) -> int:
    """Rows of the vertical opening: odd, more than twice the widest stripe (so that the
    stripe never survives it), at least 21."""
    w = max(21, 2 * math.ceil(params.max_width_px(height_px)) + 1)
    return w | 1


class _Evidence(NamedTuple):
    """The laser evidence of a frame's searched rows and its noise levels (transposed,
    (W, h): one image column per array row)."""

    y: np.ndarray          # evidence per pixel, float32
    y_avg: np.ndarray      # averaged over five columns along the stripe
    clipped: np.ndarray    # red at or above saturation
    bg_t: np.ndarray       # the opening per channel, (3 W, h)
    sigma_y: float         # noise of y (the larger of pixel noise and spread), DN
    sigma_avg: float       # the same of y_avg
    noise_avg: float       # pixel noise of y_avg (seeds candidates), DN
    chan: np.ndarray       # noise per channel (b, g, r), floored, DN
    blur_var: float        # variance the chroma's processing adds to a profile, px^2
    clip_gb: tuple[int, int]  # green's and blue's clipping levels, DN
    sigma_luma: float      # noise of the luma, DN (NaN: not subsampled, or not used)


def _evidence(sub: np.ndarray, img_t: np.ndarray, mask_t: np.ndarray, chan: np.ndarray,
              win: int, params: LaserParams, sheet_test: bool,
              clip_gb: tuple[int, int]) -> _Evidence:
    """Background (vertical opening of ``win`` rows), laser evidence and its noise for
    the searched rows ``sub`` (h, W, 3) BGR; ``img_t``, ``mask_t`` their transposes,
    ``chan`` the per-channel noise (module notes of :mod:`~slitcli.laser.evidence`),
    ``clip_gb`` the green and blue clipping levels (red: ``params.saturation_dn``)."""
    w = sub.shape[1]
    # the opening along the columns: on the (rows, 3 W) one-channel view a vertical
    # window mixes no channels; its transpose holds each column's channels as runs
    flat = np.ascontiguousarray(sub.reshape(sub.shape[0], 3 * w))
    opened = np.empty_like(flat)
    evidence.vertical_opening(flat, win, opened)
    bg_t = cv2.transpose(opened)
    y = np.empty((w, sub.shape[0]), np.float32)
    clipped = np.empty((w, sub.shape[0]), bool)
    # the share of the surface colour to remove: texture against noise, on this image
    lo, hi = params.texture_share_range()
    lam = hi if lo >= hi else max(lo, evidence.texture_share(
        img_t, bg_t, mask_t, params.saturation_dn, 2 * evidence.NOISE_STEP, hi))
    # a pixel with any channel at its clipping level (measured on the image) is clipped
    evidence.laser_evidence(img_t, bg_t, params.saturation_dn, lam, y, clipped, *clip_gb)
    # the stripe runs along the image rows: the evidence averaged over five columns
    # (1, 4, 6, 4, 1) / 16 has about half the noise (its own is measured below)
    y_avg = cv2.filter2D(y, -1, AVG_KERNEL, borderType=cv2.BORDER_REPLICATE)
    # two noise levels of each: the pixel noise (lag-2 residuals) seeds candidates; the
    # spread of the evidence over the image (noise and the clutter it does not cancel)
    # judges them, where it is larger
    # pixels whose red is clipped to black show no noise (nor does a clipped core): the
    # noise is measured where the red channel is inside its range
    live = np.empty_like(mask_t)
    if not candidates.evidence_live(mask_t, img_t, clipped, live):
        live = mask_t
    noise_avg = max(evidence.robust_sigma(y_avg, live, evidence.NOISE_STEP),
                    AVG_NOISE * params.noise_floor_dn)
    sigma_y = max(evidence.robust_sigma(y, live, evidence.NOISE_STEP),
                  evidence.spread_sigma(y, live, evidence.NOISE_STEP), params.noise_floor_dn)
    sigma_avg = max(noise_avg, evidence.spread_sigma(y_avg, live, evidence.NOISE_STEP))
    chan = np.maximum(chan, params.noise_floor_dn)
    # subsampled chroma (JPEG 4:2:0) blurs the evidence, which is chroma, across rows;
    # told from the image where it matters (the sheet test, the luma's test and rows)
    subsampled = (sheet_test or params.luma_rows or params.luma_min_z > 0
                  or params.luma_widths) and params.chroma_smoothness_max > 0 and \
        luma.chroma_smoothness(img_t, luma.SMOOTHNESS_STEP) < params.chroma_smoothness_max
    luma_used = params.luma_rows or params.luma_min_z > 0 or params.luma_widths
    sigma_luma = max(luma.luma_sigma(img_t, evidence.NOISE_STEP), params.noise_floor_dn) \
        if subsampled and luma_used else math.nan
    return _Evidence(y, y_avg, clipped, bg_t, float(sigma_y), float(sigma_avg),
                     float(noise_avg), chan, luma.CHAIN_VAR_PX2 if subsampled else 0.0,
                     clip_gb, sigma_luma)


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
        Pixels where the stripe may lie (:class:`~slitcli.laser.frame.LaserGeometry`);
        default everywhere.
    previous_v_px : ndarray, shape (W,), optional
        The previous frame's stripe rows (NaN none), for the continuity term of Eq. 4.
    px_per_m : ndarray, shape (H, W), optional
        Image rows per metre of height on an upright surface where each pixel's ray
        meets the laser plane; with it, candidates must match the sheet's thickness
        ``params.sheet_sigma_mm``.

    Returns
    -------
    StripeColumns
    """
    img, mask, prev = _checked_inputs(left_bgr, search_mask, previous_v_px)
    h, w = img.shape[:2]
    nan = np.full(w, np.nan)
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        return StripeColumns(nan, nan.copy(), np.zeros(w, bool), 0.0, 0.0, np.zeros(3))
    # each channel's clipping level as this image shows it (white balance and tone
    # curves clip some channels below saturation_dn); red's sets saturation_dn
    clip_b, clip_g, clip_r = evidence.clip_levels(img, params.saturation_dn)
    if clip_r != params.saturation_dn:
        params = replace(params, saturation_dn=clip_r)
    max_w = params.max_width_px(h)
    win = background_window_px(params, h)
    # rows above the search region, beyond the reach of the opening, are left out
    r0 = max(int(rows[0]) - win, 0)
    sub = img[r0:]
    img_t = cv2.transpose(sub)  # (W, h, 3): one image column per array row
    mask_t = np.ascontiguousarray(mask[r0:].T)
    chan = evidence.channel_sigma(img_t, evidence.NOISE_STEP)
    if params.method == "paper":
        v = np.empty(w)
        amp = np.empty(w)
        paper.paper_columns(img_t, mask_t, params.min_th, params.min_delta_th, params.alpha,
                            params.beta, params.gamma, params.continuity_px, max_w, v, amp)
        return StripeColumns(v + r0, amp, np.zeros(w, bool), float(np.median(chan)), 0.0, chan)
    ev = _evidence(sub, img_t, mask_t, chan, win, params,
                   px_per_m is not None and params.sheet_sigma_mm > 0, (clip_g, clip_b))
    y, y_avg, clipped = ev.y, ev.y_avg, ev.clipped
    sigma_y, sigma_avg = ev.sigma_y, ev.sigma_avg
    seed = params.seed_z * ev.noise_avg
    s_max = max_w / judge.EQ_WIDTH
    cand, ok, laser = _judged_candidates(img_t, mask_t, r0, ev, seed, s_max, px_per_m, params)
    v = np.empty(w)
    amp = np.empty(w)
    sat = np.empty(w, bool)
    choose.choose_stripe(cand, ok, prev, params.beta, params.weak_z, params.continuity_px,
                         params.max_jump_px, params.min_segment_cols(w), params.min_z,
                         params.strong_share * params.min_z,
                         round(params.min_stripe_share * int(mask.any(axis=0).sum())),
                         params.choice_rounds, v, amp, sat)
    # columns without a stripe inside a segment, where the stripe must pass
    candidates.fill_gaps(v, amp, cand, y, y_avg, clipped, mask_t, float(sigma_y),
                         float(sigma_avg), r0, choose.MAX_GAP, params.max_jump_px,
                         params.gap_z_share * params.weak_z, params.shape_error, s_max,
                         params.own_z, img_t, ev.bg_t, float(params.saturation_dn),
                         sat.view(np.uint8))
    if ev.blur_var > 0.0 and (params.luma_min_z > 0 or params.luma_rows) and \
            np.isfinite(v).any():
        if params.luma_min_z > 0:
            _luma_checked(v, amp, sat, cand, img_t, r0, ev, s_max, ev.sigma_luma, params)
        if params.luma_rows and np.isfinite(v).any():
            v = _luma_refined(v, sat, cand, img_t, r0, ev, s_max, ev.sigma_luma, params)
    return StripeColumns(v, amp, sat, float(sigma_y), float(seed), ev.chan, laser)


def _luma_checked(v: np.ndarray, amp: np.ndarray, sat: np.ndarray, cand: np.ndarray,
                  img_t: np.ndarray, r0: int, ev: _Evidence, s_max: float,
                  sigma_luma: float, params: LaserParams) -> None:
    """The pieces of stripe ``v`` (W,) found on the evidence of an image with
    subsampled chroma whose luma (noise ``sigma_luma``, DN) shows no light at their
    rows (:func:`slitcli.laser.luma.luma_segments`) taken out of ``v``, ``amp`` and
    ``sat``, in place."""
    keep = luma.luma_segments(
        img_t, ev.bg_t, v, sat, cand, r0, sigma_dn=sigma_luma, blur_var_px2=ev.blur_var,
        s_max=s_max, saturation_dn=params.saturation_dn, max_gap=choose.MAX_GAP,
        max_jump_px=params.max_jump_px, min_z=params.luma_min_z)
    v[~keep] = np.nan
    amp[~keep] = np.nan
    sat[~keep] = False


def _luma_refined(v: np.ndarray, sat: np.ndarray, cand: np.ndarray, img_t: np.ndarray,
                  r0: int, ev: _Evidence, s_max: float, sigma_luma: float,
                  params: LaserParams) -> np.ndarray:
    """The rows ``v`` (W,) found on the evidence of an image with subsampled chroma, fitted
    again on the luma (noise ``sigma_luma``, DN) where it shows the stripe
    (:func:`slitcli.laser.luma.luma_rows`) and its offset from the evidence's row
    agrees with its neighbours' (:func:`slitcli.laser.luma.consistent_offsets`),
    smoothed along the segments as the evidence's rows are, and combined with them by
    their variances (:func:`slitcli.laser.luma.combined_rows`)."""
    v_l, se_l, w_l, se_ev = luma.luma_rows(
        img_t, ev.bg_t, v, sat, cand, r0, sigma_dn=sigma_luma, blur_var_px2=ev.blur_var,
        shape_error=params.shape_error, max_chi2=params.max_chi2, s_max=s_max,
        min_z=params.weak_z, saturation_dn=params.saturation_dn)
    keep = luma.consistent_offsets(v, v_l, max_gap=choose.MAX_GAP,
                                   max_jump_px=params.max_jump_px)
    v_l[~keep] = np.nan
    smooth = np.empty_like(v_l)
    choose.smooth_rows(v_l, se_l, w_l, keep.view(np.uint8), params.max_jump_px, smooth)
    return luma.combined_rows(v, se_ev, smooth, se_l)


def _luma_width_valid(cand: np.ndarray, ok: np.ndarray, img_t: np.ndarray, r0: int,
                      ev: _Evidence, s_max: float, params: LaserParams, tests: dict,
                      laser: np.ndarray | None) -> np.ndarray:
    """(W, K) bool: the candidates that fail the tests of ``judge.valid_candidates``
    (arguments ``tests``) on their evidence's width and pass them on their width fitted
    on the luma (:func:`slitcli.laser.luma.luma_widths`). The luma's profile is the
    light's; the tests allow for the evidence's 4:2:0 blur, so the luma's width is
    compared with that added (``ev.blur_var``).

    Asked only of strong candidates (``strong_share x min_z``) whose light shows the
    frame's laser colour ``laser`` (RGB, red 1; None: the frame does not show it, and
    no candidate is asked): their added green at most the laser's share of their added
    red plus three noise sigmas of the core's mean. The codec spreads a stripe's chroma
    beside a colour edge; a hump too wide for the sheet is as often the codec's chroma
    clutter, the surface's own colour and greyer than the laser (measured through
    ``webcam``: rescued clutter 360 -> 154 candidates, the stripe's 72 -> 68), or
    weak (a wall's clutter segment chosen over the stripe).
    """
    if laser is None:
        return np.zeros_like(ok)
    n_core = np.maximum(np.nan_to_num(cand[..., F_NCORE]), 1.0)
    green_excess = cand[..., F_TG] - laser[1] * cand[..., F_TR]
    need = ~ok & (cand[..., F_Z] >= params.strong_share * params.min_z) & \
        (green_excess <= judge.COLOUR_SIGMAS * tests["channel_sigma_dn"]
         * math.sqrt(1.0 + laser[1] ** 2) / np.sqrt(n_core))
    if not need.any():
        return np.zeros_like(ok)
    w_luma = luma.luma_widths(
        img_t, ev.bg_t, cand, need, r0, sigma_dn=ev.sigma_luma, blur_var_px2=ev.blur_var,
        shape_error=params.shape_error, max_chi2=params.max_chi2, s_max=s_max,
        min_z=params.weak_z, saturation_dn=params.saturation_dn)
    fitted = np.isfinite(w_luma)
    if not fitted.any():
        return np.zeros_like(ok)
    as_luma = cand.copy()
    as_luma[..., F_WIDTH] = np.where(fitted, np.sqrt(w_luma ** 2 + ev.blur_var),
                                     cand[..., F_WIDTH])
    return fitted & judge.valid_candidates(as_luma, **tests)[0]


def checked_image(left_bgr: np.ndarray) -> np.ndarray:
    """``left_bgr`` as an array, or ValueError where it is no (H, W, 3) uint8 image (a
    grey or float image, or ``cv2.imread``'s None)."""
    img = np.asarray(left_bgr)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError("left_bgr must be an (H, W, 3) uint8 BGR image")
    return img


def _checked_inputs(left_bgr: np.ndarray, search_mask: np.ndarray | None,
                    previous_v_px: np.ndarray | None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`extract_stripe`'s inputs as arrays of the layout its kernels read: the image
    (H, W, 3) uint8, the search mask (H, W) bool (everywhere if none) and the previous
    rows (W,) float64 (empty if none); ValueError naming the one that does not fit."""
    img = checked_image(left_bgr)
    h, w = img.shape[:2]
    mask = np.ones((h, w), bool) if search_mask is None else \
        np.asarray(search_mask, dtype=bool)
    if mask.shape != (h, w):
        raise ValueError(f"search_mask is {mask.shape}, the image {(h, w)}")
    prev = np.empty(0) if previous_v_px is None else \
        np.asarray(previous_v_px, dtype=np.float64)
    if prev.size not in (0, w):
        raise ValueError(f"previous_v_px has {prev.size} entries, the image {w} columns")
    return img, mask, prev


def _judged_candidates(img_t: np.ndarray, mask_t: np.ndarray, r0: int, ev: _Evidence,
                       seed: float, s_max: float, px_per_m: np.ndarray | None,
                       params: LaserParams) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Steps 3-4: every column's candidates (W, K_BEST, N_FIELDS; rows from the image's
    top) fitted where the evidence passes ``seed``, which of them can be the laser
    (W, K) bool, and the laser colour the tests used (None: not measured)."""
    w, h = img_t.shape[0], img_t.shape[1] + r0
    y, y_avg, clipped, chan = ev.y, ev.y_avg, ev.clipped, ev.chan
    chan_sigma = float(np.sort(chan)[1])  # (the median of three)
    cand = np.empty((w, K_BEST, N_FIELDS))
    candidates.column_candidates(img_t, ev.bg_t, y, y_avg, clipped, mask_t, ev.sigma_y,
                                 ev.sigma_avg, seed, params.strong_share * params.min_z,
                                 params.saturation_dn, s_max, params.shape_error,
                                 params.max_chi2, params.weak_z, cand, ev.clip_gb)
    cand[..., F_POS] += r0
    sheet_px = None
    if px_per_m is not None and params.sheet_sigma_mm > 0:
        sheet_px = np.empty(cand.shape[:2])
        # (column-major, as LaserGeometry holds it)
        candidates.sheet_width_px(cand, np.asfortranarray(px_per_m, dtype=np.float64),
                                  params.sheet_sigma_mm, sheet_px)
    tests = {"height_px": h, "s_max": s_max, "min_z": params.min_z,
             "max_chi2": params.max_chi2, "min_th": params.min_th,
             "min_delta_th": params.min_delta_th, "colour_error": params.colour_error,
             "channel_sigma_dn": chan_sigma, "sheet_px": sheet_px,
             "sheet_tolerance": params.sheet_tolerance,
             "sheet_support": round(params.min_stripe_share * w),
             "blur_var_px2": ev.blur_var, "max_hue_deg": params.max_hue_deg,
             "width_spread": params.width_spread, "laser_share_z": params.laser_share_z}
    ok, laser = judge.valid_candidates(cand, **tests)
    if params.luma_widths and ev.blur_var > 0.0:
        ok |= _luma_width_valid(cand, ok, img_t, r0, ev, s_max, params, tests, laser)
    # a candidate less than weak_z significant is never chosen (choose.best_path): the
    # tests on the image around it are spent on the others alone
    need = ok & (cand[..., F_Z] >= params.weak_z)
    if math.isfinite(params.surface_step):
        ok &= judge.surface_continues(cand, img_t, r0, chan_sigma, need,
                                      step=params.surface_step, min_dn=params.surface_min_dn)
    ok &= judge.own_light_candidates(cand, y, y_avg, clipped, mask_t, r0, float(ev.sigma_y),
                                      params.shape_error, need, own_z=params.own_z)
    return cand, judge.one_crossing(cand, ok) if params.one_crossing else ok, laser


