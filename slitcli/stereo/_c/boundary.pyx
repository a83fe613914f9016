# cflags: -fno-math-errno -fno-trapping-math
# (sqrtf sets no errno and nothing traps, as in the numba kernels these replace: lets
# gcc vectorise the row loops and changes no value. The FMAs and reciprocals that
# numba's fastmath contract/arcp made are spelled out in the code, see zncc.pxd.)
"""Compiled tests of the Eq. 10 matcher at depth edges (slitcli.stereo._boundary).

The local, one-sided and cross support and the depth-edge two-hypothesis test, run
row by row after matching; the module notes of slitcli.stereo._boundary say what each
test checks and why. :func:`post_rows` is the entry point: it releases the GIL, and
each row's result depends only on read-only inputs, so bands of rows run on plain
threads.
"""

import numpy as np

from libc.math cimport fmaf, nextafterf, sqrt

from slitcli.stereo._c.depth_edge cimport (
    BIG,
    Img,
    _BOUNDARY,
    _SUPPORT,
    _candidates,
    _depth_edge_row,
    _window_min,
)
from slitcli.stereo._c.zncc cimport fmax_nb, fmin_nb, zncc_blocks

#: the codes :func:`post_rows` writes (Reason.SUPPORT, Reason.BOUNDARY)
REASON_SUPPORT = _SUPPORT
REASON_BOUNDARY = _BOUNDARY


# the largest float32 at or below 1e-3: a float32 den is above 1e-3 (numba compared
# them in float64) exactly when it is above FLAT
cdef float FLAT = (<float>1e-3 if <double><float>1e-3 <= 1e-3
                   else nextafterf(<float>1e-3, 0.0))


cdef struct Req:
    # work arrays of a row's block requests (at most two per pixel): pixel, block
    # centre row and column, disparity, correlation
    Py_ssize_t* who
    Py_ssize_t* yc
    Py_ssize_t* xc
    float* dd
    float* res



# ---- the support tests

cdef void _warp_row(const float* gr, const float* disp, Py_ssize_t y, Py_ssize_t width,
                    float* out) noexcept nogil:
    """``out(x) = gr(x - disp(x, y), y)`` (linear in x, clamped to the image; no shift
    where ``disp`` is NaN)."""
    cdef Py_ssize_t x, x0
    cdef float d, xr, t
    cdef const float* row = gr + y * width
    for x in range(width):
        d = disp[y * width + x]
        xr = <float>x - (d if d == d else <float>0.0)
        xr = fmin_nb(fmax_nb(xr, 0.0), <float>(width - 1))
        x0 = min(<Py_ssize_t>xr, width - 2)
        t = xr - <float>x0
        out[x] = fmaf(t, row[x0 + 1], (1.0 - t) * row[x0])


cdef extern from *:
    """
    #include <math.h>
    /* The window sums' row loops, with restrict: the five sums and the two rows never
       overlap, and without the promise gcc versions every loop on run-time overlap
       checks. One rounding per product (fmaf), as numba fused them. */
    static inline void slitcli_acc_rows(
            float *restrict s0, float *restrict s1, float *restrict s2,
            float *restrict s3, float *restrict s4, const float *restrict a,
            const float *restrict b, Py_ssize_t n) {
        for (Py_ssize_t i = 0; i < n; i++) {
            float x = a[i], y = b[i];
            s0[i] = s0[i] + x;
            s1[i] = s1[i] + y;
            s2[i] = fmaf(x, x, s2[i]);
            s3[i] = fmaf(y, y, s3[i]);
            s4[i] = fmaf(x, y, s4[i]);
        }
    }
    static inline void slitcli_acc(float *restrict s, const float *restrict a,
                                   Py_ssize_t n) {
        for (Py_ssize_t i = 0; i < n; i++)
            s[i] = s[i] + a[i];
    }
    /* The correlations from the window sums h (5 rows of n: a, b, aa, bb, ab) of
       windows 2r+1 wide (clipped) and `rows` tall. Three divisions by the count:
       numba (arcp) took one reciprocal and fused each product. Branch-free, all
       float (a float32 den is above numba's float64 1e-3 exactly when it is above
       `flat`), int column counts: gcc vectorises it. */
    static inline void slitcli_zncc_finish(const float *restrict h, Py_ssize_t n,
                                           Py_ssize_t r, float rows, float flat,
                                           float nv, float nvf, float nfr,
                                           float *restrict out,
                                           float *restrict plain) {
        const float *h0 = h, *h1 = h + n, *h2 = h + 2 * n, *h3 = h + 3 * n,
                    *h4 = h + 4 * n;
        int w = (int)n, ri = (int)r;
        for (int x = 0; x < w; x++) {
            int hi = x + ri + 1 < w ? x + ri + 1 : w;
            int lo = x - ri > 0 ? x - ri : 0;
            float cnt = rows * (float)(hi - lo);
            float rc = 1.0f / cnt;
            float sa = h0[x], sb = h1[x];
            float va = fmaf(-(sa * sa), rc, h2[x]);
            float vb = fmaf(-(sb * sb), rc, h3[x]);
            float cov = fmaf(-(sa * sb), rc, h4[x]);
            float den0 = sqrtf((0.0f > va ? 0.0f : va) * (0.0f > vb ? 0.0f : vb));
            float q0 = cov / den0;
            plain[x] = den0 > flat ? q0 : 0.0f;
            float ne = nv * cnt - nvf;  /* the window's noise energy (zncc.pxd, finish) */
            if (ne > 0.0f) {
                /* zncc.pxd, noise_bound: the 95 % bound of noise alone */
                float sig = ne * (1.0f + 2.326f * sqrtf(2.0f * nvf / ne));
                va = va >= sig ? va - nfr * ne : va;
                vb = vb >= sig ? vb - nfr * ne : vb;
            }
            float den = sqrtf((0.0f > va ? 0.0f : va) * (0.0f > vb ? 0.0f : vb));
            float q = cov / den;
            out[x] = den > flat ? q : 0.0f;
        }
    }
    """
    void _acc_rows "slitcli_acc_rows"(float* s0, float* s1, float* s2, float* s3,
                                       float* s4, const float* a, const float* b,
                                       Py_ssize_t n) noexcept nogil
    void _acc "slitcli_acc"(float* s, const float* a, Py_ssize_t n) noexcept nogil
    void _zncc_finish "slitcli_zncc_finish"(const float* h, Py_ssize_t width, Py_ssize_t r,
                                             float rows, float flat, float nv, float nvf,
                                             float nfr, float* out,
                                             float* plain) noexcept nogil


cdef void _zncc_row(const float* gl, Py_ssize_t height, Py_ssize_t width,
                    const float* ring, Py_ssize_t y, Py_ssize_t r, float* s, float* h,
                    float* out, float nv, float nvf, float nfr,
                    float* plain) noexcept nogil:
    """Zero-mean normalised correlation of the (2r+1)^2 windows (clipped to the image)
    of ``gl`` and the warped right image around row y (``ring`` row yy % (2r+1) holds
    warped row yy): ``out`` in [-1, 1], 0 where a window is flat. ``s``: (5, width +
    2r) and ``h``: (5, width) work arrays. ``plain``: the same without the noise
    model (``nv``, ``nvf``; zncc.pxd, finish)."""
    cdef Py_ssize_t k2 = 2 * r + 1, sw = width + 2 * r
    cdef Py_ssize_t y0 = max(0, y - r), y1 = min(height, y + r + 1)
    cdef Py_ssize_t yy, q, k, i
    cdef const float* a
    cdef const float* b
    for i in range(5 * sw):
        s[i] = 0.0
    for i in range(5 * width):
        h[i] = 0.0
    for yy in range(y0, y1):
        a = gl + yy * width
        b = ring + (yy % k2) * width
        _acc_rows(s + r, s + sw + r, s + 2 * sw + r, s + 3 * sw + r, s + 4 * sw + r, a, b,
                  width)
    # window sums along x: 2r+1 shifted adds of the zero-padded column sums
    for q in range(5):
        for k in range(k2):
            _acc(h + q * width, s + q * sw + k, width)
    _zncc_finish(h, width, r, <float>(y1 - y0), FLAT, nv, nvf, nfr, out, plain)


cdef void _support_codes(const unsigned char* reason, const float* zncc, double smin,
                         bint support, unsigned char* codes, Py_ssize_t n) noexcept nogil:
    """``codes = reason``, and SUPPORT for valid pixels whose centred support ``zncc``
    is below ``smin``."""
    cdef Py_ssize_t x
    cdef unsigned char c
    for x in range(n):
        c = reason[x]
        codes[x] = _SUPPORT if (c == 0) & support & (not (zncc[x] >= smin)) else c


cdef void _one_sided_row(Img im, const float* disp, const float* zrow, Py_ssize_t y,
                         double side_min, Py_ssize_t rx, Py_ssize_t ry,
                         unsigned char* codes, Req req) noexcept nogil:
    """One-sided support of row y (module notes; ``zrow``: its centred correlations):
    failing valid pixels of ``codes`` get SUPPORT. A pixel's test reads its own code
    only, so the row's blocks are correlated together (zncc.pxd, zncc_blocks)."""
    cdef Py_ssize_t width = im.width, n = 0, x, side, xx, i
    for x in range(width):
        if codes[x] != 0:
            continue
        for side in range(-1, 2, 2):
            xx = x + side
            if xx < 0 or xx >= width or zrow[xx] >= side_min:
                continue
            req.who[n] = x
            req.yc[n] = y
            req.xc[n] = xx
            req.dd[n] = disp[y * width + x]
            n += 1
    zncc_blocks(im.gl, im.gr, im.height, width, req.yc, req.xc, req.dd, n, rx, ry, req.res,
                im.nv, im.nvf, im.nfr)
    for i in range(n):
        if req.res[i] < side_min:
            codes[req.who[i]] = _SUPPORT


cdef Py_ssize_t _cross_stage(Img im, const float* disp, Py_ssize_t y, Py_ssize_t dy,
                             Py_ssize_t dx, Py_ssize_t r, double cross_min,
                             Py_ssize_t* lst, Py_ssize_t m, Req req) noexcept nogil:
    """Keep in ``lst[:m]`` (in place, in order) the pixels x whose (2r+1)^2 block
    centred at (x + dx, y + dy) correlates with the right image at their own
    disparity to at least ``cross_min``; returns their count."""
    cdef Py_ssize_t i, j = 0, x
    for i in range(m):
        x = lst[i]
        req.yc[i] = y + dy
        req.xc[i] = x + dx
        req.dd[i] = disp[y * im.width + x]
    zncc_blocks(im.gl, im.gr, im.height, im.width, req.yc, req.xc, req.dd, m, r, r,
                req.res, im.nv, im.nvf, im.nfr)
    for i in range(m):
        if req.res[i] >= cross_min:
            lst[j] = lst[i]
            j += 1
    return j


cdef void _cross_row(Img im, const float* disp, const float* zrow, Py_ssize_t y,
                     double cross_min, double strong, Py_ssize_t r, unsigned char* codes,
                     Req req, Py_ssize_t* cand, Py_ssize_t* cur,
                     unsigned char* held) noexcept nogil:
    """Cross support of row y (module notes; ``zrow``: its centred correlations,
    without the noise model: the gate asks how well the window carries its match over
    its noise, not how well its signals agree): valid pixels of ``codes`` below ``strong`` and supported on neither axis get
    SUPPORT. The row's blocks are correlated together, one side at a time: the
    blocks below for the pixels whose block above passed, and so on, as the scalar
    test would have asked for them. ``cand``, ``cur`` (width,) and ``held`` (width,)
    are work arrays."""
    cdef Py_ssize_t width = im.width, k = 2 * r + 1, n = 0, m, x, i, dy, dx
    cdef int vertical
    for x in range(width):
        if codes[x] == 0 and zrow[x] < strong:
            cand[n] = x
            held[x] = False
            n += 1
    for vertical in range(1, -1, -1):
        m = 0
        for i in range(n):
            if not held[cand[i]]:
                cur[m] = cand[i]
                m += 1
        dy = k if vertical else 0
        dx = 0 if vertical else k
        m = _cross_stage(im, disp, y, -dy, -dx, r, cross_min, cur, m, req)
        m = _cross_stage(im, disp, y, dy, dx, r, cross_min, cur, m, req)
        for i in range(m):
            held[cur[i]] = True
    for i in range(n):
        if not held[cand[i]]:
            codes[cand[i]] = _SUPPORT


# ---- the fused pass: local support, one-sided support, depth edges (rows y0 .. y1-1)

def post_rows(const float[:, ::1] gl, const float[:, ::1] gr, const float[:, ::1] disp,
              const float[:, ::1] rdisp, double smin, double side_min, double cross_min,
              double strong, Py_ssize_t r, Py_ssize_t ry, double tol, double ratio,
              double step, Py_ssize_t radius, double floor2, double nv, double nvf,
              double nfr, Py_ssize_t y0, Py_ssize_t y1, unsigned char[:, ::1] reason):
    """Local support (centred, one-sided, cross) and the depth-edge test, rows y0 ..
    y1 - 1, in place on ``reason``, in one pass (slitcli.stereo._boundary, module
    notes).

    Parameters
    ----------
    gl, gr : (H, W) float32, C order
        Grey left and right images.
    disp : (H, W) float32
        Left winner-take-all disparities (px; kept for invalid pixels too); read for
        rows y0 - r .. y1 - 1 + r (the warped right image).
    rdisp : (H, W) float32
        The right view's winner-take-all disparities (whole px, NaN where none).
    smin, side_min : float
        ``support_min_zncc`` (0 = no support test) and ``support_side_min_zncc``
        (0 = no one-sided test).
    cross_min, strong : float
        ``support_cross_min_zncc`` (0 = no cross-support test) and
        ``support_strong_zncc`` (a centred correlation this high needs no cross support).
    r, ry : int
        Half size of the (2r+1)^2 support window; half height of the one-sided block
        (2r+1 columns by 2ry+1 rows) and of the depth-edge columns.
    tol : float
        A right pixel's candidate needs a left partner within ``tol`` px.
    ratio, step, radius, floor2 : float, float, int, float
        The depth-edge test (``ratio`` 0 = off): the farther surface wins below
        ``ratio`` x the pixel's own residual; a neighbour is another surface when its
        disparity is below d - ``step``; ``radius`` columns are searched on each side;
        own residuals at or below ``floor2`` (DN^2, the noise of a correct match) carry
        no evidence.
    nv, nvf : float
        The noise model of the support correlations (zncc.pxd, ``finish``): the grey
        images' noise variance per pixel (DN^2) and ``nv`` times the variance factor of
        a block sum (correlated noise); 0, 0: plain zero-mean normalised correlations.
    nfr : float
        Share of the noise taken off (0-1; zncc.pxd, ``finish``): of a block's noise
        energy in the support correlations, and of a column residual's ``2 nv`` in the
        depth-edge test (both hypotheses' residuals, before their ratio is formed).
    y0, y1 : int
        The rows to test, 0 <= y0 <= y1 <= H.
    reason : (H, W) uint8
        Valid pixels (0) that fail get Reason.SUPPORT or Reason.BOUNDARY. Each row's
        result depends only on read-only inputs, so bands of rows can run in parallel
        (the GIL is released).
    """
    cdef Py_ssize_t height = gl.shape[0], width = gl.shape[1]
    if (gr.shape[0] != height or gr.shape[1] != width or disp.shape[0] != height
            or disp.shape[1] != width or rdisp.shape[0] != height
            or rdisp.shape[1] != width or reason.shape[0] != height
            or reason.shape[1] != width):
        raise ValueError("post_rows: every image must have the shape of gl")
    if not (0 <= y0 <= y1 <= height) or r < 0 or ry < 0 or radius < 0 or width < 2:
        raise ValueError("post_rows: rows, radii or width out of range")
    if height == 0 or y0 == y1:
        return
    cdef Py_ssize_t k2 = 2 * r + 1
    cdef float[:, ::1] ring = np.empty((k2, width), np.float32)
    cdef float[::1] s = np.empty(5 * (width + 2 * r), np.float32)
    cdef float[::1] h = np.empty(5 * width, np.float32)
    cdef float[::1] zncc = np.zeros(width, np.float32)
    cdef float[::1] zplain = np.zeros(width, np.float32)
    cdef unsigned char[::1] codes = np.empty(width, np.uint8)
    cdef float[:, ::1] cand = np.empty((2, width), np.float32)
    cdef float[:, ::1] wmin = np.empty((2, width), np.float32)
    cdef float[:, ::1] pad = np.empty((2, width + 2 * radius), np.float32)
    cdef Py_ssize_t[:, ::1] ireq = np.empty((3, 2 * width), np.intp)
    cdef float[:, ::1] freq = np.empty((2, 2 * width), np.float32)
    cdef Py_ssize_t[:, ::1] lists = np.empty((2, width), np.intp)
    cdef unsigned char[::1] held = np.zeros(width, np.uint8)
    cdef Img im = Img(&gl[0, 0], &gr[0, 0], height, width, <float>nv, <float>nvf,
                      <float>nfr)
    cdef Req req = Req(&ireq[0, 0], &ireq[1, 0], &ireq[2, 0], &freq[0, 0], &freq[1, 0])
    cdef bint support = smin != 0
    cdef Py_ssize_t y, yy, x
    with nogil:
        if support:
            for yy in range(max(0, y0 - r), min(height, y0 + r)):
                _warp_row(im.gr, &disp[0, 0], yy, width, &ring[yy % k2, 0])
        for y in range(y0, y1):
            if support:
                if y + r < height:
                    _warp_row(im.gr, &disp[0, 0], y + r, width, &ring[(y + r) % k2, 0])
                _zncc_row(im.gl, height, width, &ring[0, 0], y, r, &s[0], &h[0], &zncc[0],
                          im.nv, im.nvf, im.nfr, &zplain[0])
            _support_codes(&reason[y, 0], &zncc[0], smin, support, &codes[0], width)
            if support and side_min != 0:
                _one_sided_row(im, &disp[0, 0], &zncc[0], y, side_min, r, ry, &codes[0],
                               req)
            if support and cross_min != 0:
                _cross_row(im, &disp[0, 0], &zplain[0], y, cross_min, strong, r, &codes[0],
                           req, &lists[0, 0], &lists[1, 0], &held[0])
            if ratio > 0:
                _candidates(&codes[0], &disp[y, 0], &rdisp[y, 0], tol, &cand[0, 0],
                            &cand[1, 0], width)
                _window_min(&cand[0, 0], width, radius, &wmin[0, 0], &pad[0, 0],
                            &pad[1, 0])
                _window_min(&cand[1, 0], width, radius, &wmin[1, 0], &pad[0, 0],
                            &pad[1, 0])
                _depth_edge_row(im, &disp[0, 0], y, step, radius, ry, ratio, floor2,
                                &cand[0, 0], &cand[1, 0], &wmin[0, 0], &wmin[1, 0],
                                &codes[0])
            for x in range(width):
                reason[y, x] = codes[x]


def support_zncc(const float[:, ::1] gl, const float[:, ::1] gr, const float[:, ::1] disp,
                 Py_ssize_t r, float nv=0.0, float nvf=0.0, float nfr=1.0):
    """The centred correlations the local support test compares with
    ``support_min_zncc`` (as :func:`post_rows` computes them).

    Parameters
    ----------
    gl, gr : (H, W) float32, C order
        Grey left and right images.
    disp : (H, W) float32
        Left disparities (px; NaN: no shift).
    r : int
        Half size of the (2r+1)^2 window (clipped to the image).
    nv, nvf : float
        Noise model, as for :func:`post_rows` (0, 0: plain correlations).

    Returns
    -------
    (H, W) float32
        Zero-mean normalised correlation of each left window with the same window of
        the right image warped by ``disp`` (bilinear in x, clamped to the image); 0
        where a window is flat.
    """
    cdef Py_ssize_t height = gl.shape[0], width = gl.shape[1]
    if (gr.shape[0] != height or gr.shape[1] != width or disp.shape[0] != height
            or disp.shape[1] != width or width < 2 or r < 0):
        raise ValueError("support_zncc: gl, gr, disp of one shape, >= 2 columns; r >= 0")
    out_arr = np.zeros((height, width), np.float32)
    cdef float[:, ::1] out = out_arr
    cdef Py_ssize_t k2 = 2 * r + 1, y, yy
    cdef float[:, ::1] ring = np.empty((k2, width), np.float32)
    cdef float[::1] s = np.empty(5 * (width + 2 * r), np.float32)
    cdef float[::1] h = np.empty(5 * width, np.float32)
    cdef float[::1] plain = np.empty(width, np.float32)
    if height == 0:
        return out_arr
    with nogil:
        for yy in range(0, min(height, r)):
            _warp_row(&gr[0, 0], &disp[0, 0], yy, width, &ring[yy % k2, 0])
        for y in range(height):
            if y + r < height:
                _warp_row(&gr[0, 0], &disp[0, 0], y + r, width, &ring[(y + r) % k2, 0])
            _zncc_row(&gl[0, 0], height, width, &ring[0, 0], y, r, &s[0], &h[0], &out[y, 0],
                      nv, nvf, nfr, &plain[0])
    return out_arr


def window_min(const float[::1] v, Py_ssize_t radius):
    """The running minimum the depth-edge test takes of a row's candidates.

    Parameters
    ----------
    v : (W,) float32
        One row of values.
    radius : int
        Half width of the window (px, >= 0).

    Returns
    -------
    (W,) float32
        ``out[x]`` = min of ``v`` over columns x - radius .. x + radius; columns outside
        the row count as 3e38 (cv2.erode with that border value).
    """
    if radius < 0:
        raise ValueError("window_min: radius must be >= 0")
    cdef Py_ssize_t width = v.shape[0]
    out_arr = np.empty(width, np.float32)
    cdef float[::1] out = out_arr
    cdef float[:, ::1] pad = np.empty((2, width + 2 * radius), np.float32)
    if width == 0:
        return out_arr
    with nogil:
        _window_min(&v[0], width, radius, &out[0], &pad[0, 0], &pad[1, 0])
    return out_arr
