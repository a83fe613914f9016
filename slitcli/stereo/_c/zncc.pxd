# Block correlations of the support tests (slitcli.stereo._boundary), one at a time or
# eight at a time: inline C helpers, compiled into the module that cimports them.
#
# The one-sided and cross support tests correlate small grey blocks of the left image
# with the right image shifted by the tested pixel's own (subpixel) disparity. Every
# pixel has its own shift, so the blocks of neighbouring pixels share no sums (no
# running sums or integral images apply), and a block is a short chain of dependent
# float additions: one block at a time, the processor waits on the adds' latency.
# zncc_blocks takes a row's blocks together and computes eight of them side by side
# (_lanes8: a loop over 8 floats per sample, one AVX2 vector once gcc vectorises it);
# each lane runs exactly the operations of zncc_block in the same order, so every
# correlation is the scalar one bit for bit (tests/test_stereo_zncc.py). Blocks
# clipped by the image border run the scalar code.
#
# Arithmetic: the numba kernels these replace ran with fastmath contract/arcp, under
# which LLVM fused a multiply feeding an add into one FMA and divided by a repeated
# divisor through its reciprocal. The fused operations are spelled out here (fmaf, a
# single rounding; the build turns contraction off, so gcc fuses nothing else), the
# reciprocal too, so the results are those of the numba kernels bit for bit.

from libc.math cimport floorf, fmaf, nextafterf, sqrtf

# the largest float32 at or below 1e-3: a float32 den is above 1e-3 (finish() compares
# in double) exactly when it is above this
cdef float FLAT_ZNCC = (<float>1e-3 if <double><float>1e-3 <= 1e-3
                        else nextafterf(<float>1e-3, 0.0))


cdef inline float finish(float sa, float sb, float saa, float sbb, float sab,
                         Py_ssize_t cnt, float nv, float nvf, float nfr) noexcept nogil:
    """The correlation from a block's sums (``cnt`` samples); 0 for a flat block.

    With a noise model (``nv`` > 0: the images' noise variance per sample, DN^2, and
    ``nvf``: nv times the variance factor of a block sum, so that a block's zero-mean
    energy holds ``ne = nv cnt - nvf`` of noise), each energy is that of the signal,
    ``v - ne``, where the block's energy ``v`` is above what noise alone reaches in 99 %
    of blocks (:func:`noise_bound`): the correlation of the two signals; elsewhere ``v``
    (plain ZNCC: a block of noise is not made to correlate better). ``nv`` = 0: plain
    ZNCC. ``nfr``: the share of ``ne`` taken off (the noise beyond what the thresholds
    were set at, :func:`slitcli.stereo.noise.MatchNoise.excess_share`)."""
    cdef float n = <float>cnt
    # three divisions by n: numba (arcp) took one reciprocal and fused each product
    cdef float rn = 1.0 / n
    cdef float va = fmaf(-(sa * sa), rn, saa)
    cdef float vb = fmaf(-(sb * sb), rn, sbb)
    cdef float cov = fmaf(-(sa * sb), rn, sab)
    cdef float ne = nv * n - nvf
    cdef float sig
    if ne > 0:
        sig = ne * noise_bound(ne, nvf)
        va = va - nfr * ne if va >= sig else va
        vb = vb - nfr * ne if vb >= sig else vb
    cdef float den = sqrtf(fmax_nb(va, 0.0) * fmax_nb(vb, 0.0))
    return cov / den if den > 1e-3 else 0.0


cdef inline float noise_bound(float ne, float nvf) noexcept nogil:
    """The 99 % bound of a noise-only block's zero-mean energy over its mean ``ne``:
    the energy has ``dof = ne / nvf`` degrees of freedom (samples over the variance
    factor, one taken by the mean), so ``1 + 2.326 sqrt(2 / dof)`` (normal approximation
    of the chi-square)."""
    return 1.0 + 2.326 * sqrtf(2.0 * nvf / ne)


cdef inline float fmax_nb(float a, float b) noexcept nogil:
    """Python's ``max(a, b)`` as numba compiles it: ``b`` only where ``b > a``."""
    return b if b > a else a


cdef inline float fmin_nb(float a, float b) noexcept nogil:
    """Python's ``min(a, b)`` as numba compiles it: ``b`` only where ``b < a``."""
    return b if b < a else a


cdef inline float zncc_block(const float* gl, const float* gr, Py_ssize_t height,
                             Py_ssize_t width, Py_ssize_t y, Py_ssize_t xc, float d,
                             Py_ssize_t rx, Py_ssize_t ry, float nv,
                             float nvf, float nfr) noexcept nogil:
    """Zero-mean normalised correlation of the left block centred at (xc, y), (2rx+1)
    x (2ry+1) clipped to the image, with the right image at xc - d (linear in x); 0
    where a block is flat or too small. ``gl``, ``gr``: (height, width) C order."""
    # every sample of the block shares the fractional shift: right column xx + off
    # and xx + off + 1 with weights 1 - t, t; the columns are clipped once
    cdef Py_ssize_t off = <Py_ssize_t>floorf(-d)
    cdef float t = -d - <float>off
    cdef Py_ssize_t c0 = max(xc - rx, 0, -off)
    cdef Py_ssize_t c1 = min(xc + rx, width - 1, width - 2 - off)
    cdef Py_ssize_t r0 = max(0, y - ry)
    cdef Py_ssize_t r1 = min(height, y + ry + 1)
    cdef Py_ssize_t cnt = (c1 - c0 + 1) * (r1 - r0)
    cdef float u = 1.0 - t
    cdef float sa = 0.0, sb = 0.0, saa = 0.0, sbb = 0.0, sab = 0.0
    cdef float a, b
    cdef Py_ssize_t yy, xx
    cdef const float* pa
    cdef const float* pb
    if c1 < c0 or cnt < 2:
        return 0.0
    for yy in range(r0, r1):
        pa = gl + yy * width
        pb = gr + yy * width + off
        for xx in range(c0, c1 + 1):
            a = pa[xx]
            b = fmaf(u, pb[xx], t * pb[xx + 1])
            sa = sa + a
            sb = sb + b
            saa = fmaf(a, a, saa)
            sbb = fmaf(b, b, sbb)
            sab = fmaf(a, b, sab)
    return finish(sa, sb, saa, sbb, sab, cnt, nv, nvf, nfr)


cdef extern from *:
    """
    /* Eight blocks side by side, one per lane of an AVX2 vector (GCC vector
       extensions; the FMA is the instruction, one rounding, as fmaf). Every lane's
       sample is loaded on its own: the eight blocks lie anywhere in the image, and
       AMD's gather instructions are slower than the separate loads. Without AVX2 and
       FMA (a portable build) the scalar loop of zncc.pxd runs instead. */
    #if defined(__AVX2__) && defined(__FMA__)
    #include <immintrin.h>
    #define SLITCLI_ZNCC_LANES 1
    typedef float slitcli_f8 __attribute__((vector_size(32)));
    static inline void slitcli_zncc_lanes8(
            const float *gl, const float *gr, const Py_ssize_t *base_l,
            const Py_ssize_t *base_r, const float *u8, const float *t8, Py_ssize_t rx,
            Py_ssize_t ry, Py_ssize_t width, float *sums) {
        const float *l0 = gl + base_l[0], *l1 = gl + base_l[1], *l2 = gl + base_l[2],
                    *l3 = gl + base_l[3], *l4 = gl + base_l[4], *l5 = gl + base_l[5],
                    *l6 = gl + base_l[6], *l7 = gl + base_l[7];
        const float *r0 = gr + base_r[0], *r1 = gr + base_r[1], *r2 = gr + base_r[2],
                    *r3 = gr + base_r[3], *r4 = gr + base_r[4], *r5 = gr + base_r[5],
                    *r6 = gr + base_r[6], *r7 = gr + base_r[7];
        slitcli_f8 vu, vt, sa = {0}, sb = {0}, saa = {0}, sbb = {0}, sab = {0};
        __builtin_memcpy(&vu, u8, sizeof vu);
        __builtin_memcpy(&vt, t8, sizeof vt);
        for (Py_ssize_t j = 0; j < 2 * ry + 1; j++) {
            for (Py_ssize_t i = 0; i < 2 * rx + 1; i++) {
                Py_ssize_t k = j * width + i;
                slitcli_f8 a = {l0[k], l1[k], l2[k], l3[k], l4[k], l5[k], l6[k], l7[k]};
                slitcli_f8 g0 = {r0[k], r1[k], r2[k], r3[k], r4[k], r5[k], r6[k], r7[k]};
                slitcli_f8 g1 = {r0[k + 1], r1[k + 1], r2[k + 1], r3[k + 1], r4[k + 1],
                                 r5[k + 1], r6[k + 1], r7[k + 1]};
                slitcli_f8 b = (slitcli_f8)_mm256_fmadd_ps((__m256)vu, (__m256)g0,
                                                           (__m256)(vt * g1));
                sa = sa + a;
                sb = sb + b;
                saa = (slitcli_f8)_mm256_fmadd_ps((__m256)a, (__m256)a, (__m256)saa);
                sbb = (slitcli_f8)_mm256_fmadd_ps((__m256)b, (__m256)b, (__m256)sbb);
                sab = (slitcli_f8)_mm256_fmadd_ps((__m256)a, (__m256)b, (__m256)sab);
            }
        }
        __builtin_memcpy(sums, &sa, sizeof sa);
        __builtin_memcpy(sums + 8, &sb, sizeof sb);
        __builtin_memcpy(sums + 16, &saa, sizeof saa);
        __builtin_memcpy(sums + 24, &sbb, sizeof sbb);
        __builtin_memcpy(sums + 32, &sab, sizeof sab);
    }
    /* finish() of zncc.pxd for the eight lanes at once: the same IEEE operations in
       the same order (the negated product, one FMA each, the product of the clamped
       variances, its correctly rounded root, the division; maxps(0, v) is fmax_nb(v,
       0) bit for bit, NaN and -0 included), the reciprocal `rn` taken by the caller as
       finish() takes it, and `den > 1e-3` (a double comparison) as `den > flat`,
       flat the largest float at or below 1e-3. */
    static inline void slitcli_zncc_finish8(const float *sums, float rn, float flat,
                                            float ne, float sig, float *res) {
        __m256 sa = _mm256_loadu_ps(sums), sb = _mm256_loadu_ps(sums + 8),
               saa = _mm256_loadu_ps(sums + 16), sbb = _mm256_loadu_ps(sums + 24),
               sab = _mm256_loadu_ps(sums + 32);
        __m256 vrn = _mm256_set1_ps(rn), zero = _mm256_setzero_ps();
        __m256 sign = _mm256_set1_ps(-0.0f);
        __m256 va = _mm256_fmadd_ps(_mm256_xor_ps(_mm256_mul_ps(sa, sa), sign), vrn, saa);
        __m256 vb = _mm256_fmadd_ps(_mm256_xor_ps(_mm256_mul_ps(sb, sb), sign), vrn, sbb);
        __m256 cov = _mm256_fmadd_ps(_mm256_xor_ps(_mm256_mul_ps(sa, sb), sign), vrn, sab);
        if (ne > 0.0f) {  /* the signals' energies, as finish() takes them */
            __m256 vne = _mm256_set1_ps(ne), vsig = _mm256_set1_ps(sig);
            va = _mm256_blendv_ps(va, _mm256_sub_ps(va, vne),
                                  _mm256_cmp_ps(va, vsig, _CMP_GE_OQ));
            vb = _mm256_blendv_ps(vb, _mm256_sub_ps(vb, vne),
                                  _mm256_cmp_ps(vb, vsig, _CMP_GE_OQ));
        }
        __m256 den = _mm256_sqrt_ps(_mm256_mul_ps(_mm256_max_ps(zero, va),
                                                  _mm256_max_ps(zero, vb)));
        __m256 q = _mm256_div_ps(cov, den);
        __m256 ok = _mm256_cmp_ps(den, _mm256_set1_ps(flat), _CMP_GT_OQ);
        _mm256_storeu_ps(res, _mm256_and_ps(q, ok));
    }
    #else
    #define SLITCLI_ZNCC_LANES 0
    static inline void slitcli_zncc_lanes8(
            const float *gl, const float *gr, const Py_ssize_t *base_l,
            const Py_ssize_t *base_r, const float *u8, const float *t8, Py_ssize_t rx,
            Py_ssize_t ry, Py_ssize_t width, float *sums) {}
    static inline void slitcli_zncc_finish8(const float *sums, float rn, float flat,
                                            float ne, float sig, float *res) {}
    #endif
    """
    bint ZNCC_LANES "SLITCLI_ZNCC_LANES"
    void zncc_lanes8_sums "slitcli_zncc_lanes8"(
        const float* gl, const float* gr, const Py_ssize_t* base_l,
        const Py_ssize_t* base_r, const float* u8, const float* t8, Py_ssize_t rx,
        Py_ssize_t ry, Py_ssize_t width, float* sums) noexcept nogil
    void zncc_finish8 "slitcli_zncc_finish8"(const float* sums, float rn, float flat,
                                             float ne, float sig,
                                             float* res) noexcept nogil


cdef inline void _lanes8(const float* gl, const float* gr, const Py_ssize_t* base_l,
                         const Py_ssize_t* base_r, const float* u8, const float* t8,
                         Py_ssize_t rx, Py_ssize_t ry, Py_ssize_t width,
                         float* res, float nv, float nvf, float nfr) noexcept nogil:
    """Eight unclipped blocks side by side: lane j's left block starts at flat index
    ``base_l[j]`` of ``gl``, its right samples at ``base_r[j]`` of ``gr`` (weights
    ``u8[j]``, ``t8[j]``); the eight correlations into ``res``."""
    cdef float sums[40]
    cdef float a, b, n, rn, ne
    cdef Py_ssize_t j, i, k, k0
    if ZNCC_LANES:
        zncc_lanes8_sums(gl, gr, base_l, base_r, u8, t8, rx, ry, width, sums)
        # the eight finishes in vector lanes, bit for bit those of finish() (the scalar
        # divisions and roots were a third of the cross-support test's time)
        n = <float>((2 * rx + 1) * (2 * ry + 1))
        rn = 1.0 / n
        ne = nv * n - nvf
        zncc_finish8(sums, rn, FLAT_ZNCC, nfr * ne if ne > 0 else 0.0,
                     ne * noise_bound(ne, nvf) if ne > 0 else 0.0, res)
        return
    else:
        for k in range(40):
            sums[k] = 0.0
        for j in range(2 * ry + 1):
            for i in range(2 * rx + 1):
                k0 = j * width + i
                for k in range(8):
                    a = gl[base_l[k] + k0]
                    b = fmaf(u8[k], gr[base_r[k] + k0], t8[k] * gr[base_r[k] + k0 + 1])
                    sums[k] = sums[k] + a
                    sums[8 + k] = sums[8 + k] + b
                    sums[16 + k] = fmaf(a, a, sums[16 + k])
                    sums[24 + k] = fmaf(b, b, sums[24 + k])
                    sums[32 + k] = fmaf(a, b, sums[32 + k])
    k0 = (2 * rx + 1) * (2 * ry + 1)
    for k in range(8):
        res[k] = finish(sums[k], sums[8 + k], sums[16 + k], sums[24 + k], sums[32 + k], k0,
                        nv, nvf, nfr)


cdef inline void _flush(const float* gl, const float* gr, Py_ssize_t* base_l,
                        Py_ssize_t* base_r, float* u8, float* t8, const Py_ssize_t* idx,
                        Py_ssize_t lanes, Py_ssize_t rx, Py_ssize_t ry, Py_ssize_t width,
                        float* out, float nv, float nvf, float nfr) noexcept nogil:
    cdef float res[8]
    cdef Py_ssize_t j
    for j in range(lanes, 8):   # unused lanes repeat lane 0 (valid addresses)
        base_l[j] = base_l[0]
        base_r[j] = base_r[0]
        u8[j] = u8[0]
        t8[j] = t8[0]
    _lanes8(gl, gr, base_l, base_r, u8, t8, rx, ry, width, res, nv, nvf, nfr)
    for j in range(lanes):
        out[idx[j]] = res[j]


cdef inline void zncc_blocks(const float* gl, const float* gr, Py_ssize_t height,
                             Py_ssize_t width, const Py_ssize_t* yc, const Py_ssize_t* xc,
                             const float* d, Py_ssize_t n, Py_ssize_t rx, Py_ssize_t ry,
                             float* out, float nv, float nvf, float nfr) noexcept nogil:
    """``out[i] = zncc_block(gl, gr, height, width, yc[i], xc[i], d[i], rx, ry)`` for
    i < n, bit for bit; blocks inside the image eight at a time."""
    cdef Py_ssize_t base_l[8]
    cdef Py_ssize_t base_r[8]
    cdef float u8[8]
    cdef float t8[8]
    cdef Py_ssize_t idx[8]
    cdef Py_ssize_t lanes = 0, i, off, x0, y0
    cdef float di, t
    for i in range(n):
        di = d[i]
        off = <Py_ssize_t>floorf(-di)
        x0 = xc[i] - rx
        y0 = yc[i] - ry
        if not (y0 >= 0 and yc[i] + ry < height and x0 >= 0 and x0 + off >= 0
                and xc[i] + rx <= width - 2 - off and xc[i] + rx <= width - 1):
            out[i] = zncc_block(gl, gr, height, width, yc[i], xc[i], di, rx, ry, nv, nvf, nfr)
            continue
        t = -di - <float>off
        base_l[lanes] = y0 * width + x0
        base_r[lanes] = y0 * width + x0 + off
        t8[lanes] = t
        u8[lanes] = 1.0 - t
        idx[lanes] = i
        lanes += 1
        if lanes == 8:
            _flush(gl, gr, base_l, base_r, u8, t8, idx, lanes, rx, ry, width, out, nv, nvf, nfr)
            lanes = 0
    if lanes:
        _flush(gl, gr, base_l, base_r, u8, t8, idx, lanes, rx, ry, width, out, nv, nvf, nfr)
