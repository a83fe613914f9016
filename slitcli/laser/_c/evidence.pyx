# cflags: -fno-math-errno -fno-trapping-math
"""Compiled kernels of :mod:`slitcli.laser.evidence`: the background opening, the laser
evidence per pixel and the image's noise (the model is in that module's notes).

Images come transposed, ``(W, H, 3)`` BGR uint8 (one image column per array row). Every
entry point releases the GIL. The arithmetic is the IEEE operations of the expressions as
written, in their order (no reassociation): the results equal those of the numba kernels
these replace, bit for bit.
"""

from libc.math cimport fabs, log, sqrt
from libc.stdint cimport int64_t, uint8_t
from libc.stdlib cimport free, malloc
from libc.string cimport memcpy, memset

from cython cimport floating

from slitcli.laser._c.select cimport select_kth

import numpy as np

#: 2 ln 2: the median of |n|^2 for isotropic Gaussian noise n of variance sigma^2 per
#: dimension in a plane is 2 ln 2 sigma^2 (chi-square with two degrees of freedom)
cdef double _CHI2_2_MEDIAN = 2.0 * log(2.0)
CHI2_2_MEDIAN = _CHI2_2_MEDIAN
#: a MAD of a Gaussian is 0.6745 sigma; the lag-2 residual has variance 1.5 sigma^2
cdef double _MAD_TO_SIGMA = 1.0 / (0.6745 * sqrt(1.5))
MAD_TO_SIGMA = _MAD_TO_SIGMA
#: bins of the median's histogram (:func:`_median`)
cdef enum:
    _BINS = 1024
MEDIAN_BINS = _BINS


# ---------------------------------------------------------------------------------------
# the vertical opening

cdef inline void _min3(const uint8_t* a, const uint8_t* b, const uint8_t* c, uint8_t* d,
                       Py_ssize_t m) noexcept nogil:
    """``d[t] = min(a[t], b[t], c[t])`` for ``t < m`` (``d`` may be ``a``, ``b`` or
    ``c`` element for element: each ``d[t]`` is written after its three reads)."""
    cdef Py_ssize_t t
    cdef uint8_t u, v, w
    for t in range(m):
        u = a[t]
        v = b[t]
        w = c[t]
        u = u if u < v else v
        d[t] = u if u < w else w


cdef inline void _max3(const uint8_t* a, const uint8_t* b, const uint8_t* c, uint8_t* d,
                       Py_ssize_t m) noexcept nogil:
    """``d[t] = max(a[t], b[t], c[t])`` for ``t < m``."""
    cdef Py_ssize_t t
    cdef uint8_t u, v, w
    for t in range(m):
        u = a[t]
        v = b[t]
        w = c[t]
        u = u if u > v else v
        d[t] = u if u > w else w


cdef inline void _min2(const uint8_t* a, const uint8_t* b, uint8_t* d,
                       Py_ssize_t m) noexcept nogil:
    """``d[t] = min(a[t], b[t])`` for ``t < m``."""
    cdef Py_ssize_t t
    cdef uint8_t u, v
    for t in range(m):
        u = a[t]
        v = b[t]
        d[t] = u if u < v else v


cdef inline void _max2(const uint8_t* a, const uint8_t* b, uint8_t* d,
                       Py_ssize_t m) noexcept nogil:
    """``d[t] = max(a[t], b[t])`` for ``t < m``."""
    cdef Py_ssize_t t
    cdef uint8_t u, v
    for t in range(m):
        u = a[t]
        v = b[t]
        d[t] = u if u > v else v


cdef inline void _join3(const uint8_t* src, uint8_t* dst, Py_ssize_t m, Py_ssize_t sh1,
                        Py_ssize_t sh2, bint is_max) noexcept nogil:
    """``dst[t] = min(src[t], src[t + sh1], src[t + sh2])`` (max with ``is_max``); two
    inputs when the shifts are equal (the doubling passes)."""
    if sh1 == sh2:
        if is_max:
            _max2(src, src + sh1, dst, m)
        else:
            _min2(src, src + sh1, dst, m)
    elif is_max:
        _max3(src, src + sh1, src + sh2, dst, m)
    else:
        _min3(src, src + sh1, src + sh2, dst, m)


cdef void _vertical_filter(const uint8_t* x, Py_ssize_t n, Py_ssize_t c, Py_ssize_t k,
                           uint8_t* out, uint8_t* buf_a, uint8_t* buf_b,
                           bint is_max) noexcept nogil:
    """Minimum (maximum) over ``k`` rows, anchor ``k // 2``, of ``x`` (n, c) uint8 into
    ``out``; rows beyond the border are left out (OpenCV's erosion and dilation with a
    (k, 1) kernel). Windows doubled in width pass by pass (1, 2, 4, ... rows), the last
    pass joins three: a handful of passes instead of ``k`` comparisons a pixel; the
    scratch buffers hold ``(n + k - 1) c`` values. ``out`` may be ``x``."""
    cdef Py_ssize_t hc = (k // 2) * c
    cdef Py_ssize_t total = (n + k - 1) * c
    cdef uint8_t fill = 0 if is_max else 255  # the padding never wins
    cdef Py_ssize_t w = 1
    cdef uint8_t* src = buf_a
    cdef uint8_t* dst = buf_b
    cdef uint8_t* tmp
    cdef Py_ssize_t sh
    memset(buf_a, fill, hc)
    memcpy(buf_a + hc, x, n * c)
    memset(buf_a + hc + n * c, fill, total - hc - n * c)
    while 3 * w < k:
        # rows j .. j + 2 w - 1 from two windows of w rows
        _join3(src, dst, (n + k - 2 * w) * c, w * c, w * c, is_max)
        w *= 2
        tmp = src
        src = dst
        dst = tmp
    # rows j .. j + k - 1 from three windows of w rows (3 w >= k)
    sh = w if w < k - w else k - w
    _join3(src, out, n * c, sh * c, (k - w) * c, is_max)


def vertical_opening(const uint8_t[:, ::1] x, Py_ssize_t k, uint8_t[:, ::1] out) -> None:
    """Morphological opening of ``x`` (rows, C) uint8 along its rows with a window of
    ``k`` rows, into ``out`` (same shape): the same values as OpenCV's
    ``morphologyEx(x, MORPH_OPEN, ones((k, 1)))`` (min and max are exact), single
    threaded, a fifth faster at 320 x 240 x 3.

    Parameters
    ----------
    x : ndarray, shape (rows, C), uint8, C-contiguous
    k : int
        Window, rows (>= 1).
    out : ndarray, shape (rows, C), uint8, C-contiguous
        Written.
    """
    cdef Py_ssize_t n = x.shape[0], c = x.shape[1]
    if k < 1:
        raise ValueError(f"window k must be at least 1 row, not {k}")
    if out.shape[0] != n or out.shape[1] != c:
        raise ValueError("out must have the shape of x")
    if n * c == 0:
        return
    cdef uint8_t* buf_a
    cdef uint8_t* buf_b
    with nogil:
        buf_a = <uint8_t*> malloc((n + k - 1) * c)
        buf_b = <uint8_t*> malloc((n + k - 1) * c)
        if buf_a != NULL and buf_b != NULL:
            _vertical_filter(&x[0, 0], n, c, k, &out[0, 0], buf_a, buf_b, False)
            _vertical_filter(&out[0, 0], n, c, k, &out[0, 0], buf_a, buf_b, True)
    ok = buf_a != NULL and buf_b != NULL
    free(buf_a)
    free(buf_b)
    if not ok:
        raise MemoryError()


# ---------------------------------------------------------------------------------------
# the median

cdef inline Py_ssize_t _bin(double x, double lo, double scale) noexcept nogil:
    cdef int64_t b = <int64_t> ((x - lo) * scale)
    return b if b < _BINS - 1 else _BINS - 1


cdef double _median_of(const double* v, Py_ssize_t n, double* sel) noexcept nogil:
    """Median of ``v[:n]`` (n >= 1), the same value as ``np.median``, without sorting
    all of it: a histogram of ``MEDIAN_BINS`` bins over its range finds the bins of the
    middle order statistics, and only their values are ordered (``sel``: scratch of
    ``n`` values)."""
    cdef double lo, hi, scale, s_lo, s_hi, a, b
    cdef double lo4[4]
    cdef double hi4[4]
    cdef Py_ssize_t t, k1, k2, b1, b2, m, bb, q
    cdef int64_t below, through
    cdef int64_t counts[_BINS]
    # the range in four independent lanes (no chain of dependent compares); a NaN never
    # enters unless it is v[0], as in a plain running minimum
    for q in range(4):
        lo4[q] = v[0]
        hi4[q] = v[0]
    t = 0
    while t + 4 <= n:
        for q in range(4):
            lo4[q] = v[t + q] if v[t + q] < lo4[q] else lo4[q]
            hi4[q] = v[t + q] if v[t + q] > hi4[q] else hi4[q]
        t += 4
    while t < n:
        lo4[0] = v[t] if v[t] < lo4[0] else lo4[0]
        hi4[0] = v[t] if v[t] > hi4[0] else hi4[0]
        t += 1
    lo = lo4[0]
    hi = hi4[0]
    for q in range(1, 4):
        lo = lo4[q] if lo4[q] < lo else lo
        hi = hi4[q] if hi4[q] > hi else hi
    if not hi > lo:
        # all equal: a running minimum keeps v[0] (whatever the sign of a zero)
        return v[0]
    # (a lane may hold -0.0 where a running minimum holds 0.0: the bins are the same)
    scale = _BINS / (hi - lo)
    memset(counts, 0, sizeof(counts))
    for t in range(n):
        counts[_bin(v[t], lo, scale)] += 1
    k1 = (n - 1) // 2  # the middle order statistics (one for odd n)
    k2 = n // 2
    below = 0  # values in bins before b1
    b1 = 0
    while below + counts[b1] <= k1:
        below += counts[b1]
        b1 += 1
    b2 = b1
    through = below + counts[b1]
    while through <= k2:
        b2 += 1
        through += counts[b2]
    m = 0
    for t in range(n):
        # (every value written, kept when in the bins: no branch to mispredict)
        bb = _bin(v[t], lo, scale)
        sel[m] = v[t]
        m += (bb >= b1) & (bb <= b2)
    # many equal values (a quantised or clipped quantity) need no ordering
    s_lo = sel[0]
    s_hi = sel[0]
    for t in range(m):
        s_lo = sel[t] if sel[t] < s_lo else s_lo
        s_hi = sel[t] if sel[t] > s_hi else s_hi
    if s_lo == s_hi:
        return s_lo
    select_kth(sel, m, k1 - below)
    a = sel[k1 - below]
    if k2 == k1:
        b = a
    else:
        # the next order statistic: the smallest value after position k1 - below
        b = sel[k1 - below + 1]
        for t in range(k1 - below + 2, m):
            b = sel[t] if sel[t] < b else b
    return 0.5 * (a + b)


cdef double _median_abs_dev(double* v, Py_ssize_t n, double* sel) noexcept nogil:
    """Median of ``|v - median(v)|`` (``v`` is overwritten by the deviations)."""
    cdef double med = _median_of(v, n, sel)
    cdef Py_ssize_t t
    for t in range(n):
        v[t] = fabs(v[t] - med)
    return _median_of(v, n, sel)


def _median(const double[::1] v) -> float:
    """Median of ``v`` (n,) float64, n >= 1, the same value as ``np.median``, without
    sorting all of it (histogram of ``MEDIAN_BINS`` bins, then a selection in the bins
    of the middle order statistics)."""
    cdef Py_ssize_t n = v.shape[0]
    if n == 0:
        raise ValueError("the median of no values")
    cdef double* sel = <double*> malloc(n * sizeof(double))
    cdef double med
    if sel == NULL:
        raise MemoryError()
    with nogil:
        med = _median_of(&v[0], n, sel)
    free(sel)
    return med


# ---------------------------------------------------------------------------------------
# the evidence and its share of the surface colour

cdef Py_ssize_t _texture_split(const uint8_t[:, :, ::1] img, const uint8_t[:, ::1] bg,
                               const uint8_t[:, ::1] mask, int64_t sat_dn, Py_ssize_t step,
                               double* along, double* across) noexcept nogil:
    """The contrast of every ``step``-th column and second row of :func:`texture_share`,
    split into its length along the surface colour (``along``) and its squared length
    across it (``across``); returns how many pixels entered."""
    cdef Py_ssize_t n_cols = img.shape[0], n = img.shape[1], i, ii, j, m = 0
    cdef double kr, kg, kb, tr, tg, tb, tk, q
    cdef const uint8_t* xi
    cdef const uint8_t* b_b
    cdef const uint8_t* b_g
    cdef const uint8_t* b_r
    for ii in range((n_cols + step - 1) // step):
        i = ii * step
        b_b = &bg[3 * i, 0]
        b_g = &bg[3 * i + 1, 0]
        b_r = &bg[3 * i + 2, 0]
        xi = &img[i, 0, 0]
        for j in range(0, n, 2):
            if not mask[i, j] or xi[3 * j + 2] >= sat_dn or xi[3 * j + 1] >= sat_dn or \
                    xi[3 * j] >= sat_dn:
                continue
            kr = b_r[j] + 0.5
            kg = b_g[j] + 0.5
            kb = b_b[j] + 0.5
            tr = <double> xi[3 * j + 2] - b_r[j]
            tg = <double> xi[3 * j + 1] - b_g[j]
            tb = <double> xi[3 * j] - b_b[j]
            tk = (tr * kr + tg * kg + tb * kb) / sqrt(kr * kr + kg * kg + kb * kb)
            along[m] = tk
            q = tr * tr + tg * tg + tb * tb - tk * tk
            across[m] = 0.0 if 0.0 > q else q  # Python's max(q, 0.0)
            m += 1
    return m


def texture_share(const uint8_t[:, :, ::1] img, const uint8_t[:, ::1] bg,
                  const uint8_t[:, ::1] mask, int64_t sat_dn, Py_ssize_t step,
                  double max_share) -> float:
    """Share ``lam = tau^2 / (tau^2 + sigma^2)`` of the surface colour that the evidence
    removes (module notes), measured on the image: the contrast ``t = x - bg`` of every
    ``step``-th column and every second row (a few thousand pixels fix the spreads to a
    few per cent), split along the surface colour ``k`` and across it. Across ``k``
    there is noise alone (and the few laser pixels): the median of its squared length is
    ``2 ln 2 sigma^2``; along ``k`` texture and noise, of robust spread ``s``
    (1.4826 MAD); so ``lam = 1 - sigma^2 / s^2``, clamped to ``[0, max_share]``.

    Parameters
    ----------
    img : ndarray, shape (W, H, 3), uint8, BGR (transposed image)
    bg : ndarray, shape (3 W, H), uint8
        As for :func:`laser_evidence`.
    mask : ndarray, shape (W, H), bool
        The pixels to use (unclipped pixels of the searched rows).
    sat_dn : int
        Saturation level, DN.
    step : int
        Every ``step``-th column enters.
    max_share : float

    Returns
    -------
    float
    """
    cdef Py_ssize_t n_cols = img.shape[0], n = img.shape[1], m
    if step < 1:
        raise ValueError(f"step must be at least 1, not {step}")
    if mask.shape[0] != n_cols or mask.shape[1] != n or bg.shape[0] != 3 * n_cols \
            or bg.shape[1] != n:
        raise ValueError("bg must be (3 W, H), mask (W, H) for img (W, H, 3)")
    cdef Py_ssize_t cap = ((n_cols + step - 1) // step) * ((n + 1) // 2)
    cdef double* along = <double*> malloc((cap + 1) * sizeof(double))
    cdef double* across = <double*> malloc((cap + 1) * sizeof(double))
    cdef double* sel = <double*> malloc((cap + 1) * sizeof(double))
    cdef double s, var_n, out
    if along == NULL or across == NULL or sel == NULL:
        free(along)
        free(across)
        free(sel)
        raise MemoryError()
    with nogil:
        m = _texture_split(img, bg, mask, sat_dn, step, along, across)
        if m < 16:
            out = max_share
        else:
            s = 1.4826 * _median_abs_dev(along, m, sel)
            var_n = _median_of(across, m, sel) / _CHI2_2_MEDIAN
            if not s > 0.0:
                out = max_share
            else:
                out = 1.0 - var_n / (s * s)
                out = 0.0 if 0.0 > out else out   # Python's max(out, 0.0), min(out, max_share)
                out = max_share if max_share < out else out
    free(along)
    free(across)
    free(sel)
    return out


def laser_evidence(const uint8_t[:, :, ::1] img, const uint8_t[:, ::1] bg, int64_t sat_dn,
                   double lam, float[:, ::1] y, uint8_t[:, ::1] clipped,
                   int64_t sat_g=256, int64_t sat_b=256) -> None:
    """Laser evidence ``y`` (W, H) float32 of every pixel (module notes) and its clipped
    flag (red at or above ``sat_dn``, green at or above ``sat_g`` or blue at or above
    ``sat_b``: 256, the default, never).

    ``img`` (W, H, 3) BGR, ``bg`` the opening per channel as (3 W, H): row ``3 i + c``
    holds channel ``c`` (b, g, r) of column ``i``; ``lam`` the share of the surface
    colour removed (:func:`texture_share`). With ``k = bg + 1/2`` and the red axis
    ``e_r``, ``w = (e_r - lam k k_r / |k|^2) / (1 - lam k_r^2 / |k|^2)`` (``w . e_r = 1``)
    and ``y = w . (x - bg)``. ``y`` and ``clipped`` (W, H) bool are written.
    """
    cdef Py_ssize_t n_cols = img.shape[0], n = img.shape[1], i, j
    cdef double kr, kg, kb, k2, inv, tr, tg, tb
    cdef const uint8_t* xi
    cdef const uint8_t* b_b
    cdef const uint8_t* b_g
    cdef const uint8_t* b_r
    cdef float* yi
    cdef uint8_t* ci
    if y.shape[0] != n_cols or y.shape[1] != n or clipped.shape[0] != n_cols \
            or clipped.shape[1] != n or bg.shape[0] != 3 * n_cols or bg.shape[1] != n:
        raise ValueError("bg must be (3 W, H), y and clipped (W, H) for img (W, H, 3)")
    if n == 0:
        return
    with nogil:
        for i in range(n_cols):
            b_b = &bg[3 * i, 0]
            b_g = &bg[3 * i + 1, 0]
            b_r = &bg[3 * i + 2, 0]
            xi = &img[i, 0, 0]
            yi = &y[i, 0]
            ci = &clipped[i, 0]
            for j in range(n):
                kr = b_r[j] + 0.5
                kg = b_g[j] + 0.5
                kb = b_b[j] + 0.5
                k2 = kr * kr + kg * kg + kb * kb
                inv = 1.0 / (k2 - lam * kr * kr)
                tr = <double> xi[3 * j + 2] - b_r[j]
                tg = <double> xi[3 * j + 1] - b_g[j]
                tb = <double> xi[3 * j] - b_b[j]
                yi[j] = <float> (((k2 - lam * kr * kr) * tr - lam * kr * (kg * tg + kb * tb))
                                 * inv)
                ci[j] = (xi[3 * j + 2] >= sat_dn) | (xi[3 * j + 1] >= sat_g) | \
                    (xi[3 * j] >= sat_b)


# ---------------------------------------------------------------------------------------
# the noise

cdef int _sample_buffers(const uint8_t[:, ::1] mask, Py_ssize_t n_cols, Py_ssize_t n,
                         Py_ssize_t step, Py_ssize_t per_column, double** vals,
                         double** sel) except -1:
    """Check a sampling of every ``step``-th column of an (n_cols, n) array under ``mask``
    and allocate its two buffers (values, selection scratch) for ``per_column`` values a
    sampled column; the caller frees both."""
    if step < 1:
        raise ValueError(f"step must be at least 1, not {step}")
    if mask.shape[0] != n_cols or mask.shape[1] != n:
        raise ValueError("mask must have the shape of x")
    cdef Py_ssize_t cap = ((n_cols + step - 1) // step) * per_column
    vals[0] = <double*> malloc((cap + 1) * sizeof(double))
    sel[0] = <double*> malloc((cap + 1) * sizeof(double))
    if vals[0] == NULL or sel[0] == NULL:
        free(vals[0])
        free(sel[0])
        raise MemoryError()
    return 0


def robust_sigma(const floating[:, ::1] x, const uint8_t[:, ::1] mask,
                 Py_ssize_t step) -> float:
    """Noise sigma of ``x`` (W, H) float32 or float64 from the median absolute lag-2
    residual down every ``step``-th column, over rows where ``mask`` (W, H) bool holds
    at all five rows used (the residual of float32 values sums its two neighbours in
    float32, as the numba kernel did)."""
    cdef Py_ssize_t n_cols = x.shape[0], n = x.shape[1], i, ii, j, m = 0
    cdef double* vals
    cdef double* sel
    cdef double out = 0.0
    _sample_buffers(mask, n_cols, n, step, n - 4 if n > 4 else 0, &vals, &sel)
    with nogil:
        for ii in range((n_cols + step - 1) // step):
            i = ii * step
            for j in range(2, n - 2):
                if mask[i, j - 2] and mask[i, j + 2]:
                    vals[m] = fabs(x[i, j] - 0.5 * (x[i, j - 2] + x[i, j + 2]))
                    m += 1
        if m > 0:
            out = _MAD_TO_SIGMA * _median_of(vals, m, sel)
    free(vals)
    free(sel)
    return out


def channel_sigma(const uint8_t[:, :, ::1] img, Py_ssize_t step):
    """Per-channel noise sigma (R, G, B), DN, of ``img`` (W, H, 3) BGR: the median
    absolute lag-2 residual down every ``step``-th column, unclipped pixels only.

    The residuals of integers come in halves (``k / 2``, ``k = |2 b - a - d|`` in
    0 .. 510): they are counted per half (a histogram, no sort), and the median is
    interpolated within its half-DN bin as for grouped data (the plain median of such
    values moves in whole steps: a 2 DN noise reads 2.4); the bin at 0 is half wide.

    Returns
    -------
    ndarray, shape (3,), float64
        (R, G, B), DN.
    """
    cdef Py_ssize_t n_cols = img.shape[0], n = img.shape[1], i, ii, j, c, k
    if step < 1:
        raise ValueError(f"step must be at least 1, not {step}")
    out_arr = np.zeros(3)
    cdef double[::1] out = out_arr
    cdef int64_t hist[3][511]
    cdef int64_t a, b, d, m, half, lo, hi, r
    cdef double step_dn = 0.5, med, width, edge
    cdef const uint8_t* col
    with nogil:
        memset(hist, 0, sizeof(hist))
        for ii in range((n_cols + step - 1) // step):
            i = ii * step
            col = &img[i, 0, 0]
            for j in range(2, n - 2):
                for c in range(3):
                    a = col[3 * (j - 2) + c]
                    b = col[3 * j + c]
                    d = col[3 * (j + 2) + c]
                    if a < 255 and b < 255 and d < 255:
                        r = 2 * b - a - d
                        hist[c][r if r >= 0 else -r] += 1
        for c in range(3):
            m = 0
            for k in range(511):
                m += hist[c][k]
            if m == 0:
                continue
            half = m // 2
            lo = 0  # values below the median's bin
            k = 0
            while lo + hist[c][k] <= half:
                lo += hist[c][k]
                k += 1
            hi = lo + hist[c][k]
            med = 0.5 * k
            width = step_dn if k > 0 else 0.5 * step_dn
            edge = med - 0.5 * step_dn if k > 0 else 0.0
            out[2 - c] = _MAD_TO_SIGMA * (edge + (0.5 * m - lo) / <double> (
                hi - lo if hi - lo > 1 else 1) * width)
    return out_arr


def spread_sigma(const floating[:, ::1] x, const uint8_t[:, ::1] mask,
                 Py_ssize_t step) -> float:
    """Robust spread of ``x`` (W, H) float32 or float64 about its median over the
    ``mask``ed pixels (W, H) bool of every ``step``-th column (1.4826 times the median
    absolute deviation): noise and all the scene structure that the evidence does not
    cancel (clutter)."""
    cdef Py_ssize_t n_cols = x.shape[0], n = x.shape[1], i, ii, j, m = 0
    cdef double* vals
    cdef double* sel
    cdef double out = 0.0
    _sample_buffers(mask, n_cols, n, step, n, &vals, &sel)
    with nogil:
        for ii in range((n_cols + step - 1) // step):
            i = ii * step
            for j in range(n):
                if mask[i, j]:
                    vals[m] = x[i, j]
                    m += 1
        if m > 0:
            out = 1.4826 * _median_abs_dev(vals, m, sel)
    free(vals)
    free(sel)
    return out


def grey_share_holds(const uint8_t[:, :, :] bgr, Py_ssize_t step, int grey_dn,
                     double share) -> bool:
    """Whether at least ``share`` of the pixels of every ``step``-th row and column of
    ``bgr`` (H, W, 3) uint8 BGR (any strides) have red within ``grey_dn`` of green and
    of blue (:func:`slitcli.laser.diagnose.is_grey`): the share as numpy's mean of the
    pixels' test gives it (their count over their number); it stops once the pixels
    that fail leave the share below ``share`` (the count can only fall)."""
    if bgr.shape[2] != 3 or step < 1:
        raise ValueError("grey_share_holds: bgr must be (H, W, 3) and step at least 1")
    cdef Py_ssize_t h = (bgr.shape[0] + step - 1) // step, w = (bgr.shape[1] + step - 1) // step
    cdef Py_ssize_t n = h * w, miss = 0, i, j
    cdef int r
    cdef bint fell = False
    if n == 0:
        return bool(np.mean(np.zeros(0, bool)) >= share)  # (numpy's NaN mean: False)
    with nogil:
        for i in range(h):
            for j in range(w):
                r = bgr[i * step, j * step, 2]
                if abs(r - <int>bgr[i * step, j * step, 1]) > grey_dn \
                        or abs(r - <int>bgr[i * step, j * step, 0]) > grey_dn:
                    miss += 1
            if not <double>(n - miss) / n >= share:
                fell = True
                break
    return not fell and <double>(n - miss) / n >= share
