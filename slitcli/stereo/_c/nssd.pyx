# cflags: -fno-math-errno -fno-trapping-math -funroll-loops
# (value-preserving: sqrtf need not set errno and no operation traps, so the compiler may
# compute a quotient or root on lanes that a select then discards and the loops vectorise,
# as they did under LLVM; no reassociation, no contraction: every result keeps its bits;
# unrolled as LLVM unrolls its vector loops)
"""The compiled Eq. 10 matcher: cost, winner-take-all, subpixel, uniqueness, left-right
and texture tests, for a band of rows (:func:`nssd_rows`).

The matcher walks the image one row at a time and keeps, per column, the running
vertical window sums of squared differences of all disparities (``width x
num_disparities`` floats per band, disparity-contiguous), so the full cost volume is
never stored. At pixel x one pass over the disparities slides column x + m down one
row, slides the window sums along x (one add and one subtract per disparity whatever
the window size), takes Eq. 10 and finds the pixel's winner and, along the same costs,
every right pixel's winner as minima over packed (cost | index) integer keys. These
per-pixel loops are small functions of their own over ``__restrict__`` pointers
(slitcli/stereo/_c/nssd_loops.pxd: the arrays they write never overlap the ones they
read), so the C compiler vectorises them without run-time overlap checks. Pixels whose
window or disparities leave the image take a slower general path (clipped windows,
masked Eq. 10).

All sums are of integers below 2**24 (the prefiltered images are quantised), so they are
exact in float32 and the result does not depend on the order of the additions or on
how the rows are split into bands. No reassociation or fast reciprocal: every quotient
and root is IEEE float32 (float64 where the source mixes in a double), vectorised or
not, in the operation order written here, so the results are the same bits on every
x86-64 machine.
"""

from libc.math cimport sqrtf
from libc.stdint cimport int32_t, uint8_t

from slitcli.stereo._c.nssd_loops cimport (
    BIG_INV,
    INF,
    INF_BITS,
    NAN,
    SSD_EPS,
    _column_sums,
    _diagonal_norms,
    _fast_px,
    _interior_costs,
    _keys,
    _prefix,
    _right_edge_costs,
    _second_bits,
    _slide_energy,
    _slide_sums,
    _window_energy_row,
    bits,
    fmax_,
    from_bits,
)

import numpy as np

from slitcli.stereo.reasons import Reason

#: the float32 constants of Eq. 10 (as the kernel uses them)
BIG_INV_F32 = np.float32(1e30)
SSD_EPS_F32 = np.float32(1e-3)

# the codes this kernel writes (slitcli.stereo.reasons), read once at import
cdef uint8_t REASON_VALID = int(Reason.VALID)
cdef uint8_t REASON_NO_CANDIDATE = int(Reason.NO_CANDIDATE)
cdef uint8_t REASON_TEXTURE = int(Reason.TEXTURE)
cdef uint8_t REASON_UNIQUENESS = int(Reason.UNIQUENESS)
cdef uint8_t REASON_LEFT_RIGHT = int(Reason.LEFT_RIGHT)


cdef struct Band:
    # image and disparity geometry; x0 .. x1 - 1: pixels whose disparities and windows
    # all lie inside both images
    Py_ssize_t height, width, dmin, num, m, n, m2, x0, x1
    double uniq, lr_tol
    bint subpixel, fast_border
    float texture_min
    int32_t index_mask, key_mask, inf_key
    const float *pl
    const float *pr
    const float *prr
    float *disp
    float *cost
    float *rdisp
    uint8_t *reason
    # per-row state: the rows entering (ra) and leaving (rs) the window, their weights
    Py_ssize_t ra, rs
    float wa, ws, rows_y
    # scratch
    float *colsum
    float *ssum
    int32_t *cb
    int32_t *rkey
    int32_t *best_i
    int32_t *rbest_i
    float *c_0
    float *c_m
    float *c_p
    float *second
    uint8_t *lr_fail
    float *zeros
    float *vl
    float *vr
    double *cly
    double *cry
    float *il
    float *ir
    float *irr
    float *el
    float *er
    float *diag


cdef inline void _border_x(Band *b, Py_ssize_t i0, Py_ssize_t i1,
                           Py_ssize_t x) noexcept nogil:
    """Eq. 10 of pixel x for disparity indices i0..i1-1 whose window leaves the columns
    both images have: sums and energies over the clipped window (masked Eq. 10).
    Writes the costs' bit patterns to ``cb``."""
    cdef Py_ssize_t i, d, lo, hi, c0, c1
    cdef float sl, sr, g
    for i in range(i0, i1):
        d = b.dmin + i
        lo = max(0, d)
        hi = min(b.width, b.width + d)
        c0 = max(x - b.m, lo)
        c1 = min(x + b.m, hi - 1)
        sl = <float>(b.cly[c1 + 1] - b.cly[c0])
        sr = <float>(b.cry[c1 + 1 - d] - b.cry[c0 - d])
        if sl < 0.5 or sr < 0.5:
            g = BIG_INV * (BIG_INV if sl < 0.5 and sr < 0.5 else
                           <float>1.0 / sqrtf(fmax_(sl, sr)))
        else:
            g = <float>1.0 / sqrtf(sl * sr)
        b.cb[i] = bits((b.ssum[i] + SSD_EPS) * g)


cdef void _finish_row(Band *b, Py_ssize_t y) noexcept nogil:
    """Subpixel disparity, validity code and cost of row y from the winners (branch-
    free, so it vectorises; the quotient is IEEE-exact). ``best_i`` -1: no candidate;
    ``second``: best cost more than 1 px from the winner; ``rbest_i``: the right
    pixels' winners; ``el``: left window energies."""
    cdef Py_ssize_t x, xr, dd, width = b.width, m = b.m, dmin = b.dmin, num = b.num
    cdef const int32_t *best_i = b.best_i
    cdef const int32_t *rbest_i = b.rbest_i
    cdef const float *c_0 = b.c_0
    cdef const float *c_m = b.c_m
    cdef const float *c_p = b.c_p
    cdef const float *second = b.second
    cdef const float *el = b.el
    cdef float *disp_o = b.disp + y * width
    cdef float *cost_o = b.cost + y * width
    cdef uint8_t *reason_o = b.reason + y * width
    cdef uint8_t *lr_o = b.lr_fail
    cdef bint lr_on = b.lr_tol >= 0.0
    cdef bint uniq_on = b.uniq > 0.0
    cdef bint tex_on = b.texture_min > 0
    cdef bint refine, found, bad, flat
    cdef int32_t i, rb
    cdef float c1v, cm, cp, delta, cols_x, tex = b.texture_min, rows_y = b.rows_y
    cdef double den, lr_tol = b.lr_tol, uniq1 = 1.0 + b.uniq
    cdef uint8_t reason, r_valid = REASON_VALID, r_none = REASON_NO_CANDIDATE
    cdef uint8_t r_tex = REASON_TEXTURE, r_uniq = REASON_UNIQUENESS
    cdef uint8_t r_lr = REASON_LEFT_RIGHT
    # 32-bit ints where an int becomes a float (exact either way, below 2**24): AVX2
    # converts 32-bit vectors, not 64-bit ones
    cdef int32_t xi, dmin32 = <int32_t>dmin, m32 = <int32_t>m, w1 = <int32_t>width - 1
    for x in range(width):
        i = best_i[x]
        c1v = c_0[x]
        cm = c_m[x]
        cp = c_p[x]
        den = cm - 2.0 * c1v + cp
        refine = (b.subpixel & (i > 0) & (i < num - 1) & (cm < INF) & (cp < INF)
                  & (den > 0.0))
        delta = <float>(0.5 * (cm - cp) / den)
        delta = delta if refine else <float>0.0
        found = (i >= 0) & (c1v < INF)
        disp_o[x] = (<float>(dmin32 + i) + delta) if found else NAN
    for x in range(width):
        cost_o[x] = c_0[x]
    for x in range(width):
        # the left-right test's partner (a gather: its own loop)
        xr = x - (dmin + best_i[x])
        rb = rbest_i[min(max(xr, 0), width - 1)]
        dd = <Py_ssize_t>rb - best_i[x]
        dd = dd if dd >= 0 else -dd
        bad = lr_on & ((xr < 0) | (xr >= width) | (<double>dd > lr_tol))
        lr_o[x] = 1 if bad else 0
    for xi in range(<int32_t>width):
        i = best_i[xi]
        c1v = c_0[xi]
        cols_x = <float>(min(xi + m32, w1) - max(xi - m32, 0) + 1)
        flat = tex_on & (el[xi] < tex * (rows_y * cols_x))
        reason = r_tex if flat else r_valid
        reason = r_lr if lr_o[xi] != 0 else reason
        reason = r_uniq if uniq_on & (second[xi] < c1v * uniq1) else reason
        found = (i >= 0) & (c1v < INF)
        reason_o[xi] = reason if found else r_none


cdef void _fast_run(Band *b, Py_ssize_t x0, Py_ssize_t x1) noexcept nogil:
    """Pixels x0 .. x1 - 1 of the current row, whose disparities and windows all lie
    inside both images: :func:`_fast_px`, then the winner's index and cost and its
    neighbours' costs (``best_i``, ``c_0``, ``c_m``, ``c_p``) and, with uniqueness on,
    the best cost more than 1 px from the winner (``second``). Its own function, so the
    pixel loop's few variables stay in registers."""
    cdef Py_ssize_t x, c, j0, jc, width = b.width, m = b.m, num = b.num, dmin = b.dmin
    cdef Py_ssize_t m2 = b.m2
    cdef float *col = b.colsum
    cdef float *ssum = b.ssum
    cdef int32_t *cb = b.cb
    cdef int32_t *rkey = b.rkey
    cdef const float *irr = b.irr
    cdef const float *il = b.il
    cdef const float *ra_row = b.prr + b.ra * width
    cdef const float *rs_row = b.prr + b.rs * width
    cdef const float *pla = b.pl + b.ra * width
    cdef const float *pls = b.pl + b.rs * width
    cdef int32_t key_mask = b.key_mask, index_mask = b.index_mask, inf_key = b.inf_key
    cdef float wa = b.wa, ws = b.ws
    cdef bint uniq_on = b.uniq > 0.0
    cdef int32_t lk, bi
    for x in range(x0, x1):
        c = x + m
        j0 = width - 1 - x + dmin
        jc = width - 1 - c + dmin
        lk = _fast_px(col + (x + m2) * num, col + x * num, ssum, cb, ra_row + jc,
                      rs_row + jc, rkey + j0, irr + j0, pla[c], pls[c], wa, ws, il[x],
                      key_mask, num)
        if lk >= inf_key:
            b.best_i[x] = -1
            b.c_0[x] = INF
            continue
        bi = lk & index_mask
        b.best_i[x] = bi
        b.c_0[x] = from_bits(cb[bi])
        b.c_m[x] = from_bits(cb[bi - 1]) if bi >= 1 else INF
        b.c_p[x] = from_bits(cb[bi + 1]) if bi + 1 < num else INF
        if uniq_on:
            b.second[x] = from_bits(_second_bits(cb, 0, num, bi))


cdef void _column_in(Band *b, Py_ssize_t c, float *col) noexcept nogil:
    """Slide column c's vertical sums (``col``: its colsum row) down one row, for the
    disparities whose right pixel c - d lies in the image."""
    cdef Py_ssize_t width = b.width, dmin = b.dmin
    cdef Py_ssize_t lo = max(0, c - width + 1 - dmin)
    cdef Py_ssize_t hi = min(b.num, c - dmin + 1)
    cdef Py_ssize_t jc
    if lo < hi:
        jc = width - 1 - c + dmin + lo
        _column_sums(col + lo, b.prr + b.ra * width + jc, b.prr + b.rs * width + jc,
                     b.pl[b.ra * width + c], b.pl[b.rs * width + c], b.wa, b.ws, hi - lo)


cdef void _general_px(Band *b, Py_ssize_t x) noexcept nogil:
    """Pixel x outside the fast run: window sums as in the fast run, Eq. 10 over the
    clipped windows (masked where they leave an image), winner and its neighbours."""
    cdef Py_ssize_t width = b.width, m = b.m, dmin = b.dmin, num = b.num
    cdef Py_ssize_t c = x + m, i, ilo, ihi
    cdef float *col_in = b.colsum + (x + b.m2) * num
    cdef Py_ssize_t j0 = width - 1 - x + dmin   # reversed right column of index 0
    cdef Py_ssize_t vlo = max(0, x - width + 1 - dmin)
    cdef Py_ssize_t vhi = min(num, x - dmin + 1)
    cdef int32_t *cb = b.cb
    cdef int32_t lk, bi
    if c < width:
        _column_in(b, c, col_in)
    _slide_sums(b.ssum, col_in, b.colsum + x * num, num)
    if vlo >= vhi:
        b.best_i[x] = -1
        b.c_0[x] = INF
        return
    ilo = vlo
    ihi = vlo
    if m <= x <= width - 1 - m:
        ilo = max(vlo, x + m + 1 - width - dmin)
        ihi = min(vhi, x - m - dmin + 1)
    if ilo >= ihi:
        ilo = vlo
        ihi = vlo
    if ilo < ihi:
        _interior_costs(cb + ilo, b.ssum + ilo, b.irr + j0 + ilo, b.il[x], ihi - ilo)
    if b.fast_border and x <= width - 1 - m:
        # left border: every disparity of [ihi, vhi) has x - d < m
        for i in range(ihi, vhi):
            cb[i] = bits((b.ssum[i] + SSD_EPS) * b.diag[(x - dmin - i) * num + i])
    elif b.fast_border and dmin + vhi - 1 <= x - m:
        _right_edge_costs(cb + vlo, b.ssum + vlo, <float>(b.cly[width] - b.cly[x - m]),
                          b.cry + width - dmin - vlo, b.cry + x - m - dmin - vlo,
                          vhi - vlo)
    else:
        _border_x(b, vlo, ilo, x)
        _border_x(b, ihi, vhi, x)
    lk = _keys(cb + vlo, b.rkey + j0 + vlo, vlo, b.key_mask, vhi - vlo)
    if lk >= b.inf_key:
        b.best_i[x] = -1
        b.c_0[x] = INF
        return
    bi = lk & b.index_mask
    b.best_i[x] = bi
    b.c_0[x] = from_bits(cb[bi])
    b.c_m[x] = from_bits(cb[bi - 1]) if bi - 1 >= vlo else INF
    b.c_p[x] = from_bits(cb[bi + 1]) if bi + 1 < vhi else INF
    if b.uniq > 0.0:
        b.second[x] = from_bits(_second_bits(cb, vlo, vhi, bi))


cdef void _first_window(Band *b, Py_ssize_t y0) noexcept nogil:
    """The band's first window: rows y0 - n .. y0 + n - 1 (row y0 + n is added by the
    first row) into the column energies and the vertical window sums."""
    cdef Py_ssize_t r, c, lo, hi, width = b.width, dmin = b.dmin, num = b.num
    cdef const float *rr
    for r in range(max(0, y0 - b.n), min(b.height, y0 + b.n)):
        _slide_energy(b.vl, b.pl + r * width, b.zeros, 1.0, 0.0, width)
        _slide_energy(b.vr, b.pr + r * width, b.zeros, 1.0, 0.0, width)
        for c in range(width):
            lo = max(0, c - width + 1 - dmin)
            hi = min(num, c - dmin + 1)
            if lo < hi:
                rr = b.prr + r * width + width - 1 - c + dmin + lo
                _column_sums(b.colsum + (c + b.m + 1) * num + lo, rr, rr,
                             b.pl[r * width + c], b.pl[r * width + c], 1.0, 0.0, hi - lo)


cdef void _row_energies(Band *b, Py_ssize_t y, Py_ssize_t y0) noexcept nogil:
    """Slide the column energies to row y's window; its clipped window energies and
    inverse norms, and the left border's norm table (``diag``)."""
    cdef Py_ssize_t k, nk, j, width = b.width, m = b.m, n = b.n, dmin = b.dmin
    b.ra = min(y + n, b.height - 1)
    b.rs = max(y - n - 1, 0)
    b.wa = 1.0 if y + n < b.height else 0.0
    b.ws = 1.0 if y > y0 and y - n - 1 >= 0 else 0.0
    _slide_energy(b.vl, b.pl + b.ra * width, b.pl + b.rs * width, b.wa, b.ws, width)
    _slide_energy(b.vr, b.pr + b.ra * width, b.pr + b.rs * width, b.wa, b.ws, width)
    _prefix(b.vl, b.cly, width)
    _prefix(b.vr, b.cry, width)
    _window_energy_row(b.cly, b.el, b.il, m, width)
    b.rows_y = <float>(min(y + n, b.height - 1) - max(y - n, 0) + 1)
    _window_energy_row(b.cry, b.er, b.ir, m, width)
    if b.fast_border:
        for k in range(m):
            nk = max(0, min(b.num, width - k - m - dmin))
            _diagonal_norms(b.diag + k * b.num, b.cly + dmin + k + m + 1, b.cly + dmin,
                            <float>(b.cry[k + m + 1] - b.cry[0]), nk)
    for j in range(width):
        b.irr[j] = b.ir[width - 1 - j]


cdef void _row(Band *b, Py_ssize_t y, Py_ssize_t y0) noexcept nogil:
    """Match row y: slide the window sums, winners of every pixel, then row y's
    outputs."""
    cdef Py_ssize_t c, p, x, width = b.width, m = b.m, num = b.num
    _row_energies(b, y, y0)
    for x in range(width):
        b.rkey[x] = b.inf_key
    # column c enters the window at pixel c - m: columns 0 .. m-1 before pixel 0
    for c in range(min(m, width)):
        _column_in(b, c, b.colsum + (c + m + 1) * num)
    # window sums of pixel -1: columns -m-1 .. m-1 (colsum rows 0 .. 2m)
    for p in range(num):
        b.ssum[p] = 0.0
    for p in range(b.m2):
        _slide_sums(b.ssum, b.colsum + p * num, b.zeros, num)
    x = 0
    while x < width:
        if x == b.x0 and b.x0 < b.x1:
            _fast_run(b, b.x0, b.x1)
            x = b.x1
            continue
        _general_px(b, x)
        x += 1
    for x in range(width):
        c = b.rkey[width - 1 - x]
        b.rbest_i[x] = (c & b.index_mask) if c < b.inf_key else -1
        b.rdisp[y * width + x] = (<float>(b.dmin + b.rbest_i[x]) if b.rbest_i[x] >= 0
                                  else NAN)
    _finish_row(b, y)


def nssd_rows(const float[:, ::1] pl, const float[:, ::1] pr, const float[:, ::1] prr,
              Py_ssize_t y0, Py_ssize_t y1, Py_ssize_t dmin, Py_ssize_t num, Py_ssize_t m,
              Py_ssize_t n, double uniq, double lr_tol, bint subpixel, float texture_min,
              float[:, ::1] disp_out, float[:, ::1] cost_out, uint8_t[:, ::1] reason_out,
              float[:, ::1] rdisp_out):
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
        Disparities ``dmin .. dmin + num - 1`` px.
    m, n : int
        Half window width and height in px: the window is (2m+1) x (2n+1).
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
        Disparity in px (NaN where no candidate) and Eq. 10 cost of the winner (+inf
        where none); rows y0 .. y1 - 1 are written.
    reason_out : (H, W) uint8
        REASON_* code per pixel (slitcli.stereo.reasons).
    rdisp_out : (H, W) float32
        The right image's own winner-take-all disparity per right pixel (whole pixels,
        read from the same costs as the left-right check; NaN where none): the right
        view's disparity image, for the depth-edge test of slitcli.stereo._boundary.
    """
    cdef Py_ssize_t height = pl.shape[0], width = pl.shape[1], y, index_bits = 1
    cdef Band b
    shape = (pl.shape[0], pl.shape[1])
    for name, a in (("pr", pr), ("prr", prr), ("disp_out", disp_out),
                    ("cost_out", cost_out), ("reason_out", reason_out),
                    ("rdisp_out", rdisp_out)):
        if (a.shape[0], a.shape[1]) != shape:
            raise ValueError(f"nssd_rows: {name} has shape {a.shape[:2]}, pl {shape}")
    if not (0 <= y0 <= y1 <= height and num >= 1 and m >= 0 and n >= 0 and width >= 1):
        raise ValueError(f"nssd_rows: rows {y0}..{y1} of {height}, {num} disparities, "
                         f"half window {m} x {n}")
    b.height, b.width, b.dmin, b.num, b.m, b.n = height, width, dmin, num, m, n
    b.m2 = 2 * m + 1
    b.uniq, b.lr_tol, b.subpixel, b.texture_min = uniq, lr_tol, subpixel, texture_min
    while (1 << index_bits) < num:
        index_bits += 1
    b.index_mask = <int32_t>((1 << index_bits) - 1)
    b.key_mask = ~b.index_mask
    b.inf_key = INF_BITS & ~b.index_mask
    # the clipped windows at the borders take the slow scalar path (_border_x) unless
    # the disparities are non-negative and the image is wider than the window: then
    # the left border's norms are a table per row (offset k = x - d < m, disparity)
    # and the right border's are computed per pixel, both vectorised
    b.fast_border = dmin >= 0 and width >= b.m2
    b.x0 = max(m, num - 1 + dmin + m, 0)
    b.x1 = min(width - m, width - m + dmin, width + dmin)
    b.pl, b.pr, b.prr = &pl[0, 0], &pr[0, 0], &prr[0, 0]
    b.disp, b.cost = &disp_out[0, 0], &cost_out[0, 0]
    b.reason, b.rdisp = &reason_out[0, 0], &rdisp_out[0, 0]
    # scratch: colsum row c + m + 1 holds column c (rows of columns outside the image
    # stay 0)
    cdef float[::1] colsum = np.zeros((width + b.m2) * num, np.float32)
    cdef float[::1] f32 = np.empty(num + 4 * width, np.float32)
    cdef float[::1] energies = np.empty(5 * width, np.float32)
    cdef float[::1] zeros = np.zeros(max(width, num) + 2 * width, np.float32)
    cdef float[::1] diag = np.empty(max(m, 1) * num, np.float32)
    cdef int32_t[::1] i32 = np.empty(num + 3 * width, np.int32)
    cdef uint8_t[::1] lr_fail = np.empty(width, np.uint8)
    cdef double[::1] prefix = np.empty(2 * (width + 1), np.float64)
    b.colsum, b.diag, b.lr_fail = &colsum[0], &diag[0], &lr_fail[0]
    b.ssum, b.c_0, b.c_m = &f32[0], &f32[num], &f32[num + width]
    b.c_p, b.second = &f32[num + 2 * width], &f32[num + 3 * width]
    b.il, b.ir, b.irr = &energies[0], &energies[width], &energies[2 * width]
    b.el, b.er = &energies[3 * width], &energies[4 * width]
    b.zeros = &zeros[0]
    b.vl, b.vr = &zeros[max(width, num)], &zeros[max(width, num) + width]
    b.cb, b.rkey = &i32[0], &i32[num]
    b.best_i, b.rbest_i = &i32[num + width], &i32[num + 2 * width]
    b.cly, b.cry = &prefix[0], &prefix[width + 1]
    with nogil:
        _first_window(&b, y0)
        for y in range(y0, y1):
            _row(&b, y, y0)
