"""Compiled kernel of SGM's subpixel step (slitcli.stereo.sgm.raw_subpixel).

The winner step of SGM fits its parabola to the aggregated sums, whose path penalties
pull it towards the whole pixel; :func:`cost_subpixel` refits it to the pixel's own
quantised Eq. 10 costs where they locate the minimum (see slitcli.stereo.sgm).
"""

from libc.math cimport floorf
from libc.stdint cimport uint8_t, uint16_t


def cost_subpixel(float[:, ::1] disp, const uint16_t[:, :, ::1] cost, Py_ssize_t dmin,
                  double den_min, double top, const uint8_t[:, ::1] where=None):
    """Replace the subpixel offsets of ``disp`` (H, W) float32 px, in place, by the
    parabola through the costs ``cost`` (H, W, D) uint16 at ``bi - 1, bi, bi + 1``,
    ``bi`` the whole disparity nearest ``disp - dmin``, where ``bi`` is a local minimum
    of them, both neighbours cost less than ``top`` (the clip: no partner) and the
    curvature ``C(bi - 1) - 2 C(bi) + C(bi + 1)`` reaches ``den_min`` (and is > 0).
    NaN pixels and winners at the ends of the range stay as they are, and so do the
    pixels where ``where`` (H, W) bool as uint8, if given, is 0."""
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], num = cost.shape[2]
    cdef Py_ssize_t y, x, bi
    cdef float v, rel, cm, c0, cp, den
    cdef bint masked = where is not None
    if cost.shape[0] != height or cost.shape[1] != width:
        raise ValueError("cost_subpixel: cost must be (H, W, D) of disp's (H, W)")
    if masked and (where.shape[0] != height or where.shape[1] != width):
        raise ValueError("cost_subpixel: where must be (H, W) of disp")
    with nogil:
        for y in range(height):
            for x in range(width):
                if masked and where[y, x] == 0:
                    continue
                v = disp[y, x]
                if v != v:
                    continue
                rel = v - <float>dmin
                if not (rel >= 0.5 and rel <= <float>num - <float>1.5):
                    continue
                bi = <Py_ssize_t>floorf(rel + <float>0.5)
                cm = <float>cost[y, x, bi - 1]
                c0 = <float>cost[y, x, bi]
                cp = <float>cost[y, x, bi + 1]
                den = cm - <float>2.0 * c0 + cp
                if cm >= c0 and cp >= c0 and cm < top and cp < top and den > 0 \
                        and den >= den_min:
                    disp[y, x] = <float>(bi + dmin) + <float>0.5 * (cm - cp) / den
