"""Subsampled chroma, compiled: the lag medians that tell it
(:func:`slitcli.laser.luma.chroma_smoothness` calls :func:`lag_medians`), the stripe's
row on the luma (:func:`slitcli.laser.luma.luma_rows` calls :func:`luma_rows`; the fit
is ``profile.pxd``'s :func:`fit_gaussian`) and the luma's light at the stripe's rows
(:func:`slitcli.laser.luma.luma_segments` calls :func:`luma_column_z`; the matched
filter is ``profile.pxd``'s :func:`linear_z`)."""

import numpy as np

from libc.math cimport NAN, ceil, fabs, isfinite, rint, sqrt

from slitcli.laser._c.fields cimport F_POS, F_SE_POS, F_WIDTH
from slitcli.laser._c.profile cimport (MIN_SIGMA_PX, SEED_MIN_SIGMA_PX, fit_gaussian,
                                       flat_top, half_max_sigma, imax, imin, linear_z, pmax,
                                       pmin, used_min)

#: rows either side whose luma gives a fit's local noise; residuals beyond CLIP_SIGMAS
#: global sigmas count as that many (an edge); the mean absolute lag-2 residual over
#: sigma: sqrt(2 / pi) sqrt(1.5) (as the candidates', slitcli.laser.candidates)
cdef Py_ssize_t NOISE_HALF = 24
cdef double CLIP_SIGMAS = 5.0
cdef double MEAN_TO_SIGMA = sqrt(3.141592653589793 / 2.0) / sqrt(1.5)

# the luma's weights of (b, g, r), ITU-R BT.601 as JPEG's YCbCr (JFIF)
cdef double W_B = 0.114
cdef double W_G = 0.587
cdef double W_R = 0.299


cdef inline double _local_sigma(const unsigned char[:, :, ::1] img, Py_ssize_t i,
                               Py_ssize_t j, Py_ssize_t core, double sigma_dn) noexcept nogil:
    """The luma's noise near row ``j`` of column ``i``: the larger of ``sigma_dn`` and
    the mean absolute lag-2 residual of the luma within ``NOISE_HALF`` rows, the
    ``core`` rows either side of ``j`` left out, each residual clipped at ``CLIP_SIGMAS``
    of ``sigma_dn`` (texture the opening leaves is noise to the luma's fit, as to the
    evidence's candidates)."""
    cdef Py_ssize_t h = img.shape[1], jj, n = 0
    cdef double acc = 0.0, r, clip = CLIP_SIGMAS * sigma_dn
    cdef const unsigned char* a
    cdef const unsigned char* b
    cdef const unsigned char* c
    for jj in range(imax(j - NOISE_HALF, 2), imin(j + NOISE_HALF + 1, h - 2)):
        if jj >= j - core and jj <= j + core:
            continue
        a = &img[i, jj - 2, 0]
        b = &img[i, jj, 0]
        c = &img[i, jj + 2, 0]
        r = W_B * (b[0] - 0.5 * (a[0] + c[0])) + W_G * (b[1] - 0.5 * (a[1] + c[1])) + \
            W_R * (b[2] - 0.5 * (a[2] + c[2]))
        acc += pmin(fabs(r), clip)
        n += 1
    if n < 8:
        return sigma_dn
    return pmax(sigma_dn, MEAN_TO_SIGMA * acc / n)


cdef inline Py_ssize_t _nearest_fit(const double[:, :, ::1] cand, Py_ssize_t i,
                                    double v) noexcept nogil:
    """The fit of column ``i`` of the candidate table nearest row ``v``; -1 none."""
    cdef Py_ssize_t q, best = -1
    cdef double d, dmin = 1e300
    for q in range(cand.shape[1]):
        d = fabs(cand[i, q, F_POS] - v)
        if isfinite(d) and d < dmin:
            dmin = d
            best = q
    return best


cdef inline void _luma_window(const unsigned char[:, :, ::1] img,
                              const unsigned char[:, ::1] bg, Py_ssize_t i, Py_ssize_t a,
                              Py_ssize_t m, int sat_dn, float* yl,
                              unsigned char* use) noexcept nogil:
    """The luma's contrast over its opening in rows ``a .. a + m - 1`` of column ``i``
    into ``yl``, and in ``use`` whether no channel of the row reaches ``sat_dn``."""
    cdef Py_ssize_t jj
    cdef const unsigned char* px
    for jj in range(m):
        px = &img[i, a + jj, 0]
        yl[jj] = <float>(W_B * (<double>px[0] - bg[3 * i, a + jj]) +
                         W_G * (<double>px[1] - bg[3 * i + 1, a + jj]) +
                         W_R * (<double>px[2] - bg[3 * i + 2, a + jj]))
        use[jj] = px[0] < sat_dn and px[1] < sat_dn and px[2] < sat_dn


cdef inline Py_ssize_t _luma_peak(const float* yl, const unsigned char* use, Py_ssize_t m,
                                  Py_ssize_t j0, double v, double reach) noexcept nogil:
    """The used row of the window ``yl`` (m rows from image row ``j0``) of the largest
    luma contrast within ``reach`` rows of ``v``; -1 none."""
    cdef Py_ssize_t jj, k = -1
    for jj in range(m):
        if use[jj] and fabs(j0 + jj - v) <= reach and (k < 0 or yl[jj] > yl[k]):
            k = jj
    return k


cdef inline bint _luma_fit(const unsigned char[:, :, ::1] img,
                           const unsigned char[:, ::1] bg, Py_ssize_t i, double v,
                           double s_ev, Py_ssize_t row0, double sigma_dn, double blur_var_px2,
                           double shape_error, double max_chi2, double s_max, double min_z,
                           int sat_dn, double reach_sigmas, bint seek, float* yl,
                           unsigned char* use, double* ebuf, double* out) noexcept nogil:
    """The luma's fit of column ``i`` near row ``v`` (image rows) from the evidence's
    width ``s_ev`` (module function :func:`luma_rows`); ``out`` (6,) as
    :func:`fit_gaussian`'s; False where none is kept."""
    cdef Py_ssize_t h = img.shape[1], j, a, b, m, k
    cdef double s0, start = v, reach
    cdef bint ok
    s_ev = pmin(s_ev if isfinite(s_ev) else 1.0, s_max)
    reach = reach_sigmas * pmax(1.0, s_ev)
    s0 = sqrt(pmax(s_ev * s_ev - blur_var_px2, 0.36))
    j = <Py_ssize_t>rint(v) - row0
    a = imax(j - <Py_ssize_t>ceil(3.0 * s_ev) - 3, 0)
    b = imin(j + <Py_ssize_t>ceil(3.0 * s_ev) + 4, h)
    m = b - a
    if m < 7:
        return False
    sigma_dn = _local_sigma(img, i, j, j - a, sigma_dn)
    _luma_window(img, bg, i, a, m, sat_dn, yl, use)
    if seek:
        # from the luma's own peak in reach, at that hump's width
        k = _luma_peak(yl, use, m, row0 + a, v, reach)
        if k < 0:
            return False
        start = row0 + a + k
        s0 = pmin(pmax(half_max_sigma(yl, use, m, k), SEED_MIN_SIGMA_PX), s_max)
    ok = fit_gaussian(yl, use, m, row0 + a, start, s0, sigma_dn, shape_error, s_max, out,
                      ebuf, NULL)
    if seek and not (ok and out[5] <= max_chi2 and out[3] >= min_z
                     and out[2] >= MIN_SIGMA_PX):
        # a hump the Gaussian does not describe, centred by its upper half as the
        # evidence's flat tops: one that fails the shape test (a camera's sharpening
        # rings beside a thin line), or a line thinner than a row, whose width and peak
        # the rows cannot tell apart (the fit narrows below a pixel's own extent and
        # its peak's error grows without bound); a centre of gravity over so few rows is
        # no better than the rows' own extent allows
        ok = flat_top(yl, use, m, row0 + a, start, used_min(yl, use, m), sigma_dn, out)
        if ok:
            out[4] = pmax(out[4], MIN_SIGMA_PX / pmax(1.0, 2.355 * out[2]))
    return ok and out[3] >= min_z and out[5] <= max_chi2 and out[2] <= s_max and \
        fabs(out[0] - v) <= reach


def luma_rows(const unsigned char[:, :, ::1] img, const unsigned char[:, ::1] bg,
              const double[::1] v, const unsigned char[::1] sat,
              const double[:, :, ::1] cand, Py_ssize_t row0, double sigma_dn,
              double blur_var_px2, double shape_error, double max_chi2, double s_max,
              double min_z, int sat_dn, double reach_sigmas, bint seek, double[::1] v_out,
              double[::1] se_out, double[::1] w_out, double[::1] se_ev_out) -> Py_ssize_t:
    """Each found column's row fitted again on the luma's contrast; returns how many.

    Parameters
    ----------
    img : ndarray, shape (W, H', 3), uint8
        The searched rows, transposed (one image column per array row), BGR.
    bg : ndarray, shape (3 W, H'), uint8
        The vertical opening per channel (row ``3 i + c``: channel ``c`` (b, g, r) of
        column ``i``).
    v : ndarray, shape (W,), float64
        The stripe's row per column found on the evidence, image rows (NaN none).
    sat : ndarray, shape (W,), bool as uint8
        The column's core is clipped (not fitted again).
    cand : ndarray, shape (W, K, N_FIELDS), float64
        The candidate table; the fit nearest ``v`` gives the evidence's width.
    row0 : int
        Image row of ``img``'s first row.
    sigma_dn : float
        Noise sigma of the luma, DN.
    blur_var_px2 : float
        Variance the chroma's processing added to the evidence's profile, px^2: the
        luma fit starts from the evidence's width with it taken off.
    shape_error, max_chi2, s_max : float
        The profile's model error, its largest reduced chi-square, the widest sigma, px.
    min_z : float
        Least significance of the luma's peak.
    sat_dn : int
        Rows with any channel at or above this are left out.
    reach_sigmas : float
        The luma's row is kept within this many of the evidence's sigmas (at least a
        pixel each) of ``v``.
    seek : bool
        Start from the luma's own peak within that reach (at its hump's half-maximum
        width), and centre a hump that is no Gaussian by its upper half; False: the
        Gaussian from ``v`` at the evidence's width less the blur.
    v_out, se_out, w_out : ndarray, shape (W,), float64
        Out: the luma's row, its standard error and its sigma, px (NaN where no fit is
        kept: not significant, not a Gaussian within the model error (without ``seek``),
        or beyond the reach).
    se_ev_out : ndarray, shape (W,), float64
        Out: the standard error of the evidence's fit nearest ``v``, px (NaN none).
    """
    cdef Py_ssize_t w = img.shape[0], h = img.shape[1]
    cdef Py_ssize_t i, best, n_kept = 0
    cdef double s_ev
    cdef double out[6]
    if bg.shape[0] != 3 * w or bg.shape[1] != h or v.shape[0] != w or sat.shape[0] != w \
            or cand.shape[0] != w or v_out.shape[0] != w or se_out.shape[0] != w \
            or w_out.shape[0] != w or se_ev_out.shape[0] != w:
        raise ValueError("luma_rows: img (W, H, 3), bg (3 W, H), v, sat, cand (W, ...) "
                         "and the outputs (W,) disagree in shape")
    cdef Py_ssize_t max_m = 2 * (<Py_ssize_t>ceil(3.0 * s_max) + 4) + 1
    cdef float[::1] yl = np.empty(max_m, np.float32)
    cdef unsigned char[::1] use = np.empty(max_m, np.uint8)
    cdef double[::1] ebuf = np.empty(max_m)
    with nogil:
        for i in range(w):
            v_out[i] = NAN
            se_out[i] = NAN
            w_out[i] = NAN
            se_ev_out[i] = NAN
            if not isfinite(v[i]) or sat[i]:
                continue
            # the evidence's width: the fit of this column nearest the row
            best = _nearest_fit(cand, i, v[i])
            s_ev = cand[i, best, F_WIDTH] if best >= 0 else 1.0
            if best >= 0:
                se_ev_out[i] = cand[i, best, F_SE_POS]
            if not _luma_fit(img, bg, i, v[i], s_ev, row0, sigma_dn, blur_var_px2,
                             shape_error, max_chi2, s_max, min_z, sat_dn, reach_sigmas, seek,
                             &yl[0], &use[0], &ebuf[0], out):
                continue
            v_out[i] = out[0]
            se_out[i] = out[4]
            w_out[i] = out[2]
            n_kept += 1
    return n_kept




def luma_column_z(const unsigned char[:, :, ::1] img, const unsigned char[:, ::1] bg,
                  const double[::1] v, const unsigned char[::1] sat,
                  const double[:, :, ::1] cand, Py_ssize_t row0, double sigma_dn,
                  double blur_var_px2, double s_max, int sat_dn,
                  const double[::1] offsets_px, double[:, ::1] z_out) -> None:
    """The luma's light near each found column's row: the significance of a Gaussian of
    the stripe's width at ``v + offset`` on the luma's contrast, over a straight
    background, for each of ``offsets_px``.

    The matched filter over a window of three widths, three rows and the largest offset
    either side of ``v`` (rows with a channel at ``sat_dn`` left out) at a fixed row and
    width: its least-squares amplitude over its standard error against the luma's local
    noise (the larger of ``sigma_dn`` and the robust lag-2 residual within 24 rows, the
    window left out; texture counts as noise). The width is the evidence's (the fit of
    ``cand`` nearest ``v``) less ``blur_var_px2``, at least 0.6 px. Arguments as
    :func:`luma_rows`'; ``z_out`` (len(offsets_px), W) float64 gets the significance at
    each offset (px, down), NaN where ``v`` is NaN, the core is clipped (``sat``) or the
    window holds fewer than six rows.
    """
    cdef Py_ssize_t w = img.shape[0], h = img.shape[1]
    cdef Py_ssize_t n_off = offsets_px.shape[0], reach = 0
    cdef Py_ssize_t i, best, j, a, b, m, o
    cdef double s_ev, s0, sig, num
    if bg.shape[0] != 3 * w or bg.shape[1] != h or v.shape[0] != w or sat.shape[0] != w \
            or cand.shape[0] != w or z_out.shape[0] != n_off or z_out.shape[1] != w:
        raise ValueError("luma_column_z: img (W, H, 3), bg (3 W, H), v, sat, cand (W, ...) "
                         "and z_out (len(offsets_px), W) disagree in shape")
    for o in range(n_off):
        if not isfinite(offsets_px[o]) or fabs(offsets_px[o]) > 8.0:
            raise ValueError("luma_column_z: offsets_px must be finite, at most 8 px")
        reach = imax(reach, <Py_ssize_t>ceil(fabs(offsets_px[o])))
    # the window spans the row's reach either side of every offset
    cdef Py_ssize_t max_m = 2 * (<Py_ssize_t>ceil(3.0 * s_max) + 4 + reach) + 1
    cdef float[::1] yl = np.empty(max_m, np.float32)
    cdef unsigned char[::1] use = np.empty(max_m, np.uint8)
    cdef double[::1] ebuf = np.empty(max_m)
    with nogil:
        for i in range(w):
            for o in range(n_off):
                z_out[o, i] = NAN
            if not isfinite(v[i]) or sat[i]:
                continue
            best = _nearest_fit(cand, i, v[i])
            s_ev = pmin(cand[i, best, F_WIDTH] if best >= 0 else 1.0, s_max)
            s0 = sqrt(pmax(s_ev * s_ev - blur_var_px2, 0.36))
            j = <Py_ssize_t>rint(v[i]) - row0
            if j < 0 or j >= h:
                continue
            # one window for every offset; the noise from the rows beyond it
            a = imax(j - <Py_ssize_t>ceil(3.0 * s_ev) - 3 - reach, 0)
            b = imin(j + <Py_ssize_t>ceil(3.0 * s_ev) + 4 + reach, h)
            m = b - a
            if m < 6:
                continue
            sig = _local_sigma(img, i, j, j - a, sigma_dn)
            _luma_window(img, bg, i, a, m, sat_dn, &yl[0], &use[0])
            for o in range(n_off):
                num = linear_z(&yl[0], &use[0], m, row0 + a, v[i] + offsets_px[o], s0, sig,
                               &ebuf[0])
                # (0 from linear_z: fewer than six rows, or a Gaussian the line explains)
                if num != 0.0:
                    z_out[o, i] = num


cdef enum:
    # the histograms' bins: a quarter DN each (differences of the luma and chroma in
    # thousandths of a DN, 250 to a bin), up to 512 DN
    N_BINS = 2048
    BIN_MILLI_DN = 250


cdef double _hist_median(const long long* hist) noexcept nogil:
    """Median of a histogram of ``N_BINS`` quarter-DN bins (the bin's centre), DN; 0 when
    empty."""
    cdef long long n = 0, acc = 0
    cdef Py_ssize_t k
    for k in range(N_BINS):
        n += hist[k]
    if n == 0:
        return 0.0
    for k in range(N_BINS):
        acc += hist[k]
        if 2 * acc >= n:
            return (k + 0.5) * BIN_MILLI_DN / 1000.0
    return (N_BINS - 0.5) * BIN_MILLI_DN / 1000.0


def lag_medians(const unsigned char[:, :, ::1] img, Py_ssize_t step, Py_ssize_t lag):
    """Median absolute differences at lags 1 and ``lag`` rows of the luma and the
    red-difference chroma (JFIF weights) down every ``step``-th column of ``img`` (W, H,
    3) BGR (transposed: one image column per array row): ``(Y_1, Y_lag, Cr_1, Cr_lag)``,
    DN, to a quarter DN (histograms, no sort)."""
    cdef Py_ssize_t n_cols = img.shape[0], n = img.shape[1], ii, i, j
    if step < 1 or lag < 1:
        raise ValueError("lag_medians: step and lag must be at least 1")
    cdef long long[:, ::1] hist = np.zeros((4, N_BINS), np.int64)
    cdef const unsigned char* col
    cdef long long y0, c0, y1, c1, y2, c2, d
    with nogil:
        for ii in range((n_cols + step - 1) // step):
            i = ii * step
            col = &img[i, 0, 0]
            for j in range(n - lag):
                # (thousandths of a DN: 114 b + 587 g + 299 r, -81 b - 419 g + 500 r)
                y0 = 114 * col[3 * j] + 587 * col[3 * j + 1] + 299 * col[3 * j + 2]
                c0 = -81 * col[3 * j] - 419 * col[3 * j + 1] + 500 * col[3 * j + 2]
                y1 = 114 * col[3 * j + 3] + 587 * col[3 * j + 4] + 299 * col[3 * j + 5]
                c1 = -81 * col[3 * j + 3] - 419 * col[3 * j + 4] + 500 * col[3 * j + 5]
                y2 = 114 * col[3 * (j + lag)] + 587 * col[3 * (j + lag) + 1] + \
                    299 * col[3 * (j + lag) + 2]
                c2 = -81 * col[3 * (j + lag)] - 419 * col[3 * (j + lag) + 1] + \
                    500 * col[3 * (j + lag) + 2]
                d = (y1 - y0 if y1 >= y0 else y0 - y1) // BIN_MILLI_DN
                hist[0, d if d < N_BINS else N_BINS - 1] += 1
                d = (y2 - y0 if y2 >= y0 else y0 - y2) // BIN_MILLI_DN
                hist[1, d if d < N_BINS else N_BINS - 1] += 1
                d = (c1 - c0 if c1 >= c0 else c0 - c1) // BIN_MILLI_DN
                hist[2, d if d < N_BINS else N_BINS - 1] += 1
                d = (c2 - c0 if c2 >= c0 else c0 - c2) // BIN_MILLI_DN
                hist[3, d if d < N_BINS else N_BINS - 1] += 1
    return (_hist_median(&hist[0, 0]), _hist_median(&hist[1, 0]),
            _hist_median(&hist[2, 0]), _hist_median(&hist[3, 0]))
