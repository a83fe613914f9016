# cflags: -fno-math-errno -fno-trapping-math
"""Gaps of the chosen stripe, compiled: columns between two found ones refitted on the
averaged evidence at the row interpolated across the gap (:func:`fill_gaps`; called by
:mod:`slitcli.laser.extract` after the choice along the stripe, re-exported by
:mod:`slitcli.laser.candidates`). Moved unchanged from ``candidates.pyx``: the same
arithmetic and flags, so the same rows."""

import numpy as np

from libc.float cimport DBL_MAX
from libc.math cimport INFINITY, NAN, ceil, fabs, isfinite, isnan

from slitcli.laser._c.fields cimport N_FIELDS
from slitcli.laser._c.light cimport own_light
from slitcli.laser._c.profile cimport clip_plateau, fit_gaussian, imax, imin, pmax, pmin


cdef inline double _fit_gap(const float[:, ::1] y_avg, const unsigned char[:, ::1] ci,
                            const unsigned char[:, ::1] mi, Py_ssize_t i, double row,
                            double width, double sigma_avg, double z_min,
                            double shape_error, double s_max, double* res,
                            unsigned char* use, double* ebuf) noexcept nogil:
    """The averaged evidence of column ``i`` fitted near ``row`` (rows of ``y_avg``),
    starting at width ``width``: the fitted row, or NaN where the fit is not within a
    pixel of ``row`` or less than ``z_min`` significant (against ``sigma_avg``)."""
    cdef Py_ssize_t n = y_avg.shape[1], jj
    cdef double s0 = pmin(pmax(width, 0.6), s_max)
    cdef Py_ssize_t w_half = <Py_ssize_t>ceil(3.0 * s0 + 3.0)
    cdef Py_ssize_t c = <Py_ssize_t>(row + 0.5)
    cdef Py_ssize_t j0 = imax(c - w_half, 0)
    cdef Py_ssize_t j1 = imin(c + w_half + 1, n)
    cdef Py_ssize_t m = j1 - j0
    if m < 6:
        return NAN
    for jj in range(m):
        use[jj] = mi[i, j0 + jj] and not ci[i, j0 + jj]
    if fit_gaussian(&y_avg[i, j0], use, m, j0, row, s0, sigma_avg, shape_error, s_max, res,
                    ebuf, NULL) and fabs(res[0] - row) <= 1.0 and res[3] >= z_min:
        return res[0]
    return NAN


cdef inline double _clipped_gap(const unsigned char[:, ::1] ci,
                                const unsigned char[:, ::1] mi,
                                const unsigned char[:, :, ::1] img,
                                const unsigned char[:, ::1] bg, Py_ssize_t i, double row,
                                double sat_dn, Py_ssize_t max_run,
                                double* red) noexcept nogil:
    """The clipped core of column ``i`` through ``row`` (rows of ``ci``), centred on its
    plateau (:func:`clip_plateau`): NaN where ``row`` is not clipped, the run is longer
    than ``max_run`` or its centre more than a pixel from ``row``. ``red`` (H',) is
    scratch."""
    cdef Py_ssize_t n = ci.shape[1], c = <Py_ssize_t>(row + 0.5), a, b
    cdef double pc
    if c < 0 or c >= n or not ci[i, c] or not mi[i, c]:
        return NAN
    a = c
    while a > 0 and ci[i, a - 1] and mi[i, a - 1]:
        a -= 1
    b = c + 1
    while b < n and ci[i, b] and mi[i, b]:
        b += 1
    if b - a > max_run:
        return NAN
    pc = clip_plateau(img, bg, i, a, b, sat_dn, red)
    return pc if fabs(pc - row) <= 1.0 else NAN


def fill_gaps(double[::1] v, double[::1] amp, const double[:, :, ::1] cand,
              const float[:, ::1] y, const float[:, ::1] y_avg, clipped, mask,
              double sigma_y, double sigma_avg, Py_ssize_t row0, Py_ssize_t max_gap,
              double max_jump_px, double z_min, double shape_error, double s_max,
              double own_z, const unsigned char[:, :, ::1] img=None,
              const unsigned char[:, ::1] bg=None, double sat_dn=255.0,
              unsigned char[::1] sat=None):
    """Columns without a stripe between two found ones at most ``max_gap + 1`` apart
    whose rows differ by at most ``max_jump_px`` a column: the stripe passes there, so
    the averaged evidence ``y_avg`` (W, H', float32, rows from ``row0``) of each column
    between is fitted at the row interpolated across the gap (starting at the width of
    the left column's candidate nearest its row). Where that fit holds (``z_min``
    significant against ``sigma_avg``, within a pixel of the interpolated row, and its
    light the column's own: :func:`~slitcli.laser.judge.own_light` on ``y`` (W, H')
    float32, ``own_z``), ``v`` (W,) float64, rows from the image's top, gets the fitted
    row and ``amp`` (W,) float64 the left column's peak (0 where that is NaN), in place.
    ``cand`` (W, K, N_FIELDS) is the candidate table, ``clipped`` and ``mask`` (W, H')
    bool. With ``img`` (W, H', 3) uint8 BGR, its opening ``bg`` (3 W, H') and the red
    clipping level ``sat_dn``, a gap column clipped at the interpolated row takes the
    centre of that clipped core's plateau (a run at most as long as a clipped seed's,
    within a pixel of the row) instead: the stripe passes there, so the clip is its
    core, though its flanks need not show red (a white core with white shoulders);
    ``sat`` (W,) bool, when given, is set there."""
    cdef const unsigned char[:, ::1] ci = np.ascontiguousarray(clipped).view(np.uint8)
    cdef const unsigned char[:, ::1] mi = np.ascontiguousarray(mask).view(np.uint8)
    cdef Py_ssize_t n_cols = v.shape[0], n = y_avg.shape[1]
    if amp.shape[0] != n_cols or cand.shape[0] != n_cols or cand.shape[2] != N_FIELDS \
            or y.shape[0] != n_cols or y_avg.shape[0] != n_cols or ci.shape[0] != n_cols \
            or mi.shape[0] != n_cols or y.shape[1] != n or ci.shape[1] != n \
            or mi.shape[1] != n:
        raise ValueError("fill_gaps: v, amp (W,), cand (W, K, N_FIELDS), y, y_avg, "
                         "clipped and mask (W, H') disagree in shape")
    if n == 0 or n_cols == 0:
        return
    if img is not None and (bg is None or img.shape[0] != n_cols or img.shape[1] != n
                            or bg.shape[0] != 3 * n_cols or bg.shape[1] != n):
        raise ValueError("fill_gaps: img (W, H', 3) and bg (3 W, H') disagree with y")
    if sat is not None and sat.shape[0] != n_cols:
        raise ValueError("fill_gaps: sat must be (W,)")
    cdef bint mark = sat is not None
    cdef bint plateaus = img is not None
    # (a clipped core spans more than the stripe's width, as column_candidates' seeds)
    cdef Py_ssize_t max_run = <Py_ssize_t>ceil(5.0 * s_max)
    cdef unsigned char[::1] use = np.empty(n, np.uint8)
    cdef double[::1] ebuf = np.empty(n)
    cdef double[::1] red = np.empty(n)
    cdef double res[6]
    cdef Py_ssize_t a = -1, b, i, q, k_best
    cdef double best, d, width, fill, t, row, fit
    with nogil:
        for b in range(n_cols):
            if not isfinite(v[b]):
                continue
            if a < 0 or b - a <= 1 or b - a > max_gap + 1 \
                    or not fabs(v[b] - v[a]) <= max_jump_px * (b - a):
                a = b
                continue
            # the width of the left column's candidate nearest its row (the first of
            # equals)
            k_best = -1
            best = INFINITY
            for q in range(cand.shape[1]):
                d = fabs(cand[a, q, 0] - v[a])
                if d < best:
                    best = d
                    k_best = q
            width = cand[a, imax(k_best, 0), 2]
            fill = 0.0 if isnan(amp[a]) else pmin(pmax(amp[a], -DBL_MAX), DBL_MAX)
            for i in range(a + 1, b):
                t = <double>(i - a) / (b - a)
                row = v[a] + t * (v[b] - v[a])
                fit = _clipped_gap(ci, mi, img, bg, i, row - row0, sat_dn, max_run,
                                   &red[0]) if plateaus else NAN
                if isfinite(fit):
                    v[i] = fit + row0
                    amp[i] = fill
                    if mark:
                        sat[i] = 1
                    continue
                fit = _fit_gap(y_avg, ci, mi, i, row - row0, width, sigma_avg, z_min,
                               shape_error, s_max, res, &use[0], &ebuf[0])
                if isfinite(fit) and own_light(&y[i, 0], &y_avg[i, 0], &ci[i, 0], &mi[i, 0],
                                               n, fit, width, sigma_y, shape_error, own_z):
                    v[i] = fit + row0
                    amp[i] = fill
            a = b
