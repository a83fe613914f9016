"""Compiled kernel of the SGM bracket test (slitcli.stereo.sgm).

A pixel that semi-global aggregation matched but whose own neighbourhood does not carry
the match (the support test rejected it: weak texture) is kept when supported pixels
on both sides of it, along its row or along its column and within ``reach`` pixels,
bracket its disparity: ``min(d_a, d_b) - tol <= d <= max(d_a, d_b) + tol``. On a
smooth surface (plain, slanted or not) the aggregated disparity runs between those of
its textured borders; where the aggregation carried a neighbour's disparity across an
edge onto a plain surface (a floor's or a wall's disparity into a plain box, whose
own silhouette matched at the box's disparity) the box's borders do not bracket it.
"""

from libc.math cimport fabsf
from libc.stdint cimport int64_t, uint8_t

import numpy as np

cdef extern from "math.h":
    const float NAN


cdef inline bint _between(float d, float a, float b, float tol, float span) noexcept nogil:
    """``min(a, b) - tol <= d <= max(a, b) + tol`` and ``|a - b| <= span``."""
    cdef float lo = b if b < a else a
    cdef float hi = b if b > a else a
    return (d >= lo - tol) and (d <= hi + tol) and fabsf(a - b) <= span


def bracket_rows(const float[:, ::1] disp, const uint8_t[:, ::1] reason, int code_valid,
                 const uint8_t[::1] weak, Py_ssize_t reach, float tol, float span,
                 uint8_t[:, ::1] keep):
    """Set ``keep`` (H, W) bool where a pixel whose code is marked in ``weak`` (bool per
    code, 256) is bracketed along its row or its column by pixels of code
    ``code_valid`` within ``reach`` px (``tol``, ``span`` in px, see the module).

    ``disp`` (H, W) float32, px; ``reason`` (H, W) uint8 codes. Only ``keep`` is
    written (False for the other non-valid pixels; valid pixels untouched)."""
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], x, y, lx, rx
    cdef float[::1] left = np.empty(width, np.float32)
    # column scans: the last valid disparity above (and its row) per column
    cdef float[:, ::1] up_d = np.full((height, width), np.nan, np.float32)
    cdef float[::1] last_d = np.full(width, np.nan, np.float32)
    cdef int64_t[::1] last_y = np.full(width, -(1 << 30), np.int64)
    cdef float d, a, ld, rd
    cdef uint8_t r
    with nogil:
        for y in range(height):
            for x in range(width):
                if reason[y, x] == code_valid:
                    last_d[x] = disp[y, x]
                    last_y[x] = y
                elif y - last_y[x] <= reach:
                    up_d[y, x] = last_d[x]
        for x in range(width):
            last_d[x] = NAN
            last_y[x] = 1 << 30
        for y in range(height - 1, -1, -1):
            for x in range(width):
                r = reason[y, x]
                if r == code_valid:
                    last_d[x] = disp[y, x]
                    last_y[x] = y
                    continue
                keep[y, x] = False
                if not weak[r]:
                    continue
                a = up_d[y, x]
                if last_y[x] - y <= reach and a == a:
                    keep[y, x] = _between(disp[y, x], a, last_d[x], tol, span)
        for y in range(height):
            ld = NAN
            lx = -(1 << 30)
            for x in range(width):
                if reason[y, x] == code_valid:
                    ld = disp[y, x]
                    lx = x
                    left[x] = NAN
                else:
                    left[x] = ld if x - lx <= reach else NAN
            rd = NAN
            rx = 1 << 30
            for x in range(width - 1, -1, -1):
                r = reason[y, x]
                if r == code_valid:
                    rd = disp[y, x]
                    rx = x
                    continue
                if not weak[r] or keep[y, x]:
                    continue
                a = left[x]
                if rx - x <= reach and a == a:
                    d = disp[y, x]
                    keep[y, x] = _between(d, a, rd, tol, span)


cdef inline float _nearest(const float[:, ::1] disp, const uint8_t[:, ::1] reason,
                           const uint8_t[:, ::1] mark, int code_valid, Py_ssize_t y,
                           Py_ssize_t x, Py_ssize_t dy, Py_ssize_t dx,
                           Py_ssize_t reach) noexcept nogil:
    """The disparity of the nearest pixel of code ``code_valid`` and not marked from
    (y, x) in steps (dy, dx), within ``reach`` steps; NaN where there is none."""
    cdef Py_ssize_t k, yy = y, xx = x, height = disp.shape[0], width = disp.shape[1]
    for k in range(reach):
        yy += dy
        xx += dx
        if yy < 0 or yy >= height or xx < 0 or xx >= width:
            break
        if reason[yy, xx] == code_valid and not mark[yy, xx]:
            return disp[yy, xx]
    return NAN


def bracket_marked(const float[:, ::1] disp, uint8_t[:, ::1] reason, int code_valid,
                   const uint8_t[:, ::1] mark, Py_ssize_t reach, float tol, float span,
                   int code):
    """:func:`bracket_rows` for the few pixels ``mark`` (H, W) sets: each is tested
    against the nearest pixels of code ``code_valid`` that are not marked, searched
    from it along its row and its column (the scans of :func:`bracket_rows` over the
    whole image find the same pixels), and gets ``code`` in ``reason`` where it is not
    bracketed. The same rule as :func:`bracket_rows`, whose result
    for a copy of ``reason`` with the marked pixels as its only weak code this equals
    (the marked pixels are never bracketing pixels, so writing their codes in place
    changes no other pixel's test). The bracket test's second pass
    (slitcli.stereo.sgm): the small regions are a few hundred pixels, and a scan of
    the whole image for them took as long as the first pass."""
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], x, y
    cdef float d, a, b
    cdef bint keep
    if (reason.shape[0] != height or reason.shape[1] != width or mark.shape[0] != height
            or mark.shape[1] != width):
        raise ValueError("bracket_marked: every array must have the shape of disp")
    with nogil:
        for y in range(height):
            for x in range(width):
                if not mark[y, x]:
                    continue
                d = disp[y, x]
                keep = False
                a = _nearest(disp, reason, mark, code_valid, y, x, -1, 0, reach)
                if a == a:
                    b = _nearest(disp, reason, mark, code_valid, y, x, 1, 0, reach)
                    keep = _between(d, a, b, tol, span)
                if not keep:
                    a = _nearest(disp, reason, mark, code_valid, y, x, 0, -1, reach)
                    if a == a:
                        b = _nearest(disp, reason, mark, code_valid, y, x, 0, 1, reach)
                        keep = _between(d, a, b, tol, span)
                if not keep:
                    reason[y, x] = code
