# SGM's subpixel refit of one row (slitcli.stereo.sgm.raw_subpixel): inline C, compiled
# into the modules that cimport it (subpixel.pyx for the whole map, sgm.pyx in the
# winner step of the fused passes, while the row's costs are in cache).
#
# The rule (see slitcli/stereo/_c/subpixel.pyx): where the whole disparity bi nearest
# d - dmin lies inside the range and is a local minimum of the pixel's own quantised
# costs, both neighbours below the clip ``top`` and the curvature C(bi-1) - 2 C(bi) +
# C(bi+1) positive and at least ``den_min``, d becomes bi + dmin + (C(bi-1) -
# C(bi+1)) / 2 / curvature. Written without branches on the data (whether a pixel's
# costs make a local minimum is as good as random); the arithmetic and comparisons are
# those Cython made of the rule as first written, in the same types (float; the clip
# and den_min compared in double), so the offsets are the same bits.

from libc.stdint cimport uint8_t, uint16_t


cdef extern from *:
    """
    #include <math.h>
    #include <stdint.h>
    /* d (width) float32 px, in place; c the row's costs (width x num) uint16; where
       NULL or (width) 0/1: only pixels with 1 are refitted. Pixels that fail the
       range test read the costs of bi = 1 (inside the row: the caller has num >= 3). */
    #if defined(__AVX2__)
    #include <immintrin.h>
    /* Eight pixels x0 .. x0 + 7 (no `where`): the scalar rule below, lane by lane. The
       costs are read as 32-bit words at bi - 1 and bi (two neighbours each; bi stays in
       1 .. num - 2, so both words lie inside the pixel's costs). The double comparisons
       become float ones with thresholds that give the same answer for every float:
       the clip `top` and 0.5 are whole or half numbers (exact), den_min is replaced by
       the least float f with (double) f >= den_min. */
    static inline void slitcli_refit8(float *restrict d, const uint16_t *restrict c,
                                      Py_ssize_t x0, Py_ssize_t num, Py_ssize_t dmin,
                                      float den_min_f, float top_f, float hi) {
        __m256 v = _mm256_loadu_ps(d + x0);
        __m256 rel = _mm256_sub_ps(v, _mm256_set1_ps((float)dmin));
        __m256 ok = _mm256_and_ps(_mm256_cmp_ps(rel, _mm256_set1_ps(0.5f), _CMP_GE_OQ),
                                  _mm256_cmp_ps(rel, _mm256_set1_ps(hi), _CMP_LE_OQ));
        __m256i bi = _mm256_cvttps_epi32(_mm256_floor_ps(
            _mm256_add_ps(rel, _mm256_set1_ps(0.5f))));
        bi = _mm256_blendv_epi8(_mm256_set1_epi32(1), bi, _mm256_castps_si256(ok));
        __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        __m256i at = _mm256_add_epi32(
            _mm256_mullo_epi32(_mm256_add_epi32(lane, _mm256_set1_epi32((int)x0)),
                               _mm256_set1_epi32((int)num)), bi);
        int idx[8];
        _mm256_storeu_si256((__m256i *)idx, at);
        uint32_t lo[8], up[8];
        for (int k = 0; k < 8; k++) {
            __builtin_memcpy(&lo[k], c + idx[k] - 1, 4);
            __builtin_memcpy(&up[k], c + idx[k], 4);
        }
        __m256i wl = _mm256_loadu_si256((const __m256i *)lo);
        __m256i wu = _mm256_loadu_si256((const __m256i *)up);
        __m256i m16 = _mm256_set1_epi32(0xFFFF);
        __m256 cm = _mm256_cvtepi32_ps(_mm256_and_si256(wl, m16));
        __m256 c0 = _mm256_cvtepi32_ps(_mm256_srli_epi32(wl, 16));
        __m256 cp = _mm256_cvtepi32_ps(_mm256_srli_epi32(wu, 16));
        __m256 den = _mm256_add_ps(_mm256_sub_ps(cm, _mm256_mul_ps(_mm256_set1_ps(2.0f), c0)),
                                   cp);
        __m256 top = _mm256_set1_ps(top_f);
        __m256 take = _mm256_and_ps(ok, _mm256_cmp_ps(cm, c0, _CMP_GE_OQ));
        take = _mm256_and_ps(take, _mm256_cmp_ps(cp, c0, _CMP_GE_OQ));
        take = _mm256_and_ps(take, _mm256_cmp_ps(cm, top, _CMP_LT_OQ));
        take = _mm256_and_ps(take, _mm256_cmp_ps(cp, top, _CMP_LT_OQ));
        take = _mm256_and_ps(take, _mm256_cmp_ps(den, _mm256_setzero_ps(), _CMP_GT_OQ));
        take = _mm256_and_ps(take, _mm256_cmp_ps(den, _mm256_set1_ps(den_min_f),
                                                 _CMP_GE_OQ));
        __m256 whole = _mm256_cvtepi32_ps(_mm256_add_epi32(bi, _mm256_set1_epi32((int)dmin)));
        __m256 nv = _mm256_add_ps(whole, _mm256_div_ps(
            _mm256_mul_ps(_mm256_set1_ps(0.5f), _mm256_sub_ps(cm, cp)), den));
        _mm256_storeu_ps(d + x0, _mm256_blendv_ps(v, nv, take));
    }
    #endif
    static inline void slitcli_refit_row(float *restrict d, const uint16_t *restrict c,
                                         const uint8_t *restrict where, Py_ssize_t width,
                                         Py_ssize_t num, Py_ssize_t dmin, double den_min,
                                         double top) {
        float hi = (float)num - (float)1.5;
        Py_ssize_t x = 0;
    #if defined(__AVX2__)
        /* the vector lanes where their thresholds are exact as floats (always, for the
           clip of match_sgm: 512) and the flat indices fit in int */
        float den_min_f = (float)den_min;
        if ((double)den_min_f < den_min)
            den_min_f = nextafterf(den_min_f, INFINITY);
        int vec = where == NULL && (double)(float)top == top && top == floor(top)
                  && (double)den_min_f >= den_min && width * num < 0x7FFFFFFF
                  && (double)dmin == (double)(float)dmin && num < (1 << 24);
        if (vec)
            for (; x + 8 <= width; x += 8)
                slitcli_refit8(d, c, x, num, dmin, den_min_f, (float)top, hi);
    #endif
        for (; x < width; x++) {
            float v = d[x];
            float rel = v - (float)dmin;
            int ok = (rel >= 0.5) & (rel <= hi) & (where == NULL || where[x] != 0);
            Py_ssize_t bi = ok ? (Py_ssize_t)floorf(rel + (float)0.5) : 1;
            const uint16_t *q = c + x * num + bi;
            float cm = (float)q[-1], c0 = (float)q[0], cp = (float)q[1];
            float den = (cm - (float)2.0 * c0) + cp;
            int take = ok & (cm >= c0) & (cp >= c0) & (cm < top) & (cp < top)
                       & (den > 0.0) & (den >= den_min);
            float nv = (float)(bi + dmin) + ((float)0.5 * (cm - cp)) / den;
            d[x] = take ? nv : v;
        }
    }
    """
    void refit_row "slitcli_refit_row"(float* d, const uint16_t* c, const uint8_t* where,
                                       Py_ssize_t width, Py_ssize_t num, Py_ssize_t dmin,
                                       double den_min, double top) noexcept nogil
