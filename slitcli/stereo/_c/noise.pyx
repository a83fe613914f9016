"""The match differences of :func:`slitcli.stereo.noise.estimate_match_noise`.

:func:`match_differences` walks the valid matches once, in row order, and keeps those
whose whole-pixel partner lies inside the right image with a subpixel part of at most
``max_fraction_px``: their left-minus-right difference with the fractional shift
removed by the right image's slope, the slope itself, their pixel and whole disparity.
On a frame with many matches only pairs of rows are taken (``(y // 2) % row_step == 0``),
so neighbours along y stay together. The GIL is released.
"""

from libc.math cimport fabsf, isfinite, rintf
from libc.stdint cimport int32_t, uint8_t


def count_matches(const float[:, ::1] disp, const uint8_t[:, ::1] valid) -> int:
    """How many pixels are valid with a finite disparity."""
    cdef Py_ssize_t y, x, n = 0
    with nogil:
        for y in range(disp.shape[0]):
            for x in range(disp.shape[1]):
                n += valid[y, x] != 0 and isfinite(disp[y, x])
    return n


def match_differences(const float[:, ::1] left, const float[:, ::1] right,
                      const float[:, ::1] disp, const uint8_t[:, ::1] valid,
                      Py_ssize_t row_step, float max_fraction_px,
                      int32_t[::1] ys, int32_t[::1] xs, int32_t[::1] whole_px,
                      float[::1] diff_dn, float[::1] slope_dn) -> int:
    """Fill the output arrays (each at least as long as the matches) and return how
    many matches were kept.

    ``diff_dn = L(y, x) - R(y, xr) + f S``, with ``xr = x - rint(d)``, ``f = d - rint(d)``
    and the right image's central slope ``S = (R(y, xr + 1) - R(y, xr - 1)) / 2``, all
    in single precision in that order (``L(x) = R(x - d) ~ R(xr) - f S``).
    """
    cdef Py_ssize_t h = disp.shape[0], w = disp.shape[1], y, x, xr, n = 0
    cdef float d, di, f, s
    with nogil:
        for y in range(h):
            if row_step > 1 and (y // 2) % row_step != 0:
                continue
            for x in range(w):
                d = disp[y, x]
                if valid[y, x] == 0 or not isfinite(d):
                    continue
                di = rintf(d)
                f = d - di
                xr = x - <Py_ssize_t>di
                if not (fabsf(f) <= max_fraction_px and xr >= 1 and xr <= w - 2):
                    continue
                s = 0.5 * (right[y, xr + 1] - right[y, xr - 1])
                ys[n] = <int32_t>y
                xs[n] = <int32_t>x
                whole_px[n] = <int32_t>di
                diff_dn[n] = (left[y, x] - right[y, xr]) + f * s
                slope_dn[n] = s
                n += 1
    return n


def neighbour_sums(const int32_t[::1] ys, const int32_t[::1] xs, const int32_t[::1] whole_px,
                   const double[::1] res_dn, int32_t[::1] index, Py_ssize_t height,
                   Py_ssize_t width, double[:, ::1] out) -> None:
    """Sums over the neighbour pairs of the given matches: ``out[k] = (pairs, sum a^2,
    sum b^2, sum a b)`` for the neighbours right, below, below-right and below-left
    (k = 0..3) of each match ``a`` that is itself a given match ``b`` on the same whole
    disparity. ``index`` (height x width, all -1) is used as scratch and left all -1."""
    cdef Py_ssize_t n = ys.shape[0], i, j, k, ny, nx
    cdef Py_ssize_t dy[4]
    cdef Py_ssize_t dx[4]
    cdef double a, b
    dy[:] = [0, 1, 1, 1]
    dx[:] = [1, 0, 1, -1]
    with nogil:
        for k in range(4):
            out[k, 0] = 0.0
            out[k, 1] = 0.0
            out[k, 2] = 0.0
            out[k, 3] = 0.0
        for i in range(n):
            index[ys[i] * width + xs[i]] = <int32_t>i
        for i in range(n):
            a = res_dn[i]
            for k in range(4):
                ny = ys[i] + dy[k]
                nx = xs[i] + dx[k]
                if ny >= height or nx < 0 or nx >= width:
                    continue
                j = index[ny * width + nx]
                if j < 0 or whole_px[j] != whole_px[i]:
                    continue
                b = res_dn[j]
                out[k, 0] += 1.0
                out[k, 1] += a * a
                out[k, 2] += b * b
                out[k, 3] += a * b
        for i in range(n):
            index[ys[i] * width + xs[i]] = -1
