"""Numba kernel of the Eq. 10 matcher: cost rows, winner-take-all, uniqueness, left-right.

The kernel walks the image one row at a time and keeps, per disparity, the running
vertical window sums of squared differences (``num_disparities x width`` floats per
thread), so the full cost volume is never stored. Hot loops index whole arrays with
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

# invalid_reason codes (documented in docs/stereo.md); 2 (texture) and 5 (speckle) are
# set by the caller
REASON_VALID = 0
REASON_NO_CANDIDATE = 1
REASON_UNIQUENESS = 3
REASON_LEFT_RIGHT = 4


_U = nb.uint64


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _colsum_step(colsum, i, pl, pr, ra, rs, do_add, do_sub, d, m, width):
    """Slide disparity i's vertical window sums of squared differences down one row."""
    lo = max(0, d)
    hi = min(width, width + d)
    if lo >= hi:
        return
    n = _U(hi - lo)
    ui = _U(i)
    cb = _U(m + lo)
    lb = _U(lo)
    rb = _U(lo - d)
    ua = _U(ra)
    us = _U(rs)
    if do_add and do_sub:
        for j in range(n):
            t = pl[ua, lb + j] - pr[ua, rb + j]
            u = pl[us, lb + j] - pr[us, rb + j]
            colsum[ui, cb + j] += t * t - u * u
    elif do_add:
        for j in range(n):
            t = pl[ua, lb + j] - pr[ua, rb + j]
            colsum[ui, cb + j] += t * t
    elif do_sub:
        for j in range(n):
            u = pl[us, lb + j] - pr[us, rb + j]
            colsum[ui, cb + j] -= u * u


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _box_but_last(ssd, colsum, i, win, width):
    """``ssd[x] = colsum[i, x] + ... + colsum[i, x + win - 2]`` (all but the last term).

    The window width is odd, so its last term is added by the caller's cost loop; the
    rest goes in unrolled groups of 8, 4 and 2 that LLVM vectorises over x.
    """
    ui = _U(i)
    w = _U(width)
    k = 0
    first = True
    rest = win - 1
    while rest - k >= 8:
        o = _U(k)
        if first:
            for x in range(w):
                ssd[x] = (colsum[ui, o + x] + colsum[ui, o + x + _U(1)]
                          + colsum[ui, o + x + _U(2)] + colsum[ui, o + x + _U(3)]
                          + colsum[ui, o + x + _U(4)] + colsum[ui, o + x + _U(5)]
                          + colsum[ui, o + x + _U(6)] + colsum[ui, o + x + _U(7)])
        else:
            for x in range(w):
                ssd[x] += (colsum[ui, o + x] + colsum[ui, o + x + _U(1)]
                           + colsum[ui, o + x + _U(2)] + colsum[ui, o + x + _U(3)]
                           + colsum[ui, o + x + _U(4)] + colsum[ui, o + x + _U(5)]
                           + colsum[ui, o + x + _U(6)] + colsum[ui, o + x + _U(7)])
        first = False
        k += 8
    if rest - k >= 4:
        o = _U(k)
        if first:
            for x in range(w):
                ssd[x] = (colsum[ui, o + x] + colsum[ui, o + x + _U(1)]
                          + colsum[ui, o + x + _U(2)] + colsum[ui, o + x + _U(3)])
        else:
            for x in range(w):
                ssd[x] += (colsum[ui, o + x] + colsum[ui, o + x + _U(1)]
                           + colsum[ui, o + x + _U(2)] + colsum[ui, o + x + _U(3)])
        first = False
        k += 4
    if rest - k >= 2:
        o = _U(k)
        if first:
            for x in range(w):
                ssd[x] = colsum[ui, o + x] + colsum[ui, o + x + _U(1)]
        else:
            for x in range(w):
                ssd[x] += colsum[ui, o + x] + colsum[ui, o + x + _U(1)]
        first = False
        k += 2
    if first:
        for x in range(w):
            ssd[x] = 0.0


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _border_cost(cost, i, ssd, colsum, cly, cry, x0, x1, lo, hi, d, m):
    """Eq. 10 with the window clipped to the columns both images have (left/right edges)."""
    win = 2 * m + 1
    for x in range(x0, x1):
        c0 = max(x - m, lo)
        c1 = min(x + m, hi - 1)
        sl = np.float32(cly[c1 + 1] - cly[c0])
        sr = np.float32(cry[c1 + 1 - d] - cry[c0 - d])
        if sl < 0.5 or sr < 0.5:
            f = BIG_INV * (BIG_INV if sl < 0.5 and sr < 0.5 else
                           np.float32(1.0) / np.sqrt(max(sl, sr)))
        else:
            f = np.float32(1.0) / np.sqrt(sl * sr)
        cost[i, x] = (ssd[x] + colsum[i, x + win - 1] + SSD_EPS) * f


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
    for x in range(width):
        e = prefix[min(x + m, width - 1) + 1] - prefix[max(x - m, 0)]
        inv[x] = BIG_INV if e < 0.5 else np.float32(1.0 / np.sqrt(e))


@nb.njit(cache=True, fastmath=_FASTMATH)
def _band(pl, pr, y0, y1, dmin, num, m, n, uniq, lr_tol, subpixel,
          disp_out, cost_out, reason_out):
    height, width = pl.shape
    win = 2 * m + 1
    colsum = np.zeros((num, width + 2 * m), np.float32)
    cost = np.empty((num, width), np.float32)
    cost_bits = cost.view(np.int32)
    ssd = np.empty(width, np.float32)
    lkey = np.empty(width, np.int32)
    rkey = np.empty(width, np.int32)
    best_i = np.empty(width, np.int32)
    rbest_i = np.empty(width, np.int32)
    second = np.empty(width, np.float32)
    c_0 = np.empty(width, np.float32)
    c_m = np.empty(width, np.float32)
    c_p = np.empty(width, np.float32)
    vl = np.zeros(width, np.float32)
    vr = np.zeros(width, np.float32)
    cly = np.empty(width + 1, np.float64)
    cry = np.empty(width + 1, np.float64)
    il = np.empty(width, np.float32)
    ir = np.empty(width, np.float32)
    inf = np.float32(np.inf)
    index_bits = 1
    while (1 << index_bits) < num:
        index_bits += 1
    index_mask = np.int32((1 << index_bits) - 1)
    key_mask = np.int32(~index_mask)
    inf_key = np.int32(0x7F800000 & ~index_mask)
    for r in range(max(0, y0 - n), min(height, y0 + n + 1)):
        _slide_energy(vl, pl, r, r, True, False)
        _slide_energy(vr, pr, r, r, True, False)
        for i in range(num):
            _colsum_step(colsum, i, pl, pr, r, r, True, False, dmin + i, m, width)
    for y in range(y0, y1):
        ra = min(y + n, height - 1)
        rs = max(y - n - 1, 0)
        do_add = y > y0 and y + n < height
        do_sub = y > y0 and y - n - 1 >= 0
        _slide_energy(vl, pl, ra, rs, do_add, do_sub)
        _slide_energy(vr, pr, ra, rs, do_add, do_sub)
        _window_energy(vl, cly, il, m)
        _window_energy(vr, cry, ir, m)
        lkey[:] = inf_key
        rkey[:] = inf_key
        for i in range(num):
            d = dmin + i
            lo = max(0, d)
            hi = min(width, width + d)
            ui = _U(i)
            _colsum_step(colsum, i, pl, pr, ra, rs, do_add, do_sub, d, m, width)
            for x in range(0, max(lo, 0)):
                cost[i, x] = inf
            for x in range(max(hi, 0), width):
                cost[i, x] = inf
            if lo >= hi:
                continue
            _box_but_last(ssd, colsum, i, win, width)
            # interior: the whole window lies where both images have data
            a = min(lo + m, hi)
            b = max(hi - m, a)
            ua = _U(a)
            ur = _U(a - d)
            ul = _U(win - 1) + ua
            for j in range(_U(b - a)):
                cost[ui, ua + j] = ((ssd[ua + j] + colsum[ui, ul + j] + SSD_EPS)
                                    * il[ua + j] * ir[ur + j])
            # borders: the window clipped to the columns both images have (masked Eq. 10)
            _border_cost(cost, i, ssd, colsum, cly, cry, lo, a, lo, hi, d, m)
            _border_cost(cost, i, ssd, colsum, cly, cry, b, hi, lo, hi, d, m)
            # winner-take-all for the left and the right image at once on packed
            # (cost bits | index) keys: one vectorised integer min per side
            ii = np.int32(i)
            ulo = _U(lo)
            urr = _U(lo - d)
            for j in range(_U(hi - lo)):
                k = np.int32(np.int32(cost_bits[ui, ulo + j] & key_mask) | ii)
                lk = lkey[ulo + j]
                lkey[ulo + j] = k if k < lk else lk
                rk = rkey[urr + j]
                rkey[urr + j] = k if k < rk else rk
        for x in range(width):
            best_i[x] = np.int32(lkey[x] & index_mask) if lkey[x] < inf_key else -1
            rbest_i[x] = np.int32(rkey[x] & index_mask) if rkey[x] < inf_key else -1
        # costs around each winner, kept for the parabola before they are masked out
        for x in range(width):
            i = best_i[x]
            c_0[x] = cost[i, x] if i >= 0 else inf
            c_m[x] = cost[i - 1, x] if i >= 1 else inf
            c_p[x] = cost[i + 1, x] if 0 <= i < num - 1 else inf
        if uniq > 0.0:
            # second best away from the winner: mask winner +-1, then a plain min
            for x in range(width):
                i = best_i[x]
                for k in range(max(i - 1, 0), min(i + 2, num)):
                    cost[k, x] = inf
            second[:] = inf
            uw = _U(width)
            for i in range(num):
                ui = _U(i)
                for x in range(uw):
                    c = cost[ui, x]
                    s2 = second[x]
                    second[x] = c if c < s2 else s2
        for x in range(width):
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


@nb.njit(cache=True, parallel=True, nogil=True)
def nssd_match(pl, pr, dmin, num, m, n, uniq, lr_tol, subpixel, bands,
               disp_out, cost_out, reason_out):
    """Match rows in parallel bands; see :func:`slitcli.stereo.matcher.match_nssd`."""
    height = pl.shape[0]
    for b in nb.prange(bands):
        y0 = b * height // bands
        y1 = (b + 1) * height // bands
        _band(pl, pr, y0, y1, dmin, num, m, n, uniq, lr_tol, subpixel,
              disp_out, cost_out, reason_out)

