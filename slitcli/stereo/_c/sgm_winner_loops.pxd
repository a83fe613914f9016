"""The winner step's per-pixel loops of semi-global aggregation (sgm_winner.pxd), each
over one pixel's disparities: the int32 keys ``(s_a + s_b) << 9 | i`` (any D, any
build) and, with AVX2 and D a multiple of 16, the uint16 sums in 16 lanes
(``winners16_row``), whose minimum and first index are the smallest key's; the right
view's keys lowered from either. Split from sgm_loops.pxd (the cost and sweep loops),
whose constants (``KEY_SHIFT``, ``NO_KEY``) and types these use; the same operations.
"""

from libc.stdint cimport int32_t, uint8_t, uint16_t

# the constants and restrict types of sgm_loops.pxd (its C code comes first)
from slitcli.stereo._c.sgm_loops cimport KEY_SHIFT, NO_KEY, cip, ip

cdef extern from *:
    """
    #include <math.h>
    #ifdef __AVX2__
    #include <immintrin.h>
    #endif
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
    #ifdef __AVX2__
    #define SGM_HAVE_LANES16 1
    /* The winner step in uint16 lanes (n a multiple of 16). s = sa + sb of one pixel's
       n disparities into s16, SGM_NO_SUM where cost >= top (no candidate); the sums
       the sweeps make stay far below it (8 paths: <= 8 (top + P2) <= 20488), and a sum
       that reaches it (saturating add) sets *ovf: the caller then takes the int32 keys
       for the row. Returns the smallest sum (SGM_NO_SUM: no candidate) and its first
       index into *bi: the same winner as the smallest key (sum << 9 | i), ties to the
       smallest index, at 16 lanes instead of 8 and without the key array. */
    #define SGM_NO_SUM 0xFFFF
    static inline uint16_t sgm_hmin_u16(__m256i v) {
        __m128i m = _mm_min_epu16(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
        return (uint16_t)_mm_extract_epi16(_mm_minpos_epu16(m), 0);
    }
    static inline uint16_t sgm_pixel_sums16(const uint16_t *restrict sa,
                                            const uint16_t *restrict sb,
                                            const uint16_t *restrict cost,
                                            uint16_t *restrict s16, uint16_t top,
                                            Py_ssize_t n, int32_t *bi, int *ovf) {
        __m256i none = _mm256_set1_epi16(-1), tv = _mm256_set1_epi16((short)top);
        __m256i vmin = none, vo = _mm256_setzero_si256();
        for (Py_ssize_t i = 0; i < n; i += 16) {
            __m256i s = _mm256_adds_epu16(_mm256_loadu_si256((const __m256i *)(sa + i)),
                                          _mm256_loadu_si256((const __m256i *)(sb + i)));
            __m256i c = _mm256_loadu_si256((const __m256i *)(cost + i));
            vo = _mm256_or_si256(vo, _mm256_cmpeq_epi16(s, none));
            /* c >= top (unsigned): max(c, top) == c */
            s = _mm256_or_si256(s, _mm256_cmpeq_epi16(_mm256_max_epu16(c, tv), c));
            _mm256_storeu_si256((__m256i *)(s16 + i), s);
            vmin = _mm256_min_epu16(vmin, s);
        }
        *ovf |= !_mm256_testz_si256(vo, vo);
        uint16_t m = sgm_hmin_u16(vmin);
        /* the first index of m, without a branch on where it lies (which block holds
           the minimum is random: a mispredicted jump per pixel); from the last block
           down, each block holding m takes the index over */
        __m256i mv = _mm256_set1_epi16((short)m);
        int32_t first = 0;
        for (Py_ssize_t i = n - 16; i >= 0; i -= 16) {
            uint32_t hit = (uint32_t)_mm256_movemask_epi8(_mm256_cmpeq_epi16(
                _mm256_loadu_si256((const __m256i *)(s16 + i)), mv));
            int32_t at = (int32_t)i + (int32_t)(__builtin_ctz(hit | 0x80000000u) >> 1);
            first = hit ? at : first;
        }
        *bi = first;
        return m;
    }
    /* The smallest sum outside indices bi-1..bi+1 (SGM_NO_SUM: none), as the smallest
       key there (sgm_second_key) gives it. */
    static inline uint16_t sgm_second16(const uint16_t *restrict s16, int32_t bi,
                                        Py_ssize_t n) {
        __m256i idx = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        __m256i lo = _mm256_set1_epi16((short)(bi - 1)), two = _mm256_set1_epi16(2);
        __m256i step = _mm256_set1_epi16(16), vmin = _mm256_set1_epi16(-1);
        for (Py_ssize_t i = 0; i < n; i += 16) {
            /* i - (bi - 1) in 0..2 (unsigned, wrapping): inside the excluded three */
            __m256i d = _mm256_sub_epi16(idx, lo);
            __m256i in = _mm256_cmpeq_epi16(_mm256_min_epu16(d, two), d);
            vmin = _mm256_min_epu16(vmin, _mm256_or_si256(
                _mm256_loadu_si256((const __m256i *)(s16 + i)), in));
            idx = _mm256_add_epi16(idx, step);
        }
        return sgm_hmin_u16(vmin);
    }
    /* The per-pixel part of sgm.pyx's _winners16 over a row, in C (pointers and
       parameters in registers): the winner, the subpixel parabola through the sums,
       the winner's cost / scale and the texture and uniqueness codes (uniqueness + 100:
       it overrides left-right), the same operations as _winners32. Returns 0 where a
       sum reached SGM_NO_SUM (the caller then takes the int32 keys). */
    static inline int sgm_winners16_row(const uint16_t *sa, const uint16_t *sb,
                                        const uint16_t *c, const float *el,
                                        const float *count, Py_ssize_t width, Py_ssize_t n,
                                        Py_ssize_t dmin, int subpixel, float uniq,
                                        float energy_min, uint16_t top, float scale,
                                        uint16_t *restrict s16, int32_t *restrict best_i,
                                        float *restrict disp, float *restrict mcost,
                                        uint8_t *restrict reason, int r_valid, int r_none,
                                        int r_texture, int r_uniq) {
        int ovf = 0, ex;
        /* a power-of-two scale: c / scale is c times its exact inverse, bit for bit
           (no rounding in either), without a division per pixel */
        int pow2 = frexpf(scale, &ex) == 0.5f;
        float inv = pow2 ? 1.0f / scale : 0.0f;
        for (Py_ssize_t x = 0; x < width; x++) {
            Py_ssize_t base = x * n;
            int32_t bi = 0;
            uint16_t best = sgm_pixel_sums16(sa + base, sb + base, c + base, s16 + base, top,
                                             n, &bi, &ovf);
            if (best == SGM_NO_SUM) {
                best_i[x] = -1;
                disp[x] = NAN;
                mcost[x] = INFINITY;
                reason[x] = (uint8_t)r_none;
                continue;
            }
            best_i[x] = bi;
            float bv = (float)best, delta = 0.0f;
            uint16_t sm = bi > 0 ? s16[base + bi - 1] : SGM_NO_SUM;
            uint16_t sp = bi < n - 1 ? s16[base + bi + 1] : SGM_NO_SUM;
            if (subpixel && bi > 0 && bi < n - 1 && sm != SGM_NO_SUM && sp != SGM_NO_SUM) {
                float cm = (float)sm, cp = (float)sp;
                float den = cm - 2.0f * bv + cp;
                if (den > 0)
                    delta = 0.5f * (cm - cp) / den;
            }
            disp[x] = (float)(dmin + bi) + delta;
            mcost[x] = pow2 ? (float)c[base + bi] * inv : (float)c[base + bi] / scale;
            int code = r_valid;
            if (energy_min > 0 && el[x] < energy_min * count[x])
                code = r_texture;
            if (uniq > 0) {
                uint16_t sk = sgm_second16(s16 + base, bi, n);
                if (sk != SGM_NO_SUM && (float)sk < bv * (1.0f + uniq))
                    code = r_uniq + 100;
            }
            reason[x] = (uint8_t)code;
        }
        return !ovf;
    }
    /* rkey = min(rkey, keys) with the keys (s << 9 | i) made from the sums: a sum
       SGM_NO_SUM gives a key >= SGM_NO_SUM << 9, above every real one (the caller's
       "no key" bound), so no mask is needed. */
    #define SGM_NO_SUM_KEY ((int32_t)SGM_NO_SUM << SGM_KEY_SHIFT)
    static inline void sgm_lower_sums16(int32_t *restrict rkey, const uint16_t *restrict s16,
                                        Py_ssize_t n) {
        __m256i idx = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), step = _mm256_set1_epi32(8);
        for (Py_ssize_t i = 0; i < n; i += 8) {
            __m256i k = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(s16 + i)));
            k = _mm256_or_si256(_mm256_slli_epi32(k, SGM_KEY_SHIFT), idx);
            idx = _mm256_add_epi32(idx, step);
            __m256i r = _mm256_loadu_si256((const __m256i *)(rkey + i));
            _mm256_storeu_si256((__m256i *)(rkey + i), _mm256_min_epi32(r, k));
        }
    }
    #else
    #define SGM_HAVE_LANES16 0
    #define SGM_NO_SUM 0xFFFF
    #define SGM_NO_SUM_KEY ((int32_t)SGM_NO_SUM << SGM_KEY_SHIFT)
    static inline uint16_t sgm_pixel_sums16(const uint16_t *sa, const uint16_t *sb,
                                            const uint16_t *cost, uint16_t *s16,
                                            uint16_t top, Py_ssize_t n, int32_t *bi,
                                            int *ovf) { *ovf = 1; return SGM_NO_SUM; }
    static inline uint16_t sgm_second16(const uint16_t *s16, int32_t bi, Py_ssize_t n) {
        return SGM_NO_SUM; }
    static inline void sgm_lower_sums16(int32_t *rkey, const uint16_t *s16, Py_ssize_t n) {}
    static inline int sgm_winners16_row(const uint16_t *sa, const uint16_t *sb,
                                        const uint16_t *c, const float *el,
                                        const float *count, Py_ssize_t width, Py_ssize_t n,
                                        Py_ssize_t dmin, int subpixel, float uniq,
                                        float energy_min, uint16_t top, float scale,
                                        uint16_t *s16, int32_t *best_i, float *disp,
                                        float *mcost, uint8_t *reason, int r_valid,
                                        int r_none, int r_texture, int r_uniq) { return 0; }
    #endif
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
    const bint HAVE_LANES16 "SGM_HAVE_LANES16"
    const uint16_t NO_SUM "SGM_NO_SUM"
    const int32_t NO_SUM_KEY "SGM_NO_SUM_KEY"
    uint16_t pixel_sums16 "sgm_pixel_sums16" (const uint16_t *sa, const uint16_t *sb,
                                              const uint16_t *cost, uint16_t *s16,
                                              uint16_t top, Py_ssize_t n, int32_t *bi,
                                              int *ovf) noexcept nogil
    uint16_t second16 "sgm_second16" (const uint16_t *s16, int32_t bi,
                                      Py_ssize_t n) noexcept nogil
    void lower_sums16 "sgm_lower_sums16" (int32_t *rkey, const uint16_t *s16,
                                          Py_ssize_t n) noexcept nogil
    bint winners16_row "sgm_winners16_row" (const uint16_t *sa, const uint16_t *sb,
                                            const uint16_t *c, const float *el,
                                            const float *count, Py_ssize_t width,
                                            Py_ssize_t n, Py_ssize_t dmin, bint subpixel,
                                            float uniq, float energy_min, uint16_t top,
                                            float scale, uint16_t *s16, int32_t *best_i,
                                            float *disp, float *mcost, uint8_t *reason,
                                            int r_valid, int r_none, int r_texture,
                                            int r_uniq) noexcept nogil
    int32_t second_key "sgm_second_key" (const int32_t *keys, int32_t lo, int32_t hi,
                                         Py_ssize_t n) noexcept nogil


cdef inline void lower_keys(ip rkey, cip keys, Py_ssize_t n) noexcept nogil:
    """``rkey = min(rkey, keys)``: the right view's best keys."""
    cdef Py_ssize_t i
    cdef int32_t a, b
    for i in range(n):
        a = rkey[i]
        b = keys[i]
        rkey[i] = a if a < b else b
