"""Laser slit extraction from one colour image (paper §2.1.1, Eqs. 1-4).

Pipeline, all array code (no Python loop over pixels or columns):

1. Local contrast. A vertical morphological top-hat (``x - opening(x)``, window
   ``background_window_px``) of the red channel and of the white brightness
   ``max(g, b)`` gives the light a pixel adds above its local background. A wide
   red object is background at this scale, so the stripe crossing it stands out
   as a narrow bright run while the object itself does not.
2. Candidates (Eqs. 1-3) among pixels whose red contrast passes a seed level:
   chromaticity (Eq. 1), red chromaticity tests (Eq. 2) and white-brightness
   rejection on the contrast (Eq. 3). Saturated red pixels are exempt from
   Eqs. 2-3 (a clipped laser core turns white); a run made only of exempt
   pixels is rejected (a saturated white highlight).
3. Vertical runs of candidates per column, each scored by Eq. 4 (red peak +
   beta f(y) continuity + gamma g(I) narrowness); the best run of each column
   is chosen in two passes (the second knows the neighbouring columns' choice).
4. Sub-pixel centre: Gaussian (weighted log-parabola) fit where the peak is
   unsaturated, background-subtracted centre of gravity over the run where it
   is saturated.
5. Segments: chosen rows joined across columns with row steps up to
   ``max_jump_px``; segments shorter than ``min_segment_cols`` are noise.

Images are processed transposed (one image column per array row) so that every
column's pixels are contiguous.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from slitcli.laser.params import LaserParams

_FIT_HALF = 2  # half-width of the Gaussian fit window, pixels (5 samples)
_COG_MARGIN = 3  # pixels beyond the saturated plateau in the centre of gravity
_RUN_SHARE = 0.35  # run pixels hold at least this share of the local maximum contrast
_RATIO_WINDOW_PX = 15  # box window of the local red/white ratio, pixels
_MU_MAX = 2.0  # largest red/white ratio removed (see red_excess)
_WIN_HALF = 8  # half-height of the per-column window around the stripe, pixels
_BG_INNER = 5  # window rows at least this far from the stripe are background, pixels


@dataclass(frozen=True)
class StripeColumns:
    """The stripe found in one image, per column.

    Attributes
    ----------
    v_px : ndarray, shape (W,)
        Sub-pixel stripe row (pixel centres at integers); NaN where there is no stripe.
    strength_dn : ndarray, shape (W,)
        Red contrast of the stripe above its local background, DN; NaN where none.
    saturated : ndarray, shape (W,) bool
        The stripe's red core is clipped (centre of gravity used).
    noise_sigma_dn : float
        Image noise standard deviation estimated for the acceptance threshold, DN.
    threshold_dn : float
        The red-contrast acceptance threshold used, DN.
    """

    v_px: np.ndarray
    strength_dn: np.ndarray
    saturated: np.ndarray
    noise_sigma_dn: float
    threshold_dn: float


def chromaticity(bgr: np.ndarray) -> np.ndarray:
    """Relative intensities R, G, B of paper Eq. 1.

    Parameters
    ----------
    bgr : ndarray, shape (..., 3), BGR order
        Absolute intensities b, g, r (any numeric type).

    Returns
    -------
    rgb_chroma : ndarray, shape (..., 3), float64, RGB order
        ``R = r / (r + g + b)`` etc.; all zero where ``r + g + b = 0`` (black).
    """
    x = np.asarray(bgr, dtype=np.float64)[..., ::-1]
    s = x.sum(axis=-1, keepdims=True)
    return np.divide(x, s, out=np.zeros_like(x), where=s > 0)


def candidate_mask(bgr: np.ndarray, red_contrast_dn: np.ndarray, white_contrast_dn: np.ndarray,
                   params: LaserParams) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel laser candidates, paper Eqs. 1-3.

    Parameters
    ----------
    bgr : ndarray, shape (..., 3), uint8
        Absolute intensities b, g, r (DN).
    red_contrast_dn, white_contrast_dn : ndarray, shape (...)
        Red excess (:func:`red_excess`) and white-brightness (``max(g, b)``) contrast
        above the local background, DN.
    params : LaserParams

    Returns
    -------
    red : ndarray of bool, shape (...)
        Eq. 2 on the chromaticities of Eq. 1, ``R > min_th`` and
        ``R - max(G, B) > min_delta_th`` (false where ``r + g + b = 0``), and Eq. 3
        on the contrasts, ``e^ > alpha w^``, both hold: the red excess contrast
        ``e^`` (see :func:`red_excess`) beats alpha times the white-brightness contrast.
    saturated : ndarray of bool, shape (...)
        Red at or above ``saturation_dn`` (exempt from Eqs. 2-3, see module notes).

    Notes
    -----
    Eq. 2 is evaluated multiplied through by ``s = r + g + b`` (``r > min_th s``,
    ``r - max(g, b) > min_delta_th s``), which equals the chromaticity form for
    ``s > 0`` and is false for black pixels, in float32 over whole images.
    """
    x = np.asarray(bgr)
    b = x[..., 0].astype(np.float32)
    g = x[..., 1].astype(np.float32)
    r = x[..., 2].astype(np.float32)
    s = r + g + b
    eq2 = (r > np.float32(params.min_th) * s) & \
        ((r - np.maximum(g, b)) > np.float32(params.min_delta_th) * s) & (s > 0)
    rc = np.asarray(red_contrast_dn, dtype=np.float32)
    wc = np.asarray(white_contrast_dn, dtype=np.float32)
    eq3 = rc > np.float32(params.alpha) * wc
    return eq2 & eq3, x[..., 2] >= params.saturation_dn


def red_excess(bgr: np.ndarray) -> np.ndarray:
    """Red light a pixel holds beyond what its surface colour explains, DN (float32, (H, W)).

    ``e = r - mu w`` with the white brightness ``w = (g + b) / 2`` and ``mu`` the local
    ratio of red to white brightness (box means over ``_RATIO_WINDOW_PX``), clipped to
    ``[0, _MU_MAX]``. Shading, texture and white light scale red and white alike on a
    surface and cancel; the laser adds red (and only ``crosstalk`` of it to green and
    blue) and stays. The clip keeps a strongly red surface (large ``mu``) from
    cancelling the laser through its crosstalk and from amplifying the noise of its
    dark green and blue channels.
    """
    x = np.asarray(bgr).astype(np.float32)
    b, g, r = cv2.split(x)
    w = cv2.addWeighted(g, 0.5, b, 0.5, 0.0)
    k = (_RATIO_WINDOW_PX, _RATIO_WINDOW_PX)
    mu = cv2.boxFilter(r, -1, k) / np.maximum(cv2.boxFilter(w, -1, k), np.float32(1.0))
    np.clip(mu, 0.0, _MU_MAX, out=mu)
    return r - mu * w


def estimate_noise_dn(green_t: np.ndarray, blue_t: np.ndarray) -> float:
    """Robust sensor-noise sigma (DN) from the green-minus-blue vertical high-pass.

    Grey and red surfaces have (nearly) equal green and blue albedo, so their
    texture cancels in ``g - b`` while independent channel noise adds up: the
    second difference ``2 d[v] - d[v-1] - d[v+1]`` of ``d = g - b`` has variance
    ``12 sigma^2``. Inputs are transposed images (one image column per row); every
    eighth column is used.
    """
    d = green_t[::8].astype(np.int16) - blue_t[::8].astype(np.int16)
    hp = np.abs(2 * d[:, 1:-1] - d[:, :-2] - d[:, 2:]).ravel()
    if hp.size == 0:
        return 0.0
    med = float(np.partition(hp, hp.size // 2)[hp.size // 2])
    return 1.4826 * med / np.sqrt(12.0)


def extract_stripe(left_bgr: np.ndarray, params: LaserParams, *,
                   search_mask: np.ndarray | None = None,
                   previous_v_px: np.ndarray | None = None) -> StripeColumns:
    """Find the laser stripe in a colour image, one sub-pixel row per column (Eqs. 1-4).

    Parameters
    ----------
    left_bgr : ndarray, shape (H, W, 3), uint8, BGR
        The (rectified) left image.
    params : LaserParams
    search_mask : ndarray, shape (H, W) bool, optional
        Pixels where the stripe may lie (from the rig geometry, see
        :func:`slitcli.laser.frame.search_mask`); default everywhere.
    previous_v_px : ndarray, shape (W,), optional
        The previous frame's stripe rows (NaN none), used by the continuity term.

    Returns
    -------
    StripeColumns
    """
    img = np.asarray(left_bgr)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise ValueError("left_bgr must be an (H, W, 3) uint8 BGR image")
    h, w = img.shape[:2]
    bgr_t = cv2.transpose(img)  # (W, H, 3): one image column per row
    b_t, g_t, _ = cv2.split(bgr_t)
    se = np.ones((1, params.background_window_px), np.uint8)
    rc_t = cv2.morphologyEx(red_excess(bgr_t), cv2.MORPH_TOPHAT, se)
    wc_t = cv2.morphologyEx(cv2.max(g_t, b_t), cv2.MORPH_TOPHAT, se)
    sigma = estimate_noise_dn(g_t, b_t)
    thr = max(params.min_peak_dn, params.noise_k * sigma)
    red, sat = candidate_mask(bgr_t, rc_t, wc_t, params)
    # run membership: above the seed level and above a share of the local maximum, so
    # that the stripe on a red surface is cut out of the surface's own red runs
    local_max = cv2.dilate(rc_t, se)
    # (a run can only reach the acceptance threshold where its window's maximum does)
    cand = (red | sat) & (rc_t >= params.seed_fraction * thr) & \
        (rc_t >= np.float32(_RUN_SHARE) * local_max) & (local_max >= np.float32(thr))
    if search_mask is not None:
        cand &= np.asarray(search_mask, dtype=bool).T
    pos = np.flatnonzero(cand)
    empty = StripeColumns(np.full(w, np.nan), np.full(w, np.nan), np.zeros(w, bool), sigma, thr)
    if pos.size == 0:
        return empty
    runs = _runs(pos, rc_t.ravel()[pos].astype(np.float64), red.ravel()[pos], sat.ravel()[pos], h)
    keep = runs.has_red & (runs.peak >= thr) & (runs.width_eq <= params.max_width_px)
    runs = runs.select(keep)
    if runs.col.size == 0:
        return empty

    best = _rank(runs, w, params, previous_v_px)
    chosen = runs.select(best)
    v, ok = _subpixel(bgr_t, chosen, sigma, params)
    chosen = chosen.select(ok)
    v = v[ok]

    v_px = np.full(w, np.nan)
    strength = np.full(w, np.nan)
    saturated = np.zeros(w, bool)
    v_px[chosen.col] = v
    strength[chosen.col] = chosen.peak
    saturated[chosen.col] = chosen.n_sat > 0
    keep_cols = _segments(v_px, params)
    v_px[~keep_cols] = np.nan
    strength[~keep_cols] = np.nan
    saturated &= keep_cols
    return StripeColumns(v_px, strength, saturated, sigma, thr)


@dataclass(frozen=True)
class _Runs:
    """Vertical candidate runs (one entry per run), all arrays of equal length."""

    col: np.ndarray  # image column u
    v0: np.ndarray  # first row
    n: np.ndarray  # length, pixels
    peak: np.ndarray  # max red contrast, DN
    total: np.ndarray  # summed red contrast, DN px
    peak_v: np.ndarray  # row of the peak (first maximum)
    n_sat: np.ndarray  # saturated pixels
    sat_v: np.ndarray  # mean row of the saturated pixels (NaN if none)
    has_red: np.ndarray  # holds at least one pixel passing Eqs. 2-3

    @property
    def width_eq(self) -> np.ndarray:
        """Equivalent width: summed / peak red contrast, pixels (2.5 sigma for a Gaussian)."""
        return self.total / self.peak

    @property
    def centre_v(self) -> np.ndarray:
        """Integer-accuracy row of the run: plateau centre if saturated, else the peak."""
        return np.where(self.n_sat > 0, self.sat_v, self.peak_v)

    def select(self, which: np.ndarray) -> _Runs:
        return _Runs(**{k: getattr(self, k)[which] for k in self.__dataclass_fields__})


def _runs(pos: np.ndarray, rc: np.ndarray, red: np.ndarray, sat: np.ndarray, h: int) -> _Runs:
    """Group sorted flat positions (transposed layout) into vertical runs."""
    new = np.ones(pos.size, bool)
    new[1:] = (np.diff(pos) != 1) | (pos[1:] % h == 0)
    starts = np.flatnonzero(new)
    rid = np.cumsum(new) - 1
    n = np.diff(np.append(starts, pos.size))
    peak = np.maximum.reduceat(rc, starts)
    total = np.add.reduceat(rc, starts)
    rows = (pos % h).astype(np.float64)
    at_peak = np.flatnonzero(rc == peak[rid])
    first = at_peak[np.r_[True, rid[at_peak][1:] != rid[at_peak][:-1]]]
    n_sat = np.add.reduceat(sat.astype(np.int64), starts)
    sat_sum = np.add.reduceat(np.where(sat, rows, 0.0), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        sat_v = np.where(n_sat > 0, sat_sum / np.maximum(n_sat, 1), np.nan)
    return _Runs(col=pos[starts] // h, v0=pos[starts] % h, n=n, peak=peak, total=total,
                 peak_v=rows[first], n_sat=n_sat, sat_v=sat_v,
                 has_red=np.maximum.reduceat(red.astype(np.uint8), starts) > 0)


def _best_per_column(col: np.ndarray, score: np.ndarray) -> np.ndarray:
    """Index of the highest-scoring entry of each column present (sorted by column)."""
    order = np.lexsort((score, col))
    c = col[order]
    last = np.r_[c[1:] != c[:-1], True]
    return order[last]


def _closeness(v: np.ndarray, ref: np.ndarray, scale_px: float) -> np.ndarray:
    """exp(-dv^2 / 2 s^2), 0 where the reference is NaN."""
    with np.errstate(invalid="ignore"):
        f = np.exp(-0.5 * ((v - ref) / scale_px) ** 2)
    return np.nan_to_num(f)


def _rank(runs: _Runs, w: int, params: LaserParams,
          previous_v_px: np.ndarray | None) -> np.ndarray:
    """Eq. 4: choose each column's run by red peak + beta f(y) + gamma g(I).

    Normalisation (docs/laser.md): red peak divided by the column's strongest
    run (1 for the strongest); g(I) = 1 - width_eq / max_width_px in [0, 1];
    f(y) = the mean agreement with the rows chosen in columns u-2, u-1, u+1, u+2 by
    a first pass (which uses the previous frame only), averaged with the agreement
    with the previous frame's row when one is given; each agreement is
    ``exp(-dv^2 / (2 continuity_px^2))``, in [0, 1].
    """
    colmax = np.zeros(w)
    np.maximum.at(colmax, runs.col, runs.peak)
    red_peak = runs.peak / colmax[runs.col]
    narrow = np.clip(1.0 - runs.width_eq / params.max_width_px, 0.0, 1.0)
    v = runs.centre_v
    if previous_v_px is not None:
        prev = np.asarray(previous_v_px, dtype=np.float64)
        f_prev = _closeness(v, prev[runs.col], params.continuity_px)
    else:
        f_prev = np.zeros(v.size)
    base = red_peak + params.gamma * narrow
    first = _best_per_column(runs.col, base + params.beta * f_prev)
    v1 = np.full(w + 4, np.nan)  # padded by 2 columns on each side
    v1[runs.col[first] + 2] = v[first]
    f_nbr = np.zeros(v.size)
    for d in (-2, -1, 1, 2):  # four fixed neighbour offsets, vectorised over runs
        f_nbr += _closeness(v, v1[runs.col + 2 + d], params.continuity_px)
    f = f_nbr / 4.0 if previous_v_px is None else 0.5 * (f_nbr / 4.0 + f_prev)
    return _best_per_column(runs.col, base + params.beta * f)


def _subpixel(bgr_t: np.ndarray, runs: _Runs, noise_dn: float,
              params: LaserParams) -> tuple[np.ndarray, np.ndarray]:
    """Sub-pixel row per chosen run: Gaussian fit (on the flanks if saturated).

    The fitted signal is the red channel minus ``mu`` times the white brightness
    ``w = (g + b) / 2``, minus its background (a line through the mean levels of
    the window rows at least ``_BG_INNER`` above and below). Surface texture under
    the stripe changes red and white alike and would pull the centre; subtracting
    ``mu w`` with ``mu`` the column's red/white ratio cancels it. Subtracting adds
    the white channel's noise, so ``mu`` is shrunk Wiener-style by ``lambda``, the
    share of the white variance around the stripe that is texture rather than
    noise (plain surfaces: lambda ~ 0, textured: ~ 1), and clipped to ``_MU_MAX``.

    Unsaturated runs: weighted log-parabola (Gaussian) fit to the 5 rows around the
    maximum (their centre of gravity where that fit has no maximum). Saturated
    runs: the same fit to the unsaturated flank rows only (the clipped core
    carries no shape); where that fails, the centre of gravity of the signal over
    the run and ``_COG_MARGIN`` rows either side.
    """
    h = bgr_t.shape[1]
    k = np.arange(-_WIN_HALF, _WIN_HALF + 1)
    centre = np.rint(runs.centre_v).astype(np.int64)
    rows = centre[:, None] + k[None, :]
    inside = (rows >= 0) & (rows < h)
    px = bgr_t[runs.col[:, None], np.clip(rows, 0, h - 1)].astype(np.float64)
    red = px[..., 2]
    white = 0.5 * (px[..., 0] + px[..., 1])
    upper = (k <= -_BG_INNER)[None, :] & inside
    lower = (k >= _BG_INNER)[None, :] & inside
    bg_use = upper | lower
    n_bg = np.maximum(bg_use.sum(1), 1)
    w_mean = np.maximum(np.where(bg_use, white, 0.0).sum(1) / n_bg, 1.0)
    r_mean = np.where(bg_use, red, 0.0).sum(1) / n_bg
    w_var = np.where(bg_use, (white - w_mean[:, None]) ** 2, 0.0).sum(1) / np.maximum(n_bg - 1, 1)
    noise_var = 0.5 * noise_dn**2
    lam = np.where(w_var <= noise_var, 0.0, 1.0 - noise_var / np.maximum(w_var, 1e-12))
    mu = lam * np.clip(r_mean / w_mean, 0.0, _MU_MAX)
    clipped = (red >= params.saturation_dn) | (white >= params.saturation_dn)
    flat = red - mu[:, None] * white

    def side_mean(sel: np.ndarray, vals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = sel.sum(1)
        nn = np.maximum(n, 1)
        return np.where(sel, vals, 0.0).sum(1) / nn, n

    m_up, n_up = side_mean(upper, flat)
    m_lo, n_lo = side_mean(lower, flat)
    k_up, _ = side_mean(upper, np.broadcast_to(k.astype(np.float64), flat.shape))
    k_lo, _ = side_mean(lower, np.broadcast_to(k.astype(np.float64), flat.shape))
    both = (n_up > 0) & (n_lo > 0)
    one = np.where(n_up > 0, m_up, m_lo)
    slope = np.where(both, (m_lo - m_up) / np.maximum(k_lo - k_up, 1.0), 0.0)
    level = np.where(both, m_up - slope * k_up, one)
    sig = np.where(inside, flat - (level[:, None] + slope[:, None] * k[None, :]), 0.0)

    v = np.full(runs.col.size, np.nan)
    sat = runs.n_sat > 0
    # unsaturated: 5 samples around the signal's maximum near the run's peak
    core = sig[:, _WIN_HALF - 2:_WIN_HALF + 3]
    p = np.argmax(core, axis=1) - 2
    kf = np.arange(-_FIT_HALF, _FIT_HALF + 1)
    y = np.take_along_axis(sig, (p + _WIN_HALF)[:, None] + kf[None, :], axis=1)
    off, good = _log_parabola(y, kf, np.ones(y.shape, bool))
    # where the log-parabola is no maximum (noise, a flat top), the centre of gravity
    pos_y = np.maximum(y, 0.0)
    tot = pos_y.sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cog = (pos_y * kf[None, :]).sum(1) / tot
    v[~sat] = (centre + p + np.where(good, off, cog))[~sat]
    ok = ~sat & (good | (tot > 0))
    if np.any(sat):
        s = np.flatnonzero(sat)
        ys, cl, ins = sig[s], clipped[s], inside[s]
        off_s, good_s = _log_parabola(ys, k, ins & ~cl, max_offset=_WIN_HALF / 2)
        half = np.minimum(np.ceil(0.5 * runs.n[s] + _COG_MARGIN), _WIN_HALF)
        use = (np.abs(k)[None, :] <= half[:, None]) & ins
        wts = np.where(use, np.maximum(ys, 0.0), 0.0)
        tot = wts.sum(1)
        with np.errstate(invalid="ignore", divide="ignore"):
            cog = (wts * k[None, :]).sum(1) / tot
        v[s] = centre[s] + np.where(good_s, off_s, cog)
        ok[s] = good_s | (tot > 0)
    return v, ok


def _log_parabola(y: np.ndarray, k: np.ndarray, valid: np.ndarray, *,
                  max_offset: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Centre offset of a Gaussian through samples ``y`` (n, m) at offsets ``k`` (m,).

    Least squares on ``ln y = a + b k + c k^2`` over the ``valid`` samples above a
    fifth of their maximum, weighted by ``y^2`` (which makes the log-domain fit
    close to an intensity-domain fit). Returns the offset ``-b / 2c`` and whether
    the fit is a maximum (c < 0) within ``max_offset`` of k = 0.
    """
    ymax = np.where(valid, y, -np.inf).max(axis=1, keepdims=True)
    use = valid & (y > 0.2 * ymax) & (y > 0)
    ly = np.log(np.where(use, y, 1.0))
    wt = np.where(use, y * y, 0.0)
    kk = k.astype(np.float64)[None, :]
    wk = wt * kk
    wk2 = wk * kk
    s0, s1, s2 = wt.sum(1), wk.sum(1), wk2.sum(1)
    s3, s4 = (wk2 * kk).sum(1), (wk2 * kk * kk).sum(1)
    t0, t1, t2 = (wt * ly).sum(1), (wk * ly).sum(1), (wk2 * ly).sum(1)
    # cofactors of the symmetric normal matrix: c ~ num_c / det, b ~ num_b / det
    c01 = s2 * s3 - s1 * s4
    c02 = s1 * s3 - s2 * s2
    c11 = s0 * s4 - s2 * s2
    c12 = s1 * s2 - s0 * s3
    c22 = s0 * s2 - s1 * s1
    det = s0 * (s2 * s4 - s3 * s3) + s1 * c01 + s2 * c02
    num_b = c01 * t0 + c11 * t1 + c12 * t2
    num_c = c02 * t0 + c12 * t1 + c22 * t2
    good = (use.sum(1) >= 3) & (det > 1e-9 * np.maximum(s0, 1e-12) ** 3) & (num_c < 0)
    with np.errstate(invalid="ignore", divide="ignore"):
        off = -num_b / (2.0 * num_c)
    good &= np.abs(off) <= max_offset
    return np.where(good, off, 0.0), good


def _segments(v_px: np.ndarray, params: LaserParams) -> np.ndarray:
    """Columns belonging to stripe segments of at least ``min_segment_cols`` columns."""
    found = np.isfinite(v_px)
    step = np.abs(np.diff(v_px))
    joined = found[1:] & found[:-1] & (step <= params.max_jump_px)
    new = np.r_[True, ~joined]
    seg = np.cumsum(new) - 1
    counts = np.bincount(seg, weights=found.astype(np.float64))
    return found & (counts[seg] >= params.min_segment_cols)
