# The depth-edge two-hypothesis test of the Eq. 10 matcher (slitcli.stereo._boundary):
# inline C helpers, compiled into the module that cimports them (boundary.pyx, whose
# post_rows runs this test after the support tests, row by row).
#
# Where a valid neighbour within ``radius`` columns lies at a smaller disparity (a depth
# step; a row-wise running minimum of the candidates, _window_min, says where), the
# pixel's one-pixel-wide, window-tall grey column is compared with the right image at
# its own disparity and at the neighbour's; the farther surface wins when it explains
# the column with less than ``ratio`` of the residual. The same test runs for the
# right image's pixel the match lands on (_column_residual_right).
#
# Arithmetic: as the numba kernels these replace (fastmath contract/arcp), the fused
# multiply-adds and the reciprocal of the row count are spelled out (zncc.pxd).

from libc.math cimport INFINITY, fabsf, fmaf, rintf

from slitcli.stereo._c.zncc cimport fmin_nb

cdef enum:
    # the codes the depth-edge and support tests write (slitcli.stereo.reasons.Reason;
    # a test checks them)
    _SUPPORT = 7
    _BOUNDARY = 8


cdef extern from *:
    """
    static const float SLITCLI_DEPTH_EDGE_BIG = 3e38f;
    static const float SLITCLI_DEPTH_EDGE_SAME_PX = 0.25f;
    """
    # "no candidate"
    const float BIG "SLITCLI_DEPTH_EDGE_BIG"
    # Neighbours on one surface have nearly the same disparity: a candidate within this of
    # one already tried on the same side would give nearly the same residual.
    const float SAME_PX "SLITCLI_DEPTH_EDGE_SAME_PX"


cdef struct Img:
    # a grey image pair, (height, width) float32 in C order
    const float* gl
    const float* gr
    Py_ssize_t height
    Py_ssize_t width
    # the noise model of the support correlations (zncc.pxd, finish): noise variance
    # per sample (DN^2), nv times the variance factor of a block sum, and the share of
    # the noise energy taken off; 0 = plain ZNCC
    float nv
    float nvf
    float nfr



cdef inline float _column_residual_left(Img im, Py_ssize_t y, Py_ssize_t x, float d,
                                        Py_ssize_t hh) noexcept nogil:
    """Mean squared difference, over rows y-hh..y+hh, between left column x and the
    right image at x - d (linear in x); +inf where x - d leaves the image."""
    cdef Py_ssize_t width = im.width
    cdef float xr = <float>x - d
    if not (xr >= 0.0 and xr <= <double>(width - 1)):
        return INFINITY
    cdef Py_ssize_t x0 = min(<Py_ssize_t>xr, width - 2)
    cdef float t = xr - <float>x0
    cdef float u = 1.0 - t
    cdef float s = 0.0, v
    cdef Py_ssize_t y0 = max(0, y - hh)
    cdef Py_ssize_t y1 = min(im.height, y + hh + 1)
    cdef Py_ssize_t yy
    for yy in range(y0, y1):
        v = im.gl[yy * width + x] - fmaf(u, im.gr[yy * width + x0],
                                         t * im.gr[yy * width + x0 + 1])
        s = fmaf(v, v, s)
    # numba (arcp) hoisted the reciprocal of the row count out of its loops
    return s * <float>(1.0 / <float>(y1 - y0))


cdef inline float _column_residual_right(Img im, Py_ssize_t y, Py_ssize_t xr, float d,
                                         Py_ssize_t hh) noexcept nogil:
    """As :func:`_column_residual_left` for right column xr against the left image at
    xr + d."""
    cdef Py_ssize_t width = im.width
    cdef float xl = <float>xr + d
    if not (xl >= 0.0 and xl <= <double>(width - 1)):
        return INFINITY
    cdef Py_ssize_t x0 = min(<Py_ssize_t>xl, width - 2)
    cdef float t = xl - <float>x0
    cdef float u = 1.0 - t
    cdef float s = 0.0, v
    cdef Py_ssize_t y0 = max(0, y - hh)
    cdef Py_ssize_t y1 = min(im.height, y + hh + 1)
    cdef Py_ssize_t yy
    for yy in range(y0, y1):
        v = fmaf(u, im.gl[yy * width + x0], t * im.gl[yy * width + x0 + 1]) \
            - im.gr[yy * width + xr]
        s = fmaf(v, v, s)
    # numba (arcp) hoisted the reciprocal of the row count out of its loops
    return s * <float>(1.0 / <float>(y1 - y0))


cdef inline bint _explained(Img im, const float* cand, Py_ssize_t y, Py_ssize_t x,
                            double lim, Py_ssize_t radius, Py_ssize_t hh, double bound,
                            bint right) noexcept nogil:
    """True if a candidate disparity (``cand``, one row; below ``lim``) within
    +-radius columns of x explains column x (of the left image, or of the right one
    if ``right``) with a residual below ``bound``."""
    cdef Py_ssize_t side, j, xx
    cdef float last, v, res
    for side in range(-1, 2, 2):
        last = -1e30
        for j in range(1, radius + 1):
            xx = x + side * j
            if xx < 0 or xx >= im.width:
                break
            v = cand[xx]
            if v < lim and fabsf(v - last) > SAME_PX:
                last = v
                if right:
                    res = _column_residual_right(im, y, x, v, hh)
                else:
                    res = _column_residual_left(im, y, x, v, hh)
                if res < bound:
                    return True
    return False


cdef inline void _depth_edge_row(Img im, const float* disp, Py_ssize_t y, double step,
                          Py_ssize_t radius, Py_ssize_t hh, double ratio, double floor2,
                          const float* left_cand, const float* right_cand,
                          const float* left_min, const float* right_min,
                          unsigned char* codes) noexcept nogil:
    """Depth-edge test of row y (``disp``: the whole map; the other arrays one row
    each): valid pixels of ``codes`` that fail get BOUNDARY, in place (a pixel's test
    reads the candidates, not the codes, of its neighbours)."""
    cdef Py_ssize_t width = im.width, x, xr
    cdef float d, own
    cdef double lim
    cdef bint left_step, right_step, kill
    # under the noise model (im.nv > 0) a column's residual holds 2 nv of the two views'
    # noise; the share beyond the reference noise (nfr) is taken off both hypotheses,
    # and the own residual must exceed it by what the noise of a column mean reaches
    # in 99 % of columns (zncc.pxd, noise_bound), or by floor2, whichever is larger
    cdef double nx = 2.0 * im.nv * im.nfr
    cdef double n_rows = 2.0 * hh + 1.0
    cdef double vf = im.nvf / im.nv if im.nv > 0 else 1.0
    cdef double floor_eff = floor2 - nx
    for x in range(width):
        if codes[x] != 0:
            continue
        d = disp[y * width + x]
        lim = d - step
        xr = <Py_ssize_t>rintf(<float>x - d)
        left_step = left_min[x] < lim
        right_step = 0 <= xr < width and right_min[xr] < lim
        if not (left_step or right_step):
            continue
        kill = False
        if left_step:
            own = _column_residual_left(im, y, x, d, hh) - nx
            if own > floor_eff:
                kill = _explained(im, left_cand, y, x, lim, radius, hh, ratio * own + nx,
                                  False)
        if not kill and right_step:
            own = _column_residual_right(im, y, xr, d, hh) - nx
            if own > floor_eff:
                kill = _explained(im, right_cand, y, xr, lim, radius, hh, ratio * own + nx,
                                  True)
        if kill:
            codes[x] = _BOUNDARY


cdef inline void _candidates(const unsigned char* codes, const float* disp, const float* rdisp,
                      double tol, float* left_cand, float* right_cand,
                      Py_ssize_t width) noexcept nogil:
    """The depth-edge candidates of one row (``disp``, ``rdisp``: the row):
    ``left_cand`` the disparity of every valid left pixel; ``right_cand`` at right
    column x the disparity of the left pixel xq = rint(x + v) that the right view's
    winner v points to, where that pixel agrees with v within ``tol``; BIG elsewhere."""
    cdef Py_ssize_t x, xq
    cdef float v, dq
    for x in range(width):
        left_cand[x] = disp[x] if codes[x] == 0 else BIG
    for x in range(width):
        v = rdisp[x]
        xq = <Py_ssize_t>rintf(<float>x + v) if v == v else -1
        dq = disp[min(max(xq, 0), width - 1)]
        right_cand[x] = dq if (xq >= 0) & (xq < width) & (fabsf(dq - v) <= tol) else BIG


cdef inline void _window_min(const float* v, Py_ssize_t width, Py_ssize_t radius, float* out,
                      float* pad, float* tmp) noexcept nogil:
    """``out(x)`` = min of ``v`` over columns x - radius .. x + radius (outside the
    image: BIG, as cv2.erode with that border value), by doubling: minima over 1, 2,
    4 ... columns, then two overlapping runs cover the window. ``pad`` and ``tmp``
    hold width + 2 radius floats."""
    cdef Py_ssize_t total = width + 2 * radius, length = 1, i
    cdef float* cur = pad
    cdef float* nxt = tmp
    cdef float* swap
    for i in range(total):
        pad[i] = BIG
    for i in range(width):
        pad[radius + i] = v[i]
    while 2 * length <= 2 * radius + 1:
        _min_shift(nxt, cur, length, total - length)
        swap = cur
        cur = nxt
        nxt = swap
        length *= 2
    _min_shift(out, cur, 2 * radius + 1 - length, width)


cdef inline void _min_shift(float* out, const float* a, Py_ssize_t shift,
                     Py_ssize_t n) noexcept nogil:
    """``out[i] = min(a[i], a[i + shift])`` over n elements."""
    cdef Py_ssize_t i
    for i in range(n):
        out[i] = fmin_nb(a[i], a[i + shift])
