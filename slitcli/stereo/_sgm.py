"""Kernels of semi-global aggregation over the Eq. 10 cost (compiled ahead of time:
slitcli/stereo/_c/sgm.pyx, where the equations are documented).

- :func:`window_inputs`: window energies and counts, the right image reversed and padded;
- :func:`cost_rows`: quantised Eq. 10 costs (H, W, D) uint16 of a band of rows;
- :func:`aggregate_pass`: the path-cost sum of one sweep (top-down or bottom-up);
- :func:`winners_rows`: winner-take-all with the texture, uniqueness and left-right
  tests and the subpixel parabola.

All release the GIL and take any disparity count D >= 2.
"""

from __future__ import annotations

from slitcli.stereo._c.sgm import aggregate_pass, cost_rows, window_inputs, winners_rows

#: path rows carry this at both ends (above any path cost), so that d -+ 1 needs no branch
SENTINEL = 0x3FFF
#: winner keys: ``(s_a + s_b) << KEY_SHIFT | i``, NO_KEY where a disparity has no candidate
KEY_SHIFT = 9
NO_KEY = 0x7FFFFFFF

__all__ = ["KEY_SHIFT", "NO_KEY", "SENTINEL", "aggregate_pass", "cost_rows", "window_inputs",
           "winners_rows"]
