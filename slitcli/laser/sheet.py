"""The laser sheet's thickness as image columns show it (numba): the thickness a fitted
stripe width implies on an upright surface, and the frame's own thickness from its
clean, strong candidates (which replaces ``LaserParams.sheet_sigma_mm`` when many
agree)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.candidates import MAX_EDGE
from slitcli.laser.fit import C_CHI2, C_CLUT, C_EDGE, C_POS, C_SAT, C_WIDTH, C_Z, PIXEL_VAR

#: narrowest plausible Gaussian sigma of a stripe across a column, px
MIN_SIGMA_PX = 0.4
#: a Gaussian's equivalent width (sum / peak) in sigmas, rounded: sigma <= max_width / 2.5
EQ_WIDTH = 2.5
#: the frame's own sheet thickness: candidates at least MODE_Z significant with a
#: reduced chi-square of at most MODE_CHI2 vote; the densest window of relative
#: half-width MODE_WINDOW wins when it holds MODE_SUPPORT of them and half of all
MODE_Z = 12.0
MODE_CHI2 = 3.0
MODE_WINDOW = 0.12
MODE_SUPPORT = 16


@njit(cache=True, nogil=True)
def sheet_sigma_m(width_px: float, slope: float, hvar_px2: float,
                  g_px_per_m: float) -> float:  # pragma: no cover
    """Laser-sheet thickness (Gaussian sigma, metres) implied by a fitted stripe width.

    Across one column the profile is the sheet's thickness seen on an upright surface,
    ``g_px_per_m`` pixels per metre of height there, widened by the pixel's extent
    (``PIXEL_VAR``) and, along a stripe of slope ``dv/du``, by ``slope^2`` times the
    variance of the sampling across columns (``hvar_px2``).
    """
    core = width_px * width_px - PIXEL_VAR - slope * slope * hvar_px2
    return math.sqrt(max(core, 0.04)) / g_px_per_m


@njit(cache=True, nogil=True)
def sheet_mode(cand: np.ndarray, g_map: np.ndarray,
               max_width_px: float) -> tuple[float, int, int]:  # pragma: no cover
    """The laser sheet's thickness as the frame shows it (metres), and its support.

    Clean, strong candidates (significance ``MODE_Z``, reduced chi-square at most
    ``MODE_CHI2``, no clutter or edge, unsaturated, with a neighbouring column's
    candidate within a row) imply a thickness each
    (:func:`sheet_sigma_m`, slope 0); all the stripe's columns share one, texture
    spreads. Returns the centre of the densest window of relative half-width
    ``MODE_WINDOW``, how many fall in it and how many voted. ``g_map`` is (W, H),
    rows per metre."""
    w_cols, k = cand.shape[0], cand.shape[1]
    h = g_map.shape[1]
    vals = np.empty(w_cols * k)
    n = 0
    for u in range(w_cols):
        for q in range(k):
            if not np.isfinite(cand[u, q, C_POS]) or cand[u, q, C_SAT] > 0:
                continue
            if cand[u, q, C_Z] < MODE_Z or cand[u, q, C_CHI2] > MODE_CHI2 or \
                    cand[u, q, C_CLUT] > 0.0 or cand[u, q, C_EDGE] > 0.5 * MAX_EDGE:
                continue
            w = cand[u, q, C_WIDTH]
            if w < MIN_SIGMA_PX or w > max_width_px / EQ_WIDTH:
                continue
            # a flat stretch (a neighbour within a row): on a steep one the pixel's
            # width adds slope-dependent spread
            flat = False
            for d in (-1, 1):
                if 0 <= u + d < w_cols:
                    for r in range(k):
                        if abs(cand[u + d, r, C_POS] - cand[u, q, C_POS]) <= 1.0:
                            flat = True
            if not flat:
                continue
            row = min(max(int(cand[u, q, C_POS] + 0.5), 0), h - 1)
            g = g_map[u, row]
            if np.isfinite(g) and g > 0.0:
                vals[n] = math.log(sheet_sigma_m(w, 0.0, PIXEL_VAR, g))
                n += 1
    if n == 0:
        return 0.0, 0, 0
    x = np.sort(vals[:n])
    half = math.log(1.0 + MODE_WINDOW)
    best = 0
    best_c = x[0]
    b = 0
    for a in range(n):
        while b < n and x[b] - x[a] <= 2.0 * half:
            b += 1
        if b - a > best:
            best = b - a
            best_c = x[(a + b - 1) // 2]
    return math.exp(best_c), best, n
