"""Compiled (numba) kernels of the stereo pipeline besides the matcher itself
(slitcli.stereo._nssd).

- :func:`warp_rows`, :func:`support_rows`: the local-support correlation;
- :func:`clip_quantise`: the prefilter's clip and quantisation;
- :func:`reproject`, :func:`bin_percentile`: depth, sensor-frame points, obstacle
  tests and the per-bearing range percentile.

All release the GIL (``nogil``) so bands of rows can run on plain threads. Compiled on
first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
_U = nb.uint64


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def warp_rows(gr, disp, warped, y0, y1):
    """``warped(x, y) = gr(x - disp(x, y), y)`` for rows y0..y1-1 (linear in x, clamped
    to the image; no shift where ``disp`` is NaN)."""
    _warp_rows(gr, gr, disp, warped, y0, y1)


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def support_rows(gl, warped, r, y0, y1, out):
    """Zero-mean normalised correlation of the (2r+1)^2 windows of ``gl`` and
    ``warped`` (clipped to the image) for rows y0..y1-1: ``out`` in [-1, 1], 0 where a
    window is flat. ``warped`` must be complete for rows y0 - r .. y1 - 1 + r."""
    width = gl.shape[1]
    s = np.zeros((5, width + 2 * r), np.float32)
    h = np.zeros((5, width), np.float32)
    for y in range(y0, y1):
        _support_row(gl, warped, y, r, s, h, out)


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _warp_rows(gl, gr, disp, warped, y0, y1):
    width = gl.shape[1]
    for y in range(y0, y1):
        for x in range(width):
            d = disp[y, x]
            xr = np.float32(x) - (d if d == d else np.float32(0.0))
            xr = min(max(xr, np.float32(0.0)), np.float32(width - 1))
            x0 = min(int(xr), width - 2)
            t = xr - np.float32(x0)
            warped[y, x] = (np.float32(1.0) - t) * gr[y, x0] + t * gr[y, x0 + 1]


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _support_row(gl, warped, y, r, s, h, out):
    height, width = gl.shape
    # column sums over the window's rows, zero-padded by r on both sides, then window
    # sums along x as 2r+1 shifted adds (vectorised)
    s[:] = 0.0
    h[:] = 0.0
    y0 = max(0, y - r)
    y1 = min(height, y + r + 1)
    uw = _U(width)
    ur = _U(r)
    for yy in range(_U(y0), _U(y1)):
        for x in range(uw):
            a = gl[yy, x]
            b = warped[yy, x]
            s[0, ur + x] += a
            s[1, ur + x] += b
            s[2, ur + x] += a * a
            s[3, ur + x] += b * b
            s[4, ur + x] += a * b
    for q in range(_U(5)):
        for k in range(_U(2 * r + 1)):
            for x in range(uw):
                h[q, x] += s[q, x + k]
    rows = np.float32(y1 - y0)
    for x in range(width):
        cnt = rows * np.float32(min(width, x + r + 1) - max(0, x - r))
        a = h[0, x]
        b = h[1, x]
        var_a = h[2, x] - a * a / cnt
        var_b = h[3, x] - b * b / cnt
        cov = h[4, x] - a * b / cnt
        den = np.sqrt(max(var_a, np.float32(0.0)) * max(var_b, np.float32(0.0)))
        out[y, x] = cov / den if den > 1e-3 else np.float32(0.0)


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def reproject(disp, rays_s, fb, height_m, floor_margin_m, two_sigma_d, robot_height_m,
              max_range_m, depth_out, pts_out, obstacle_out, feature_out):
    """Eq. 8 depth, sensor-frame points and the obstacle / feature tests in one pass.

    ``rays_s`` (H, W, 3) are the pixel rays in the sensor frame at unit optical-axis
    depth; ``fb`` is f x baseline; a point is floor below
    ``floor_margin_m + two_sigma_d |r_z| D^2 / fb`` (see slitcli.stereo.obstacles).
    """
    height, width = disp.shape
    nan = np.float32(np.nan)
    for y in range(height):
        for x in range(width):
            d = disp[y, x]
            if not (d > 0):
                depth_out[y, x] = nan
                pts_out[y, x, 0] = nan
                pts_out[y, x, 1] = nan
                pts_out[y, x, 2] = nan
                obstacle_out[y, x] = False
                feature_out[y, x] = False
                continue
            dep = np.float32(fb) / d
            px = rays_s[y, x, 0] * dep
            py = rays_s[y, x, 1] * dep
            pz = rays_s[y, x, 2] * dep + np.float32(height_m)
            depth_out[y, x] = dep
            pts_out[y, x, 0] = px
            pts_out[y, x, 1] = py
            pts_out[y, x, 2] = pz
            floor_z = floor_margin_m + two_sigma_d * abs(rays_s[y, x, 2]) * dep * dep / fb
            not_floor = pz >= floor_z
            feature_out[y, x] = not_floor
            obstacle_out[y, x] = (not_floor and pz < robot_height_m and px > 0
                                  and px * px + py * py <= max_range_m * max_range_m)


@nb.njit(cache=True, nogil=True)
def bin_percentile(pts, obstacle, feature, bin_idx, nbins, step_m, max_range_m,
                   percentile, range_out, obstacle_px, feature_px):
    """Per bearing bin: pixel counts and the percentile of the obstacle ranges.

    Ranges go into ``step_m`` histogram cells up to ``max_range_m``; the percentile is
    the centre of the cell holding the ``floor(p (n - 1))``-th smallest range.
    ``range_out`` is left untouched for bins without obstacle points.
    """
    height, width = obstacle.shape
    cells = int(np.ceil(max_range_m / step_m)) + 1
    hist = np.zeros((nbins, cells), np.int32)
    obstacle_px[:] = 0
    feature_px[:] = 0
    for y in range(height):
        for x in range(width):
            b = bin_idx[y, x]
            if b < 0:
                continue
            if feature[y, x]:
                feature_px[b] += 1
            if obstacle[y, x]:
                r = np.sqrt(pts[y, x, 0] * pts[y, x, 0] + pts[y, x, 1] * pts[y, x, 1])
                c = min(int(r / step_m), cells - 1)
                hist[b, c] += 1
                obstacle_px[b] += 1
    for b in range(nbins):
        nb_ = obstacle_px[b]
        if nb_ == 0:
            continue
        rank = int(np.floor(percentile / 100.0 * (nb_ - 1)))
        acc = 0
        for c in range(cells):
            acc += hist[b, c]
            if acc > rank:
                range_out[b] = (c + 0.5) * step_m
                break


@nb.njit(cache=True, nogil=True)
def clip_quantise(grey, smooth, sign, cap, scale, out):
    """``out = rint(clip(grey - sign * smooth, -cap, cap) * scale)`` in one pass.

    With ``sign = 0`` ``smooth`` is ignored and ``grey`` itself is clipped (the
    derivative prefilters pass their response as ``grey``).
    """
    height, width = grey.shape
    for y in range(height):
        for x in range(width):
            v = grey[y, x] - sign * smooth[y, x]
            v = min(max(v, -cap), cap)
            out[y, x] = np.float32(np.rint(v * scale))


@nb.njit(cache=True, inline="always")
def _root(parent, i):
    """Root of i's set (path halving; every link points to an earlier pixel)."""
    while parent[i] != i:
        p = parent[i]
        parent[i] = parent[p]
        i = p
    return i


@nb.njit(cache=True, nogil=True)
def speckle_finish(disp, reason, max_size, max_diff_16, speckle_code):
    """Speckle removal, then NaN for every invalid pixel, in place.

    The regions are those of ``cv2.filterSpeckles`` on the disparities in 1/16 px
    (``trunc(16 d)``): 4-connected valid pixels whose neighbours differ by at most
    ``max_diff_16``. Valid pixels of regions of at most ``max_size`` pixels get
    ``speckle_code`` (``max_size`` 0: no speckle removal). The regions are the
    connected components of a union-find built in one raster pass (a pixel joins the
    run on its left, runs join the row above; every set is rooted at its first pixel,
    so a second raster pass reads each pixel's root in O(1)): O(pixels), and
    independent of the order of the pass.
    """
    height, width = disp.shape
    nan = np.float32(np.nan)
    if max_size <= 0:
        for y in range(height):
            for x in range(width):
                if reason[y, x] != 0:
                    disp[y, x] = nan
        return
    npx = height * width
    fixed = np.empty(npx, np.int32)
    parent = np.empty(npx, np.int32)
    size = np.empty(npx, np.int32)
    for y in range(height):
        run = -1     # root of the set of pixel x - 1, -1 when it is invalid
        for x in range(width):
            i = y * width + x
            if reason[y, x] != 0:
                run = -1
                continue
            f = np.int32(np.int16(disp[y, x] * np.float32(16.0)))
            fixed[i] = f
            if run >= 0 and abs(f - fixed[i - 1]) <= max_diff_16:
                parent[i] = run
                size[run] += 1
                root = run
            else:
                parent[i] = i
                size[i] = 1
                root = i
            if y > 0 and reason[y - 1, x] == 0 and abs(f - fixed[i - width]) <= max_diff_16:
                up = _root(parent, i - width)
                if up != root:
                    lo = min(up, root)
                    hi = max(up, root)
                    parent[hi] = lo
                    size[lo] += size[hi]
                    root = lo
            run = root
    for y in range(height):
        for x in range(width):
            i = y * width + x
            if reason[y, x] == 0:
                r = parent[parent[i]]   # parent[i] < i is already flattened to its root
                parent[i] = r
                if size[r] <= max_size:
                    reason[y, x] = speckle_code
                    disp[y, x] = nan
            else:
                disp[y, x] = nan
