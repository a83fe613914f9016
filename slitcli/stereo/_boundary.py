"""Compiled (numba) tests of the Eq. 10 matcher at depth edges (slitcli.stereo.matcher).

A (2m+1) x (2n+1) correlation window that straddles a depth edge is matched by
whichever surface carries the stronger texture, so that surface's disparity is
carried up to half a window past its silhouette ("foreground fattening"): the
pixels just beside an object get the object's range. :func:`post_rows` re-examines
the matches, row by row, with evidence that does not straddle the edge:

- local support: the zero-mean normalised correlation of the (2r+1)^2 grey windows of
  the left image and of the right image warped by the winning disparities must reach
  ``support_min_zncc``;
- one-sided support: a pixel next to a weakly supported pixel (a textureless or
  wrongly matched neighbour) must also be supported by the (2r+1)-wide, window-tall
  block centred one column towards that neighbour. A textureless pixel that borrowed
  its disparity from texture on its other side has nothing there to correlate.
- cross support: the match must also hold on both sides of the pixel along one axis:
  the (2r+1)^2 left blocks just above and just below it (rows y -+ (2r+1)), or just
  left and right of it, correlated with the right image at the pixel's own disparity,
  must both reach ``cross_min_zncc``. A textureless pixel within half a window of an
  edge or of the laser stripe has that texture on one side only; a pixel of a thin
  pole keeps the blocks above and below it, and one on a silhouette the blocks along
  the silhouette. The blocks do not overlap the centred one, so on a plain surface
  the sensor noise passes the centred and both blocks of an axis rarely together.
  A pixel whose own centred correlation reaches ``strong`` carries its match alone and
  is not tested (most pixels of a textured surface: this keeps the test cheap).
- depth edges, a two-hypothesis test on the pixel's own column. Where a
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

All four run in one pass over a band of rows (``y0 .. y1 - 1``; the warped right
image is kept for the 2r+1 rows around the current one only), O(pixels): the
per-pixel work is a fixed-size window, and the residual columns are computed only
next to depth steps (a row-wise running minimum of the candidates says where). The
kernel releases the GIL; each row's result depends only on read-only inputs, so bands
can run on plain threads.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from slitcli.stereo._simd import offset, ptr
from slitcli.stereo._zncc import zncc_blocks
from slitcli.stereo.reasons import Reason

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
# the codes this kernel writes (slitcli.stereo.reasons); compile-time constants
REASON_SUPPORT = int(Reason.SUPPORT)
REASON_BOUNDARY = int(Reason.BOUNDARY)


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
def _one_sided_row(gl, gr, disp, zncc, y, zy, side_min, rx, ry, codes, req):
    """One-sided support of row y (module notes; its centred correlations are
    ``zncc[zy]``): failing valid pixels of ``codes`` get REASON_SUPPORT. A pixel's test
    reads its own code only, so the row's blocks are correlated together
    (slitcli.stereo._zncc.zncc_blocks; ``req``: :func:`_requests`)."""
    width = gl.shape[1]
    who, yc, xc, dd, res = req
    n = 0
    for x in range(width):
        if codes[x] != 0:
            continue
        for side in (-1, 1):
            xx = x + side
            if xx < 0 or xx >= width or zncc[zy, xx] >= side_min:
                continue
            who[n] = x
            yc[n] = y
            xc[n] = xx
            dd[n] = disp[y, x]
            n += 1
    zncc_blocks(gl, gr, yc, xc, dd, n, rx, ry, res)
    for i in range(n):
        if res[i] < side_min:
            codes[who[i]] = REASON_SUPPORT


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _cross_stage(gl, gr, disp, y, dy, dx, r, cross_min, lst, m, req):
    """Keep in ``lst[:m]`` (in place, in order) the pixels x whose (2r+1)^2 block
    centred at (x + dx, y + dy) correlates with the right image at their own disparity
    to at least ``cross_min``; returns their count."""
    _, yc, xc, dd, res = req
    for i in range(m):
        x = lst[i]
        yc[i] = y + dy
        xc[i] = x + dx
        dd[i] = disp[y, x]
    zncc_blocks(gl, gr, yc, xc, dd, m, r, r, res)
    j = 0
    for i in range(m):
        if res[i] >= cross_min:
            lst[j] = lst[i]
            j += 1
    return j


@nb.njit(cache=True, fastmath=_FASTMATH)
def _cross_row(gl, gr, disp, zrow, y, cross_min, strong, r, codes, req, lists, held):
    """Cross support of row y (module notes; ``zrow``: its centred correlations): valid
    pixels of ``codes`` below ``strong`` and supported on neither axis get
    REASON_SUPPORT. A pixel's test reads its own code only, so the row's blocks are
    correlated together, one side at a time (slitcli.stereo._zncc.zncc_blocks): the
    blocks below for the pixels whose block above passed, and so on, as the scalar
    test would have asked for them. ``lists`` (2, W) int64 and ``held`` (W,) bool are
    work arrays."""
    width = gl.shape[1]
    k = 2 * r + 1
    cand = lists[0]
    cur = lists[1]
    n = 0
    for x in range(width):
        if codes[x] == 0 and zrow[x] < strong:
            cand[n] = x
            held[x] = False
            n += 1
    for vertical in (True, False):
        m = 0
        for i in range(n):
            if not held[cand[i]]:
                cur[m] = cand[i]
                m += 1
        dy = k if vertical else 0
        dx = 0 if vertical else k
        m = _cross_stage(gl, gr, disp, y, -dy, -dx, r, cross_min, cur, m, req)
        m = _cross_stage(gl, gr, disp, y, dy, dx, r, cross_min, cur, m, req)
        for i in range(m):
            held[cur[i]] = True
    for i in range(n):
        if not held[cand[i]]:
            codes[cand[i]] = REASON_SUPPORT


@nb.njit(cache=True)
def _requests(width):
    """Work arrays of a row's block requests (at most two per pixel): pixel, block
    centre row and column, disparity, correlation."""
    return (np.empty(2 * width, np.int64), np.empty(2 * width, np.int64),
            np.empty(2 * width, np.int64), np.empty(2 * width, np.float32),
            np.empty(2 * width, np.float32))


@nb.njit(cache=True, fastmath=_FASTMATH)
def _depth_edge_row(gl, gr, disp, y, step, radius, hh, ratio, floor2, left_cand, right_cand,
                    left_min, right_min, codes):
    """Depth-edge test of row y (the row arrays are one row each): valid pixels of
    ``codes`` that fail get REASON_BOUNDARY, in place (a pixel's test reads the
    candidates, not the codes, of its neighbours)."""
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
            codes[x] = REASON_BOUNDARY


# ---- the fused pass: local support, one-sided support, depth edges (rows y0 .. y1-1)

_BIG = np.float32(3e38)   # "no candidate"
_U = nb.uint64


@nb.njit(cache=True, fastmath=_FASTMATH)
def _acc(s, a, n):
    """``s += a`` over n elements (a vectorised row helper; pointer arguments)."""
    for i in range(n):
        s[i] += a[i]


@nb.njit(cache=True, fastmath=_FASTMATH)
def _acc_prod(s, a, b, n):
    """``s += a b`` over n elements (a vectorised row helper; pointer arguments)."""
    for i in range(n):
        s[i] += a[i] * b[i]


@nb.njit(cache=True, fastmath=_FASTMATH)
def _warp_row(gr, disp, y, out):
    """``out(x) = gr(x - disp(x, y), y)`` (linear in x, clamped to the image; no shift
    where ``disp`` is NaN)."""
    width = gr.shape[1]
    for x in range(width):
        d = disp[y, x]
        xr = np.float32(x) - (d if d == d else np.float32(0.0))
        xr = min(max(xr, np.float32(0.0)), np.float32(width - 1))
        x0 = min(int(xr), width - 2)
        t = xr - np.float32(x0)
        out[x] = (np.float32(1.0) - t) * gr[y, x0] + t * gr[y, x0 + 1]


@nb.njit(cache=True, fastmath=_FASTMATH)
def _zncc_row(gl, ring, y, r, s, h, out):
    """Zero-mean normalised correlation of the (2r+1)^2 windows (clipped to the image)
    of ``gl`` and the warped right image around row y (``ring[yy % (2r+1)]`` holds
    warped row yy): ``out`` in [-1, 1], 0 where a window is flat."""
    height, width = gl.shape
    k2 = 2 * r + 1
    s[:] = 0.0
    h[:] = 0.0
    y0 = max(0, y - r)
    y1 = min(height, y + r + 1)
    for yy in range(y0, y1):
        a = offset(ptr(gl), yy * width)
        b = ptr(ring[yy % k2])
        _acc(offset(ptr(s[0]), r), a, width)
        _acc(offset(ptr(s[1]), r), b, width)
        _acc_prod(offset(ptr(s[2]), r), a, a, width)
        _acc_prod(offset(ptr(s[3]), r), b, b, width)
        _acc_prod(offset(ptr(s[4]), r), a, b, width)
    # window sums along x: 2r+1 shifted adds of the zero-padded column sums
    for q in range(5):
        for k in range(k2):
            _acc(ptr(h[q]), offset(ptr(s[q]), k), width)
    rows = np.float32(y1 - y0)
    for x in range(width):
        cnt = rows * np.float32(min(width, x + r + 1) - max(0, x - r))
        a = h[0, x]
        b = h[1, x]
        var_a = h[2, x] - a * a / cnt
        var_b = h[3, x] - b * b / cnt
        cov = h[4, x] - a * b / cnt
        den = np.sqrt(max(var_a, np.float32(0.0)) * max(var_b, np.float32(0.0)))
        out[x] = cov / den if den > 1e-3 else np.float32(0.0)


@nb.njit(cache=True, fastmath=_FASTMATH)
def _min_shift(out, a, shift, n):
    """``out[i] = min(a[i], a[i + shift])`` over n elements (pointer arguments)."""
    for i in range(n):
        out[i] = min(a[i], a[i + shift])


@nb.njit(cache=True, fastmath=_FASTMATH)
def _window_min(v, radius, out, pad, tmp):
    """``out(x)`` = min of ``v`` over columns x - radius .. x + radius (outside the
    image: 3e38, as cv2.erode with that border value), by doubling: minima over 1, 2, 4
    ... columns, then two overlapping runs cover the window. ``pad`` and ``tmp`` hold
    width + 2 radius floats."""
    width = v.shape[0]
    total = width + 2 * radius
    pad[:] = _BIG
    pad[radius:radius + width] = v
    length = 1
    cur = pad
    nxt = tmp
    while 2 * length <= 2 * radius + 1:
        _min_shift(ptr(nxt), ptr(cur), length, total - length)
        cur, nxt = nxt, cur
        length *= 2
    _min_shift(ptr(out), ptr(cur), 2 * radius + 1 - length, width)


@nb.njit(cache=True, fastmath=_FASTMATH)
def _support_codes(reason, zncc, smin, support, codes, n):
    """``codes = reason``, and REASON_SUPPORT for valid pixels whose centred support
    ``zncc`` is below ``smin`` (pointer arguments; branch-free, vectorised)."""
    for x in range(n):
        c = reason[x]
        weak = (c == 0) & support & ~(zncc[x] >= smin)
        codes[x] = np.uint8(REASON_SUPPORT) if weak else c


@nb.njit(cache=True, fastmath=_FASTMATH)
def _candidates(codes, disp, rdisp, tol, left_cand, right_cand, width):
    """The depth-edge candidates of one row (pointer arguments): ``left_cand`` the
    disparity of every valid left pixel; ``right_cand`` at right column x the disparity
    of the left pixel xq = rint(x + v) that the right view's winner v points to, where
    that pixel agrees with v within ``tol``; 3e38 elsewhere. Branch-free."""
    for x in range(width):
        left_cand[x] = disp[x] if codes[x] == 0 else _BIG
    for x in range(width):
        v = rdisp[x]
        xq = int(np.rint(np.float32(x) + v)) if v == v else -1
        dq = disp[min(max(xq, 0), width - 1)]
        ok = (xq >= 0) & (xq < width) & (abs(dq - v) <= tol)
        right_cand[x] = dq if ok else _BIG


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def post_rows(gl, gr, disp, rdisp, smin, side_min, cross_min, strong, r, ry, tol, ratio, step,
              radius, floor2, y0, y1, reason):
    """Local support (centred, one-sided, cross) and the depth-edge test, rows y0 .. y1 - 1, in
    place on ``reason``, in one pass (module notes).

    Parameters
    ----------
    gl, gr : (H, W) float32
        Grey left and right images.
    disp : (H, W) float32
        Left winner-take-all disparities (px; kept for invalid pixels too); read for
        rows y0 - r .. y1 - 1 + r (the warped right image).
    rdisp : (H, W) float32
        The right view's winner-take-all disparities (whole px, NaN where none).
    smin, side_min : float
        ``support_min_zncc`` (0 = no support test) and ``support_side_min_zncc``
        (0 = no one-sided test).
    cross_min, strong : float
        ``support_cross_min_zncc`` (0 = no cross-support test) and
        ``support_strong_zncc`` (a centred correlation this high needs no cross support).
    r, ry : int
        Half size of the (2r+1)^2 support window; half height of the one-sided block
        (2r+1 columns by 2ry+1 rows) and of the depth-edge columns.
    tol : float
        A right pixel's candidate needs a left partner within ``tol`` px.
    ratio, step, radius, floor2 : float, float, int, float
        The depth-edge test (module notes; ``ratio`` 0 = off): the farther surface wins
        below ``ratio`` x the pixel's own residual; a neighbour is another surface when
        its disparity is below d - ``step``; ``radius`` columns are searched on each
        side; own residuals at or below ``floor2`` (DN^2, the noise of a correct match)
        carry no evidence.
    reason : (H, W) uint8
        Valid pixels (0) that fail get REASON_SUPPORT or REASON_BOUNDARY. Each row's
        result depends only on read-only inputs, so bands of rows can run in parallel.
    """
    height, width = gl.shape
    k2 = 2 * r + 1
    ring = np.empty((k2, width), np.float32)
    s = np.zeros((5, width + 2 * r), np.float32)
    h = np.zeros((5, width), np.float32)
    zncc = np.zeros((1, width), np.float32)
    codes = np.empty(width, np.uint8)
    left_cand = np.empty(width, np.float32)
    right_cand = np.empty(width, np.float32)
    left_min = np.empty(width, np.float32)
    right_min = np.empty(width, np.float32)
    pad = np.empty(width + 2 * radius, np.float32)
    tmp = np.empty(width + 2 * radius, np.float32)
    req = _requests(width)
    lists = np.empty((2, width), np.int64)
    held = np.zeros(width, np.bool_)
    support = smin != 0
    if support:
        for yy in range(max(0, y0 - r), min(height, y0 + r)):
            _warp_row(gr, disp, yy, ring[yy % k2])
    for y in range(y0, y1):
        if support:
            if y + r < height:
                _warp_row(gr, disp, y + r, ring[(y + r) % k2])
            _zncc_row(gl, ring, y, r, s, h, zncc[0])
        _support_codes(offset(ptr(reason), y * width), ptr(zncc), smin, support, ptr(codes),
                       width)
        if support and side_min != 0:
            _one_sided_row(gl, gr, disp, zncc, y, 0, side_min, r, ry, codes, req)
        if support and cross_min != 0:
            _cross_row(gl, gr, disp, zncc[0], y, cross_min, strong, r, codes, req, lists,
                       held)
        if ratio > 0:
            _candidates(ptr(codes), offset(ptr(disp), y * width), offset(ptr(rdisp), y * width),
                        tol, ptr(left_cand), ptr(right_cand), width)
            _window_min(left_cand, radius, left_min, pad, tmp)
            _window_min(right_cand, radius, right_min, pad, tmp)
            _depth_edge_row(gl, gr, disp, y, step, radius, ry, ratio, floor2, left_cand,
                            right_cand, left_min, right_min, codes)
        reason[y] = codes
