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

from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

import numpy as np

from slitcli.stereo._c.nssd import BIG_INV_F32 as BIG_INV
from slitcli.stereo._c.nssd import SSD_EPS_F32 as SSD_EPS
from slitcli.stereo._c.nssd import nssd_rows
from slitcli.stereo.bands import run_row_bands
from slitcli.stereo.cost import _QUANT

if TYPE_CHECKING:
    from slitcli.stereo.matcher import MatcherParams


def winners(pl: np.ndarray, pr: np.ndarray, params: MatcherParams,
            pool: ThreadPoolExecutor | None, threads: int, disp: np.ndarray,
            cost: np.ndarray, reason: np.ndarray, rdisp: np.ndarray) -> None:
    """Eq. 10 winner-take-all with the window-energy, uniqueness and left-right tests
    and the subpixel parabola over prefiltered images ``pl``, ``pr`` (H, W) (compiled,
    in bands of rows), filling the outputs (H, W): ``disp`` px (NaN = none), ``cost``,
    ``reason`` (slitcli.stereo.reasons.Reason) and ``rdisp``, the right view's
    disparities (read by the depth-edge filter). The local matcher's winner step and
    the ground estimate's first pass (slitcli.stereo.ground)."""
    m = params.window_w_px // 2
    n = params.window_h_px // 2
    prr = np.ascontiguousarray(pr[:, ::-1])
    # the prefiltered image is zero-mean: its window RMS is its texture, tested in the
    # kernel on the window energy: RMS / 4 < t  <=>  energy < (4 t)^2 x pixel count
    energy_min = (params.texture_min_dn * _QUANT) ** 2 if params.prefilter != "none" else 0.0
    args = (int(params.min_disparity_px), int(params.num_disparities), int(m), int(n),
            float(params.uniqueness_ratio), float(params.lr_max_diff_px),
            params.subpixel == "parabola", np.float32(energy_min), disp, cost, reason, rdisp)
    run_row_bands(lambda y0, y1: nssd_rows(pl, pr, prr, y0, y1, *args), pl.shape[0],
                  pool, threads, min_rows=2 * n + 1)


__all__ = ["BIG_INV", "SSD_EPS", "nssd_rows", "winners"]
