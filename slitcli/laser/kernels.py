"""Compiled (numba) kernels of the stripe extractor: per-line candidates and their fit.

A *line* is one image column (the main pass) or one image row (the pass for steep
stripe parts); the caller hands in images laid out line-major, ``(L, N, 3)`` BGR
uint8, so that every line is contiguous. All loops over pixels live here, compiled.

Signal model of one line, per channel c in (r, g, b) and position j along the line::

    x_c(j) = s(j) k_c + A p(j) l_c + n_c(j)

``s(j) k_c``: the surface (colour ``k``, texture and shading ``s``); ``A p(j) l_c``:
the laser, a Gaussian profile ``p`` of peak ``A`` (red DN) with the colour
``l = (1, XT, XT)`` (a red laser leaks ``XT`` of itself into green and blue);
``n``: sensor noise of standard deviation ``sigma`` per channel. After the local
background (a morphological opening along the line) is removed, the colour
direction of the surface is known and the best linear estimate of ``A p(j)`` per
position is the weighted channel sum ``w . d`` with ``w . l = 1`` that minimises
noise plus texture variance (generalised least squares, see :func:`_row_weights`):
on grey or coloured surfaces the texture cancels, on a red surface (colour parallel
to the laser) it cannot and is counted as noise. Saturated channels are left out
of the sum of their position.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: green and blue response to the red laser, fraction of the red response (a red
#: diode seen by a Bayer colour sensor; the renderer's default crosstalk)
XT = 0.12
#: |l|^2 of the laser colour l = (1, XT, XT)
A_LASER = 1.0 + 2.0 * XT * XT
#: share of the surface-colour direction removed by the detection signal (see
#: :func:`line_candidates`): 1 would remove all texture and amplify noise without
#: bound on surfaces whose colour is the laser's
LAM_DETECT = 0.99
FIT_HALF = 8  # half-length of the fit window along the line, px
MIN_ROWS = 5  # fewest usable positions for a fit


@njit(cache=True, nogil=True)
def noise_sigma(img: np.ndarray, bg: np.ndarray, step: int) -> float:  # pragma: no cover
    """Robust per-channel noise sigma (DN) from the colour component orthogonal to the
    surface colour.

    Texture and shading scale all channels of a surface alike, so the part of a pixel
    orthogonal to its background colour (the opening ``bg``) holds only noise (two
    dimensions) plus rare edges, highlights and the laser. Its second difference along
    the line has ``E|d2|^2 = 12 sigma^2`` (chi-square, 2 dof, median ``2 ln 2``
    times the mean / 2). Every ``step``-th line is used.
    """
    n_lines, n = img.shape[0], img.shape[1]
    vals = np.empty(((n_lines + step - 1) // step) * max(n - 2, 0))
    m = 0
    p = np.empty((n, 3))
    for i in range(0, n_lines, step):
        for j in range(n):
            cb = bg[i, j, 0] + 0.5
            cg = bg[i, j, 1] + 0.5
            cr = bg[i, j, 2] + 0.5
            nn = math.sqrt(cb * cb + cg * cg + cr * cr)
            cb /= nn
            cg /= nn
            cr /= nn
            xb = float(img[i, j, 0])
            xg = float(img[i, j, 1])
            xr = float(img[i, j, 2])
            q = xb * cb + xg * cg + xr * cr
            p[j, 0] = xb - q * cb
            p[j, 1] = xg - q * cg
            p[j, 2] = xr - q * cr
        for j in range(1, n - 1):
            s = 0.0
            for c in range(3):
                d = 2.0 * p[j, c] - p[j - 1, c] - p[j + 1, c]
                s += d * d
            vals[m] = s
            m += 1
    if m == 0:
        return 0.0
    med = np.median(vals[:m])
    return math.sqrt(med / (6.0 * 2.0 * math.log(2.0)))


@njit(cache=True, nogil=True)
def _solve4(a: np.ndarray, b: np.ndarray, x: np.ndarray) -> bool:  # pragma: no cover
    """Solve the symmetric 4x4 system ``a x = b`` in place (Gaussian elimination with
    partial pivoting); False if it is singular."""
    m = np.empty((4, 5))
    for r in range(4):
        for c in range(4):
            m[r, c] = a[r, c]
        m[r, 4] = b[r]
    for col in range(4):
        piv = col
        for r in range(col + 1, 4):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if abs(m[piv, col]) < 1e-300:
            return False
        if piv != col:
            for c in range(5):
                t = m[col, c]
                m[col, c] = m[piv, c]
                m[piv, c] = t
        for r in range(col + 1, 4):
            f = m[r, col] / m[col, col]
            for c in range(col, 5):
                m[r, c] -= f * m[col, c]
    for r in range(3, -1, -1):
        s = m[r, 4]
        for c in range(r + 1, 4):
            s -= m[r, c] * x[c]
        x[r] = s / m[r, r]
    return True


@njit(cache=True, nogil=True)
def _gls(m: np.ndarray, l: np.ndarray, w: np.ndarray) -> float:  # pragma: no cover
    """Best linear unbiased weights for a signal of colour ``l`` in noise of covariance
    ``m`` (3x3): ``w = m^-1 l / (l' m^-1 l)`` written to ``w``; returns the information
    ``l' m^-1 l`` (the inverse variance of ``w . x``), 0 if ``m`` is singular."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 1], m[1, 2], m[2, 2]
    i00 = d * f - e * e
    i01 = c * e - b * f
    i02 = b * e - c * d
    i11 = a * f - c * c
    i12 = b * c - a * e
    i22 = a * d - b * b
    det = a * i00 + b * i01 + c * i02
    if abs(det) < 1e-300:
        return 0.0
    v0 = (i00 * l[0] + i01 * l[1] + i02 * l[2]) / det
    v1 = (i01 * l[0] + i11 * l[1] + i12 * l[2]) / det
    v2 = (i02 * l[0] + i12 * l[1] + i22 * l[2]) / det
    info = l[0] * v0 + l[1] * v1 + l[2] * v2
    if info <= 0.0:
        return 0.0
    w[0] = v0 / info
    w[1] = v1 / info
    w[2] = v2 / info
    return info


@njit(cache=True, nogil=True)
def fit_profile(img: np.ndarray, bg: np.ndarray, i: int, centre: float, run_n: int,
                sigma: float, sat_dn: int, out: np.ndarray) -> bool:  # pragma: no cover
    """Fit the laser profile around ``centre`` of line ``i`` (see the module notes).

    Writes ``out[:] = (position, amplitude A (red DN), Gaussian sigma (px), standard
    error of A, standard error of the position, reduced chi-square, saturated 0/1)``
    and returns whether the fit converged to a peak inside the window.
    """
    n = img.shape[1]
    c = int(math.floor(centre + 0.5))
    flank = max(4, run_n // 2 + 2)
    half = max(FIT_HALF, flank + 3)
    j0 = max(c - half, 0)
    j1 = min(c + half + 1, n)
    m = j1 - j0
    # per-channel straight-line background through the flank positions (unsaturated);
    # the surface colour is their mean colour
    sw = 0.0
    sj = 0.0
    sjj = 0.0
    sx = np.zeros(3)
    sxj = np.zeros(3)
    for j in range(j0, j1):
        if abs(j - c) < flank:
            continue
        if img[i, j, 2] >= sat_dn or img[i, j, 1] >= sat_dn or img[i, j, 0] >= sat_dn:
            continue
        dj = float(j - c)
        sw += 1.0
        sj += dj
        sjj += dj * dj
        for ch in range(3):
            sx[ch] += img[i, j, ch]
            sxj[ch] += img[i, j, ch] * dj
    if sw < 3.0:
        return False
    det = sw * sjj - sj * sj
    lvl = np.empty(3)
    slope = np.empty(3)
    for ch in range(3):
        if det > 1e-9:
            slope[ch] = (sw * sxj[ch] - sj * sx[ch]) / det
        else:
            slope[ch] = 0.0
        lvl[ch] = (sx[ch] - slope[ch] * sj) / sw
    # surface colour on either side (unit, RGB order) and the texture variance along
    # it about the line: two colours where the window straddles an edge between
    # surfaces, one where it does not
    s2n = sigma * sigma
    tex = np.zeros((3, 3))  # texture covariance, DN^2
    t2_max = 0.0
    for side in (-1, 1):
        col = np.zeros(3)
        cnt = 0
        for j in range(j0, j1):
            if (j - c) * side < flank:
                continue
            if img[i, j, 2] >= sat_dn or img[i, j, 1] >= sat_dn or img[i, j, 0] >= sat_dn:
                continue
            for ch in range(3):
                col[ch] += img[i, j, 2 - ch]
            cnt += 1
        if cnt < 2:
            continue
        nk = 0.0
        for ch in range(3):
            col[ch] = col[ch] / cnt + 0.5
            nk += col[ch] * col[ch]
        nk = math.sqrt(nk)
        for ch in range(3):
            col[ch] /= nk
        s2 = 0.0
        for j in range(j0, j1):
            if (j - c) * side < flank:
                continue
            if img[i, j, 2] >= sat_dn or img[i, j, 1] >= sat_dn or img[i, j, 0] >= sat_dn:
                continue
            dj = float(j - c)
            q = 0.0
            for ch in range(3):
                q += (img[i, j, 2 - ch] - lvl[2 - ch] - slope[2 - ch] * dj) * col[ch]
            s2 += q * q
        t2 = max(s2 / max(cnt - 1.0, 1.0) - s2n, 0.0)
        t2_max = max(t2_max, t2)
        for r in range(3):
            for q in range(3):
                tex[r, q] += t2 * col[r] * col[q]
    if t2_max == 0.0 and sw < 3.0:
        return False
    y = np.empty(m)
    wt = np.empty(m)
    pos = np.empty(m)
    mm = np.empty((3, 3))
    ll = np.empty(3)
    wv = np.empty(3)
    nsat = 0
    nuse = 0
    for jj in range(m):
        j = j0 + jj
        dj = float(j - c)
        pos[jj] = j
        if img[i, j, 2] >= sat_dn:
            nsat += 1
        for r in range(3):
            unsat_r = img[i, j, 2 - r] < sat_dn
            ll[r] = (1.0 if r == 0 else XT) if unsat_r else 0.0
            for q in range(3):
                unsat_q = img[i, j, 2 - q] < sat_dn
                if unsat_r and unsat_q:
                    mm[r, q] = tex[r, q] + (s2n if r == q else 0.0)
                else:
                    mm[r, q] = 1.0 if r == q else 0.0
        info = _gls(mm, ll, wv)
        a = ll[0] * ll[0] + ll[1] * ll[1] + ll[2] * ll[2]
        if a == 0.0 or info * s2n <= 1e-4 * a:
            wt[jj] = 0.0
            y[jj] = 0.0
            continue
        acc = 0.0
        for r in range(3):
            acc += wv[r] * (img[i, j, 2 - r] - lvl[2 - r] - slope[2 - r] * dj)
        y[jj] = acc
        wt[jj] = info
        nuse += 1
    if nuse < MIN_ROWS:
        return False
    # initial values: offset from the flanks, peak near the centre
    v0 = centre
    s = 1.2
    amp = 0.0
    for jj in range(m):
        if wt[jj] > 0 and abs(pos[jj] - centre) <= 1.5 and y[jj] > amp:
            amp = y[jj]
    if amp <= 0.0:
        amp = 1.0
    off = 0.0
    jt = np.empty(4)
    h = np.empty((4, 4))
    g = np.empty(4)
    dx = np.empty(4)
    lm = 1e-3
    converged = False
    chi = _chi2(y, wt, pos, off, amp, v0, s)
    for _ in range(30):
        for r in range(4):
            g[r] = 0.0
            for q in range(4):
                h[r, q] = 0.0
        for jj in range(m):
            if wt[jj] == 0.0:
                continue
            t = (pos[jj] - v0) / s
            e = math.exp(-0.5 * t * t)
            res = y[jj] - (off + amp * e)
            jt[0] = 1.0
            jt[1] = e
            jt[2] = amp * e * t / s
            jt[3] = amp * e * t * t / s
            for r in range(4):
                g[r] += wt[jj] * jt[r] * res
                for q in range(4):
                    h[r, q] += wt[jj] * jt[r] * jt[q]
        improved = False
        for _try in range(8):
            hh = h.copy()
            for r in range(4):
                hh[r, r] *= 1.0 + lm
            if not _solve4(hh, g, dx):
                lm *= 10.0
                continue
            n_off, n_amp = off + dx[0], amp + dx[1]
            n_v0, n_s = v0 + dx[2], s + dx[3]
            if n_s < 0.3 or n_s > 8.0 or abs(n_v0 - centre) > FIT_HALF - 1:
                lm *= 10.0
                continue
            n_chi = _chi2(y, wt, pos, n_off, n_amp, n_v0, n_s)
            if n_chi <= chi:
                converged = abs(dx[2]) < 1e-4 and abs(dx[3]) < 1e-4
                off, amp, v0, s, chi = n_off, n_amp, n_v0, n_s, n_chi
                lm = max(lm * 0.3, 1e-7)
                improved = True
                break
            lm *= 10.0
        if not improved or converged:
            break
    # covariance at the solution
    for r in range(4):
        for q in range(4):
            h[r, q] = 0.0
    for jj in range(m):
        if wt[jj] == 0.0:
            continue
        t = (pos[jj] - v0) / s
        e = math.exp(-0.5 * t * t)
        jt[0] = 1.0
        jt[1] = e
        jt[2] = amp * e * t / s
        jt[3] = amp * e * t * t / s
        for r in range(4):
            for q in range(4):
                h[r, q] += wt[jj] * jt[r] * jt[q]
    unit = np.zeros(4)
    col = np.empty(4)
    unit[1] = 1.0
    if not _solve4(h, unit, col):
        return False
    var_a = col[1]
    unit[1] = 0.0
    unit[2] = 1.0
    if not _solve4(h, unit, col):
        return False
    var_v = col[2]
    dof = max(nuse - 4, 1)
    out[0] = v0
    out[1] = amp
    out[2] = s
    z = amp / math.sqrt(max(var_a, 1e-12))
    if nsat > 0:
        # a clipped core: how far saturation lies above what the surface reaches
        z = max(z, (sat_dn - lvl[2]) / math.sqrt(s2n + tex[0, 0]))
    out[3] = z
    out[4] = math.sqrt(max(var_v, 0.0))
    out[5] = chi / dof
    out[6] = 1.0 if nsat > 0 else 0.0
    out[7] = math.sqrt(t2_max)
    return amp > 0.0 and var_a > 0.0 and var_v > 0.0


@njit(cache=True, nogil=True)
def _chi2(y: np.ndarray, wt: np.ndarray, pos: np.ndarray, off: float, amp: float, v0: float,
          s: float) -> float:  # pragma: no cover
    acc = 0.0
    for jj in range(y.shape[0]):
        if wt[jj] == 0.0:
            continue
        t = (pos[jj] - v0) / s
        r = y[jj] - (off + amp * math.exp(-0.5 * t * t))
        acc += wt[jj] * r * r
    return acc


#: columns of the candidate table written by :func:`line_candidates`
C_POS, C_AMP, C_WIDTH, C_Z, C_SE_POS, C_CHI2, C_SAT, C_TEX, C_PRE, C_RUN, C_CLUT = range(11)
N_FIELDS = 11
CLUTTER_HALF = 24  # half-window of the clutter estimate along the line, px
CLUTTER_CORE = 4  # half-width left out around the candidate, px
CLUTTER_QUANTILE = 0.8  # quantile of the laser evidence taken as the clutter level


@njit(cache=True, nogil=True)
def detection_signal(img: np.ndarray, bg: np.ndarray, mask: np.ndarray, i: int,
                     min_th: float, min_delta_th: float, alpha: float, sat_dn: int,
                     score: np.ndarray, sat: np.ndarray, proj: np.ndarray
                     ) -> None:  # pragma: no cover
    """Per-pixel laser evidence of line ``i`` (paper Eqs. 1-3), written to ``score``.

    On the contrast ``t = x - bg`` (light above the local background): Eq. 1/2 on the
    chromaticity of ``t`` (``t_r > min_th sum(t)``, ``t_r - max(t_g, t_b) >
    min_delta_th sum(t)``) and Eq. 3, white rejection, ``y > alpha max(t_g, t_b)``
    with ``y = w . t`` the laser estimate: ``w . l = 1`` and the surface colour (the
    background's) removed to the share ``LAM_DETECT``, so texture and shading cancel
    (white light on a grey surface too). ``score = y`` where all hold, -1 elsewhere;
    a saturated red pixel (exempt, a clipped core turns white) gets its red contrast
    and ``sat`` True. ``proj`` gets ``y`` everywhere (0 at saturated pixels and
    outside the mask).
    """
    n = img.shape[1]
    for j in range(n):
        score[j] = -1.0
        sat[j] = False
        proj[j] = 0.0
        if not mask[i, j]:
            continue
        tr = float(img[i, j, 2]) - bg[i, j, 2]
        tg = float(img[i, j, 1]) - bg[i, j, 1]
        tb = float(img[i, j, 0]) - bg[i, j, 0]
        if img[i, j, 2] >= sat_dn:
            sat[j] = True
            score[j] = tr
            continue
        kr = bg[i, j, 2] + 0.5
        kg = bg[i, j, 1] + 0.5
        kb = bg[i, j, 0] + 0.5
        nk = math.sqrt(kr * kr + kg * kg + kb * kb)
        b = (kr + XT * (kg + kb)) / nk
        den = A_LASER - LAM_DETECT * b * b
        f = LAM_DETECT * b / nk
        y = ((1.0 - f * kr) * tr + (XT - f * kg) * tg + (XT - f * kb) * tb) / den
        proj[j] = y
        ssum = tr + tg + tb
        wht = max(tg, tb)
        if ssum <= 0 or tr <= min_th * ssum or tr - wht <= min_delta_th * ssum:
            continue
        if y > alpha * wht:
            score[j] = y


#: share of a candidate's peak evidence that bounds its extent along the line
CORE_SHARE = 0.35
#: half-width of the non-maximum suppression along the line, px
NMS_HALF = 2


@njit(cache=True, nogil=True)
def line_candidates(img: np.ndarray, bg: np.ndarray, mask: np.ndarray, sigma: float,
                    seed_dn: float, min_th: float, min_delta_th: float, alpha: float,
                    sat_dn: int, max_run_px: int, k_best: int,
                    out: np.ndarray) -> None:  # pragma: no cover
    """Candidate stripe crossings of every line, fitted.

    Evidence per pixel from :func:`detection_signal`. Candidates are its local maxima
    (within ``NMS_HALF``) of at least ``seed_dn``, and saturated red plateaus; a
    candidate's extent is the contiguous stretch around it whose evidence stays
    above ``CORE_SHARE`` of its peak (so a stripe crossing a red surface is cut out of
    the surface's own texture). Candidates wider than ``max_run_px`` or without an
    unsaturated red pixel next to a saturated plateau (a white highlight) are
    dropped; the ``k_best`` strongest of each line are fitted by :func:`fit_profile`.

    ``out`` has shape (L, k_best, N_FIELDS); rows without a candidate get NaN.
    """
    n_lines, n = img.shape[0], img.shape[1]
    out[:] = np.nan
    res = np.empty(8)
    rs = np.empty(k_best)
    rc = np.empty(k_best)
    rn = np.empty(k_best, np.int64)
    score = np.empty(n)
    sat = np.empty(n, np.bool_)
    proj = np.empty(n)
    tmp = np.empty(2 * CLUTTER_HALF + 1)
    for i in range(n_lines):
        detection_signal(img, bg, mask, i, min_th, min_delta_th, alpha, sat_dn, score, sat,
                         proj)
        nk = 0
        j = 0
        while j < n:
            if score[j] < seed_dn:
                j += 1
                continue
            if sat[j]:
                # a saturated plateau: one candidate at its centre
                j0 = j
                peak = score[j]
                while j < n and sat[j] and score[j] >= seed_dn:
                    peak = max(peak, score[j])
                    j += 1
                j1 = j  # exclusive
                centre = 0.5 * (j0 + j1 - 1)
                red_flank = (j0 > 0 and score[j0 - 1] >= seed_dn) or \
                    (j1 < n and score[j1] >= seed_dn)
                if not red_flank:
                    continue  # no red next to the plateau: a white highlight
                lim = max(seed_dn, CORE_SHARE * peak)
                a = j0
                while a > 0 and score[a - 1] >= lim and not sat[a - 1]:
                    a -= 1
                b = j1
                while b < n and score[b] >= lim and not sat[b]:
                    b += 1
                run_n = b - a
            else:
                # a local maximum of the evidence
                lo = max(j - NMS_HALF, 0)
                hi = min(j + NMS_HALF + 1, n)
                is_max = True
                for q in range(lo, hi):
                    if q != j and (score[q] > score[j] or (score[q] == score[j] and q < j)
                                   or sat[q]):
                        is_max = False
                        break
                if not is_max:
                    j += 1
                    continue
                peak = score[j]
                centre = float(j)
                lim = max(seed_dn, CORE_SHARE * peak)
                a = j
                while a > 0 and score[a - 1] >= lim and not sat[a - 1]:
                    a -= 1
                b = j + 1
                while b < n and score[b] >= lim and not sat[b]:
                    b += 1
                run_n = b - a
                j += 1
            if run_n > max_run_px:
                continue
            # keep the k_best strongest (insertion into a short sorted list)
            if nk < k_best:
                slot = nk
                nk += 1
            elif peak > rs[nk - 1]:
                slot = nk - 1
            else:
                continue
            while slot > 0 and rs[slot - 1] < peak:
                rs[slot] = rs[slot - 1]
                rc[slot] = rc[slot - 1]
                rn[slot] = rn[slot - 1]
                slot -= 1
            rs[slot] = peak
            rc[slot] = centre
            rn[slot] = run_n
        for q in range(nk):
            if fit_profile(img, bg, i, rc[q], rn[q], sigma, sat_dn, res):
                for f in range(8):
                    out[i, q, f] = res[f]
                out[i, q, C_PRE] = rs[q]
                out[i, q, C_RUN] = rn[q]
                # clutter: robust spread of the laser estimate around the candidate,
                # its core left out (texture a red surface adds where colour cannot
                # separate it from the laser; robust to a neighbouring edge)
                c = int(rc[q] + 0.5)
                h = max(CLUTTER_CORE, rn[q] // 2 + 2)
                nn = 0
                for jj in range(max(c - CLUTTER_HALF, 0), min(c + CLUTTER_HALF + 1, n)):
                    if abs(jj - c) > h and mask[i, jj] and not sat[jj]:
                        tmp[nn] = max(score[jj], 0.0)
                        nn += 1
                if nn >= 4:
                    srt = np.sort(tmp[:nn])
                    out[i, q, C_CLUT] = srt[int(CLUTTER_QUANTILE * (nn - 1))]
