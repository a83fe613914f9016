"""Step 4 of the stripe model, compiled: which candidates can be the laser.

The tests of :mod:`slitcli.laser.judge` (its notes give the model): a fit's own tests
(place, width, shape, Eq. 2), the sheet's thickness, the frame's width spread, the
laser's colour and its share, and whether the surface beneath a candidate is one
surface. The arithmetic is the numba kernels' in the same order (Python's ``min`` and
``max``: the first argument kept unless the second is strictly beyond it; a division by
zero gives inf or NaN, as numba's ``error_model="numpy"`` did), so that results are
bit-identical; the one fused multiply-add numba made (``_dot3``, ``fastmath`` contract)
is spelled out with ``fma``.
"""

import numpy as np

from libc.math cimport INFINITY, M_PI, ceil, fabs, fma, isfinite, isnan, rint, sqrt, tan

from slitcli.laser._c.fields cimport (
    F_AMP,
    F_CHI2,
    F_FLAT,
    F_KB,
    F_KG,
    F_KR,
    F_NCORE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_TB,
    F_TG,
    F_TR,
    F_WIDTH,
    F_Z,
    N_FIELDS,
)
from slitcli.laser._c.profile cimport pmax, pmin
from slitcli.laser._c.select cimport median_inplace

# (the constants of slitcli.laser.judge and slitcli.laser.profile; constants() returns
# them and tests/test_laser_kernels.py checks that the two sides agree)
cdef extern from *:
    """
    #define SLITCLI_MIN_SIGMA_PX 0.3
    #define SLITCLI_EQ_WIDTH 2.5
    #define SLITCLI_PIXEL_VAR (1.0 / 12.0)
    #define SLITCLI_COLOUR_Z 2.0
    #define SLITCLI_MAX_LASER_GB 0.6
    #define SLITCLI_COLOUR_SIGMAS 3.0
    """
    const double MIN_SIGMA_PX "SLITCLI_MIN_SIGMA_PX"
    const double EQ_WIDTH "SLITCLI_EQ_WIDTH"
    const double PIXEL_VAR "SLITCLI_PIXEL_VAR"
    const double COLOUR_Z "SLITCLI_COLOUR_Z"
    const double MAX_LASER_GB "SLITCLI_MAX_LASER_GB"
    const double COLOUR_SIGMAS "SLITCLI_COLOUR_SIGMAS"

cdef enum:
    COLOUR_SUPPORT = 8

#: the largest finite double (``_fits_sheet`` caps an infinite standard error by it)
cdef double DBL_BIG = 1.7976931348623157e308


def constants() -> dict:
    """The compiled constants, by their Python names (for the test that they agree)."""
    return {"MIN_SIGMA_PX": MIN_SIGMA_PX, "EQ_WIDTH": EQ_WIDTH, "PIXEL_VAR": PIXEL_VAR,
            "COLOUR_Z": COLOUR_Z, "COLOUR_SUPPORT": COLOUR_SUPPORT,
            "MAX_LASER_GB": MAX_LASER_GB, "COLOUR_SIGMAS": COLOUR_SIGMAS,
            "F_POS": F_POS, "F_WIDTH": F_WIDTH, "F_Z": F_Z, "F_SE_POS": F_SE_POS,
            "F_CHI2": F_CHI2, "F_SAT": F_SAT, "F_TR": F_TR, "F_TG": F_TG, "F_TB": F_TB,
            "F_KR": F_KR, "F_KG": F_KG, "F_KB": F_KB, "F_NCORE": F_NCORE,
            "F_FLAT": F_FLAT}


cdef inline bint _yellow(const double* c, double hue_tan, double sigma_dn) noexcept nogil:
    """Whether the light an unclipped core adds (``F_T*``) has a hue beyond ``atan
    hue_tan`` towards yellow by more than ``COLOUR_SIGMAS`` noise sigmas of its
    linear form ``sqrt 3 (g - b) - hue_tan (2 r - g - b)`` (each channel's mean over
    the core: ``sigma_dn / sqrt(F_NCORE)``)."""
    cdef double se, d
    if not c[F_NCORE] > 0 or c[F_SAT] > 0 or not isfinite(hue_tan):
        return False
    se = sigma_dn / sqrt(pmax(c[F_NCORE], 1.0))
    d = sqrt(3.0) * (c[F_TG] - c[F_TB]) - hue_tan * (2.0 * c[F_TR] - c[F_TG] - c[F_TB])
    return d > COLOUR_SIGMAS * se * sqrt(6.0 + 6.0 * hue_tan * hue_tan)


cdef void _model_tests(const double* cand, Py_ssize_t n, Py_ssize_t height_px, double s_max,
                       double max_chi2, double min_th, double min_delta_th,
                       double hue_tan, double sigma_dn, unsigned char* ok) noexcept nogil:
    """The tests of one fit on its own (place, width, shape, Eq. 2 and the hue of the
    light its core adds) of the ``n`` fits of ``cand`` (n, N_FIELDS) into ``ok``
    (n,)."""
    cdef Py_ssize_t i
    cdef const double* c
    cdef double pos, s, tr, tg, tb, tot
    cdef bint sat, good, eq2
    for i in range(n):
        c = cand + i * N_FIELDS
        pos = c[F_POS]
        s = c[F_WIDTH]
        sat = c[F_SAT] > 0
        good = isfinite(pos) and pos >= -0.5 and pos <= height_px - 0.5 and \
            s >= MIN_SIGMA_PX and s <= s_max and \
            (sat or c[F_FLAT] > 0 or c[F_CHI2] <= max_chi2)
        tr = c[F_TR]
        tg = c[F_TG]
        tb = c[F_TB]
        tot = tr + tg + tb
        eq2 = tot > 0 and tr / tot > min_th and \
            tr / tot - pmax(tg, tb) / tot > min_delta_th
        # the unclipped rows of a clipped core are the clip's shoulders, which a tone
        # curve whitens: their colour is not the laser's (the red flanks that seeded the
        # core were)
        ok[i] = good and (eq2 or sat) and \
            not _yellow(c, hue_tan, sigma_dn)


cdef bint _fits_sheet(double s, double se_pos, double sheet_px, double ref,
                      double tolerance, double blur_var) noexcept nogil:
    """A fitted width ``s`` that a sheet of sigma ``r x sheet_px`` (``r`` 1 or ``ref``)
    gives, up to ``tolerance`` times either way, the pixel's extent added (and, to the
    widest, the image processing's blur ``blur_var``, px^2: subsampled chroma blurs the
    evidence by up to it, fully on a grey surface, where the evidence is all chroma,
    less on a red one, where the red channel's luma keeps full resolution), widened by
    two
    standard errors of the width (about the centre's ``se_pos``); True where the
    sheet's width is unknown (:func:`slitcli.laser.judge.valid_candidates`)."""
    cdef double se, a, b, r
    cdef int i
    if not isfinite(sheet_px):
        return True
    se = 0.0 if isnan(se_pos) else pmin(se_pos, DBL_BIG)
    se = 2.0 * se
    for i in range(2):
        r = 1.0 if i == 0 else ref
        a = r * sheet_px / tolerance
        b = r * sheet_px * tolerance
        if sqrt(a * a + PIXEL_VAR) - se <= s and \
                s <= sqrt(b * b + PIXEL_VAR + blur_var) + se:
            return True
    return False


cdef bint _laser_colour(const double* cand, Py_ssize_t n, const unsigned char* ok,
                        double min_z, double* g, double* b, double* laser) noexcept nogil:
    """The laser's colour (RGB, red 1) into ``laser`` from the frame's strong unclipped
    candidates among the ``n`` of ``cand`` (median of their core contrast over its red;
    ``g``, ``b`` scratch of n entries); False with fewer than ``COLOUR_SUPPORT`` of
    them."""
    cdef Py_ssize_t i, m = 0
    cdef const double* c
    for i in range(n):
        c = cand + i * N_FIELDS
        if ok[i] and c[F_Z] >= COLOUR_Z * min_z and c[F_SAT] == 0 and \
                c[F_NCORE] > 0 and c[F_TR] > 0:
            g[m] = c[F_TG] / c[F_TR]
            b[m] = c[F_TB] / c[F_TR]
            m += 1
    if m < COLOUR_SUPPORT:
        return False
    laser[0] = 1.0
    laser[1] = pmin(pmax(median_inplace(g, m), 0.0), MAX_LASER_GB)
    laser[2] = pmin(pmax(median_inplace(b, m), 0.0), MAX_LASER_GB)
    return True


cdef void _sheet_tests(const double* cand, Py_ssize_t n, const double* sheet_px,
                       double strong_z, double sheet_tolerance, Py_ssize_t sheet_support,
                       double blur_var, unsigned char* ok, double* vals) noexcept nogil:
    """The sheet's thickness test of :func:`shape_tests` of the ``n`` fits of ``cand``
    (``sheet_px`` (n,); ``blur_var`` px^2 the image processing's blur) into ``ok``
    (``vals`` scratch of n entries)."""
    cdef Py_ssize_t i, m = 0
    cdef const double* c
    cdef double s, ratio, ref
    # the sheet's thickness relative to the parameter's; where the frame shows its own
    # clearly (a stripe's worth of strong unclipped columns: a few strong columns beside
    # a clipped core are widened by it), that is a second reference
    for i in range(n):
        c = cand + i * N_FIELDS
        s = c[F_WIDTH]
        ratio = sqrt(pmax(s * s - PIXEL_VAR - blur_var, 0.01)) / sheet_px[i]
        if ok[i] and not c[F_SAT] > 0 and c[F_Z] >= strong_z and isfinite(ratio):
            vals[m] = ratio
            m += 1
    ref = median_inplace(vals, m) if m >= (sheet_support if sheet_support > COLOUR_SUPPORT
                                    else COLOUR_SUPPORT) else 1.0
    for i in range(n):
        c = cand + i * N_FIELDS
        if ok[i] and not c[F_SAT] > 0:
            ok[i] = _fits_sheet(c[F_WIDTH], c[F_SE_POS], sheet_px[i], ref, sheet_tolerance,
                                blur_var)


cdef bint _shape_tests(const double* cand, Py_ssize_t n, const double* sheet_px,
                       Py_ssize_t height_px, double s_max, double min_z, double max_chi2,
                       double min_th, double min_delta_th, double sheet_tolerance,
                       Py_ssize_t sheet_support, double width_spread, double blur_var,
                       double hue_tan, double sigma_dn, unsigned char* ok, double* work,
                       double* laser) noexcept nogil:
    """:func:`shape_tests` of the ``n`` fits of ``cand`` (``sheet_px`` (n,) or NULL;
    ``work`` scratch of 3 n entries); returns whether the frame shows the laser's
    colour."""
    cdef Py_ssize_t i, m = 0
    cdef const double* c
    cdef double strong_z = COLOUR_Z * min_z, widest
    _model_tests(cand, n, height_px, s_max, max_chi2, min_th, min_delta_th, hue_tan,
                 sigma_dn, ok)
    if sheet_px != NULL:
        _sheet_tests(cand, n, sheet_px, strong_z, sheet_tolerance, sheet_support, blur_var,
                     ok, work)
    # the sheet's width as the frame shows it: its strong unclipped columns
    for i in range(n):
        c = cand + i * N_FIELDS
        if ok[i] and not c[F_SAT] > 0 and c[F_Z] >= strong_z:
            work[m] = c[F_WIDTH]
            m += 1
    if m >= COLOUR_SUPPORT:
        widest = width_spread * median_inplace(work, m)
        for i in range(n):
            c = cand + i * N_FIELDS
            if not c[F_SAT] > 0:
                ok[i] = ok[i] and c[F_WIDTH] <= widest
    return _laser_colour(cand, n, ok, min_z, work + n, work + 2 * n, laser)


def shape_tests(const double[:, :, ::1] cand, sheet_px, Py_ssize_t height_px, double s_max,
                double min_z, double max_chi2, double min_th, double min_delta_th,
                double sheet_tolerance, Py_ssize_t sheet_support, double width_spread,
                double blur_var_px2=0.0, double max_hue_deg=90.0,
                double channel_sigma_dn=0.0):
    """:func:`slitcli.laser.judge.valid_candidates` up to the colour tests.

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64
        The candidate table (:mod:`slitcli.laser.profile`'s fields), rows in px.
    sheet_px : ndarray, shape (W, K), float64, or None
        The sheet's sigma at each candidate's row, px (NaN unknown); None: not judged.
    height_px : int
        Image rows.
    s_max, min_z, max_chi2, min_th, min_delta_th, sheet_tolerance, sheet_support, \
width_spread
        As :func:`~slitcli.laser.judge.valid_candidates` (``width_spread``:
        ``WIDTH_SPREAD``).
    blur_var_px2 : float
        Variance the image processing adds to the stripe's profile across rows, px^2
        (the sheet's test; :data:`slitcli.laser.luma.CHAIN_VAR_PX2` under 4:2:0 chroma).
    max_hue_deg, channel_sigma_dn : float
        The hue test of an unclipped core's light (``LaserParams.max_hue_deg``; 90: none)
        and the noise of one channel, DN.

    Returns
    -------
    ok : ndarray, shape (W, K), bool
        The candidates that pass.
    laser : ndarray, shape (3,), float64, or None
        The laser's colour (RGB, red 1) from the frame's strong unclipped candidates;
        None with fewer than ``COLOUR_SUPPORT`` of them.
    """
    if cand.shape[2] != N_FIELDS:
        raise ValueError(f"cand has {cand.shape[2]} fields, not {N_FIELDS}")
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1], n = w * k
    ok_arr = np.empty((w, k), np.bool_)
    if n == 0:
        return ok_arr, None
    cdef unsigned char[:, ::1] ok = ok_arr
    cdef const double[:, ::1] sheet
    cdef const double* sheet_ptr = NULL
    if sheet_px is not None:
        sheet = np.ascontiguousarray(sheet_px, np.float64)
        if sheet.shape[0] != w or sheet.shape[1] != k:
            raise ValueError(f"sheet_px is {(sheet.shape[0], sheet.shape[1])}, the "
                             f"candidates {(w, k)}")
        sheet_ptr = &sheet[0, 0]
    # (scratch for the medians, and the laser's colour after it)
    work_arr = np.empty(3 * n + 3)
    cdef double[::1] work = work_arr
    cdef bint found
    cdef double hue_tan = tan(max_hue_deg * (M_PI / 180.0)) if max_hue_deg < 90.0 \
        else INFINITY
    with nogil:
        found = _shape_tests(&cand[0, 0, 0], n, sheet_ptr, height_px, s_max, min_z,
                             max_chi2, min_th, min_delta_th, sheet_tolerance, sheet_support,
                             width_spread, blur_var_px2, hue_tan, channel_sigma_dn,
                             &ok[0, 0], &work[0], &work[3 * n])
    return ok_arr, (work_arr[3 * n:].copy() if found else None)


cdef inline double _dot3(double a0, double a1, double a2, const double* b) noexcept nogil:
    """``a . b`` of 3-vectors, rounded as numpy's ``matmul`` rounds it: the multiply-adds
    fused as numba's ``fastmath`` contraction fused them (measured on its kernel)."""
    return fma(a2, b[2], fma(a0, b[0], a1 * b[1]))


cdef inline double _norm3(double a0, double a1, double a2) noexcept nogil:
    return sqrt(a0 * a0 + a1 * a1 + a2 * a2)


cdef inline double _colour_residual(const double* t, const double* k,
                                    const double* lu) noexcept nogil:
    """Size of a core contrast ``t`` (RGB, DN) across the plane of the laser colour (unit
    ``lu``) and the surface colour ``k`` (texture and shading move the surface along its
    colour, the laser adds along its own)."""
    cdef double kd = _dot3(k[0], k[1], k[2], lu)
    cdef double e0 = k[0] - kd * lu[0], e1 = k[1] - kd * lu[1], e2 = k[2] - kd * lu[2]
    cdef double n2 = _norm3(e0, e1, e2), td, te
    if n2 > 1e-6 * _norm3(k[0], k[1], k[2]):
        e0 = e0 / n2
        e1 = e1 / n2
        e2 = e2 / n2
    else:
        e0 = e1 = e2 = 0.0
    td = _dot3(t[0], t[1], t[2], lu)
    te = t[0] * e0 + t[1] * e1 + t[2] * e2
    return _norm3(t[0] - td * lu[0] - te * e0, t[1] - td * lu[1] - te * e1,
                  t[2] - td * lu[2] - te * e2)


cdef inline bint _laser_share(const double* t, const double* k, const double* laser,
                              const double* lu, double n_core, double channel_sigma_dn,
                              double share_z) noexcept nogil:
    """:func:`laser_share` on pointers to 3-vectors."""
    cdef double kk = _norm3(k[0], k[1], k[2])
    cdef double kn[3]
    kn[0] = k[0] / kk
    kn[1] = k[1] / kk
    kn[2] = k[2] / kk
    cdef double kd = _dot3(kn[0], kn[1], kn[2], laser)
    cdef double e[3]
    e[0] = laser[0] - kd * kn[0]
    e[1] = laser[1] - kd * kn[1]
    e[2] = laser[2] - kd * kn[2]
    cdef double en = _norm3(e[0], e[1], e[2])
    e[0] = e[0] / en
    e[1] = e[1] / en
    e[2] = e[2] / en
    cdef double power = _norm3(t[0], t[1], t[2]) * _dot3(e[0], e[1], e[2], lu)
    cdef double se = channel_sigma_dn / sqrt(pmax(n_core, 1.0))
    cdef double across = t[0] * e[0] + t[1] * e[1] + t[2] * e[2]
    return not (power >= 2.0 * share_z * se and across < share_z * se)


def laser_share(const double[::1] t, const double[::1] k, const double[::1] laser,
                const double[::1] lu, double n_core, double channel_sigma_dn,
                double share_z) -> bool:
    """Whether the light a candidate adds shows the laser's colour where the colours can
    tell it from the surface's (True: it does, or they cannot).

    Parameters
    ----------
    t : ndarray, shape (3,), float64
        The core contrast (RGB, DN): the laser's light ``a L`` plus a change of the
        surface's own colour ``b K`` (texture, shading).
    k : ndarray, shape (3,), float64
        The surface colour beneath (RGB, DN).
    laser, lu : ndarray, shape (3,), float64
        The laser's colour (red 1) and its unit vector.
    n_core : float
        Rows of the candidate's core.
    channel_sigma_dn : float
        Noise sigma of one channel, DN.
    share_z : float
        Significance asked of the laser's share (``LASER_SHARE_Z``).

    Notes
    -----
    Only the part of ``L`` across ``K``, the unit vector ``e``, tells the two apart:
    ``t . e`` is ``a`` times ``L . e`` plus noise of ``channel_sigma_dn / sqrt(n)``.
    Where all of ``t`` being laser light would show across ``K`` by at least twice
    ``share_z`` noise sigmas but ``t . e`` stays below ``share_z`` sigmas, the light is
    the surface's own (a brighter patch of its texture next to a faint stripe's end). On
    a surface of the laser's colour ``L . e`` is near zero and the test does not judge.
    """
    if t.shape[0] != 3 or k.shape[0] != 3 or laser.shape[0] != 3 or lu.shape[0] != 3:
        raise ValueError("t, k, laser and lu must be 3-vectors")
    return _laser_share(&t[0], &k[0], &laser[0], &lu[0], n_core, channel_sigma_dn, share_z)


def colour_tests(const double[:, :, ::1] cand, const double[::1] laser,
                 const double[::1] lu, double channel_sigma_dn, double colour_error,
                 double share_z, unsigned char[:, ::1] ok) -> None:
    """The colour tests of :func:`slitcli.laser.judge.valid_candidates` on the
    candidates that show a core, applied to ``ok_arr`` (W, K, bool, in place).

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64
        The candidate table.
    laser, lu : ndarray, shape (3,), float64
        The laser's colour (red 1) and its unit vector.
    channel_sigma_dn : float
        Noise sigma of one channel, DN.
    colour_error : float
        The colour residual allowed beyond the noise, as a share of the contrast; 1:
        no residual test (the laser-share test still runs).
    share_z : float
        Significance of the laser's share (:func:`laser_share`); 0 skips that test.
    ok : ndarray, shape (W, K), bool, C-contiguous
        The candidates that passed so far; those that fail are set False.
    """
    if cand.shape[2] != N_FIELDS:
        raise ValueError(f"cand has {cand.shape[2]} fields, not {N_FIELDS}")
    if ok.shape[0] != cand.shape[0] or ok.shape[1] != cand.shape[1]:
        raise ValueError("ok_arr and cand differ in shape")
    if laser.shape[0] != 3 or lu.shape[0] != 3:
        raise ValueError("laser and lu must be 3-vectors")
    cdef Py_ssize_t u, q
    cdef const double* c
    cdef double t[3]
    cdef double kc[3]
    cdef double lim
    with nogil:
        for u in range(ok.shape[0]):
            for q in range(ok.shape[1]):
                c = &cand[u, q, 0]
                # (a clipped core's unclipped rows are the clip's whitened shoulders:
                # their colour is not judged, as in the model tests)
                if not ok[u, q] or not c[F_NCORE] > 0 or c[F_SAT] > 0:
                    continue
                t[0] = c[F_TR]
                t[1] = c[F_TG]
                t[2] = c[F_TB]
                kc[0] = c[F_KR]
                kc[1] = c[F_KG]
                kc[2] = c[F_KB]
                if colour_error < 1.0:
                    # (at 1 every contrast passes: its part off the plane is at most
                    # its size)
                    lim = COLOUR_SIGMAS * channel_sigma_dn / sqrt(pmax(c[F_NCORE], 1.0)) \
                        + colour_error * _norm3(t[0], t[1], t[2])
                    ok[u, q] = _colour_residual(t, kc, &lu[0]) <= lim
                if ok[u, q] and share_z > 0:
                    ok[u, q] = _laser_share(t, kc, &laser[0], &lu[0], c[F_NCORE],
                                            channel_sigma_dn, share_z)


cdef inline bint _side_colour(const unsigned char* img_t, Py_ssize_t n_rows, Py_ssize_t col,
                              double pos, double edge, double* tot) noexcept nogil:
    """Sum (B, G, R) into ``tot`` of column ``col`` of ``img_t`` (W, n_rows, 3) at the two
    rows ``rint(pos + edge)`` and ``rint(pos + edge +- 1)`` (away from ``pos``); False
    where one of them lies outside the image."""
    cdef Py_ssize_t ri, c
    cdef bint inside = True
    cdef double step = 1.0 if edge > 0 else -1.0, r
    cdef int extra
    cdef const unsigned char* px
    tot[0] = tot[1] = tot[2] = 0.0
    for extra in range(2):
        r = rint(pos + step * (fabs(edge) + extra))
        inside = inside and 0 <= r and r < n_rows
        ri = <Py_ssize_t>pmin(pmax(r, 0.0), <double>(n_rows - 1))
        px = img_t + (col * n_rows + ri) * 3
        for c in range(3):
            tot[c] += <double>px[c]
    return inside


cdef bint _breaks(const unsigned char* img_t, Py_ssize_t n_cols, Py_ssize_t n_rows,
                  Py_ssize_t u, double pos, double off, double channel_sigma_dn, double step,
                  double min_dn) noexcept nogil:
    """Whether the surfaces above and below row ``pos`` of column ``u`` of ``img_t``
    (n_cols, n_rows, 3; ``off`` rows away) differ in colour by more than ``step``
    (chromaticity) plus the noise, in the neighbouring columns too; sides darker than
    ``min_dn`` per channel on average are not judged."""
    cdef Py_ssize_t col, shift, c
    cdef double up[3]
    cdef double dn[3]
    cdef double s_up, s_dn, d, noise
    cdef bint inside
    # an edge along the stripe runs on: the break must show in the neighbouring columns
    # too (at the same rows); where an object's side crosses the stripe (its end column)
    # the surfaces differ in one column only
    for shift in range(-1, 2):
        col = u + shift
        col = 0 if col < 0 else (n_cols - 1 if col > n_cols - 1 else col)
        inside = _side_colour(img_t, n_rows, col, pos, -off, up)
        inside = _side_colour(img_t, n_rows, col, pos, off, dn) and inside
        s_up = up[0] + up[1] + up[2]
        s_dn = dn[0] + dn[1] + dn[2]
        if not (inside and s_up >= 6.0 * min_dn and s_dn >= 6.0 * min_dn):
            return False
        d = 0.0
        for c in range(3):
            d = pmax(d, fabs(up[c] / s_up - dn[c] / s_dn))
        # a chromaticity of a two-row sum of three channels: noise about sigma sqrt(2) /
        # sum per channel, on each side
        noise = channel_sigma_dn * sqrt(2.0) * (1.0 / s_up + 1.0 / s_dn)
        if not d > step + 4.0 * noise:
            return False
    return True


def surface_table(const double[:, :, ::1] cand, const unsigned char[:, :, ::1] img_t,
                  Py_ssize_t row0, double channel_sigma_dn,
                  const unsigned char[:, ::1] need, double step, double min_dn):
    """:func:`slitcli.laser.judge.surface_continues` of the candidates where ``need``.

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64, C-contiguous
        The candidate table, rows from the image's top.
    img_t : ndarray, shape (W, H', 3), uint8, BGR, C-contiguous
        The image transposed (one column per array row), rows from ``row0``.
    row0 : int
        Image row of ``img_t``'s first row.
    channel_sigma_dn : float
        Noise sigma of one channel, DN.
    need : ndarray, shape (W, K), bool, C-contiguous
        The candidates to judge.
    step, min_dn : float
        The chromaticity step beyond which the sides are two surfaces, and the least
        mean DN per channel of a side that is judged (LaserParams.surface_step,
        surface_min_dn).

    Returns
    -------
    ndarray, shape (W, K), bool
        True where the surface continues, where it cannot be told, and where not
        ``need``.
    """
    if cand.shape[2] != N_FIELDS:
        raise ValueError(f"cand has {cand.shape[2]} fields, not {N_FIELDS}")
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1], n_cols = img_t.shape[0]
    cdef Py_ssize_t n_rows = img_t.shape[1], i
    if need.shape[0] != w or need.shape[1] != k:
        raise ValueError("need and cand differ in shape")
    if img_t.shape[2] != 3:
        raise ValueError("img_t must be a (W, H', 3) image")
    out_arr = np.empty((w, k), np.bool_)
    if w * k == 0:
        return out_arr
    if n_cols == 0 or n_rows == 0:
        out_arr[...] = True
        return out_arr
    cdef unsigned char[:, ::1] out = out_arr
    cdef unsigned char* o = &out[0, 0]
    cdef const unsigned char* nd = &need[0, 0]
    cdef const unsigned char* im = &img_t[0, 0, 0]
    cdef const double* c
    cdef double pos, wid, off
    with nogil:
        for i in range(w * k):
            c = &cand[0, 0, 0] + i * N_FIELDS
            pos = c[F_POS] - row0
            o[i] = True
            # a clipped core's light reaches far past its fitted width (bloom, the
            # halo beyond the clip), unevenly above and below: the rows beside it show
            # its own light, not the bare surface
            if not nd[i] or not isfinite(pos) or c[F_SAT] > 0:
                continue
            wid = c[F_WIDTH]
            # (an integer number of rows, as numba's math.ceil gave)
            off = <double><long long>ceil(EQ_WIDTH * (1.0 if isnan(wid) else wid) + 2.0)
            o[i] = not _breaks(im, n_cols, n_rows, i // k, pos, off, channel_sigma_dn, step,
                               min_dn)
    return out_arr


def one_crossing_table(const double[:, :, ::1] cand, const unsigned char[:, ::1] ok):
    """:func:`slitcli.laser.judge.one_crossing`: ``ok`` (W, K) with each candidate False
    that a valid candidate of its column overlaps (centres closer than the sum of the
    two widths) while brighter and narrower; a new (W, K) bool array. The comparisons
    are numpy's (IEEE: a NaN field overlaps nothing)."""
    if cand.shape[2] != N_FIELDS:
        raise ValueError(f"cand has {cand.shape[2]} fields, not {N_FIELDS}")
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1], col, a, b
    if ok.shape[0] != w or ok.shape[1] != k:
        raise ValueError("ok and cand differ in shape")
    out_arr = np.empty((w, k), np.bool_)
    if w * k == 0:
        return out_arr
    cdef unsigned char[:, ::1] out = out_arr
    cdef const double* c
    cdef const double* ca
    cdef const double* cb
    cdef bint keep
    with nogil:
        for col in range(w):
            c = &cand[col, 0, 0]
            for b in range(k):
                cb = c + b * N_FIELDS
                keep = ok[col, b] != 0
                a = 0
                while keep and a < k:
                    ca = c + a * N_FIELDS
                    if ok[col, a] and fabs(ca[F_POS] - cb[F_POS]) < ca[F_WIDTH] + cb[F_WIDTH] \
                            and ca[F_AMP] > cb[F_AMP] and ca[F_WIDTH] < cb[F_WIDTH]:
                        keep = False
                    a += 1
                out[col, b] = keep
    return out_arr

