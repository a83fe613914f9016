"""The winner step of semi-global aggregation (slitcli/stereo/_c/sgm.pyx: winners_rows
and the fused bottom-up pass), one row at a time: winner-take-all over the sum of the
two sweeps with the tests that need the whole cost curve (texture energy, uniqueness,
left-right consistency from the same sums) and the subpixel parabola.

Two forms with the same results: int32 keys ``(s_a + s_b) << 9 | i`` (any D, any
build) and, with AVX2 and D a multiple of 16, uint16 sums in 16 lanes
(sgm_winner_loops.pxd: winners16_row), whose minimum and first index are the smallest key's.
"""

from libc.stdint cimport int32_t, uint8_t, uint16_t
from libc.stdlib cimport llabs

from slitcli.stereo._c.sgm_loops cimport KEY_SHIFT, NO_KEY
from slitcli.stereo._c.sgm_winner_loops cimport (
    HAVE_LANES16,
    NO_SUM_KEY,
    lower_keys,
    lower_sums16,
    pixel_keys,
    second_key,
    winners16_row,
)

cdef extern from "math.h":
    const float NAN
    const float INFINITY


cdef struct Tests:
    # the winner step's parameters (see winners_rows) and row buffers: keys (W x D),
    # the right view's keys (W + 2 pad), the winners (W)
    Py_ssize_t dmin
    float uniq
    double lr_tol
    bint subpixel
    float energy_min
    uint16_t top
    float scale
    int32_t *keys
    int32_t *rkey
    int32_t *best_i
    # the reason codes (slitcli.stereo.reasons.Reason) the step writes
    int r_valid, r_none, r_texture, r_uniq, r_lr


cdef inline float _subpixel(const Tests *t, Py_ssize_t bi, Py_ssize_t num, float bv,
                            bint has_m, bint has_p, float cm, float cp) noexcept nogil:
    """The parabola's offset through the sums at bi - 1, bi, bi + 1 (0 at the ends of
    the range, where a neighbour has no candidate, or without a minimum)."""
    cdef float den
    if t.subpixel and 0 < bi < num - 1 and has_m and has_p:
        den = cm - <float>2.0 * bv + cp
        if den > 0:
            return <float>0.5 * (cm - cp) / den
    return 0.0


cdef inline int _codes(const Tests *t, Py_ssize_t x, float bv, bint has_second, float sv,
                       const float *el, const float *count) noexcept nogil:
    """The texture and uniqueness codes (uniqueness + 100: it overrides left-right)."""
    cdef int code = t.r_valid
    if t.energy_min > 0 and el[x] < t.energy_min * count[x]:
        code = t.r_texture
    if t.uniq > 0 and has_second and sv < bv * (<float>1.0 + t.uniq):
        code = t.r_uniq + 100
    return code


cdef inline void _no_candidate(const Tests *t, Py_ssize_t x, float *disp, float *mcost,
                               uint8_t *reason) noexcept nogil:
    t.best_i[x] = -1
    disp[x] = NAN
    mcost[x] = INFINITY
    reason[x] = t.r_none


cdef inline void _winners32(const Tests *t, const uint16_t *sa, const uint16_t *sb,
                     const uint16_t *c, const float *el, const float *count,
                     Py_ssize_t width, Py_ssize_t num, float *disp, float *mcost,
                     uint8_t *reason) noexcept nogil:
    """Winners of one row from int32 keys ``(s_a + s_b) << 9 | i`` (any sums), the right
    view's keys lowered into ``t.rkey``."""
    cdef Py_ssize_t dmin = t.dmin, pad = num + llabs(t.dmin) + 1, x, x0, base, bi
    cdef int32_t *keys = t.keys
    cdef int32_t best, km, kp, sk = NO_KEY, imask = (1 << KEY_SHIFT) - 1
    cdef float bv
    for x in range(width):
        base = x * num
        best = pixel_keys(sa + base, sb + base, c + base, keys + base, t.top, num)
        if best == NO_KEY:
            _no_candidate(t, x, disp, mcost, reason)
            continue
        bi = best & imask
        t.best_i[x] = bi
        bv = <float>(best >> KEY_SHIFT)
        km = keys[base + bi - 1] if bi > 0 else NO_KEY
        kp = keys[base + bi + 1] if bi < num - 1 else NO_KEY
        disp[x] = <float>(dmin + bi) + _subpixel(t, bi, num, bv, km != NO_KEY,
                                                  kp != NO_KEY, <float>(km >> KEY_SHIFT),
                                                  <float>(kp >> KEY_SHIFT))
        mcost[x] = <float>c[base + bi] / t.scale
        if t.uniq > 0:
            sk = second_key(keys + base, bi - 1, bi + 1, num)
        reason[x] = _codes(t, x, bv, sk != NO_KEY, <float>(sk >> KEY_SHIFT), el, count)
    # the right view: pixel x's keys lower the right pixels x - d, windows one element
    # apart for neighbouring x; taken 16 columns apart, so that no vector load waits
    # for an overlapping store just before it
    for x0 in range(16):
        for x in range(x0, width, 16):
            lower_keys(t.rkey + pad + width - 1 - x + dmin, keys + x * num, num)


cdef inline bint _winners16(const Tests *t, const uint16_t *sa, const uint16_t *sb,
                     const uint16_t *c, const float *el, const float *count,
                     Py_ssize_t width, Py_ssize_t num, float *disp, float *mcost,
                     uint8_t *reason) noexcept nogil:
    """:func:`_winners32` in uint16 lanes (AVX2, D a multiple of 16): the sums, their
    minimum, its first index and the smallest sum outside it in 16 lanes
    (sgm_winner_loops.pxd: winners16_row), the right view's keys made from the sums. The same
    winners, parabolas and codes (the minimum sum and its first index are the smallest
    key's). False (nothing usable written) where a sum reaches NO_SUM, which the
    sweeps' sums never do (at most 8 (top + P2) for 8 paths)."""
    cdef Py_ssize_t dmin = t.dmin, pad = num + llabs(t.dmin) + 1, x, x0
    cdef uint16_t *s16 = <uint16_t *>t.keys
    if not winners16_row(sa, sb, c, el, count, width, num, dmin, t.subpixel, t.uniq,
                         t.energy_min, t.top, t.scale, s16, t.best_i, disp, mcost, reason,
                         t.r_valid, t.r_none, t.r_texture, t.r_uniq):
        return False
    for x0 in range(16):
        for x in range(x0, width, 16):
            lower_sums16(t.rkey + pad + width - 1 - x + dmin, s16 + x * num, num)
    return True


cdef inline void winner_row(const Tests *t, const uint16_t *sa, const uint16_t *sb,
                     const uint16_t *c, const float *el, const float *count,
                     Py_ssize_t width, Py_ssize_t num, float *disp, float *mcost,
                     uint8_t *reason, float *rdisp) noexcept nogil:
    """One row of :func:`winners_rows`: ``sa``, ``sb``, ``c`` the row's W x D sums and
    costs, the outputs the row's (W,) arrays."""
    cdef Py_ssize_t dmin = t.dmin, pad = num + llabs(t.dmin) + 1, x, xr, bi
    cdef int32_t *rkey = t.rkey
    cdef int32_t k, none = NO_KEY, imask = (1 << KEY_SHIFT) - 1
    cdef int code
    cdef bint ok
    for x in range(width + 2 * pad):
        rkey[x] = NO_KEY
    if HAVE_LANES16 and num % 16 == 0 and _winners16(t, sa, sb, c, el, count, width, num,
                                                     disp, mcost, reason):
        none = NO_SUM_KEY   # keys of sums without a candidate lie at or above it
    else:
        _winners32(t, sa, sb, c, el, count, width, num, disp, mcost, reason)
    for xr in range(width):
        k = rkey[pad + width - 1 - xr]
        rdisp[xr] = <float>(dmin + (k & imask)) if k < none else NAN
    for x in range(width):
        bi = t.best_i[x]
        if bi < 0:
            continue
        code = reason[x]
        if code >= 100:
            reason[x] = code - 100
            continue
        if t.lr_tol >= 0:
            xr = x - dmin - bi
            ok = (xr >= 0) and (xr < width)
            if ok:
                k = rkey[pad + width - 1 - xr]
                ok = k < none and <double>llabs((k & imask) - bi) <= t.lr_tol
            if not ok:
                reason[x] = t.r_lr
