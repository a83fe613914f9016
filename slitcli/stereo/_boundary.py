"""Compiled tests of the Eq. 10 matcher at depth edges (slitcli.stereo.matcher).

A (2m+1) x (2n+1) correlation window that straddles a depth edge is matched by
whichever surface carries the stronger texture, so that surface's disparity is
carried up to half a window past its silhouette ("foreground fattening"): the
pixels just beside an object get the object's range. :func:`post_rows` re-examines
the matches, row by row, with evidence that does not straddle the edge:

- local support: the zero-mean normalised correlation of the (2r+1)^2 grey windows of
  the left image and of the right image warped by the winning disparities must reach
  ``support_min_zncc``;
- one-sided support: a pixel next to a weakly supported pixel (a textureless or
  wrongly matched neighbour) must also be supported by the (2r+1)-wide, window-tall
  block centred one column towards that neighbour. A textureless pixel that borrowed
  its disparity from texture on its other side has nothing there to correlate.
- cross support: the match must also hold on both sides of the pixel along one axis:
  the (2r+1)^2 left blocks just above and just below it (rows y -+ (2r+1)), or just
  left and right of it, correlated with the right image at the pixel's own disparity,
  must both reach ``cross_min_zncc``. A textureless pixel within half a window of an
  edge or of the laser stripe has that texture on one side only; a pixel of a thin
  pole keeps the blocks above and below it, and one on a silhouette the blocks along
  the silhouette. The blocks do not overlap the centred one, so on a plain surface
  the sensor noise passes the centred and both blocks of an axis rarely together.
  A pixel whose own centred correlation reaches ``strong`` carries its match alone and
  is not tested (most pixels of a textured surface: this keeps the test cheap).
- depth edges, a two-hypothesis test on the pixel's own column. Where a
  valid neighbour within ``radius`` columns lies at a smaller disparity (a depth
  step), the grey-level column of the pixel (window-tall, one pixel wide, so it
  cannot straddle a vertical edge) is compared with the right image at the pixel's
  disparity and at the neighbour's; if the neighbour's explains it with less than
  ``ratio`` of the residual, the pixel belongs to the farther surface and is
  invalid. The same test runs for the right image's pixel the match lands on, with
  the disparities of the right view's own neighbours (confirmed by the left view):
  a pixel hidden from the right camera (the band beside an object's left edge)
  takes the object's disparity when its window reaches the object, and its partner
  in the right image is then better explained by the farther surface.

All four run in one pass over a band of rows (``y0 .. y1 - 1``; the warped right
image is kept for the 2r+1 rows around the current one only), O(pixels): the
per-pixel work is a fixed-size window, and the residual columns are computed only
next to depth steps (a row-wise running minimum of the candidates says where). The
kernel releases the GIL; each row's result depends only on read-only inputs, so bands
can run on plain threads.

The kernels are compiled ahead of time (Cython: slitcli/stereo/_c/boundary.pyx, the
depth-edge test in slitcli/stereo/_c/depth_edge.pxd, and the block correlations of the
one-sided and cross tests, eight at a time, in slitcli/stereo/_c/zncc.pxd), so this
module imports no JIT compiler. They reproduce
the numba kernels they replaced bit for bit, including the fused multiply-adds and
reciprocals that numba's fastmath had made (docs/notes/stereo-support-cython.md).
"""

from __future__ import annotations

from slitcli.stereo._c.boundary import (
    REASON_BOUNDARY,
    REASON_SUPPORT,
    post_rows,
    support_zncc,
    window_min,
)

__all__ = ["REASON_BOUNDARY", "REASON_SUPPORT", "post_rows", "support_zncc", "window_min"]
