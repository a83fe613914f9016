"""SGM path costs with explicit 16-lane int16 vectors (slitcli.stereo._lanes).

The same recurrence, buffers and sentinels as :func:`slitcli.stereo._sgm.aggregate_pass`
(see there), with the two (four) paths of a pixel computed in one loop over its
disparities that stores both path rows and their sum: the scalar kernel needs one
loop per store stream to be vectorised at all. Integer operations wrap in 16 bits as
the scalar kernel's ``np.int16(...)`` do, so the sums are equal bit for bit. Needs
D to be a multiple of 16.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from slitcli.stereo._lanes import (
    hmin16,
    iota16,
    load16,
    loadf8,
    splat16,
    splatf8,
    store16,
    store_u16_where_positive,
    storef8,
    vadd,
    vmax,
    vmin,
    vmul,
    vsub,
    where_eq,
    where_lt,
)
from slitcli.stereo._sgm import (
    REASON_LEFT_RIGHT,
    REASON_NO_CANDIDATE,
    REASON_TEXTURE,
    REASON_UNIQUENESS,
    REASON_VALID,
    SENTINEL,
    _p2,
)
from slitcli.stereo._simd import offset, ptr


@nb.njit(cache=True, nogil=True, inline="always")
def _lane_step(cv, prev, k, q1, h, pm):
    """``L = C + min(prev, prev -+ 1 + P1, min prev + P2) - min prev`` for the 16
    disparities from ``k`` (``prev`` from index 1, sentinels at both ends)."""
    a = load16(prev, k + 1)
    b = vadd(load16(prev, k), q1)
    c = vadd(load16(prev, k + 2), q1)
    v = vmin(vmin(vmin(a, b), c), h)
    return vsub(vadd(cv, v), pm)


@nb.njit(cache=True, nogil=True, inline="always")
def _pair_step(c, o, ap, ac, am, bp, bc, bm, p1, p2a, p2b, accumulate, blocks):
    """Paths a and b at one pixel: rows into ``ac``, ``bc`` (from index 1), their sum
    into ``o`` (added to it with ``accumulate``); returns both minima."""
    q1 = splat16(p1)
    ha = splat16(am + p2a)
    pa = splat16(am)
    hb = splat16(bm + p2b)
    pb = splat16(bm)
    ma = splat16(0x7FFF)
    mb = splat16(0x7FFF)
    for j in range(blocks):
        k = j * 16
        cv = load16(c, k)
        la = _lane_step(cv, ap, k, q1, ha, pa)
        lb = _lane_step(cv, bp, k, q1, hb, pb)
        store16(ac, k + 1, la)
        store16(bc, k + 1, lb)
        s = vadd(la, lb)
        if accumulate:
            s = vadd(load16(o, k), s)
        store16(o, k, s)
        ma = vmin(ma, la)
        mb = vmin(mb, lb)
    return hmin16(ma), hmin16(mb)


@nb.njit(cache=True, nogil=True)
def _sweep_row(c_row, o_row, grey, y, yy, ys, reverse, p1, p2, g, eight, blocks, bufs,
               mins):
    """One row of a sweep (``y``-th row visited: image row ``yy``, its vertical paths
    coming from row ``ys``): path rows carried in ``bufs`` (hbuf, vbuf, dbuf, ebuf,
    zero) and their minima in ``mins`` (3, 2, W) int32; the row's path sum into
    ``o_row`` (pointer to W x D int16)."""
    hbuf, vbuf, dbuf, ebuf, zero = bufs
    width = vbuf.shape[1]
    stride = vbuf.shape[2]
    num = blocks * 16
    adapt = g > 0
    src = y & 1
    dst = 1 - src
    hmin = np.int32(0)
    p_zero = ptr(zero)
    p_h = ptr(hbuf)
    p_v = ptr(vbuf)
    p_d = ptr(dbuf)
    p_e = ptr(ebuf)
    for x in range(width):
        xx = width - 1 - x if reverse else x
        xs = xx + 1 if reverse else xx - 1
        hs = x & 1
        c = offset(c_row, xx * num)
        o = offset(o_row, xx * num)
        hp = p_zero if x == 0 else offset(p_h, hs * stride)
        vp = p_zero if y == 0 else offset(p_v, (src * width + x) * stride)
        vm = np.int32(0) if y == 0 else mins[0, src, x]
        p2h = p2
        p2v = p2
        if adapt:
            if x > 0:
                p2h = _p2(p1, p2, g, grey[yy, xx], grey[yy, xs])
            if y > 0:
                p2v = _p2(p1, p2, g, grey[yy, xx], grey[ys, xx])
        hc = offset(p_h, (1 - hs) * stride)
        vc = offset(p_v, (dst * width + x) * stride)
        hmin, mins[0, dst, x] = _pair_step(c, o, hp, hc, hmin, vp, vc, vm, p1, p2h, p2v,
                                           False, blocks)
        if eight:
            first = y == 0 or x == 0
            last = y == 0 or x == width - 1
            dp = p_zero if first else offset(p_d, (src * width + x - 1) * stride)
            ep = p_zero if last else offset(p_e, (src * width + x + 1) * stride)
            dm = np.int32(0) if first else mins[1, src, x - 1]
            em = np.int32(0) if last else mins[2, src, x + 1]
            p2d = p2
            p2e = p2
            if adapt:
                if not first:
                    p2d = _p2(p1, p2, g, grey[yy, xx], grey[ys, xs])
                if not last:
                    p2e = _p2(p1, p2, g, grey[yy, xx], grey[ys, 2 * xx - xs])
            dc = offset(p_d, (dst * width + x) * stride)
            ec = offset(p_e, (dst * width + x) * stride)
            mins[1, dst, x], mins[2, dst, x] = _pair_step(c, o, dp, dc, dm, ep, ec, em, p1,
                                                          p2d, p2e, True, blocks)


@nb.njit(cache=True, nogil=True)
def _sweep_state(width, num):
    """Path buffers of a sweep (all sentinels; ``zero``: a first pixel's previous
    row, zeros between sentinels) and the path minima."""
    stride = num + 2
    zero = np.zeros(stride, np.int16)
    zero[0] = SENTINEL
    zero[stride - 1] = SENTINEL
    bufs = (np.full((2, stride), SENTINEL, np.int16),
            np.full((2, width, stride), SENTINEL, np.int16),
            np.full((2, width, stride), SENTINEL, np.int16),
            np.full((2, width, stride), SENTINEL, np.int16), zero)
    return bufs, np.zeros((3, 2, width), np.int32)


@nb.njit(cache=True, nogil=True)
def aggregate_pass_lanes(cost, p1, p2, eight, reverse, out, grey, p2_grad):
    """:func:`slitcli.stereo._sgm.aggregate_pass` (same arguments and result) in
    16-lane vectors; D a multiple of 16."""
    height, width, num = cost.shape
    bufs, mins = _sweep_state(width, num)
    cost16 = cost.view(np.int16)
    out16 = out.view(np.int16)
    for y in range(height):
        yy = height - 1 - y if reverse else y
        ys = yy + 1 if reverse else yy - 1
        _sweep_row(offset(ptr(cost16), yy * width * num), offset(ptr(out16), yy * width * num),
                   grey, y, yy, ys, reverse, np.int32(p1), np.int32(p2), np.float32(p2_grad),
                   eight, num // 16, bufs, mins)


# ---- winner step in lanes: the sums s_a + s_b (int16), 0x7FFF where the cost is
# ``top`` (no partner, no energy); the scalar kernel's keys ``s << 9 | i`` order the
# same way as (sum, index), so the lanes keep each lane's smallest sum and, among
# equal sums, its first (smallest) index.

NO_SUM = 0x7FFF


@nb.njit(cache=True, nogil=True, inline="always")
def _pixel_sums(sa, sb, c, sums, top, blocks):
    """Sums of one pixel into ``sums`` (NO_SUM where the cost is ``top``); returns the
    best sum and its smallest index."""
    none = splat16(NO_SUM)
    t = splat16(top)
    best = none
    bidx = none
    for j in range(blocks):
        k = j * 16
        s = where_lt(load16(c, k), t, vadd(load16(sa, k), load16(sb, k)), none)
        store16(sums, k, s)
        bidx = where_lt(s, best, iota16(k), bidx)
        best = vmin(best, s)
    bv = hmin16(best)
    return bv, hmin16(where_eq(best, splat16(bv), bidx, none))


@nb.njit(cache=True, nogil=True, inline="always")
def _right_update(sums, rsum, ridx, blocks):
    """Lower the right view's best sums ``rsum`` and indices ``ridx`` with one left
    pixel's ``sums``: among equal sums the smaller index (the scalar kernel's key order),
    so that the pixels may come in any order."""
    for j in range(blocks):
        k = j * 16
        s = load16(sums, k)
        r = load16(rsum, k)
        i = load16(ridx, k)
        store16(ridx, k, where_lt(s, r, iota16(k), where_eq(s, r, vmin(iota16(k), i), i)))
        store16(rsum, k, vmin(s, r))


@nb.njit(cache=True, nogil=True, inline="always")
def _second_sum(sums, lo, hi, blocks):
    """Smallest sum outside indices lo..hi."""
    none = splat16(NO_SUM)
    vlo = splat16(lo)
    vhi = splat16(hi)
    m = none
    for j in range(blocks):
        k = j * 16
        idx = iota16(k)
        s = load16(sums, k)
        m = vmin(m, where_lt(idx, vlo, s, where_lt(vhi, idx, s, none)))
    return hmin16(m)


@nb.njit(cache=True, nogil=True)
def _winner_row(p_sa, p_sb, p_c, el_row, count_row, dmin, uniq, lr_tol, subpixel, energy_min,
                top, scale, sums, rsum, ridx, best_i, disp_out, cost_out, reason_out,
                rdisp_out):
    """One row of :func:`winners_rows_lanes`: ``p_sa``, ``p_sb``, ``p_c`` point to the
    row's W x D sums and costs (int16), the outputs are the row's (W,) arrays."""
    width = disp_out.shape[0]
    num = sums.shape[0] // width
    blocks = num // 16
    pad = num + abs(dmin) + 1
    rsum[:] = NO_SUM
    p_rs = ptr(rsum)
    p_ri = ptr(ridx)
    p_row = ptr(sums)
    for x in range(width):
        base = x * num
        p_s = offset(p_row, base)
        bv, bi = _pixel_sums(offset(p_sa, base), offset(p_sb, base), offset(p_c, base),
                             p_s, top, blocks)
        if bv == NO_SUM:
            best_i[x] = -1
            disp_out[x] = np.nan
            cost_out[x] = np.inf
            reason_out[x] = REASON_NO_CANDIDATE
            continue
        best_i[x] = bi
        bvf = np.float32(bv)
        delta = np.float32(0.0)
        if subpixel and 0 < bi < num - 1:
            sm = sums[base + bi - 1]
            sp = sums[base + bi + 1]
            if sm != NO_SUM and sp != NO_SUM:
                cm = np.float32(sm)
                cp = np.float32(sp)
                den = cm - np.float32(2.0) * bvf + cp
                if den > 0:
                    delta = np.float32(0.5) * (cm - cp) / den
        disp_out[x] = np.float32(dmin + bi) + delta
        cost_out[x] = np.float32(p_c[base + bi]) / np.float32(scale)
        code = REASON_VALID
        if (energy_min > 0) and (el_row[x] < energy_min * count_row[x]):
            code = REASON_TEXTURE
        if uniq > 0:
            sk = _second_sum(p_s, bi - 1, bi + 1, blocks)
            if sk != NO_SUM and np.float32(sk) < bvf * (np.float32(1.0) + uniq):
                code = REASON_UNIQUENESS + 100
        reason_out[x] = code
    # the right view: pixel x's sums lower the right pixels x - d, windows one element
    # apart for neighbouring x. Taken 16 columns apart, each pixel's blocks load what
    # the last one stored at the same addresses (in order: unaligned overlapping
    # vector loads wait for the store before them, measured ~2 ms a frame)
    for x0 in range(16):
        for x in range(x0, width, 16):
            r0 = pad + width - 1 - x + dmin
            _right_update(offset(p_row, x * num), offset(p_rs, r0), offset(p_ri, r0), blocks)
    for xr in range(width):
        j = pad + width - 1 - xr
        rdisp_out[xr] = np.float32(dmin + ridx[j]) if rsum[j] != NO_SUM else np.nan
    for x in range(width):
        bi = best_i[x]
        if bi < 0:
            continue
        code = reason_out[x]
        if code >= 100:
            reason_out[x] = code - 100
            continue
        if lr_tol >= 0:
            xr = x - dmin - bi
            ok = (xr >= 0) and (xr < width)
            if ok:
                j = pad + width - 1 - xr
                ok = rsum[j] != NO_SUM and abs(ridx[j] - bi) <= lr_tol
            if not ok:
                reason_out[x] = REASON_LEFT_RIGHT


@nb.njit(cache=True, nogil=True)
def _winner_state(width, num, dmin):
    pad = num + abs(dmin) + 1
    return (np.empty(width * num, np.int16), np.empty(width + 2 * pad, np.int16),
            np.zeros(width + 2 * pad, np.int16), np.empty(width, np.int32))


@nb.njit(cache=True, nogil=True)
def winners_rows_lanes(s_a, s_b, cost, el, count, dmin, uniq, lr_tol, subpixel, energy_min,
                       top, scale, y0, y1, disp_out, cost_out, reason_out, rdisp_out):
    """:func:`slitcli.stereo._sgm.winners_rows` (same arguments, same results bit for
    bit) in 16-lane vectors; D a multiple of 16."""
    _, width, num = s_a.shape
    sums, rsum, ridx, best_i = _winner_state(width, num, dmin)
    sa16 = s_a.view(np.int16)
    sb16 = s_b.view(np.int16)
    c16 = cost.view(np.int16)
    for y in range(y0, y1):
        k = y * width * num
        _winner_row(offset(ptr(sa16), k), offset(ptr(sb16), k), offset(ptr(c16), k), el[y],
                    count[y], dmin, uniq, lr_tol, subpixel, energy_min, np.int32(top), scale,
                    sums, rsum, ridx, best_i, disp_out[y], cost_out[y], reason_out[y],
                    rdisp_out[y])


# ---- Eq. 10 costs in 8-lane float32 vectors: slitcli.stereo._sgm.cost_rows with the
# same operations in the same order (no contraction), so the same quantised costs.


@nb.njit(cache=True, nogil=True, inline="always")
def _column_slide_lanes(col, ra, rs, a, b, blocks):
    va = splatf8(a)
    vb = splatf8(b)
    for j in range(blocks):
        k = j * 8
        storef8(col, k, vadd(loadf8(col, k), vsub(vmul(va, loadf8(ra, k)),
                                                  vmul(vb, loadf8(rs, k)))))


@nb.njit(cache=True, nogil=True, inline="always")
def _pixel_costs_lanes(hs, col_in, col_out, wa, ws, e1, r1, err, irr, top, scale, c_max, out,
                       blocks):
    vwa = splatf8(wa)
    vws = splatf8(ws)
    ve1 = splatf8(e1)
    vr1 = splatf8(r1)
    two = splatf8(np.float32(2.0))
    zero = splatf8(np.float32(0.0))
    cm = splatf8(c_max)
    sc = splatf8(scale)
    half = splatf8(np.float32(0.5))
    for j in range(blocks):
        k = j * 8
        x = vsub(vadd(loadf8(hs, k), vmul(vwa, loadf8(col_in, k))),
                 vmul(vws, loadf8(col_out, k)))
        storef8(hs, k, x)
        w = vmul(vr1, loadf8(irr, k))
        c = vmul(vsub(vadd(ve1, loadf8(err, k)), vmul(two, x)), w)
        q = vadd(vmul(vmin(vmax(c, zero), cm), sc), half)
        store_u16_where_positive(out, k, q, w, top)


@nb.njit(cache=True, nogil=True)
def _cost_start(pl, prr_pad, pad, dmin, num, n, y0, col):
    """The vertical window sums of the cross term at row ``y0 - 1`` into ``col``."""
    height, width = pl.shape
    stride = prr_pad.shape[1]
    p_col = ptr(col)
    p_r = ptr(prr_pad)
    for yy in range(max(0, y0 - 1 - n), min(height, y0 + n)):
        for x in range(width):
            ra = offset(p_r, yy * stride + pad + width - 1 - x + dmin)
            _column_slide_lanes(offset(p_col, (x + 1) * num), ra, ra, pl[yy, x],
                                np.float32(0.0), num // 8)


@nb.njit(cache=True, nogil=True)
def _cost_row(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale, y, col,
              hs, o_row):
    """Row ``y`` of the quantised costs into ``o_row`` (pointer to W x D int16), the
    column sums ``col`` one row down first."""
    height, width = pl.shape
    blocks = num // 8
    stride = prr_pad.shape[1]
    top = np.int32(round(c_max * scale))
    sc = np.float32(scale)
    cm = np.float32(c_max)
    p_col = ptr(col)
    p_r = ptr(prr_pad)
    p_hs = ptr(hs)
    p_i = ptr(irr_pad)
    p_e = ptr(err_pad)
    ya = y + n
    ys = y - n - 1
    if ya < height or ys >= 0:
        for x in range(width):
            base = pad + width - 1 - x + dmin
            a = pl[ya, x] if ya < height else np.float32(0.0)
            b = pl[ys, x] if ys >= 0 else np.float32(0.0)
            ra = offset(p_r, min(ya, height - 1) * stride + base)
            rs = offset(p_r, max(ys, 0) * stride + base)
            _column_slide_lanes(offset(p_col, (x + 1) * num), ra, rs, a, b, blocks)
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
        _pixel_costs_lanes(p_hs, offset(p_col, (min(xa, width - 1) + 1) * num),
                           offset(p_col, (max(xs, -1) + 1) * num), wa, ws, e1, r1,
                           offset(p_e, k), offset(p_i, k), top, sc, cm,
                           offset(o_row, x * num), blocks)


@nb.njit(cache=True, nogil=True)
def cost_rows_lanes(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale,
                    y0, y1, out):
    """:func:`slitcli.stereo._sgm.cost_rows` (same arguments, same costs bit for bit)
    in 8-lane vectors; ``num`` a multiple of 8."""
    width = pl.shape[1]
    col = np.zeros((width + 1, num), np.float32)   # row 0: the zero column
    hs = np.zeros(num, np.float32)
    out16 = out.view(np.int16)
    _cost_start(pl, prr_pad, pad, dmin, num, n, y0, col)
    for y in range(y0, y1):
        _cost_row(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale, y,
                  col, hs, offset(ptr(out16), y * width * num))


# ---- fused passes: the cost of each row and the top-down sweep over it while it is in
# cache; the bottom-up sweep with the winner step of each row, its sums in a row buffer
# (no second volume). The same row kernels as above, so the same results.


@nb.njit(cache=True, nogil=True)
def first_sweep_rows(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale,
                     p1, p2, eight, grey, p2_grad, cost, s_a, y0, y1, with_cost, col, hs, bufs,
                     mins):
    """Rows y0..y1-1 of the top-down sweep into ``s_a``, each row's costs first (with
    ``with_cost``; the column sums ``col`` at row y0 - 1, :func:`_cost_start`) or read
    from ``cost`` (computed by another thread). ``bufs``, ``mins``: the sweep's state
    (:func:`_sweep_state`), carried from the rows before."""
    width = pl.shape[1]
    c16 = cost.view(np.int16)
    a16 = s_a.view(np.int16)
    for y in range(y0, y1):
        k = y * width * num
        c_row = offset(ptr(c16), k)
        if with_cost:
            _cost_row(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale, y,
                      col, hs, c_row)
        _sweep_row(c_row, offset(ptr(a16), k), grey, y, y, y - 1, False, np.int32(p1),
                   np.int32(p2), np.float32(p2_grad), eight, num // 16, bufs, mins)


@nb.njit(cache=True, nogil=True)
def cost_and_first_sweep(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max,
                         scale, p1, p2, eight, grey, p2_grad, cost, s_a):
    """Costs (H, W, D) uint16 into ``cost`` and the top-down sweep's sums into ``s_a``
    (:func:`cost_rows_lanes` and :func:`aggregate_pass_lanes`, row by row); D a
    multiple of 16."""
    height, width = pl.shape
    col = np.zeros((width + 1, num), np.float32)
    hs = np.zeros(num, np.float32)
    bufs, mins = _sweep_state(width, num)
    _cost_start(pl, prr_pad, pad, dmin, num, n, 0, col)
    first_sweep_rows(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale,
                     p1, p2, eight, grey, p2_grad, cost, s_a, 0, height, True, col, hs, bufs,
                     mins)


@nb.njit(cache=True, nogil=True)
def second_sweep_rows(cost, s_a, p1, p2, eight, grey, p2_grad, el, count, dmin, uniq, lr_tol,
                      subpixel, energy_min, top, scale, disp_out, cost_out, reason_out,
                      rdisp_out, v0, v1, winners, s_b, bufs, mins):
    """Visits v0..v1-1 of the bottom-up sweep (image row H - 1 - v), state ``bufs``,
    ``mins`` carried from the visits before. ``winners``: each row's winner step over
    ``s_a`` + the row's sums (:func:`winners_rows_lanes`); else the sums into ``s_b``."""
    height, width, num = cost.shape
    sums, rsum, ridx, best_i = _winner_state(width, num, dmin)
    row = np.empty(width * num, np.int16)
    c16 = cost.view(np.int16)
    a16 = s_a.view(np.int16)
    b16 = s_b.view(np.int16)
    for y in range(v0, v1):
        yy = height - 1 - y
        k = yy * width * num
        c_row = offset(ptr(c16), k)
        o_row = ptr(row) if winners else offset(ptr(b16), k)
        _sweep_row(c_row, o_row, grey, y, yy, yy + 1, True, np.int32(p1), np.int32(p2),
                   np.float32(p2_grad), eight, num // 16, bufs, mins)
        if winners:
            _winner_row(offset(ptr(a16), k), ptr(row), c_row, el[yy], count[yy], dmin, uniq,
                        lr_tol, subpixel, energy_min, np.int32(top), scale, sums, rsum, ridx,
                        best_i, disp_out[yy], cost_out[yy], reason_out[yy], rdisp_out[yy])


@nb.njit(cache=True, nogil=True)
def second_sweep_winners(cost, s_a, p1, p2, eight, grey, p2_grad, el, count, dmin, uniq,
                         lr_tol, subpixel, energy_min, top, scale, disp_out, cost_out,
                         reason_out, rdisp_out):
    """The bottom-up sweep (:func:`aggregate_pass_lanes`, ``reverse``) and, row by row,
    the winner step over ``s_a`` + its sums (:func:`winners_rows_lanes`)."""
    height, width, num = cost.shape
    bufs, mins = _sweep_state(width, num)
    second_sweep_rows(cost, s_a, p1, p2, eight, grey, p2_grad, el, count, dmin, uniq, lr_tol,
                      subpixel, energy_min, top, scale, disp_out, cost_out, reason_out,
                      rdisp_out, 0, height, True, cost, bufs, mins)
