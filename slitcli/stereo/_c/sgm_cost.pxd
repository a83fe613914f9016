"""The cost rows of semi-global aggregation (slitcli/stereo/_c/sgm.pyx: cost_rows and the
fused top-down pass), one row at a time: the fronto-parallel window's column sums slid
down the image and the quantised Eq. 10 costs from them; below the horizon, with a
window sheared by the ground's disparity gradient (slitcli.stereo.cost.
ground_window_shifts), the same for a block of disparities around the ground's, whose
smaller costs are taken (the second hypothesis). What the rows read is a
:c:type:`CostIn` (sgm.pyx: _cost_in, _shear_in).
"""

from libc.math cimport ceilf, floorf, sqrtf
from libc.stdint cimport uint16_t

from slitcli.stereo._c.sgm_loops cimport (
    HAVE_COSTS16,
    column_slide,
    cost_pixels16,
    min_u16,
    pixel_costs,
    slide_columns16,
)


cdef enum:
    # most row groups of a sheared window (2 x the largest shift + 1)
    MAX_GROUPS = 15


cdef struct CostIn:
    # what the cost rows read (see cost_rows)
    const float *pl
    const float *prr
    const float *el
    const float *err
    const float *irr
    Py_ssize_t height, width, stride, pad, dmin, num, m, n
    float c_max, scale
    uint16_t top
    # the window sheared by the ground's disparity gradient (see _shear_in): rows
    # >= horizon; groups of window rows lo..hi (offsets from the centre row) whose
    # right samples are shifted by shift px; the sheared right energies err_s, irr_s
    Py_ssize_t groups, horizon
    Py_ssize_t g_shift[MAX_GROUPS]
    Py_ssize_t g_lo[MAX_GROUPS]
    Py_ssize_t g_hi[MAX_GROUPS]
    const float *err_s
    const float *irr_s
    # the sheared window's cost is a second hypothesis for disparities within band px
    # of the ground's (grad (y - horizon_px)): the smaller of both costs is kept
    float grad, horizon_px, band
    Py_ssize_t nb


cdef inline bint _sheared(const CostIn *c, Py_ssize_t y) noexcept nogil:
    return c.groups > 1 and y >= c.horizon


cdef inline void _sheared_slide(const CostIn *c, Py_ssize_t y, Py_ssize_t j0, float *col,
                         bint fresh) noexcept nogil:
    """The sheared window's column sums of the ``c.nb`` disparities from index ``j0``
    ((W + 1) x nb) slid from row y - 1 to row y: each row group (window rows lo..hi,
    right samples shifted by its shift) takes in its row y + hi and lets go of row
    y + lo - 1 (whole numbers below 2^24: exact in any order); ``fresh``: summed from
    zeros at row y."""
    cdef Py_ssize_t width = c.width, nb = c.nb, height = c.height, x, r, k, base, off
    cdef Py_ssize_t ya, ys
    cdef bint a_in, s_in
    cdef bint lanes = HAVE_COSTS16 and nb % 16 == 0
    cdef float a, b
    if fresh:
        for x in range((width + 1) * nb):
            col[x] = 0.0
        for k in range(c.groups):
            off = c.pad + width - 1 + c.dmin + j0 + c.g_shift[k]
            for r in range(max(0, y + c.g_lo[k]), min(height, y + c.g_hi[k] + 1)):
                for x in range(width):
                    base = r * c.stride + off - x
                    column_slide(col + (x + 1) * nb, c.prr + base, c.prr + base,
                                 c.pl[r * width + x], 0.0, nb)
        return
    for k in range(c.groups):
        off = c.pad + width - 1 + c.dmin + j0 + c.g_shift[k]
        ya = y + c.g_hi[k]
        ys = y + c.g_lo[k] - 1
        a_in = 0 <= ya < height
        s_in = 0 <= ys < height
        if not (a_in or s_in):
            continue
        if lanes:
            slide_columns16(col, c.pl + ya * width if a_in else NULL,
                            c.pl + ys * width if s_in else NULL,
                            c.prr + min(max(ya, 0), height - 1) * c.stride + off,
                            c.prr + min(max(ys, 0), height - 1) * c.stride + off, width, nb)
            continue
        for x in range(width):
            a = c.pl[ya * width + x] if a_in else <float>0.0
            b = c.pl[ys * width + x] if s_in else <float>0.0
            column_slide(col + (x + 1) * nb,
                         c.prr + min(max(ya, 0), height - 1) * c.stride + off - x,
                         c.prr + min(max(ys, 0), height - 1) * c.stride + off - x, a, b, nb)


cdef inline void _sheared_row(const CostIn *c, Py_ssize_t y, float *col, float *hs,
                       uint16_t *o_row) noexcept nogil:
    """Row ``y``'s costs ``o_row`` (W x D) become the smaller of theirs and the sheared
    window's where the candidate disparity lies within ``band`` px of the ground's at
    this row: ground is expected there, and only there. Elsewhere (an object standing
    on the ground: nearer than the ground at its rows) the fronto-parallel window
    stays, which the sheared one would misregister by up to its largest shift.

    Only ``c.nb`` disparities from index ``j0`` are computed (a block holding the
    band, kept while the band stays inside it: the ground's disparity grows by
    ``grad`` per row). ``col``'s blocks (:func:`cost_columns`): 1 the sheared sums
    ((W + 1) x nb), 2 a W x nb uint16 scratch row, 3 the current ``j0`` (-1: none,
    the sums to be summed anew)."""
    cdef Py_ssize_t size = (c.width + 1) * c.num, nb = c.nb, x
    cdef float *state = col + 3 * size
    cdef uint16_t *tmp = <uint16_t *>(col + 2 * size)
    cdef float ground = c.grad * (<float>y - c.horizon_px)
    # the band's disparity indices, clamped in float (an infinite band: all of them)
    cdef float lo = ceilf(ground - c.band) - <float>c.dmin
    cdef float hi = floorf(ground + c.band) - <float>c.dmin
    cdef Py_ssize_t i0 = 0 if lo <= 0 else (<Py_ssize_t>lo if lo < c.num else c.num)
    cdef Py_ssize_t i1 = c.num - 1 if hi >= c.num - 1 else (<Py_ssize_t>hi if hi >= 0 else -1)
    cdef Py_ssize_t j0 = <Py_ssize_t>state[0]
    cdef bint fresh = j0 < 0 or i0 < j0 or i1 >= j0 + nb
    if i1 < i0:
        state[0] = -1.0
        return
    if fresh:
        j0 = min(i0, c.num - nb)
        state[0] = <float>j0
    _sheared_slide(c, y, j0, col + size, fresh)
    _costs_from_columns(c, y, col + size, hs, c.err_s, c.irr_s, j0, nb, tmp)
    for x in range(c.width):
        min_u16(o_row + x * c.num + i0, tmp + x * nb + i0 - j0, i1 - i0 + 1)


cdef inline void _cost_start(const CostIn *c, Py_ssize_t y0, float *col) noexcept nogil:
    """The vertical window sums of the cross term at row ``y0 - 1`` (rows y0-1-n ..
    y0-1+n) into ``col`` ((W + 1) x D, row 0 the zero column)."""
    cdef Py_ssize_t yy, x
    cdef const float *ra
    for yy in range(max(0, y0 - 1 - c.n), min(c.height, y0 + c.n)):
        for x in range(c.width):
            ra = c.prr + yy * c.stride + c.pad + c.width - 1 - x + c.dmin
            column_slide(col + (x + 1) * c.num, ra, ra, c.pl[yy * c.width + x], 0.0, c.num)
    if c.groups > 1:
        col[3 * (c.width + 1) * c.num] = -1.0   # no band block yet


cdef inline void _cost_row(const CostIn *c, Py_ssize_t y, float *col, float *hs,
                    uint16_t *o_row) noexcept nogil:
    """Row ``y`` of the quantised costs into ``o_row`` (W x D), the column sums ``col``
    slid one row down first; below the horizon with a sheared window (``c.groups`` >
    1) the sheared window's cost is the second hypothesis near the ground's disparity
    (_sheared_row)."""
    _plain_slide(c, y, col)
    _costs_from_columns(c, y, col, hs, c.err, c.irr, 0, c.num, o_row)
    if _sheared(c, y):
        _sheared_row(c, y, col, hs, o_row)


cdef inline void _plain_slide(const CostIn *c, Py_ssize_t y, float *col) noexcept nogil:
    """The fronto-parallel window's column sums ``col`` slid from row y - 1 to y."""
    cdef Py_ssize_t width = c.width, num = c.num, height = c.height
    cdef Py_ssize_t ya = y + c.n, ys = y - c.n - 1, x, base, k
    cdef float a, b
    cdef bint lanes = HAVE_COSTS16 and num % 16 == 0 and c.c_max * c.scale < 60000
    if lanes and (ya < height or ys >= 0):
        k = c.pad + width - 1 + c.dmin
        slide_columns16(col, c.pl + ya * width if ya < height else NULL,
                        c.pl + ys * width if ys >= 0 else NULL,
                        c.prr + min(ya, height - 1) * c.stride + k,
                        c.prr + max(ys, 0) * c.stride + k, width, num)
    elif ya < height or ys >= 0:
        for x in range(width):
            base = c.pad + width - 1 - x + c.dmin
            a = c.pl[ya * width + x] if ya < height else <float>0.0
            b = c.pl[ys * width + x] if ys >= 0 else <float>0.0
            column_slide(col + (x + 1) * num, c.prr + min(ya, height - 1) * c.stride + base,
                         c.prr + max(ys, 0) * c.stride + base, a, b, num)


cdef inline void _costs_from_columns(const CostIn *c, Py_ssize_t y, const float *col, float *hs,
                              const float *err, const float *irr, Py_ssize_t j0,
                              Py_ssize_t num, uint16_t *o_row) noexcept nogil:
    """Row ``y``'s quantised costs of the ``num`` disparities from index ``j0`` into
    ``o_row`` (W x num) from the column sums ``col`` ((W + 1) x num, slid along the
    row) and the right energies ``err``, ``irr`` (layout of ``err_pad``)."""
    cdef Py_ssize_t width = c.width, x, xx, xa, xs, i, k
    cdef float wa, ws, e1, r1
    # the AVX2 lanes (pixel_costs16) where D is a multiple of 16 and every cost packs
    # into uint16 unchanged
    cdef bint lanes = HAVE_COSTS16 and num % 16 == 0 and c.c_max * c.scale < 60000
    for i in range(num):
        hs[i] = 0.0
    for xx in range(min(c.m, width)):
        for i in range(num):
            hs[i] += col[(xx + 1) * num + i]
    if lanes:
        k = y * c.stride + c.pad + width - 1 + c.dmin + j0
        cost_pixels16(hs, col, c.el + y * width, err + k, irr + k, width, num, c.m, c.top,
                      c.scale, c.c_max, o_row)
        return
    for x in range(width):
        xa = x + c.m
        xs = x - c.m - 1
        wa = <float>1.0 if xa < width else <float>0.0
        ws = <float>1.0 if xs >= 0 else <float>0.0
        e1 = c.el[y * width + x]
        r1 = <float>1.0 / sqrtf(e1) if e1 > 0 else <float>0.0
        k = y * c.stride + c.pad + width - 1 - x + c.dmin + j0
        pixel_costs(hs, col + (min(xa, width - 1) + 1) * num, col + (max(xs, -1) + 1) * num,
                    wa, ws, e1, r1, err + k, irr + k, c.top, c.scale, c.c_max,
                    o_row + x * num, num)
