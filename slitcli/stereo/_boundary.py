"""Compiled (numba) tests of the Eq. 10 matcher at depth edges (slitcli.stereo.matcher).

A (2m+1) x (2n+1) correlation window that straddles a depth edge is matched by
whichever surface carries the stronger texture, so that surface's disparity is
carried up to half a window past its silhouette ("foreground fattening"): the
pixels just beside an object get the object's range. These kernels re-examine the
matches with evidence that does not straddle the edge:

:func:`support_rows` applies the local-support threshold and then

- one-sided support: a pixel next to a weakly supported pixel (a textureless or
  wrongly matched neighbour) must also be supported by the (2r+1)-wide, window-tall
  block centred one column towards that neighbour. A textureless pixel that borrowed
  its disparity from texture on its other side has nothing there to correlate.
- :func:`depth_edge_rows`, a two-hypothesis test on the pixel's own column. Where a
  valid neighbour within ``radius`` columns lies at a smaller disparity (a depth
  step), the grey-level column of the pixel (window-tall, one pixel wide, so it
  cannot straddle a vertical edge) is compared with the right image at the pixel's
  disparity and at the neighbour's; if the neighbour's explains it with less than
  ``ratio`` of the residual, the pixel belongs to the farther surface and is
  invalid. The same test runs for the right image's pixel the match lands on, with
  the disparities of the right view's own neighbours (confirmed by the left view):
  a pixel hidden from the right camera (the band beside an object's left edge)
  takes the object's disparity when its window reaches the object, and its partner
  in the right image is then better explained by the farther surface.

Both kernels release the GIL and work on a band of rows (``y0 .. y1 - 1``) so bands can
run on plain threads; each row's result depends only on read-only inputs.
"""

from __future__ import annotations

import numba as nb
import numpy as np

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
REASON_SUPPORT = 7
REASON_BOUNDARY = 8


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _column_residual_left(gl, gr, y, x, d, hh):
    """Mean squared difference, over rows y-hh..y+hh, between left column x and the
    right image at x - d (linear in x); +inf where x - d leaves the image."""
    height, width = gl.shape
    xr = np.float32(x) - d
    if not (xr >= 0.0 and xr <= width - 1):
        return np.float32(np.inf)
    x0 = min(int(xr), width - 2)
    t = xr - np.float32(x0)
    s = np.float32(0.0)
    y0 = max(0, y - hh)
    y1 = min(height, y + hh + 1)
    for yy in range(y0, y1):
        v = gl[yy, x] - ((np.float32(1.0) - t) * gr[yy, x0] + t * gr[yy, x0 + 1])
        s += v * v
    return s / np.float32(y1 - y0)


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _column_residual_right(gl, gr, y, xr, d, hh):
    """As :func:`_column_residual_left` for right column xr against the left image at
    xr + d."""
    height, width = gl.shape
    xl = np.float32(xr) + d
    if not (xl >= 0.0 and xl <= width - 1):
        return np.float32(np.inf)
    x0 = min(int(xl), width - 2)
    t = xl - np.float32(x0)
    s = np.float32(0.0)
    y0 = max(0, y - hh)
    y1 = min(height, y + hh + 1)
    for yy in range(y0, y1):
        v = (np.float32(1.0) - t) * gl[yy, x0] + t * gl[yy, x0 + 1] - gr[yy, xr]
        s += v * v
    return s / np.float32(y1 - y0)


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _zncc_block(gl, gr, y, xc, d, rx, ry):
    """Zero-mean normalised correlation of the left block centred at (xc, y), (2rx+1)
    x (2ry+1) clipped to the image, with the right image at xc - d (linear in x);
    0 where a block is flat or too small."""
    height, width = gl.shape
    # every sample of the block shares the fractional shift: right column xx + off
    # and xx + off + 1 with weights 1 - t, t; the columns are clipped once
    off = int(np.floor(-d))
    t = -d - np.float32(off)
    c0 = max(xc - rx, 0, -off)
    c1 = min(xc + rx, width - 1, width - 2 - off)
    r0 = max(0, y - ry)
    r1 = min(height, y + ry + 1)
    cnt = (c1 - c0 + 1) * (r1 - r0)
    if c1 < c0 or cnt < 2:
        return np.float32(0.0)
    u = np.float32(1.0) - t
    sa = np.float32(0.0)
    sb = np.float32(0.0)
    saa = np.float32(0.0)
    sbb = np.float32(0.0)
    sab = np.float32(0.0)
    for yy in range(r0, r1):
        for xx in range(c0, c1 + 1):
            a = gl[yy, xx]
            b = u * gr[yy, xx + off] + t * gr[yy, xx + off + 1]
            sa += a
            sb += b
            saa += a * a
            sbb += b * b
            sab += a * b
    n = np.float32(cnt)
    va = saa - sa * sa / n
    vb = sbb - sb * sb / n
    cov = sab - sa * sb / n
    den = np.sqrt(max(va, np.float32(0.0)) * max(vb, np.float32(0.0)))
    return cov / den if den > 1e-3 else np.float32(0.0)


# Neighbours on one surface have nearly the same disparity: a candidate within this of
# one already tried on the same side would give nearly the same residual.
_SAME_PX = np.float32(0.25)


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _left_candidates(gl, gr, cand, y, x, lim, radius, hh, bound):
    """True if a candidate disparity (``cand``, one row; below ``lim``) within
    +-radius columns of x explains left column x with a residual below ``bound``."""
    width = gl.shape[1]
    for side in (-1, 1):
        last = np.float32(-1e30)
        for j in range(1, radius + 1):
            xx = x + side * j
            if xx < 0 or xx >= width:
                break
            v = cand[xx]
            if v < lim and abs(v - last) > _SAME_PX:
                last = v
                if _column_residual_left(gl, gr, y, x, v, hh) < bound:
                    return True
    return False


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _right_candidates(gl, gr, cand, y, xr, lim, radius, hh, bound):
    """As :func:`_left_candidates` for right column xr and the right view's
    candidates."""
    width = gl.shape[1]
    for side in (-1, 1):
        last = np.float32(-1e30)
        for j in range(1, radius + 1):
            xx = xr + side * j
            if xx < 0 or xx >= width:
                break
            v = cand[xx]
            if v < lim and abs(v - last) > _SAME_PX:
                last = v
                if _column_residual_right(gl, gr, y, xr, v, hh) < bound:
                    return True
    return False


@nb.njit(cache=True, fastmath=_FASTMATH)
def _one_sided_row(gl, gr, disp, zncc, y, side_min, rx, ry, codes):
    """One-sided support of row y (module notes): failing valid pixels of ``codes``
    get REASON_SUPPORT. A pixel's test reads its own code only."""
    width = gl.shape[1]
    for x in range(width):
        if codes[x] != 0:
            continue
        d = disp[y, x]
        for side in (-1, 1):
            xx = x + side
            if xx < 0 or xx >= width or zncc[y, xx] >= side_min:
                continue
            if _zncc_block(gl, gr, y, xx, d, rx, ry) < side_min:
                codes[x] = REASON_SUPPORT
                break


@nb.njit(cache=True, fastmath=_FASTMATH)
def _depth_edge_row(gl, gr, disp, y, step, radius, hh, ratio, floor2, left_cand, right_cand,
                    left_min, right_min, codes, out):
    """Depth-edge test of row y (the row arrays are one row each): valid pixels of
    ``codes`` that fail get REASON_BOUNDARY in ``out``; ``codes`` may be ``out[y]``,
    since a pixel's test reads the candidates, not the codes, of its neighbours."""
    width = gl.shape[1]
    for x in range(width):
        if codes[x] != 0:
            continue
        d = disp[y, x]
        lim = d - step
        xr = int(np.rint(np.float32(x) - d))
        left_step = left_min[x] < lim
        right_step = 0 <= xr < width and right_min[xr] < lim
        if not (left_step or right_step):
            continue
        kill = False
        if left_step:
            own = _column_residual_left(gl, gr, y, x, d, hh)
            if own > floor2:
                kill = _left_candidates(gl, gr, left_cand, y, x, lim, radius, hh, ratio * own)
        if not kill and right_step:
            own = _column_residual_right(gl, gr, y, xr, d, hh)
            if own > floor2:
                kill = _right_candidates(gl, gr, right_cand, y, xr, lim, radius, hh,
                                         ratio * own)
        if kill:
            out[y, x] = REASON_BOUNDARY


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def support_rows(gl, gr, disp, rdisp, zncc, smin, side_min, rx, ry, tol, y0, y1, reason,
                 left_cand, right_cand):
    """Local support (centred and one-sided) and the depth-edge candidates, rows y0..y1-1.

    Valid pixels (``reason`` 0) whose centred support ``zncc`` is below ``smin`` get
    REASON_SUPPORT, and so do those failing the one-sided support (``side_min`` > 0;
    module notes); ``reason`` is updated in place (each test of a row reads that row).
    Then the disparities the depth-edge test may offer as the farther surface:
    ``left_cand`` holds those of the valid left pixels, ``right_cand`` at right column
    xx the disparity of the left pixel xq = xx + v that the right view's winner v
    points to, where that pixel agrees with v within ``tol`` (a left-right consistent
    pair; subpixel, from the left image); 3e38 elsewhere.

    Parameters
    ----------
    gl, gr : (H, W) float32
        Grey left and right images.
    disp : (H, W) float32
        Left winner-take-all disparities (px; kept for invalid pixels too).
    rdisp : (H, W) float32
        The right view's winner-take-all disparities (whole px, NaN where none).
    zncc : (H, W) float32
        Centred local-support correlation (ignored when ``smin`` is 0).
    smin, side_min : float
        ``support_min_zncc`` and ``support_side_min_zncc`` (0 = off).
    rx, ry : int
        Half width and half height of the one-sided block.
    """
    width = gl.shape[1]
    big = np.float32(3e38)
    codes = np.empty(width, np.uint8)
    for y in range(y0, y1):
        for x in range(width):
            c = reason[y, x]
            if c == 0 and smin != 0 and not zncc[y, x] >= smin:
                c = REASON_SUPPORT
            codes[x] = c
        if smin != 0 and side_min != 0:
            _one_sided_row(gl, gr, disp, zncc, y, side_min, rx, ry, codes)
        for x in range(width):
            reason[y, x] = codes[x]
            left_cand[y, x] = disp[y, x] if codes[x] == 0 else big
            right_cand[y, x] = big
            v = rdisp[y, x]
            if v == v:
                xq = int(np.rint(np.float32(x) + v))
                if 0 <= xq < width and abs(disp[y, xq] - v) <= tol:
                    right_cand[y, x] = disp[y, xq]


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def depth_edge_rows(gl, gr, disp, left_cand, right_cand, left_min, right_min, step, radius,
                    hh, ratio, floor2, y0, y1, reason):
    """The depth-edge test (module notes), rows y0..y1-1, in place on ``reason``.

    Parameters
    ----------
    gl, gr : (H, W) float32
        Grey left and right images.
    disp : (H, W) float32
        Left winner-take-all disparities (px).
    left_cand, right_cand : (H, W) float32
        From :func:`support_rows`; ``left_min``, ``right_min``: their minima over
        +-``radius`` columns, so a pixel (or its right partner) without a candidate
        below ``d - step`` skips the test at once.
    step : float
        A neighbour is another surface when its disparity is below d - step.
    radius : int
        Columns searched on each side for such neighbours.
    hh : int
        The column residuals run over rows y-hh..y+hh.
    ratio : float
        The farther surface wins when its residual is below ratio x the pixel's own.
    floor2 : float
        Own residuals at or below this (DN^2, the noise of a correct match) carry no
        evidence: the pixel is kept.
    reason : (H, W) uint8
        Valid pixels (0) that fail get REASON_BOUNDARY. The candidates were taken
        before this test, so the result does not depend on the order of the pixels.
    """
    for y in range(y0, y1):
        _depth_edge_row(gl, gr, disp, y, step, radius, hh, ratio, floor2, left_cand[y],
                        right_cand[y], left_min[y], right_min[y], reason[y], reason)
