"""Compiled kernel of SGM's subpixel step (slitcli.stereo.sgm.raw_subpixel).

The winner step of SGM fits its parabola to the aggregated sums, whose path penalties
pull it towards the whole pixel; :func:`cost_subpixel` refits it to the pixel's own
quantised Eq. 10 costs where they locate the minimum (see slitcli.stereo.sgm).
"""

from libc.stdint cimport uint8_t, uint16_t

from slitcli.stereo._c.refit cimport refit_row


def cost_subpixel(float[:, ::1] disp, const uint16_t[:, :, ::1] cost, Py_ssize_t dmin,
                  double den_min, double top, const uint8_t[:, ::1] where=None):
    """Replace the subpixel offsets of ``disp`` (H, W) float32 px, in place, by the
    parabola through the costs ``cost`` (H, W, D) uint16 at ``bi - 1, bi, bi + 1``,
    ``bi`` the whole disparity nearest ``disp - dmin``, where ``bi`` is a local minimum
    of them, both neighbours cost less than ``top`` (the clip: no partner) and the
    curvature ``C(bi - 1) - 2 C(bi) + C(bi + 1)`` reaches ``den_min`` (and is > 0).
    NaN pixels and winners at the ends of the range stay as they are, and so do the
    pixels where ``where`` (H, W) bool as uint8, if given, is 0 (refit.pxd, the same
    row function the fused passes of sgm.pyx run)."""
    cdef Py_ssize_t height = disp.shape[0], width = disp.shape[1], num = cost.shape[2]
    cdef Py_ssize_t y
    cdef bint masked = where is not None
    if cost.shape[0] != height or cost.shape[1] != width:
        raise ValueError("cost_subpixel: cost must be (H, W, D) of disp's (H, W)")
    if masked and (where.shape[0] != height or where.shape[1] != width):
        raise ValueError("cost_subpixel: where must be (H, W) of disp")
    if height == 0 or width == 0 or num < 3:
        return   # no whole disparity has both neighbours inside the range
    with nogil:
        for y in range(height):
            refit_row(&disp[y, 0], &cost[y, 0, 0], &where[y, 0] if masked else NULL,
                      width, num, dmin, den_min, top)
