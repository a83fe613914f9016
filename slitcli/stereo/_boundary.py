"""Compiled (numba) tests of the Eq. 10 matcher at depth edges (slitcli.stereo.matcher).

A (2m+1) x (2n+1) correlation window that straddles a depth edge is matched by
whichever surface carries the stronger texture, so that surface's disparity is
carried up to half a window past its silhouette ("foreground fattening"): the
pixels just beside an object get the object's range. These kernels re-examine the
matches with evidence that does not straddle the edge:

- :func:`one_sided_rows`: a pixel next to a weakly supported pixel (a textureless or
  wrongly matched neighbour) must also be supported by the (2r+1)-wide, window-tall
  block centred one column towards that neighbour. A
  textureless pixel that borrowed its disparity from texture on its other side has
  nothing there to correlate.
- :func:`boundary_rows`: a two-hypothesis test on the pixel's own column. Where a
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

All kernels release the GIL and work on a band of rows (``y0 .. y1 - 1``) so they can
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
    sa = np.float32(0.0)
    sb = np.float32(0.0)
    saa = np.float32(0.0)
    sbb = np.float32(0.0)
    sab = np.float32(0.0)
    cnt = 0
    for yy in range(max(0, y - ry), min(height, y + ry + 1)):
        for xx in range(max(0, xc - rx), min(width, xc + rx + 1)):
            xr = np.float32(xx) - d
            if not (xr >= 0.0 and xr <= width - 1):
                continue
            x0 = min(int(xr), width - 2)
            t = xr - np.float32(x0)
            a = gl[yy, xx]
            b = (np.float32(1.0) - t) * gr[yy, x0] + t * gr[yy, x0 + 1]
            sa += a
            sb += b
            saa += a * a
            sbb += b * b
            sab += a * b
            cnt += 1
    if cnt < 2:
        return np.float32(0.0)
    n = np.float32(cnt)
    va = saa - sa * sa / n
    vb = sbb - sb * sb / n
    cov = sab - sa * sb / n
    den = np.sqrt(max(va, np.float32(0.0)) * max(vb, np.float32(0.0)))
    return cov / den if den > 1e-3 else np.float32(0.0)


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def one_sided_rows(gl, gr, disp, zncc, side_min, rx, ry, y0, y1, reason):
    """One-sided local support for rows y0..y1-1 (in place on ``reason``).

    Parameters
    ----------
    gl, gr : (H, W) float32
        Grey left and right images.
    disp : (H, W) float32
        Winner-take-all disparities (px).
    zncc : (H, W) float32
        The centred local-support correlation of every pixel.
    side_min : float
        ``support_side_min_zncc``: a neighbour whose centred correlation is below it
        calls for the one-sided block, which must reach it too.
    rx, ry : int
        Half width and half height of the one-sided block.
    reason : (H, W) uint8
        Valid pixels (0) that fail get REASON_SUPPORT; the test of a pixel reads only
        its own code, so updating in place is order-independent.
    """
    width = gl.shape[1]
    for y in range(y0, y1):
        for x in range(width):
            if reason[y, x] != 0:
                continue
            d = disp[y, x]
            for side in (-1, 1):
                xx = x + side
                if xx < 0 or xx >= width or zncc[y, xx] >= side_min:
                    continue
                if _zncc_block(gl, gr, y, xx, d, rx, ry) < side_min:
                    reason[y, x] = REASON_SUPPORT
                    break


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def boundary_rows(gl, gr, disp, rdisp, reason, left_min, right_min, step, radius, hh,
                  ratio, floor2, tol, y0, y1, out):
    """Depth-edge hypothesis test for rows y0..y1-1 (see the module notes).

    Parameters
    ----------
    gl, gr : (H, W) float32
        Grey left and right images.
    disp : (H, W) float32
        Left winner-take-all disparities (subpixel; kept for invalid pixels too).
    rdisp : (H, W) float32
        Right view's winner-take-all disparities (whole pixels, NaN where none).
    reason : (H, W) uint8
        Codes before this test (read only): the left candidates are valid pixels.
    left_min, right_min : (H, W) float32
        Smallest valid left disparity, and smallest right-view disparity, within
        +-``radius`` columns (+inf where none): pixels with no neighbour below
        ``d - step`` on either side skip the test at once.
    step : float
        A neighbour counts as another surface when its disparity is below d - step.
    radius : int
        Columns searched on each side.
    hh : int
        The column residuals run over rows y-hh..y+hh.
    ratio : float
        The neighbour's hypothesis wins when its residual is below ratio x the
        pixel's own.
    floor2 : float
        Own residuals at or below this (DN^2, the noise of a correct match) carry no
        evidence: the pixel is kept.
    tol : float
        A right-view candidate v (at right column xx) is used only if the left pixel
        it points to, xx + v, has a disparity within tol of v.
    out : (H, W) uint8
        ``reason`` with REASON_BOUNDARY for the pixels that fail.
    """
    width = gl.shape[1]
    for y in range(y0, y1):
        for x in range(width):
            out[y, x] = reason[y, x]
            if reason[y, x] != 0:
                continue
            d = disp[y, x]
            lim = d - step
            xr = int(np.rint(np.float32(x) - d))
            left_step = left_min[y, x] < lim
            right_step = 0 <= xr < width and right_min[y, xr] < lim
            if not (left_step or right_step):
                continue
            kill = False
            if left_step:
                own = _column_residual_left(gl, gr, y, x, d, hh)
                if own > floor2:
                    for j in range(1, radius + 1):
                        for xx in (x - j, x + j):
                            if xx < 0 or xx >= width or reason[y, xx] != 0:
                                continue
                            v = disp[y, xx]
                            if v < lim and \
                                    _column_residual_left(gl, gr, y, x, v, hh) < ratio * own:
                                kill = True
                                break
                        if kill:
                            break
            if not kill and right_step:
                own = _column_residual_right(gl, gr, y, xr, d, hh)
                if own > floor2:
                    for j in range(1, radius + 1):
                        for xx in (xr - j, xr + j):
                            if xx < 0 or xx >= width:
                                continue
                            v = rdisp[y, xx]
                            if not v < lim:
                                continue
                            xq = int(np.rint(np.float32(xx) + v))
                            if xq < 0 or xq >= width:
                                continue
                            vq = disp[y, xq]
                            if abs(vq - v) <= tol and vq < lim and \
                                    _column_residual_right(gl, gr, y, xr, vq, hh) < ratio * own:
                                kill = True
                                break
                        if kill:
                            break
            if kill:
                out[y, x] = REASON_BOUNDARY
