"""The Eq. 10 matcher's kernel: cost, winner-take-all, subpixel, uniqueness, left-right
and texture tests, for a band of rows (:func:`nssd_rows`).

The kernel is compiled ahead of time (Cython, slitcli/stereo/_c/nssd.pyx, built by the
package's install): it walks the image one row at a time and keeps, per column, the
running vertical window sums of squared differences of all disparities, so the full
cost volume is never stored; pixels whose window or disparities leave the image take a
general path (clipped windows, masked Eq. 10). It releases the GIL, so
slitcli.stereo.matcher runs bands of rows on several threads.

All sums are of integers below 2**24 (the prefiltered images are quantised), so they are
exact in float32 and the result does not depend on the order of the additions or on
how the rows are split into bands. No reassociation and no approximate reciprocal:
every quotient and inverse root is IEEE float32 (float64 where the formula mixes in a
double), so the disparities are the same bits on every machine.
"""

from __future__ import annotations

from slitcli.stereo._c.nssd import BIG_INV_F32 as BIG_INV
from slitcli.stereo._c.nssd import SSD_EPS_F32 as SSD_EPS
from slitcli.stereo._c.nssd import nssd_rows

__all__ = ["BIG_INV", "SSD_EPS", "nssd_rows"]
