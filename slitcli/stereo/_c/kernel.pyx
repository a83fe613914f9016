"""Compiled kernels of the stereo pipeline besides the matcher itself
(slitcli.stereo._nssd) and its support and depth-edge tests (slitcli.stereo._boundary).

- :func:`clip_quantise`: the prefilter's clip and quantisation;
- :func:`reproject`, :func:`bin_percentile`: depth, sensor-frame points, obstacle
  tests and the per-bearing range percentile;
- :func:`trim_silhouettes`: obstacle runs cut back to their last intensity step where
  they end on a plain (unmatched) background;
- :func:`floor_check`: obstacle pixels that the floor explains better than their match;
- speckle removal (``speckle_finish``, ``speckle_small``): slitcli/stereo/_c/speckle.pyx.

All release the GIL, so bands of rows can run on plain threads. The arithmetic is that
of the expressions as written, in their order, with one exception: :func:`reproject`
spells out the fused multiply-adds and the reciprocal of ``fb`` that the numba kernel it
replaces was compiled to (it had fastmath's contraction and reciprocal licence), so the
results are the same bits as before.
"""

from libc.math cimport ceil, fabsf, floor, fma, fmaf, INFINITY, isnan, NAN, rintf, sqrtf
from libc.stdint cimport int32_t, int64_t, uint8_t

import numpy as np


def reproject(const float[:, ::1] disp, const float[:, :, ::1] rays_s, double fb,
              double height_m, double floor_margin_m, double two_sigma_d,
              double robot_height_m, double max_range_m, float[:, ::1] depth_out,
              float[:, :, ::1] pts_out, uint8_t[:, ::1] obstacle_out,
              uint8_t[:, ::1] feature_out) -> None:
    """Eq. 8 depth, sensor-frame points and the obstacle / feature tests in one pass.

    Parameters
    ----------
    disp : ndarray, shape (H, W), float32
        Disparity, px (not > 0: invalid).
    rays_s : ndarray, shape (H, W, 3), float32
        Pixel rays in the sensor frame at unit optical-axis depth.
    fb : float
        Focal length (px) times baseline (m).
    height_m : float
        Sensor height above the floor, m.
    floor_margin_m, two_sigma_d : float
        A point is floor below ``floor_margin_m + two_sigma_d |r_z| D^2 / fb`` (m; see
        slitcli.stereo.obstacles).
    robot_height_m, max_range_m : float
        Obstacles lie below ``robot_height_m`` and within ``max_range_m`` (horizontal).
    depth_out : ndarray, shape (H, W), float32
        Written: depth, m (NaN invalid).
    pts_out : ndarray, shape (H, W, 3), float32
        Written: sensor-frame points, m (NaN invalid).
    obstacle_out, feature_out : ndarray, shape (H, W), bool
        Written: obstacle points; points not floor.
    """
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], y, x
    if rays_s.shape[0] != height or rays_s.shape[1] != width or rays_s.shape[2] != 3 \
            or depth_out.shape[0] != height or depth_out.shape[1] != width \
            or pts_out.shape[0] != height or pts_out.shape[1] != width \
            or pts_out.shape[2] != 3 or obstacle_out.shape[0] != height \
            or obstacle_out.shape[1] != width or feature_out.shape[0] != height \
            or feature_out.shape[1] != width:
        raise ValueError("reproject: rays_s and pts_out (H, W, 3), the others (H, W)")
    cdef float fb32 = <float> fb, h32 = <float> height_m
    cdef double inv_fb, max_r2
    with nogil:
        # numba's fastmath (arcp, contract) divided by fb as a product with its
        # reciprocal and fused these multiply-adds; spelt out, the bits stay the same
        inv_fb = 1.0 / fb
        max_r2 = max_range_m * max_range_m
        for y in range(height):
            _reproject_row(&disp[y, 0], &rays_s[y, 0, 0], width, fb32, h32, inv_fb,
                           floor_margin_m, two_sigma_d, robot_height_m, max_r2,
                           &depth_out[y, 0], &pts_out[y, 0, 0], &obstacle_out[y, 0],
                           &feature_out[y, 0])


cdef inline void _reproject_row(const float* disp, const float* rays, Py_ssize_t width,
                                float fb32, float h32, double inv_fb, double floor_margin_m,
                                double two_sigma_d, double robot_height_m, double max_r2,
                                float* depth, float* pts, uint8_t* obstacle,
                                uint8_t* feature) noexcept nogil:
    """One image row of :func:`reproject` (rays and points: 3 floats a pixel)."""
    cdef Py_ssize_t x
    cdef float d, dep, px, py, pz
    cdef float nan32 = NAN
    cdef double floor_z, dep64
    cdef bint not_floor
    for x in range(width):
        d = disp[x]
        if not (d > 0):
            depth[x] = nan32
            pts[3 * x] = nan32
            pts[3 * x + 1] = nan32
            pts[3 * x + 2] = nan32
            obstacle[x] = False
            feature[x] = False
            continue
        dep = fb32 / d
        px = rays[3 * x] * dep
        py = rays[3 * x + 1] * dep
        # the fused multiply-adds numba's fastmath (contract) compiled these to
        pz = fmaf(rays[3 * x + 2], dep, h32)
        depth[x] = dep
        pts[3 * x] = px
        pts[3 * x + 1] = py
        pts[3 * x + 2] = pz
        dep64 = dep
        floor_z = fma(two_sigma_d * <double> fabsf(rays[3 * x + 2]) * dep64 * dep64, inv_fb,
                      floor_margin_m)
        not_floor = pz >= floor_z
        feature[x] = not_floor
        obstacle[x] = (not_floor and pz < robot_height_m and px > 0
                       and fmaf(px, px, py * py) <= max_r2)


cdef inline bint _split(double r_near, double r_far, double fb, double gap_px) noexcept nogil:
    """Whether two ranges lie on separate surfaces: their disparities ``fb / r`` differ
    by more than ``gap_px``."""
    return fb * (r_far - r_near) > gap_px * r_near * r_far


cdef inline Py_ssize_t _rank_cell(const int32_t* hist, Py_ssize_t lo, Py_ssize_t hi,
                                  int64_t rank) noexcept nogil:
    """The cell in ``[lo, hi]`` of one bin's row ``hist`` holding the ``rank``-th
    (0-based) count."""
    cdef int64_t acc = 0
    cdef Py_ssize_t c
    for c in range(lo, hi + 1):
        acc += hist[c]
        if acc > rank:
            return c
    return hi


cdef void _bin_ranges(const int32_t* hist, Py_ssize_t cells, int64_t n_b, double step_m,
                      double percentile, double fb, double gap_px,
                      double* range_b) noexcept nogil:
    """The percentile range of one bin from its histogram row (see
    :func:`bin_percentile`)."""
    cdef Py_ssize_t ck, lo, hi, c, cs
    cdef int64_t n_s
    cdef double r2
    ck = _rank_cell(hist, 0, cells - 1, <int64_t> floor(percentile / 100.0 * (n_b - 1)))
    range_b[0] = (ck + 0.5) * step_m
    if not gap_px > 0:
        return
    lo = ck
    for c in range(ck - 1, -1, -1):
        if hist[c] > 0:
            if _split((c + 0.5) * step_m, (lo + 0.5) * step_m, fb, gap_px):
                break
            lo = c
        elif _split((c + 0.5) * step_m, (lo + 0.5) * step_m, fb, gap_px):
            break   # every cell nearer than this is split from lo already
    hi = ck
    for c in range(ck + 1, cells):
        if hist[c] > 0:
            if _split((hi + 0.5) * step_m, (c + 0.5) * step_m, fb, gap_px):
                break
            hi = c
        elif _split((hi + 0.5) * step_m, (c + 0.5) * step_m, fb, gap_px):
            break
    n_s = 0
    for c in range(lo, hi + 1):
        n_s += hist[c]
    cs = _rank_cell(hist, lo, hi, <int64_t> floor(percentile / 100.0 * (n_s - 1)))
    r2 = (cs + 0.5) * step_m
    range_b[0] = r2 if r2 < range_b[0] else range_b[0]


def bin_percentile(const float[:, :, ::1] pts, const uint8_t[:, ::1] obstacle,
                   const uint8_t[:, ::1] feature, const int64_t[:, ::1] bin_idx,
                   Py_ssize_t nbins, double step_m, double max_range_m, double percentile,
                   double fb, double gap_px, double[::1] range_out,
                   int64_t[::1] obstacle_px, int64_t[::1] feature_px) -> None:
    """Per bearing bin: pixel counts and the percentile of the obstacle ranges.

    Ranges go into ``step_m`` histogram cells up to ``max_range_m``; the bin's
    percentile cell holds the ``floor(p (n - 1))``-th smallest range. With
    ``gap_px > 0`` the surface that cell lies on (the run of occupied cells around it
    whose neighbours' disparities ``fb / r`` differ by at most ``gap_px``) gets its own
    percentile, and the nearer of the two is returned: a near object that fills part
    of a bin is ranged from its own points, not from a rank diluted by the background
    behind it. ``range_out`` is left untouched for bins without obstacle points.

    Parameters
    ----------
    pts : ndarray, shape (H, W, 3), float32
        Sensor-frame points, m.
    obstacle, feature : ndarray, shape (H, W), bool
    bin_idx : ndarray, shape (H, W), int64
        Bearing bin of every pixel, -1 none.
    nbins : int
    step_m, max_range_m, percentile, fb, gap_px : float
        Cell size (m), histogram reach (m), percentile (0-100), focal length x
        baseline (px m), surface gap (px).
    range_out : ndarray, shape (nbins,), float64
        Written for bins with obstacle points: range, m.
    obstacle_px, feature_px : ndarray, shape (nbins,), int64
        Written: counts per bin.
    """
    cdef Py_ssize_t height = obstacle.shape[0], width = obstacle.shape[1], y, x, c, b
    cdef Py_ssize_t cells = <Py_ssize_t> ceil(max_range_m / step_m) + 1
    if pts.shape[0] != height or pts.shape[1] != width or pts.shape[2] != 3 \
            or feature.shape[0] != height or feature.shape[1] != width \
            or bin_idx.shape[0] != height or bin_idx.shape[1] != width \
            or range_out.shape[0] != nbins or obstacle_px.shape[0] != nbins \
            or feature_px.shape[0] != nbins:
        raise ValueError("bin_percentile: pts (H, W, 3), masks and bin_idx (H, W), the "
                         "outputs (nbins,)")
    hist_arr = np.zeros((max(nbins, 1), cells), np.int32)
    cdef int32_t[:, ::1] hist = hist_arr
    cdef int64_t bi
    cdef float r
    cdef double q
    with nogil:
        for b in range(nbins):
            obstacle_px[b] = 0
            feature_px[b] = 0
        for y in range(height):
            for x in range(width):
                bi = bin_idx[y, x]
                if bi < 0:
                    continue
                if feature[y, x]:
                    feature_px[bi] += 1
                if obstacle[y, x]:
                    r = sqrtf(pts[y, x, 0] * pts[y, x, 0] + pts[y, x, 1] * pts[y, x, 1])
                    # (the far cell also takes a NaN point, which an obstacle pixel
                    # never is: no cell index from an undefined conversion)
                    q = r / step_m
                    c = <Py_ssize_t> q if q < cells - 1 else cells - 1
                    hist[bi, c] += 1
                    obstacle_px[bi] += 1
        for b in range(nbins):
            if obstacle_px[b] == 0:
                continue
            _bin_ranges(&hist[b, 0], cells, obstacle_px[b], step_m, percentile, fb, gap_px,
                        &range_out[b])


cdef inline bint _plain(const float[:, ::1] grey, const float[:, ::1] disp, Py_ssize_t y,
                        Py_ssize_t x0, Py_ssize_t step, Py_ssize_t reach_px,
                        double step_dn) noexcept nogil:
    """Whether ``x0`` and the next ``reach_px`` pixels outwards (fewer at the border) are
    all unmatched and stay within ``step_dn`` of each other: a plain background, not a
    hole in a textured surface."""
    cdef Py_ssize_t width = grey.shape[1], x = x0, t
    cdef float lo = grey[y, x0], hi = grey[y, x0], g
    for t in range(reach_px):
        x += step
        if x < 0 or x >= width:
            break
        if not isnan(disp[y, x]):
            return False
        g = grey[y, x]
        lo = g if g < lo else lo
        hi = g if g > hi else hi
    return hi - lo <= step_dn


cdef void _trim_row(const uint8_t[:, ::1] obstacle, const float[:, ::1] grey,
                    const float[:, ::1] disp, Py_ssize_t y, Py_ssize_t reach_px,
                    double step_dn, double same_px, uint8_t[:, :] out) noexcept nogil:
    """:func:`trim_silhouettes` on row ``y``."""
    cdef Py_ssize_t width = obstacle.shape[1], x = 0, a, b, g, k, g_end
    while x < width:
        if not obstacle[y, x]:
            x += 1
            continue
        a = x
        while x < width and obstacle[y, x]:
            x += 1
        b = x - 1
        # right end: steps between g and g + 1 for g in [b - reach, b]
        if b + 1 < width and isnan(disp[y, b + 1]) and _plain(grey, disp, y, b + 1, 1,
                                                              reach_px, step_dn):
            g_end = a if a > b - reach_px else b - reach_px
            g = b
            while g >= g_end:
                if fabsf(grey[y, g + 1] - grey[y, g]) > step_dn:
                    if g < b and fabsf(disp[y, b] - disp[y, g]) <= same_px:
                        for k in range(g + 1, b + 1):
                            out[y, k] = False
                    break
                g -= 1
        # left end: steps between g and g + 1 for g in [a - 1, a - 1 + reach]
        if a >= 1 and isnan(disp[y, a - 1]) and _plain(grey, disp, y, a - 1, -1,
                                                       reach_px, step_dn):
            g_end = b - 1 if b - 1 < a - 1 + reach_px else a - 1 + reach_px
            for g in range(a - 1, g_end + 1):
                if fabsf(grey[y, g + 1] - grey[y, g]) > step_dn:
                    if g >= a and fabsf(disp[y, a] - disp[y, g + 1]) <= same_px:
                        for k in range(a, g + 1):
                            out[y, k] = False
                    break


def trim_silhouettes(const uint8_t[:, ::1] obstacle, const float[:, ::1] grey,
                     const float[:, ::1] disp, Py_ssize_t reach_px, double step_dn,
                     double same_px, uint8_t[:, :] out) -> None:
    """Cut each row's obstacle runs back to their outermost intensity step.

    A run of obstacle pixels that ends on a plain background (the next ``reach_px + 1``
    pixels unmatched and within ``step_dn`` of each other)
    keeps only the pixels up to the outermost step of more than
    ``step_dn`` between two neighbours of ``grey`` within ``reach_px`` columns of the end;
    without such a step, or at the image border, the run is kept whole, and so is a run
    whose disparity changes by more than ``same_px`` across the step (a depth edge between
    two matched surfaces, such as a plain object's matched rim before a textured wall).

    Parameters
    ----------
    obstacle : ndarray, shape (H, W), bool
    grey : ndarray, shape (H, W), float32
        Left image, DN.
    disp : ndarray, shape (H, W), float32
        Disparity, px (NaN invalid).
    reach_px : int
    step_dn, same_px : float
    out : ndarray, shape (H, W), bool
        Written: the trimmed mask.
    """
    cdef Py_ssize_t height = obstacle.shape[0], width = obstacle.shape[1], y, x
    if grey.shape[0] != height or grey.shape[1] != width or disp.shape[0] != height \
            or disp.shape[1] != width or out.shape[0] != height or out.shape[1] != width:
        raise ValueError("trim_silhouettes: every array (H, W)")
    with nogil:
        for y in range(height):
            for x in range(width):
                out[y, x] = obstacle[y, x]
        for y in range(height):
            _trim_row(obstacle, grey, disp, y, reach_px, step_dn, same_px, out)


cdef inline double _right_at(const float[:, ::1] right, Py_ssize_t y, Py_ssize_t x,
                             double d) noexcept nogil:
    """The right image at row ``y``, column ``x - d`` (linear along the row); NaN outside."""
    cdef double xr = x - d, a
    cdef Py_ssize_t x0
    if isnan(xr):
        return NAN
    x0 = <Py_ssize_t> floor(xr)
    if x0 < 0 or x0 + 1 >= right.shape[1]:
        return NAN
    a = xr - x0
    return right[y, x0] * (1.0 - a) + right[y, x0 + 1] * a


cdef inline double _column_zssd(const float[:, ::1] left, const float[:, ::1] right,
                                Py_ssize_t y, Py_ssize_t x, Py_ssize_t half_h, double d,
                                const float[:, ::1] dmap, bint per_row) noexcept nogil:
    """Zero-mean SSD of the left image's column ``x``, rows ``y - half_h .. y + half_h``,
    against the right image shifted by ``d`` (``per_row``: by each row's ``dmap[row, x]``,
    a plane whose disparity changes along the column); infinite when it leaves the image."""
    cdef Py_ssize_t n = 2 * half_h + 1, i
    cdef double sl = 0.0, sr = 0.0, ml, mr, acc = 0.0, r, e
    for i in range(-half_h, half_h + 1):
        r = _right_at(right, y + i, x, dmap[y + i, x] if per_row else d)
        if isnan(r):
            return INFINITY
        sl += left[y + i, x]
        sr += r
    ml = sl / n
    mr = sr / n
    for i in range(-half_h, half_h + 1):
        r = _right_at(right, y + i, x, dmap[y + i, x] if per_row else d)
        e = (left[y + i, x] - ml) - (r - mr)
        acc += e * e
    return acc


def floor_check(const uint8_t[:, ::1] obstacle, const float[:, ::1] left,
                const float[:, ::1] right, const float[:, ::1] disp,
                const float[:, ::1] floor_disp, Py_ssize_t half_h, double ratio,
                double min_step_px, Py_ssize_t reach_px, uint8_t[:, :] out) -> None:
    """Drop obstacle pixels that the floor explains better than their own disparity.

    For an obstacle pixel below the horizon (``floor_disp > 0``, the disparity the floor
    plane would have there) whose disparity differs from the floor's by at least
    ``min_step_px``, the pixel's own one-pixel-wide column of ``2 half_h + 1`` rows is
    compared with the right image at its disparity and at the floor's (each row at its
    own: the floor's disparity grows down the image); if the floor's residual is below
    ``ratio`` times its own, the pixel is floor (``out`` False). Only pixels within
    ``reach_px`` columns of the end of their row's obstacle run are tested (how far
    window fattening reaches).

    Parameters
    ----------
    obstacle : ndarray, shape (H, W), bool
    left, right : ndarray, shape (H, W), float32
        The rectified pair, grey, DN.
    disp, floor_disp : ndarray, shape (H, W), float32
        Disparity (NaN invalid) and the floor plane's, px.
    half_h : int
    ratio, min_step_px : float
    reach_px : int
    out : ndarray, shape (H, W), bool
        Written: the mask without the floor's pixels.
    """
    cdef Py_ssize_t height = obstacle.shape[0], width = obstacle.shape[1], y, x, k, k0, k1
    cdef bint at_end
    cdef float df, d
    cdef double own, flo
    if left.shape[0] != height or left.shape[1] != width or right.shape[0] != height \
            or right.shape[1] != width or disp.shape[0] != height or disp.shape[1] != width \
            or floor_disp.shape[0] != height or floor_disp.shape[1] != width \
            or out.shape[0] != height or out.shape[1] != width:
        raise ValueError("floor_check: every array (H, W)")
    with nogil:
        for y in range(height):
            for x in range(width):
                out[y, x] = obstacle[y, x]
        for y in range(half_h, height - half_h):
            for x in range(width):
                if not obstacle[y, x]:
                    continue
                at_end = False
                k0 = x - reach_px if x - reach_px > 0 else 0
                k1 = x + reach_px + 1 if x + reach_px + 1 < width else width
                for k in range(k0, k1):
                    if not obstacle[y, k]:
                        at_end = True
                        break
                if not at_end:
                    continue
                df = floor_disp[y, x]
                d = disp[y, x]
                if not (df > 0) or fabsf(d - df) < min_step_px:
                    continue
                own = _column_zssd(left, right, y, x, half_h, d, floor_disp, False)
                flo = _column_zssd(left, right, y, x, half_h, df, floor_disp, True)
                if flo < ratio * own:
                    out[y, x] = False


def clip_quantise(const float[:, :] grey, const float[:, :] smooth, float sign, float cap,
                  float scale, float[:, :] out) -> None:
    """``out = rint(clip(grey - sign * smooth, -cap, cap) * scale)`` in one pass, float32
    (H, W) throughout.

    With ``sign = 0`` ``smooth`` is ignored and ``grey`` itself is clipped (the
    derivative prefilters pass their response as ``grey``).
    """
    cdef Py_ssize_t height = grey.shape[0], width = grey.shape[1], y, x
    cdef float v
    if smooth.shape[0] != height or smooth.shape[1] != width or out.shape[0] != height \
            or out.shape[1] != width:
        raise ValueError("clip_quantise: every array (H, W)")
    cdef bint contiguous = (grey.strides[1] == 4 and smooth.strides[1] == 4
                            and out.strides[1] == 4)
    with nogil:
        if contiguous:
            for y in range(height):
                _clip_row(&grey[y, 0], &smooth[y, 0], sign, cap, scale, &out[y, 0], width)
        else:
            for y in range(height):
                for x in range(width):
                    v = grey[y, x] - sign * smooth[y, x]
                    v = -cap if -cap > v else v   # Python's max(v, -cap), min(v, cap)
                    v = cap if cap < v else v
                    out[y, x] = rintf(v * scale)


cdef inline void _clip_row(const float* g, const float* s, float sign, float cap,
                           float scale, float* o, Py_ssize_t n) noexcept nogil:
    """One contiguous row of :func:`clip_quantise` (a loop the compiler vectorises)."""
    cdef Py_ssize_t x
    cdef float v
    for x in range(n):
        v = g[x] - sign * s[x]
        v = -cap if -cap > v else v   # Python's max(v, -cap), min(v, cap)
        v = cap if cap < v else v
        o[x] = rintf(v * scale)
