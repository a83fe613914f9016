# cflags: -fno-math-errno -fno-trapping-math -funroll-loops
# (value-preserving: sqrtf need not set errno and no operation traps, so the per-pixel
# loops vectorise; no reassociation, no contraction: every cost keeps its bits)
"""Compiled kernels of semi-global aggregation (Hirschmueller's SGM) over the Eq. 10 cost.

- :func:`window_inputs`: left window energies and pixel counts, the right image's rows
  reversed and padded with its window energies and their inverse square roots (with
  :func:`sheared_energies`, in slitcli/stereo/_c/sgm_inputs.pyx, re-exported here);
- :func:`cost_rows`: the Eq. 10 normalised cost ``C = (E_l + E_r - 2 X) / sqrt(E_l E_r)``
  of every pixel and disparity (window sums of the prefiltered images, zeros outside
  the image), quantised to ``round(min(C, c_max) scale)`` in a uint16 volume (H, W, D);
  a candidate whose partner leaves the right image or whose window has no energy costs
  ``c_max scale``; below the horizon, for the disparities near the ground's, the
  smaller of that and the cost over a window sheared by the ground's disparity
  gradient (``shear``; the rows in sgm_cost.pxd, :func:`sheared_energies` the
  sheared windows' right energies);
- :func:`aggregate_pass`: the sum of the path costs ``L_r(p, d) = C(p, d) + min(L_r(p-r,
  d), L_r(p-r, d+-1) + P1, min_k L_r(p-r, k) + P2) - min_k L_r(p-r, k)`` of one sweep
  over the rows: top-down (left to right, top, and with 8 paths top-left and
  top-right) or bottom-up (the same on the image turned by 180 degrees);
- :func:`winners_rows`: winner-take-all over the sum of both sweeps with the tests that
  need the whole cost curve (texture energy, uniqueness, left-right consistency from
  the same sums) and the subpixel parabola;
- the fused passes of slitcli.stereo.sgm._match_fused (:func:`cost_and_first_sweep`,
  :func:`second_sweep_winners` and their row-range pieces for two threads): each
  row's costs with the top-down sweep over it while it is in cache, then the bottom-up
  sweep with each row's winner step, its sums kept for one row only.

Every kernel releases the GIL (slitcli.stereo.sgm calls them from row-band threads)
and works for any disparity count D >= 2; the per-pixel loops (sgm_loops.pxd) are
vectorised by the compiler, and with AVX2 and D a multiple of 16 whole rows run in
explicit 16-lane C functions (sgm_loops.pxd), with a constant P2 or one adapted to
each step's grey levels (a scalar per pixel and path, from a table of the 256 steps). The results do not depend on D's
divisibility, on the processor, on the bands or on the fusion: the same integer and
float operations in the same order.
"""

from libc.math cimport fabsf, rint
from libc.stdint cimport int16_t, int32_t, int64_t, uint8_t, uint16_t

from slitcli.stereo._c.sgm_cost cimport (
    MAX_GROUPS,
    CostIn,
    _cost_row,
    _cost_start,
)
from slitcli.stereo._c.sgm_loops cimport (
    HAVE_COSTS16,
    HAVE_ROW4,
    SENTINEL,
    path_pair,
    sweep_row4,
    sweep_row8,
)
from slitcli.stereo._c.refit cimport refit_row
from slitcli.stereo._c.sgm_winner cimport Tests, winner_row

import numpy as np

# the cost kernels' inputs (slitcli/stereo/_c/sgm_inputs.pyx), exported here as before
from slitcli.stereo._c.sgm_inputs import sheared_energies, window_inputs
from slitcli.stereo.reasons import Reason

cdef int R_VALID = int(Reason.VALID)
cdef int R_NO_CANDIDATE = int(Reason.NO_CANDIDATE)
cdef int R_TEXTURE = int(Reason.TEXTURE)
cdef int R_UNIQUENESS = int(Reason.UNIQUENESS)
cdef int R_LEFT_RIGHT = int(Reason.LEFT_RIGHT)


cdef CostIn _cost_in(const float[:, ::1] pl, const float[:, ::1] prr_pad,
                     const float[:, ::1] el, const float[:, ::1] err_pad,
                     const float[:, ::1] irr_pad, Py_ssize_t pad, Py_ssize_t dmin,
                     Py_ssize_t num, Py_ssize_t m, Py_ssize_t n, double c_max, double scale):
    cdef CostIn c
    c.pl = &pl[0, 0]
    c.prr = &prr_pad[0, 0]
    c.el = &el[0, 0]
    c.err = &err_pad[0, 0]
    c.irr = &irr_pad[0, 0]
    c.height = pl.shape[0]
    c.width = pl.shape[1]
    c.stride = prr_pad.shape[1]
    c.pad = pad
    c.dmin = dmin
    c.num = num
    c.m = m
    c.n = n
    c.c_max = <float>c_max
    c.scale = <float>scale
    c.top = <uint16_t>rint(c_max * scale)   # numba's round(): half to even
    c.groups = 1
    c.horizon = c.height
    c.err_s = NULL
    c.irr_s = NULL
    return c


cdef void _shear_in(CostIn *c, object shear) except *:
    """Fill ``c``'s sheared window from ``shear`` (None: fronto-parallel windows
    everywhere): ``(horizon_row, shifts, err_s, irr_s)`` with ``shifts`` (2n + 1,)
    int64 the right column shift of window rows -n..n (non-decreasing), ``err_s``,
    ``irr_s`` (H, W + 2 pad) float32 the sheared windows' right energies and their
    inverse square roots, laid out as ``err_pad`` (:func:`cost_rows`)."""
    cdef const int64_t[::1] shifts
    cdef const float[:, ::1] e
    cdef const float[:, ::1] r
    cdef Py_ssize_t k = 0, dv
    if shear is None:
        return
    horizon, shifts, e, r, grad, horizon_px, band = shear
    if shifts.shape[0] != 2 * c.n + 1 or e.shape[0] != c.height or e.shape[1] != c.stride \
            or r.shape[0] != c.height or r.shape[1] != c.stride:
        raise ValueError("shear: shifts, err_s or irr_s do not fit the window and image")
    c.g_shift[0] = shifts[0]
    c.g_lo[0] = -c.n
    for dv in range(1, 2 * c.n + 1):
        if shifts[dv] != shifts[dv - 1]:
            c.g_hi[k] = dv - 1 - c.n
            k += 1
            if k >= MAX_GROUPS:
                raise ValueError(f"shear: more than {MAX_GROUPS} row groups")
            c.g_shift[k] = shifts[dv]
            c.g_lo[k] = dv - c.n
    c.g_hi[k] = c.n
    for dv in range(k + 1):
        if abs(c.g_shift[dv]) + c.num + abs(c.dmin) + 1 > c.pad:
            raise ValueError("shear: the padding does not hold the shifted windows")
    c.groups = k + 1
    c.horizon = max(0, min(<Py_ssize_t>horizon, c.height))
    c.err_s = &e[0, 0]
    c.irr_s = &r[0, 0]
    c.grad = grad
    c.horizon_px = horizon_px
    c.band = band
    # the block of disparities computed with the sheared window: the band's (at most
    # 2 band + 1 whole disparities) with one to spare, whole 16-lane vectors where
    # the rows run in them
    c.nb = min(c.num, <Py_ssize_t>(2 * min(c.band, <float>c.num)) + 2)
    if HAVE_COSTS16 and c.num % 16 == 0:
        c.nb = min(c.num, 16 * ((c.nb + 15) // 16))


def cost_columns(Py_ssize_t width, Py_ssize_t num, object shear):
    """The cost rows' column sums, zeros: (W + 1, D) float32; with a sheared window
    (``shear``, :func:`cost_rows`) (W + 1, D) blocks for the fronto-parallel sums, the
    sheared sums, a scratch row of sheared costs and the state of the block of
    disparities they cover (_sheared_row)."""
    cdef Py_ssize_t blocks = 1
    if shear is not None:
        blocks += 3
    return np.zeros((blocks * (width + 1), num), np.float32)


cdef void _check_columns(const CostIn *c, float[:, ::1] col) except *:
    if col.shape[1] != c.num or col.shape[0] < (4 if c.groups > 1 else 1) * (c.width + 1):
        raise ValueError("col: too small for the window's row groups (cost_columns)")


def cost_start(const float[:, ::1] pl, const float[:, ::1] prr_pad, Py_ssize_t pad,
               Py_ssize_t dmin, Py_ssize_t num, Py_ssize_t n, Py_ssize_t y0,
               float[:, ::1] col, object shear=None):
    """The vertical window sums of the cross term at row ``y0 - 1`` into ``col``
    (:func:`cost_columns`, zeros on entry): the state :func:`first_sweep_rows` starts
    from."""
    cdef CostIn c = _cost_in(pl, prr_pad, pl, prr_pad, prr_pad, pad, dmin, num, 0, n,
                             2.0, 1.0)
    _shear_in(&c, shear)
    _check_columns(&c, col)
    with nogil:
        _cost_start(&c, y0, &col[0, 0])


def cost_rows(const float[:, ::1] pl, const float[:, ::1] prr_pad, const float[:, ::1] el,
              const float[:, ::1] err_pad, const float[:, ::1] irr_pad, Py_ssize_t pad,
              Py_ssize_t dmin, Py_ssize_t num, Py_ssize_t m, Py_ssize_t n, double c_max,
              double scale, Py_ssize_t y0, Py_ssize_t y1, uint16_t[:, :, ::1] out,
              object shear=None):
    """Quantised Eq. 10 costs of rows y0..y1-1 into ``out`` (H, W, D) uint16.

    ``pl``: (H, W) float32 prefiltered left image; ``prr_pad``: (H, W + 2 pad) the
    prefiltered right image reversed along x, with ``pad`` zero columns each side, so
    right column ``x - d`` is ``prr_pad[:, pad + W - 1 - x + d]`` and the disparities of
    a pixel are contiguous; ``el``: (H, W) left window energies; ``err_pad``,
    ``irr_pad``: (H, W + 2 pad) the right window energies and their inverse square
    roots, reversed and padded likewise (0 where the window has no energy or the centre
    is outside the image). (2m+1) x (2n+1) windows, D = ``num`` from ``dmin``.

    ``shear``: None, or the window sheared by the ground plane's disparity gradient in
    the rows from ``horizon_row`` down, ``(horizon_row, shifts, err_s, irr_s)``: window
    row ``dv`` (-n..n) compares the left row ``y + dv`` with the right row shifted by
    ``shifts[dv + n]`` px more (the ground's disparity there is that much larger), so
    a pixel's right partner ``x - d`` stays the window's centre; ``err_s``, ``irr_s``
    the sheared windows' right energies (and inverse roots), laid out as ``err_pad``.
    ``pad`` must hold the largest shift too.
    """
    cdef CostIn c = _cost_in(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n,
                             c_max, scale)
    _shear_in(&c, shear)
    cdef float[:, ::1] col = cost_columns(c.width, num, shear)
    cdef float[::1] hs = np.zeros(num, np.float32)
    cdef Py_ssize_t y
    with nogil:
        _cost_start(&c, y0, &col[0, 0])
        for y in range(y0, y1):
            _cost_row(&c, y, &col[0, 0], &hs[0], &out[y, 0, 0])


def sweep_state(Py_ssize_t width, Py_ssize_t num):
    """A sweep's state: its path rows (6 W + 3, D + 2) int16 (rows of the vertical,
    the two diagonal paths for the previous and the current image row, the horizontal
    path's two, and a path's first previous row: zeros), all sentinels but the zeros,
    and the path minima (3, 2, W) int32."""
    paths = np.full((6 * width + 3, num + 2), SENTINEL, np.int16)
    paths[6 * width + 2, 1:num + 1] = 0
    return paths, np.zeros((3, 2, width), np.int32)


cdef inline int32_t _p2(int32_t p1, int32_t p2, float g, uint8_t a,
                        uint8_t b) noexcept nogil:
    """P2 for a step between two pixels of grey levels a and b: ``P2 g / (g + |a - b|)``
    (Hirschmueller: a disparity jump is likelier across an intensity edge), at least
    P1 + 1; ``g`` <= 0: P2 itself. (int times float32 is float64, as in numpy.)"""
    if g <= 0:
        return p2
    cdef int32_t q = <int32_t>(<double>p2 * <double>g
                               / <double>(g + fabsf(<float>a - <float>b)))
    return q if q > p1 + 1 else p1 + 1


cdef const int32_t *_p2_steps(int32_t p1, int32_t p2, float g,
                              int32_t *table) noexcept nogil:
    """P2 of every grey step ``a - b`` (-255..255) into ``table`` (511 entries): the
    returned pointer to its middle gives ``_p2(p1, p2, g, a, b)`` at ``[a - b]`` (the
    float32 ``a - b`` of two uint8 levels is exact, so ``_p2`` depends on ``|a - b|``
    alone and the table gives its very bits); NULL for ``g`` <= 0 (a constant P2). One
    division per level instead of one per pixel and path, and signed steps: no branch
    on the sign (with one, random grey levels cost a mispredicted jump per step)."""
    cdef int32_t k
    if g <= 0:
        return NULL
    for k in range(256):
        table[255 + k] = _p2(p1, p2, g, <uint8_t>k, 0)
        table[255 - k] = table[255 + k]
    return table + 255


cdef inline int32_t _step_p2(const int32_t *p2_step, uint8_t a, uint8_t b) noexcept nogil:
    return p2_step[<int32_t>a - <int32_t>b]


cdef void sweep_row(const int16_t *c_row, int16_t *o_row, const uint8_t *grey,
                    Py_ssize_t width, Py_ssize_t num, Py_ssize_t y, Py_ssize_t yy,
                    Py_ssize_t ys, bint reverse, int32_t p1, int32_t p2,
                    const int32_t *p2_step, bint eight, int16_t *paths,
                    int32_t *mins) noexcept nogil:
    """One row of a sweep (the ``y``-th row visited: image row ``yy``, its vertical
    paths coming from row ``ys``): path rows carried in ``paths`` and their minima in
    ``mins`` (:func:`sweep_state`); the row's path sum into ``o_row`` (W x D).
    ``p2_step``: P2 of each grey step (:func:`_p2_steps`), NULL for a constant P2."""
    cdef Py_ssize_t stride = num + 2, x, xx, xs, src = y & 1, dst = 1 - (y & 1), hs
    cdef int16_t *pv = paths
    cdef int16_t *pd = paths + 2 * width * stride
    cdef int16_t *pe = paths + 4 * width * stride
    cdef int16_t *ph = paths + 6 * width * stride
    cdef const int16_t *zero = paths + (6 * width + 2) * stride
    cdef int32_t *mv = mins
    cdef int32_t *md = mins + 2 * width
    cdef int32_t *me = mins + 4 * width
    cdef const int16_t *c
    cdef const int16_t *prev_a
    cdef const int16_t *prev_b
    cdef int16_t *o
    cdef int32_t hmin = 0, ma, mb, p2a, p2b
    cdef bint adapt = p2_step != NULL, first, last
    cdef const uint8_t *row = grey + yy * width
    cdef const uint8_t *above = grey + ys * width
    if HAVE_ROW4 and num % 16 == 0:
        if eight:
            sweep_row8(c_row, o_row, width, num, reverse, y == 0, p1, p2, p2_step, row,
                       above, ph,
                       pv + src * width * stride, pv + dst * width * stride, mv + src * width,
                       mv + dst * width, pd + src * width * stride, pd + dst * width * stride,
                       md + src * width, md + dst * width, pe + src * width * stride,
                       pe + dst * width * stride, me + src * width, me + dst * width, zero)
        else:
            sweep_row4(c_row, o_row, width, num, reverse, y == 0, p1, p2, p2_step, row,
                       above, ph,
                       pv + src * width * stride, pv + dst * width * stride, mv + src * width,
                       mv + dst * width, zero)
        return
    for x in range(width):
        xx = width - 1 - x if reverse else x
        xs = xx + 1 if reverse else xx - 1
        hs = x & 1
        c = c_row + xx * num
        o = o_row + xx * num
        prev_a = zero if x == 0 else ph + hs * stride
        prev_b = zero if y == 0 else pv + (src * width + x) * stride
        ma = 0 if y == 0 else mv[src * width + x]
        p2a = p2
        p2b = p2
        if adapt:
            if x > 0:
                p2a = _step_p2(p2_step, row[xx], row[xs])
            if y > 0:
                p2b = _step_p2(p2_step, row[xx], above[xx])
        hmin = path_pair(c, o, prev_a, ph + (1 - hs) * stride, hmin, prev_b,
                         pv + (dst * width + x) * stride, ma, p1, p2a, p2b, False, num,
                         &mv[dst * width + x])
        if eight:
            first = y == 0 or x == 0
            last = y == 0 or x == width - 1
            prev_a = zero if first else pd + (src * width + x - 1) * stride
            prev_b = zero if last else pe + (src * width + x + 1) * stride
            ma = 0 if first else md[src * width + x - 1]
            mb = 0 if last else me[src * width + x + 1]
            p2a = p2
            p2b = p2
            if adapt:
                if not first:
                    p2a = _step_p2(p2_step, row[xx], above[xs])
                if not last:
                    p2b = _step_p2(p2_step, row[xx], above[2 * xx - xs])
            md[dst * width + x] = path_pair(c, o, prev_a, pd + (dst * width + x) * stride, ma,
                                            prev_b, pe + (dst * width + x) * stride, mb, p1,
                                            p2a, p2b, True, num, &me[dst * width + x])


def aggregate_pass(uint16_t[:, :, ::1] cost, int p1, int p2, bint eight, bint reverse,
                   uint16_t[:, :, ::1] out, const uint8_t[:, ::1] grey, double p2_grad):
    """Sum of the path costs of one sweep over the rows, (H, W, D) uint16 into ``out``.

    ``reverse`` False: the top-down sweep, paths left to right and from the top (and,
    with ``eight``, from the top-left and top-right); True: the same on the image
    turned by 180 degrees. ``p1``, ``p2``: the penalties in cost units (1/256 of Eq.
    10); ``grey`` (H, W) with ``p2_grad`` > 0: P2 adapted to the grey step along each
    path, ``P2 g / (g + |grey step|)``, at least P1 + 1. Needs D >= 2.
    """
    cdef Py_ssize_t height = cost.shape[0], width = cost.shape[1], num = cost.shape[2]
    paths_, mins_ = sweep_state(width, num)
    cdef int16_t[:, ::1] paths = paths_
    cdef int32_t[:, :, ::1] mins = mins_
    cdef Py_ssize_t y, yy
    cdef int32_t table[511]
    cdef const int32_t *p2_step
    with nogil:
        p2_step = _p2_steps(p1, p2, <float>p2_grad, table)
        for y in range(height):
            yy = height - 1 - y if reverse else y
            sweep_row(<int16_t *>&cost[yy, 0, 0], <int16_t *>&out[yy, 0, 0], &grey[0, 0],
                      width, num, y, yy, yy + 1 if reverse else yy - 1, reverse, p1, p2,
                      p2_step, eight, &paths[0, 0], &mins[0, 0, 0])


def _winner_buffers(Py_ssize_t width, Py_ssize_t num, Py_ssize_t dmin):
    return np.empty((3, max(width * num, width + 2 * (num + abs(dmin) + 1))), np.int32)


def winners_rows(uint16_t[:, :, ::1] s_a, uint16_t[:, :, ::1] s_b, uint16_t[:, :, ::1] cost,
                 const float[:, ::1] el, const float[:, ::1] count, Py_ssize_t dmin,
                 float uniq, double lr_tol, bint subpixel, float energy_min, uint16_t top,
                 float scale, Py_ssize_t y0, Py_ssize_t y1, float[:, ::1] disp_out,
                 float[:, ::1] cost_out, uint8_t[:, ::1] reason_out,
                 float[:, ::1] rdisp_out, float[:, ::1] refit_out=None,
                 double refit_den_min=0.0):
    """Winner-take-all over ``s_a + s_b`` for rows y0..y1-1 with the validity tests.

    ``cost``: the quantised Eq. 10 volume (a pixel without any candidate below ``top``
    has no candidate); ``el``, ``count``: window energy and pixel count (texture test:
    ``el < energy_min count``); ``uniq``: no disparity more than 1 px from the winner
    may have a sum below ``(1 + uniq)`` times the winner's; ``lr_tol`` < 0: no
    left-right test (the right pixel's own best left match from the same sums must lie
    within ``lr_tol`` px of the winner). Writes disparity (float32 px, NaN where none),
    the winner's Eq. 10 cost (``cost / scale``, inf where none), the reason code
    (uniqueness over left-right over texture) and the right view's integer disparities.
    With ``refit_out`` (H, W) float32: the disparities refitted to the row's own costs
    too (refit.pxd, ``den_min`` ``refit_den_min``, clip ``top``), while they are in cache.
    """
    cdef Py_ssize_t width = s_a.shape[1], num = s_a.shape[2], y
    cdef bint refit = refit_out is not None and num >= 3
    cdef int32_t[:, ::1] buf = _winner_buffers(width, num, dmin)
    cdef Tests t = Tests(dmin, uniq, lr_tol, subpixel, energy_min, top, scale, &buf[0, 0],
                         &buf[1, 0], &buf[2, 0], R_VALID, R_NO_CANDIDATE, R_TEXTURE,
                         R_UNIQUENESS, R_LEFT_RIGHT)
    with nogil:
        for y in range(y0, y1):
            winner_row(&t, &s_a[y, 0, 0], &s_b[y, 0, 0], &cost[y, 0, 0], &el[y, 0],
                    &count[y, 0], width, num, &disp_out[y, 0], &cost_out[y, 0],
                    &reason_out[y, 0], &rdisp_out[y, 0])
            if refit:
                _refit(&disp_out[y, 0], &refit_out[y, 0], &cost[y, 0, 0], width, num, dmin,
                       refit_den_min, top)


cdef inline void _refit(const float *disp, float *out, const uint16_t *cost, Py_ssize_t width,
                        Py_ssize_t num, Py_ssize_t dmin, double den_min,
                        uint16_t top) noexcept nogil:
    """One row's winners refitted to its own costs (refit.pxd) into ``out``."""
    cdef Py_ssize_t x
    for x in range(width):
        out[x] = disp[x]
    refit_row(out, cost, NULL, width, num, dmin, den_min, <double>top)


def first_sweep_rows(const float[:, ::1] pl, const float[:, ::1] prr_pad,
                     const float[:, ::1] el, const float[:, ::1] err_pad,
                     const float[:, ::1] irr_pad, Py_ssize_t pad, Py_ssize_t dmin,
                     Py_ssize_t num, Py_ssize_t m, Py_ssize_t n, double c_max, double scale,
                     int p1, int p2, bint eight, const uint8_t[:, ::1] grey,
                     double p2_grad, uint16_t[:, :, ::1] cost, uint16_t[:, :, ::1] s_a,
                     Py_ssize_t y0,
                     Py_ssize_t y1, bint with_cost, float[:, ::1] col, float[::1] hs,
                     int16_t[:, ::1] paths, int32_t[:, :, ::1] mins, object shear=None):
    """Rows y0..y1-1 of the top-down sweep into ``s_a``, each row's costs first (with
    ``with_cost``; the column sums ``col`` at row y0 - 1, :func:`cost_start`) or read
    from ``cost`` (computed by another thread). ``paths``, ``mins``: the sweep's state
    (:func:`sweep_state`), carried from the rows before; ``shear``: :func:`cost_rows`."""
    cdef CostIn c = _cost_in(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n,
                             c_max, scale)
    _shear_in(&c, shear)
    if with_cost:
        _check_columns(&c, col)
    cdef Py_ssize_t y, width = c.width
    cdef int32_t table[511]
    cdef const int32_t *p2_step
    with nogil:
        p2_step = _p2_steps(p1, p2, <float>p2_grad, table)
        for y in range(y0, y1):
            if with_cost:
                _cost_row(&c, y, &col[0, 0], &hs[0], &cost[y, 0, 0])
            sweep_row(<int16_t *>&cost[y, 0, 0], <int16_t *>&s_a[y, 0, 0], &grey[0, 0],
                      width, num, y, y, y - 1, False, p1, p2, p2_step, eight,
                      &paths[0, 0], &mins[0, 0, 0])


def cost_and_first_sweep(const float[:, ::1] pl, const float[:, ::1] prr_pad,
                         const float[:, ::1] el, const float[:, ::1] err_pad,
                         const float[:, ::1] irr_pad, Py_ssize_t pad, Py_ssize_t dmin,
                         Py_ssize_t num, Py_ssize_t m, Py_ssize_t n, double c_max,
                         double scale, int p1, int p2, bint eight,
                         const uint8_t[:, ::1] grey, double p2_grad,
                         uint16_t[:, :, ::1] cost, uint16_t[:, :, ::1] s_a, object shear=None):
    """Costs (H, W, D) uint16 into ``cost`` and the top-down sweep's sums into ``s_a``
    (:func:`cost_rows` and :func:`aggregate_pass`, row by row, while each row's costs
    are in cache; ``shear``: :func:`cost_rows`)."""
    width = pl.shape[1]
    col = cost_columns(width, num, shear)
    hs = np.zeros(num, np.float32)
    paths, mins = sweep_state(width, num)
    cost_start(pl, prr_pad, pad, dmin, num, n, 0, col, shear)
    first_sweep_rows(pl, prr_pad, el, err_pad, irr_pad, pad, dmin, num, m, n, c_max, scale,
                     p1, p2, eight, grey, p2_grad, cost, s_a, 0, pl.shape[0], True, col, hs,
                     paths, mins, shear)


def second_sweep_rows(uint16_t[:, :, ::1] cost, uint16_t[:, :, ::1] s_a, int p1, int p2,
                      bint eight, const uint8_t[:, ::1] grey, double p2_grad,
                      const float[:, ::1] el, const float[:, ::1] count, Py_ssize_t dmin,
                      float uniq, double lr_tol, bint subpixel, float energy_min,
                      uint16_t top, float scale, float[:, ::1] disp_out,
                      float[:, ::1] cost_out, uint8_t[:, ::1] reason_out,
                      float[:, ::1] rdisp_out, Py_ssize_t v0, Py_ssize_t v1, bint winners,
                      uint16_t[:, :, ::1] s_b, int16_t[:, ::1] paths,
                      int32_t[:, :, ::1] mins, float[:, ::1] refit_out=None,
                      double refit_den_min=0.0):
    """Visits v0..v1-1 of the bottom-up sweep (image row H - 1 - v), state ``paths``,
    ``mins`` carried from the visits before. ``winners``: each row's winner step over
    ``s_a`` + the row's sums (:func:`winners_rows`, with its ``refit_out``); else the
    sums into ``s_b``."""
    cdef Py_ssize_t height = cost.shape[0], width = cost.shape[1], num = cost.shape[2]
    cdef bint refit = refit_out is not None and num >= 3
    cdef Py_ssize_t y, yy
    cdef int32_t[:, ::1] buf = _winner_buffers(width, num, dmin)
    cdef Tests t = Tests(dmin, uniq, lr_tol, subpixel, energy_min, top, scale, &buf[0, 0],
                         &buf[1, 0], &buf[2, 0], R_VALID, R_NO_CANDIDATE, R_TEXTURE,
                         R_UNIQUENESS, R_LEFT_RIGHT)
    cdef uint16_t[::1] row = np.empty(width * num, np.uint16)
    cdef uint16_t *o_row
    cdef int32_t table[511]
    cdef const int32_t *p2_step
    with nogil:
        p2_step = _p2_steps(p1, p2, <float>p2_grad, table)
        for y in range(v0, v1):
            yy = height - 1 - y
            o_row = &row[0] if winners else &s_b[yy, 0, 0]
            sweep_row(<int16_t *>&cost[yy, 0, 0], <int16_t *>o_row, &grey[0, 0], width, num,
                      y, yy, yy + 1, True, p1, p2, p2_step, eight, &paths[0, 0],
                      &mins[0, 0, 0])
            if winners:
                winner_row(&t, &s_a[yy, 0, 0], o_row, &cost[yy, 0, 0], &el[yy, 0],
                        &count[yy, 0], width, num, &disp_out[yy, 0], &cost_out[yy, 0],
                        &reason_out[yy, 0], &rdisp_out[yy, 0])
                if refit:
                    _refit(&disp_out[yy, 0], &refit_out[yy, 0], &cost[yy, 0, 0], width,
                           num, dmin, refit_den_min, top)


def second_sweep_winners(cost, s_a, p1, p2, eight, grey, p2_grad, el, count, dmin, uniq,
                         lr_tol, subpixel, energy_min, top, scale, disp_out, cost_out,
                         reason_out, rdisp_out, refit_out=None, refit_den_min=0.0):
    """The bottom-up sweep (:func:`aggregate_pass`, ``reverse``) and, row by row, the
    winner step over ``s_a`` + its sums (:func:`winners_rows`, with its ``refit_out``)."""
    paths, mins = sweep_state(cost.shape[1], cost.shape[2])
    second_sweep_rows(cost, s_a, p1, p2, eight, grey, p2_grad, el, count, dmin, uniq, lr_tol,
                      subpixel, energy_min, top, scale, disp_out, cost_out, reason_out,
                      rdisp_out, 0, cost.shape[0], True, cost, paths, mins, refit_out,
                      refit_den_min)
