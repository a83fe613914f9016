"""Compiled kernels of the ground line fit (slitcli.stereo.ground.fit_ground_line).

The fit works on a few thousand first-pass disparities; in NumPy its some sixty array
calls on them took about 1 ms of a 320 x 240 frame (more than the first pass itself),
nearly all of it call overhead. Here each step is one loop:

- :func:`valid_points`: the finite disparities' rows and values, in row-major order
  (``np.nonzero``'s);
- :func:`line_mass`: each hypothesis' v-disparity mass within ``tol`` of its line, from
  the histogram's cumulated rows (the same integer bins as the NumPy version: the same
  masses, so the same best hypothesis);
- :func:`line_refit`: least squares on one line's inliers (float64 sums in order);
- :func:`line_inliers`: one line's inliers' residuals and their count per row.
"""

from libc.math cimport fabs, floor
from libc.stdint cimport int32_t, int64_t

import numpy as np


def valid_points(const float[:, ::1] disp, int32_t[::1] rows, double[::1] r,
                 double[::1] d) -> int:
    """The finite entries of ``disp`` (Hr, Wr) in row-major order: their rows into
    ``rows`` (int32) and ``r`` (float64) and their values into ``d`` (float64), each
    at least Hr * Wr long. Returns their number."""
    cdef Py_ssize_t hr = disp.shape[0], wr = disp.shape[1], y, x, n = 0
    cdef float v
    with nogil:
        for y in range(hr):
            for x in range(wr):
                v = disp[y, x]
                if v == v and v - v == 0:   # finite: not NaN, not +-inf
                    rows[n] = <int32_t>y
                    r[n] = <double>y
                    d[n] = <double>v
                    n += 1
    return n


def line_mass(const int32_t[::1] rows, const double[::1] d, Py_ssize_t hr, double q,
              int64_t lo, int64_t nb, double half, const double[::1] g,
              const double[::1] b, int64_t[::1] mass):
    """v-disparity mass of each line ``d = g[k] r + b[k]`` within ``half`` bins.

    Bins of width ``q`` (bin ``floor(d / q) - lo``, ``nb`` of them per row); the line's
    bins at row ``r`` are ``[a, z)`` with ``a = clip(floor(c - half), 0, nb)``,
    ``z = clip(floor(c + half) + 1, 0, nb)``, ``c = (g r + b) / q - lo``, and
    ``mass[k]`` is the sum over rows of the points in them."""
    cdef Py_ssize_t n = d.shape[0], k, v, i
    cdef Py_ssize_t stride = nb + 1
    cdef int64_t[::1] cum = np.zeros(hr * stride, np.int64)
    cdef int64_t a, z, total
    cdef double c
    with nogil:
        for i in range(n):
            cum[rows[i] * stride + 1 + <int64_t>floor(d[i] / q) - lo] += 1
        for v in range(hr):
            for i in range(1, stride):
                cum[v * stride + i] += cum[v * stride + i - 1]
        for k in range(g.shape[0]):
            total = 0
            for v in range(hr):
                c = (g[k] * <double>v + b[k]) / q - <double>lo
                a = <int64_t>_clip(floor(c - half), 0.0, <double>nb)
                z = <int64_t>_clip(floor(c + half) + 1.0, 0.0, <double>nb)
                total += cum[v * stride + z] - cum[v * stride + a]
            mass[k] = total


cdef inline double _clip(double x, double lo, double hi) noexcept nogil:
    return lo if x < lo else (hi if x > hi else x)


def line_refit(const double[::1] r, const double[::1] d, double g, double b, double tol):
    """Least squares line through the points within ``tol`` of ``d = g r + b``.

    Returns (g, b, count, r_mean, sxx): the refitted gradient and intercept (the given
    ones where fewer than 2 points or no spread in rows), the inliers' number, mean row
    and sum of squared row deviations."""
    cdef Py_ssize_t n = d.shape[0], i, count = 0
    cdef double sr = 0, sd = 0, r_mean, d_mean, sxx = 0, sxd = 0, dr
    with nogil:
        for i in range(n):
            if fabs(d[i] - (g * r[i] + b)) <= tol:
                count += 1
                sr += r[i]
                sd += d[i]
        r_mean = sr / count if count else 0.0
        d_mean = sd / count if count else 0.0
        for i in range(n):
            if fabs(d[i] - (g * r[i] + b)) <= tol:
                dr = r[i] - r_mean
                sxx += dr * dr
                sxd += dr * d[i]
    if count < 2 or sxx <= 0:
        return g, b, count, r_mean, sxx
    return sxd / sxx, d_mean - (sxd / sxx) * r_mean, count, r_mean, sxx


def line_inliers(const int32_t[::1] rows, const double[::1] r, const double[::1] d,
                 double g, double b, double tol, double[::1] resid,
                 int64_t[::1] per_row) -> int:
    """The residuals ``d - (g r + b)`` of the points within ``tol`` of the line into
    ``resid`` and their number per row added to ``per_row`` (Hr,). Returns how many."""
    cdef Py_ssize_t n = d.shape[0], i, count = 0
    cdef double e
    with nogil:
        for i in range(n):
            e = d[i] - (g * r[i] + b)
            if fabs(e) <= tol:
                resid[count] = e
                per_row[rows[i]] += 1
                count += 1
    return count
