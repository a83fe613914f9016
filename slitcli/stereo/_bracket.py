"""Compiled (numba) kernel of the SGM bracket test (slitcli.stereo.sgm).

A pixel that semi-global aggregation matched but whose own neighbourhood does not carry
the match (the support test rejected it: weak texture) is kept when supported pixels
on both sides of it, along its row or along its column and within ``reach`` pixels,
bracket its disparity: ``min(d_a, d_b) - tol <= d <= max(d_a, d_b) + tol``. On a
smooth surface (plain, slanted or not) the aggregated disparity runs between those of
its textured borders; where the aggregation carried a neighbour's disparity across an
edge onto a plain surface (a floor's or a wall's disparity into a plain box, whose
own silhouette matched at the box's disparity) the box's borders do not bracket it.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def bracket_rows(disp, reason, code_valid, weak, reach, tol, span, keep):
    """Set ``keep`` (H, W) bool where a pixel whose code is marked in ``weak`` (bool
    per code) is bracketed along its row or its column by pixels of code
    ``code_valid`` within ``reach`` px.

    ``disp`` (H, W) float32, px; ``reason`` (H, W) uint8 codes. Only ``keep`` is
    written."""
    height, width = disp.shape
    left = np.empty(width, np.float32)
    # column scans: the last valid disparity above (and its row) per column
    up_d = np.full((height, width), np.nan, np.float32)
    last_d = np.full(width, np.nan, np.float32)
    last_y = np.full(width, -(1 << 30), np.int64)
    for y in range(height):
        for x in range(width):
            if reason[y, x] == code_valid:
                last_d[x] = disp[y, x]
                last_y[x] = y
            elif y - last_y[x] <= reach:
                up_d[y, x] = last_d[x]
    last_d[:] = np.nan
    last_y[:] = 1 << 30
    for y in range(height - 1, -1, -1):
        for x in range(width):
            if reason[y, x] == code_valid:
                last_d[x] = disp[y, x]
                last_y[x] = y
                continue
            keep[y, x] = False
            if not weak[reason[y, x]]:
                continue
            d = disp[y, x]
            a = up_d[y, x]
            if last_y[x] - y <= reach and a == a:
                b = last_d[x]
                keep[y, x] = ((d >= min(a, b) - tol) and (d <= max(a, b) + tol)
                              and abs(a - b) <= span)
    for y in range(height):
        ld = np.float32(np.nan)
        lx = -(1 << 30)
        for x in range(width):
            if reason[y, x] == code_valid:
                ld = disp[y, x]
                lx = x
                left[x] = np.nan
            else:
                left[x] = ld if x - lx <= reach else np.nan
        rd = np.float32(np.nan)
        rx = 1 << 30
        for x in range(width - 1, -1, -1):
            if reason[y, x] == code_valid:
                rd = disp[y, x]
                rx = x
                continue
            if not weak[reason[y, x]] or keep[y, x]:
                continue
            a = left[x]
            if rx - x <= reach and a == a:
                d = disp[y, x]
                keep[y, x] = ((d >= min(a, rd) - tol) and (d <= max(a, rd) + tol)
                              and abs(a - rd) <= span)
