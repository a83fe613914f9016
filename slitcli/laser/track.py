"""Compiled (numba) fits along a stripe segment: its gaps and its fading ends.

Conventions as :mod:`slitcli.laser.fit` (transposed images, candidate-table rows).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.fit import (
    AVG_VAR,
    C_AMP,
    C_CHI2,
    C_EDGE,
    C_HVAR,
    C_POS,
    C_SAT,
    C_SE_AMP,
    C_SE_POS,
    C_WIDTH,
    C_Z,
    N_FIELDS,
    N_WORK,
    PIXEL_VAR,
    fit_profile,
)
from slitcli.laser.select import (
    AMP_HALF,
    MAX_CHI2,
    MAX_EDGE,
    MAX_GAP,
    MIN_SIGMA_PX,
    end_level,
    links,
    segment,
)

#: columns of a segment's end whose straight line predicts a track's next row
TRACK_LINE = 12
#: a track goes on while its last TRACK_WINDOW columns together are TRACK_Z
#: significant; a full fit replaces the matched filter's row from TRACK_SINGLE_Z
TRACK_WINDOW = 5
TRACK_Z = 4.0
TRACK_SINGLE_Z = 2.0
#: columns in a row that may fall short of the track's brightness (an abrupt end:
#: a partly covered column, then none)
TRACK_PENDING = 2
#: standard error of a tracked row taken from the prediction (px), and the floor of
#: the rows' standard errors in the line's weights
TRACK_ROW_SE = 0.5
TRACK_MIN_SE = 0.05
#: an end column at least this share as bright as the next three predict counts as
#: whole (the amplitudes' noise): its row is not moved
FULL_SHARE = 0.8


@njit(cache=True, nogil=True)
def fit_at(img: np.ndarray, cols: np.ndarray, rows: np.ndarray, slopes: np.ndarray,
           sigma: float, sigma_avg: float, sat_dn: int, s_max: float, g_map: np.ndarray,
           sheet_m: float, out: np.ndarray) -> None:  # pragma: no cover
    """Fit the profile at given columns and starting rows (a segment's gaps), on each
    column and on the three columns averaged along the stripe's slope (``slopes``,
    rows per column; :func:`~slitcli.laser.fit.fit_profile`);
    the more significant fit goes to ``out[k]`` (N_FIELDS; NaN if neither converges;
    ``C_HVAR`` the sampling variance across columns). Conventions as
    :func:`column_candidates`."""
    ws = np.empty((8, N_WORK))
    res = np.empty(N_FIELDS)
    _fit_at(img, cols, rows, slopes, sigma, sigma_avg, sat_dn, s_max, g_map, sheet_m, ws,
            res, out)


@njit(cache=True, nogil=True)
def _fit_at(img: np.ndarray, cols: np.ndarray, rows: np.ndarray, slopes: np.ndarray,
            sigma: float, sigma_avg: float, sat_dn: int, s_max: float, g_map: np.ndarray,
            sheet_m: float, ws: np.ndarray, res: np.ndarray,
            out: np.ndarray) -> None:  # pragma: no cover
    """:func:`fit_at` with workspaces ``ws`` (8, N_WORK) and ``res`` (N_FIELDS,)."""
    n = img.shape[1]
    for k in range(cols.shape[0]):
        out[k] = np.nan
        i = cols[k]
        c = rows[k]
        s_core = 0.0
        if sheet_m > 0.0:
            gpx = g_map[i, min(max(int(c + 0.5), 0), n - 1)]
            if np.isfinite(gpx):
                s_core = gpx * sheet_m
        sl = slopes[k]
        for averaged in (False, True):
            if fit_profile(img, i, c, 3, sigma_avg if averaged else sigma, sat_dn, s_max,
                           s_core, sl, averaged, False, 0.0, ws, res):
                if not np.isfinite(out[k, C_Z]) or res[C_Z] > out[k, C_Z]:
                    for f in range(N_FIELDS):
                        out[k, f] = res[f]
                    # sampling variance across columns, as slope^2 times it
                    rest = (sl - round(sl)) ** 2 * AVG_VAR if averaged else 0.0
                    out[k, C_HVAR] = PIXEL_VAR + (rest / (sl * sl) if sl != 0.0 else 0.0)


@njit(cache=True, nogil=True)
def track_ends(img: np.ndarray, pick: np.ndarray, keep: np.ndarray, tracked: np.ndarray,
               sigma: float, sigma_avg: float, sat_dn: int, s_max: float, g_map: np.ndarray,
               sheet_m: float, max_jump_px: float, share: float, min_peak_dn: float,
               row_px: float) -> None:  # pragma: no cover
    """Follow kept segments past their ends, column by column, while the stripe is there.

    A stripe is a smooth curve: beyond a segment's end its row is predicted by the
    straight line through the segment's last ``TRACK_LINE`` columns (refitted with
    every column the track takes). At the predicted row the matched filter of the
    expected profile (:func:`~slitcli.laser.fit.fit_profile` with ``fixed``, on the
    column averaged with its neighbours along the slope) measures the stripe's
    amplitude, unbiased where there is none; the track goes on while the last
    ``TRACK_WINDOW`` columns together are at least ``TRACK_Z`` significant
    (inverse-variance weighted mean amplitude over its standard error), so
    significance accumulates along the curve (Eq. 4's continuity) instead of being
    required of each faint column alone. It stops there, at the image border, at
    another kept column, or after ``TRACK_MISS`` columns in a row whose amplitude
    falls short of ``share`` of the track's recent brightness (the median of its last
    three unsaturated columns) by more than two standard errors (a fading stripe dims
    gradually; at an object's edge it ends abruptly); trailing columns less than
    ``TRACK_SINGLE_Z`` significant on their own are let go.

    A column taken gets the full fit (:func:`fit_at`) where that stays within
    ``row_px`` of the prediction and inside the image, is ``TRACK_SINGLE_Z``
    significant, no wider than ``s_max``, not on an edge between two surfaces
    (``MAX_EDGE``) and, unsaturated, a Gaussian (``MAX_CHI2``); otherwise the matched
    filter's amplitude at the predicted row, with that row's standard error taken as
    ``TRACK_ROW_SE``. ``pick`` (W, N_FIELDS), ``keep`` and ``tracked`` (W,) bool are
    updated.
    """
    w = pick.shape[0]
    h = img.shape[1]
    cols = np.empty(1, np.int64)
    rows = np.empty(1)
    slopes = np.empty(1)
    res = np.empty((1, N_FIELDS))
    ws = np.empty((8, N_WORK))
    one = np.empty(N_FIELDS)
    mf = np.empty(N_FIELDS)
    xs = np.empty(TRACK_LINE)  # the track's last columns, rows and row weights,
    vs = np.empty(TRACK_LINE)  # newest first
    vw = np.empty(TRACK_LINE)
    wa = np.zeros(TRACK_WINDOW)  # per column of the window: weight x amplitude, weight
    wi = np.zeros(TRACK_WINDOW)
    taken = np.empty(w, np.int64)
    pend = np.empty((TRACK_PENDING + 1, N_FIELDS))  # columns awaiting a passing one
    pend_x = np.empty(TRACK_PENDING + 1, np.int64)
    ends = np.empty((w, 2), np.int64)
    n_ends = 0
    for u in range(w):
        if not keep[u]:
            continue
        for d in (-1, 1):
            if 0 <= u + d < w and not keep[u + d]:
                ends[n_ends, 0] = u
                ends[n_ends, 1] = d
                n_ends += 1
    for e in range(n_ends):
        u = ends[e, 0]
        d = ends[e, 1]
        if 0 <= u + d < w and keep[u + d]:
            continue  # reached by another track
        # the segment's last columns, inward from its end (across its short gaps)
        n = 0
        n_win = 0
        x = u
        last = u
        while n < TRACK_LINE and 0 <= x < w and abs(x - last) <= MAX_GAP + 1:
            if not keep[x]:
                x -= d
                continue
            dv = pick[x, C_POS] - pick[last, C_POS]
            if n > 0 and not (links(dv, pick[x, C_WIDTH], pick[last, C_WIDTH], max_jump_px)
                              if abs(x - last) == 1 else abs(dv) <= max_jump_px * abs(x - last)):
                break
            last = x
            xs[n] = x
            vs[n] = pick[x, C_POS]
            vw[n] = _row_weight(pick[x, C_SE_POS])
            n += 1
            if n_win < TRACK_WINDOW:
                # newest last: the ring below overwrites the oldest first
                _window_put(wa, wi, TRACK_WINDOW - 1 - n_win, pick[x, C_AMP],
                            pick[x, C_SE_AMP])
                n_win += 1
            x -= d
        for k in range(TRACK_WINDOW - n_win):
            wa[k] = 0.0
            wi[k] = 0.0
        slot = 0  # next window slot to overwrite (the oldest)
        n_taken = 0
        n_pend = 0
        x = u + d
        while 0 <= x < w and not keep[x]:
            pred, slope = _line_at(xs, vs, vw, n, float(x))
            if not (0.0 <= pred <= h - 1.0):
                break
            s_core = 0.0
            if sheet_m > 0.0:
                gpx = g_map[x, min(max(int(pred + 0.5), 0), h - 1)]
                if np.isfinite(gpx):
                    s_core = gpx * sheet_m
            clipped = keep[x - d] and pick[x - d, C_SAT] > 0.0 and \
                _clipped_to_border(img, x, pred, sat_dn)
            if clipped:
                # a clipped core running off the image (:func:`fit_profile` gives no
                # fit: neither its plateau nor one flank pins the centre down): the
                # stripe is there, its row continues the segment's line
                for f in range(N_FIELDS):
                    mf[f] = pick[x - d, f]
                mf[C_POS] = pred
            elif not fit_profile(img, x, pred, 3, sigma_avg, sat_dn, s_max, s_core, slope,
                                 True, True, 0.0, ws, mf):
                break
            _window_put(wa, wi, slot, mf[C_AMP], mf[C_SE_AMP])
            slot = (slot + 1) % TRACK_WINDOW
            if _window_z(wa, wi) < TRACK_Z:
                break
            # the column alone (an average reaches into the neighbours, and at an
            # object's end into the stripe beside it) must show the stripe over at
            # least ``share`` of its width (of the window's mean brightness); up to
            # TRACK_PENDING columns in a row may fall short (noise), the next one that
            # does not vouches for them
            passed = clipped or (fit_profile(
                img, x, pred, 3, sigma, sat_dn, s_max, s_core, slope, False, True, 0.0, ws,
                one) and (one[C_SAT] > 0.0 or
                          one[C_AMP] >= share * max(_window_mean(wa, wi), min_peak_dn)))
            r = pend[n_pend]
            for f in range(N_FIELDS):
                r[f] = mf[f]
            if not clipped:
                cols[0] = x
                rows[0] = pred
                slopes[0] = slope
                _fit_at(img, cols, rows, slopes, sigma, sigma_avg, sat_dn, s_max, g_map,
                        sheet_m, ws, one, res)
                q = res[0]
                if abs(q[C_POS] - pred) <= row_px and 0.0 <= q[C_POS] <= h - 1.0 and \
                        q[C_Z] >= TRACK_SINGLE_Z and MIN_SIGMA_PX <= q[C_WIDTH] <= s_max and \
                        q[C_EDGE] <= MAX_EDGE and (q[C_SAT] > 0.0 or q[C_CHI2] <= MAX_CHI2):
                    for f in range(N_FIELDS):
                        r[f] = q[f]
                else:
                    r[C_SE_POS] = TRACK_ROW_SE
                    r[C_HVAR] = PIXEL_VAR
                    # only a column whose own fit finds the stripe vouches for
                    # columns that fell short before it
                    passed = passed and n_pend == 0
            pend_x[n_pend] = x
            n_pend += 1
            x += d
            if not passed:
                if n_pend > TRACK_PENDING:
                    break
                continue
            for p in range(n_pend):
                xp = pend_x[p]
                r = pend[p]
                for f in range(N_FIELDS):
                    pick[xp, f] = r[f]
                keep[xp] = True
                tracked[xp] = True
                taken[n_taken] = xp
                n_taken += 1
                for k in range(min(n, TRACK_LINE - 1), 0, -1):
                    xs[k] = xs[k - 1]
                    vs[k] = vs[k - 1]
                    vw[k] = vw[k - 1]
                xs[0] = xp
                vs[0] = r[C_POS]
                vw[0] = _row_weight(r[C_SE_POS])
                n = min(n + 1, TRACK_LINE)
            n_pend = 0
        # the track's trailing samples that are not significant on their own are
        # as likely noise next to the stripe's end
        for k in range(n_taken - 1, -1, -1):
            x = taken[k]
            if pick[x, C_Z] >= TRACK_SINGLE_Z:
                break
            keep[x] = False
            tracked[x] = False


@njit(cache=True, nogil=True)
def _window_put(wa: np.ndarray, wi: np.ndarray, k: int, amp: float,
                se: float) -> None:  # pragma: no cover
    """Put an amplitude of standard error ``se`` into slot ``k`` of the track's
    window: its inverse variance and that times the amplitude."""
    ok = np.isfinite(se) and se > 0.0 and np.isfinite(amp)
    wi[k] = 1.0 / (se * se) if ok else 0.0
    wa[k] = wi[k] * amp if ok else 0.0


@njit(cache=True, nogil=True)
def _window_mean(wa: np.ndarray, wi: np.ndarray) -> float:  # pragma: no cover
    """The window's inverse-variance weighted mean amplitude."""
    sa = 0.0
    si = 0.0
    for k in range(wa.shape[0]):
        sa += wa[k]
        si += wi[k]
    return sa / si if si > 0.0 else 0.0


@njit(cache=True, nogil=True)
def _window_z(wa: np.ndarray, wi: np.ndarray) -> float:  # pragma: no cover
    """Significance of the window's weighted mean amplitude."""
    sa = 0.0
    si = 0.0
    for k in range(wa.shape[0]):
        sa += wa[k]
        si += wi[k]
    return sa / math.sqrt(si) if si > 0.0 else 0.0


@njit(cache=True, nogil=True)
def _clipped_to_border(img: np.ndarray, i: int, row: float,
                       sat_dn: int) -> bool:  # pragma: no cover
    """Column ``i``'s red is clipped from row ``row`` to the nearer image border."""
    h = img.shape[1]
    c = min(max(int(row + 0.5), 0), h - 1)
    a, b = (c, h) if 2 * c >= h else (0, c + 1)
    for j in range(a, b):
        if img[i, j, 2] < sat_dn:
            return False
    return True


@njit(cache=True, nogil=True)
def _row_weight(se: float) -> float:  # pragma: no cover
    """Weight of a row of standard error ``se`` (px) in the track's line."""
    e = max(se, TRACK_MIN_SE) if np.isfinite(se) else TRACK_ROW_SE
    return 1.0 / (e * e)


@njit(cache=True, nogil=True)
def _line_at(xs: np.ndarray, vs: np.ndarray, ws: np.ndarray, n: int,
             x: float) -> tuple[float, float]:  # pragma: no cover
    """Value at ``x`` and slope of the weighted least-squares line through
    ``(xs, vs)[:n]`` (weights ``ws``; a constant for one point)."""
    sw = 0.0
    mx = 0.0
    mv = 0.0
    for k in range(n):
        sw += ws[k]
        mx += ws[k] * xs[k]
        mv += ws[k] * vs[k]
    mx /= sw
    mv /= sw
    sxx = 0.0
    sxv = 0.0
    for k in range(n):
        sxx += ws[k] * (xs[k] - mx) ** 2
        sxv += ws[k] * (xs[k] - mx) * (vs[k] - mv)
    slope = sxv / sxx if sxx > 0.0 else 0.0
    return mv + slope * (x - mx), slope


@njit(cache=True, nogil=True)
def drop_faint_tracked(v: np.ndarray, width: np.ndarray, amp: np.ndarray, sat: np.ndarray,
                       keep: np.ndarray, tracked: np.ndarray, max_jump_px: float,
                       min_peak_dn: float) -> None:  # pragma: no cover
    """The visibility test of :func:`slitcli.laser.select.keep_segments` for tracked
    columns: the running median of the amplitude over ``AMP_HALF`` found columns either
    side along the segment (clipped cores count as bright) must reach ``min_peak_dn``.
    A track at a segment's end is cut after its outermost passing column; tracked
    columns inside a segment go where they fail. ``keep`` and ``tracked`` are
    updated."""
    n = v.shape[0]
    idx = np.empty(n, np.int64)
    ok = np.empty(n, np.bool_)
    win = np.empty(2 * AMP_HALF + 1)
    u = 0
    while u < n:
        if not keep[u]:
            u += 1
            continue
        cnt = segment(v, width, keep, u, max_jump_px, idx)
        last = idx[cnt - 1]
        for k in range(cnt):
            ok[k] = True
            if not tracked[idx[k]]:
                continue
            m = 0
            for y in range(max(0, k - AMP_HALF), min(cnt, k + AMP_HALF + 1)):
                win[m] = 255.0 if sat[idx[y]] else amp[idx[y]]
                m += 1
            ok[k] = np.median(win[:m]) >= min_peak_dn
        # a track's tail ends at its outermost passing column (a fading stripe
        # stays faint beyond it; noise dips inside it do not end it); a track
        # between two stretches of the segment loses its failing columns
        a = 0
        while a < cnt and tracked[idx[a]]:
            a += 1
        b = cnt
        while b > a and tracked[idx[b - 1]]:
            b -= 1
        lo = a
        for k in range(a):
            if ok[k]:
                lo = k
                break
        hi = b
        for k in range(cnt - 1, b - 1, -1):
            if ok[k]:
                hi = k + 1
                break
        for k in range(cnt):
            if k < lo or k >= hi or (a <= k < b and tracked[idx[k]] and not ok[k]):
                keep[idx[k]] = False
                tracked[idx[k]] = False
        u = last + 1


@njit(cache=True, nogil=True)
def shift_end_rows(v: np.ndarray, amp: np.ndarray, sat: np.ndarray, keep: np.ndarray,
                   out: np.ndarray) -> None:  # pragma: no cover
    """Move the row of a partly covered end column to the column's centre.

    The object covers only the inner part of a segment's end column (share ``c``, at
    least one half: its centre ray meets the object), so the stripe's light there is
    centred ``(1 - c) / 2`` columns inward of the column's centre; along a steep
    stripe (slope ``s`` rows per column from the next two columns) the row at the
    centre lies ``s (1 - c) / 2`` further along. ``c`` is the end column's
    brightness over what the next three predict (:func:`end_level`), at least 0.5;
    from ``FULL_SHARE`` on the column counts as whole (amplitude noise).
    ``out`` (the smoothed rows) is updated at the ends of runs of at least four kept
    columns (unsaturated)."""
    n = v.shape[0]
    for u in range(n):
        if not keep[u] or sat[u]:
            continue
        for d in (-1, 1):
            x1, x2, x3 = u - d, u - 2 * d, u - 3 * d
            if not (0 <= x3 < n) or (0 <= u + d < n and keep[u + d]):
                continue
            if not (keep[x1] and keep[x2] and keep[x3]):
                continue
            level = end_level(amp[x1], amp[x2], amp[x3])
            if not (level > 0.0):
                continue
            c = max(amp[u] / level, 0.5)
            if c >= FULL_SHARE:
                continue  # as bright as a whole column, within the amplitudes' noise
            slope = v[x1] - v[x2]
            out[u] += slope * 0.5 * (1.0 - c)
