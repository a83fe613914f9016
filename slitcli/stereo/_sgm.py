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

from slitcli.stereo.reasons import Reason

_FASTMATH = {"nsz", "arcp", "contract", "afn"}
REASON_VALID = int(Reason.VALID)
REASON_NO_CANDIDATE = int(Reason.NO_CANDIDATE)
REASON_TEXTURE = int(Reason.TEXTURE)
REASON_UNIQUENESS = int(Reason.UNIQUENESS)
REASON_LEFT_RIGHT = int(Reason.LEFT_RIGHT)


@nb.njit(cache=True, nogil=True, fastmath=_FASTMATH)
def cost_rows(pl, prr_pad, el, er_rev_pad, pad, dmin, num, m, n, c_max, scale, y0, y1, out):
    """Quantised Eq. 10 costs of rows y0..y1-1 into ``out`` (H, W, D) uint16.

    ``pl``: (H, W) float32 prefiltered left image; ``prr_pad``: (H, W + 2 pad) the
    prefiltered right image reversed along x, with ``pad`` zero columns each side, so
    right column ``x - d`` is ``prr_pad[:, pad + W - 1 - x + d]`` and the disparities of
    a pixel are contiguous; ``el``: (H, W) left window energies; ``er_rev_pad``:
    (H, W + 2 pad) the right window energies, reversed and padded likewise.
    """
    height, width = pl.shape
    col = np.zeros((width, num), np.float32)
    hs = np.zeros(num, np.float32)
    q = np.zeros(num, np.float32)
    top = np.float32(c_max * scale)
    sc = np.float32(scale)
    cm = np.float32(c_max)
    # the vertical window sums of the cross term at row y0 - 1 (rows y0-1-n..y0-1+n)
    for yy in range(max(0, y0 - 1 - n), min(height, y0 + n)):
        for x in range(width):
            a = pl[yy, x]
            base = pad + width - 1 - x + dmin
            for i in range(num):
                col[x, i] += a * prr_pad[yy, base + i]
    for y in range(y0, y1):
        ya = y + n
        ys = y - n - 1
        if ya < height:
            for x in range(width):
                a = pl[ya, x]
                base = pad + width - 1 - x + dmin
                for i in range(num):
                    col[x, i] += a * prr_pad[ya, base + i]
        if ys >= 0:
            for x in range(width):
                a = pl[ys, x]
                base = pad + width - 1 - x + dmin
                for i in range(num):
                    col[x, i] -= a * prr_pad[ys, base + i]
        for i in range(num):
            hs[i] = 0.0
        for xx in range(0, min(m, width)):
            for i in range(num):
                hs[i] += col[xx, i]
        for x in range(width):
            xa = x + m
            xs = x - m - 1
            if xa < width:
                for i in range(num):
                    hs[i] += col[xa, i]
            if xs >= 0:
                for i in range(num):
                    hs[i] -= col[xs, i]
            e1 = el[y, x]
            base = pad + width - 1 - x + dmin
            lo = x - (width - 1) - dmin      # i below lo: partner right of the image
            hi = x - dmin                    # i above hi: partner left of the image
            er_row = er_rev_pad[y, base:base + num]
            for i in range(num):
                e2 = er_row[i]
                den = e1 * e2
                c = (e1 + e2 - np.float32(2.0) * hs[i]) / np.sqrt(max(den, np.float32(1e-30)))
                c = min(max(c, np.float32(0.0)), cm) * sc + np.float32(0.5)
                ok = (den > np.float32(0.0)) & (i >= lo) & (i <= hi)
                q[i] = c if ok else top
            o = out[y, x]
            for i in range(num):
                o[i] = np.uint16(np.int32(q[i]))


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _step(cost, prev, prev_min, p1, p2, cur, num):
    """One path step: ``cur = cost + min(prev, prev -+ 1 + P1, prev_min + P2) - prev_min``;
    returns min(cur). Branch-free inner loop (the two ends apart), so it vectorises;
    the minimum is exact in any order (fastmath's reassociation is harmless here)."""
    big = prev_min + p2
    cur[0] = np.float32(cost[0]) + min(min(prev[0], prev[1] + p1), big) - prev_min
    for i in range(1, num - 1):
        v = min(min(prev[i], prev[i - 1] + p1), min(prev[i + 1] + p1, big))
        cur[i] = np.float32(cost[i]) + v - prev_min
    k = num - 1
    cur[k] = np.float32(cost[k]) + min(min(prev[k], prev[k - 1] + p1), big) - prev_min
    cur_min = cur[0]
    for i in range(1, num):
        cur_min = min(cur_min, cur[i])
    return cur_min


@nb.njit(cache=True, nogil=True, fastmath=True, inline="always")
def _start(cost, cur, num):
    """A path's first pixel: ``cur = cost``; returns min(cur)."""
    for i in range(num):
        cur[i] = np.float32(cost[i])
    cur_min = cur[0]
    for i in range(1, num):
        cur_min = min(cur_min, cur[i])
    return cur_min


@nb.njit(cache=True, nogil=True, fastmath=True)
def aggregate_pass(cost, p1, p2, eight, reverse, out):
    """Sum of the path costs of one sweep over the rows, (H, W, D) uint16 into ``out``.

    ``reverse`` False: the top-down sweep, paths left to right and from the top (and,
    with ``eight``, from the top-left and top-right); True: the same on the image
    turned by 180 degrees (right to left, bottom, bottom-right, bottom-left). Needs
    D >= 2.
    """
    height, width, num = cost.shape
    p1 = np.float32(p1)
    p2 = np.float32(p2)
    # previous row's path costs per (sweep) column and their minima
    t_prev = np.zeros((width, num), np.float32)
    tl_prev = np.zeros((width, num), np.float32)
    tr_prev = np.zeros((width, num), np.float32)
    t_cur = np.zeros((width, num), np.float32)
    tl_cur = np.zeros((width, num), np.float32)
    tr_cur = np.zeros((width, num), np.float32)
    t_min = np.zeros(width, np.float32)
    tl_min = np.zeros(width, np.float32)
    tr_min = np.zeros(width, np.float32)
    t_min_c = np.zeros(width, np.float32)
    tl_min_c = np.zeros(width, np.float32)
    tr_min_c = np.zeros(width, np.float32)
    h_a = np.zeros(num, np.float32)
    h_b = np.zeros(num, np.float32)
    for y in range(height):
        yy = height - 1 - y if reverse else y
        h_min = np.float32(0.0)
        for x in range(width):
            xx = width - 1 - x if reverse else x
            c = cost[yy, xx]
            if x == 0:
                h_min = _start(c, h_a, num)
            else:
                h_min = _step(c, h_b, h_min, p1, p2, h_a, num)
            if y == 0:
                t_min_c[x] = _start(c, t_cur[x], num)
            else:
                t_min_c[x] = _step(c, t_prev[x], t_min[x], p1, p2, t_cur[x], num)
            o = out[yy, xx]
            tc = t_cur[x]
            if eight:
                if y == 0 or x == 0:
                    tl_min_c[x] = _start(c, tl_cur[x], num)
                else:
                    tl_min_c[x] = _step(c, tl_prev[x - 1], tl_min[x - 1], p1, p2,
                                        tl_cur[x], num)
                if y == 0 or x == width - 1:
                    tr_min_c[x] = _start(c, tr_cur[x], num)
                else:
                    tr_min_c[x] = _step(c, tr_prev[x + 1], tr_min[x + 1], p1, p2,
                                        tr_cur[x], num)
                tlc = tl_cur[x]
                trc = tr_cur[x]
                for i in range(num):
                    o[i] = np.uint16(h_a[i] + tc[i] + tlc[i] + trc[i])
            else:
                for i in range(num):
                    o[i] = np.uint16(h_a[i] + tc[i])
            h_a, h_b = h_b, h_a
        t_prev, t_cur = t_cur, t_prev
        tl_prev, tl_cur = tl_cur, tl_prev
        tr_prev, tr_cur = tr_cur, tr_prev
        t_min, t_min_c = t_min_c, t_min
        tl_min, tl_min_c = tl_min_c, tl_min
        tr_min, tr_min_c = tr_min_c, tr_min


@nb.njit(cache=True, nogil=True, fastmath=_FASTMATH, inline="always")
def _right_view(by_d, off, dmin, num, width, big, rbest_v, rbest_i):
    """Right pixel xr takes its best left match x = xr + dmin + i over the row's sums
    stored by disparity (columns outside the image hold ``big``, so never win)."""
    for xr in range(width):
        rbest_v[xr] = big
        rbest_i[xr] = -1
    for i in range(num):
        row_i = by_d[i, off + dmin + i:off + dmin + i + width]
        for xr in range(width):
            v = row_i[xr]
            better = v < rbest_v[xr]
            rbest_i[xr] = i if better else rbest_i[xr]
            rbest_v[xr] = v if better else rbest_v[xr]


@nb.njit(cache=True, nogil=True, fastmath=_FASTMATH, inline="always")
def _row_codes(best_i, rbest_i, uq, dmin, width, lr_tol, codes):
    """Left-right and uniqueness codes of one row, in the local matcher's precedence
    (uniqueness over left-right over texture)."""
    for x in range(width):
        bi = best_i[x]
        if bi < 0:
            continue
        if lr_tol >= 0:
            xr = x - dmin - bi
            ok = (xr >= 0) and (xr < width)
            if not ok or rbest_i[xr] < 0 or abs(rbest_i[xr] - bi) > lr_tol:
                codes[x] = REASON_LEFT_RIGHT
        if uq[x]:
            codes[x] = REASON_UNIQUENESS


@nb.njit(cache=True, nogil=True, fastmath=_FASTMATH)
def winners_rows(s_a, s_b, cost, el, count, dmin, uniq, lr_tol, subpixel, energy_min, top,
                 scale, y0, y1, disp_out, cost_out, reason_out, rdisp_out):
    """Winner-take-all over ``s_a + s_b`` for rows y0..y1-1 with the validity tests.

    ``cost``: the quantised Eq. 10 volume (a pixel without any candidate below ``top``
    has no candidate); ``el``, ``count``: window energy and pixel count (texture test:
    ``el < energy_min count``); ``uniq``: no disparity more than 1 px from the winner
    may have a sum below ``(1 + uniq)`` times the winner's; ``lr_tol`` < 0: no
    left-right test. Writes disparity (float32, NaN where none), the winner's Eq. 10
    cost (``cost / scale``), the reason code and the right view's integer disparities.
    A uniqueness failure is held as code + 100 until the row's left-right test is done
    (uniqueness takes precedence), then stored as its code.
    """
    _, width, num = s_a.shape
    big = np.float32(3.0e38)
    t = np.empty(num, np.float32)
    # the row's sums by disparity (D, W + D + |dmin|): the right view reads, for each
    # disparity, a contiguous run of left columns (a vectorised loop per disparity)
    off = num + abs(dmin)
    by_d = np.full((num, width + 2 * off), big, np.float32)
    best_i = np.empty(width, np.int32)
    rbest_v = np.empty(width, np.float32)
    rbest_i = np.empty(width, np.int32)
    uq = np.empty(width, np.bool_)
    for y in range(y0, y1):
        for x in range(width):
            sa = s_a[y, x]
            sb = s_b[y, x]
            cv = cost[y, x]
            # candidates: partner inside the right image and a window with energy
            for i in range(num):
                v = np.float32(sa[i]) + np.float32(sb[i])
                t[i] = v if cv[i] < top else big
            for i in range(num):
                by_d[i, off + x] = t[i]
            bv = t[0]
            for i in range(1, num):
                bv = min(bv, t[i])
            bi = num
            for i in range(num - 1, -1, -1):
                bi = i if t[i] == bv else bi
            bi = bi if bv < big else -1
            best_i[x] = bi
            if bi < 0:
                disp_out[y, x] = np.nan
                cost_out[y, x] = np.inf
                reason_out[y, x] = REASON_NO_CANDIDATE
                uq[x] = False
                continue
            second = big
            for i in range(num):
                far = (i < bi - 1) | (i > bi + 1)
                second = min(second, t[i] if far else big)
            delta = np.float32(0.0)
            if subpixel and 0 < bi < num - 1:
                cm = t[bi - 1]
                cp = t[bi + 1]
                den = cm - np.float32(2.0) * bv + cp
                if den > 0 and cm < big and cp < big:
                    delta = np.float32(0.5) * (cm - cp) / den
            disp_out[y, x] = np.float32(dmin + bi) + delta
            cost_out[y, x] = np.float32(cv[bi]) / np.float32(scale)
            uq[x] = (uniq > 0) & (second < bv * (np.float32(1.0) + uniq))
            tex = (energy_min > 0) & (el[y, x] < energy_min * count[y, x])
            reason_out[y, x] = REASON_TEXTURE if tex else REASON_VALID
        _right_view(by_d, off, dmin, num, width, big, rbest_v, rbest_i)
        for xr in range(width):
            rdisp_out[y, xr] = np.float32(dmin + rbest_i[xr]) if rbest_i[xr] >= 0 else np.nan
        _row_codes(best_i, rbest_i, uq, dmin, width, lr_tol, reason_out[y])
