"""The per-pixel loops of the Eq. 10 matcher (slitcli/stereo/_c/nssd.pyx) over one
pixel's disparities or one row's columns, and the float bit casts they use.

Each loop is a function of its own over ``__restrict__`` pointers: the arrays it writes
never overlap the ones it reads, so gcc vectorises it without run-time overlap checks.
Every operation is the IEEE float32 (or float64) operation written, in that order.
"""

from libc.math cimport sqrtf
from libc.stdint cimport int32_t, uint32_t
from libc.string cimport memcpy

cdef extern from *:
    """
    /* An energy-free window (all zeros after prefiltering) makes Eq. 10 0/0; its
       inverse norm is set to this so every candidate that touches it costs more than
       any real one. */
    #define NSSD_BIG_INV 1e30f
    /* Added to the SSD so that 0 * BIG_INV**2 (two empty windows) becomes +inf, not 0. */
    #define NSSD_SSD_EPS 1e-3f
    #define NSSD_INF_BITS ((int32_t)0x7F800000)
    #define NSSD_KEY_MAX ((int32_t)0x7FFFFFFF)
    """
    const float BIG_INV "NSSD_BIG_INV"
    const float SSD_EPS "NSSD_SSD_EPS"
    const int32_t INF_BITS "NSSD_INF_BITS"
    const int32_t KEY_MAX "NSSD_KEY_MAX"
    const float INF "INFINITY"
    const float NAN "NAN"
    # pointers that alias no other pointer argument of the function they are passed to
    ctypedef float *fp "float *__restrict__"
    ctypedef const float *cfp "const float *__restrict__"
    ctypedef int32_t *ip "int32_t *__restrict__"
    ctypedef const int32_t *cip "const int32_t *__restrict__"


cdef inline int32_t bits(float x) noexcept nogil:
    """The bit pattern of a float32 (non-negative floats order like it)."""
    cdef int32_t k = 0
    memcpy(&k, &x, 4)
    return k


cdef inline float from_bits(int32_t k) noexcept nogil:
    """The float32 whose bit pattern is ``k`` (inverse of :func:`bits`)."""
    cdef float x = 0
    memcpy(&x, &k, 4)
    return x


cdef inline float fmax_(float a, float b) noexcept nogil:
    """Python's ``max(a, b)`` (``b`` only if it is greater)."""
    return b if b > a else a


cdef inline void _slide_energy(fp v, cfp add, cfp sub, float wa, float ws,
                               Py_ssize_t n) noexcept nogil:
    """``v += wa add^2 - ws sub^2`` over n columns (vertical window energies)."""
    cdef Py_ssize_t c
    for c in range(n):
        v[c] += wa * (add[c] * add[c]) - ws * (sub[c] * sub[c])


cdef inline void _prefix(const float *v, double *prefix, Py_ssize_t n) noexcept nogil:
    """Running sums of the column energies ``v`` (float64, exact), so the clipped
    windows of the masked Eq. 10 at the borders sum in O(1)."""
    cdef double acc = 0.0
    cdef Py_ssize_t c
    prefix[0] = 0.0
    for c in range(n):
        acc += v[c]
        prefix[c + 1] = acc


cdef inline void _window_energy_row(const double *prefix, fp e_out, fp inv_out,
                                    Py_ssize_t m, Py_ssize_t width) noexcept nogil:
    """Clipped window energies of one row from the column prefix sums, and their
    inverse roots (IEEE-exact)."""
    cdef Py_ssize_t a = min(m, width)
    cdef Py_ssize_t b = max(width - m, a)
    cdef Py_ssize_t x
    cdef const double *hi = prefix + 2 * m + 1
    cdef float e
    for x in range(a):
        e_out[x] = <float>(prefix[min(x + m, width - 1) + 1] - prefix[0])
    for x in range(a, b):
        e_out[x] = <float>(hi[x - m] - prefix[x - m])
    for x in range(b, width):
        e_out[x] = <float>(prefix[width] - prefix[max(x - m, 0)])
    for x in range(width):
        e = e_out[x]
        inv_out[x] = (<float>1.0 / sqrtf(e)) if e >= 0.5 else BIG_INV


cdef inline float _masked_norm(float sl, float sr) noexcept nogil:
    """Eq. 10's inverse norm over a clipped window pair (as in :func:`_border_x`),
    branch-free."""
    cdef bint low_l = sl < <float>0.5
    cdef bint low_r = sr < <float>0.5
    # bitwise & and | (Cython's `and`/`or` branch): the loops over it vectorise
    cdef bint low = low_l | low_r
    cdef float inv = <float>1.0 / sqrtf(fmax_(sl, sr) if low else sl * sr)
    return BIG_INV * (BIG_INV if low_l & low_r else inv) if low else inv


cdef inline void _diagonal_norms(fp g, const double *cly_hi, const double *cly_lo,
                                 float sr, Py_ssize_t n) noexcept nogil:
    """Inverse norms of the windows that the right image's left edge clips, for one
    offset k = x - d < m and n disparities from dmin: the left window is columns
    d .. d + k + m (``cly_hi`` = prefix from column dmin + k + m + 1, ``cly_lo`` from
    dmin), the right one columns 0 .. k + m (energy ``sr``)."""
    cdef Py_ssize_t i
    for i in range(n):
        g[i] = _masked_norm(<float>(cly_hi[i] - cly_lo[i]), sr)


cdef inline void _right_edge_costs(ip cb, cfp ssum, float sl, const double *cry_hi,
                                   const double *cry_lo, Py_ssize_t n) noexcept nogil:
    """Eq. 10 bits of a pixel x > W-1-m whose left window (energy ``sl``) the image's
    right edge clips, for n disparities d from dmin (all <= x - m): the right window
    is columns x-m-d .. W-1-d (``cry_hi[-i]`` = prefix at W - d, ``cry_lo[-i]`` at
    x - m - d)."""
    cdef Py_ssize_t i
    cdef float g
    for i in range(n):
        g = _masked_norm(sl, <float>(cry_hi[-i] - cry_lo[-i]))
        cb[i] = bits((ssum[i] + SSD_EPS) * g)


# ---- per-pixel loops over the disparities


cdef inline void _column_sums(fp col, cfp ra_r, cfp rs_r, float a, float b, float wa,
                              float ws, Py_ssize_t n) noexcept nogil:
    """Slide one column's vertical window sums of n disparities down one row:
    ``col += wa (a - ra_r)^2 - ws (b - rs_r)^2`` (``ra_r``, ``rs_r``: the mirrored
    right rows entering and leaving, from the column's first disparity; weights 0 or 1
    so every sum stays an exact integer)."""
    cdef Py_ssize_t i
    cdef float t, u
    for i in range(n):
        t = a - ra_r[i]
        u = b - rs_r[i]
        col[i] += wa * (t * t) - ws * (u * u)


cdef inline void _slide_sums(fp ssum, cfp col_in, cfp col_out,
                             Py_ssize_t n) noexcept nogil:
    """``ssum += col_in - col_out``: the window moves one column along x."""
    cdef Py_ssize_t i
    for i in range(n):
        ssum[i] += col_in[i] - col_out[i]


cdef inline int32_t _fast_px(fp col, cfp col_out, fp ssum, ip cb, cfp ra_r, cfp rs_r,
                             ip rkey, cfp irr, float a, float b, float wa, float ws,
                             float f, int32_t key_mask, Py_ssize_t n) noexcept nogil:
    """A pixel whose window and disparities all lie inside both images, one pass per
    disparity for each step: slide the entering column ``col`` down one row, slide the
    window sums along x, take Eq. 10 (bits into ``cb``), and lower the right pixels'
    keys ``rkey`` (``irr``: their inverse window norms). Returns the pixel's best
    packed (cost | index) key."""
    cdef Py_ssize_t i
    cdef int32_t j      # a 32-bit index: its vector needs no narrowing from 64 bits
    cdef float t, u, c
    cdef int32_t k, key, rk
    cdef int32_t lk = KEY_MAX
    for i in range(n):
        t = a - ra_r[i]
        u = b - rs_r[i]
        c = col[i] + (wa * (t * t) - ws * (u * u))
        col[i] = c
        ssum[i] += c - col_out[i]
    for j in range(<int32_t>n):
        k = bits((ssum[j] + SSD_EPS) * f * irr[j])
        cb[j] = k
        key = (k & key_mask) | j
        lk = key if key < lk else lk
        rk = rkey[j]
        rkey[j] = key if key < rk else rk
    return lk


cdef inline void _interior_costs(ip cb, cfp ssum, cfp irr, float f,
                                 Py_ssize_t n) noexcept nogil:
    """Eq. 10 bits of n disparities whose windows lie inside both images."""
    cdef Py_ssize_t i
    for i in range(n):
        cb[i] = bits((ssum[i] + SSD_EPS) * f * irr[i])


cdef inline int32_t _keys(cip cb, ip rkey, Py_ssize_t i0, int32_t key_mask,
                          Py_ssize_t n) noexcept nogil:
    """Best packed (cost | index) key of the n disparities from index i0, lowering
    the right pixels' keys."""
    cdef int32_t k      # 32-bit: see _fast_px
    cdef int32_t key, rk
    cdef int32_t lk = KEY_MAX
    for k in range(<int32_t>n):
        key = (cb[k] & key_mask) | (<int32_t>i0 + k)
        lk = key if key < lk else lk
        rk = rkey[k]
        rkey[k] = key if key < rk else rk
    return lk


cdef inline int32_t _second_bits(cip cb, Py_ssize_t lo, Py_ssize_t hi,
                                 int32_t bi) noexcept nogil:
    """Bits of the best cost of indices lo .. hi-1 more than 1 px from the winner ``bi``
    (non-negative floats order like their bits); the winner +-1 masked by one unsigned
    32-bit compare of the index."""
    cdef int32_t sb = INF_BITS
    cdef int32_t s32 = bi - 1
    cdef int32_t v
    cdef int32_t i      # 32-bit: see _fast_px
    for i in range(<int32_t>lo, <int32_t>hi):
        v = cb[i]
        v = INF_BITS if <uint32_t>(i - s32) <= 2 else v
        sb = v if v < sb else sb
    return sb
