"""The stages after the candidate fits as one compiled call (paper Eq. 4 and segments).

:func:`slitcli.laser.extract.extract_stripe` used to call each of these kernels from
Python and join them with numpy (the chosen candidates gathered by fancy indexing,
boolean columns recomputed, the gap fits accepted by masks): a dozen dispatches and
array temporaries, about 0.1 ms per 320 x 240 frame. :func:`finish_stripe` runs the
same kernels in the same order on the same values, so its output is bit-identical
(docs/laser.md, "Speed").
"""

from __future__ import annotations

import numpy as np
from numba import njit

from slitcli.laser import select, track
from slitcli.laser.fit import C_AMP, C_CHI2, C_POS, C_SAT, C_SE_POS, C_WIDTH, C_Z


@njit(cache=True, nogil=True)
def first_search_row(mask_t: np.ndarray) -> int:  # pragma: no cover
    """The first image row with a search pixel in any column (``mask_t`` (W, H) bool,
    the transposed search mask); -1 where there is none."""
    w, h = mask_t.shape
    first = h
    for u in range(w):
        # an OR over the rows above the best so far (no early exit: vectorised) tells
        # whether this column can lower it; the masks' first rows are far down
        hit = False
        for v in range(first):
            hit |= mask_t[u, v]
        if hit:
            for v in range(first):
                if mask_t[u, v]:
                    first = v
                    break
    return first if first < h else -1


@njit(cache=True, nogil=True)
def finish_stripe(img_t: np.ndarray, cand: np.ndarray, cand_avg: np.ndarray,
                  prev: np.ndarray, g_map: np.ndarray, g_map_t: np.ndarray, sheet_m: float,
                  sigma: float, sigma_avg: float, sat_dn: int, max_width_px: float,
                  s_max: float, beta: float, gamma: float, continuity_px: float,
                  max_jump_px: float, z_strong: float, z_weak: float,
                  min_segment_cols: int, min_peak_dn: float, r0: int, v_px: np.ndarray,
                  strength: np.ndarray, saturated: np.ndarray) -> None:  # pragma: no cover
    """Eq. 4, segments, tracking, gap fits and row smoothing of one frame.

    Parameters
    ----------
    img_t : ndarray, shape (W, h, 3), uint8
        The image from row ``r0`` on, transposed (columns contiguous).
    cand, cand_avg : ndarray, shape (W, K, N_FIELDS)
        The candidate stage's fits on the columns and on the averaged columns.
    prev : ndarray, shape (0,) or (W,)
        The previous frame's rows less ``r0`` (NaN none).
    g_map, g_map_t : ndarray, shape (h, W) and its transpose
        Rows per metre of height (:class:`~slitcli.laser.frame.LaserGeometry`), or
        a (1, 1) NaN array when ``sheet_m`` is 0.
    sheet_m, sigma, sigma_avg, sat_dn, max_width_px, s_max, beta, gamma, continuity_px,
    max_jump_px, z_strong, z_weak, min_segment_cols, min_peak_dn
        As passed to :func:`slitcli.laser.select.choose`,
        :func:`~slitcli.laser.select.keep_segments` and
        :func:`slitcli.laser.track.track_ends` (``s_max`` the widest fitted sigma).
    r0 : int
        The image row of ``img_t``'s first row.
    v_px, strength, saturated : ndarray, shape (W,)
        Outputs: the smoothed stripe row in image rows (NaN none), the fitted peak
        (NaN none) and whether the kept column's core is clipped.
    """
    w = cand.shape[0]
    merged = select.merge_sources(cand, cand_avg, z_strong)
    chosen = np.empty(w, np.int64)
    extended = np.empty(w, np.bool_)
    select.choose(merged, prev, g_map, sheet_m, sigma, max_width_px, beta, gamma,
                  continuity_px, max_jump_px, z_strong, z_weak, img_t.shape[1], chosen,
                  extended)
    pick = np.empty((w, merged.shape[2]))
    for u in range(w):
        if chosen[u] >= 0:
            pick[u] = merged[u, chosen[u]]
        else:
            pick[u] = np.nan
    v = pick[:, C_POS]
    keep = np.empty(w, np.bool_)
    select.keep_segments(v, pick[:, C_WIDTH], pick[:, C_AMP], pick[:, C_Z], pick[:, C_CHI2],
                         pick[:, C_SAT] > 0, extended, max_jump_px, min_segment_cols,
                         min_peak_dn, z_strong, keep)
    # fading segments followed on, the faint columns judged, the ends pruned (as in
    # extract_stripe's description, step 5); tracking may rewrite ``pick``, the two
    # tests after it do not
    tracked = np.zeros(w, np.bool_)
    track.track_ends(img_t, pick, keep, tracked, sigma, sigma_avg, sat_dn, s_max, g_map_t,
                     sheet_m, max_jump_px, select.END_SHARE, min_peak_dn, select.GAP_PX)
    sat = pick[:, C_SAT] > 0
    track.drop_faint_tracked(v, pick[:, C_WIDTH], pick[:, C_AMP], sat, keep, tracked,
                             max_jump_px, min_peak_dn)
    select.prune_ends(v, pick[:, C_WIDTH], pick[:, C_AMP], sat, keep, max_jump_px,
                      min_peak_dn)
    # single columns lost inside a segment: a fit at the interpolated row confirms them
    gap_cols = np.empty(w, np.int64)
    gap_rows = np.empty(w)
    gap_slopes = np.empty(w)
    n_gap = select.gap_rows(v, keep, max_jump_px, gap_cols, gap_rows, gap_slopes)
    if n_gap:
        fits = np.empty((n_gap, pick.shape[1]))
        track.fit_at(img_t, gap_cols[:n_gap], gap_rows[:n_gap], gap_slopes[:n_gap], sigma,
                     sigma_avg, sat_dn, s_max, g_map_t, sheet_m, fits)
        for j in range(n_gap):
            if abs(fits[j, C_POS] - gap_rows[j]) <= select.GAP_PX and \
                    fits[j, C_Z] >= select.SUPPORT_Z and fits[j, C_WIDTH] <= s_max:
                pick[gap_cols[j]] = fits[j]
                keep[gap_cols[j]] = True
    sat = pick[:, C_SAT] > 0
    select.smooth_rows(v, pick[:, C_SE_POS], pick[:, C_WIDTH], keep, max_jump_px, v_px)
    track.shift_end_rows(v, pick[:, C_AMP], sat, keep, v_px)
    for u in range(w):
        v_px[u] += r0
        strength[u] = pick[u, C_AMP] if keep[u] else np.nan
        saturated[u] = keep[u] and sat[u]
