"""Compiled (numba) sub-pixel fit of the laser profile across one image column.

Images come in transposed, ``(W, H, 3)`` BGR uint8 (one image column per array row;
views of the ``(H, W, 3)`` images).

Signal model of one column, per channel c in (r, g, b) and row v::

    x_c(v) = s(v) k_c + A p(v) l_c + n_c(v)

``s(v) k_c``: the surface (colour ``k``; texture and shading ``s`` scale all channels
alike); ``A p(v) l_c``: the laser, a Gaussian profile ``p`` of peak ``A`` (red DN) and
colour ``l = (1, XT, XT)`` (a red diode leaks ``XT`` of itself into green and blue);
``n``: sensor noise, standard deviation ``sigma`` per channel. White light (lamp
highlights) adds ``(1, 1, 1)``. The best linear estimate of ``A p(v)`` per row is the
channel sum ``w . (x - background)`` with ``w . l = 1`` that minimises noise plus
texture variance (generalised least squares,
:func:`~slitcli.laser.lsq.gls_weights`): on a grey or coloured surface the texture
cancels; on a red surface (colour parallel to the laser) it cannot, and counts as
noise. Saturated channels are left out of their row's sum.
A candidate's fit (:func:`fit_profile`) fills one row of the candidate table, whose
fields are the ``C_*`` indices below.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.lsq import gls_weights, inverse_diag12, normal_eq, solve4
from slitcli.laser.surfaces import edge_measure

#: green and blue response to the red laser, fraction of the red response (a red
#: diode seen through a Bayer colour filter; the renderer's default crosstalk)
XT = 0.12
#: |l|^2 of the laser colour l = (1, XT, XT)
A_LASER = 1.0 + 2.0 * XT * XT
FIT_HALF = 8  # half-length of the fit window, px
NEAR_ROWS = 3  # flank rows either side whose colours tell an edge between two surfaces
MIN_ROWS = 5  # fewest usable rows for a fit
MAX_ITER = 6  # Gauss-Newton iterations of the profile fit
CONVERGED_PX = 0.02  # a fit has converged when its centre moves less (px)
CONVERGED_REL_S = 0.05  # and its width less than this share of itself
QUICK_Z = 2.5  # candidates less significant at their start are not fitted further
MIN_SAT_SIGMA = 0.5  # a saturated fit narrower than this (px) has collapsed
#: rows from a saturated fit's centre within which a clipped plateau is its core
PLATEAU_REACH = 2
#: largest standard error (px) of a clipped core's centre fitted where it runs off the image
BORDER_SE = 0.2
#: largest peak of a clipped core, in units of the saturation level: a Gaussian of the
#: sheet's width s peaking this far above clipping is clipped over 2 s sqrt(2 ln 10) =
#: 4.3 s rows; a fit that needs a higher peak to span its plateau is a broad,
#: flat-topped blob (a white highlight), not the sheet
MAX_CLIP_GAIN = 10.0
S_PRIOR_SPREAD = 0.3  # relative spread of the prior on a stripe's width
COLOUR_CORE = 1.5  # rows within this many fitted sigmas of the centre: the colour check
#: extra variance across columns of the (1, 2, 1) / 4 column average, px^2
AVG_VAR = 0.5
#: variance a pixel's extent adds to a profile, px^2: the renderer averages 3 x 3
#: point samples (offsets -1/3, 0, 1/3: variance 2/27); exact integration gives 1/12
PIXEL_VAR = 2.0 / 27.0

#: fields of a candidate row (last axis of the candidate table)
(C_POS, C_AMP, C_WIDTH, C_Z, C_SE_POS, C_CHI2, C_SAT, C_TEX, C_CLUT, C_EDGE,
 C_HVAR, C_SE_AMP, C_COLOUR) = range(13)
N_FIELDS = 13
N_WORK = 2 * (FIT_HALF + 64) + 1  # longest fit window the workspace holds


@njit(cache=True, nogil=True)
def _plateau_centre(win: np.ndarray, ja: int, jb: int, m: int,
                    level: float) -> float:  # pragma: no cover
    """Midpoint of where the red profile (``win[0]``, window rows) crosses ``level`` on
    either side of the clipped plateau ``ja .. jb`` (linear interpolation; a side cut
    off by the window takes the plateau's own end)."""
    j = ja
    while j > 0 and win[0, j - 1] >= level:
        j -= 1
    up = j - 0.5
    if j > 0:
        a, b = win[0, j - 1], win[0, j]
        up = j - 1 + (level - a) / max(b - a, 1e-9)
    j = jb
    while j < m - 1 and win[0, j + 1] >= level:
        j += 1
    lo = j + 0.5
    if j < m - 1:
        a, b = win[0, j], win[0, j + 1]
        lo = j + (a - level) / max(a - b, 1e-9)
    return 0.5 * (up + lo)


@njit(cache=True, nogil=True)
def fit_profile(img: np.ndarray, i: int, centre: float, run_n: int, sigma: float,
                sat_dn: int, s_max: float, s_core: float, slope: float, averaged: bool,
                fixed: bool, max_edge: float, ws: np.ndarray,
                out: np.ndarray) -> bool:  # pragma: no cover
    """Fit the laser profile near row ``centre`` of column ``i`` (module notes).

    Background: per channel a straight line through the flank rows (at least
    ``max(4, run_n / 2 + 2)`` rows from the centre; a constant where one side is cut
    off by the image border). Texture: the surface colour above and below (two
    colours where the window straddles an edge between surfaces), with the variance
    of each flank about its line along its colour. Per row ``y = w . d``
    (:func:`~slitcli.laser.lsq.gls_weights`, saturated channels left out) with its
    information as weight; then a weighted Gauss-Newton fit of
    ``y = offset + A exp(-(v - v0)^2 / (2 s^2))``.

    Writes the ``C_*`` fields of ``out``: v0, A (red DN; with ``s_core`` the peak
    before the pixels' blur), s (px), significance, standard error of v0, reduced
    chi-square, saturated 0/1, texture sigma (DN), edge, standard error of A (``C_CLUT``
    and ``C_HVAR`` are the caller's: NaN here); significance
    is ``A`` over its standard error or, for a clipped core, the margin of saturation
    over the surface's red level in units of noise and texture; ``edge`` is one minus
    the cosine between the surface colours just above and just below. Returns whether
    the fit converged to a peak inside the window; it stops early once the width
    passes ``s_max`` (px, wider than any stripe). ``s_core > 0``: the width the
    laser sheet has here (px; with the pixels' extent, ``PIXEL_VAR``, and along a
    stripe of ``slope`` rows per column the spread of the column's samples across it,
    the width expected); it enters as a prior of relative spread
    ``S_PRIOR_SPREAD``, which keeps a faint stripe's fit from collapsing onto a
    noise spike and leaves a bright one to its data. ``averaged``: fit column ``i``
    averaged with its neighbours, weights (1, 2, 1) / 4 (a value next to a saturated
    one counts as saturated), sheared along the stripe: the neighbours' rows are
    shifted by ``round(slope)``, so a sloping stripe is averaged with itself and only
    the remainder widens it. ``ws`` is an (8, N_WORK) workspace. A clipped core
    that reaches the image's first or last row has no far edge: only a fit whose
    centre the unclipped channels place within ``BORDER_SE`` (standard error) and
    inside the image counts.

    ``fixed``: only the offset and amplitude, by linear least squares, at the centre
    ``centre`` and the prior width (1.2 px without one): the matched filter of the
    expected profile there, unbiased in noise (the amplitude may be negative); the
    row's standard error is reported as infinite, the reduced chi-square as NaN.
    ``max_edge > 0``: a window whose surface colours above and below differ by more
    (the ``edge`` measure) is not fitted (False): the caller has another candidate
    to try.
    """
    n = img.shape[1]
    c = math.floor(centre + 0.5)
    shift = round(slope) if averaged else 0
    s_prior = 0.0
    if s_core > 0.0:
        rest = slope - shift
        s_prior = math.sqrt(s_core * s_core + PIXEL_VAR * (1.0 + slope * slope)
                            + (rest * rest * AVG_VAR if averaged else 0.0))
    flank = max(4, run_n // 2 + 2)
    half = min(max(FIT_HALF, flank + 3), (N_WORK - 1) // 2)
    j0 = max(c - half, 0)
    j1 = min(c + half + 1, n)
    m = j1 - j0
    s2n = sigma * sigma
    win = ws[5:8]  # the window's red, green, blue
    ia = max(i - 1, 0)
    ib = min(i + 1, img.shape[0] - 1)
    for jj in range(m):
        j = j0 + jj
        for ch in range(3):
            x1 = img[i, j, 2 - ch]
            if averaged:
                x0 = img[ia, min(max(j - shift, 0), n - 1), 2 - ch]
                x2 = img[ib, min(max(j + shift, 0), n - 1), 2 - ch]
                if x0 >= sat_dn or x1 >= sat_dn or x2 >= sat_dn:
                    win[ch, jj] = 255.0
                else:
                    win[ch, jj] = 0.25 * (float(x0) + 2.0 * x1 + x2)
            else:
                win[ch, jj] = x1
    # pass 1: flank sums for the per-channel lines, side colours and near colours
    sw = 0.0
    sj = 0.0
    sjj = 0.0
    sxr = sxg = sxb = 0.0
    sjr = sjg = sjb = 0.0
    n_up = 0
    n_lo = 0
    ur_ = ug_ = ub_ = 0.0
    lr_ = lg_ = lb_ = 0.0
    nur = nug = nub = 0.5
    nlr = nlg = nlb = 0.5
    near_u = near_l = 0
    # per side: n, sum d, sum d^2, sum x (3), sum x d (3), sum x x' (rr rg rb gg gb bb)
    side_s = ws[4, 24:56].reshape((2, 16))
    for r in range(32):
        ws[4, 24 + r] = 0.0
    for j in range(j0, j1):
        d = j - c
        if abs(d) < flank:
            continue
        xr, xg, xb = win[0, j - j0], win[1, j - j0], win[2, j - j0]
        if xr >= sat_dn or xg >= sat_dn or xb >= sat_dn:
            continue
        fd = float(d)
        sw += 1.0
        sj += fd
        sjj += fd * fd
        sxr += xr
        sxg += xg
        sxb += xb
        sjr += xr * fd
        sjg += xg * fd
        sjb += xb * fd
        sd = side_s[0] if d < 0 else side_s[1]
        sd[0] += 1.0
        sd[1] += fd
        sd[2] += fd * fd
        sd[3] += xr
        sd[4] += xg
        sd[5] += xb
        sd[6] += xr * fd
        sd[7] += xg * fd
        sd[8] += xb * fd
        sd[9] += xr * xr
        sd[10] += xr * xg
        sd[11] += xr * xb
        sd[12] += xg * xg
        sd[13] += xg * xb
        sd[14] += xb * xb
        if d < 0:
            n_up += 1
            ur_ += xr
            ug_ += xg
            ub_ += xb
            if -d < flank + NEAR_ROWS:
                near_u += 1
                nur += xr
                nug += xg
                nub += xb
        else:
            n_lo += 1
            lr_ += xr
            lg_ += xg
            lb_ += xb
            if d < flank + NEAR_ROWS:
                near_l += 1
                nlr += xr
                nlg += xg
                nlb += xb
    if sw < 3.0:
        return False
    both_sides = near_u > 0 and near_l > 0
    if max_edge > 0.0 and edge_measure(nur, nug, nub, nlr, nlg, nlb, both_sides) > max_edge:
        return False
    det = sw * sjj - sj * sj
    if det > 1e-9 and n_up >= 2 and n_lo >= 2:
        br = (sw * sjr - sj * sxr) / det
        bg_ = (sw * sjg - sj * sxg) / det
        bb = (sw * sjb - sj * sxb) / det
    else:  # a straight line needs flanks on both sides (not so at the image border)
        br = bg_ = bb = 0.0
    ar = (sxr - br * sj) / sw
    ag = (sxg - bg_ * sj) / sw
    ab = (sxb - bb * sj) / sw
    # texture variance of each side along its own colour
    cov = ws[4, :9].reshape((3, 3))
    for r in range(9):
        ws[4, r] = 0.0
    t2_max = 0.0
    for side in (-1, 1):
        if side < 0:
            cr, cg, cb, cnt = ur_, ug_, ub_, n_up
        else:
            cr, cg, cb, cnt = lr_, lg_, lb_, n_lo
        if cnt < 2:
            continue
        nk = math.sqrt(cr * cr + cg * cg + cb * cb) + 1e-9
        cr /= nk
        cg /= nk
        cb /= nk
        # sum over the side's rows of q^2, q = c . (x - a - b d), from its sums
        sd = side_s[0] if side < 0 else side_s[1]
        big_a = cr * ar + cg * ag + cb * ab
        big_b = cr * br + cg * bg_ + cb * bb
        sx = cr * sd[3] + cg * sd[4] + cb * sd[5]
        sxd = cr * sd[6] + cg * sd[7] + cb * sd[8]
        sxx = (cr * cr * sd[9] + 2.0 * cr * cg * sd[10] + 2.0 * cr * cb * sd[11]
               + cg * cg * sd[12] + 2.0 * cg * cb * sd[13] + cb * cb * sd[14])
        s2 = (sxx - 2.0 * big_a * sx - 2.0 * big_b * sxd + sd[0] * big_a * big_a
              + 2.0 * big_a * big_b * sd[1] + big_b * big_b * sd[2])
        t2 = max(s2 / max(cnt - 1.0, 1.0) - s2n, 0.0)
        t2_max = max(t2_max, t2)
        cov[0, 0] += t2 * cr * cr
        cov[0, 1] += t2 * cr * cg
        cov[0, 2] += t2 * cr * cb
        cov[1, 1] += t2 * cg * cg
        cov[1, 2] += t2 * cg * cb
        cov[2, 2] += t2 * cb * cb
    cov[1, 0] = cov[0, 1]
    cov[2, 0] = cov[0, 2]
    cov[2, 1] = cov[1, 2]
    # pass 3: per-row laser estimate y and its information (weights cached per
    # saturation pattern: bit 0 red, 1 green, 2 blue)
    y = ws[0]
    wt = ws[1]
    wc = ws[2, :24].reshape((8, 3))
    info_c = ws[3, :8]
    for p in range(8):
        info_c[p] = -1.0
    sub = ws[4, 9:18].reshape((3, 3))
    wv = ws[4, 18:21]
    nsat = 0
    nuse = 0
    # the current pattern's weights in local variables (runs of rows share one)
    last = -1
    info = w_r = w_g = w_b = 0.0
    for jj in range(m):
        j = j0 + jj
        d = j - c
        xr, xg, xb = win[0, j - j0], win[1, j - j0], win[2, j - j0]
        pat = (1 if xr >= sat_dn else 0) | (2 if xg >= sat_dn else 0) | \
            (4 if xb >= sat_dn else 0)
        if pat & 1:
            nsat += 1
        if pat != last and info_c[pat] < 0.0:
            for r in range(3):
                for q in range(3):
                    if (pat >> r) & 1 or (pat >> q) & 1:
                        sub[r, q] = 1.0 if r == q else 0.0
                    else:
                        sub[r, q] = cov[r, q] + (s2n if r == q else 0.0)
            lr = 0.0 if pat & 1 else 1.0
            lg = 0.0 if pat & 2 else XT
            lb = 0.0 if pat & 4 else XT
            a = lr * lr + lg * lg + lb * lb
            info = gls_weights(sub, lr, lg, lb, wv) if a > 0.0 else 0.0
            if info * max(s2n, 1e-6) <= 1e-4 * a:
                info = 0.0
            info_c[pat] = info
            wc[pat, 0] = wv[0]
            wc[pat, 1] = wv[1]
            wc[pat, 2] = wv[2]
        if pat != last:
            last = pat
            info = info_c[pat]
            w_r, w_g, w_b = wc[pat, 0], wc[pat, 1], wc[pat, 2]
        if info <= 0.0:
            wt[jj] = 0.0
            y[jj] = 0.0
            continue
        y[jj] = w_r * (xr - ar - br * d) + w_g * (xg - ag - bg_ * d) + w_b * (xb - ab - bb * d)
        wt[jj] = info
        nuse += 1
    if nuse < MIN_ROWS:
        return False
    # start: the largest y within 1.5 rows of the centre, a log-parabola through it
    kpk = -1
    for jj in range(m):
        if wt[jj] > 0.0 and abs(j0 + jj - centre) <= 1.5:
            if kpk < 0 or y[jj] > y[kpk]:
                kpk = jj
    s = s_prior if s_prior > 0.0 else 1.2
    if fixed:
        v0 = centre
        amp = 0.0
    elif kpk < 0 or y[kpk] <= 0.0:
        cc = min(max(c - j0, 0), m - 1)
        if win[0, cc] < sat_dn:
            return False
        # a clipped core whose other channels carry no information either (a strongly
        # textured surface): start at its centre, the flanks decide
        kpk = cc
        v0 = float(c)
        amp = 2.0 * max(sat_dn - ar, 1.0)
    else:
        v0 = float(j0 + kpk)
        amp = y[kpk]
    if not fixed and wt[kpk] > 0.0 and 0 < kpk < m - 1 and wt[kpk - 1] > 0 and wt[kpk + 1] > 0 \
            and y[kpk - 1] > 0 and y[kpk + 1] > 0:
        l0, lm_, lp = math.log(y[kpk]), math.log(y[kpk - 1]), math.log(y[kpk + 1])
        curv = lm_ - 2.0 * l0 + lp
        if curv < -1e-6:
            off_pk = 0.5 * (lm_ - lp) / curv
            if abs(off_pk) <= 1.0:
                v0 += off_pk
                if s_prior <= 0.0:
                    s = min(max(math.sqrt(-1.0 / curv), 0.5), 3.0)
                amp = y[kpk] * math.exp(0.5 * (off_pk / s) ** 2)
    # a quick look: offset and amplitude by linear least squares at the starting
    # centre and width; a candidate that is not even QUICK_Z significant there is
    # reported as such without the (costlier) full fit
    s00 = s01 = s11 = b0 = b1 = 0.0
    t = (j0 - v0) / s
    e_next = math.exp(-0.5 * t * t)
    ratio = math.exp(-t / s - 0.5 / (s * s))
    step = math.exp(-1.0 / (s * s))
    for jj in range(m):
        e = e_next
        e_next = e * ratio
        ratio *= step
        wj = wt[jj]
        if wj == 0.0:
            continue
        s00 += wj
        s01 += wj * e
        s11 += wj * e * e
        b0 += wj * y[jj]
        b1 += wj * e * y[jj]
    det2 = s00 * s11 - s01 * s01
    if det2 <= 0.0:
        return False
    off = (s11 * b0 - s01 * b1) / det2
    amp = (s00 * b1 - s01 * b0) / det2
    z_quick = amp / math.sqrt(s00 / det2)
    if fixed:
        if nsat > 0:
            z_quick = max(z_quick, (sat_dn - ar) / math.sqrt(s2n + cov[0, 0]))
        out[C_HVAR] = np.nan
        out[C_CLUT] = np.nan
        out[C_POS] = v0
        out[C_AMP] = amp * s_prior / s_core if s_core > 0.0 else amp
        out[C_WIDTH] = s
        out[C_Z] = z_quick
        out[C_SE_AMP] = math.sqrt(s00 / det2) * (s_prior / s_core if s_core > 0.0 else 1.0)
        out[C_COLOUR] = 0.0
        out[C_SE_POS] = np.inf
        out[C_CHI2] = np.nan
        out[C_SAT] = 1.0 if nsat > 0 else 0.0
        out[C_TEX] = math.sqrt(t2_max)
        out[C_EDGE] = edge_measure(nur, nug, nub, nlr, nlg, nlb, both_sides)
        return True
    if z_quick < QUICK_Z and nsat == 0:
        if amp <= 0.0:
            return False
        out[C_HVAR] = np.nan
        out[C_CLUT] = np.nan
        out[C_POS] = v0
        out[C_AMP] = amp
        out[C_WIDTH] = s
        out[C_Z] = z_quick
        out[C_SE_AMP] = math.sqrt(s00 / det2)
        out[C_COLOUR] = 0.0
        out[C_SE_POS] = np.inf
        out[C_CHI2] = np.inf
        out[C_SAT] = 0.0
        out[C_TEX] = math.sqrt(t2_max)
        out[C_EDGE] = 0.0
        return True
    h = ws[3, 8:24].reshape((4, 4))
    g = ws[3, 24:28]
    ht = ws[3, 28:44].reshape((4, 4))
    gt = ws[3, 44:48]
    dx = ws[3, 48:52]
    scratch = ws[3, 52:72].reshape((4, 5))
    w_prior = 1.0 / (S_PRIOR_SPREAD * s_prior) ** 2 if s_prior > 0.0 else 0.0
    chi = normal_eq(y, wt, j0, m, off, amp, v0, s, h, g)
    chi += w_prior * (s - s_prior) ** 2
    h[3, 3] += w_prior
    g[3] += w_prior * (s_prior - s)
    lam = 0.0
    for _ in range(MAX_ITER):
        if lam != 0.0:  # (undamped: scaling by one is the identity, skipped)
            for r in range(4):
                h[r, r] *= 1.0 + lam
        solved = solve4(h, g, dx, scratch)
        if lam != 0.0:
            for r in range(4):
                h[r, r] /= 1.0 + lam
        if solved and abs(dx[2]) < CONVERGED_PX and abs(dx[3]) < CONVERGED_REL_S * s:
            break  # at the minimum: h, the covariance, stays that of these parameters
        n_v0, n_s = v0 + dx[2], s + dx[3]
        if solved and 0.3 <= n_s <= 8.0 and abs(n_v0 - centre) <= half - 1:
            n_chi = normal_eq(y, wt, j0, m, off + dx[0], amp + dx[1], n_v0, n_s, ht, gt)
            n_chi += w_prior * (n_s - s_prior) ** 2
            ht[3, 3] += w_prior
            gt[3] += w_prior * (s_prior - n_s)
            if n_chi <= chi * (1.0 + 1e-9):
                off += dx[0]
                amp += dx[1]
                v0 = n_v0
                s = n_s
                chi = n_chi
                # the trial's normal equations become the current ones (the buffers
                # trade places; the old ones take the next trial)
                h, ht = ht, h
                g, gt = gt, g
                lam = 0.0 if lam <= 1e-4 else lam * 0.1
                if abs(dx[2]) < CONVERGED_PX and abs(dx[3]) < CONVERGED_REL_S * s:
                    break
                if s > s_max:
                    break  # wider than any stripe: rejected whatever its exact width
                continue
        lam = max(lam * 10.0, 1e-2)
        if lam > 1e4:
            break
    # covariance of (A, v0): h holds J' W J at the solution
    var_a, var_v = inverse_diag12(h, ws[3, 72:96].reshape((4, 6)))
    if math.isnan(var_a):
        return False
    if not (amp > 0.0 and var_a > 0.0 and var_v > 0.0):
        return False
    z = amp / math.sqrt(var_a)
    if nsat > 0:
        # clipped up to the image border: the plateau's far edge is not seen
        border = (j0 == 0 and win[0, 0] >= sat_dn) or (j1 == n and win[0, m - 1] >= sat_dn)
        if amp > MAX_CLIP_GAIN * sat_dn:
            return False
        # a clipped core: how far saturation lies above what the surface reaches
        z = max(z, (sat_dn - ar) / math.sqrt(s2n + cov[0, 0]))
        # its flanks alone leave amplitude and width ill-determined: a fit whose
        # centre left the clipped plateau (or that collapsed) gives way to the
        # midpoint of the plateau's two edges
        cc = min(max(c - j0, 0), m - 1)
        if win[0, cc] < sat_dn:
            # a seed beside the clipped core (bright red texture next to it) fits
            # the core's flanks as well: a red clipped plateau (a white highlight
            # clips green and blue too) within PLATEAU_REACH rows of its centre is
            # the one it must stay on
            vc = min(max(int(v0 - j0 + 0.5), 0), m - 1)
            for dd in range(PLATEAU_REACH + 1):
                if vc - dd >= 0 and win[0, vc - dd] >= sat_dn and \
                        max(win[1, vc - dd], win[2, vc - dd]) < sat_dn:
                    cc = vc - dd
                    break
                if vc + dd < m and win[0, vc + dd] >= sat_dn and \
                        max(win[1, vc + dd], win[2, vc + dd]) < sat_dn:
                    cc = vc + dd
                    break
        if win[0, cc] >= sat_dn:
            ja = cc
            while ja > 0 and win[0, ja - 1] >= sat_dn:
                ja -= 1
            jb = cc
            while jb < m - 1 and win[0, jb + 1] >= sat_dn:
                jb += 1
            if s < MIN_SAT_SIGMA or not (j0 + ja - 0.5 <= v0 <= j0 + jb + 0.5):
                if border:
                    return False
                v0 = j0 + _plateau_centre(win, ja, jb, m, 0.5 * (ar + sat_dn))
                var_v = 0.25
        # at the border only the other channels inside the plateau (the laser's
        # crosstalk) can place the centre: where texture swamps them, or the centre
        # lies beyond the last row, there is no fit
        if border and (var_v > BORDER_SE * BORDER_SE or not 0.0 <= v0 <= n - 1.0):
            return False
    # the light the fit gives the laser must have the laser's colour: per core row the
    # excess over the background lines, across the plane of the laser colour and the
    # surface colour of the row's side (texture and shading scale that colour, the
    # laser adds along l), is noise alone for a stripe; a band of another surface's
    # colour between two others (an object's top face, a seam) leaves it there
    cq = 0.0
    nq = 0
    for jj in range(m):
        j = j0 + jj
        if abs(j - v0) > max(COLOUR_CORE * s, 1.0):
            continue
        xr, xg, xb = win[0, jj], win[1, jj], win[2, jj]
        if xr >= sat_dn or xg >= sat_dn or xb >= sat_dn:
            continue
        d = j - c
        if (j < v0 and n_up > 0) or n_lo == 0:
            kr, kg, kb = ur_, ug_, ub_
        else:
            kr, kg, kb = lr_, lg_, lb_
        # n = l x k, l = (1, XT, XT)
        nr = XT * (kb - kg)
        ng = XT * kr - kb
        nb = kg - XT * kr
        nn = math.sqrt(nr * nr + ng * ng + nb * nb)
        if nn <= 0.0:
            continue
        q = (nr * (xr - ar - br * d) + ng * (xg - ag - bg_ * d) + nb * (xb - ab - bb * d)) / nn
        cq += q * q
        nq += 1
    out[C_COLOUR] = cq / (nq * s2n) if nq > 0 else 0.0
    out[C_HVAR] = np.nan
    out[C_POS] = v0
    # the pixels' extent lowers a narrow stripe's peak; where the sheet's width here
    # is known, report the peak before it (the stripe's own brightness)
    out[C_AMP] = amp * s_prior / s_core if s_core > 0.0 else amp
    out[C_WIDTH] = s
    out[C_Z] = z
    out[C_SE_AMP] = out[C_AMP] / z
    out[C_SE_POS] = math.sqrt(var_v)
    out[C_CHI2] = chi / max(nuse - 4, 1)
    out[C_SAT] = 1.0 if nsat > 0 else 0.0
    out[C_TEX] = math.sqrt(t2_max)
    out[C_EDGE] = edge_measure(nur, nug, nub, nlr, nlg, nlb, both_sides)
    return True
