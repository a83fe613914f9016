"""Step 3 of the stripe model: candidate crossings per column, seeded and fitted.

Seeds of column ``i`` are

* local maxima (within ``NMS_HALF`` rows) of the laser evidence ``y`` at least
  ``seed_dn`` high (``seed_z`` noise sigmas), and
* clipped runs (red at the saturation level) at most ``max_run`` rows long with red
  light on both sides (the contrast's ``t_r - max(t_g, t_b) >= seed_dn`` within
  ``FLANK_ROWS`` rows beyond each end): a clipped laser core, red or turned white,
  keeps red flanks, a white highlight's fringe is white.

The ``K`` strongest (clipped cores first) are fitted (:func:`~.profile.fit_gaussian`)
on the evidence in a window of ``3 s + 3`` rows either side (``s`` the seed's half-
maximum width), clipped rows left out; a clipped core whose flank fit does not put
its centre on the plateau is centred on the plateau (:func:`~.profile.plateau_centre`).
Each seed is fitted on the column's evidence and on the evidence averaged along the
stripe, the more significant fit kept; a fit's significance is at most its seed screen
(the matched filter at the seed's row and width) over ``SEED_EFFICIENCY``, so the
evidence with the larger screen is fitted first and the other only where that bound can
beat it. Each fit's significance is judged against the local noise: the larger of the
image's evidence noise and the robust noise of the evidence around the candidate (its
core left out), so red texture that the colour cannot cancel raises the bar where it is.

The kernels (``column_candidates``, ``fill_gaps``, ``sheet_width_px``, ``evidence_live``
and the seed screen ``_linear_z``) are compiled C, ``slitcli/laser/_c/candidates.pyx``
(``fill_gaps``: ``_c/gaps.pyx``),
re-exported here (``column_candidates`` runs bands of columns on threads); this module
keeps their constants, which that file mirrors (a test checks that the two agree).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from slitcli.laser._c import candidates as _kernels
from slitcli.laser._c.candidates import (
    _linear_z,
    evidence_live,
    sheet_width_px,
)
from slitcli.laser._c.gaps import fill_gaps
from slitcli.stereo.bands import kernel_threads, run_bands

__all__ = ["_linear_z", "column_candidates", "evidence_live", "fill_gaps", "run_column_bands",
           "sheet_width_px"]

NMS_HALF = 2  # half-width of the non-maximum suppression along a column, px
FLANK_ROWS = 2  # rows beyond a clipped run that must show laser light
NOISE_HALF = 24  # rows either side whose evidence gives a candidate's local noise
N_SEEDS = 5  # seeds fitted per column, at most
SEED_MIN_SIGMA_PX = 0.6  # narrowest width a seed starts its fit with
#: share of a Gaussian's matched-filter significance left when the filter sits half a
#: row off its centre (a seed is a whole row) at the narrowest seed width: the
#: normalised correlation of two Gaussians of width s offset by d, exp(-d^2 / (4 s^2))
SEED_EFFICIENCY = math.exp(-0.25 / (4.0 * SEED_MIN_SIGMA_PX ** 2))
#: mean absolute deviation of a Gaussian is sqrt(2 / pi) sigma; the lag-2 residual's
#: sigma is sqrt(1.5) sigma
MEAN_TO_SIGMA = math.sqrt(math.pi / 2.0) / math.sqrt(1.5)
#: residuals beyond this many global noise sigmas count as that many (an edge)
CLIP_SIGMAS = 5.0
#: fewest columns of a band
MIN_BAND_COLS = 16


def column_candidates(img: np.ndarray, bg: np.ndarray, y: np.ndarray, y_avg: np.ndarray,
                      clipped: np.ndarray, mask: np.ndarray, sigma_y: float,
                      sigma_avg: float, seed_dn: float, strong_z: float, sat_dn: float,
                      s_max: float, shape_error: float, max_chi2: float, weak_z: float,
                      out: np.ndarray, sat_gb: tuple[float, float] | None = None) -> None:
    """Fitted candidates of every column into ``out`` (W, K, N_FIELDS), NaN where none.

    The compiled kernel's (``slitcli/laser/_c/candidates.pyx``; its docstring names the
    arguments), over bands of columns on up to ``SLITCLI_THREADS`` threads, and only on
    cores that no other task holds (:func:`~slitcli.stereo.bands.kernel_threads`: one in
    a process pool's workers). Columns are independent, so the result is the same on
    any number of threads. ``sat_gb``: green's and blue's clipping levels (a white
    core reaches both), DN; None: ``sat_dn``.
    """
    sat_g, sat_b = (-1.0, -1.0) if sat_gb is None else sat_gb

    def band(c0: int, c1: int) -> None:
        _kernels.column_candidates(img, bg, y, y_avg, clipped, mask, sigma_y, sigma_avg,
                                   seed_dn, strong_z, sat_dn, s_max, shape_error, max_chi2,
                                   weak_z, out, c0, c1, sat_g, sat_b)

    threads = kernel_threads()
    run_column_bands(band, out.shape[0], threads)


def run_column_bands(fn: Callable[[int, int], object], n_cols: int, threads: int) -> None:
    """Call ``fn(c0, c1)`` over bands of columns covering 0..n_cols on ``threads`` threads
    (:func:`slitcli.stereo.bands.run_bands`, bands of at least ``MIN_BAND_COLS``)."""
    run_bands(fn, n_cols, threads, min_len=MIN_BAND_COLS)
