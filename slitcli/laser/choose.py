"""Step 5 of the stripe model: the choice along the stripe (paper Eq. 4, segments, rows
smoothed along them; compiled).

:func:`choose_stripe` is Eq. 4 per column among the candidates that pass
:mod:`slitcli.laser.judge`'s tests, followed by the segments. The kernels are
:mod:`slitcli.laser._c.choose`'s, re-exported here; this module keeps their constants.
"""
from __future__ import annotations

import numpy as np

from slitcli.laser._c.choose import best_path, choose_stripe, links, smooth_rows

__all__ = ["MAX_GAP", "SMOOTH_CORNER_PX", "SMOOTH_HALF", "best_path",
           "choose_stripe", "links", "smooth_rows", "stripe_pieces"]

#: found columns of one segment may be this many columns apart
MAX_GAP = 2
#: rows are smoothed along a segment over this many columns either side
SMOOTH_HALF = 4
#: a second difference of the rows beyond this (and four times its noise) is a corner
SMOOTH_CORNER_PX = 0.5


def stripe_pieces(v_px: np.ndarray, max_gap: int,
                  max_jump_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The found columns of a stripe and the piece each lies on.

    A piece: found columns (``v_px`` (W,) finite; image rows) at most ``max_gap``
    columns apart whose rows step by at most ``max_jump_px`` per column.

    Returns
    -------
    cols : ndarray, shape (N,), int
        The found columns, in order.
    piece : ndarray, shape (N,), int
        Their piece, 0, 1, ... from the left.
    """
    v = np.asarray(v_px, dtype=np.float64)
    cols = np.flatnonzero(np.isfinite(v))
    if cols.size == 0:
        return cols, np.zeros(0, np.intp)
    step = np.diff(cols)
    new = np.concatenate(([True], (step > max_gap + 1) |
                          (np.abs(np.diff(v[cols])) > max_jump_px * step)))
    return cols, np.cumsum(new) - 1
