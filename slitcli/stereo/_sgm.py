"""Compiled (numba) kernels of semi-global aggregation over the Eq. 10 cost.

Three kernels, each over a band of rows or a whole pass, all releasing the GIL:

- :func:`cost_rows`: the Eq. 10 normalised cost of every pixel and disparity,
  ``C = (E_l + E_r - 2 X) / sqrt(E_l E_r)`` with the window sums ``E_l``, ``E_r`` (energies)
  and ``X`` (cross term) of the prefiltered images, zero outside the image (the
  windows see zeros there, which the zero-mean prefiltered images make harmless),
  quantised to integers ``round(min(C, c_max) * scale)`` in a uint16 volume (H, W, D);
  a candidate whose partner column leaves the right image, or whose window has no
  energy, costs ``c_max * scale``;
- :func:`aggregate_pass`: Hirschmueller's path costs
  ``L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d+-1) + P1, min_k L_r(p-r, k) + P2)
  - min_k L_r(p-r, k)`` along the paths of one sweep over the rows: top-down (left to
  right, top-left, top, top-right) or, on the volume turned by 180 degrees, bottom-up
  (right to left, bottom-right, bottom, bottom-left); 4-path mode keeps the
  horizontal and the vertical path of each sweep. The sum over the sweep's paths is
  stored (uint16: every L_r stays below ``c_max scale + P2``);
- :func:`winners_rows`: winner-take-all over the sum of the two sweeps, with the
  matcher's tests that need the whole cost curve (window texture energy, uniqueness,
  left-right consistency from the same sums) and the subpixel parabola.

Every per-pixel loop runs over the disparities innermost, contiguous in memory, in
float32, so LLVM vectorises it.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from slitcli.stereo._simd import offset, ptr
from slitcli.stereo.reasons import Reason

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
REASON_VALID = int(Reason.VALID)
REASON_NO_CANDIDATE = int(Reason.NO_CANDIDATE)
REASON_TEXTURE = int(Reason.TEXTURE)
REASON_UNIQUENESS = int(Reason.UNIQUENESS)
REASON_LEFT_RIGHT = int(Reason.LEFT_RIGHT)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _column_slide(col, ra, rs, a, b, n):
    """The vertical window sums of the cross term of one column, one row down:
    ``col += a ra - b rs`` (``a``, ``b``: the left pixels entering and leaving, 0 where
    the row is outside the image; ``ra``, ``rs``: the mirrored right rows from the
    column's first disparity)."""
    for i in range(n):
        col[i] += a * ra[i] - b * rs[i]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _pixel_costs(hs, col_in, col_out, wa, ws, e1, r1, err, irr, top, scale, c_max, out, n):
    """Slide the window's cross sums ``hs`` one column (``wa``, ``ws``: 0 or 1, whether
    the entering / leaving column exists) and write the quantised Eq. 10 costs
    ``round(min((E_l + E_r - 2 X) / sqrt(E_l E_r), c_max) scale)`` (``r1``, ``irr``:
    the inverse square roots of E_l and E_r); ``irr`` = 0 (a partner outside the image
    or a window without energy) or ``r1`` = 0 gives ``top``."""
    for i in range(n):
        x = hs[i] + wa * col_in[i] - ws * col_out[i]
        hs[i] = x
        ir = irr[i]
        c = (e1 + err[i] - np.float32(2.0) * x) * (r1 * ir)
        q = min(max(c, np.float32(0.0)), c_max) * scale + np.float32(0.5)
        out[i] = np.uint16(np.int32(q)) if ir * r1 > 0 else top


@nb.njit(cache=True, nogil=True)
def cost_rows(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale, y0, y1,
              out):
    """Quantised Eq. 10 costs of rows y0..y1-1 into ``out`` (H, W, D) uint16.

    ``pl``: (H, W) float32 prefiltered left image; ``prr_pad``: (H, W + 2 pad) the
    prefiltered right image reversed along x, with ``pad`` zero columns each side, so
    right column ``x - d`` is ``prr_pad[:, pad + W - 1 - x + d]`` and the disparities of
    a pixel are contiguous; ``el``: (H, W) left window energies; ``err_pad``, ``irr_pad``:
    (H, W + 2 pad) the right window energies and their inverse square roots, reversed
    and padded likewise (0 where the window has no energy or the centre is outside the
    image).
    """
    height, width = pl.shape
    stride = prr_pad.shape[1]
    col = np.zeros((width + 1, num), np.float32)   # row 0: the zero column
    hs = np.zeros(num, np.float32)
    top = np.uint16(round(c_max * scale))
    sc = np.float32(scale)
    cm = np.float32(c_max)
    p_col = ptr(col)
    p_r = ptr(prr_pad)
    p_hs = ptr(hs)
    p_i = ptr(irr_pad)
    p_e = ptr(err_pad)
    p_o = ptr(out)
    # the vertical window sums of the cross term at row y0 - 1 (rows y0-1-n..y0-1+n)
    for yy in range(max(0, y0 - 1 - n), min(height, y0 + n)):
        for x in range(width):
            ra = offset(p_r, yy * stride + pad + width - 1 - x + dmin)
            _column_slide(offset(p_col, (x + 1) * num), ra, ra, pl[yy, x], np.float32(0.0),
                          num)
    for y in range(y0, y1):
        ya = y + n
        ys = y - n - 1
        if ya < height or ys >= 0:
            for x in range(width):
                base = pad + width - 1 - x + dmin
                a = pl[ya, x] if ya < height else np.float32(0.0)
                b = pl[ys, x] if ys >= 0 else np.float32(0.0)
                ra = offset(p_r, min(ya, height - 1) * stride + base)
                rs = offset(p_r, max(ys, 0) * stride + base)
                _column_slide(offset(p_col, (x + 1) * num), ra, rs, a, b, num)
        hs[:] = 0.0
        for xx in range(0, min(m, width)):
            for i in range(num):
                hs[i] += col[xx + 1, i]
        for x in range(width):
            xa = x + m
            xs = x - m - 1
            wa = np.float32(1.0) if xa < width else np.float32(0.0)
            ws = np.float32(1.0) if xs >= 0 else np.float32(0.0)
            e1 = el[y, x]
            r1 = np.float32(1.0) / np.sqrt(e1) if e1 > 0 else np.float32(0.0)
            k = y * stride + pad + width - 1 - x + dmin
            _pixel_costs(p_hs, offset(p_col, (min(xa, width - 1) + 1) * num),
                         offset(p_col, (max(xs, -1) + 1) * num), wa, ws, e1, r1,
                         offset(p_e, k), offset(p_i, k), top, sc, cm,
                         offset(p_o, (y * width + x) * num), num)


# ---- path costs. Per-pixel loops are separate functions over raw pointers
# (slitcli.stereo._simd: inlined, LLVM keeps them scalar for fear of overlap). Path
# costs are uint16 rows of D + 2 with a sentinel at each end (index 0 and D + 1,
# value SENTINEL), so that the d -+ 1 terms need no branch; a path's first pixel reads
# a row of zeros (with sentinels), whose minimum is 0, which makes L = C there.

SENTINEL = 0x3FFF   # above any path cost (< c_max scale + P2 <= 2 x 256 + 8 x 256)


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _path_step(cost, prev, cur, prev_min, p1, p2, n):
    """One step of a path at one pixel: ``L = C + min(prev, prev -+ 1 + P1,
    min prev + P2) - min prev`` into ``cur`` (from index 1); returns min L.

    int16 throughout (every value stays below SENTINEL + P2 < 2^15), so that LLVM
    packs 16 disparities per AVX2 operation (3.5 times the int32 loop's speed,
    measured); one store stream, so that its run-time overlap checks stay few
    enough to vectorise at all."""
    h = np.int16(prev_min + p2)
    pm = np.int16(prev_min)
    q1 = np.int16(p1)
    mn = np.int16(0x7FFF)
    for i in range(n):
        a = prev[i + 1]
        b = np.int16(prev[i] + q1)
        c = np.int16(prev[i + 2] + q1)
        v = a if a < b else b
        v = v if v < c else c
        v = v if v < h else h
        val = np.int16(np.int16(cost[i] + v) - pm)
        cur[i + 1] = val
        mn = mn if mn < val else val
    return mn


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _add_paths(out, a, b, n):
    """``out = a + b`` (``a``, ``b``: path rows from index 1)."""
    for i in range(n):
        out[i] = np.int16(a[i + 1] + b[i + 1])


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _add_more_paths(out, a, b, n):
    """``out += a + b``."""
    for i in range(n):
        out[i] = np.int16(out[i] + np.int16(a[i + 1] + b[i + 1]))


@nb.njit(cache=True, nogil=True, inline="always")
def _p2(p1, p2, g, grey_a, grey_b):
    """P2 for a step between two pixels of grey levels a and b: ``P2 g / (g + |a - b|)``
    (Hirschmueller: a disparity jump is likelier across an intensity edge), at least
    P1 + 1; ``g`` <= 0: P2 itself."""
    if g <= 0:
        return p2
    q = np.int32(p2 * g / (g + abs(np.float32(grey_a) - np.float32(grey_b))))
    return max(q, p1 + 1)


@nb.njit(cache=True, nogil=True)
def aggregate_pass(cost, p1, p2, eight, reverse, out, grey, p2_grad):
    """Sum of the path costs of one sweep over the rows, (H, W, D) uint16 into ``out``.

    ``reverse`` False: the top-down sweep, paths left to right and from the top (and,
    with ``eight``, from the top-left and top-right); True: the same on the image
    turned by 180 degrees (right to left, bottom, bottom-right, bottom-left). ``grey``
    (H, W) with ``p2_grad`` > 0: P2 adapted to the grey step along each path
    (:func:`_p2`). Needs D >= 2.
    """
    height, width, num = cost.shape
    stride = num + 2
    p1 = np.int32(p1)
    p2 = np.int32(p2)
    g = np.float32(p2_grad)
    adapt = g > 0
    zero = np.zeros(stride, np.int16)
    zero[0] = SENTINEL
    zero[stride - 1] = SENTINEL
    hbuf = np.full((2, stride), SENTINEL, np.int16)
    # vertical and diagonal paths: previous and current row, one D + 2 run per column
    vbuf = np.full((2, width, stride), SENTINEL, np.int16)
    dbuf = np.full((2, width, stride), SENTINEL, np.int16)
    ebuf = np.full((2, width, stride), SENTINEL, np.int16)
    # costs (<= c_max scale) and sums (<= 4 (c_max scale + P2)) fit int16
    cost16 = cost.view(np.int16)
    out16 = out.view(np.int16)
    vmin = np.zeros((2, width), np.int32)
    dmin = np.zeros((2, width), np.int32)
    emin = np.zeros((2, width), np.int32)
    p_zero = ptr(zero)
    for y in range(height):
        yy = height - 1 - y if reverse else y
        ys = yy + 1 if reverse else yy - 1      # the row the vertical paths come from
        src = y & 1
        dst = 1 - src
        hmin = np.int32(0)
        p_cost = ptr(cost16)
        p_out = ptr(out16)
        p_h = ptr(hbuf)
        p_v = ptr(vbuf)
        p_d = ptr(dbuf)
        p_e = ptr(ebuf)
        for x in range(width):
            xx = width - 1 - x if reverse else x
            xs = xx + 1 if reverse else xx - 1   # the column the horizontal path comes from
            hs = x & 1
            c = offset(p_cost, (yy * width + xx) * num)
            o = offset(p_out, (yy * width + xx) * num)
            hp = p_zero if x == 0 else offset(p_h, hs * stride)
            vp = p_zero if y == 0 else offset(p_v, (src * width + x) * stride)
            vm = np.int32(0) if y == 0 else vmin[src, x]
            p2h = p2
            p2v = p2
            if adapt:
                if x > 0:
                    p2h = _p2(p1, p2, g, grey[yy, xx], grey[yy, xs])
                if y > 0:
                    p2v = _p2(p1, p2, g, grey[yy, xx], grey[ys, xx])
            hc = offset(p_h, (1 - hs) * stride)
            vc = offset(p_v, (dst * width + x) * stride)
            hmin = _path_step(c, hp, hc, hmin, p1, p2h, num)
            vmin[dst, x] = _path_step(c, vp, vc, vm, p1, p2v, num)
            _add_paths(o, hc, vc, num)
            if eight:
                first = y == 0 or x == 0
                last = y == 0 or x == width - 1
                dp = p_zero if first else offset(p_d, (src * width + x - 1) * stride)
                ep = p_zero if last else offset(p_e, (src * width + x + 1) * stride)
                dm = np.int32(0) if first else dmin[src, x - 1]
                em = np.int32(0) if last else emin[src, x + 1]
                p2d = p2
                p2e = p2
                if adapt:
                    if not first:
                        p2d = _p2(p1, p2, g, grey[yy, xx], grey[ys, xs])
                    if not last:
                        p2e = _p2(p1, p2, g, grey[yy, xx], grey[ys, 2 * xx - xs])
                dc = offset(p_d, (dst * width + x) * stride)
                ec = offset(p_e, (dst * width + x) * stride)
                dmin[dst, x] = _path_step(c, dp, dc, dm, p1, p2d, num)
                emin[dst, x] = _path_step(c, ep, ec, em, p1, p2e, num)
                _add_more_paths(o, dc, ec, num)


# ---- winner step. Sums of both sweeps are packed with their disparity index into
# one int32 key ``(s_a + s_b) << 9 | i`` (sums < 2^16, indices < 2^9), so that one
# minimum gives the winner and, among equal sums, the smallest disparity.

KEY_SHIFT = 9
NO_KEY = 0x7FFFFFFF


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _pixel_keys(sa, sb, cost, keys, rkey, top, n):
    """Keys of one pixel's n disparities into ``keys`` (NO_KEY where the cost is
    ``top``: no partner or no energy), lowering the right view's keys ``rkey`` (the
    right pixels x - d for d = dmin, dmin + 1, ..., reversed so they run forwards).
    Returns the pixel's best key."""
    best = np.int32(NO_KEY)
    for i in range(n):
        s = (np.int32(sa[i]) + np.int32(sb[i])) << KEY_SHIFT
        k = (s | np.int32(i)) if cost[i] < top else np.int32(NO_KEY)
        keys[i] = k
        best = min(best, k)
        rkey[i] = min(rkey[i], k)
    return best


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _second(keys, lo, hi, n):
    """Smallest key outside indices lo..hi."""
    second = np.int32(NO_KEY)
    for i in range(n):
        far = (i < lo) | (i > hi)
        second = min(second, keys[i] if far else np.int32(NO_KEY))
    return second


@nb.njit(cache=True, nogil=True, error_model="numpy")
def winners_rows(s_a, s_b, cost, el, count, dmin, uniq, lr_tol, subpixel, energy_min, top,
                 scale, y0, y1, disp_out, cost_out, reason_out, rdisp_out):
    """Winner-take-all over ``s_a + s_b`` for rows y0..y1-1 with the validity tests.

    ``cost``: the quantised Eq. 10 volume (a pixel without any candidate below ``top``
    has no candidate); ``el``, ``count``: window energy and pixel count (texture test:
    ``el < energy_min count``); ``uniq``: no disparity more than 1 px from the winner
    may have a sum below ``(1 + uniq)`` times the winner's; ``lr_tol`` < 0: no
    left-right test (the right pixel's own best left match from the same sums must lie
    within ``lr_tol`` of the winner). Writes disparity (float32, NaN where none), the
    winner's Eq. 10 cost (``cost / scale``), the reason code (uniqueness over
    left-right over texture) and the right view's integer disparities.
    """
    _, width, num = s_a.shape
    keys = np.empty(num, np.int32)
    # right view keys, reversed: right column xr at index width - 1 - xr + pad
    pad = num + abs(dmin) + 1
    rkey = np.empty(width + 2 * pad, np.int32)
    best_i = np.empty(width, np.int32)
    imask = np.int32((1 << KEY_SHIFT) - 1)
    for y in range(y0, y1):
        rkey[:] = NO_KEY
        p_sa = ptr(s_a)
        p_sb = ptr(s_b)
        p_c = ptr(cost)
        p_k = ptr(keys)
        p_r = ptr(rkey)
        for x in range(width):
            base = (y * width + x) * num
            best = _pixel_keys(offset(p_sa, base), offset(p_sb, base), offset(p_c, base),
                               p_k, offset(p_r, pad + width - 1 - x + dmin), top, num)
            if best == NO_KEY:
                best_i[x] = -1
                disp_out[y, x] = np.nan
                cost_out[y, x] = np.inf
                reason_out[y, x] = REASON_NO_CANDIDATE
                continue
            bi = best & imask
            best_i[x] = bi
            bv = np.float32(best >> KEY_SHIFT)
            delta = np.float32(0.0)
            if subpixel and 0 < bi < num - 1:
                km = keys[bi - 1]
                kp = keys[bi + 1]
                if km != NO_KEY and kp != NO_KEY:
                    cm = np.float32(km >> KEY_SHIFT)
                    cp = np.float32(kp >> KEY_SHIFT)
                    den = cm - np.float32(2.0) * bv + cp
                    if den > 0:
                        delta = np.float32(0.5) * (cm - cp) / den
            disp_out[y, x] = np.float32(dmin + bi) + delta
            cost_out[y, x] = np.float32(cost[y, x, bi]) / np.float32(scale)
            code = REASON_VALID
            if (energy_min > 0) and (el[y, x] < energy_min * count[y, x]):
                code = REASON_TEXTURE
            if uniq > 0:
                sk = _second(p_k, bi - 1, bi + 1, num)
                if sk != NO_KEY and np.float32(sk >> KEY_SHIFT) < bv * (np.float32(1.0) + uniq):
                    code = REASON_UNIQUENESS + 100
            reason_out[y, x] = code
        for xr in range(width):
            k = rkey[pad + width - 1 - xr]
            rdisp_out[y, xr] = np.float32(dmin + (k & imask)) if k != NO_KEY else np.nan
        for x in range(width):
            bi = best_i[x]
            if bi < 0:
                continue
            code = reason_out[y, x]
            if code >= 100:
                reason_out[y, x] = code - 100
                continue
            if lr_tol >= 0:
                xr = x - dmin - bi
                ok = (xr >= 0) and (xr < width)
                if ok:
                    k = rkey[pad + width - 1 - xr]
                    ok = k != NO_KEY and abs((k & imask) - bi) <= lr_tol
                if not ok:
                    reason_out[y, x] = REASON_LEFT_RIGHT


@nb.njit(cache=True, nogil=True)
def window_inputs(pl, pr, m, n, pad, el, count, prr_pad, err_pad, irr_pad):
    """The cost kernels' inputs in one pass: window energies and pixel counts of the
    left image (``el``, ``count``, (H, W)), and the right image's rows reversed into
    the padded rows of ``prr_pad`` with its window energies ``err_pad`` and their
    inverse square roots ``irr_pad`` (0 where no energy); padding left untouched.

    The (2m+1) x (2n+1) window sums (zeros outside the image) run in float64 and are
    rounded to float32 once, as ``cv2.boxFilter`` does for float32 images: the
    prefiltered images hold whole numbers (quarter DN), so the running sums are exact
    and the energies equal the box filter's bit for bit."""
    height, width = pl.shape
    cl = np.zeros(width, np.float64)
    cr = np.zeros(width, np.float64)
    for yy in range(min(n, height)):
        for x in range(width):
            a = np.float64(pl[yy, x])
            b = np.float64(pr[yy, x])
            cl[x] += a * a
            cr[x] += b * b
    for y in range(height):
        ya = y + n
        ys = y - n - 1
        if ya < height:
            for x in range(width):
                a = np.float64(pl[ya, x])
                b = np.float64(pr[ya, x])
                cl[x] += a * a
                cr[x] += b * b
        if ys >= 0:
            for x in range(width):
                a = np.float64(pl[ys, x])
                b = np.float64(pr[ys, x])
                cl[x] -= a * a
                cr[x] -= b * b
        rows = min(height - 1, ya) - max(0, y - n) + 1
        sl = 0.0
        sr = 0.0
        for x in range(min(m, width)):
            sl += cl[x]
            sr += cr[x]
        for x in range(width):
            xa = x + m
            xs = x - m - 1
            if xa < width:
                sl += cl[xa]
                sr += cr[xa]
            if xs >= 0:
                sl -= cl[xs]
                sr -= cr[xs]
            el[y, x] = np.float32(sl)
            count[y, x] = np.float32(rows * (min(width - 1, xa) - max(0, x - m) + 1))
            e = np.float32(sr)
            j = pad + width - 1 - x
            prr_pad[y, j] = pr[y, x]
            err_pad[y, j] = e
            irr_pad[y, j] = np.float32(1.0) / np.sqrt(e) if e > 0 else np.float32(0.0)
