"""Compiled (numba) kernels of the stereo pipeline.

- :func:`nssd_rows`: the Eq. 10 matcher (cost, winner-take-all, subpixel, uniqueness,
  left-right) for a band of rows;
- :func:`warp_rows`, :func:`support_rows`: the local-support correlation;
- :func:`clip_quantise`: the prefilter's clip and quantisation;
- :func:`reproject`, :func:`bin_percentile`: depth, sensor-frame points, obstacle
  tests and the per-bearing range percentile.

All release the GIL (``nogil``) so bands of rows can run on plain threads. The matcher
walks the image one row at a time and keeps, per column, the running
vertical window sums of squared differences of all disparities (``width x
num_disparities`` floats per thread, disparity-contiguous), so the full cost volume
is never stored: a window sum slides along x with one add and one subtract per
disparity whatever the window size, and the winner-take-all of a pixel is a min over
a contiguous vector of packed (cost | index) keys. Hot loops index whole arrays with
unsigned (uint64) indices: numba's negative-index wraparound on signed offsets would
stop LLVM from vectorising them, and array slices would cost an atomic reference
count each. The kernel is compiled on first use and cached on disk (``cache=True``),
so only the first run on a machine pays the compile.
"""

from __future__ import annotations

import numba as nb
import numpy as np

# An energy-free window (all zeros after prefiltering) makes Eq. 10 0/0; its inverse
# norm is set to this so every candidate that touches it costs more than any real one.
BIG_INV = np.float32(1e30)
# Added to the SSD so that 0 * BIG_INV**2 (two empty windows) becomes +inf, not 0.
SSD_EPS = np.float32(1e-3)
_FASTMATH = {"nsz", "arcp", "contract", "afn"}  # no nnan/ninf: +inf marks impossible costs

# invalid_reason codes (docs/stereo.md); texture (2), speckle (5) and support (7) are
# set by slitcli.stereo.matcher
REASON_VALID = 0
REASON_NO_CANDIDATE = 1
REASON_UNIQUENESS = 3
REASON_LEFT_RIGHT = 4


_U = nb.uint64


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _slide_energy(v, img, ra, rs, do_add, do_sub):
    """Slide the vertical window sums of squared intensities ``v`` down one row."""
    w = _U(v.shape[0])
    ua = _U(ra)
    us = _U(rs)
    if do_add and do_sub:
        for c in range(w):
            v[c] += img[ua, c] * img[ua, c] - img[us, c] * img[us, c]
    elif do_add:
        for c in range(w):
            v[c] += img[ua, c] * img[ua, c]
    elif do_sub:
        for c in range(w):
            v[c] -= img[us, c] * img[us, c]


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _window_energy(v, prefix, inv, m):
    """Inverse roots of the window energies ``sum P^2`` (window clipped to the image).

    ``prefix`` (float64, width + 1) gets the running column sums of ``v`` so the
    clipped border windows of the masked Eq. 10 can be summed in O(1).
    """
    width = v.shape[0]
    acc = 0.0
    prefix[0] = 0.0
    for c in range(width):
        acc += v[c]
        prefix[c + 1] = acc
    # interior windows in one vectorised float32 pass (the sums are exact integers
    # below 2**24 for the default 9 x 9 window), the clipped ones at the edges apart
    a = min(m, width)
    b = max(width - m, a)
    ua = _U(a)
    um = _U(m)
    for k in range(_U(b - a)):
        x = ua + k
        e = np.float32(prefix[x + um + _U(1)] - prefix[x - um])
        inv[x] = np.float32(1.0) / np.sqrt(e) if e >= 0.5 else BIG_INV
    for x in range(0, a):
        e = np.float32(prefix[min(x + m, width - 1) + 1] - prefix[0])
        inv[x] = np.float32(1.0) / np.sqrt(e) if e >= 0.5 else BIG_INV
    for x in range(b, width):
        e = np.float32(prefix[width] - prefix[max(x - m, 0)])
        inv[x] = np.float32(1.0) / np.sqrt(e) if e >= 0.5 else BIG_INV


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _border_x(cvec, ssum, cly, cry, i0, i1, x, dmin, m, width):
    """Eq. 10 of pixel x for disparity indices i0..i1-1 whose window leaves the columns
    both images have: sums and energies over the clipped window (masked Eq. 10)."""
    for i in range(i0, i1):
        d = dmin + i
        lo = max(0, d)
        hi = min(width, width + d)
        c0 = max(x - m, lo)
        c1 = min(x + m, hi - 1)
        sl = np.float32(cly[c1 + 1] - cly[c0])
        sr = np.float32(cry[c1 + 1 - d] - cry[c0 - d])
        if sl < 0.5 or sr < 0.5:
            g = BIG_INV * (BIG_INV if sl < 0.5 and sr < 0.5 else
                           np.float32(1.0) / np.sqrt(max(sl, sr)))
        else:
            g = np.float32(1.0) / np.sqrt(sl * sr)
        cvec[i] = (ssum[i] + SSD_EPS) * g


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _colsum_rows(colsum, pl, prr, ra, rs, do_add, do_sub, dmin, num, m):
    """Slide all disparities' vertical window sums down one row (disparity-contiguous)."""
    width = pl.shape[1]
    ua = _U(ra)
    us = _U(rs)
    for c in range(width):
        lo = max(0, c - width + 1 - dmin)
        hi = min(num, c - dmin + 1)
        if lo >= hi:
            continue
        p = _U(c + m + 1)
        j0 = _U(width - 1 - c + dmin + lo)
        ulo = _U(lo)
        a = pl[ua, c]
        b = pl[us, c]
        if do_add and do_sub:
            for k in range(_U(hi - lo)):
                t = a - prr[ua, j0 + k]
                u = b - prr[us, j0 + k]
                colsum[p, ulo + k] += t * t - u * u
        elif do_add:
            for k in range(_U(hi - lo)):
                t = a - prr[ua, j0 + k]
                colsum[p, ulo + k] += t * t
        elif do_sub:
            for k in range(_U(hi - lo)):
                u = b - prr[us, j0 + k]
                colsum[p, ulo + k] -= u * u


@nb.njit(cache=True, fastmath=_FASTMATH, nogil=True)
def nssd_rows(pl, pr, prr, y0, y1, dmin, num, m, n, uniq, lr_tol, subpixel,
              disp_out, cost_out, energy_out, reason_out, rdisp_out):
    """Eq. 10 winner-take-all with subpixel, uniqueness and left-right check.

    Parameters
    ----------
    pl, pr : (H, W) float32
        Matched (prefiltered) left and right images, integer-valued.
    prr : (H, W) float32
        ``pr`` mirrored left-right (contiguous), so that the right pixels x - d of
        consecutive disparities are consecutive in memory.
    dmin, num : int
        Disparities ``dmin .. dmin + num - 1``.
    m, n : int
        Half window width and height: the window is (2m+1) x (2n+1).
    uniq : float
        Uniqueness ratio (0 = off).
    lr_tol : float
        Left-right tolerance in px (< 0 = off).
    subpixel : bool
        Parabola refinement.
    y0, y1 : int
        Rows y0 .. y1 - 1 are matched (the GIL is released: bands of rows can run
        on several threads; the result does not depend on the split, every sum is
        exact).
    disp_out, cost_out, energy_out : (H, W) float32
        Disparity (NaN where no candidate), Eq. 10 cost of the winner (+inf where
        none) and left window energy ``sum P_l^2`` over the window clipped to the image.
    reason_out : (H, W) uint8
        REASON_* code per pixel.
    rdisp_out : (H, W) float32
        The right image's own winner-take-all disparity per right pixel (whole pixels,
        read from the same costs as the left-right check; NaN where none): the right
        view's disparity image, for the depth-edge test of slitcli.stereo._boundary.
    """
    height, width = pl.shape
    uw = _U(width)
    colsum = np.zeros((width + 2 * m + 1, num), np.float32)
    ssum = np.empty(num, np.float32)
    cvec = np.empty(num, np.float32)
    cbits = cvec.view(np.int32)
    rkey = np.empty(width, np.int32)          # right best key, reversed column index
    best_i = np.empty(width, np.int32)
    rbest_i = np.empty(width, np.int32)
    c_0 = np.empty(width, np.float32)
    c_m = np.empty(width, np.float32)
    c_p = np.empty(width, np.float32)
    second = np.empty(width, np.float32)
    s2 = np.empty(1, np.int32)
    s2f = s2.view(np.float32)
    vl = np.zeros(width, np.float32)
    vr = np.zeros(width, np.float32)
    cly = np.empty(width + 1, np.float64)
    cry = np.empty(width + 1, np.float64)
    il = np.empty(width, np.float32)
    ir = np.empty(width, np.float32)
    irr = np.empty(width, np.float32)
    inf = np.float32(np.inf)
    inf_bits = np.int32(0x7F800000)
    index_bits = 1
    while (1 << index_bits) < num:
        index_bits += 1
    index_mask = np.int32((1 << index_bits) - 1)
    key_mask = np.int32(~index_mask)
    inf_key = np.int32(0x7F800000 & ~index_mask)
    for r in range(max(0, y0 - n), min(height, y0 + n + 1)):
        _slide_energy(vl, pl, r, r, True, False)
        _slide_energy(vr, pr, r, r, True, False)
        _colsum_rows(colsum, pl, prr, r, r, True, False, dmin, num, m)
    for y in range(y0, y1):
        ra = min(y + n, height - 1)
        rs = max(y - n - 1, 0)
        do_add = y > y0 and y + n < height
        do_sub = y > y0 and y - n - 1 >= 0
        _slide_energy(vl, pl, ra, rs, do_add, do_sub)
        _slide_energy(vr, pr, ra, rs, do_add, do_sub)
        _colsum_rows(colsum, pl, prr, ra, rs, do_add, do_sub, dmin, num, m)
        _window_energy(vl, cly, il, m)
        _window_energy(vr, cry, ir, m)
        for j in range(uw):
            irr[j] = ir[uw - _U(1) - j]
        rkey[:] = inf_key
        un = _U(num)
        # window sums of column x = -1: colsum rows 0 .. 2m
        ssum[:] = 0.0
        for p in range(_U(2 * m + 1)):
            for i in range(un):
                ssum[i] += colsum[p, i]
        for x in range(width):
            ux = _U(x)
            # slide the window one column: add column x + m, drop column x - m - 1
            pa = ux + _U(2 * m + 1)
            for i in range(un):
                ssum[i] += colsum[pa, i] - colsum[ux, i]
            vlo = max(0, x - width + 1 - dmin)
            vhi = min(num, x - dmin + 1)
            for i in range(0, max(min(vlo, num), 0)):
                cvec[i] = inf
            for i in range(max(vhi, 0), num):
                cvec[i] = inf
            if vlo >= vhi:
                best_i[x] = -1
                c_0[x] = inf
                continue
            j0 = width - 1 - x + dmin   # reversed right column of disparity index 0
            if m <= x <= width - 1 - m:
                ilo = max(vlo, x + m + 1 - width - dmin)
                ihi = min(vhi, x - m - dmin + 1)
            else:
                ilo = vlo
                ihi = vlo
            if ilo < ihi:
                f = il[x]
                uj = _U(j0 + ilo)
                for k in range(_U(ihi - ilo)):
                    i = _U(ilo) + k
                    cvec[i] = (ssum[i] + SSD_EPS) * f * irr[uj + k]
            else:
                ilo = vlo
                ihi = vlo
            _border_x(cvec, ssum, cly, cry, vlo, ilo, x, dmin, m, width)
            _border_x(cvec, ssum, cly, cry, ihi, vhi, x, dmin, m, width)
            # winner-take-all for this left pixel (a min over packed cost|index keys)
            # and, along the same costs, for every right pixel it can see
            lk = inf_key
            uj = _U(j0 + vlo)
            for k in range(_U(vhi - vlo)):
                i = _U(vlo) + k
                key = np.int32(np.int32(cbits[i] & key_mask) | np.int32(i))
                lk = key if key < lk else lk
                rk = rkey[uj + k]
                rkey[uj + k] = key if key < rk else rk
            if lk >= inf_key:
                best_i[x] = -1
                c_0[x] = inf
                continue
            bi = np.int32(lk & index_mask)
            best_i[x] = bi
            c_0[x] = cvec[bi]
            c_m[x] = cvec[bi - 1] if bi >= 1 else inf
            c_p[x] = cvec[bi + 1] if bi < num - 1 else inf
            if uniq > 0.0:
                # best cost further than 1 px from the winner: mask the winner +-1, then
                # a min over the float bits (non-negative floats order like their bits)
                for i in range(max(bi - 1, 0), min(bi + 2, num)):
                    cbits[i] = inf_bits
                sb = inf_bits
                ulo = _U(vlo)
                for k in range(_U(vhi - vlo)):
                    b = cbits[ulo + k]
                    sb = b if b < sb else sb
                s2[0] = sb
                second[x] = s2f[0]
        for x in range(width):
            rk = rkey[width - 1 - x]
            rbest_i[x] = np.int32(rk & index_mask) if rk < inf_key else -1
            rdisp_out[y, x] = np.float32(dmin + rbest_i[x]) if rbest_i[x] >= 0 else np.nan
        for x in range(width):
            energy_out[y, x] = cly[min(x + m, width - 1) + 1] - cly[max(x - m, 0)]
            i = best_i[x]
            c1v = c_0[x]
            cost_out[y, x] = c1v
            if i < 0 or not (c1v < inf):
                disp_out[y, x] = np.nan
                reason_out[y, x] = REASON_NO_CANDIDATE
                continue
            d = dmin + i
            delta = np.float32(0.0)
            if subpixel and i > 0 and i < num - 1:
                cm = c_m[x]
                cp = c_p[x]
                den = cm - 2.0 * c1v + cp
                if cm < inf and cp < inf and den > 0.0:
                    delta = np.float32(0.5 * (cm - cp) / den)
            disp_out[y, x] = np.float32(d) + delta
            reason = REASON_VALID
            if uniq > 0.0 and second[x] < c1v * (1.0 + uniq):
                reason = REASON_UNIQUENESS
            if reason == REASON_VALID and lr_tol >= 0.0:
                xr = x - d
                if xr < 0 or xr >= width or abs(rbest_i[xr] - i) > lr_tol:
                    reason = REASON_LEFT_RIGHT
            reason_out[y, x] = reason


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
