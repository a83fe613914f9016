"""Subsampled chroma (JPEG 4:2:0): how the image tells it, and the stripe's row on the luma.

A JPEG codec stores luma ``Y`` at full resolution and the two chroma planes (``Cb``,
``Cr``) at half the vertical and horizontal resolution in 4:2:0 (webcams, MJPEG, most
camera JPEGs): each chroma sample is the mean of a 2x2 block, the decoder interpolates
them back, and the quantiser smooths chroma more than luma. A red stripe's red excess
``r - (g + b) / 2`` is almost all chroma (with ``r = Y + 1.402 Cr``, ``g = Y - 0.344 Cb -
0.714 Cr``, ``b = Y + 1.772 Cb``, the luma cancels in it), so the laser evidence sees the
stripe blurred: at least by the two-row mean (variance 1/4 px^2) and the decoder's linear
interpolation between samples two rows apart (a triangle of half-width 2 rows, 2/3 px^2),
:data:`CHAIN_VAR_PX2` in all, and phase-locked to the sample grid (row errors of up to
half a pixel that do not average out along a level stripe). The luma keeps the stripe at
full resolution.

:func:`chroma_smoothness` tells such an image from the image itself (the library takes
arrays; a file's sampling factors are not known): sensor noise and fine detail are as
rough in chroma as in luma, so the ratio of short-lag to long-lag differences is about
the same in both; after subsampling and chroma quantisation, chroma's short-lag
differences nearly vanish. :func:`luma_rows` fits the stripe's row again on the luma's
contrast where the evidence has found it.
"""

from __future__ import annotations

import math

import numpy as np

from slitcli.laser._c.luma import lag_medians as _lag_medians
from slitcli.laser._c.luma import luma_rows as _luma_rows

#: variance the 4:2:0 chain adds to a profile across rows: the two-row mean (1/4 px^2)
#: and the decoder's linear interpolation between samples two rows apart (a triangle of
#: half-width 2 rows: 2^2 / 6 px^2)
CHAIN_VAR_PX2 = 0.25 + 4.0 / 6.0
#: the long lag of the smoothness ratio, rows (beyond the 4:2:0 chain's reach)
LONG_LAG = 4
#: every SMOOTHNESS_STEP-th column enters the smoothness ratio (~9,000 pairs a lag at
#: 320x240)
SMOOTHNESS_STEP = 8
# JFIF's YCbCr: the luma and red-difference chroma of (b, g, r)
_Y_BGR = np.array([0.114, 0.587, 0.299], np.float32)
#: the lag medians' bin (slitcli/laser/_c/luma.pyx), DN
_BIN_DN = 0.25


def chroma_smoothness(img_t: np.ndarray, step: int) -> float:
    """How much smoother the image's red-difference chroma is than its luma down the
    columns (about 1 or more: as rough; near 0: subsampled or heavily quantised chroma).

    ``(D_C(1) / D_C(L)) / (D_Y(1) / D_Y(L))`` with ``D(k)`` the median absolute difference
    at a lag of ``k`` rows (to a quarter DN, the median's bin centre) over every
    ``step``-th column of ``img_t`` (W, H, 3) uint8 BGR (transposed: one image column per
    array row), ``L`` = :data:`LONG_LAG`, ``C`` = ``Cr``, ``Y`` the luma (JFIF). Infinite
    where the luma shows no differences (a flat image: nothing to tell); 0 where the
    luma does and the chroma shows none at the long lag (a plain surface through a
    codec that flattens chroma, or a grey image, which carries no red stripe anyway).
    """
    if img_t.shape[0] == 0 or img_t.shape[1] <= LONG_LAG:
        return math.inf
    d_y1, d_yl, d_c1, d_cl = _lag_medians(np.ascontiguousarray(img_t, dtype=np.uint8),
                                          step, LONG_LAG)
    # (a median in the first bin is "no difference")
    floor = 0.5 * _BIN_DN
    if d_y1 <= floor or d_yl <= floor:
        return math.inf
    if d_cl <= floor:
        return 0.0
    return (d_c1 / d_cl) / (d_y1 / d_yl)


def luma_sigma(img_t: np.ndarray, step: int) -> float:
    """Noise sigma of the luma (JFIF), DN: the evidence's robust estimate
    (:func:`slitcli.laser.evidence.robust_sigma`, the median absolute lag-2 residual)
    down every ``step``-th column of ``img_t`` (W, H, 3) BGR."""
    from slitcli.laser.evidence import robust_sigma

    sub = np.ascontiguousarray(np.asarray(img_t[::step], dtype=np.float32) @ _Y_BGR)
    if sub.shape[1] < 5:
        return 0.0
    return robust_sigma(sub, np.ones(sub.shape, np.uint8), 1)


def luma_rows(img_t: np.ndarray, bg_t: np.ndarray, v_px: np.ndarray, saturated: np.ndarray,
              cand: np.ndarray, row0: int, *, sigma_dn: float, blur_var_px2: float,
              shape_error: float, max_chi2: float, s_max: float, min_z: float,
              saturation_dn: int
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stripe's row fitted on the luma's contrast in every found, unclipped column.

    Where the evidence has found the stripe at ``v_px`` (W,) (image rows, NaN none), the
    luma's contrast ``Y(x - opening)`` of the column (``img_t`` (W, H', 3) BGR and the
    opening per channel ``bg_t`` (3 W, H'), rows from ``row0``) is fitted with the
    profile model of :mod:`slitcli.laser.profile`, from the evidence's width (the fit in
    ``cand`` (W, K, N_FIELDS) nearest the row) less ``blur_var_px2``, in a window of
    three such widths and three rows either side, rows with a channel at
    ``saturation_dn`` left out. A fit is kept where its peak is ``min_z`` significant
    against ``sigma_dn``, it is a Gaussian within the model error (``shape_error``,
    ``max_chi2``), at most ``s_max`` wide and within the evidence's sigma (at least a
    pixel) of ``v_px``.

    Returns
    -------
    v_px, se_px, width_px : ndarray, shape (W,), float64
        The luma's row, its standard error and sigma, px; NaN where no fit is kept.
    se_evidence_px : ndarray, shape (W,), float64
        The standard error of the evidence's fit nearest ``v_px``, px (NaN none).
    """
    w = v_px.shape[0]
    v_out, se_out, w_out, se_ev = np.empty(w), np.empty(w), np.empty(w), np.empty(w)
    _luma_rows(img_t, bg_t, np.ascontiguousarray(v_px, dtype=np.float64),
               np.ascontiguousarray(saturated, dtype=np.bool_).view(np.uint8),
               np.ascontiguousarray(cand, dtype=np.float64), row0, max(sigma_dn, 1e-3),
               blur_var_px2, shape_error, max_chi2, s_max, min_z, saturation_dn,
               v_out, se_out, w_out, se_ev)
    return v_out, se_out, w_out, se_ev


#: median of chi-square with one degree of freedom: median(d^2) / this estimates the
#: mean square of a Gaussian d
CHI2_1_MEDIAN = 0.4549364
#: fewest columns with both rows that measure the evidence's own row error
MIN_PAIRS = 8


def combined_rows(v_ev: np.ndarray, se_ev: np.ndarray, v_luma: np.ndarray,
                  se_luma: np.ndarray) -> np.ndarray:
    """The evidence's and the luma's rows (W,) combined by their variances.

    The evidence's rows carry, beyond their fit's standard error ``se_ev``, the error
    the chroma's processing leaves (the sample grid's phase, the quantiser), which the
    fit does not see; it is measured on the frame from the columns with both rows: the
    robust mean square of their difference less the two fits' variances (``e^2``, at
    least 0; 0 with fewer than ``MIN_PAIRS`` such columns). Each column's row is then the
    inverse-variance mean of ``v_ev`` (variance ``se_ev^2 + e^2``) and ``v_luma``
    (``se_luma^2``) where it has both, ``v_ev`` elsewhere.
    """
    both = np.isfinite(v_ev) & np.isfinite(v_luma) & np.isfinite(se_ev) & \
        np.isfinite(se_luma)
    out = v_ev.copy()
    if not both.any():
        return out
    d2 = (v_ev[both] - v_luma[both]) ** 2
    e2 = 0.0
    if d2.size >= MIN_PAIRS:
        e2 = max(float(np.median(d2)) / CHI2_1_MEDIAN -
                 float(np.median(se_ev[both] ** 2 + se_luma[both] ** 2)), 0.0)
    w_ev = 1.0 / (se_ev[both] ** 2 + e2 + 1e-12)
    w_l = 1.0 / (se_luma[both] ** 2 + 1e-12)
    out[both] = (w_ev * v_ev[both] + w_l * v_luma[both]) / (w_ev + w_l)
    return out

