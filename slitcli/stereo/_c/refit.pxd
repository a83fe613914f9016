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
    static inline void slitcli_refit_row(float *restrict d, const uint16_t *restrict c,
                                         const uint8_t *restrict where, Py_ssize_t width,
                                         Py_ssize_t num, Py_ssize_t dmin, double den_min,
                                         double top) {
        float hi = (float)num - (float)1.5;
        for (Py_ssize_t x = 0; x < width; x++) {
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
