"""Compiled (numba) candidate crossings per image column (paper Eqs. 1-3 and the seeds of Eq. 4).

Images come in transposed, ``(W, H, 3)`` BGR uint8 (one image column per array row;
views of the ``(H, W, 3)`` images), the background as ``(3 W, H)`` (one channel of one
column per row, :func:`evidence`); all loops over pixels live here and in
:mod:`slitcli.laser.fit`, compiled. The signal model is :mod:`slitcli.laser.fit`'s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.fit import (
    A_LASER,
    C_AMP,
    C_CHI2,
    C_CLUT,
    C_Z,
    N_FIELDS,
    N_WORK,
    XT,
    fit_profile,
)

#: share of the surface-colour direction the per-pixel evidence removes: 1 would
#: remove all texture but amplify noise without bound on surfaces of the laser's colour
LAM_DETECT = 0.99
NOISE_BLOCK = 16  # rows sharing one surface colour in the noise estimate
CORE_SHARE = 0.35  # a candidate's extent: evidence above this share of its peak
#: a candidate whose evidence is below this share of a strong first candidate's is not
#: fitted: its red-peak term (at most this share) plus beta and gamma (each at most 1,
#: paper weights 0.25) cannot beat the first's
SECONDARY_SHARE = 0.5
NMS_HALF = 2  # half-width of the non-maximum suppression along a column, px
CLUTTER_HALF = 24  # half-window of the clutter level, px
CLUTTER_CORE = 4  # half-width left out around the candidate for the clutter, px
#: a candidate must stand MIN_CLUTTER_RATIO times (in quadrature with the noise)
#: above all but CLUTTER_SHARE of the evidence around it
MIN_CLUTTER_RATIO = 1.5
CLUTTER_SHARE = 0.2
#: one minus the cosine between the surface colours above and below beyond which a
#: candidate sits on an edge between two surfaces (a red band ending at the floor)
MAX_EDGE = 0.02
#: largest mean square, per core row in noise variances, of the light a fit gives the
#: laser across the plane of the laser colour and the surface colour
#: (:data:`~slitcli.laser.fit.C_COLOUR`): 16 = 4 noise sigmas a row, beyond any noise
#: (a stripe's rows in the stress set: median 0.8, 99.5 % below 7)
MAX_COLOUR = 16.0
#: evidence peaks per column taken in order of strength to fill the K fitted slots:
#: a peak found on an edge between surfaces (never the stripe) frees its slot for the
#: next, so a red object's two edges cannot hide the stripe between them
N_SEEDS = 5


@njit(cache=True, nogil=True)
def _min3(src: np.ndarray, dst: np.ndarray, m: int, sh1: int, sh2: int,
          is_max: bool) -> None:  # pragma: no cover
    """``dst[t] = min(src[t], src[t + sh1], src[t + sh2])`` (max with ``is_max``) for
    ``t < m``; the explicit slices let the compiler vectorise the loop."""
    a = src[:m]
    b = src[sh1:sh1 + m]
    c = src[sh2:sh2 + m]
    d = dst[:m]
    if is_max:
        for t in range(m):
            u, v, w = a[t], b[t], c[t]
            u = u if u > v else v
            d[t] = u if u > w else w
    else:
        for t in range(m):
            u, v, w = a[t], b[t], c[t]
            u = u if u < v else v
            d[t] = u if u < w else w


@njit(cache=True, nogil=True)
def _vertical_filter(x: np.ndarray, k: int, out: np.ndarray, buf_a: np.ndarray,
                     buf_b: np.ndarray, is_max: bool) -> None:  # pragma: no cover
    """Minimum (maximum) over ``k`` rows, anchor ``k // 2``, of ``x`` (rows, C) uint8
    into ``out``; rows beyond the border are left out (OpenCV's erosion and dilation
    with a (k, 1) kernel). Windows doubled in width pass by pass (1, 2, 4, ... rows),
    the last pass joins three: a handful of passes instead of ``k`` comparisons a
    pixel; the scratch buffers hold ``(rows + k - 1) C`` values."""
    n = x.shape[0]
    c = x.shape[1]
    hc = (k // 2) * c
    xf = x.reshape(n * c)
    fill = 0 if is_max else 255  # the padding never wins
    pad_a = buf_a[:hc]
    for t in range(hc):
        pad_a[t] = fill
    mid = buf_a[hc:hc + n * c]
    for t in range(n * c):
        mid[t] = xf[t]
    pad_b = buf_a[hc + n * c:(n + k - 1) * c]
    for t in range(pad_b.size):
        pad_b[t] = fill
    w = 1
    src, dst = buf_a, buf_b
    while 3 * w < k:
        # rows j .. j + 2 w - 1 from two windows of w rows
        _min3(src, dst, (n + k - 2 * w) * c, w * c, w * c, is_max)
        w *= 2
        src, dst = dst, src
    # rows j .. j + k - 1 from three windows of w rows (3 w >= k)
    _min3(src, out.reshape(n * c), n * c, min(w, k - w) * c, (k - w) * c, is_max)


@njit(cache=True, nogil=True)
def vertical_opening(x: np.ndarray, k: int, out: np.ndarray) -> None:  # pragma: no cover
    """Morphological opening of ``x`` (rows, C) uint8 along its rows with a window of
    ``k`` rows, into ``out`` (same shape): the same values as OpenCV's
    ``morphologyEx(x, MORPH_OPEN, ones((k, 1)))`` (min and max are exact), single
    threaded, a fifth faster at 320 x 240 x 3."""
    n, c = x.shape
    buf_a = np.empty((n + k - 1) * c, np.uint8)
    buf_b = np.empty((n + k - 1) * c, np.uint8)
    _vertical_filter(x, k, out, buf_a, buf_b, False)
    _vertical_filter(out, k, out, buf_a, buf_b, True)


@njit(cache=True, nogil=True)
def noise_sigma(img: np.ndarray, bg: np.ndarray, step: int) -> float:  # pragma: no cover
    """Robust per-channel noise sigma (DN) from the colour orthogonal to the surface's.

    Texture and shading scale all channels of a surface alike, so the part of a pixel
    orthogonal to its surface's colour (the mean colour of its block of
    ``NOISE_BLOCK`` rows) is noise (two dimensions) plus rare edges, highlights and
    the laser. Its second difference along the column has ``E|d2|^2 = 12 sigma^2``, a
    scaled chi-square with 2 degrees of freedom whose median is ``2 ln 2`` times its
    mean over 2. Every ``step``-th column is used; ``bg`` is not needed (kept for the
    callers' symmetry).
    """
    n_lines, n = img.shape[0], img.shape[1]
    vals = np.empty(((n_lines + step - 1) // step) * n)
    m = 0
    p = np.empty((NOISE_BLOCK, 3))
    for i in range(0, n_lines, step):
        for j0 in range(0, n - NOISE_BLOCK + 1, NOISE_BLOCK):
            cr = cg = cb = 0.5
            for j in range(j0, j0 + NOISE_BLOCK):
                cr += img[i, j, 2]
                cg += img[i, j, 1]
                cb += img[i, j, 0]
            nn = math.sqrt(cr * cr + cg * cg + cb * cb)
            cr /= nn
            cg /= nn
            cb /= nn
            for jj in range(NOISE_BLOCK):
                xr = float(img[i, j0 + jj, 2])
                xg = float(img[i, j0 + jj, 1])
                xb = float(img[i, j0 + jj, 0])
                q = xr * cr + xg * cg + xb * cb
                p[jj, 0] = xr - q * cr
                p[jj, 1] = xg - q * cg
                p[jj, 2] = xb - q * cb
            for jj in range(1, NOISE_BLOCK - 1):
                acc = 0.0
                for c in range(3):
                    d = 2.0 * p[jj, c] - p[jj - 1, c] - p[jj + 1, c]
                    acc += d * d
                vals[m] = acc
                m += 1
    if m == 0:
        return 0.0
    med = np.median(vals[:m])
    return math.sqrt(med / (6.0 * 2.0 * math.log(2.0)))


@njit(cache=True, nogil=True, error_model="numpy")
def evidence(img: np.ndarray, bg: np.ndarray, mask: np.ndarray, i: int, min_th: float,
             min_delta_th: float, alpha: float, sat_dn: int, score: np.ndarray,
             sat: np.ndarray) -> None:  # pragma: no cover
    """Per-pixel laser evidence of column ``i`` (paper Eqs. 1-3), into ``score``.

    ``bg``, the local background (a vertical opening), comes per channel, (3 W, H):
    row ``3 i + c`` holds channel ``c`` (b, g, r) of column ``i`` (the transpose of
    the one-channel (H, 3 W) view of an (H, W, 3) image). On the contrast ``t = x -
    bg`` (light above the local background): Eq. 1/2 on the chromaticity of ``t``,
    ``t_r > min_th sum(t)`` and ``t_r - max(t_g, t_b) > min_delta_th sum(t)``; Eq. 3,
    white rejection, ``y > alpha max(t_g, t_b)`` with ``y = w . t`` the laser estimate
    (``w . l = 1``, the background's colour removed to the share ``LAM_DETECT``, so
    texture, shading and, on grey surfaces, white light cancel). ``score = y`` where all hold, -1
    elsewhere; a saturated red pixel (exempt: a clipped core turns white) gets its
    red contrast and ``sat`` True.
    """
    n = img.shape[1]
    # the column's pixels as flat runs of b, g, r, every pixel computed alike and the
    # outcomes selected without branches: the compiler turns the loop into vector
    # instructions (twice as fast as skipping masked pixels and caching the weights per
    # background colour, with the same values: the weights are a function of it)
    # (C-contiguous images, as the extractor's, are not copied here; other layouts are;
    # the background's channels are separate runs, which load without shuffles)
    xi = np.ascontiguousarray(img[i]).reshape(n * 3)
    b_b, b_g, b_r = bg[3 * i], bg[3 * i + 1], bg[3 * i + 2]
    mi = mask[i]
    for j in range(n):
        xr = xi[3 * j + 2]
        br = b_r[j]
        bgg = b_g[j]
        bb = b_b[j]
        tr = float(xr) - br
        tg = float(xi[3 * j + 1]) - bgg
        tb = float(xi[3 * j]) - bb
        # w = (l - LAM k (k . l) / |k|^2) / (|l|^2 - LAM (k . l)^2 / |k|^2), with
        # |k|^2 multiplied through: one division, no square root
        kr = br + 0.5
        kg = bgg + 0.5
        kb = bb + 0.5
        k2 = kr * kr + kg * kg + kb * kb
        lq = LAM_DETECT * (kr + XT * (kg + kb))
        inv = 1.0 / (A_LASER * k2 - lq * (kr + XT * (kg + kb)))
        wr = (k2 - lq * kr) * inv
        wg = (XT * k2 - lq * kg) * inv
        wb = (XT * k2 - lq * kb) * inv
        ssum = tr + tg + tb
        wht = max(tg, tb)
        y = wr * tr + wg * tg + wb * tb
        ok = (tr > 0.0) & (tr > min_th * ssum) & (tr - wht > min_delta_th * ssum) & \
            (y > alpha * wht)
        m = mi[j]
        clipped = xr >= sat_dn
        sat[j] = m & clipped
        v = y if ok else -1.0
        v = tr if clipped else v
        score[j] = v if m else -1.0


@njit(cache=True, nogil=True)
def _clutter(score: np.ndarray, sat: np.ndarray, mask: np.ndarray, i: int, centre: float,
             run_n: int, amp: float, sigma: float) -> float:  # pragma: no cover
    """Share of the positive evidence within ``CLUTTER_HALF`` rows (the candidate's
    core left out) that comes within ``MIN_CLUTTER_RATIO`` of the amplitude ``amp``
    (in quadrature with the noise): texture of a red surface, which colour cannot
    tell from the laser, makes it large."""
    n = score.shape[0]
    c = int(centre + 0.5)
    hw = max(CLUTTER_CORE, run_n // 2 + 2)
    lim = amp / MIN_CLUTTER_RATIO
    lim = math.sqrt(max(lim * lim - sigma * sigma, 0.0))
    nn = 0
    above = 0
    # the rows above the core, then below it (counts without branches)
    for jj in range(max(c - CLUTTER_HALF, 0), min(c - hw, n)):
        use = mask[i, jj] & (not sat[jj])
        nn += use
        above += use & (score[jj] > lim)
    for jj in range(max(c + hw + 1, 0), min(c + CLUTTER_HALF + 1, n)):
        use = mask[i, jj] & (not sat[jj])
        nn += use
        above += use & (score[jj] > lim)
    return above / nn if nn > 0 else 0.0


@njit(cache=True, nogil=True)
def column_candidates(img: np.ndarray, bg: np.ndarray, mask: np.ndarray, sigma: float,
                      sigma_avg: float, seed_dn: float, min_th: float, min_delta_th: float,
                      alpha: float, sat_dn: int, max_run_px: int, s_max: float,
                      support_z: float, z_strong: float, g_map: np.ndarray, sheet_m: float,
                      out: np.ndarray, out_avg: np.ndarray) -> None:  # pragma: no cover
    """The ``K = out.shape[1]`` strongest candidate crossings of every column, fitted.

    Candidates are local maxima (within ``NMS_HALF``) of the :func:`evidence` of at
    least ``seed_dn``, and saturated red plateaus with red pixels on both sides (a white
    highlight's fringe is white). A candidate's extent is the stretch around it where the
    evidence stays above ``CORE_SHARE`` of its peak (so a stripe crossing a red
    surface is cut out of the surface's texture); longer than ``max_run_px``, it is
    a red object. Seeds rank by their evidence peak (a clipped plateau by its
    brightest flank where that is higher: on a red surface the clipped pixels keep
    only ``255`` less the surface's red). Each is fitted by :func:`fit_profile`
    (widths beyond ``s_max`` px are not refined), with ``C_CLUT`` from
    :func:`_clutter`. ``bg`` is the background as :func:`evidence` takes it. A
    candidate of significance in ``[support_z, z_strong)`` (a
    faint stripe, or noise) is fitted again on the column averaged with its
    neighbours (noise ``sigma_avg``) into ``out_avg``. With ``sheet_m > 0`` the
    width of the sheet there (``g_map`` (W, H), rows per metre, times ``sheet_m``)
    is the fits' prior. ``out`` and ``out_avg`` have shape (W, K, N_FIELDS); NaN
    where none.
    """
    n_lines = img.shape[0]
    out[:] = np.nan
    out_avg[:] = np.nan
    _candidates_range(img, bg, mask, sigma, sigma_avg, seed_dn, min_th, min_delta_th, alpha,
                      sat_dn, max_run_px, s_max, support_z, z_strong, g_map, sheet_m, 0,
                      n_lines, out, out_avg)


@njit(cache=True, nogil=True)
def _candidates_range(img: np.ndarray, bg: np.ndarray, mask: np.ndarray, sigma: float,
                      sigma_avg: float, seed_dn: float, min_th: float, min_delta_th: float,
                      alpha: float, sat_dn: int, max_run_px: int, s_max: float,
                      support_z: float, z_strong: float, g_map: np.ndarray, sheet_m: float,
                      i0: int, i1: int, out: np.ndarray,
                      out_avg: np.ndarray) -> None:  # pragma: no cover
    """:func:`column_candidates` for columns ``i0 .. i1 - 1`` (own workspace)."""
    n = img.shape[1]
    k_best = out.shape[1]
    res = np.empty(N_FIELDS)
    ws = np.empty((8, N_WORK))
    n_seeds = max(k_best, N_SEEDS)
    rs = np.empty(n_seeds)
    rc = np.empty(n_seeds)
    rn = np.empty(n_seeds, np.int64)
    score = np.empty(n)
    sat = np.empty(n, np.bool_)
    for i in range(i0, i1):
        evidence(img, bg, mask, i, min_th, min_delta_th, alpha, sat_dn, score, sat)
        nk = 0
        j = 0
        while j < n:
            if score[j] < seed_dn:
                j += 1
                continue
            if sat[j]:
                j0 = j
                peak = score[j]
                while j < n and sat[j] and score[j] >= seed_dn:
                    peak = max(peak, score[j])
                    j += 1
                # a clipped laser core has red flanks on both sides (its light is red
                # wherever it is not clipped); a white highlight's fringe is white, and
                # noise or texture makes one side red only by chance
                red_a = j0 == 0 or not mask[i, j0 - 1] or score[j0 - 1] >= seed_dn
                red_b = j == n or not mask[i, j] or score[j] >= seed_dn
                if not (red_a and red_b):
                    continue
                if nk == n_seeds and peak <= rs[nk - 1]:
                    continue  # weaker than every kept seed: its extent does not matter
                centre = 0.5 * (j0 + j - 1)
                # the clipped pixels' contrast understates the core (its flanks can
                # show more): the seed ranks by its brightest flank when that is higher
                rank = max(peak, score[j0 - 1] if j0 > 0 else 0.0,
                           score[j] if j < n else 0.0)
                lim = max(seed_dn, CORE_SHARE * peak)
                # the extent's walks stop once it is longer than max_run_px (then a red
                # object, whatever its length): red surfaces hold many texture maxima
                a = j0
                while a > 0 and j - a <= max_run_px and score[a - 1] >= lim and \
                        not sat[a - 1]:
                    a -= 1
                b = j
                while b < n and b - a <= max_run_px and score[b] >= lim and not sat[b]:
                    b += 1
            else:
                beaten = -1
                for q in range(max(j - NMS_HALF, 0), min(j + NMS_HALF + 1, n)):
                    if q != j and (score[q] > score[j] or (score[q] == score[j] and q < j)
                                   or sat[q]):
                        beaten = q
                        break
                if beaten >= 0:
                    # the rows between j and a later row that beats it are no higher
                    # than j and unsaturated: that row beats them too
                    j = max(beaten, j + 1)
                    continue
                peak = score[j]
                if nk == n_seeds and peak <= rs[nk - 1]:
                    j += NMS_HALF + 1  # (the next NMS_HALF rows are below j: no maxima)
                    continue
                centre = float(j)
                rank = peak
                lim = max(seed_dn, CORE_SHARE * peak)
                a = j
                while a > 0 and j + 1 - a <= max_run_px and score[a - 1] >= lim and \
                        not sat[a - 1]:
                    a -= 1
                b = j + 1
                while b < n and b - a <= max_run_px and score[b] >= lim and not sat[b]:
                    b += 1
                j += NMS_HALF + 1
            run_n = b - a
            if run_n > max_run_px:
                continue
            if nk < n_seeds:
                slot = nk
                nk += 1
            elif rank > rs[nk - 1]:
                slot = nk - 1
            else:
                continue
            while slot > 0 and rs[slot - 1] < rank:
                rs[slot] = rs[slot - 1]
                rc[slot] = rc[slot - 1]
                rn[slot] = rn[slot - 1]
                slot -= 1
            rs[slot] = rank
            rc[slot] = centre
            rn[slot] = run_n
        p = 0  # slots filled
        r0q = 0  # the seed in slot 0
        for q in range(nk):
            if p == k_best:
                break
            if p > 0 and out[i, 0, C_Z] >= z_strong and rs[q] < SECONDARY_SHARE * rs[r0q]:
                break  # Eq. 4 cannot prefer it to a strong first candidate
            s_core = 0.0
            if sheet_m > 0.0:
                gpx = g_map[i, min(max(int(rc[q] + 0.5), 0), n - 1)]
                if np.isfinite(gpx):
                    s_core = gpx * sheet_m
            # on an edge between surfaces (never the stripe) a seed is not fitted
            # while another is left to take the slot
            if not fit_profile(img, i, rc[q], rn[q], sigma, sat_dn, s_max, s_core, 0.0, False,
                               False, MAX_EDGE if q + 1 < nk else 0.0, ws, res):
                continue
            if p == 0:
                r0q = q
            for f in range(N_FIELDS):
                out[i, p, f] = res[f]
            if np.isfinite(res[C_CHI2]):  # (a quick look's noise bump needs no clutter)
                out[i, p, C_CLUT] = _clutter(score, sat, mask, i, rc[q], rn[q], res[C_AMP],
                                             sigma)
            # a faint candidate, in a column without a strong one, is fitted again on
            # the column averaged with its neighbours
            strong = p > 0 and out[i, 0, C_Z] >= z_strong
            if not strong and support_z <= res[C_Z] < z_strong and \
                    fit_profile(img, i, rc[q], rn[q], sigma_avg, sat_dn, s_max, s_core, 0.0, True,
                                False, 0.0, ws, res):
                for f in range(N_FIELDS):
                    out_avg[i, p, f] = res[f]
                out_avg[i, p, C_CLUT] = _clutter(score, sat, mask, i, rc[q], rn[q],
                                                 res[C_AMP], sigma)
            p += 1


