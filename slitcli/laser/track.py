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
    C_HVAR,
    C_POS,
    C_WIDTH,
    C_Z,
    N_FIELDS,
    N_WORK,
    PIXEL_VAR,
    fit_profile,
)

AVG_MAX_SLOPE = 0.5  # steeper stripes (rows per column) are not averaged across columns

@njit(cache=True, nogil=True)
def fit_at(img: np.ndarray, cols: np.ndarray, rows: np.ndarray, slopes: np.ndarray,
           sigma: float, sigma_avg: float, sat_dn: int, s_max: float, g_map: np.ndarray,
           sheet_m: float, out: np.ndarray) -> None:  # pragma: no cover
    """Fit the profile at given columns and starting rows (a segment's gaps), on each
    column and, where the stripe's slope (``slopes``, rows per column) is at most
    ``AVG_MAX_SLOPE`` (steeper, averaging smears it), on the three columns averaged;
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
        for averaged in (False, True):
            if averaged and abs(slopes[k]) > AVG_MAX_SLOPE:
                continue
            if fit_profile(img, i, c, 3, sigma_avg if averaged else sigma, sat_dn, s_max,
                           s_core, slopes[k], averaged, ws, res):
                if not np.isfinite(out[k, C_Z]) or res[C_Z] > out[k, C_Z]:
                    for f in range(N_FIELDS):
                        out[k, f] = res[f]
                    out[k, C_HVAR] = PIXEL_VAR + (AVG_VAR if averaged else 0.0)


@njit(cache=True, nogil=True)
def extend_ends(img: np.ndarray, pick: np.ndarray, keep: np.ndarray, sigma: float,
                sigma_avg: float, sat_dn: int, s_max: float, g_map: np.ndarray,
                sheet_m: float, max_jump_px: float, z_min: float, min_peak_dn: float,
                share: float, n_max: int, row_px: float) -> None:  # pragma: no cover
    """Carry kept segments on past their ends where the stripe fades (up to ``n_max``
    columns each way): at the row extrapolated along the segment's last three
    columns a fit (:func:`fit_at`) within ``row_px`` of it, of significance
    ``z_min``, amplitude ``min_peak_dn`` and at least ``share`` of the previous
    column's (a fade is gradual, an object's edge abrupt), extends the segment; the
    first failure stops it. ``pick`` (W, N_FIELDS) and ``keep`` (W,) are updated."""
    w = pick.shape[0]
    cols = np.empty(1, np.int64)
    rows = np.empty(1)
    slopes = np.empty(1)
    res = np.empty((1, N_FIELDS))
    ws = np.empty((8, N_WORK))
    one = np.empty(N_FIELDS)
    for u in range(w):
        if not keep[u]:
            continue
        for d in (-1, 1):
            if 0 <= u + d < w and keep[u + d]:
                continue
            # slope from up to three kept columns behind the end, on the same segment
            slope = 0.0
            nb = 0
            for b in range(1, 4):
                x = u - d * b
                if not (0 <= x < w) or not keep[x]:
                    break
                # one stripe: a small step, or along a steep one (see select.links)
                dv = abs(pick[x, C_POS] - pick[x + d, C_POS])
                if dv > max_jump_px and \
                        dv > math.sqrt(3.0) * (pick[x, C_WIDTH] + pick[x + d, C_WIDTH]):
                    break
                nb = b
            if nb > 0:
                slope = (pick[u, C_POS] - pick[u - d * nb, C_POS]) / nb
            for step in range(1, n_max + 1):
                x = u + d * step
                if not (0 <= x < w) or keep[x]:
                    break
                cols[0] = x
                rows[0] = pick[u, C_POS] + slope * step
                if not (0.0 <= rows[0] <= img.shape[1] - 1.0):
                    break
                slopes[0] = slope
                _fit_at(img, cols, rows, slopes, sigma, sigma_avg, sat_dn, s_max, g_map,
                        sheet_m, ws, one, res)
                prev = pick[x - d, C_AMP]
                if not (abs(res[0, C_POS] - rows[0]) <= row_px and res[0, C_Z] >= z_min
                        and res[0, C_AMP] >= max(min_peak_dn, share * prev)
                        and res[0, C_WIDTH] <= s_max):
                    break
                for f in range(N_FIELDS):
                    pick[x, f] = res[0, f]
                keep[x] = True
