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

The decoder makes a stripe's colour from chroma that also carries its surroundings:
on a textured, colourful surface the quantised, interpolated chroma forms red bumps of
a few pixels with no light behind them, which the evidence cannot tell from a faint
stripe. Laser light adds to the luma too (a red laser at least ``0.299`` of its red),
and the luma is kept at full resolution: :func:`luma_segments` keeps a piece of stripe
only where the luma shows light at its rows.
"""

from __future__ import annotations

import math

import numpy as np

from slitcli.laser._c.luma import lag_medians as _lag_medians
from slitcli.laser._c.luma import luma_column_z as _luma_column_z
from slitcli.laser._c.luma import luma_rows as _luma_rows
from slitcli.laser.choose import stripe_pieces
from slitcli.laser.profile import F_POS, F_SAT

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
#: :func:`luma_rows` looks for the light within this many of the evidence's sigmas of
#: its row: the evidence's hump is the light's chroma, blurred and possibly displaced by
#: the camera's processing, and the light lies within it (inside two sigmas of a
#: Gaussian hump: where it is above 1/e^2 of its peak)
ROW_REACH_SIGMAS = 2.0
#: :func:`consistent_offsets`: the columns either side of a column whose offsets give its
#: local median (within one piece of stripe)
OFFSET_HALF_COLS = 8
#: :func:`consistent_offsets`: a column's offset may differ from the local median by at
#: most this much, px (the evidence's own row error, the 4:2:0 grid's phase, reaches
#: about half a pixel)
OFFSET_TOL_PX = 1.0


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

    # (channel by channel, not ``@ _Y_BGR``: numpy hands that product to BLAS, which
    # wakes its threads beside the extractor's; the sums are the same to the bit)
    px = np.asarray(img_t[::step], dtype=np.float32)
    sub = px[..., 0] * _Y_BGR[0]
    sub += px[..., 1] * _Y_BGR[1]
    sub += px[..., 2] * _Y_BGR[2]
    if sub.shape[1] < 5:
        return 0.0
    return robust_sigma(sub, np.ones(sub.shape, np.uint8), 1)


def luma_rows(img_t: np.ndarray, bg_t: np.ndarray, v_px: np.ndarray, saturated: np.ndarray,
              cand: np.ndarray, row0: int, *, sigma_dn: float, blur_var_px2: float,
              shape_error: float, max_chi2: float, s_max: float, min_z: float,
              saturation_dn: int, seek: bool = True
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The stripe's row fitted on the luma's contrast in every found, unclipped column.

    Where the evidence has found the stripe at ``v_px`` (W,) (image rows, NaN none), the
    luma's contrast ``Y(x - opening)`` of the column (``img_t`` (W, H', 3) BGR and the
    opening per channel ``bg_t`` (3 W, H'), rows from ``row0``) is fitted with the
    profile model of :mod:`slitcli.laser.profile` in a window of three of the
    evidence's widths (the fit in ``cand`` (W, K, N_FIELDS) nearest the row) and three
    rows either side, rows with a channel at ``saturation_dn`` left out.

    With ``seek`` (the rows) the fit starts from the luma's own peak within
    :data:`ROW_REACH_SIGMAS` of the evidence's sigmas (at least a pixel each) of
    ``v_px``, at that hump's half-maximum width: the light lies inside the evidence's
    hump, but the camera's chroma processing may have moved the hump off it by more
    than the fit's own reach. A hump that fails the shape test (a camera's sharpening
    rings beside a thin line) is centred by its upper half (``flat_top``), its standard
    error at least :data:`~slitcli.laser.profile.MIN_SIGMA_PX` over its half-maximum
    rows. Without ``seek`` (a candidate's width) the Gaussian starts from ``v_px`` at the
    evidence's width less ``blur_var_px2`` and must stay within one such sigma.

    A fit is kept where its peak is ``min_z`` significant against ``sigma_dn`` (or the
    luma's local noise, if larger), it passes the shape test (``shape_error``,
    ``max_chi2``; or is a flat top), it is at most ``s_max`` wide and within the reach.

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
               ROW_REACH_SIGMAS if seek else 1.0, seek, v_out, se_out, w_out, se_ev)
    return v_out, se_out, w_out, se_ev


def luma_widths(img_t: np.ndarray, bg_t: np.ndarray, cand: np.ndarray, need: np.ndarray,
                row0: int, *, sigma_dn: float, blur_var_px2: float, shape_error: float,
                max_chi2: float, s_max: float, min_z: float, saturation_dn: int
                ) -> np.ndarray:
    """The width of each candidate where ``need`` (W, K) bool, fitted on the luma.

    Beside a colour edge a 4:2:0 codec spreads chroma, and with it the evidence, over
    rows the light does not reach; the luma keeps the light's own profile. Each needed,
    unclipped candidate of ``cand`` (W, K, N_FIELDS) is fitted on the luma at its row as
    :func:`luma_rows` fits a found column without ``seek`` (the Gaussian from the
    candidate's own row and width; same window, tests and arguments). (Seeking the
    luma's peak there lets more of the codec's clutter pass: through the ``webcam``
    preset the corridor's detected bins 96.56 -> 96.49 %, the random open scenes'
    phantom bins 61 -> 68.)

    Returns
    -------
    width_px : ndarray, shape (W, K), float64
        The luma's sigma, px; NaN where not needed or no fit is kept.
    """
    out = np.full(need.shape, np.nan)
    sat = np.asarray(cand[..., F_SAT] > 0)
    for k in np.flatnonzero(need.any(axis=0)):
        v = np.where(need[:, k], cand[:, k, F_POS], np.nan)
        out[:, k] = luma_rows(img_t, bg_t, v, sat[:, k], cand, row0, sigma_dn=sigma_dn,
                              blur_var_px2=blur_var_px2, shape_error=shape_error,
                              max_chi2=max_chi2, s_max=s_max, min_z=min_z,
                              saturation_dn=saturation_dn, seek=False)[2]
    return out


def consistent_offsets(v_ev: np.ndarray, v_luma: np.ndarray, *, max_gap: int,
                       max_jump_px: float) -> np.ndarray:
    """Which columns' luma rows (W,) follow the light: their offset from the evidence's
    row ``v_ev`` (W,) agrees with the offsets of their neighbours on the stripe.

    The evidence's hump is displaced from the light by the camera's chroma processing,
    the same way along a piece of stripe (one surface, one camera) but for the grid's
    phase; the luma's peak within reach of a piece of codec clutter, or on strong
    texture, is wherever the luma's texture puts it. So a column keeps its luma row
    only where its offset ``v_luma - v_ev`` lies within :data:`OFFSET_TOL_PX` of the
    median offset of its piece's columns (:func:`~slitcli.laser.choose.stripe_pieces`
    of ``v_ev`` with ``max_gap`` and ``max_jump_px``) within :data:`OFFSET_HALF_COLS`
    either side, itself included.

    Returns
    -------
    keep : ndarray, shape (W,), bool
        False where ``v_luma`` or ``v_ev`` is NaN or the offset disagrees.
    """
    keep = np.zeros(v_ev.shape[0], bool)
    cols, piece = stripe_pieces(v_ev, max_gap, max_jump_px)
    d = v_luma[cols] - v_ev[cols]
    has = np.isfinite(d)
    if not has.any():
        return keep
    h = OFFSET_HALF_COLS
    d_pad = np.concatenate([np.full(h, np.nan), d, np.full(h, np.nan)])
    p_pad = np.concatenate([np.full(h, -1), piece, np.full(h, -1)])
    # the window of each found column with a luma row: its piece's offsets only (a row
    # holds at least its own, so no median is of nothing)
    win = np.lib.stride_tricks.sliding_window_view(d_pad, 2 * h + 1)[has].copy()
    win[np.lib.stride_tricks.sliding_window_view(p_pad, 2 * h + 1)[has]
        != piece[has, None]] = np.nan
    local = np.nanmedian(win, axis=1)
    keep[cols[has]] = np.abs(d[has] - local) <= OFFSET_TOL_PX
    return keep


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


#: the luma's matched filter looks for the light within this many rows of the
#: evidence's, in half rows: twice the 4:2:0 chain's blur (its sigma,
#: sqrt(CHAIN_VAR_PX2) = 0.96 px), rounded up to the half pixel; under a tone curve on a
#: surface of the laser's own colour the evidence's rows lie up to 2 px off (docs/laser.md)
LUMA_REACH_PX = math.ceil(2.0 * math.sqrt(CHAIN_VAR_PX2) * 2.0) / 2.0
#: the offsets tried, px
LUMA_OFFSETS_PX = np.arange(-LUMA_REACH_PX, LUMA_REACH_PX + 0.25, 0.5)


def luma_segments(img_t: np.ndarray, bg_t: np.ndarray, v_px: np.ndarray,
                  saturated: np.ndarray, cand: np.ndarray, row0: int, *, sigma_dn: float,
                  blur_var_px2: float, s_max: float, saturation_dn: int, max_gap: int,
                  max_jump_px: float, min_z: float) -> np.ndarray:
    """Which found columns lie on a piece of stripe whose luma shows the laser's light.

    The stripe's columns ``v_px`` (W,) (image rows, NaN none) fall into pieces: found
    columns at most ``max_gap`` columns apart whose rows step by at most ``max_jump_px``
    per column. In each unclipped column the luma's matched filter at the stripe's row
    (shifted by each of :data:`LUMA_OFFSETS_PX`) and width gives a significance ``z``
    (:func:`slitcli.laser._c.luma.luma_column_z`: against the luma's local noise,
    texture included). A piece is kept where, at its best offset (one for the whole
    piece), its unclipped columns' combined significance ``sum(z) / sqrt(n)`` reaches
    ``min_z``, or where it holds a clipped core (the clip is light; a codec's chroma
    bump never reaches it, and the unclipped columns beside a core carry its bloom,
    not the stripe's profile). Under light, the luma rises at the stripe in every
    column and the combined significance grows with the piece's length; a chroma bump
    of the codec has no light behind it, and its luma is the surface's texture, as
    often darker as brighter: its combined significance is N(0, 1) at each offset, and
    the best of the nine reaches 2 with a chance of about 4 % (tests/test_laser_luma.py).

    Arguments as :func:`luma_rows`' (``img_t`` (W, H', 3) BGR and ``bg_t`` (3 W, H')
    from ``row0``; ``cand`` (W, K, N_FIELDS) gives the evidence's width, less
    ``blur_var_px2``).

    Returns
    -------
    keep : ndarray, shape (W,), bool
        False in the found columns of the pieces whose luma shows no light (and where
        nothing was found).
    """
    w = v_px.shape[0]
    v = np.ascontiguousarray(v_px, dtype=np.float64)
    z = np.empty((LUMA_OFFSETS_PX.size, w))
    _luma_column_z(img_t, bg_t, v, np.ascontiguousarray(saturated, dtype=np.bool_).view(
                   np.uint8), np.ascontiguousarray(cand, dtype=np.float64), row0,
                   max(sigma_dn, 1e-3), blur_var_px2, s_max, saturation_dn, LUMA_OFFSETS_PX,
                   z)
    cols, piece = stripe_pieces(v, max_gap, max_jump_px)
    keep = np.zeros(w, bool)
    if cols.size == 0:
        return keep
    n_pieces = int(piece[-1]) + 1
    zc = z[:, cols]
    judged = np.isfinite(zc)
    # (offset, piece) sums in one pass: each offset's pieces get their own bins
    bins = (np.arange(zc.shape[0])[:, None] * n_pieces + piece).ravel()
    n = np.bincount(bins, weights=judged.ravel(), minlength=zc.shape[0] * n_pieces)
    total = np.bincount(bins, weights=np.where(judged, zc, 0.0).ravel(),
                        minlength=zc.shape[0] * n_pieces)
    combined = np.where(n > 0, total / np.sqrt(np.maximum(n, 1.0)), -np.inf)
    best = combined.reshape(zc.shape[0], n_pieces).max(axis=0)
    clipped = np.bincount(piece, weights=np.asarray(saturated, bool)[cols],
                          minlength=n_pieces)
    ok = (clipped > 0) | (best >= min_z)
    keep[cols] = ok[piece]
    return keep
