"""The paper's Eqs. 1-4 taken literally (``LaserParams.method = "paper"``), a baseline.

Per pixel of the raw image (no background, no noise model): the relative intensities
(Eq. 1), the red tests (Eq. 2) ``R > min_th`` and ``R - max(G, B) > min_delta_th``, and
white rejection (Eq. 3) ``r > alpha max(g, b)``. Per column the passing pixels form
runs; each run scores (Eq. 4) ``r_max / 255 + beta f(y) + gamma g(I)``, with ``f`` the
closeness ``exp(-dv^2 / 2 continuity_px^2)`` of its row to the previous column's
choice and ``g = 1 - run length / max width`` (a wide red object scores low). The best
run's row is the centre of gravity of its red.

The kernel is compiled ahead of time (Cython, :mod:`slitcli.laser._c.paper`) and
re-exported here.
"""

from __future__ import annotations

from slitcli.laser._c.paper import paper_columns

__all__ = ["paper_columns"]
