"""Numba kernel of the Eq. 10 matcher: cost rows, winner-take-all, uniqueness, left-right.

The kernel walks the image one row at a time and keeps, per disparity, the running
vertical window sums of squared differences (``num_disparities x width`` floats per
thread), so the full cost volume is never stored. Loops run over 0-based slices
because numba's negative-index wraparound on offset indices would stop LLVM from
vectorising them. The kernel is compiled on first use and cached on disk
(``cache=True``), so only the first run on a machine pays the compile.
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


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _add_group(out, s, k0, size, first):
    """``out[x] (+)= s[x+k0] + ... + s[x+k0+size-1]`` for size in {1, 2, 4, 8}."""
    width = out.shape[0]
    a = s[k0:k0 + width + size - 1]
    if size == 8:
        if first:
            for x in range(width):
                out[x] = (a[x] + a[x + 1] + a[x + 2] + a[x + 3]
                          + a[x + 4] + a[x + 5] + a[x + 6] + a[x + 7])
        else:
            for x in range(width):
                out[x] += (a[x] + a[x + 1] + a[x + 2] + a[x + 3]
                           + a[x + 4] + a[x + 5] + a[x + 6] + a[x + 7])
    elif size == 4:
        if first:
            for x in range(width):
                out[x] = a[x] + a[x + 1] + a[x + 2] + a[x + 3]
        else:
            for x in range(width):
                out[x] += a[x] + a[x + 1] + a[x + 2] + a[x + 3]
    elif size == 2:
        if first:
            for x in range(width):
                out[x] = a[x] + a[x + 1]
        else:
            for x in range(width):
                out[x] += a[x] + a[x + 1]
    else:
        if first:
            for x in range(width):
                out[x] = a[x]
        else:
            for x in range(width):
                out[x] += a[x]


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _box_row_but_last(out, s, win):
    """``out[x] = s[x] + ... + s[x+win-2]``: all but the last term of a window sum.

    The window width is odd, so its last term is added by the caller's fused loop;
    the rest goes in unrolled groups of 8, 4 and 2 that LLVM vectorises over x.
    """
    k = 0
    first = True
    rest = win - 1
    while rest - k >= 8:
        _add_group(out, s, k, 8, first)
        first = False
        k += 8
    for size in (4, 2):
        if rest - k >= size:
            _add_group(out, s, k, size, first)
            first = False
            k += size
    if first:
        out[:] = 0.0


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _colsum_step(row, pl_add, pr_add, pl_sub, pr_sub, do_add, do_sub, d):
    """Slide one disparity's vertical window sums of squared differences down a row."""
    width = pl_add.shape[0]
    lo = max(0, d)
    hi = min(width, width + d)
    if lo >= hi:
        return
    r = row[lo:hi]
    a = pl_add[lo:hi]
    b = pr_add[lo - d:hi - d]
    e = pl_sub[lo:hi]
    f = pr_sub[lo - d:hi - d]
    if do_add and do_sub:
        for j in range(hi - lo):
            t = a[j] - b[j]
            u = e[j] - f[j]
            r[j] += t * t - u * u
    elif do_add:
        for j in range(hi - lo):
            t = a[j] - b[j]
            r[j] += t * t
    elif do_sub:
        for j in range(hi - lo):
            u = e[j] - f[j]
            r[j] -= u * u


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _border_cost(crow, ssd, last, cly, cry, x0, x1, lo, hi, d, m):
    """Eq. 10 with the window clipped to the columns both images have (left/right edges)."""
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
        crow[x] = (ssd[x] + last[x] + SSD_EPS) * f


@nb.njit(cache=True, fastmath=_FASTMATH, inline="always")
def _slide_energy(v, add, sub, do_add, do_sub):
    """Slide the vertical window sum of squared intensities ``v`` down one row."""
    if do_add and do_sub:
        for c in range(v.shape[0]):
            v[c] += add[c] * add[c] - sub[c] * sub[c]
    elif do_add:
        for c in range(v.shape[0]):
            v[c] += add[c] * add[c]
    elif do_sub:
        for c in range(v.shape[0]):
            v[c] -= sub[c] * sub[c]


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
    ssd = np.empty(width, np.float32)
    cost_bits = cost.view(np.int32)
    lkey = np.empty(width, np.int32)
    rkey = np.empty(width, np.int32)
    best_i = np.empty(width, np.int32)
    rbest_i = np.empty(width, np.int32)
    second = np.empty(width, np.float32)
    index_bits = 1
    while (1 << index_bits) < num:
        index_bits += 1
    index_mask = np.int32((1 << index_bits) - 1)
    key_mask = np.int32(~index_mask)
    inf_key = np.int32(0x7F800000 & ~index_mask)
    vl = np.zeros(width, np.float32)
    vr = np.zeros(width, np.float32)
    cly = np.empty(width + 1, np.float64)
    cry = np.empty(width + 1, np.float64)
    il = np.empty(width, np.float32)
    ir = np.empty(width, np.float32)
    inf = np.float32(np.inf)
    for r in range(max(0, y0 - n), min(height, y0 + n + 1)):
        _slide_energy(vl, pl[r], pl[r], True, False)
        _slide_energy(vr, pr[r], pr[r], True, False)
        for i in range(num):
            _colsum_step(colsum[i, m:m + width], pl[r], pr[r], pl[r], pr[r], True, False,
                         dmin + i)
    for y in range(y0, y1):
        ra = min(y + n, height - 1)
        rs = max(y - n - 1, 0)
        do_add = y > y0 and y + n < height
        do_sub = y > y0 and y - n - 1 >= 0
        pla, pra, pls, prs = pl[ra], pr[ra], pl[rs], pr[rs]
        _slide_energy(vl, pla, pls, do_add, do_sub)
        _slide_energy(vr, pra, prs, do_add, do_sub)
        _window_energy(vl, cly, il, m)
        _window_energy(vr, cry, ir, m)
        lkey[:] = inf_key
        rkey[:] = inf_key
        for i in range(num):
            d = dmin + i
            lo = max(0, d)
            hi = min(width, width + d)
            crow = cost[i]
            srow = colsum[i]
            _colsum_step(srow[m:m + width], pla, pra, pls, prs, do_add, do_sub, d)
            if lo >= hi:
                crow[:] = inf
                continue
            crow[:lo] = inf
            crow[hi:] = inf
            _box_row_but_last(ssd, srow, win)
            last = srow[win - 1:win - 1 + width]
            # interior: the whole window lies where both images have data
            a = min(lo + m, hi)
            b = max(hi - m, a)
            ci = crow[a:b]
            si = ssd[a:b]
            la = last[a:b]
            li = il[a:b]
            ri = ir[a - d:b - d]
            for j in range(b - a):
                ci[j] = (si[j] + la[j] + SSD_EPS) * li[j] * ri[j]
            # borders: the window clipped to the columns both images have (masked Eq. 10)
            _border_cost(crow, ssd, last, cly, cry, lo, a, lo, hi, d, m)
            _border_cost(crow, ssd, last, cly, cry, b, hi, lo, hi, d, m)
            # winner-take-all for the left and the right image at once on packed
            # (cost bits | index) keys: one vectorised integer min per side
            ii = np.int32(i)
            ck = cost_bits[i, lo:hi]
            lk = lkey[lo:hi]
            rk = rkey[lo - d:hi - d]
            for j in range(hi - lo):
                k = np.int32(np.int32(ck[j] & key_mask) | ii)
                lk[j] = k if k < lk[j] else lk[j]
                rk[j] = k if k < rk[j] else rk[j]
        for x in range(width):
            best_i[x] = np.int32(lkey[x] & index_mask) if lkey[x] < inf_key else -1
            rbest_i[x] = np.int32(rkey[x] & index_mask) if rkey[x] < inf_key else -1
        if uniq > 0.0:
            second[:] = inf
            for i in range(num):
                crow = cost[i]
                ii = np.int32(i)
                for x in range(width):
                    c = crow[x]
                    bi = best_i[x]
                    far = (ii < bi - 1) or (ii > bi + 1)
                    second[x] = c if (far and c < second[x]) else second[x]
        for x in range(width):
            i = best_i[x]
            c1v = cost[i, x] if i >= 0 else inf
            cost_out[y, x] = c1v
            if i < 0 or not (c1v < inf):
                disp_out[y, x] = np.nan
                reason_out[y, x] = REASON_NO_CANDIDATE
                continue
            d = dmin + i
            delta = np.float32(0.0)
            if subpixel and i > 0 and i < num - 1:
                cm = cost[i - 1, x]
                cp = cost[i + 1, x]
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


@nb.njit(cache=True, parallel=True, nogil=True)
def local_zncc(gl, gr, disp, r, out):
    """Zero-mean normalised correlation of the (2r+1)^2 neighbourhood at each disparity.

    For every pixel with a finite ``disp`` the left window around (x, y) is compared
    with the right window around (x - disp, y), the right image linearly interpolated
    along x; windows are clipped to the image. ``out`` gets the correlation in
    [-1, 1], 0 for flat windows and NaN where ``disp`` is NaN.
    """
    height, width = gl.shape
    for y in nb.prange(height):
        for x in range(width):
            d = disp[y, x]
            if not (d == d):
                out[y, x] = np.nan
                continue
            n = 0
            sl = 0.0
            sr = 0.0
            sll = 0.0
            srr = 0.0
            slr = 0.0
            for yy in range(max(0, y - r), min(height, y + r + 1)):
                for xl in range(max(0, x - r), min(width, x + r + 1)):
                    xr = xl - d
                    if xr < 0.0 or xr > width - 1:
                        continue
                    x0 = int(np.floor(xr))
                    t = xr - x0
                    x1 = min(x0 + 1, width - 1)
                    a = float(gl[yy, xl])
                    b = (1.0 - t) * float(gr[yy, x0]) + t * float(gr[yy, x1])
                    n += 1
                    sl += a
                    sr += b
                    sll += a * a
                    srr += b * b
                    slr += a * b
            if n < 2:
                out[y, x] = np.nan
                continue
            vl = sll - sl * sl / n
            vr = srr - sr * sr / n
            cov = slr - sl * sr / n
            out[y, x] = cov / np.sqrt(vl * vr) if vl > 1e-9 and vr > 1e-9 else 0.0
