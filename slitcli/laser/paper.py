"""The paper's Eqs. 1-4 taken literally (``LaserParams.method = "paper"``), a baseline.

Per pixel of the raw image (no background, no noise model): the relative intensities
(Eq. 1), the red tests (Eq. 2) ``R > min_th`` and ``R - max(G, B) > min_delta_th``, and
white rejection (Eq. 3) ``r > alpha max(g, b)``. Per column the passing pixels form
runs; each run scores (Eq. 4) ``r_max / 255 + beta f(y) + gamma g(I)``, with ``f`` the
closeness ``exp(-dv^2 / 2 continuity_px^2)`` of its row to the previous column's
choice and ``g = 1 - run length / max width`` (a wide red object scores low). The best
run's row is the centre of gravity of its red.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def paper_columns(img: np.ndarray, mask: np.ndarray, min_th: float, min_delta_th: float,
                  alpha: float, beta: float, gamma: float, continuity_px: float,
                  max_width_px: float, v_out: np.ndarray,
                  amp_out: np.ndarray) -> None:  # pragma: no cover
    """Eqs. 1-4 on ``img`` (W, H, 3) BGR uint8 (transposed), ``mask`` (W, H) the searched
    pixels; per column the row (NaN none) and the run's red peak (DN)."""
    n_cols, n = img.shape[0], img.shape[1]
    prev = np.nan
    for i in range(n_cols):
        v_out[i] = np.nan
        amp_out[i] = np.nan
        best = -1e300
        j = 0
        while j < n:
            ok = False
            if mask[i, j]:
                r, g, b = float(img[i, j, 2]), float(img[i, j, 1]), float(img[i, j, 0])
                s = r + g + b
                ok = s > 0 and r / s > min_th and (r - max(g, b)) / s > min_delta_th and \
                    r > alpha * max(g, b)
            if not ok:
                j += 1
                continue
            a = j
            rmax = 0.0
            sw = 0.0
            sv = 0.0
            while j < n and mask[i, j]:
                r, g, b = float(img[i, j, 2]), float(img[i, j, 1]), float(img[i, j, 0])
                s = r + g + b
                if not (s > 0 and r / s > min_th and (r - max(g, b)) / s > min_delta_th and
                        r > alpha * max(g, b)):
                    break
                rmax = max(rmax, r)
                sw += r
                sv += r * j
                j += 1
            centre = sv / sw if sw > 0 else 0.5 * (a + j - 1)
            f = 0.0
            if np.isfinite(prev):
                d = (centre - prev) / continuity_px
                f = math.exp(-0.5 * d * d)
            score = rmax / 255.0 + beta * f + gamma * (1.0 - (j - a) / max_width_px)
            if score > best:
                best = score
                v_out[i] = centre
                amp_out[i] = rmax
        if np.isfinite(v_out[i]):
            prev = v_out[i]
