"""Step 2 of the stripe model, compiled: the profile across one column, fitted.

The model and its terms are :mod:`slitcli.laser.profile`'s notes; these are its kernels,
inlined into the modules that cimport them (the candidates' inner loop runs ~900 fits a
frame). A row ``jj`` of a window starting at image row ``j0`` is image row ``j0 + jj``.
The arithmetic is the numba kernels' in the same order (Python ``min``/``max``: the first
argument kept unless the second is strictly beyond it), so that results are bit-identical
where the C compiler may not reorder sums.
"""

from libc.math cimport exp, fabs, floor, sqrt
from libc.string cimport memcpy

# the fit's sizes (slitcli.laser.profile's; tests/test_laser_kernels.py checks that the two
# agree); the fields of the candidate table are in fields.pxd
cdef enum:
    N_PAR = 5
    MAX_ITER = 6
    MIN_ROWS = 6

cdef extern from *:
    """
    #define SLITCLI_CONVERGED_PX 0.005
    #define SLITCLI_MIN_SIGMA_PX 0.3
    #define SLITCLI_SEED_MIN_SIGMA_PX 0.6
    """
    const double CONVERGED_PX "SLITCLI_CONVERGED_PX"
    const double MIN_SIGMA_PX "SLITCLI_MIN_SIGMA_PX"
    # narrowest width a fit starts from at a seed (slitcli.laser.candidates')
    const double SEED_MIN_SIGMA_PX "SLITCLI_SEED_MIN_SIGMA_PX"

# The sums of the normal equations over a window's rows, with the 20 accumulators in five
# 4-lane GCC vectors: each lane sums its own product row after row, the same IEEE
# operations in the same order as one scalar accumulator (no reassociation), so the
# results are those of the scalar loop, bit for bit. Scalar code spilled the accumulators
# to the stack, and each row's sums then waited on a store and a load (about 2x slower).
# (GCC and Clang lower the vectors to whatever the target has, down to plain scalars.)
cdef extern from *:
    """
    typedef double slitcli_d4 __attribute__((vector_size(32)));

    static inline double slitcli_normal_rows(
            const float* y, const unsigned char* use, Py_ssize_t m, Py_ssize_t j0,
            double ref, double c, double a, double v0, double u, double sl, double var0,
            double shape_error, const double* e, int with_chi, double* acc)
    {
        slitcli_d4 a0 = {0.0, 0.0, 0.0, 0.0}, a1 = a0, a2 = a0, a3 = a0, a4 = a0, g = a0;
        double chi = 0.0, n = 0.0, g0 = 0.0;
        for (Py_ssize_t jj = 0; jj < m; jj++) {
            double w = use[jj] ? 1.0 : 0.0;
            double t = ((double)(j0 + jj) - v0) * u;
            double ej = e[jj];
            double model = a * ej;
            double d = (double)(j0 + jj) - ref;
            double r = (double)y[jj] - ((c + sl * d) + model);
            double rw = r * w;
            if (with_chi) {
                double sm = shape_error * model;
                chi += (rw * r) / (var0 + sm * sm);
            }
            n += w;
            double j2 = (model * t) * u;
            double j3 = j2 * t;
            slitcli_d4 v = {ej, j2, j3, d};
            g0 += rw;
            g += v * rw;          /* g1 .. g4 */
            a0 += v * w;          /* h01 .. h04 */
            a1 += v * (ej * w);   /* h11 .. h14 */
            a2 += v * (j2 * w);   /* h22 .. h24 in lanes 1-3 */
            a3 += v * (j3 * w);   /* h33, h34 in lanes 2-3 */
            a4 += v * (d * w);    /* h44 in lane 3 */
        }
        acc[0] = n;
        acc[1] = a0[0]; acc[2] = a0[1]; acc[3] = a0[2]; acc[4] = a0[3];
        acc[6] = a1[0]; acc[7] = a1[1]; acc[8] = a1[2]; acc[9] = a1[3];
        acc[12] = a2[1]; acc[13] = a2[2]; acc[14] = a2[3];
        acc[18] = a3[2]; acc[19] = a3[3];
        acc[24] = a4[3];
        acc[25] = g0; acc[26] = g[0]; acc[27] = g[1]; acc[28] = g[2]; acc[29] = g[3];
        return chi;
    }
    """
    double normal_rows "slitcli_normal_rows"(
        const float* y, const unsigned char* use, Py_ssize_t m, Py_ssize_t j0, double ref,
        double c, double a, double v0, double u, double sl, double var0, double shape_error,
        const double* e, int with_chi, double* acc) noexcept nogil


cdef inline double pmax(double a, double b) noexcept nogil:
    """Python's ``max(a, b)``: ``b`` only where strictly larger (a NaN ``a`` is kept)."""
    return b if b > a else a


cdef inline double pmin(double a, double b) noexcept nogil:
    """Python's ``min(a, b)``."""
    return b if b < a else a


cdef inline Py_ssize_t imax(Py_ssize_t a, Py_ssize_t b) noexcept nogil:
    return b if b > a else a


cdef inline Py_ssize_t imin(Py_ssize_t a, Py_ssize_t b) noexcept nogil:
    return b if b < a else a


cdef inline double half_max_sigma(const float* y, const unsigned char* use, Py_ssize_t n,
                                  Py_ssize_t k) noexcept nogil:
    """The half-maximum width over 2.355 of the hump of ``y`` (n rows) whose peak is row
    ``k``: the contiguous used rows at or above half its peak, px."""
    cdef Py_ssize_t lo = k, hi = k
    cdef double half = 0.5 * y[k]
    while lo > 0 and y[lo - 1] >= half and use[lo - 1]:
        lo -= 1
    while hi < n - 1 and y[hi + 1] >= half and use[hi + 1]:
        hi += 1
    return (hi - lo + 1) / 2.355


cdef inline double used_min(const float* y, const unsigned char* use,
                            Py_ssize_t m) noexcept nogil:
    """The least of ``y`` (m rows) over the used rows (1e300 none): a flat top's base."""
    cdef double base = 1e300
    cdef Py_ssize_t jj
    for jj in range(m):
        if use[jj]:
            base = pmin(base, y[jj])
    return base


cdef inline bint _solve(double* a, const double* b, double* x,
                        bint factor) noexcept nogil:
    """Solve ``a x = b`` for a small symmetric positive definite ``a`` by its Cholesky
    factor ``L`` (``a = L L'``), which ``factor`` first writes over the lower triangle of
    ``a`` (the factor of the normal equations serves the step and the covariance alike);
    False if ``a`` is not positive definite. ``b`` is kept."""
    cdef Py_ssize_t i, j, k
    cdef double d, t
    if factor:
        for j in range(N_PAR):
            d = a[j * N_PAR + j]
            for k in range(j):
                d -= a[j * N_PAR + k] * a[j * N_PAR + k]
            if not d > 1e-300:
                return False
            d = sqrt(d)
            a[j * N_PAR + j] = d
            for i in range(j + 1, N_PAR):
                t = a[i * N_PAR + j]
                for k in range(j):
                    t -= a[i * N_PAR + k] * a[j * N_PAR + k]
                a[i * N_PAR + j] = t / d
    for i in range(N_PAR):  # L z = b
        t = b[i]
        for k in range(i):
            t -= a[i * N_PAR + k] * x[k]
        x[i] = t / a[i * N_PAR + i]
    for i in range(N_PAR - 1, -1, -1):  # L' x = z
        t = x[i]
        for k in range(i + 1, N_PAR):
            t -= a[k * N_PAR + i] * x[k]
        x[i] = t / a[i * N_PAR + i]
    return True


cdef inline void gaussian_rows(Py_ssize_t j0, double v0, double s, double* e,
                               Py_ssize_t m) noexcept nogil:
    """``e[k] = exp(-(j0 + k - v0)^2 / (2 s^2))`` for ``k < m``, by the ratio recurrence
    from the row nearest the centre (``exp(-(t + u)^2 / 2) = exp(-t^2 / 2)
    exp(-t u - u^2 / 2)``, ``u = 1 / s``): three exponentials instead of one a row."""
    cdef double u = 1.0 / s
    cdef Py_ssize_t jc = imin(imax(<Py_ssize_t>floor(v0 - j0 + 0.5), 0), m - 1)
    cdef double tc = (j0 + jc - v0) * u
    cdef double dd, q
    cdef Py_ssize_t jj
    e[jc] = exp(-0.5 * tc * tc)
    dd = exp(-u * u)
    q = exp(-tc * u - 0.5 * u * u)
    for jj in range(jc + 1, m):
        e[jj] = e[jj - 1] * q
        q *= dd
    q = exp(tc * u - 0.5 * u * u)
    for jj in range(jc - 1, -1, -1):
        e[jj] = e[jj + 1] * q
        q *= dd


cdef inline double _normal(const float* y, const unsigned char* use, Py_ssize_t m,
                           Py_ssize_t j0, double ref, const double* p, double sigma,
                           double shape_error, double* h, double* g,
                           double* e, bint with_chi, Py_ssize_t* n_used,
                           bint rows_ready=False) noexcept nogil:
    """Chi-square of the model at ``p = (c, A, v0, s, b)`` under the row variance with
    the model error (only ``with_chi``, else 0), and the Gauss-Newton normal equations
    ``h = J' J / sigma^2``, ``g = J' r / sigma^2`` there (the noise alone weighs the
    rows); ``n_used`` gets the rows used. The background is the line ``c + b (v - ref)``;
    ``e`` (m,) is scratch for the Gaussian's samples (``rows_ready``: it holds them
    already, :func:`gaussian_rows` at ``v0``, ``s``)."""
    cdef double s = p[3]
    cdef double u = 1.0 / s
    cdef double chi
    cdef double wt = 1.0 / (sigma * sigma)
    cdef double acc[30]
    cdef Py_ssize_t i, k
    if not rows_ready:
        gaussian_rows(j0, p[2], s, e, m)
    # unused rows weigh 0 (branch-free); the sums: normal_rows
    chi = normal_rows(y, use, m, j0, ref, p[0], p[1], p[2], u, p[4], sigma * sigma,
                      shape_error, e, with_chi, acc)
    # (row-major 5 x 5: entry (i, k) at 5 i + k)
    for i in range(N_PAR):
        for k in range(i, N_PAR):
            h[i * N_PAR + k] = wt * acc[i * N_PAR + k]
    for i in range(N_PAR):
        for k in range(i):
            h[i * N_PAR + k] = h[k * N_PAR + i]
    for i in range(N_PAR):
        g[i] = wt * acc[25 + i]
    n_used[0] = <Py_ssize_t>acc[0]
    return chi


cdef inline bint fit_gaussian(const float* y, const unsigned char* use, Py_ssize_t m,
                              Py_ssize_t j0, double v_start, double s_start, double sigma,
                              double shape_error, double s_max, double* out,
                              double* ebuf, const double* e_start) noexcept nogil:
    """Fit ``c + b (v - v_start) + A exp(-(v - v0)^2 / 2 s^2)`` to ``y`` (m rows, image
    rows ``j0 ..``) where ``use``: Gauss-Newton from ``v_start``, ``s_start`` with a
    bounded step; ``out`` (6,) gets ``(v0, A, s, z, se_v0, chi2)`` (``z``: ``A`` over its
    standard error; ``chi2`` the reduced chi-square). False when fewer than ``MIN_ROWS``
    rows, no convergence to a positive peak inside the window, or a width beyond
    ``2 s_max``. ``ebuf`` (at least m) is scratch; ``e_start`` (m,), unless NULL, holds
    :func:`gaussian_rows` at ``v_start``, ``s_start`` already (a seed's screen computed
    them), which the first step then takes instead of computing them again."""
    cdef double h[N_PAR * N_PAR]
    cdef double g[N_PAR]
    cdef double dx[N_PAR]
    cdef double p[N_PAR]
    cdef double lo = 1e300, pk = -1e300, chi = 0.0, lim_v, var_a = 0.0, var_v = 0.0
    cdef Py_ssize_t jj, q, idx, it, n_use = 0
    for q in range(N_PAR):
        p[q] = 0.0
    for jj in range(m):
        if use[jj]:
            lo = pmin(lo, y[jj])
            if fabs(j0 + jj - v_start) <= pmax(1.5, s_start):
                pk = pmax(pk, y[jj])
    if lo == 1e300:
        return False
    p[0] = lo
    p[1] = pmax(pk - lo, 1e-3)
    p[2] = v_start
    p[3] = s_start
    if e_start != NULL:
        memcpy(ebuf, e_start, m * sizeof(double))
    for it in range(MAX_ITER):
        chi = _normal(y, use, m, j0, v_start, p, sigma, shape_error, h, g, ebuf, False,
                      &n_use, it == 0 and e_start != NULL)
        if n_use < MIN_ROWS:
            return False
        for q in range(N_PAR):
            h[q * N_PAR + q] *= 1.0 + 1e-6
        if not _solve(h, g, dx, True):
            return False
        # keep the step sane: the centre moves at most a width, the width changes by at
        # most half of itself
        lim_v = pmax(p[3], 0.5)
        dx[2] = pmin(pmax(dx[2], -lim_v), lim_v)
        dx[3] = pmin(pmax(dx[3], -0.5 * p[3]), 0.5 * p[3])
        for q in range(N_PAR):
            p[q] += dx[q]
        p[3] = pmax(p[3], 0.5 * MIN_SIGMA_PX)
        if p[3] > 2.0 * s_max or not (j0 - 0.5 <= p[2] <= j0 + m - 0.5):
            return False
        if fabs(dx[2]) < CONVERGED_PX and fabs(dx[3]) < 0.01 * p[3]:
            break
    chi = _normal(y, use, m, j0, v_start, p, sigma, shape_error, h, g, ebuf, True, &n_use)
    if p[1] <= 0.0 or n_use < MIN_ROWS:
        return False
    # covariance: inverse of h, diagonal entries 1 (A) and 2 (v0), from one factor
    for idx in range(1, 3):
        for q in range(N_PAR):
            g[q] = 0.0
        g[idx] = 1.0
        if not _solve(h, g, dx, idx == 1):
            return False
        if idx == 1:
            var_a = dx[idx]
        else:
            var_v = dx[idx]
    if not (var_a > 0.0 and var_v > 0.0):
        return False
    out[0] = p[2]
    out[1] = p[1]
    out[2] = p[3]
    out[3] = p[1] / sqrt(var_a)
    out[4] = sqrt(var_v)
    out[5] = chi / (n_use - N_PAR if n_use - N_PAR > 1 else 1)
    return True


cdef inline double plateau_centre(const double* red, Py_ssize_t n, Py_ssize_t a,
                                  Py_ssize_t b, double level) noexcept nogil:
    """Centre of a clipped run ``a .. b - 1`` of the red profile ``red`` (n,): the
    midpoint of where the profile crosses ``level`` on either side (linear interpolation;
    a side cut off by the border takes the run's own end)."""
    cdef Py_ssize_t j = a
    cdef double up, dn, lo_v, hi_v
    while j > 0 and red[j - 1] >= level:
        j -= 1
    up = j - 0.5
    if j > 0:
        lo_v = red[j - 1]
        hi_v = red[j]
        up = j - 1 + (level - lo_v) / pmax(hi_v - lo_v, 1e-9)
    j = b - 1
    while j < n - 1 and red[j + 1] >= level:
        j += 1
    dn = j + 0.5
    if j < n - 1:
        hi_v = red[j]
        lo_v = red[j + 1]
        dn = j + (hi_v - level) / pmax(hi_v - lo_v, 1e-9)
    return 0.5 * (up + dn)


cdef inline double clip_plateau(const unsigned char[:, :, ::1] img,
                                const unsigned char[:, ::1] bg, Py_ssize_t i, Py_ssize_t a,
                                Py_ssize_t b, double sat_dn, double* red) noexcept nogil:
    """Centre of the clipped run ``a .. b - 1`` of column ``i`` of ``img`` (W, H', 3) BGR:
    :func:`plateau_centre` of its red profile at half way from the opening ``bg``
    (3 W, H') at the run's middle row to the clip ``sat_dn``. ``red`` (H',) is
    scratch."""
    cdef Py_ssize_t n = img.shape[1], jj
    for jj in range(n):
        red[jj] = img[i, jj, 2]
    return plateau_centre(red, n, a, b, 0.5 * (bg[3 * i + 2, (a + b - 1) // 2] + sat_dn))


cdef inline bint flat_top(const float* y, const unsigned char* use, Py_ssize_t m,
                          Py_ssize_t j0, double v_start, double base, double sigma,
                          double* out) noexcept nogil:
    """A hump that is no Gaussian (a flat or skewed top), centred without a shape model:
    the centre of gravity of its upper half. The peak is the largest used ``y`` within 2
    rows of ``v_start``; the hump is the run of rows above half its height over
    ``base``, which must end inside the window on both sides. ``out`` gets ``(v0,
    height, s, z, se_v0, chi2)`` with ``s`` the half-height width over 2.355, ``z`` the
    height over ``sigma`` and ``se_v0`` the centre of gravity's noise."""
    cdef Py_ssize_t kp = -1, jj, a, b
    cdef double height, level, sw = 0.0, sv = 0.0, wgt, v0, var = 0.0, dv
    for jj in range(m):
        if use[jj] and fabs(j0 + jj - v_start) <= 2.0 and (kp < 0 or y[jj] > y[kp]):
            kp = jj
    if kp < 0:
        return False
    height = y[kp] - base
    if height <= 0.0:
        return False
    level = base + 0.5 * height
    a = kp
    while a > 0 and use[a - 1] and y[a - 1] >= level:
        a -= 1
    b = kp
    while b < m - 1 and use[b + 1] and y[b + 1] >= level:
        b += 1
    if a == 0 or b == m - 1 or not (use[a - 1] and use[b + 1]):
        return False  # a flank cut off: no crossing on that side
    for jj in range(a, b + 1):
        wgt = y[jj] - level
        sw += wgt
        sv += wgt * jj
    v0 = sv / sw
    for jj in range(a, b + 1):
        dv = jj - v0
        var += dv * dv
    out[0] = j0 + v0
    out[1] = height
    # the full width at half height between the interpolated crossings (the rows above
    # half height overstate it by up to a row)
    out[2] = ((b + (y[b] - level) / pmax(y[b] - y[b + 1], 1e-9))
              - (a - 1 + (level - y[a - 1]) / pmax(y[a] - y[a - 1], 1e-9))) / 2.355
    out[3] = height / sigma
    out[4] = sigma * sqrt(var) / sw
    out[5] = 0.0
    return True


# the evidence's type in the matched filter below (float32 in the kernels; float64 for
# tests)
ctypedef fused real:
    float
    double


cdef inline bint screen_sums(const real* yi, const real* ya, const unsigned char* use,
                             Py_ssize_t m, Py_ssize_t j0, double v, double s, double* e,
                             double* num) noexcept nogil:
    """The seed screen of a window on two evidences at once (the Gaussian's samples ``e``
    (m,), written here, and the line's sums are shared): the significance of a Gaussian
    of fixed centre ``v`` and width ``s`` on a straight background over the used rows of
    ``yi`` (m rows from image row ``j0``) is ``num[0] / (sigma num[2])``, on ``ya``
    ``num[1] / (sigma num[2])``; False where it is 0 on any evidence (fewer than six
    rows, or a Gaussian the line explains)."""
    cdef double n = 0.0, s2 = 0.0, se = 0.0, sd = 0.0, sdd = 0.0, sde = 0.0, sy = 0.0
    cdef double sdy = 0.0, sey = 0.0, ty = 0.0, tdy = 0.0, tey = 0.0
    cdef double w, d, ej, yj, det, ae, be, ee
    cdef Py_ssize_t jj
    gaussian_rows(j0, v, s, e, m)
    for jj in range(m):
        w = 1.0 if use[jj] else 0.0
        d = j0 + jj - v
        ej = e[jj] * w
        n += w
        sd += d * w
        sdd += d * d * w
        se += ej
        sde += d * ej
        s2 += ej * e[jj]
        yj = yi[jj] * w
        sy += yj
        sdy += d * yj
        sey += ej * yi[jj]
        yj = ya[jj] * w
        ty += yj
        tdy += d * yj
        tey += ej * ya[jj]
    if n < 6.0:
        return False
    # the line's normal equations (n, sd; sd, sdd) give the projections of the
    # Gaussian onto the line, which leave e_perp . e_perp and e_perp . y
    det = n * sdd - sd * sd
    if not det > 0.0:
        return False
    ae = (sdd * se - sd * sde) / det
    be = (n * sde - sd * se) / det
    ee = s2 - (ae * se + be * sde)
    if not ee > 1e-12 * s2:
        return False
    num[0] = sey - (ae * sy + be * sdy)
    num[1] = tey - (ae * ty + be * tdy)
    num[2] = sqrt(ee)
    return True


cdef inline double linear_z(const real* y, const unsigned char* use, Py_ssize_t m,
                            Py_ssize_t j0, double v, double s, double sigma,
                            double* e) noexcept nogil:
    """Significance of a Gaussian of fixed centre ``v`` and width ``s`` on a straight
    background over the used rows of ``y`` (m rows from image row ``j0``): the linear
    least-squares amplitude over its standard error; 0 with fewer than six rows."""
    cdef double num[3]
    if not screen_sums(y, y, use, m, j0, v, s, e, num):
        return 0.0
    return num[0] / (sigma * num[2])
