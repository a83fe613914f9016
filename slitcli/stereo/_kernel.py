"""Compiled (numba) kernels of the stereo pipeline besides the matcher itself
(slitcli.stereo._nssd) and its support and depth-edge tests (slitcli.stereo._boundary).

- :func:`clip_quantise`: the prefilter's clip and quantisation;
- :func:`reproject`, :func:`bin_percentile`: depth, sensor-frame points, obstacle
  tests and the per-bearing range percentile;
- :func:`trim_silhouettes`: obstacle runs cut back to their last intensity step where
  they end on a plain (unmatched) background;
- :func:`speckle_finish`: speckle removal and the NaN of invalid pixels.

All release the GIL (``nogil``) so bands of rows can run on plain threads. Compiled on
first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
_U = nb.uint64


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


@nb.njit(cache=True, nogil=True, inline="always")
def _split(r_near, r_far, fb, gap_px):
    """Whether two ranges lie on separate surfaces: their disparities ``fb / r`` differ
    by more than ``gap_px``."""
    return fb * (r_far - r_near) > gap_px * r_near * r_far


@nb.njit(cache=True, nogil=True, inline="always")
def _rank_cell(hist, b, lo, hi, rank):
    """The cell in ``[lo, hi]`` holding the ``rank``-th (0-based) count of row ``b``."""
    acc = 0
    for c in range(lo, hi + 1):
        acc += hist[b, c]
        if acc > rank:
            return c
    return hi


@nb.njit(cache=True, nogil=True)
def bin_percentile(pts, obstacle, feature, bin_idx, nbins, step_m, max_range_m,
                   percentile, fb, gap_px, range_out, obstacle_px, feature_px):
    """Per bearing bin: pixel counts and the percentile of the obstacle ranges.

    Ranges go into ``step_m`` histogram cells up to ``max_range_m``; the bin's
    percentile cell holds the ``floor(p (n - 1))``-th smallest range. With
    ``gap_px > 0`` the surface that cell lies on (the run of occupied cells around it
    whose neighbours' disparities ``fb / r`` differ by at most ``gap_px``) gets its own
    percentile, and the nearer of the two is returned: a near object that fills part
    of a bin is ranged from its own points, not from a rank diluted by the background
    behind it. ``range_out`` is left untouched for bins without obstacle points.
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
        ck = _rank_cell(hist, b, 0, cells - 1, int(np.floor(percentile / 100.0 * (nb_ - 1))))
        range_out[b] = (ck + 0.5) * step_m
        if not gap_px > 0:
            continue
        lo = ck
        for c in range(ck - 1, -1, -1):
            if hist[b, c] > 0:
                if _split((c + 0.5) * step_m, (lo + 0.5) * step_m, fb, gap_px):
                    break
                lo = c
            elif _split((c + 0.5) * step_m, (lo + 0.5) * step_m, fb, gap_px):
                break   # every cell nearer than this is split from lo already
        hi = ck
        for c in range(ck + 1, cells):
            if hist[b, c] > 0:
                if _split((hi + 0.5) * step_m, (c + 0.5) * step_m, fb, gap_px):
                    break
                hi = c
            elif _split((hi + 0.5) * step_m, (c + 0.5) * step_m, fb, gap_px):
                break
        n_s = 0
        for c in range(lo, hi + 1):
            n_s += hist[b, c]
        cs = _rank_cell(hist, b, lo, hi, int(np.floor(percentile / 100.0 * (n_s - 1))))
        range_out[b] = min(range_out[b], (cs + 0.5) * step_m)


@nb.njit(cache=True, nogil=True, inline="always")
def _plain(grey, disp, y, x0, step, reach_px, step_dn):
    """Whether ``x0`` and the next ``reach_px`` pixels outwards (fewer at the border) are
    all unmatched and stay within ``step_dn`` of each other: a plain background, not a
    hole in a textured surface."""
    width = grey.shape[1]
    lo = hi = grey[y, x0]
    x = x0
    for _ in range(reach_px):
        x += step
        if x < 0 or x >= width:
            break
        if not np.isnan(disp[y, x]):
            return False
        lo = min(lo, grey[y, x])
        hi = max(hi, grey[y, x])
    return hi - lo <= step_dn


@nb.njit(cache=True, nogil=True)
def trim_silhouettes(obstacle, grey, disp, reach_px, step_dn, same_px, out):
    """Cut each row's obstacle runs back to their outermost intensity step.

    A run of obstacle pixels that ends on a plain background (the next ``reach_px + 1``
    pixels unmatched and within ``step_dn`` of each other)
    keeps only the pixels up to the outermost step of more than
    ``step_dn`` between two neighbours of ``grey`` within ``reach_px`` columns of the end;
    without such a step, or at the image border, the run is kept whole, and so is a run
    whose disparity changes by more than ``same_px`` across the step (a depth edge between
    two matched surfaces, such as a plain object's matched rim before a textured wall).
    """
    height, width = obstacle.shape
    out[:, :] = obstacle
    for y in range(height):
        x = 0
        while x < width:
            if not obstacle[y, x]:
                x += 1
                continue
            a = x
            while x < width and obstacle[y, x]:
                x += 1
            b = x - 1
            # right end: steps between g and g + 1 for g in [b - reach, b]
            if b + 1 < width and np.isnan(disp[y, b + 1]) and _plain(grey, disp, y, b + 1,
                                                                     1, reach_px, step_dn):
                for g in range(b, max(a, b - reach_px) - 1, -1):
                    if abs(grey[y, g + 1] - grey[y, g]) > step_dn:
                        if g < b and abs(disp[y, b] - disp[y, g]) <= same_px:
                            for k in range(g + 1, b + 1):
                                out[y, k] = False
                        break
            # left end: steps between g and g + 1 for g in [a - 1, a - 1 + reach]
            if a >= 1 and np.isnan(disp[y, a - 1]) and _plain(grey, disp, y, a - 1, -1,
                                                              reach_px, step_dn):
                for g in range(a - 1, min(b - 1, a - 1 + reach_px) + 1):
                    if abs(grey[y, g + 1] - grey[y, g]) > step_dn:
                        if g >= a and abs(disp[y, a] - disp[y, g + 1]) <= same_px:
                            for k in range(a, g + 1):
                                out[y, k] = False
                        break


@nb.njit(cache=True, nogil=True, inline="always")
def _right_at(right, y, x, d):
    """The right image at row ``y``, column ``x - d`` (linear along the row); NaN outside."""
    xr = x - d
    x0 = int(np.floor(xr))
    if x0 < 0 or x0 + 1 >= right.shape[1]:
        return np.nan
    a = xr - x0
    return right[y, x0] * (1.0 - a) + right[y, x0 + 1] * a


@nb.njit(cache=True, nogil=True, inline="always")
def _column_zssd(left, right, y, x, half_h, d, dmap, per_row):
    """Zero-mean SSD of the left image's column ``x``, rows ``y - half_h .. y + half_h``,
    against the right image shifted by ``d`` (``per_row``: by each row's ``dmap[row, x]``,
    a plane whose disparity changes along the column); infinite when it leaves the image."""
    n = 2 * half_h + 1
    sl = 0.0
    sr = 0.0
    for i in range(-half_h, half_h + 1):
        r = _right_at(right, y + i, x, dmap[y + i, x] if per_row else d)
        if np.isnan(r):
            return np.inf
        sl += left[y + i, x]
        sr += r
    ml = sl / n
    mr = sr / n
    acc = 0.0
    for i in range(-half_h, half_h + 1):
        r = _right_at(right, y + i, x, dmap[y + i, x] if per_row else d)
        e = (left[y + i, x] - ml) - (r - mr)
        acc += e * e
    return acc


@nb.njit(cache=True, nogil=True)
def floor_check(obstacle, left, right, disp, floor_disp, half_h, ratio, min_step_px, reach_px,
                out):
    """Drop obstacle pixels that the floor explains better than their own disparity.

    For an obstacle pixel below the horizon (``floor_disp > 0``, the disparity the floor
    plane would have there) whose disparity differs from the floor's by at least
    ``min_step_px``, the pixel's own one-pixel-wide column of ``2 half_h + 1`` rows is
    compared with the right image at its disparity and at the floor's (each row at its
    own: the floor's disparity grows down the image); if the floor's residual is below
    ``ratio`` times its own, the pixel is floor (``out`` False). Only pixels within
    ``reach_px`` columns of the end of their row's obstacle run are tested (how far
    window fattening reaches).
    """
    height, width = obstacle.shape
    out[:, :] = obstacle
    for y in range(half_h, height - half_h):
        for x in range(width):
            if not obstacle[y, x]:
                continue
            at_end = False
            for k in range(max(0, x - reach_px), min(width, x + reach_px + 1)):
                if not obstacle[y, k]:
                    at_end = True
                    break
            if not at_end:
                continue
            df = floor_disp[y, x]
            d = disp[y, x]
            if not (df > 0) or abs(d - df) < min_step_px:
                continue
            own = _column_zssd(left, right, y, x, half_h, d, floor_disp, False)
            flo = _column_zssd(left, right, y, x, half_h, df, floor_disp, True)
            if flo < ratio * own:
                out[y, x] = False


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
