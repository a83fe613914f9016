"""The per-pixel loops of semi-global aggregation (slitcli/stereo/_c/sgm.pyx), each over
one pixel's disparities.

Each loop is a function of its own over ``__restrict__`` pointers (what it writes never
overlaps what it reads), so gcc vectorises it, 16 int16 or 8 float32 disparities per
AVX2 operation, for any disparity count (a scalar tail takes the rest). Integer
operations wrap in 16 bits where the casts say so; float operations are the IEEE
float32 operations written, in that order, without contraction, so the costs and
sums are the same bits whatever the vector width.
"""

from libc.stdint cimport int16_t, int32_t, uint16_t

cdef extern from *:
    """
    /* above any path cost (< c_max scale + P2 <= 2 x 256 + 8 x 256) */
    #define SGM_SENTINEL ((int16_t)0x3FFF)
    #define SGM_KEY_SHIFT 9
    #define SGM_NO_KEY ((int32_t)0x7FFFFFFF)
    """
    const int16_t SENTINEL "SGM_SENTINEL"
    const int KEY_SHIFT "SGM_KEY_SHIFT"
    const int32_t NO_KEY "SGM_NO_KEY"
    ctypedef float *fp "float *__restrict__"
    ctypedef const float *cfp "const float *__restrict__"
    ctypedef int16_t *sp "int16_t *__restrict__"
    ctypedef const int16_t *csp "const int16_t *__restrict__"
    ctypedef const uint16_t *cup "const uint16_t *__restrict__"
    ctypedef uint16_t *up "uint16_t *__restrict__"
    ctypedef int32_t *ip "int32_t *__restrict__"
    ctypedef const int32_t *cip "const int32_t *__restrict__"

cdef extern from *:
    """
    /* The winner step's keys (s_a + s_b) << 9 | i of one pixel's n disparities into
       keys (SGM_NO_KEY where the cost is top: no partner or no energy): one minimum
       gives the winner and, among equal sums, the smallest disparity. Returns the best
       key. In C with a mask for the choice: gcc (12) leaves the loop scalar with a
       conditional expression or with Cython's branches. */
    static inline int32_t sgm_pixel_keys(const uint16_t *restrict sa,
                                         const uint16_t *restrict sb,
                                         const uint16_t *restrict cost,
                                         int32_t *restrict keys, uint16_t top,
                                         Py_ssize_t n) {
        int32_t best = SGM_NO_KEY;
        for (int32_t i = 0; i < (int32_t)n; i++) {
            int32_t k = (((int32_t)sa[i] + (int32_t)sb[i]) << SGM_KEY_SHIFT) | i;
            int32_t m = -(int32_t)(cost[i] < top);
            k = (k & m) | (SGM_NO_KEY & ~m);
            keys[i] = k;
            best = k < best ? k : best;
        }
        return best;
    }
    /* The smallest key outside indices lo..hi. */
    static inline int32_t sgm_second_key(const int32_t *restrict keys, int32_t lo,
                                         int32_t hi, Py_ssize_t n) {
        int32_t second = SGM_NO_KEY;
        for (int32_t i = 0; i < (int32_t)n; i++) {
            int32_t m = -(int32_t)((i < lo) | (i > hi));
            int32_t k = (keys[i] & m) | (SGM_NO_KEY & ~m);
            second = k < second ? k : second;
        }
        return second;
    }
    """
    int32_t pixel_keys "sgm_pixel_keys" (const uint16_t *sa, const uint16_t *sb,
                                         const uint16_t *cost, int32_t *keys, uint16_t top,
                                         Py_ssize_t n) noexcept nogil
    int32_t second_key "sgm_second_key" (const int32_t *keys, int32_t lo, int32_t hi,
                                         Py_ssize_t n) noexcept nogil


cdef inline void column_slide(fp col, cfp ra, cfp rs, float a, float b,
                              Py_ssize_t n) noexcept nogil:
    """The vertical window sums of the cross term of one column, one row down:
    ``col += a ra - b rs`` (``a``, ``b``: the left pixels entering and leaving, 0 where
    the row is outside the image; ``ra``, ``rs``: the mirrored right rows from the
    column's first disparity)."""
    cdef Py_ssize_t i
    for i in range(n):
        col[i] += a * ra[i] - b * rs[i]


cdef inline void pixel_costs(fp hs, cfp col_in, cfp col_out, float wa, float ws, float e1,
                             float r1, cfp err, cfp irr, uint16_t top, float scale,
                             float c_max, up out, Py_ssize_t n) noexcept nogil:
    """Slide the window's cross sums ``hs`` one column (``wa``, ``ws``: 0 or 1) and write
    the quantised Eq. 10 costs ``round(min((E_l + E_r - 2 X) / sqrt(E_l E_r), c_max)
    scale)``; ``irr`` = 0 (a partner outside the image or a window without energy) or
    ``r1`` = 0 gives ``top``."""
    cdef Py_ssize_t i
    cdef float x, w, c, q
    for i in range(n):
        x = hs[i] + wa * col_in[i] - ws * col_out[i]
        hs[i] = x
        w = r1 * irr[i]
        c = (e1 + err[i] - <float>2.0 * x) * w
        c = c if c > <float>0.0 else <float>0.0
        c = c if c < c_max else c_max
        q = c * scale + <float>0.5
        out[i] = <uint16_t><int32_t>q if w > <float>0.0 else top


cdef inline int32_t path_pair(csp c, sp o, csp ap, sp ac, int32_t am, csp bp, sp bc,
                              int32_t bm, int32_t p1, int32_t p2a, int32_t p2b, bint acc,
                              Py_ssize_t n, int32_t *bmin) noexcept nogil:
    """Paths a and b at one pixel: ``L = C + min(prev, prev -+ 1 + P1, min prev + P2) -
    min prev`` (Hirschmueller) into ``ac``, ``bc`` (from index 1; ``ap``, ``bp``: the
    previous rows with a sentinel at both ends), their sum into ``o`` (added to it with
    ``acc``). int16 throughout (every value stays below SENTINEL + P2 < 2^15). Returns
    min L of path a, min L of path b into ``bmin``."""
    cdef int16_t q1 = <int16_t>p1
    cdef int16_t ha = <int16_t>(am + p2a), pa = <int16_t>am
    cdef int16_t hb = <int16_t>(bm + p2b), pb = <int16_t>bm
    cdef int16_t ma = 0x7FFF, mb = 0x7FFF, va, vb, t, la, lb
    cdef Py_ssize_t i
    for i in range(n):
        va = ap[i + 1]
        t = <int16_t>(ap[i] + q1)
        va = va if va < t else t
        t = <int16_t>(ap[i + 2] + q1)
        va = va if va < t else t
        va = va if va < ha else ha
        la = <int16_t>(<int16_t>(c[i] + va) - pa)
        vb = bp[i + 1]
        t = <int16_t>(bp[i] + q1)
        vb = vb if vb < t else t
        t = <int16_t>(bp[i + 2] + q1)
        vb = vb if vb < t else t
        vb = vb if vb < hb else hb
        lb = <int16_t>(<int16_t>(c[i] + vb) - pb)
        ac[i + 1] = la
        bc[i + 1] = lb
        if acc:
            o[i] = <int16_t>(o[i] + <int16_t>(la + lb))
        else:
            o[i] = <int16_t>(la + lb)
        ma = ma if ma < la else la
        mb = mb if mb < lb else lb
    bmin[0] = mb
    return ma


cdef inline void lower_keys(ip rkey, cip keys, Py_ssize_t n) noexcept nogil:
    """``rkey = min(rkey, keys)``: the right view's best keys."""
    cdef Py_ssize_t i
    cdef int32_t a, b
    for i in range(n):
        a = rkey[i]
        b = keys[i]
        rkey[i] = a if a < b else b


