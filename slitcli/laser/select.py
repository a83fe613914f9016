"""Compiled (numba) choice of one stripe crossing per column (paper Eq. 4) and segments.

Input: the fitted candidates of every column from :func:`slitcli.laser.kernels.
line_candidates`, an array ``(W, K, N_FIELDS)``. Output: per column the chosen
row, amplitude and saturation flag, NaN where the column has no stripe.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.kernels import C_AMP, C_CHI2, C_CLUT, C_POS, C_SAT, C_WIDTH, C_Z

#: narrowest plausible Gaussian sigma of a stripe across a column, px
MIN_SIGMA_PX = 0.4
#: sigma of a stripe is at most max_width_px / EQ_WIDTH (equivalent width of a Gaussian)
EQ_WIDTH = 2.5
#: reduced chi-square above which an unsaturated candidate is not a Gaussian stripe
MAX_CHI2 = 8.0
#: variance a pixel's width adds to the profile across a column, px^2 (the renderer's
#: 3 x 3 supersampling; exact pixel integration gives 1/12)
PIXEL_VAR = 2.0 / 27.0
#: a stripe's sheet thickness may differ from the expected by this factor
SHEET_TOLERANCE = 1.6


@njit(cache=True, nogil=True)
def sheet_sigma_m(width_px: float, slope: float, g_px_per_m: float) -> float:  # pragma: no cover
    """Laser-sheet thickness (Gaussian sigma, metres) implied by a fitted stripe width.

    Across one column the stripe's profile is the sheet's thickness seen on an upright
    surface, ``g_px_per_m`` pixels per metre of height there, widened by the pixel's
    own extent (``PIXEL_VAR``, and along a stripe of slope ``dv/du`` also by
    ``slope^2 PIXEL_VAR``).
    """
    core = width_px * width_px - PIXEL_VAR * (1.0 + slope * slope)
    return math.sqrt(max(core, 0.04)) / g_px_per_m


@njit(cache=True, nogil=True)
def _valid(cand: np.ndarray, u: int, q: int, sigma: float, max_width_px: float,
           z_weak: float, zc_min: float) -> bool:  # pragma: no cover
    pos = cand[u, q, C_POS]
    if not np.isfinite(pos):
        return False
    w = cand[u, q, C_WIDTH]
    if w < MIN_SIGMA_PX or w > max_width_px / EQ_WIDTH:
        return False
    if cand[u, q, C_Z] < z_weak:
        return False
    if cand[u, q, C_SAT] > 0:
        return True
    if cand[u, q, C_CHI2] > MAX_CHI2:
        return False
    clut = cand[u, q, C_CLUT]
    if np.isfinite(clut):
        if cand[u, q, C_AMP] < zc_min * math.sqrt(clut * clut + sigma * sigma):
            return False
    return True


@njit(cache=True, nogil=True)
def _closeness(v: float, ref: float, scale: float) -> float:  # pragma: no cover
    if not np.isfinite(ref):
        return 0.0
    d = (v - ref) / scale
    return math.exp(-0.5 * d * d)


@njit(cache=True, nogil=True)
def _links(dv: float, w_a: float, w_b: float, max_jump_px: float) -> bool:  # pragma: no cover
    """Rows of neighbouring columns that belong to one stripe: a step of at most
    ``max_jump_px``, or on a steep stripe (the profile across a column widens to
    ``slope / sqrt(12)``) of at most ``sqrt(3)`` times the sum of their widths."""
    dv = abs(dv)
    return dv <= max_jump_px or dv <= math.sqrt(3.0) * (w_a + w_b)


@njit(cache=True, nogil=True)
def choose(cand: np.ndarray, prev_v: np.ndarray, g_map: np.ndarray, expected_sheet_m: float,
           sigma: float, max_width_px: float, beta: float, gamma: float,
           continuity_px: float, max_jump_px: float, z_strong: float, z_weak: float,
           zc_min: float, chosen: np.ndarray) -> None:  # pragma: no cover
    """Eq. 4: per column the candidate of best ``red_peak + beta f(y) + gamma g(I)``.

    ``red_peak``: amplitude over the column's largest valid amplitude (1 for the
    strongest); ``g(I) = 1 - sigma_fit / (max_width_px / EQ_WIDTH)`` clipped to
    [0, 1]; ``f(y)``: mean agreement ``exp(-dv^2 / (2 continuity_px^2))`` with the
    rows chosen among the strong candidates (``z >= z_strong``) of columns u-2, u-1,
    u+1, u+2 in a first pass, averaged with the agreement with ``prev_v`` (the
    previous frame) where that is finite. A weak candidate (``z_weak <= z <
    z_strong``) is eligible only when a neighbouring first-pass row agrees with it
    within ``continuity_px``. In the second pass a candidate must also imply a sheet
    thickness (:func:`sheet_sigma_m`, the slope taken from the first-pass rows it
    links to) within ``SHEET_TOLERANCE`` of ``expected_sheet_m`` (0: no test).
    ``chosen[u]`` gets the candidate index or -1.
    """
    w_cols, k = cand.shape[0], cand.shape[1]
    h = g_map.shape[0]
    first = np.full(w_cols, np.nan)
    first_w = np.full(w_cols, np.nan)
    has_prev = prev_v.shape[0] == w_cols
    for u in range(w_cols):
        amax = 0.0
        for q in range(k):
            if _valid(cand, u, q, sigma, max_width_px, z_weak, zc_min):
                amax = max(amax, cand[u, q, C_AMP])
        best = -1e300
        for q in range(k):
            if not _valid(cand, u, q, sigma, max_width_px, z_weak, zc_min):
                continue
            if cand[u, q, C_Z] < z_strong:
                continue
            sc = cand[u, q, C_AMP] / amax + gamma * max(
                0.0, 1.0 - cand[u, q, C_WIDTH] * EQ_WIDTH / max_width_px)
            if has_prev:
                sc += beta * _closeness(cand[u, q, C_POS], prev_v[u], continuity_px)
            if sc > best:
                best = sc
                first[u] = cand[u, q, C_POS]
                first_w[u] = cand[u, q, C_WIDTH]
    ok = np.zeros(k, np.bool_)
    for u in range(w_cols):
        chosen[u] = -1
        amax = 0.0
        for q in range(k):
            ok[q] = _valid(cand, u, q, sigma, max_width_px, z_weak, zc_min)
            if ok[q] and expected_sheet_m > 0.0:
                v = cand[u, q, C_POS]
                w = cand[u, q, C_WIDTH]
                slope = 0.0
                n_sl = 0
                if u > 0 and np.isfinite(first[u - 1]) and \
                        _links(v - first[u - 1], w, first_w[u - 1], max_jump_px):
                    slope += v - first[u - 1]
                    n_sl += 1
                if u + 1 < w_cols and np.isfinite(first[u + 1]) and \
                        _links(first[u + 1] - v, w, first_w[u + 1], max_jump_px):
                    slope += first[u + 1] - v
                    n_sl += 1
                if n_sl > 0:
                    slope /= n_sl
                row = min(max(int(v + 0.5), 0), h - 1)
                t = sheet_sigma_m(w, slope, g_map[row, u])
                ok[q] = expected_sheet_m / SHEET_TOLERANCE <= t <= \
                    expected_sheet_m * SHEET_TOLERANCE
            if ok[q]:
                amax = max(amax, cand[u, q, C_AMP])
        best = -1e300
        for q in range(k):
            if not ok[q]:
                continue
            v = cand[u, q, C_POS]
            f_nbr = 0.0
            near = False
            for d in (-2, -1, 1, 2):
                if 0 <= u + d < w_cols:
                    c = _closeness(v, first[u + d], continuity_px)
                    f_nbr += c
                    near = near or c > math.exp(-0.5)
            f = f_nbr / 4.0
            if has_prev and np.isfinite(prev_v[u]):
                f = 0.5 * (f + _closeness(v, prev_v[u], continuity_px))
            if cand[u, q, C_Z] < z_strong and not near:
                continue
            sc = cand[u, q, C_AMP] / amax + beta * f + gamma * max(
                0.0, 1.0 - cand[u, q, C_WIDTH] * EQ_WIDTH / max_width_px)
            if sc > best:
                best = sc
                chosen[u] = q


@njit(cache=True, nogil=True)
def segments(v: np.ndarray, width: np.ndarray, max_jump_px: float,
             seg: np.ndarray) -> int:  # pragma: no cover
    """Label runs of found columns (``seg``, -1 where none); returns their number.

    Neighbouring columns join when their rows link (:func:`_links`).
    """
    n = 0
    for u in range(v.shape[0]):
        if not np.isfinite(v[u]):
            seg[u] = -1
            continue
        if u > 0 and seg[u - 1] >= 0:
            if _links(v[u] - v[u - 1], width[u], width[u - 1], max_jump_px):
                seg[u] = seg[u - 1]
                continue
        seg[u] = n
        n += 1
    return n
