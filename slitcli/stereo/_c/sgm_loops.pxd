"""The per-pixel loops of semi-global aggregation's cost and sweeps
(slitcli/stereo/_c/sgm.pyx), each over one pixel's disparities.

Each loop is a function of its own over ``__restrict__`` pointers (what it writes never
overlaps what it reads), so gcc vectorises it, 16 int16 or 8 float32 disparities per
AVX2 operation, for any disparity count (a scalar tail takes the rest). Integer
operations wrap in 16 bits where the casts say so; float operations are the IEEE
float32 operations written, in that order, without contraction, so the costs and
sums are the same bits whatever the vector width.

Where the processor has AVX2 (``__AVX2__``: not in SLITCLI_PORTABLE_BUILD wheels) and D
is a multiple of 16, whole rows run in C functions written with AVX2 intrinsics (the
cost row with its column slide, the sweep rows with a constant or an edge-adapted P2;
the winner step's, in uint16 lanes, are in sgm_winner_loops.pxd): the same operations
in the same order, with the loop over a row's pixels in C so that its pointers stay in registers (Cython's loops spilled
them, and the per-pixel work outside the vector loops was ~40 % of a sweep). Other D
and portable builds take the loops above; both give the same bits (checked on
Middlebury and rendered pairs, 4 and 8 paths, constant and adaptive P2, one and two
threads).
"""

from libc.stdint cimport int16_t, int32_t, uint8_t, uint16_t

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
    /* One path at one pixel, d = 0..n-1: L = C + min(prev, prev -+ 1 + P1, min prev + P2)
       - min prev (Hirschmueller) with prev from index 1 (a sentinel at both ends),
       int16 throughout (every value stays below SGM_SENTINEL + P2 < 2^15, so the smaller
       of prev[i], prev[i + 2] plus P1 is the smaller of the two sums). */
    #define SGM_STEP(prev, h, pm, l) do { \
            int16_t v_ = prev[i + 1], t_ = prev[i] < prev[i + 2] ? prev[i] : prev[i + 2]; \
            t_ = (int16_t)(t_ + q1); \
            v_ = t_ < v_ ? t_ : v_; \
            v_ = h < v_ ? h : v_; \
            l = (int16_t)((int16_t)(c[i] + v_) - pm); \
        } while (0)
    /* Paths a and b at one pixel: rows into ac, bc (from index 1), their sum into o
       (added to it with acc); returns min L of path a, that of b into bmin. In C:
       the two loops (acc or not) each vectorise as one, Cython's branch in the loop
       kept gcc from unswitching it well. */
    #ifdef __AVX2__
    #include <immintrin.h>
    /* min(a + P1, b + P1) is min(a, b) + P1: no term wraps (all below SGM_SENTINEL + P1
       < 2^15), so one add instead of two, the same values */
    #define SGM_VSTEP(prev, q, h, pm, cv) _mm256_sub_epi16(_mm256_add_epi16(cv, \
        _mm256_min_epi16(_mm256_min_epi16( \
            _mm256_loadu_si256((const __m256i *)(prev + i + 1)), \
            _mm256_add_epi16(_mm256_min_epi16( \
                _mm256_loadu_si256((const __m256i *)(prev + i)), \
                _mm256_loadu_si256((const __m256i *)(prev + i + 2))), q)), h)), \
        pm)
    /* the smallest of 16 int16 lanes (minpos works on unsigned: flip the sign bit) */
    static inline int16_t sgm_hmin16(__m256i v) {
        __m128i m = _mm_min_epi16(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
        m = _mm_minpos_epu16(_mm_xor_si128(m, _mm_set1_epi16((short)0x8000)));
        return (int16_t)(_mm_extract_epi16(m, 0) ^ 0x8000);
    }
    /* sgm_path_pair for n a multiple of 16 in AVX2 16-lane vectors: the same int16
       operations (wrapping adds, signed minima), so the same rows; the compiler's
       vector loop pays an overlap check, a 16-byte and a scalar tail each call, and
       took 1.3-1.5 times as long (measured at D = 64) */
    static inline int32_t sgm_path_pair16(
            const int16_t *restrict c, int16_t *restrict o, const int16_t *restrict ap,
            int16_t *restrict ac, int32_t am, const int16_t *restrict bp,
            int16_t *restrict bc, int32_t bm, int32_t p1, int32_t p2a, int32_t p2b,
            int acc, Py_ssize_t n, int32_t *bmin) {
        __m256i q = _mm256_set1_epi16((short)p1);
        __m256i ha = _mm256_set1_epi16((short)(am + p2a)), pa = _mm256_set1_epi16((short)am);
        __m256i hb = _mm256_set1_epi16((short)(bm + p2b)), pb = _mm256_set1_epi16((short)bm);
        __m256i ma = _mm256_set1_epi16(0x7FFF), mb = ma;
        for (Py_ssize_t i = 0; i < n; i += 16) {
            __m256i cv = _mm256_loadu_si256((const __m256i *)(c + i));
            __m256i la = SGM_VSTEP(ap, q, ha, pa, cv);
            __m256i lb = SGM_VSTEP(bp, q, hb, pb, cv);
            _mm256_storeu_si256((__m256i *)(ac + i + 1), la);
            _mm256_storeu_si256((__m256i *)(bc + i + 1), lb);
            __m256i s = _mm256_add_epi16(la, lb);
            if (acc)
                s = _mm256_add_epi16(_mm256_loadu_si256((const __m256i *)(o + i)), s);
            _mm256_storeu_si256((__m256i *)(o + i), s);
            ma = _mm256_min_epi16(ma, la);
            mb = _mm256_min_epi16(mb, lb);
        }
        *bmin = sgm_hmin16(mb);
        return sgm_hmin16(ma);
    }
    /* One row of a 4-path sweep: sweep_row's loop (sgm.pyx) in C, so that the compiler
       keeps its few pointers in registers (the general loop, with the diagonal paths
       and the adaptive P2, spilled them to the stack: about 40 % of a sweep's time was
       outside the vector loop). p2_step NULL: a constant P2; else the P2 of a step
       between grey levels a and b is p2_step[a - b] (sgm.pyx's table of _p2), row
       the image row's grey levels, above those of the row the vertical paths come
       from; a P2 is one scalar per pixel and path, broadcast over the disparities. The
       same calls with the same penalties in the same order, so the same rows. */
    #define SGM_HAVE_ROW4 1
    #define SGM_STEP_P2(tab, a, b) ((tab)[(int32_t)(a) - (int32_t)(b)])
    static inline void sgm_sweep_row4(const int16_t *restrict c_row, int16_t *restrict o_row,
                                      Py_ssize_t width, Py_ssize_t n, int reverse,
                                      int first_row, int32_t p1, int32_t p2,
                                      const int32_t *p2_step, const uint8_t *row,
                                      const uint8_t *above, int16_t *ph,
                                      const int16_t *pv_src, int16_t *pv_dst,
                                      const int32_t *mv_src, int32_t *mv_dst,
                                      const int16_t *zero) {
        Py_ssize_t stride = n + 2;
        int32_t hmin = 0;
        for (Py_ssize_t x = 0; x < width; x++) {
            Py_ssize_t xx = reverse ? width - 1 - x : x, hs = x & 1;
            Py_ssize_t xs = reverse ? xx + 1 : xx - 1;
            int32_t p2a = p2, p2b = p2;
            if (p2_step) {
                if (x > 0)
                    p2a = SGM_STEP_P2(p2_step, row[xx], row[xs]);
                if (!first_row)
                    p2b = SGM_STEP_P2(p2_step, row[xx], above[xx]);
            }
            hmin = sgm_path_pair16(c_row + xx * n, o_row + xx * n,
                                   x == 0 ? zero : ph + hs * stride, ph + (1 - hs) * stride,
                                   hmin, first_row ? zero : pv_src + x * stride,
                                   pv_dst + x * stride, first_row ? 0 : mv_src[x], p1, p2a,
                                   p2b, 0, n, mv_dst + x);
        }
    }
    /* sgm_sweep_row4 with the two diagonal paths (8 paths): d from the top-left
       (rows d_*, minima md_*, grey step to above[xs]), e from the top-right (grey step
       to the pixel above on the other side), their pair added to o. */
    static inline void sgm_sweep_row8(const int16_t *restrict c_row, int16_t *restrict o_row,
                                      Py_ssize_t width, Py_ssize_t n, int reverse,
                                      int first_row, int32_t p1, int32_t p2,
                                      const int32_t *p2_step, const uint8_t *row,
                                      const uint8_t *above, int16_t *ph,
                                      const int16_t *pv_src, int16_t *pv_dst,
                                      const int32_t *mv_src, int32_t *mv_dst,
                                      const int16_t *pd_src, int16_t *pd_dst,
                                      const int32_t *md_src, int32_t *md_dst,
                                      const int16_t *pe_src, int16_t *pe_dst,
                                      const int32_t *me_src, int32_t *me_dst,
                                      const int16_t *zero) {
        Py_ssize_t stride = n + 2;
        int32_t hmin = 0;
        for (Py_ssize_t x = 0; x < width; x++) {
            Py_ssize_t xx = reverse ? width - 1 - x : x, hs = x & 1;
            Py_ssize_t xs = reverse ? xx + 1 : xx - 1;
            const int16_t *c = c_row + xx * n;
            int16_t *o = o_row + xx * n;
            int first = first_row || x == 0, last = first_row || x == width - 1;
            int32_t p2a = p2, p2b = p2, p2d = p2, p2e = p2;
            if (p2_step) {
                uint8_t g0 = row[xx];
                if (x > 0)
                    p2a = SGM_STEP_P2(p2_step, g0, row[xs]);
                if (!first_row)
                    p2b = SGM_STEP_P2(p2_step, g0, above[xx]);
                if (!first)
                    p2d = SGM_STEP_P2(p2_step, g0, above[xs]);
                if (!last)
                    p2e = SGM_STEP_P2(p2_step, g0, above[2 * xx - xs]);
            }
            hmin = sgm_path_pair16(c, o, x == 0 ? zero : ph + hs * stride,
                                   ph + (1 - hs) * stride, hmin,
                                   first_row ? zero : pv_src + x * stride, pv_dst + x * stride,
                                   first_row ? 0 : mv_src[x], p1, p2a, p2b, 0, n, mv_dst + x);
            md_dst[x] = sgm_path_pair16(c, o, first ? zero : pd_src + (x - 1) * stride,
                                        pd_dst + x * stride, first ? 0 : md_src[x - 1],
                                        last ? zero : pe_src + (x + 1) * stride,
                                        pe_dst + x * stride, last ? 0 : me_src[x + 1], p1, p2d,
                                        p2e, 1, n, me_dst + x);
        }
    }
    #else
    #define SGM_HAVE_ROW4 0
    static inline void sgm_sweep_row4(const int16_t *c_row, int16_t *o_row, Py_ssize_t width,
                                      Py_ssize_t n, int reverse, int first_row, int32_t p1,
                                      int32_t p2, const int32_t *p2_step, const uint8_t *row,
                                      const uint8_t *above, int16_t *ph,
                                      const int16_t *pv_src, int16_t *pv_dst,
                                      const int32_t *mv_src, int32_t *mv_dst,
                                      const int16_t *zero) {}
    static inline void sgm_sweep_row8(const int16_t *c_row, int16_t *o_row, Py_ssize_t width,
                                      Py_ssize_t n, int reverse, int first_row, int32_t p1,
                                      int32_t p2, const int32_t *p2_step, const uint8_t *row,
                                      const uint8_t *above, int16_t *ph,
                                      const int16_t *pv_src,
                                      int16_t *pv_dst, const int32_t *mv_src,
                                      int32_t *mv_dst, const int16_t *pd_src,
                                      int16_t *pd_dst, const int32_t *md_src,
                                      int32_t *md_dst, const int16_t *pe_src,
                                      int16_t *pe_dst, const int32_t *me_src,
                                      int32_t *me_dst, const int16_t *zero) {}
    #endif
    static inline int32_t sgm_path_pair(
            const int16_t *restrict c, int16_t *restrict o, const int16_t *restrict ap,
            int16_t *restrict ac, int32_t am, const int16_t *restrict bp,
            int16_t *restrict bc, int32_t bm, int32_t p1, int32_t p2a, int32_t p2b,
            int acc, Py_ssize_t n, int32_t *bmin) {
    #ifdef __AVX2__
        if (n % 16 == 0)
            return sgm_path_pair16(c, o, ap, ac, am, bp, bc, bm, p1, p2a, p2b, acc, n, bmin);
    #endif
        int16_t q1 = (int16_t)p1, ha = (int16_t)(am + p2a), pa = (int16_t)am;
        int16_t hb = (int16_t)(bm + p2b), pb = (int16_t)bm, ma = 0x7FFF, mb = 0x7FFF;
        if (acc) {
            for (Py_ssize_t i = 0; i < n; i++) {
                int16_t la, lb;
                SGM_STEP(ap, ha, pa, la);
                SGM_STEP(bp, hb, pb, lb);
                ac[i + 1] = la;
                bc[i + 1] = lb;
                o[i] = (int16_t)(o[i] + (int16_t)(la + lb));
                ma = la < ma ? la : ma;
                mb = lb < mb ? lb : mb;
            }
        } else {
            for (Py_ssize_t i = 0; i < n; i++) {
                int16_t la, lb;
                SGM_STEP(ap, ha, pa, la);
                SGM_STEP(bp, hb, pb, lb);
                ac[i + 1] = la;
                bc[i + 1] = lb;
                o[i] = (int16_t)(la + lb);
                ma = la < ma ? la : ma;
                mb = lb < mb ? lb : mb;
            }
        }
        *bmin = mb;
        return ma;
    }
    #ifdef __AVX2__
    /* pixel_costs (sgm_loops.pxd) for n a multiple of 16 in AVX2 lanes, with inner
       (wa = ws = 1: the products 1 x v are v, dropped) and tops below 60000 (so that
       the truncated int32 costs pack into uint16 unchanged): the same float32
       operations in the same order (no contraction); c > 0 ? c : 0 and c < c_max ? c :
       c_max are exactly max_ps(c, 0) and min_ps(c, c_max) (gcc keeps a compare and a
       mask for the first), and the packing takes one pack and one permute per 16. */
    #define SGM_HAVE_COSTS16 1
    static inline __m256 sgm_cost8(float *restrict hs, const float *restrict ci,
                                   const float *restrict co, __m256 wa, __m256 ws,
                                   int inner, __m256 e1, __m256 r1,
                                   const float *restrict err, const float *restrict irr,
                                   __m256 c_max, __m256 scale, __m256 *valid) {
        __m256 x;
        if (inner)
            x = _mm256_sub_ps(_mm256_add_ps(_mm256_loadu_ps(hs), _mm256_loadu_ps(ci)),
                              _mm256_loadu_ps(co));
        else
            x = _mm256_sub_ps(_mm256_add_ps(_mm256_loadu_ps(hs),
                                            _mm256_mul_ps(wa, _mm256_loadu_ps(ci))),
                              _mm256_mul_ps(ws, _mm256_loadu_ps(co)));
        _mm256_storeu_ps(hs, x);
        __m256 w = _mm256_mul_ps(r1, _mm256_loadu_ps(irr));
        __m256 c = _mm256_mul_ps(_mm256_sub_ps(_mm256_add_ps(e1, _mm256_loadu_ps(err)),
                                               _mm256_mul_ps(_mm256_set1_ps(2.0f), x)), w);
        c = _mm256_min_ps(_mm256_max_ps(c, _mm256_setzero_ps()), c_max);
        *valid = _mm256_cmp_ps(w, _mm256_setzero_ps(), _CMP_GT_OQ);
        return _mm256_add_ps(_mm256_mul_ps(c, scale), _mm256_set1_ps(0.5f));
    }
    static inline void sgm_pixel_costs16(float *restrict hs, const float *restrict ci,
                                         const float *restrict co, float wa, float ws,
                                         int inner, float e1, float r1,
                                         const float *restrict err,
                                         const float *restrict irr, uint16_t top,
                                         float scale, float c_max,
                                         uint16_t *restrict out, Py_ssize_t n) {
        __m256 vwa = _mm256_set1_ps(wa), vws = _mm256_set1_ps(ws), ve1 = _mm256_set1_ps(e1);
        __m256 vr1 = _mm256_set1_ps(r1), vmax = _mm256_set1_ps(c_max);
        __m256 vscale = _mm256_set1_ps(scale);
        __m256i vtop = _mm256_set1_epi16((short)top);
        for (Py_ssize_t i = 0; i < n; i += 16) {
            __m256 va, vb;
            __m256 qa = sgm_cost8(hs + i, ci + i, co + i, vwa, vws, inner, ve1, vr1, err + i,
                                  irr + i, vmax, vscale, &va);
            __m256 qb = sgm_cost8(hs + i + 8, ci + i + 8, co + i + 8, vwa, vws, inner, ve1,
                                  vr1, err + i + 8, irr + i + 8, vmax, vscale, &vb);
            __m256i q = _mm256_packus_epi32(_mm256_cvttps_epi32(qa), _mm256_cvttps_epi32(qb));
            __m256i m = _mm256_packs_epi32(_mm256_castps_si256(va), _mm256_castps_si256(vb));
            q = _mm256_permute4x64_epi64(_mm256_blendv_epi8(vtop, q, m), 0xD8);
            _mm256_storeu_si256((__m256i *)(out + i), q);
        }
    }
    /* A row's pixels (the x loop of sgm.pyx's _cost_row) over pixel_costs16, in C for
       the same reason as sgm_sweep_row4: the pointers stay in registers. el_row: the
       row's left window energies; err_row, irr_row: the right energies at the row's
       first pixel's first disparity (pixel x: minus x). The same operations. */
    static inline void sgm_cost_pixels16(float *restrict hs, const float *col,
                                         const float *restrict el_row,
                                         const float *err_row, const float *irr_row,
                                         Py_ssize_t width, Py_ssize_t n, Py_ssize_t m,
                                         uint16_t top, float scale, float c_max,
                                         uint16_t *out) {
        for (Py_ssize_t x = 0; x < width; x++) {
            Py_ssize_t xa = x + m, xs = x - m - 1;
            float e1 = el_row[x];
            float r1 = e1 > 0 ? 1.0f / sqrtf(e1) : 0.0f;
            sgm_pixel_costs16(hs, col + ((xa < width ? xa : width - 1) + 1) * n,
                              col + ((xs >= 0 ? xs : -1) + 1) * n, xa < width ? 1.0f : 0.0f,
                              xs >= 0 ? 1.0f : 0.0f, xa < width && xs >= 0, e1, r1,
                              err_row - x, irr_row - x, top, scale, c_max, out + x * n, n);
        }
    }
    /* The column sums of a row slid one row down (the first loop of _cost_row,
       column_slide over every column): col[x + 1] += a ra - b rs with a, b the left
       pixels entering and leaving (a_row / s_row NULL: outside the image, 0), ra, rs
       the mirrored right rows at column 0's first disparity (column x: minus x). */
    static inline void sgm_slide_columns16(float *restrict col, const float *a_row,
                                           const float *s_row, const float *ra_row,
                                           const float *rs_row, Py_ssize_t width,
                                           Py_ssize_t n) {
        for (Py_ssize_t x = 0; x < width; x++) {
            __m256 a = _mm256_set1_ps(a_row ? a_row[x] : 0.0f);
            __m256 b = _mm256_set1_ps(s_row ? s_row[x] : 0.0f);
            float *cx = col + (x + 1) * n;
            const float *ra = ra_row - x, *rs = rs_row - x;
            for (Py_ssize_t i = 0; i < n; i += 8)
                _mm256_storeu_ps(cx + i, _mm256_add_ps(_mm256_loadu_ps(cx + i), _mm256_sub_ps(
                    _mm256_mul_ps(a, _mm256_loadu_ps(ra + i)),
                    _mm256_mul_ps(b, _mm256_loadu_ps(rs + i)))));
        }
    }
    #else
    #define SGM_HAVE_COSTS16 0
    static inline void sgm_pixel_costs16(float *hs, const float *ci, const float *co,
                                         float wa, float ws, int inner, float e1, float r1,
                                         const float *err, const float *irr, uint16_t top,
                                         float scale, float c_max, uint16_t *out,
                                         Py_ssize_t n) {}
    static inline void sgm_cost_pixels16(float *hs, const float *col, const float *el_row,
                                         const float *err_row, const float *irr_row,
                                         Py_ssize_t width, Py_ssize_t n, Py_ssize_t m,
                                         uint16_t top, float scale, float c_max,
                                         uint16_t *out) {}
    static inline void sgm_slide_columns16(float *col, const float *a_row, const float *s_row,
                                           const float *ra_row, const float *rs_row,
                                           Py_ssize_t width, Py_ssize_t n) {}
    #endif
    """
    int32_t path_pair "sgm_path_pair" (const int16_t *c, int16_t *o, const int16_t *ap,
                                       int16_t *ac, int32_t am, const int16_t *bp,
                                       int16_t *bc, int32_t bm, int32_t p1, int32_t p2a,
                                       int32_t p2b, bint acc, Py_ssize_t n,
                                       int32_t *bmin) noexcept nogil
    const bint HAVE_COSTS16 "SGM_HAVE_COSTS16"
    void pixel_costs16 "sgm_pixel_costs16" (float *hs, const float *ci, const float *co,
                                            float wa, float ws, bint inner, float e1,
                                            float r1, const float *err, const float *irr,
                                            uint16_t top, float scale, float c_max,
                                            uint16_t *out, Py_ssize_t n) noexcept nogil
    const bint HAVE_ROW4 "SGM_HAVE_ROW4"
    void sweep_row4 "sgm_sweep_row4" (const int16_t *c_row, int16_t *o_row, Py_ssize_t width,
                                      Py_ssize_t n, bint reverse, bint first_row, int32_t p1,
                                      int32_t p2, const int32_t *p2_step, const uint8_t *row,
                                      const uint8_t *above, int16_t *ph, const int16_t *pv_src,
                                      int16_t *pv_dst, const int32_t *mv_src,
                                      int32_t *mv_dst, const int16_t *zero) noexcept nogil
    void cost_pixels16 "sgm_cost_pixels16" (float *hs, const float *col, const float *el_row,
                                            const float *err_row, const float *irr_row,
                                            Py_ssize_t width, Py_ssize_t n, Py_ssize_t m,
                                            uint16_t top, float scale, float c_max,
                                            uint16_t *out) noexcept nogil
    void slide_columns16 "sgm_slide_columns16" (float *col, const float *a_row,
                                                const float *s_row, const float *ra_row,
                                                const float *rs_row, Py_ssize_t width,
                                                Py_ssize_t n) noexcept nogil
    void sweep_row8 "sgm_sweep_row8" (const int16_t *c_row, int16_t *o_row, Py_ssize_t width,
                                      Py_ssize_t n, bint reverse, bint first_row, int32_t p1,
                                      int32_t p2, const int32_t *p2_step, const uint8_t *row,
                                      const uint8_t *above, int16_t *ph, const int16_t *pv_src,
                                      int16_t *pv_dst, const int32_t *mv_src,
                                      int32_t *mv_dst, const int16_t *pd_src,
                                      int16_t *pd_dst, const int32_t *md_src,
                                      int32_t *md_dst, const int16_t *pe_src,
                                      int16_t *pe_dst, const int32_t *me_src,
                                      int32_t *me_dst, const int16_t *zero) noexcept nogil


cdef inline void add_floats(fp dst, cfp src, Py_ssize_t n) noexcept nogil:
    """``dst[:n] += src[:n]`` (sums of whole numbers below 2^24: exact in any
    order)."""
    cdef Py_ssize_t i
    for i in range(n):
        dst[i] += src[i]


cdef inline void min_u16(up dst, cup src, Py_ssize_t n) noexcept nogil:
    """``dst[:n] = min(dst[:n], src[:n])``."""
    cdef Py_ssize_t i
    for i in range(n):
        dst[i] = src[i] if src[i] < dst[i] else dst[i]


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
