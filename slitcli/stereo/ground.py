"""The ground's disparity gradient and horizon row from the pair itself (v-disparity).

SGM's sheared window (``MatcherParams.sgm_ground_*``, slitcli.stereo.cost) needs the
ground plane's disparity gradient and horizon row. A rig gives them (Eq. 8 with the
floor's depth: ``d(v) = W cos(tilt) / h (v - v_h)`` below the horizon ``v_h``, no
roll); a folder of pairs has no rig. Then the pair tells: the ground is the one
surface whose disparity grows linearly down the image over many rows and across the
whole width, a straight line ``d = g (v - v_h)`` in the histogram of disparities
per image row (the *v-disparity* image, Labayrade et al. 2002), where an upright
surface is a vertical segment (one disparity over its rows).

:func:`estimate_ground`:

1. a cheap first pass: the local Eq. 10 matcher (its winner step's texture,
   uniqueness and left-right tests; the line fit needs no more) on the
   pair reduced by a whole factor ``s`` to about ``GroundFitParams.area_px`` pixels
   (block means: a reduced pixel is the mean of ``s x s`` pixels, so a reduced
   disparity is the full one over ``s`` and the gradient in px per row is the same);
   its window is wide and short (``window_w_px x window_h_px``, 9 x 3) so that the
   ground's disparity changes little across the window's rows;
2. the v-disparity histogram of its valid pixels (reduced rows x disparity bins);
3. line hypotheses through pairs of valid pixels (a fixed seed: the same pair gives
   the same estimate), each scored by the histogram mass within ``inlier_px`` of it,
   row by row (cumulative sums: a hypothesis costs one look-up per row), among
   gradients ``px_per_row_min .. px_per_row_max``;
4. the best line refitted by least squares to its inliers (twice, the inliers
   re-selected), with its residual spread and the gradient's standard error;
5. accepted only where the line is well supported: a share ``min_share`` of the
   valid pixels in the rows where it lies inside the disparity range lie on it, at
   least ``min_row_share`` of those rows hold ground across ``row_width_share`` of
   the image width, the residual's robust spread stays below ``max_residual_px`` and
   the ground spans at least ``min_rows_share`` of the image height. An indoor
   scene without a floor (objects at a few depths) has no such line; a wall facing
   the camera is a vertical segment (gradient 0).

The band of disparities that take the sheared window (``sgm_ground_band_px``) follows
from the fit: ``band_sigmas`` times the residual spread (the ground's own departures
from one line, roll and camber, and the first pass's noise) plus the line's
uncertainty at the bottom row, at least ``band_min_px``.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import KW_ONLY, dataclass, replace
from typing import TYPE_CHECKING

import cv2
import numpy as np

from slitcli.errors import SlitcliError

if TYPE_CHECKING:
    from slitcli.stereo.matcher import MatcherParams

#: Where SGM's ground comes from when ``sgm_ground_px_per_row`` is None:
#: ``auto`` the rig where one is known, else the pair; ``rig`` the rig only (none
#: without one); ``pair`` the pair even when a rig is known; ``check`` the rig's,
#: replaced by the pair's where the pair's ground leaves the rig's band (a rig whose
#: tilt is off; the pair alone without a rig); ``off`` nowhere.
GROUND_SOURCES = ("auto", "rig", "pair", "check", "off")


@dataclass(frozen=True)
class GroundFitParams:
    """How the ground is estimated from a pair (:func:`estimate_ground`).

    Pixel units are those of the full-size pair unless named ``reduced``.
    """

    _: KW_ONLY
    area_px: int = 9600
    window_w_px: int = 9
    window_h_px: int = 3
    inlier_px: float = 1.5
    hypotheses: int = 128
    px_per_row_min: float = 0.05
    px_per_row_max: float = 2.0
    min_share: float = 0.4
    min_row_share: float = 0.6
    row_width_share: float = 0.15
    min_rows_share: float = 0.2
    max_residual_px: float = 1.5
    band_sigmas: float = 2.5
    band_min_px: float = 1.0

    def __post_init__(self) -> None:
        check_ground_fit(self)


def check_ground_fit(p: GroundFitParams) -> None:
    """Raise :class:`SlitcliError` naming the parameter for impossible settings."""
    if not isinstance(p.area_px, int) or p.area_px < 1024:
        raise SlitcliError(f"sgm_ground_fit.area_px {p.area_px} must be a whole number "
                           ">= 1024 px", param="sgm_ground_fit")
    for name in ("window_w_px", "window_h_px"):
        w = getattr(p, name)
        if not isinstance(w, int) or w < 1 or w % 2 == 0:
            raise SlitcliError(f"sgm_ground_fit.{name} {w} must be an odd number of pixels",
                               param="sgm_ground_fit")
    if not 0 < p.px_per_row_min < p.px_per_row_max <= 2.0:
        raise SlitcliError("sgm_ground_fit: 0 < px_per_row_min < px_per_row_max <= 2 px "
                           "per row", param="sgm_ground_fit")
    shares = (p.min_share, p.min_row_share, p.row_width_share, p.min_rows_share)
    if not all(0 <= s <= 1 for s in shares):
        raise SlitcliError("sgm_ground_fit: min_share, min_row_share, row_width_share and "
                           "min_rows_share must lie in 0..1", param="sgm_ground_fit")
    if not (p.inlier_px > 0 and p.max_residual_px > 0 and p.band_sigmas >= 0
            and p.band_min_px >= 0 and p.hypotheses >= 1):
        raise SlitcliError("sgm_ground_fit: inlier_px and max_residual_px must be > 0 px, "
                           "band_sigmas and band_min_px >= 0, hypotheses >= 1",
                           param="sgm_ground_fit")


@dataclass(frozen=True)
class GroundEstimate:
    """The ground line ``d = px_per_row (v - horizon_row_px)`` found in a pair.

    Attributes
    ----------
    found : bool
        The line passed every acceptance test; only then do the fields below set
        SGM's sheared window.
    px_per_row : float
        Disparity gradient, px of disparity per image row (v down); NaN when no line.
    horizon_row_px : float
        Row (px, v down) where the line's disparity is 0.
    band_px : float
        Disparities within this of the line take the sheared window, px.
    share : float
        Valid first-pass pixels on the line over those in the rows it spans.
    row_share : float
        Share of those rows that hold ground across ``row_width_share`` of the width.
    residual_px : float
        Robust spread (1.4826 MAD) of the inliers' disparities about the line, px.
    px_per_row_sigma : float
        Standard error of the gradient, px per row.
    why : str
        The first test that failed ("" when found).
    """

    found: bool
    px_per_row: float = math.nan
    horizon_row_px: float = math.nan
    band_px: float = math.nan
    share: float = 0.0
    row_share: float = 0.0
    residual_px: float = math.nan
    px_per_row_sigma: float = math.nan
    why: str = ""


def first_pass(left_grey: np.ndarray, right_grey: np.ndarray, params: MatcherParams,
               fit: GroundFitParams, pool: ThreadPoolExecutor | None = None
               ) -> tuple[np.ndarray, int]:
    """The local Eq. 10 matcher on the pair reduced by a whole factor ``s``.

    Returns
    -------
    disparity_reduced_px : ndarray, float32, shape (H // s, W // s)
        Disparity in reduced pixels (full-size px / s), NaN = invalid.
    s : int
        The reduction factor; reduced row ``r`` is the mean of full rows
        ``s r .. s r + s - 1`` (centre ``s r + (s - 1) / 2``).
    """
    from slitcli.stereo import _nssd
    from slitcli.stereo.bands import kernel_threads
    from slitcli.stereo.cost import prefilter_image

    h, w = left_grey.shape
    s = max(1, round(math.sqrt(h * w / fit.area_px)))
    hs, ws = h // s, w // s
    dmin = math.floor(params.min_disparity_px / s)
    num = math.ceil((params.min_disparity_px + params.num_disparities) / s) - dmin
    num = min(num, ws - 1 - max(dmin, 0))
    # the local matcher needs a window the reduced image holds
    ww = min(fit.window_w_px, ws - ws % 2 - 1)
    wh = min(fit.window_h_px, hs - hs % 2 - 1)
    if ww < 1 or wh < 1 or num < 2:
        return np.full((max(hs, 0), max(ws, 0)), np.nan, np.float32), s

    def reduce(img: np.ndarray) -> np.ndarray:
        if s == 1:
            return np.ascontiguousarray(img)
        return cv2.resize(np.ascontiguousarray(img[:hs * s, :ws * s]), (ws, hs),
                          interpolation=cv2.INTER_AREA)

    # the local matcher's winner step alone (texture, uniqueness, left-right, subpixel),
    # on the matcher's prefilter: the line fit is robust to the few wrong pixels the
    # support, depth-edge and speckle filters would remove, at a third of the time
    p = replace(params, aggregation="none", num_disparities=int(num),
                min_disparity_px=int(dmin), window_w_px=int(ww), window_h_px=int(wh))
    pl, pr = prefilter_image(reduce(left_grey), p), prefilter_image(reduce(right_grey), p)
    disp, cost, rdisp = np.empty((3, hs, ws), np.float32)
    reason = np.empty((hs, ws), np.uint8)
    # a second thread only on the caller's pool: a pool of its own costs about 0.5 ms,
    # more than half this pass
    threads = kernel_threads() if pool is not None else 1
    _nssd.winners(pl, pr, p, pool if threads > 1 else None, threads, disp, cost, reason,
                  rdisp)
    return np.where(reason == 0, disp, np.float32(np.nan)), s


def fit_ground_line(disparity_reduced_px: np.ndarray, s: int, dmin_px: float,
                    dmax_px: float, fit: GroundFitParams) -> GroundEstimate:
    """The ground line in a (reduced) disparity image's v-disparity histogram.

    Parameters
    ----------
    disparity_reduced_px : ndarray, float32, shape (Hr, Wr)
        First-pass disparities in reduced pixels, NaN = invalid.
    s : int
        Reduction factor (full px = s x reduced px; full row = s r + (s - 1) / 2).
    dmin_px, dmax_px : float
        The full-size disparity range searched: rows whose ground disparity lies
        outside it are not asked to hold ground.
    fit : GroundFitParams

    Returns
    -------
    GroundEstimate
        In full-size pixels and rows.

    Notes
    -----
    The per-point steps run in compiled loops (slitcli/stereo/_c/ground.pyx): in NumPy
    their call overhead took about 1 ms of a 320 x 240 frame.
    """
    from slitcli.stereo._c import ground as _k

    disp = np.ascontiguousarray(disparity_reduced_px, np.float32)
    hr, wr = disp.shape
    rows = np.empty(hr * wr, np.int32)
    r, d = np.empty((2, hr * wr), np.float64)
    count = _k.valid_points(disp, rows, r, d)
    if count < 20:
        return GroundEstimate(False, why="too few first-pass disparities")
    rows, r, d = rows[:count], r[:count], d[:count]
    tol = fit.inlier_px / s
    g, b = _best_hypothesis(rows, r, d, hr, tol, fit)
    if not math.isfinite(g):
        return GroundEstimate(False, why="no line with a plausible gradient")
    for _ in range(2):
        # least squares on the line's inliers, selected again about the refitted line
        g, b, n_on, r_mean, sxx = _k.line_refit(r, d, g, b, tol)
        if n_on < 10 or sxx <= 0:
            return GroundEstimate(False, why="too few pixels on the line")
    resid = np.empty(count, np.float64)
    per_row = np.zeros(hr, np.int64)
    resid = resid[:_k.line_inliers(rows, r, d, g, b, tol, resid, per_row)]
    sigma_red = 1.4826 * _median(np.abs(resid - _median(resid)))
    # standard error of the gradient and of the line at the bottom row
    g_sigma = sigma_red / math.sqrt(sxx)
    bottom_sigma = sigma_red * math.sqrt(1.0 / n_on + (hr - 1 - r_mean) ** 2 / sxx)
    horizon_red = -b / g if g > 0 else math.nan
    est = {"px_per_row": float(g), "horizon_row_px": float(s * horizon_red + (s - 1) / 2),
           "residual_px": s * sigma_red, "px_per_row_sigma": float(g_sigma),
           "band_px": max(fit.band_min_px, s * (fit.band_sigmas * sigma_red + bottom_sigma))}
    if not fit.px_per_row_min <= g <= fit.px_per_row_max:
        return GroundEstimate(False, **est, why="gradient out of range")
    # the rows where the line lies inside the searched disparities (and below the
    # horizon): there every row of a ground would hold it
    line = g * np.arange(hr) + b
    span = (line >= dmin_px / s + 1) & (line <= dmax_px / s - 1)
    if span.sum() < fit.min_rows_share * hr:
        return GroundEstimate(False, **est, why="the line spans too few rows")
    share = float(per_row[span].sum() / max(np.bincount(rows, minlength=hr)[span].sum(), 1))
    row_share = float((per_row[span] >= fit.row_width_share * wr).mean())
    est.update(share=share, row_share=row_share)
    if s * sigma_red > fit.max_residual_px:
        return GroundEstimate(False, **est, why="residual too large")
    if share < fit.min_share:
        return GroundEstimate(False, **est, why="too small a share of pixels on the line")
    if row_share < fit.min_row_share:
        return GroundEstimate(False, **est, why="too few rows hold ground")
    return GroundEstimate(True, **est)


def _median(values: np.ndarray) -> float:
    """``np.median`` of a 1-D float64 array by one partition (its checks and copies
    cost more than the partition on a few thousand values)."""
    n = values.size
    if n == 0:
        return math.nan
    k = n // 2
    if n % 2:
        return float(np.partition(values, k)[k])
    part = np.partition(values, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2)


def _best_hypothesis(rows: np.ndarray, r: np.ndarray, d: np.ndarray, hr: int, tol: float,
                     fit: GroundFitParams) -> tuple[float, float]:
    """Gradient and intercept (reduced units, ``d = g r + b``) of the line through
    pairs of valid pixels that holds the most v-disparity mass within ``tol``."""
    from slitcli.stereo._c import ground as _k

    rng = np.random.default_rng(0)
    k = fit.hypotheses
    i = rng.integers(0, r.size, 4 * k)
    j = rng.integers(0, r.size, 4 * k)
    dr = r[j] - r[i]
    ok = np.abs(dr) >= max(2.0, hr / 8)
    g = np.where(ok, (d[j] - d[i]) / np.where(ok, dr, 1.0), np.nan)
    ok &= (g >= fit.px_per_row_min) & (g <= fit.px_per_row_max)
    if not ok.any():
        return math.nan, math.nan
    g = g[ok][:k]
    b = d[i][ok][:k] - g * r[i][ok][:k]
    # v-disparity histogram: rows x bins of tol / 2, cumulated along the disparity;
    # each hypothesis' mass: its bins within tol at every row (compiled)
    q = tol / 2
    lo = math.floor(d.min() / q) - 1
    nb = math.floor(d.max() / q) - lo + 2
    mass = np.empty(g.size, np.int64)
    _k.line_mass(rows, d, hr, q, lo, nb, tol / q, g, b, mass)
    best = int(np.argmax(mass))
    return float(g[best]), float(b[best])


def estimate_ground(left_grey: np.ndarray, right_grey: np.ndarray, params: MatcherParams,
                    pool: ThreadPoolExecutor | None = None) -> GroundEstimate:
    """The ground plane's disparity line in a rectified pair, or "not found".

    Parameters
    ----------
    left_grey, right_grey : ndarray, uint8, shape (H, W)
        Rectified grey pair (right camera at +baseline along x).
    params : MatcherParams
        Its disparity range and ``sgm_ground_fit`` are used.
    pool : ThreadPoolExecutor, optional
        Helper threads for the first pass.

    Returns
    -------
    GroundEstimate
        Full-size rows and pixels.
    """
    fit = params.sgm_ground_fit
    disp, s = first_pass(left_grey, right_grey, params, fit, pool)
    return fit_ground_line(disp, s, params.min_disparity_px,
                           params.min_disparity_px + params.num_disparities - 1, fit)


def with_pair_ground(params: MatcherParams, left_grey: np.ndarray, right_grey: np.ndarray,
                     pool: ThreadPoolExecutor | None = None) -> MatcherParams:
    """``params`` with SGM's ground from the pair where it has none yet (or, with
    ``sgm_ground`` 'check', where the pair's ground disagrees with the one given).

    For ``aggregation`` 'sgm' with ``sgm_ground_px_per_row`` None and ``sgm_ground``
    'auto', 'pair' or 'check': the pair's ground, or a gradient of 0 (no shear) where
    none is found; explicit ``sgm_ground_horizon_row_px`` / ``sgm_ground_band_px``
    stay. With 'check' and a gradient given (the rig's, ``with_rig_ground``): the
    pair's ground, horizon and band replace it where a ground is found whose line
    leaves the given band of the given line in some row between its horizon and the
    image bottom; otherwise ``params`` are returned as they are.
    """
    if params.aggregation != "sgm" or params.sgm_ground not in ("auto", "pair", "check"):
        return params
    given = params.sgm_ground_px_per_row is not None
    if given and params.sgm_ground != "check":
        return params
    est = estimate_ground(left_grey, right_grey, params, pool)
    if given:
        if not (est.found and _leaves_band(params, est, left_grey.shape[0])):
            return params
        return replace(params, sgm_ground_px_per_row=est.px_per_row,
                       sgm_ground_horizon_row_px=est.horizon_row_px,
                       sgm_ground_band_px=est.band_px)
    if not est.found:
        return replace(params, sgm_ground_px_per_row=0.0)
    return replace(
        params, sgm_ground_px_per_row=est.px_per_row,
        sgm_ground_horizon_row_px=_given(params.sgm_ground_horizon_row_px,
                                         est.horizon_row_px),
        sgm_ground_band_px=_given(params.sgm_ground_band_px, est.band_px))


def _leaves_band(params: MatcherParams, est: GroundEstimate, height_px: int) -> bool:
    """Whether the estimated ground line leaves the given line's band in a row from
    the estimate's horizon to the image's bottom (no band: never)."""
    band = params.sgm_ground_band_px
    if band is None:
        return False
    v = np.arange(max(0, math.ceil(est.horizon_row_px)), height_px, dtype=np.float64)
    given = params.sgm_ground_px_per_row * (v - (params.sgm_ground_horizon_row_px or 0.0))
    found = est.px_per_row * (v - est.horizon_row_px)
    return bool(v.size) and float(np.abs(found - given).max()) > band


def _given(value: float | None, default: float) -> float:
    return default if value is None else value


__all__ = ["GROUND_SOURCES", "GroundEstimate", "GroundFitParams", "estimate_ground",
           "first_pass", "fit_ground_line", "with_pair_ground"]
