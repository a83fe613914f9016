# cflags: -fno-math-errno -fno-trapping-math
"""Step 3 of the stripe model, compiled: candidate crossings per column, seeded and fitted.

The seeds (``seeds.pxd``), the fits (``profile.pxd``) and their notes are
:mod:`slitcli.laser.candidates`'; these are its kernels. Arithmetic in the numba kernels'
order and types (float32 evidence, float64 sums; Python ``min``/``max``; uint8
differences as numba's unsigned 64-bit ones), so that results are bit-identical to
numba's but for ``profile.pxd``'s ``_normal`` sums, which numba could reorder
(``fastmath``) and C here does not: IEEE order, the same on every machine.
"""

import numpy as np

from libc.math cimport ceil, exp, fabs, isnan, rint, sqrt

from slitcli.laser._c.light cimport OWN_REACH_PX
from slitcli.laser._c.fields cimport (F_AMP, F_CHI2, F_FLAT, F_GNOISE, F_KB, F_KG, F_KR,
                                      F_NCORE, F_NOISE, F_POS, F_SAT, F_SE_POS, F_TB, F_TG,
                                      F_TR, F_WIDTH, F_Z, N_FIELDS)
from slitcli.laser._c.profile cimport (CONVERGED_PX, MAX_ITER, MIN_ROWS, MIN_SIGMA_PX, N_PAR,
                                       SEED_MIN_SIGMA_PX, clip_plateau, fit_gaussian,
                                       flat_top, gaussian_rows, half_max_sigma, imax, imin,
                                       linear_z, pmax, pmin, real, screen_sums, used_min)
from slitcli.laser._c.seeds cimport (CLIP_SIGMAS, FLANK_ROWS, MEAN_TO_SIGMA, N_SEEDS, NMS_HALF,
                                     NOISE_HALF, _local_sigma, _seeds)

# (slitcli.laser.candidates' constants, as seeds.pxd's; tests/test_laser_kernels.py checks
# that they agree)
cdef double SEED_EFFICIENCY = exp(-0.25 / (4.0 * (SEED_MIN_SIGMA_PX * SEED_MIN_SIGMA_PX)))


def constants():
    """The compiled constants (:mod:`slitcli.laser.candidates`', :mod:`.profile`'s and
    its field indices, :mod:`.judge`'s ``OWN_REACH_PX``), for the test that they agree
    with the Python ones."""
    return {"NMS_HALF": NMS_HALF, "FLANK_ROWS": FLANK_ROWS, "NOISE_HALF": NOISE_HALF,
            "N_SEEDS": N_SEEDS, "SEED_MIN_SIGMA_PX": SEED_MIN_SIGMA_PX,
            "SEED_EFFICIENCY": SEED_EFFICIENCY, "MEAN_TO_SIGMA": MEAN_TO_SIGMA,
            "CLIP_SIGMAS": CLIP_SIGMAS, "CONVERGED_PX": CONVERGED_PX, "N_PAR": N_PAR,
            "MAX_ITER": MAX_ITER, "MIN_ROWS": MIN_ROWS, "OWN_REACH_PX": OWN_REACH_PX,
            "MIN_SIGMA_PX": MIN_SIGMA_PX, "N_FIELDS": N_FIELDS,
            "F_POS": F_POS, "F_AMP": F_AMP, "F_WIDTH": F_WIDTH, "F_Z": F_Z,
            "F_SE_POS": F_SE_POS, "F_CHI2": F_CHI2, "F_SAT": F_SAT, "F_NOISE": F_NOISE,
            "F_TR": F_TR, "F_TG": F_TG, "F_TB": F_TB, "F_KR": F_KR, "F_KG": F_KG,
            "F_KB": F_KB, "F_NCORE": F_NCORE, "F_FLAT": F_FLAT, "F_GNOISE": F_GNOISE}


def _linear_z(const real[::1] y, use, Py_ssize_t j0, double v, double s, double sigma,
              double[::1] e):
    """Significance of a Gaussian of fixed centre ``v`` and width ``s`` on a straight
    background over the used rows of ``y`` (rows ``j0 ..``): the linear least-squares
    amplitude over its standard error, ``e_perp . y / (sigma |e_perp|)`` with ``e_perp``
    the Gaussian's part that the line does not explain (the matched filter's output
    against the noise); 0 with fewer than six rows.

    Parameters
    ----------
    y : ndarray, shape (m,), float32 or float64
        The evidence, DN.
    use : ndarray, shape (m,), bool
        Rows used.
    j0 : int
        Image row of ``y[0]``.
    v, s : float
        The Gaussian's centre (image rows) and width, px.
    sigma : float
        Noise of ``y``, DN.
    e : ndarray, shape (>= m,), float64
        Scratch.
    """
    cdef const unsigned char[::1] u = np.ascontiguousarray(use).view(np.uint8)
    cdef Py_ssize_t m = y.shape[0]
    cdef double z
    if u.shape[0] < m or e.shape[0] < m:
        raise ValueError("_linear_z: use and e need as many entries as y")
    if m == 0:
        return 0.0
    with nogil:
        z = linear_z(&y[0], &u[0], m, j0, v, s, sigma, &e[0])
    return z


cdef inline void _core_colour(const unsigned char[:, :, ::1] img,
                              const unsigned char[:, ::1] bg, Py_ssize_t i,
                              const unsigned char* ci, Py_ssize_t n, double* o) noexcept nogil:
    """The light the core of the candidate ``o`` (its fields) adds, and the surface
    colour there (RGB): ``F_T*``, ``F_K*``, ``F_NCORE``. (The differences of uint8s are
    numba's unsigned 64-bit ones; the opening is below the image, so they never wrap.)"""
    cdef double tr = 0.0, tg = 0.0, tb = 0.0, kr = 0.0, kg = 0.0, kb = 0.0
    cdef double reach = pmax(o[F_WIDTH], 1.0), pos = o[F_POS]
    cdef Py_ssize_t nc = 0, j
    cdef unsigned long long br, bgg, bb
    for j in range(imax(<Py_ssize_t>(pos - reach), 0), imin(<Py_ssize_t>(pos + reach) + 2, n)):
        if fabs(j - pos) > reach or ci[j]:
            continue
        br = bg[3 * i + 2, j]
        bgg = bg[3 * i + 1, j]
        bb = bg[3 * i, j]
        tr += <double>(<unsigned long long>img[i, j, 2] - br)
        tg += <double>(<unsigned long long>img[i, j, 1] - bgg)
        tb += <double>(<unsigned long long>img[i, j, 0] - bb)
        kr += br + 0.5
        kg += bgg + 0.5
        kb += bb + 0.5
        nc += 1
    o[F_NCORE] = nc
    if nc > 0:
        o[F_TR] = tr / nc
        o[F_TG] = tg / nc
        o[F_TB] = tb / nc
        o[F_KR] = kr / nc
        o[F_KG] = kg / nc
        o[F_KB] = kb / nc



cdef struct _Params:
    # column_candidates' scalar arguments
    double sigma_y
    double sigma_avg
    double seed_dn
    double strong_z
    double screen_z      # SEED_EFFICIENCY x weak_z
    double eff           # SEED_EFFICIENCY
    double sat_dn        # (integer DN: the sums below are exact, as numba's int64 ones)
    double sat_g         # green's and blue's clipping levels (a white core: both reached)
    double sat_b
    double s_max
    double shape_error
    double max_chi2
    Py_ssize_t max_run


cdef inline bint _fit_seed(const float* yi, const float* ya, const unsigned char* mi,
                           Py_ssize_t n, const unsigned char* use, Py_ssize_t j0,
                           Py_ssize_t m, double centre, double s0, double core, double noise,
                           bint sat, const _Params* pr, double* res, double* res_avg,
                           double* ebuf, double* escr, double* sig, double* gsig,
                           bint* flat) noexcept nogil:
    """One seed fitted (``column_candidates``' notes) on the window's own evidence (``m``
    rows of ``yi`` from ``j0``, the column's ``n``) or the averaged ``ya``, the one whose
    screen is the larger first, the other where its screen's bound can beat that fit
    (and the own one only where it cannot reach ``strong_z`` on the average's terms); a
    Gaussian that fails the shape test is tried as a flat top. ``res`` gets the fit kept, ``sig`` and ``gsig`` the
    noise it is judged against and that of the evidence fitted, ``flat`` whether a flat
    top; returns whether a fit holds (a clipped core's flank fit: ``res`` is its own).
    ``ebuf``, ``escr`` (m,) are scratch."""
    cdef double z_own, z_avg
    cdef double num[3]
    cdef Py_ssize_t jj
    cdef bint ok = False, screened
    gsig[0] = pr.sigma_y
    flat[0] = False
    if sat:
        sig[0] = pmax(pr.sigma_y, _local_sigma(yi, mi, n, centre, core,
                                               CLIP_SIGMAS * 1.2 * pr.sigma_y))
        return fit_gaussian(yi + j0, use, m, j0, centre, s0, sig[0], pr.shape_error,
                            pr.s_max, res, ebuf, NULL)
    # one Gaussian's samples serve both screens and both fits' first steps
    screened = screen_sums(yi + j0, ya + j0, use, m, j0, centre, s0, escr, num)
    # the local noise is at least the image's: a seed that fails the screen against the
    # image's noise fails it against the local one too (IEEE division and product are
    # monotonic), and needs no local noise
    z_own = num[0] / (pr.sigma_y * num[2]) if screened else 0.0
    if z_own >= pr.screen_z or not pr.screen_z > 0.0:
        sig[0] = pmax(pr.sigma_y, _local_sigma(yi, mi, n, centre, core,
                                               CLIP_SIGMAS * 1.2 * pr.sigma_y))
        z_own = num[0] / (sig[0] * num[2]) if screened else 0.0
    z_avg = num[1] / (noise * num[2]) if screened else 0.0
    # the screens are the matched filter at the seed's row and width on each evidence; a
    # fit's significance is at most that at its own row and width, which the seed, half
    # a row off at most, shows at SEED_EFFICIENCY: a fit reaches at most its screen over
    # SEED_EFFICIENCY. The evidence of the larger screen is fitted first, the other only
    # where its bound beats the fit in hand (or that failed); the more significant fit
    # is kept. (A fit on the column's own evidence that can reach strong_z is made
    # first and, where it does, kept: the average blurs steps along the stripe.)
    if z_avg >= pr.screen_z and z_avg > z_own and z_own < pr.strong_z * pr.eff:
        if fit_gaussian(ya + j0, use, m, j0, centre, s0, noise, pr.shape_error, pr.s_max,
                        res, ebuf, escr):
            ok = True
            gsig[0] = pr.sigma_avg
        if z_own >= pr.screen_z and (not ok or z_own > pr.eff * res[3]) \
                and fit_gaussian(yi + j0, use, m, j0, centre, s0, sig[0], pr.shape_error,
                                 pr.s_max, res_avg, ebuf, escr) \
                and (not ok or res_avg[3] >= res[3]):
            for jj in range(6):
                res[jj] = res_avg[jj]
            gsig[0] = pr.sigma_y
            ok = True
        elif ok:
            sig[0] = noise
        return _flat_if_needed(yi, use, m, j0, centre, ok, pr, res, res_avg, sig, flat)
    if z_own >= pr.screen_z:
        ok = fit_gaussian(yi + j0, use, m, j0, centre, s0, sig[0], pr.shape_error,
                          pr.s_max, res, ebuf, escr)
    if (not ok or (res[3] < pr.strong_z and z_avg > pr.eff * res[3])) \
            and z_avg >= pr.screen_z:
        if fit_gaussian(ya + j0, use, m, j0, centre, s0, noise, pr.shape_error, pr.s_max,
                        res_avg, ebuf, escr) and (not ok or res_avg[3] > res[3]):
            for jj in range(6):
                res[jj] = res_avg[jj]
            sig[0] = noise
            gsig[0] = pr.sigma_avg
            ok = True
    return _flat_if_needed(yi, use, m, j0, centre, ok, pr, res, res_avg, sig, flat)


cdef inline bint _flat_if_needed(const float* yi, const unsigned char* use, Py_ssize_t m,
                                 Py_ssize_t j0, double centre, bint ok, const _Params* pr,
                                 double* res, double* scratch, const double* sig,
                                 bint* flat) noexcept nogil:
    """A held fit ``res`` whose reduced chi-square exceeds ``max_chi2`` tried as a flat
    top (``flat``, in place); returns ``ok``."""
    cdef Py_ssize_t jj
    if ok and res[5] > pr.max_chi2:
        if flat_top(yi + j0, use, m, j0, centre, used_min(yi + j0, use, m), sig[0],
                    scratch):
            for jj in range(6):
                res[jj] = scratch[jj]
            flat[0] = True
    return ok


cdef inline void _plateau(const unsigned char[:, :, ::1] img, const unsigned char[:, ::1] bg,
                          Py_ssize_t i, Py_ssize_t a, Py_ssize_t b, double centre,
                          double s0, double sig, bint ok, const _Params* pr, double* red,
                          double* res) noexcept nogil:
    """A clipped core ``[a, b)`` of column ``i`` centred on its plateau
    (:func:`plateau_centre`) unless its flank fit (``ok``, ``res``) agrees with it;
    its significance at least the clip's over the background."""
    cdef Py_ssize_t jc = <Py_ssize_t>centre
    cdef double pc = clip_plateau(img, bg, i, a, b, pr.sat_dn, red)
    # the flank fit refines the plateau's centre where it agrees with it
    if not ok or fabs(res[0] - pc) > 0.5 or res[2] < 0.5:
        res[0] = pc
        res[2] = s0  # (the run's half length, at most the widest stripe)
        res[4] = 0.25
        res[5] = 0.0
        res[1] = pr.sat_dn - bg[3 * i + 2, jc]
    else:
        # the flanks of a clipped core fit a width the clip and the bloom around it set,
        # not the stripe's: at most the plateau's
        res[2] = pmin(res[2], s0)
    res[3] = pmax(res[3] if ok else 0.0, (pr.sat_dn - bg[3 * i + 2, jc]) / sig)


cdef inline double _seed_width(const float* ya, const unsigned char* mi, Py_ssize_t n,
                               Py_ssize_t a, Py_ssize_t b, bint sat,
                               double s_max) noexcept nogil:
    """The width a seed's fit starts from: a clipped core's half length, else the
    averaged evidence's half-maximum width over 2.355; at most ``s_max``."""
    cdef double s0
    if sat:
        s0 = pmax(0.5 * (b - a), 0.8)
    else:
        s0 = pmax(half_max_sigma(ya, mi, n, a), SEED_MIN_SIGMA_PX)
    return pmin(s0, s_max)


cdef void _column(const unsigned char[:, :, ::1] img, const unsigned char[:, ::1] bg,
                  Py_ssize_t i, const float* yi, const float* ya, const unsigned char* ci,
                  const unsigned char* mi, Py_ssize_t n, const _Params* pr,
                  double* out, Py_ssize_t k_best, unsigned char* use, double* red,
                  double* ebuf, double* escr) noexcept nogil:
    """The candidates of column ``i`` into ``out`` (k_best, N_FIELDS), NaN-filled."""
    cdef double rank[N_SEEDS]
    cdef double noise[N_SEEDS]
    cdef double centre[N_SEEDS]
    cdef Py_ssize_t run_a[N_SEEDS]
    cdef Py_ssize_t run_b[N_SEEDS]
    cdef double res[6]
    cdef double res_avg[6]
    cdef double s0, sig = 0.0, gsig = 0.0
    cdef double* o
    cdef Py_ssize_t nk, p = 0, q, a, b, w_half, j0, j1, m, jj, r
    cdef bint sat, ok, flat = False, dup
    nk = _seeds(img, bg, i, ya, ci, mi, n, pr.seed_dn, pr.sigma_avg, pr.max_run, rank,
                centre, run_a, run_b, noise)
    for q in range(nk):
        if p == k_best:
            break
        a = run_a[q]
        b = run_b[q]
        sat = ci[a]
        s0 = _seed_width(ya, mi, n, a, b, sat, pr.s_max)
        # (b - a >= 1: floor division is C's)
        w_half = <Py_ssize_t>ceil(3.0 * s0 + 3.0) + (b - a) // 2
        j0 = imax(<Py_ssize_t>centre[q] - w_half, 0)
        j1 = imin(<Py_ssize_t>centre[q] + w_half + 2, n)
        m = j1 - j0
        for jj in range(m):
            use[jj] = mi[j0 + jj] and not ci[j0 + jj]
        ok = _fit_seed(yi, ya, mi, n, use, j0, m, centre[q], s0, 3.0 * s0 + 0.5 * (b - a),
                       noise[q], sat, pr, res, res_avg, ebuf, escr, &sig, &gsig, &flat)
        if sat:
            _plateau(img, bg, i, a, b, centre[q], s0, sig, ok, pr, red, res)
        elif not ok:
            continue
        # one fit per crossing: a second seed converging on a kept one is dropped
        dup = False
        for r in range(p):
            if fabs(out[r * N_FIELDS + F_POS] - res[0]) < 1.0:
                dup = True
        if dup:
            continue
        o = out + p * N_FIELDS
        o[F_POS] = res[0]
        o[F_AMP] = res[1]
        o[F_WIDTH] = res[2]
        o[F_Z] = res[3]
        o[F_SE_POS] = res[4]
        o[F_CHI2] = res[5]
        # 2: a white core (every channel at its clipping level at the run's middle row:
        # ``sat_g``, ``sat_b``), laser light
        # only by its red flanks (choose: never strong on its own)
        o[F_SAT] = 0.0 if not sat else (2.0 if img[i, (a + b - 1) // 2, 1] >= pr.sat_g
                                        and img[i, (a + b - 1) // 2, 0] >= pr.sat_b
                                        else 1.0)
        o[F_NOISE] = sig
        o[F_GNOISE] = gsig
        o[F_FLAT] = 1.0 if flat else 0.0
        _core_colour(img, bg, i, ci, n, o)
        p += 1


def column_candidates(const unsigned char[:, :, ::1] img, const unsigned char[:, ::1] bg,
                      const float[:, ::1] y, const float[:, ::1] y_avg, clipped, mask,
                      double sigma_y, double sigma_avg, double seed_dn, double strong_z,
                      double sat_dn, double s_max, double shape_error, double max_chi2,
                      double weak_z, double[:, :, ::1] out, Py_ssize_t col0=0,
                      Py_ssize_t col1=-1, double sat_g=-1.0, double sat_b=-1.0):
    """Fitted candidates of every column into ``out`` (W, K, N_FIELDS), NaN where none;
    with ``col0``, ``col1`` of the columns ``col0 .. col1 - 1`` only (``col1`` -1: to the
    last), the rest of ``out`` untouched: columns are independent, and bands of them may
    run on threads at once (the GIL is released).

    ``img`` (W, H, 3) uint8 BGR, ``bg`` its opening as (3 W, H) uint8, ``y`` and
    ``clipped`` (W, H) float32 and bool from :func:`~slitcli.laser.evidence.laser_evidence`,
    ``y_avg`` (W, H) float32 the evidence averaged along the stripe over five columns
    (weights 1, 4, 6, 4, 1), ``mask`` (W, H) bool the searched pixels, ``sigma_y`` and
    ``sigma_avg`` the image's noise of the two (DN), ``sat_dn`` the saturation level
    (red's; ``sat_g``, ``sat_b`` green's and blue's, -1: ``sat_dn``), ``s_max`` the
    widest stripe's sigma, px. Seeds come from the averaged evidence (at
    least ``seed_dn``); each is fitted on the column's own evidence and on the averaged
    one (noise about half, at the cost of resolution along the stripe), the more
    significant fit kept: the evidence whose screen (below) is the larger first, the
    other only where that screen over ``SEED_EFFICIENCY`` (what a fit can reach at most)
    beats the first fit's significance; a fit on the column's own evidence at least
    ``strong_z`` significant is kept without a fit on the averaged one. Fields:
    :mod:`slitcli.laser.profile`'s ``F_*`` (``F_T*`` the mean contrast of the core rows,
    ``F_K*`` the surface colour there, RGB). Where the Gaussian's reduced chi-square
    exceeds ``max_chi2`` a flat top is tried (``F_FLAT`` 1).

    An unclipped seed is fitted on either evidence only where a Gaussian of its own row
    and width is ``SEED_EFFICIENCY x weak_z`` significant there (``_linear_z``, against
    the fit's noise): a candidate less than ``weak_z`` significant is never chosen, and
    a seed half a row off the centre keeps ``SEED_EFFICIENCY`` of the significance; a
    seed that fails takes no candidate slot.
    """
    cdef const unsigned char[:, ::1] ci = np.ascontiguousarray(clipped).view(np.uint8)
    cdef const unsigned char[:, ::1] mi = np.ascontiguousarray(mask).view(np.uint8)
    cdef Py_ssize_t n_cols = y.shape[0], n = y.shape[1], k_best = out.shape[1], i
    cdef _Params pr
    if img.shape[0] != n_cols or img.shape[1] != n or img.shape[2] != 3 \
            or bg.shape[0] != 3 * n_cols or bg.shape[1] != n \
            or y_avg.shape[0] != n_cols or y_avg.shape[1] != n \
            or ci.shape[0] != n_cols or ci.shape[1] != n \
            or mi.shape[0] != n_cols or mi.shape[1] != n:
        raise ValueError("column_candidates: img (W, H, 3), bg (3 W, H), y, y_avg, clipped "
                         "and mask (W, H) disagree in shape")
    if out.shape[0] != n_cols or out.shape[2] != N_FIELDS:
        raise ValueError("column_candidates: out must be (W, K, N_FIELDS)")
    if col1 < 0:
        col1 = n_cols
    if not 0 <= col0 <= col1 <= n_cols:
        raise ValueError(f"column_candidates: columns {col0} .. {col1} are not inside "
                         f"0 .. {n_cols}")
    np.asarray(out)[col0:col1] = np.nan
    if n == 0:
        return
    # a clipped core spans more than the stripe's width: 2 s sqrt(2 ln(peak / clip))
    pr.max_run = <Py_ssize_t>ceil(5.0 * s_max)
    pr.screen_z = SEED_EFFICIENCY * weak_z
    pr.eff = SEED_EFFICIENCY
    pr.sigma_y = sigma_y
    pr.sigma_avg = sigma_avg
    pr.seed_dn = seed_dn
    pr.strong_z = strong_z
    pr.sat_dn = sat_dn
    pr.sat_g = sat_dn if sat_g < 0 else sat_g
    pr.sat_b = sat_dn if sat_b < 0 else sat_b
    pr.s_max = s_max
    pr.shape_error = shape_error
    pr.max_chi2 = max_chi2
    cdef unsigned char[::1] use = np.empty(n, np.uint8)
    cdef double[::1] red = np.empty(n)
    cdef double[::1] ebuf = np.empty(n)
    cdef double[::1] escr = np.empty(n)
    with nogil:
        for i in range(col0, col1):
            _column(img, bg, i, &y[i, 0], &y_avg[i, 0], &ci[i, 0], &mi[i, 0], n, &pr,
                    &out[i, 0, 0], k_best, &use[0], &red[0], &ebuf[0], &escr[0])


def sheet_width_px(const double[:, :, ::1] cand, const double[::1, :] px_per_m,
                   double sheet_sigma_mm, double[:, ::1] sheet_px):
    """The sheet's sigma, ``sheet_sigma_mm``, in pixels at each candidate's row
    (``cand[..., F_POS]``, (W, K), image rows) into ``sheet_px`` (W, K) float64;
    ``px_per_m`` (H, W) float64, column-major: image rows per metre of height where each
    pixel's ray meets the laser plane. (A gather per candidate: numpy's fancy indexing
    over a float64 copy of ``px_per_m`` cost ~0.2 ms a frame.)"""
    cdef Py_ssize_t n_rows = px_per_m.shape[0], i, q, r
    cdef double pos
    if sheet_px.shape[0] != cand.shape[0] or sheet_px.shape[1] != cand.shape[1] \
            or px_per_m.shape[1] < cand.shape[0]:
        raise ValueError("sheet_width_px: cand (W, K, N_FIELDS), px_per_m (H, W) and "
                         "sheet_px (W, K) disagree in shape")
    with nogil:
        for i in range(cand.shape[0]):
            for q in range(cand.shape[1]):
                pos = cand[i, q, F_POS]
                r = 0 if isnan(pos) else <Py_ssize_t>pmin(pmax(rint(pos), 0.0), n_rows - 1)
                sheet_px[i, q] = px_per_m[r, i] * sheet_sigma_mm * 1e-3


def evidence_live(mask, const unsigned char[:, :, ::1] img, clipped, out):
    """Pixels (W, H) whose evidence shows the noise into ``out`` (W, H) bool: searched
    (``mask`` (W, H) bool), red inside its range (above 0 in ``img`` (W, H, 3) uint8
    BGR; not ``clipped`` (W, H) bool); returns whether any."""
    cdef const unsigned char[:, ::1] mi = np.ascontiguousarray(mask).view(np.uint8)
    cdef const unsigned char[:, ::1] ci = np.ascontiguousarray(clipped).view(np.uint8)
    cdef unsigned char[:, ::1] res = out.view(np.uint8)
    cdef Py_ssize_t i, j
    if img.shape[0] != mi.shape[0] or img.shape[1] != mi.shape[1] \
            or ci.shape[0] != mi.shape[0] or ci.shape[1] != mi.shape[1] \
            or res.shape[0] != mi.shape[0] or res.shape[1] != mi.shape[1]:
        raise ValueError("evidence_live: mask, img, clipped and out disagree in shape")
    cdef unsigned char seen = 0
    with nogil:
        for i in range(mi.shape[0]):
            # (bitwise, without branches: the loop vectorises)
            for j in range(mi.shape[1]):
                res[i, j] = (mi[i, j] != 0) & (img[i, j, 2] > 0) & (ci[i, j] == 0)
                seen |= res[i, j]
    return seen != 0

