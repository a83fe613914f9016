# cflags: -fno-math-errno -fno-trapping-math -funroll-loops
# (value-preserving: sqrtf need not set errno and no operation traps, so the row loops
# vectorise; no reassociation, no contraction: every energy keeps its bits)
"""The inputs of the SGM cost kernels (slitcli/stereo/_c/sgm.pyx, which re-exports both):

- :func:`window_inputs`: left window energies and pixel counts, the right image's rows
  reversed and padded with its window energies and their inverse square roots;
- :func:`sheared_energies`: the right window energies over windows sheared by the
  ground's disparity gradient (slitcli.stereo.cost.sheared_right_energies).

Both release the GIL; every sum is exact (the prefiltered images hold whole quarter
DN), so the energies equal ``cv2.boxFilter``'s bit for bit.
"""

from libc.math cimport sqrtf
from libc.stdint cimport int64_t

from slitcli.stereo._c.sgm_loops cimport add_floats

import numpy as np


def window_inputs(const float[:, ::1] pl, const float[:, ::1] pr, Py_ssize_t m,
                  Py_ssize_t n, Py_ssize_t pad, float[:, ::1] el, float[:, ::1] count,
                  float[:, ::1] prr_pad, float[:, ::1] err_pad, float[:, ::1] irr_pad):
    """The cost kernels' inputs in one pass: window energies and pixel counts of the
    left image (``el``, ``count``, (H, W) float32), and the right image's rows reversed
    into the padded rows of ``prr_pad`` (H, W + 2 pad) with its window energies
    ``err_pad`` and their inverse square roots ``irr_pad`` (0 where no energy); the
    padding is left untouched.

    The (2m+1) x (2n+1) window sums (zeros outside the image) run in float64 and are
    rounded to float32 once, as ``cv2.boxFilter`` does for float32 images: the
    prefiltered images hold whole numbers (quarter DN), so the running sums are exact
    and the energies equal the box filter's bit for bit."""
    cdef Py_ssize_t height = pl.shape[0], width = pl.shape[1]
    cdef double[::1] cl = np.zeros(width, np.float64)
    cdef double[::1] cr = np.zeros(width, np.float64)
    cdef Py_ssize_t x, y, yy, ya, ys, xa, xs, rows, j
    cdef double a, b, sl, sr
    cdef float e
    with nogil:
        for yy in range(min(n, height)):
            for x in range(width):
                a = pl[yy, x]
                b = pr[yy, x]
                cl[x] += a * a
                cr[x] += b * b
        for y in range(height):
            ya = y + n
            ys = y - n - 1
            if ya < height:
                for x in range(width):
                    a = pl[ya, x]
                    b = pr[ya, x]
                    cl[x] += a * a
                    cr[x] += b * b
            if ys >= 0:
                for x in range(width):
                    a = pl[ys, x]
                    b = pr[ys, x]
                    cl[x] -= a * a
                    cr[x] -= b * b
            rows = min(height - 1, ya) - max(0, y - n) + 1
            sl = 0.0
            sr = 0.0
            for x in range(min(m, width)):
                sl += cl[x]
                sr += cr[x]
            for x in range(width):
                xa = x + m
                xs = x - m - 1
                if xa < width:
                    sl += cl[xa]
                    sr += cr[xa]
                if xs >= 0:
                    sl -= cl[xs]
                    sr -= cr[xs]
                el[y, x] = <float>sl
                count[y, x] = <float>(rows * (min(width - 1, xa) - max(0, x - m) + 1))
                e = <float>sr
                j = pad + width - 1 - x
                prr_pad[y, j] = pr[y, x]
                err_pad[y, j] = e
                irr_pad[y, j] = <float>1.0 / sqrtf(e) if e > 0 else <float>0.0


def sheared_energies(const float[:, ::1] pr, Py_ssize_t m, Py_ssize_t n,
                     const int64_t[::1] shifts, Py_ssize_t pad, float[:, ::1] err_pad,
                     float[:, ::1] irr_pad):
    """Right window energies over sheared windows (slitcli.stereo.cost.
    sheared_right_energies): row dv (-n..n) of the window at right column xr sums the
    squares of columns ``xr - shifts[dv + n] - m .. + m`` (zeros outside), written
    along x reversed into ``err_pad[:, pad + W - 1 - xr]`` with the inverse square
    roots into ``irr_pad`` (0 where no energy); the padding is left untouched. The
    prefiltered values are whole quarter DN, so every sum is exact."""
    cdef Py_ssize_t height = pr.shape[0], width = pr.shape[1], smax = 0, y, x, k, r, xx
    cdef Py_ssize_t span
    for k in range(2 * n + 1):
        smax = max(smax, abs(shifts[k]))
    span = width + 2 * smax
    # row sums over 2m+1 columns, centres -smax .. W - 1 + smax
    cdef float[:, ::1] rows = np.zeros((height, span), np.float32)
    cdef float[::1] acc_row = np.zeros(width, np.float32)
    cdef double acc
    cdef float e, v
    with nogil:
        for r in range(height):
            acc = 0.0
            for xx in range(-smax - m, -smax + m):
                if 0 <= xx < width:
                    v = pr[r, xx]
                    acc += v * v
            for x in range(span):
                xx = x - smax + m
                if 0 <= xx < width:
                    v = pr[r, xx]
                    acc += v * v
                xx = x - smax - m - 1
                if 0 <= xx < width:
                    v = pr[r, xx]
                    acc -= v * v
                rows[r, x] = <float>acc
        for y in range(height):
            for x in range(width):
                acc_row[x] = 0.0
            for k in range(2 * n + 1):
                r = y + k - n
                if 0 <= r < height:
                    add_floats(&acc_row[0], &rows[r, smax - shifts[k]], width)
            for x in range(width):
                e = acc_row[x]
                err_pad[y, pad + width - 1 - x] = e
                irr_pad[y, pad + width - 1 - x] = <float>1.0 / sqrtf(e) if e > 0 else <float>0.0
