"""The own-light test of step 4 of the stripe model, compiled (:mod:`slitcli.laser.judge`).

A fit on the evidence averaged along the stripe must show in its own column's evidence:
:func:`own_light`, inlined where candidates are fitted (``fill_gaps``) and judged
(:mod:`slitcli.laser._c.light`'s table). Arithmetic in the numba kernels' order.
"""

from libc.math cimport INFINITY, NAN, ceil, exp, floor, isfinite, sqrt

from slitcli.laser._c.profile cimport MIN_SIGMA_PX, imax, imin, pmax

# (slitcli.laser.judge's OWN_REACH_PX; tests/test_laser_kernels.py checks that they agree)
cdef extern from *:
    """
    #define SLITCLI_OWN_REACH_PX 1.0
    """
    const double OWN_REACH_PX "SLITCLI_OWN_REACH_PX"


cdef inline double _own_amplitude(const float* yi, const unsigned char* mi,
                                  const unsigned char* ci, Py_ssize_t n, double pos,
                                  double s, double amp, double sigma, double shape_error,
                                  double* se) noexcept nogil:
    """Peak of a Gaussian at row ``pos`` of width ``s`` in one column's own evidence
    ``yi`` (n,) (rows where ``mi`` and not ``ci``), on a straight background, by weighted
    least squares (row variance ``sigma^2 + (shape_error amp g)^2`` as the profile
    fit's); returns the peak, ``se`` its standard error (NaN, NaN with too few rows)."""
    cdef Py_ssize_t w_half = <Py_ssize_t>ceil(3.0 * s + 3.0)
    cdef Py_ssize_t c = <Py_ssize_t>floor(pos + 0.5)
    cdef Py_ssize_t j, m = 0
    # the normal equations of (1, d, g): h (symmetric) and b
    cdef double h00 = 0.0, h01 = 0.0, h02 = 0.0, h11 = 0.0, h12 = 0.0, h22 = 0.0
    cdef double b0 = 0.0, b1 = 0.0, b2 = 0.0
    cdef double d, g, var, yj, sg, c00, c01, c02, det, i20, i21, i22
    for j in range(imax(c - w_half, 0), imin(c + w_half + 1, n)):
        if not mi[j] or ci[j]:
            continue
        d = j - pos
        g = exp(-0.5 * d * d / (s * s))
        sg = shape_error * amp * g
        var = sigma * sigma + sg * sg
        yj = yi[j]
        b0 += yj / var
        b1 += d * yj / var
        b2 += g * yj / var
        h00 += 1.0 / var
        h01 += d / var
        h02 += g / var
        h11 += d * d / var
        h12 += d * g / var
        h22 += g * g / var
        m += 1
    if m < 6:
        se[0] = NAN
        return NAN
    # 3x3 inverse by cofactors (the peak's row of it)
    c00 = h11 * h22 - h12 * h12
    c01 = h12 * h02 - h01 * h22
    c02 = h01 * h12 - h11 * h02
    det = h00 * c00 + h01 * c01 + h02 * c02
    if not abs(det) > 1e-300:
        se[0] = NAN
        return NAN
    i20 = (h01 * h12 - h02 * h11) / det
    i21 = (h02 * h01 - h00 * h12) / det
    i22 = (h00 * h11 - h01 * h01) / det
    se[0] = sqrt(pmax(i22, 0.0))
    return i20 * b0 + i21 * b1 + i22 * b2


cdef inline bint own_light(const float* yi, const float* yai, const unsigned char* ci,
                           const unsigned char* mi, Py_ssize_t n, double pos, double width,
                           double sigma_y, double shape_error, double z) noexcept nogil:
    """Whether the light the averaged evidence shows at a crossing is its column's own
    (True), or not: the peak of a Gaussian at row ``pos``, width ``width``, in the
    averaged evidence ``yai`` (n,) must show in the column's own evidence ``yi``: the
    own peak (noise ``sigma_y``) may fall short of it by at most ``z`` standard errors,
    looked for within ``OWN_REACH_PX`` of ``pos`` (:func:`slitcli.laser.judge.
    own_light`'s notes). ``ci``, ``mi``: the column's clipped and searched rows."""
    cdef double s = pmax(width, MIN_SIGMA_PX)
    cdef double se = 0.0, a, a_avg, short = -INFINITY
    cdef Py_ssize_t step
    a_avg = _own_amplitude(yai, mi, ci, n, pos, s, 0.0, 1.0, 0.0, &se)
    if not a_avg > 0.0:
        return True
    # on a steep stripe the average's centre at an end column leans towards the inner
    # columns' rows (by up to a pixel): the own light is looked for within OWN_REACH_PX
    # of it, the best place kept
    for step in range(-2, 3):
        a = _own_amplitude(yi, mi, ci, n, pos + 0.5 * OWN_REACH_PX * step, s, a_avg, sigma_y,
                           shape_error, &se)
        if isfinite(a):
            short = pmax(short, (a - a_avg) / se)
    return not (short > -INFINITY and short < -z)
