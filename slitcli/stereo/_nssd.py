"""The compiled Eq. 10 matcher (numba): cost, winner-take-all, subpixel, uniqueness,
left-right and texture tests, for a band of rows (:func:`nssd_rows`).

The matcher walks the image one row at a time and keeps, per column, the running
vertical window sums of squared differences of all disparities (``width x
num_disparities`` floats per band, disparity-contiguous), so the full cost volume is
never stored. At pixel x one pass over the disparities slides column x + m down one
row, slides the window sums along x (one add and one subtract per disparity whatever
the window size), takes Eq. 10 and finds the pixel's winner and, along the same costs,
every right pixel's winner as minima over packed (cost | index) integer keys. These
per-pixel loops are small separate functions taking raw pointers (slitcli.stereo._simd
says why); they vectorise. Pixels whose window or disparities leave the image take a
slower general path (clipped windows, masked Eq. 10).

All sums are of integers below 2**24 (the prefiltered images are quantised), so they are
exact in float32 and the result does not depend on the order of the additions or on
how the rows are split into bands. No fastmath: under it LLVM turns a vectorised
``1 / sqrt`` into a CPU-dependent approximation; without it every quotient and root is
IEEE float32, vectorised or not. Compiled on first use and cached on disk
(``cache=True``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from slitcli.stereo._simd import bits, from_bits, offset, ptr
from slitcli.stereo.reasons import Reason

# An energy-free window (all zeros after prefiltering) makes Eq. 10 0/0; its inverse
# norm is set to this so every candidate that touches it costs more than any real one.
BIG_INV = np.float32(1e30)
# Added to the SSD so that 0 * BIG_INV**2 (two empty windows) becomes +inf, not 0.
SSD_EPS = np.float32(1e-3)
_INF_BITS = np.int32(0x7F800000)

# the codes this kernel writes (slitcli.stereo.reasons); compile-time constants
REASON_VALID = int(Reason.VALID)
REASON_NO_CANDIDATE = int(Reason.NO_CANDIDATE)
REASON_TEXTURE = int(Reason.TEXTURE)
REASON_UNIQUENESS = int(Reason.UNIQUENESS)
REASON_LEFT_RIGHT = int(Reason.LEFT_RIGHT)

_U = nb.uint64


@nb.njit(cache=True, error_model="numpy")
def _slide_energy(v, add, sub, wa, ws, n):
    """``v += wa add^2 - ws sub^2`` over n columns (vertical window energies)."""
    for c in range(n):
        v[c] += wa * (add[c] * add[c]) - ws * (sub[c] * sub[c])


@nb.njit(cache=True, error_model="numpy")
def _prefix(v, prefix, n):
    """Running sums of the column energies ``v`` (float64, exact), so the clipped
    windows of the masked Eq. 10 at the borders sum in O(1)."""
    acc = 0.0
    prefix[0] = 0.0
    for c in range(n):
        acc += v[c]
        prefix[c + 1] = acc


@nb.njit(cache=True, error_model="numpy")
def _window_energy_row(prefix, e_out, inv_out, m, width):
    """Clipped window energies of one row from the column prefix sums, and their
    inverse roots (IEEE-exact: the kernels of this module use no fastmath)."""
    a = min(m, width)
    b = max(width - m, a)
    for x in range(a):
        e_out[x] = np.float32(prefix[min(x + m, width - 1) + 1] - prefix[0])
    hi = offset(ptr(prefix), 2 * m + 1)
    lo = ptr(prefix)
    for x in range(a, b):
        e_out[x] = np.float32(hi[x - m] - lo[x - m])
    for x in range(b, width):
        e_out[x] = np.float32(prefix[width] - prefix[max(x - m, 0)])
    for x in range(width):
        e = e_out[x]
        inv_out[x] = np.float32(1.0) / np.sqrt(e) if e >= 0.5 else BIG_INV


@nb.njit(cache=True, error_model="numpy", inline="always")
def _border_x(cb, ssum, cly, cry, i0, i1, x, dmin, m, width):
    """Eq. 10 of pixel x for disparity indices i0..i1-1 whose window leaves the columns
    both images have: sums and energies over the clipped window (masked Eq. 10).
    Writes the costs' bit patterns to ``cb``."""
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
        cb[i] = bits((ssum[i] + SSD_EPS) * g)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _masked_norm(sl, sr):
    """Eq. 10's inverse norm over a clipped window pair (as in :func:`_border_x`),
    branch-free."""
    half = np.float32(0.5)
    low_l = sl < half
    low_r = sr < half
    inv = np.float32(1.0) / np.sqrt(max(sl, sr) if low_l or low_r else sl * sr)
    return BIG_INV * (BIG_INV if low_l and low_r else inv) if low_l or low_r else inv


@nb.njit(cache=True, error_model="numpy")
def _diagonal_norms(g, cly_hi, cly_lo, sr, n):
    """Inverse norms of the windows that the right image's left edge clips, for one
    offset k = x - d < m and n disparities from dmin: the left window is columns
    d .. d + k + m (``cly_hi`` = prefix from column dmin + k + m + 1, ``cly_lo`` from
    dmin), the right one columns 0 .. k + m (energy ``sr``)."""
    for i in range(n):
        g[i] = _masked_norm(np.float32(cly_hi[i] - cly_lo[i]), sr)


@nb.njit(cache=True, error_model="numpy")
def _right_edge_costs(cb, ssum, sl, cry_hi, cry_lo, n):
    """Eq. 10 bits of a pixel x > W-1-m whose left window (energy ``sl``) the image's
    right edge clips, for n disparities d from dmin (all <= x - m): the right window
    is columns x-m-d .. W-1-d (``cry_hi[-i]`` = prefix at W - d, ``cry_lo[-i]`` at
    x - m - d)."""
    for i in range(n):
        g = _masked_norm(sl, np.float32(cry_hi[-i] - cry_lo[-i]))
        cb[i] = bits((ssum[i] + SSD_EPS) * g)


# ---- per-pixel loops over the disparities (pointer arguments: slitcli.stereo._simd)


@nb.njit(cache=True, error_model="numpy")
def _column_sums(col, ra_r, rs_r, a, b, wa, ws, n):
    """Slide one column's vertical window sums of n disparities down one row:
    ``col += wa (a - ra_r)^2 - ws (b - rs_r)^2`` (``ra_r``, ``rs_r``: the mirrored
    right rows entering and leaving, from the column's first disparity; weights 0 or 1
    so every sum stays an exact integer)."""
    for i in range(n):
        t = a - ra_r[i]
        u = b - rs_r[i]
        col[i] += wa * (t * t) - ws * (u * u)


@nb.njit(cache=True, error_model="numpy")
def _slide_sums(ssum, col_in, col_out, n):
    """``ssum += col_in - col_out``: the window moves one column along x."""
    for i in range(n):
        ssum[i] += col_in[i] - col_out[i]


@nb.njit(cache=True, error_model="numpy")
def _fast_px(col, col_out, ssum, cb, ra_r, rs_r, rkey, irr, a, b, wa, ws, f, key_mask, n):
    """A pixel whose window and disparities all lie inside both images, one pass per
    disparity for each step: slide the entering column ``col`` down one row, slide the
    window sums along x, take Eq. 10 (bits into ``cb``), and lower the right pixels'
    keys ``rkey`` (``irr``: their inverse window norms). Returns the pixel's best
    packed (cost | index) key."""
    for i in range(n):
        t = a - ra_r[i]
        u = b - rs_r[i]
        c = col[i] + (wa * (t * t) - ws * (u * u))
        col[i] = c
        ssum[i] += c - col_out[i]
    lk = np.int32(0x7FFFFFFF)
    for i in range(n):
        k = bits((ssum[i] + SSD_EPS) * f * irr[i])
        cb[i] = k
        key = np.int32(np.int32(k & key_mask) | np.int32(i))
        lk = key if key < lk else lk
        rk = rkey[i]
        rkey[i] = key if key < rk else rk
    return lk


@nb.njit(cache=True, error_model="numpy")
def _interior_costs(cb, ssum, irr, f, n):
    """Eq. 10 bits of n disparities whose windows lie inside both images."""
    for i in range(n):
        cb[i] = bits((ssum[i] + SSD_EPS) * f * irr[i])


@nb.njit(cache=True, error_model="numpy")
def _keys(cb, rkey, i0, key_mask, n):
    """Best packed (cost | index) key of the n disparities from index i0, lowering
    the right pixels' keys."""
    lk = np.int32(0x7FFFFFFF)
    for k in range(n):
        key = np.int32(np.int32(cb[k] & key_mask) | np.int32(i0 + k))
        lk = key if key < lk else lk
        rk = rkey[k]
        rkey[k] = key if key < rk else rk
    return lk


@nb.njit(cache=True, error_model="numpy")
def _finish_row(best_i, c_0, c_m, c_p, second, rbest_i, el, disp_o, cost_o, reason_o, lr_o,
                width, dmin, num, m, uniq, lr_tol, subpixel, texture_min, rows_y):
    """Subpixel disparity, validity code and cost of one row from the winners (branch-
    free, so it vectorises; the quotient is IEEE-exact). ``best_i`` -1: no candidate;
    ``second``: best cost more than 1 px from the winner; ``rbest_i``: the right
    pixels' winners; ``el``: left window energies."""
    inf = np.float32(np.inf)
    lr_on = lr_tol >= 0.0
    uniq_on = uniq > 0.0
    tex_on = texture_min > 0
    # bitwise & and | (not and / or): no branches; and one output per loop, as LLVM
    # vectorises a loop only while it needs few run-time overlap checks
    for x in range(width):
        i = best_i[x]
        c1v = c_0[x]
        cm = c_m[x]
        cp = c_p[x]
        den = cm - 2.0 * c1v + cp
        refine = subpixel & (i > 0) & (i < num - 1) & (cm < inf) & (cp < inf) & (den > 0.0)
        delta = np.float32(0.5 * (cm - cp) / den)
        delta = delta if refine else np.float32(0.0)
        found = (i >= 0) & (c1v < inf)
        disp_o[x] = np.float32(dmin + i) + delta if found else np.float32(np.nan)
    for x in range(width):
        cost_o[x] = c_0[x]
    for x in range(width):
        # the left-right test's partner (a gather: its own loop)
        xr = x - (dmin + best_i[x])
        rb = rbest_i[min(max(xr, 0), width - 1)]
        bad = lr_on & ((xr < 0) | (xr >= width) | (abs(rb - best_i[x]) > lr_tol))
        lr_o[x] = np.uint8(1) if bad else np.uint8(0)
    for x in range(width):
        i = best_i[x]
        c1v = c_0[x]
        cols_x = np.float32(min(x + m, width - 1) - max(x - m, 0) + 1)
        flat = tex_on & (el[x] < texture_min * (rows_y * cols_x))
        reason = REASON_TEXTURE if flat else REASON_VALID
        reason = REASON_LEFT_RIGHT if lr_o[x] != 0 else reason
        reason = REASON_UNIQUENESS if uniq_on & (second[x] < c1v * (1.0 + uniq)) else reason
        found = (i >= 0) & (c1v < inf)
        reason_o[x] = reason if found else REASON_NO_CANDIDATE


@nb.njit(cache=True, error_model="numpy")
def _fast_run(x0, x1, width, m, dmin, num, p_col, p_ssum, p_cb, ra_row, rs_row, pla, pls,
              p_rkey, p_irr, il, key_mask, index_mask, inf_key, wa, ws, uniq_on, idx, best_i,
              c_0, c_m, c_p, second):
    """Pixels x0 .. x1 - 1 of a row of :func:`nssd_rows`, whose disparities and windows
    all lie inside both images: :func:`_fast_px`, then the winner's index and cost and
    its neighbours' costs (``best_i``, ``c_0``, ``c_m``, ``c_p``) and, with
    ``uniq_on``, the best cost more than 1 px from the winner (``second``). A function
    of its own (pointer arguments), so the pixel loop's few variables stay in registers.
    ``ra_row``, ``rs_row``: the mirrored right rows entering and leaving the window;
    ``pla``, ``pls``: the left ones."""
    m2 = 2 * m + 1
    inf = np.float32(np.inf)
    for x in range(x0, x1):
        c = x + m
        j0 = width - 1 - x + dmin
        jc = width - 1 - c + dmin
        lk = _fast_px(offset(p_col, (x + m2) * num), offset(p_col, x * num), p_ssum, p_cb,
                      offset(ra_row, jc), offset(rs_row, jc), offset(p_rkey, j0),
                      offset(p_irr, j0), pla[c], pls[c], wa, ws, il[x], key_mask, _U(num))
        if lk >= inf_key:
            best_i[x] = -1
            c_0[x] = inf
            continue
        bi = np.int32(lk & index_mask)
        best_i[x] = bi
        c_0[x] = from_bits(p_cb[bi])
        c_m[x] = from_bits(p_cb[bi - 1]) if bi >= 1 else inf
        c_p[x] = from_bits(p_cb[bi + 1]) if bi + 1 < num else inf
        if uniq_on:
            sb = _INF_BITS
            s32 = np.int32(bi - 1)
            for i in range(num):
                v = p_cb[i]
                v = _INF_BITS if np.uint32(np.int32(idx[i] - s32)) <= np.uint32(2) else v
                sb = v if v < sb else sb
            second[x] = from_bits(sb)


@nb.njit(cache=True, error_model="numpy", nogil=True)
def nssd_rows(pl, pr, prr, y0, y1, dmin, num, m, n, uniq, lr_tol, subpixel, texture_min,
              disp_out, cost_out, reason_out, rdisp_out):
    """Eq. 10 winner-take-all with subpixel, uniqueness, left-right and texture check.

    Parameters
    ----------
    pl, pr : (H, W) float32, C-contiguous
        Matched (prefiltered) left and right images, integer-valued.
    prr : (H, W) float32, C-contiguous
        ``pr`` mirrored left-right, so that the right pixels x - d of consecutive
        disparities are consecutive in memory.
    y0, y1 : int
        Rows y0 .. y1 - 1 are matched (the GIL is released: bands of rows can run
        on several threads; the result does not depend on the split, every sum is
        exact).
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
    texture_min : float32
        A pixel whose left window energy ``sum P_l^2`` (window clipped to the image) is
        below ``texture_min`` x its pixel count gets REASON_TEXTURE if it is otherwise
        valid (0 = off).
    disp_out, cost_out : (H, W) float32
        Disparity (NaN where no candidate) and Eq. 10 cost of the winner (+inf where
        none).
    reason_out : (H, W) uint8
        REASON_* code per pixel.
    rdisp_out : (H, W) float32
        The right image's own winner-take-all disparity per right pixel (whole pixels,
        read from the same costs as the left-right check; NaN where none): the right
        view's disparity image, for the depth-edge test of slitcli.stereo._boundary.
    """
    height, width = pl.shape
    m2 = 2 * m + 1
    # colsum row c + m + 1 holds column c (rows of columns outside the image stay 0)
    colsum = np.zeros((width + m2, num), np.float32)
    ssum = np.empty(num, np.float32)
    cb = np.empty(num, np.int32)              # bit patterns of the pixel's costs
    rkey = np.empty(width, np.int32)          # right best key, reversed column index
    best_i = np.empty(width, np.int32)
    rbest_i = np.empty(width, np.int32)
    c_0 = np.empty(width, np.float32)
    c_m = np.empty(width, np.float32)
    c_p = np.empty(width, np.float32)
    second = np.empty(width, np.float32)
    lr_fail = np.empty(width, np.uint8)
    zeros = np.zeros(max(width, num), np.float32)
    idx = np.arange(num).astype(np.int32)
    vl = np.zeros(width, np.float32)
    vr = np.zeros(width, np.float32)
    cly = np.empty(width + 1, np.float64)
    cry = np.empty(width + 1, np.float64)
    inf = np.float32(np.inf)
    index_bits = 1
    while (1 << index_bits) < num:
        index_bits += 1
    index_mask = np.int32((1 << index_bits) - 1)
    key_mask = np.int32(~index_mask)
    inf_key = np.int32(0x7F800000 & ~index_mask)
    one = np.float32(1.0)
    zero = np.float32(0.0)
    un = _U(num)
    il = np.empty(width, np.float32)
    ir = np.empty(width, np.float32)
    irr = np.empty(width, np.float32)
    er = np.empty(width, np.float32)
    el = np.empty(width, np.float32)
    # the clipped windows at the borders take the slow scalar path (_border_x) unless
    # the disparities are non-negative and the image is wider than the window: then
    # the left border's norms are a table per row (offset k = x - d < m, disparity)
    # and the right border's are computed per pixel, both vectorised
    fast_border = dmin >= 0 and width >= m2
    diag = np.empty((max(m, 1), num), np.float32)
    # pixels x0 .. x1 - 1 have every disparity and its window inside both images
    x0 = max(m, num - 1 + dmin + m, 0)
    x1 = min(width - m, width - m + dmin, width + dmin)
    # the band's first window: rows y0 - n .. y0 + n - 1 (row y0 + n is added below)
    for r in range(max(0, y0 - n), min(height, y0 + n)):
        p_zero = ptr(zeros)
        _slide_energy(ptr(vl), offset(ptr(pl), r * width), p_zero, one, zero, width)
        _slide_energy(ptr(vr), offset(ptr(pr), r * width), p_zero, one, zero, width)
        for c in range(width):
            lo = max(0, c - width + 1 - dmin)
            hi = min(num, c - dmin + 1)
            if lo < hi:
                rr = offset(ptr(prr), r * width + width - 1 - c + dmin + lo)
                _column_sums(offset(ptr(colsum), (c + m + 1) * num + lo), rr, rr, pl[r, c],
                             pl[r, c], one, zero, _U(hi - lo))
    for y in range(y0, y1):
        # numba frees an array after its last use: the pointers are taken here, in the
        # loop, so every array stays alive while they are used (slitcli.stereo._simd)
        p_el = ptr(el)
        p_il = ptr(il)
        p_ir = ptr(ir)
        p_irr = ptr(irr)
        p_er = ptr(er)
        p_col = ptr(colsum)
        p_ssum = ptr(ssum)
        p_cb = ptr(cb)
        p_rkey = ptr(rkey)
        p_prr = ptr(prr)
        p_pl = ptr(pl)
        p_pr = ptr(pr)
        p_zero = ptr(zeros)
        p_cly = ptr(cly)
        p_cry = ptr(cry)
        ra = min(y + n, height - 1)
        rs = max(y - n - 1, 0)
        wa = one if y + n < height else zero
        ws = one if y > y0 and y - n - 1 >= 0 else zero
        _slide_energy(ptr(vl), offset(p_pl, ra * width), offset(p_pl, rs * width), wa, ws,
                      width)
        _slide_energy(ptr(vr), offset(p_pr, ra * width), offset(p_pr, rs * width), wa, ws,
                      width)
        _prefix(vl, cly, width)
        _prefix(vr, cry, width)
        _window_energy_row(cly, p_el, p_il, m, width)
        rows_y = np.float32(min(y + n, height - 1) - max(y - n, 0) + 1)
        _window_energy_row(cry, p_er, p_ir, m, width)
        if fast_border:
            for k in range(m):
                nk = max(0, min(num, width - k - m - dmin))
                _diagonal_norms(offset(ptr(diag), k * num), offset(p_cly, dmin + k + m + 1),
                                offset(p_cly, dmin), np.float32(cry[k + m + 1] - cry[0]), nk)
        for j in range(_U(width)):
            irr[j] = ir[_U(width - 1) - j]
        rkey[:] = inf_key
        # column c enters the window at pixel c - m: columns 0 .. m-1 before pixel 0
        for c in range(min(m, width)):
            lo = max(0, c - width + 1 - dmin)
            hi = min(num, c - dmin + 1)
            if lo < hi:
                jc = width - 1 - c + dmin + lo
                _column_sums(offset(p_col, (c + m + 1) * num + lo),
                             offset(p_prr, ra * width + jc), offset(p_prr, rs * width + jc),
                             pl[ra, c], pl[rs, c], wa, ws, _U(hi - lo))
        # window sums of pixel -1: columns -m-1 .. m-1 (colsum rows 0 .. 2m)
        ssum[:] = 0.0
        for p in range(m2):
            _slide_sums(p_ssum, offset(p_col, p * num), p_zero, un)
        for x in range(width):
            if x0 <= x < x1:
                if x == x0:
                    _fast_run(x0, x1, width, m, dmin, num, p_col, p_ssum, p_cb,
                              offset(p_prr, ra * width), offset(p_prr, rs * width),
                              offset(p_pl, ra * width), offset(p_pl, rs * width), p_rkey,
                              p_irr, ptr(il), key_mask, index_mask, inf_key, wa, ws,
                              uniq > 0.0, ptr(idx), ptr(best_i), ptr(c_0), ptr(c_m),
                              ptr(c_p), ptr(second))
                continue
            c = x + m
            col_in = offset(p_col, (x + m2) * num)
            col_out = offset(p_col, x * num)
            j0 = width - 1 - x + dmin   # reversed right column of disparity index 0
            if c < width:
                lo = max(0, c - width + 1 - dmin)
                hi = min(num, c - dmin + 1)
                if lo < hi:
                    jc = width - 1 - c + dmin + lo
                    _column_sums(offset(col_in, lo), offset(p_prr, ra * width + jc),
                                 offset(p_prr, rs * width + jc), pl[ra, c], pl[rs, c],
                                 wa, ws, _U(hi - lo))
            _slide_sums(p_ssum, col_in, col_out, un)
            vlo = max(0, x - width + 1 - dmin)
            vhi = min(num, x - dmin + 1)
            if vlo >= vhi:
                best_i[x] = -1
                c_0[x] = inf
                continue
            if m <= x <= width - 1 - m:
                ilo = max(vlo, x + m + 1 - width - dmin)
                ihi = min(vhi, x - m - dmin + 1)
            else:
                ilo = vlo
                ihi = vlo
            if ilo >= ihi:
                ilo = vlo
                ihi = vlo
            if ilo < ihi:
                _interior_costs(offset(p_cb, ilo), offset(p_ssum, ilo),
                                offset(p_irr, j0 + ilo), il[x], _U(ihi - ilo))
            if fast_border and x <= width - 1 - m:
                # left border: every disparity of [ihi, vhi) has x - d < m
                for i in range(ihi, vhi):
                    cb[i] = bits((ssum[i] + SSD_EPS) * diag[x - dmin - i, i])
            elif fast_border and dmin + vhi - 1 <= x - m:
                _right_edge_costs(offset(p_cb, vlo), offset(p_ssum, vlo),
                                  np.float32(cly[width] - cly[x - m]),
                                  offset(p_cry, width - dmin - vlo),
                                  offset(p_cry, x - m - dmin - vlo), vhi - vlo)
            else:
                _border_x(cb, ssum, cly, cry, vlo, ilo, x, dmin, m, width)
                _border_x(cb, ssum, cly, cry, ihi, vhi, x, dmin, m, width)
            lk = _keys(offset(p_cb, vlo), offset(p_rkey, j0 + vlo), vlo, key_mask,
                       _U(vhi - vlo))
            if lk >= inf_key:
                best_i[x] = -1
                c_0[x] = inf
                continue
            bi = np.int32(lk & index_mask)
            best_i[x] = bi
            c_0[x] = from_bits(cb[bi])
            c_m[x] = from_bits(cb[bi - 1]) if bi - 1 >= vlo else inf
            c_p[x] = from_bits(cb[bi + 1]) if bi + 1 < vhi else inf
            if uniq > 0.0:
                # best cost more than 1 px from the winner (non-negative floats order
                # like their bits), the winner +-1 masked by one unsigned 32-bit compare
                # of the index (stays vectorised on 16 lanes)
                sb = _INF_BITS
                s32 = np.int32(bi - 1)
                for i in range(_U(vlo), _U(vhi)):
                    v = cb[i]
                    v = _INF_BITS if np.uint32(np.int32(idx[i] - s32)) <= np.uint32(2) else v
                    sb = v if v < sb else sb
                second[x] = from_bits(sb)
        for x in range(width):
            rk = rkey[width - 1 - x]
            rbest_i[x] = np.int32(rk & index_mask) if rk < inf_key else -1
            rdisp_out[y, x] = np.float32(dmin + rbest_i[x]) if rbest_i[x] >= 0 else np.nan
        _finish_row(ptr(best_i), ptr(c_0), ptr(c_m), ptr(c_p), ptr(second), ptr(rbest_i), p_el,
                    offset(ptr(disp_out), y * width), offset(ptr(cost_out), y * width),
                    offset(ptr(reason_out), y * width), ptr(lr_fail), width, dmin, num, m,
                    uniq, lr_tol, subpixel, texture_min, rows_y)
