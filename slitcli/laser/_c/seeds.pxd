"""Step 3 of the stripe model, compiled: a column's seeds (:mod:`slitcli.laser.candidates`'
notes), inlined into ``candidates.pyx``. Arithmetic in the numba kernels' order and types
(float32 evidence, float64 sums, Python ``min``/``max``).
"""

from libc.math cimport fabs

from slitcli.laser._c.profile cimport imax, imin, pmax, pmin

# (slitcli.laser.candidates' constants; tests/test_laser_kernels.py checks that they agree)
cdef enum:
    NMS_HALF = 2
    FLANK_ROWS = 2
    NOISE_HALF = 24
    N_SEEDS = 5

cdef extern from *:
    """
    #include <math.h>
    #define SLITCLI_CLIP_SIGMAS 5.0
    #define SLITCLI_MEAN_TO_SIGMA (sqrt(3.141592653589793 / 2.0) / sqrt(1.5))
    #define SLITCLI_FLANK_RED_SHARE 0.25
    """
    const double CLIP_SIGMAS "SLITCLI_CLIP_SIGMAS"
    const double MEAN_TO_SIGMA "SLITCLI_MEAN_TO_SIGMA"
    # the least red excess, as a share of the red contrast, of a white core's far
    # flanks (_red_flanks)
    const double FLANK_RED_SHARE "SLITCLI_FLANK_RED_SHARE"


cdef inline double _local_sigma(const float* yi, const unsigned char* mi, Py_ssize_t n,
                                double c, double core, double clip) noexcept nogil:
    """Noise of the evidence ``yi`` (n,) within ``NOISE_HALF + core`` rows of ``c``, the
    rows within ``core`` left out: the mean absolute lag-2 residual (each clipped at
    ``clip``, so that an edge or a second stripe counts as no more than that), scaled to a
    Gaussian's sigma."""
    cdef Py_ssize_t lo = imax(<Py_ssize_t>(c - core - NOISE_HALF), 2)
    cdef Py_ssize_t hi = imin(<Py_ssize_t>(c + core + NOISE_HALF) + 1, n - 2)
    cdef Py_ssize_t j, m = 0
    cdef double acc = 0.0
    for j in range(lo, hi):
        if fabs(j - c) <= core + 2.0 or not (mi[j - 2] and mi[j + 2]):
            continue
        # (float32 sum of the two neighbours, as numba's)
        acc += pmin(fabs(yi[j] - 0.5 * (yi[j - 2] + yi[j + 2])), clip)
        m += 1
    if m < 8:
        return 0.0
    return MEAN_TO_SIGMA * acc / m


cdef inline double _red_excess(const unsigned char[:, :, ::1] img,
                               const unsigned char[:, ::1] bg, Py_ssize_t i,
                               Py_ssize_t j, double share) noexcept nogil:
    """Red excess ``t_r - max(t_g, t_b)`` of the contrast of pixel ``j`` of column ``i``;
    with ``share`` > 0, -1e300 where it is below ``share`` of ``t_r`` (the light is not
    red enough); ``share`` 0 takes any excess."""
    cdef double tr = <double>img[i, j, 2] - bg[3 * i + 2, j]
    cdef double tg = <double>img[i, j, 1] - bg[3 * i + 1, j]
    cdef double tb = <double>img[i, j, 0] - bg[3 * i, j]
    cdef double e = tr - pmax(tg, tb)
    return e if share <= 0.0 or e >= share * tr else -1e300


cdef inline bint _red_flanks(const unsigned char[:, :, ::1] img,
                             const unsigned char[:, ::1] bg, Py_ssize_t i, Py_ssize_t a,
                             Py_ssize_t b, double seed_dn) noexcept nogil:
    """Whether the clipped run ``[a, b)`` of column ``i`` has red light on both flanks:
    the largest red excess beyond each end (an image border counts as ``seed_dn``)
    positive on both sides and ``2 seed_dn`` together (a laser core's flanks are both
    red; a white highlight's fringe is white on both sides). Within ``FLANK_ROWS`` rows
    any red excess counts; up to the run's length farther only light whose red excess
    is at least ``FLANK_RED_SHARE`` of its red contrast: a laser bright enough to clip
    green and blue too (a white core) leaves them clipped or near it for a few rows
    beyond the red's clip, about as far as the light stays above the clip level, before
    its red tails show; a white highlight's glow on a warm surface is a little red too,
    but only by the surface's tint."""
    cdef Py_ssize_t n = img.shape[1], d
    cdef double up = seed_dn if a == 0 else -1e300
    cdef double dn = seed_dn if b == n else -1e300
    cdef double share
    for d in range(1, FLANK_ROWS + (b - a) + 1):
        share = 0.0 if d <= FLANK_ROWS else FLANK_RED_SHARE
        if a - d >= 0:
            up = pmax(up, _red_excess(img, bg, i, a - d, share))
        if b + d - 1 < n:
            dn = pmax(dn, _red_excess(img, bg, i, b + d - 1, share))
    return up > 0.0 and dn > 0.0 and up + dn >= 2.0 * seed_dn


cdef inline Py_ssize_t _seeds(const unsigned char[:, :, ::1] img,
                              const unsigned char[:, ::1] bg, Py_ssize_t i, const float* yi,
                              const unsigned char* ci, const unsigned char* mi, Py_ssize_t n,
                              double seed_dn, double sigma_y, Py_ssize_t max_run,
                              double* rank, double* centre, Py_ssize_t* run_a,
                              Py_ssize_t* run_b, double* noise) noexcept nogil:
    """The column's seeds (at most ``N_SEEDS``), most significant first (module notes:
    against the local noise, which ``noise`` gets); returns how many."""
    cdef double clip = CLIP_SIGMAS * 1.2 * sigma_y  # (1.2 ~ sqrt(1.5): the residual's)
    cdef Py_ssize_t nk = 0, j = 0, a, b, q, lo, hi, slot
    cdef double r, c, sig
    cdef bint top
    while j < n:
        if not mi[j]:
            j += 1
            continue
        if ci[j]:
            a = j
            while j < n and ci[j] and mi[j]:
                j += 1
            b = j
            if b - a > max_run:
                continue
            if not _red_flanks(img, bg, i, a, b, seed_dn):
                continue
            c = 0.5 * (a + b - 1)
            sig = pmax(sigma_y, _local_sigma(yi, mi, n, c, 1.5 * (b - a) + 1.0, clip))
            r = 1e9 + (b - a)  # clipped cores rank first
        else:
            if yi[j] < seed_dn:
                j += 1
                continue
            top = True
            for q in range(imax(j - NMS_HALF, 0), imin(j + NMS_HALF + 1, n)):
                if q != j and (yi[q] > yi[j] or (yi[q] == yi[j] and q < j) or ci[q]):
                    top = False
            if not top:
                j += 1
                continue
            # with every slot taken, a maximum whose rank against the image's noise (at
            # most the local noise: IEEE division is monotonic) does not beat the last
            # one's cannot enter: its local noise is not needed
            if nk == N_SEEDS and yi[j] >= 0.0 and yi[j] / sigma_y <= rank[N_SEEDS - 1]:
                j += NMS_HALF + 1
                continue
            a = j
            b = j + 1
            c = <double>j
            # the core's extent: rows above half the peak
            lo = j
            while lo > 0 and yi[lo - 1] >= 0.5 * yi[j] and j - lo < max_run:
                lo -= 1
            hi = j
            while hi < n - 1 and yi[hi + 1] >= 0.5 * yi[j] and hi - j < max_run:
                hi += 1
            sig = pmax(sigma_y, _local_sigma(yi, mi, n, c, 1.5 * (hi - lo + 1) + 1.0, clip))
            r = yi[j] / sig
            j += NMS_HALF + 1
        if nk < N_SEEDS:
            slot = nk
            nk += 1
        elif r > rank[N_SEEDS - 1]:
            slot = N_SEEDS - 1
        else:
            continue
        while slot > 0 and rank[slot - 1] < r:
            rank[slot] = rank[slot - 1]
            noise[slot] = noise[slot - 1]
            centre[slot] = centre[slot - 1]
            run_a[slot] = run_a[slot - 1]
            run_b[slot] = run_b[slot - 1]
            slot -= 1
        rank[slot] = r
        noise[slot] = sig
        centre[slot] = c
        run_a[slot] = a
        run_b[slot] = b
    return nk
