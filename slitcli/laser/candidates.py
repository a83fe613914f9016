"""Step 3 of the stripe model: candidate crossings per column, seeded and fitted (numba).

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
Each fit's significance is judged against the local noise: the larger of the image's
evidence noise and the robust noise of the evidence around the candidate (its core
left out), so red texture that the colour cannot cancel raises the bar where it is.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.judge import own_light
from slitcli.laser.profile import (
    F_AMP,
    F_CHI2,
    F_FLAT,
    F_GNOISE,
    F_KB,
    F_KG,
    F_KR,
    F_NCORE,
    F_NOISE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_TB,
    F_TG,
    F_TR,
    F_WIDTH,
    F_Z,
    N_PAR,
    WORK_ROWS,
    fit_gaussian,
    flat_top,
    gaussian_rows,
    plateau_centre,
)

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


@njit(cache=True, nogil=True)
def _local_sigma(yi: np.ndarray, mi: np.ndarray, c: float, core: float,
                 clip: float) -> float:  # pragma: no cover
    """Noise of the evidence ``yi`` within ``NOISE_HALF + core`` rows of ``c``, the rows
    within ``core`` left out: the mean absolute lag-2 residual (each clipped at ``clip``,
    so that an edge or a second stripe counts as no more than that), scaled to a
    Gaussian's sigma (``sqrt(pi / 2)`` over the residual's ``sqrt(1.5)``)."""
    n = yi.shape[0]
    lo = max(int(c - core - NOISE_HALF), 2)
    hi = min(int(c + core + NOISE_HALF) + 1, n - 2)
    m = 0
    acc = 0.0
    for j in range(lo, hi):
        if abs(j - c) <= core + 2.0 or not (mi[j - 2] and mi[j + 2]):
            continue
        acc += min(abs(yi[j] - 0.5 * (yi[j - 2] + yi[j + 2])), clip)
        m += 1
    if m < 8:
        return 0.0
    return MEAN_TO_SIGMA * acc / m


@njit(cache=True, nogil=True)
def _linear_z(y: np.ndarray, use: np.ndarray, j0: int, v: float, s: float,
              sigma: float, e: np.ndarray) -> float:  # pragma: no cover
    """Significance of a Gaussian of fixed centre ``v`` and width ``s`` on a straight
    background over the used rows of ``y`` (rows ``j0 ..``): the linear least-squares
    amplitude over its standard error, ``e_perp . y / (sigma |e_perp|)`` with
    ``e_perp`` the Gaussian's part that the line does not explain (the matched
    filter's output against the noise); 0 with fewer than six rows. ``e`` (rows,)
    scratch."""
    m = y.shape[0]
    gaussian_rows(j0, v, s, e[:m])
    n = s2 = se = sd = sdd = sde = sy = sdy = sey = 0.0
    for jj in range(m):
        w = 1.0 if use[jj] else 0.0
        d = j0 + jj - v
        ej = e[jj] * w
        yj = y[jj] * w
        n += w
        sd += d * w
        sdd += d * d * w
        se += ej
        sde += d * ej
        s2 += ej * e[jj]
        sy += yj
        sdy += d * yj
        sey += ej * y[jj]
    if n < 6.0:
        return 0.0
    # the line's normal equations (n, sd; sd, sdd) give the projections of the
    # Gaussian onto the line, which leave e_perp . e_perp and e_perp . y
    det = n * sdd - sd * sd
    if not det > 0.0:
        return 0.0
    ae = (sdd * se - sd * sde) / det
    be = (n * sde - sd * se) / det
    ee = s2 - (ae * se + be * sde)
    ey = sey - (ae * sy + be * sdy)
    if not ee > 1e-12 * s2:
        return 0.0
    return ey / (sigma * math.sqrt(ee))


@njit(cache=True, nogil=True)
def _red_excess(img: np.ndarray, bg: np.ndarray, i: int, j: int) -> float:  # pragma: no cover
    """Red excess ``t_r - max(t_g, t_b)`` of the contrast of pixel ``j`` of column ``i``."""
    tr = float(img[i, j, 2]) - bg[3 * i + 2, j]
    tg = float(img[i, j, 1]) - bg[3 * i + 1, j]
    tb = float(img[i, j, 0]) - bg[3 * i, j]
    return tr - max(tg, tb)


@njit(cache=True, nogil=True)
def _red_flanks(img: np.ndarray, bg: np.ndarray, i: int, a: int, b: int,
                seed_dn: float) -> bool:  # pragma: no cover
    """Whether the clipped run ``[a, b)`` of column ``i`` has red light on both flanks:
    the largest red excess within ``FLANK_ROWS`` rows beyond each end (an image border
    counts as ``seed_dn``) positive on both sides and ``2 seed_dn`` together. A laser
    core's flanks are both red, their sum judged rather than each (a steep Gaussian
    flank sinks into the noise one row after the clip as often above as below); a
    white highlight's fringe is white on both sides."""
    n = img.shape[1]
    up = seed_dn if a == 0 else -1e300
    for d in range(1, FLANK_ROWS + 1):
        if a - d >= 0:
            up = max(up, _red_excess(img, bg, i, a - d))
    dn = seed_dn if b == n else -1e300
    for d in range(FLANK_ROWS):
        if b + d < n:
            dn = max(dn, _red_excess(img, bg, i, b + d))
    return up > 0.0 and dn > 0.0 and up + dn >= 2.0 * seed_dn


@njit(cache=True, nogil=True)
def _seeds(img: np.ndarray, bg: np.ndarray, i: int, yi: np.ndarray, ci: np.ndarray,
           mi: np.ndarray, seed_dn: float, sigma_y: float,
           max_run: int, rank: np.ndarray, centre: np.ndarray, run_a: np.ndarray,
           run_b: np.ndarray, noise: np.ndarray, buf: np.ndarray) -> int:  # pragma: no cover
    """The column's seeds, most significant first (module notes: against the local
    noise, which ``noise`` gets); returns how many."""
    clip = CLIP_SIGMAS * 1.2 * sigma_y  # (1.2 ~ sqrt(1.5): the residual's own scale)
    n = yi.shape[0]
    k = rank.shape[0]
    nk = 0
    j = 0
    while j < n:
        if not mi[j]:
            j += 1
            continue
        r = -1.0
        if ci[j]:
            a = j
            while j < n and ci[j] and mi[j]:
                j += 1
            b = j
            if b - a > max_run:
                continue
            if not _red_flanks(img, bg, i, a, b, seed_dn):
                continue
            c = 0.5 * (a + b - 1)
            sig = max(sigma_y, _local_sigma(yi, mi, c, 1.5 * (b - a) + 1.0, clip))
            r = 1e9 + (b - a)  # clipped cores rank first
        else:
            if yi[j] < seed_dn:
                j += 1
                continue
            top = True
            for q in range(max(j - NMS_HALF, 0), min(j + NMS_HALF + 1, n)):
                if q != j and (yi[q] > yi[j] or (yi[q] == yi[j] and q < j) or ci[q]):
                    top = False
            if not top:
                j += 1
                continue
            a = j
            b = j + 1
            c = float(j)
            # the core's extent: rows above half the peak
            lo = j
            while lo > 0 and yi[lo - 1] >= 0.5 * yi[j] and j - lo < max_run:
                lo -= 1
            hi = j
            while hi < n - 1 and yi[hi + 1] >= 0.5 * yi[j] and hi - j < max_run:
                hi += 1
            sig = max(sigma_y, _local_sigma(yi, mi, c, 1.5 * (hi - lo + 1) + 1.0, clip))
            r = yi[j] / sig
            j += NMS_HALF + 1
        if nk < k:
            slot = nk
            nk += 1
        elif r > rank[k - 1]:
            slot = k - 1
        else:
            continue
        while slot > 0 and rank[slot - 1] < r:
            rank[slot] = rank[slot - 1]
            noise[slot] = noise[slot - 1]
            centre[slot] = centre[slot - 1]
            run_a[slot] = run_a[slot - 1]
            run_b[slot] = run_b[slot - 1]
            slot -= 1
        rank[slot] = r
        noise[slot] = sig
        centre[slot] = c
        run_a[slot] = a
        run_b[slot] = b
    return nk


@njit(cache=True, nogil=True)
def column_candidates(img: np.ndarray, bg: np.ndarray, y: np.ndarray, y_avg: np.ndarray,
                      clipped: np.ndarray, mask: np.ndarray, sigma_y: float,
                      sigma_avg: float, seed_dn: float, strong_z: float, sat_dn: int,
                      s_max: float, shape_error: float, max_chi2: float, weak_z: float,
                      out: np.ndarray) -> None:  # pragma: no cover
    """Fitted candidates of every column into ``out`` (W, K, N_FIELDS), NaN where none.

    ``img`` (W, H, 3) BGR, ``bg`` its opening as (3 W, H), ``y`` and ``clipped`` (W, H)
    from :func:`~.evidence.laser_evidence`, ``y_avg`` the evidence averaged along the
    stripe over five columns (weights 1, 4, 6, 4, 1), ``mask`` (W, H) the searched
    pixels, ``sigma_y`` and ``sigma_avg`` the image's noise of the two, ``s_max`` the
    widest stripe's sigma, px. Seeds come from the averaged evidence (at least
    ``seed_dn``); each is fitted on the column's own evidence, and where that fit is less than
    ``strong_z`` significant also on the averaged one (noise about half, at the cost of
    resolution along the stripe), the more significant fit kept. Fields: :mod:`.profile`'s
    ``F_*`` (``F_T*`` the mean contrast of the core rows, ``F_K*`` the surface colour
    there, RGB). Where the Gaussian's reduced chi-square exceeds ``max_chi2`` a flat top
    is tried (:func:`~.profile.flat_top`; ``F_FLAT`` 1).

    An unclipped seed is fitted on either evidence only where a Gaussian of its own
    row and width is ``SEED_EFFICIENCY x weak_z`` significant there (:func:`_linear_z`,
    against the fit's noise): a candidate less than ``weak_z`` significant is never
    chosen, and a seed half a row off the centre keeps ``SEED_EFFICIENCY`` of the
    significance; a seed that fails takes no candidate slot (two thirds of the
    Gauss-Newton fits were of seeds that ended below ``weak_z``, or failed).
    """
    n_cols, n = y.shape
    k_best = out.shape[1]
    out[:] = np.nan
    # a clipped core spans more than the stripe's width: 2 s sqrt(2 ln(peak / clip))
    max_run = math.ceil(5.0 * s_max)
    screen_z = SEED_EFFICIENCY * weak_z
    rank = np.empty(N_SEEDS)
    noise = np.empty(N_SEEDS)
    centre = np.empty(N_SEEDS)
    run_a = np.empty(N_SEEDS, np.int64)
    run_b = np.empty(N_SEEDS, np.int64)
    buf = np.empty(n)
    res = np.empty(6)
    res_avg = np.empty(6)
    use = np.empty(n, np.bool_)
    red = np.empty(n)
    work = np.empty((WORK_ROWS, N_PAR))
    ebuf = np.empty(n)
    for i in range(n_cols):
        yi = y[i]
        ya = y_avg[i]
        ci = clipped[i]
        mi = mask[i]
        nk = _seeds(img, bg, i, ya, ci, mi, seed_dn, sigma_avg, max_run, rank, centre, run_a,
                    run_b, noise, buf)
        p = 0
        for q in range(nk):
            if p == k_best:
                break
            a, b = run_a[q], run_b[q]
            sat = ci[a]
            if sat:
                s0 = max(0.5 * (b - a), 0.8)
            else:
                half = 0.5 * ya[a]
                lo = a
                while lo > 0 and ya[lo - 1] >= half and mi[lo - 1]:
                    lo -= 1
                hi = a
                while hi < n - 1 and ya[hi + 1] >= half and mi[hi + 1]:
                    hi += 1
                s0 = max((hi - lo + 1) / 2.355, SEED_MIN_SIGMA_PX)
            s0 = min(s0, s_max)
            w_half = math.ceil(3.0 * s0 + 3.0) + (b - a) // 2
            j0 = max(int(centre[q]) - w_half, 0)
            j1 = min(int(centre[q]) + w_half + 2, n)
            m = j1 - j0
            for jj in range(m):
                use[jj] = mi[j0 + jj] and not ci[j0 + jj]
            core = 3.0 * s0 + 0.5 * (b - a)
            sig = max(sigma_y, _local_sigma(yi, mi, centre[q], core, CLIP_SIGMAS * 1.2 * sigma_y))
            gsig = sigma_y
            ok = (sat or _linear_z(yi[j0:j1], use[:m], j0, centre[q], s0, sig, ebuf)
                  >= screen_z) and fit_gaussian(yi[j0:j1], use[:m], j0, centre[q], s0, sig,
                                                shape_error, s_max, res, work, ebuf)
            if not sat and (not ok or res[3] < strong_z) and \
                    _linear_z(ya[j0:j1], use[:m], j0, centre[q], s0, noise[q], ebuf) >= screen_z:
                if fit_gaussian(ya[j0:j1], use[:m], j0, centre[q], s0, noise[q], shape_error,
                                s_max, res_avg, work, ebuf) and (not ok or res_avg[3] > res[3]):
                    res[:] = res_avg
                    sig = noise[q]
                    gsig = sigma_avg
                    ok = True
            flat = False
            if not sat and ok and res[5] > max_chi2:
                base = 1e300
                for jj in range(m):
                    if use[jj]:
                        base = min(base, yi[j0 + jj])
                if flat_top(yi[j0:j1], use[:m], j0, centre[q], base, sig, res_avg):
                    res[:] = res_avg
                    flat = True
            if sat:
                for jj in range(n):
                    red[jj] = img[i, jj, 2]
                lvl = 0.5 * (bg[3 * i + 2, int(centre[q])] + sat_dn)
                pc = plateau_centre(red, a, b, lvl)
                # the flank fit refines the plateau's centre where it agrees with it
                if not ok or abs(res[0] - pc) > 0.5 or res[2] < 0.5:
                    res[0] = pc
                    res[2] = s0  # (the run's half length, at most the widest stripe)
                    res[4] = 0.25
                    res[5] = 0.0
                    res[1] = sat_dn - bg[3 * i + 2, int(centre[q])]
                res[3] = max(res[3] if ok else 0.0,
                             (sat_dn - bg[3 * i + 2, int(centre[q])]) / sig)
            elif not ok:
                continue
            # one fit per crossing: a second seed converging on a kept one is dropped
            dup = False
            for r in range(p):
                if abs(out[i, r, F_POS] - res[0]) < 1.0:
                    dup = True
            if dup:
                continue
            o = out[i, p]
            o[F_POS] = res[0]
            o[F_AMP] = res[1]
            o[F_WIDTH] = res[2]
            o[F_Z] = res[3]
            o[F_SE_POS] = res[4]
            o[F_CHI2] = res[5]
            o[F_SAT] = 1.0 if sat else 0.0
            o[F_NOISE] = sig
            o[F_GNOISE] = gsig
            o[F_FLAT] = 1.0 if flat else 0.0
            # the light the core adds, and the surface colour there (RGB)
            tr = tg = tb = kr = kg = kb = 0.0
            nc = 0
            reach = max(res[2], 1.0)
            for j in range(max(int(res[0] - reach), 0), min(int(res[0] + reach) + 2, n)):
                if abs(j - res[0]) > reach or ci[j]:
                    continue
                br, bgg, bb = bg[3 * i + 2, j], bg[3 * i + 1, j], bg[3 * i, j]
                tr += img[i, j, 2] - br
                tg += img[i, j, 1] - bgg
                tb += img[i, j, 0] - bb
                kr += br + 0.5
                kg += bgg + 0.5
                kb += bb + 0.5
                nc += 1
            o[F_NCORE] = nc
            if nc > 0:
                o[F_TR], o[F_TG], o[F_TB] = tr / nc, tg / nc, tb / nc
                o[F_KR], o[F_KG], o[F_KB] = kr / nc, kg / nc, kb / nc
            p += 1


@njit(cache=True, nogil=True)
def sheet_width_px(cand: np.ndarray, px_per_m: np.ndarray, sheet_sigma_mm: float,
                   sheet_px: np.ndarray) -> None:  # pragma: no cover
    """The sheet's sigma, ``sheet_sigma_mm``, in pixels at each candidate's row
    (``cand[..., F_POS]``, (W, K), image rows) into ``sheet_px`` (W, K); ``px_per_m``
    (H, W): image rows per metre of height where each pixel's ray meets the laser
    plane. (A gather per candidate: numpy's fancy indexing over a float64 copy of
    ``px_per_m`` cost ~0.2 ms a frame.)"""
    n_rows = px_per_m.shape[0]
    for i in range(cand.shape[0]):
        for q in range(cand.shape[1]):
            pos = cand[i, q, F_POS]
            r = 0 if np.isnan(pos) else int(min(max(np.rint(pos), 0.0), n_rows - 1))
            sheet_px[i, q] = float(px_per_m[r, i]) * sheet_sigma_mm * 1e-3


@njit(cache=True, nogil=True)
def evidence_live(mask: np.ndarray, img: np.ndarray, clipped: np.ndarray,
                  out: np.ndarray) -> bool:  # pragma: no cover
    """Pixels (W, H) whose evidence shows the noise: searched (``mask``), red inside its
    range (above 0 in ``img`` (W, H, 3) BGR; not ``clipped``); returns whether any."""
    any_live = False
    for i in range(mask.shape[0]):
        for j in range(mask.shape[1]):
            out[i, j] = mask[i, j] and img[i, j, 2] > 0 and not clipped[i, j]
            any_live = any_live or out[i, j]
    return any_live


@njit(cache=True, nogil=True)
def _fit_gap(y_avg: np.ndarray, clipped: np.ndarray, mask: np.ndarray, i: int, row: float,
             width: float, sigma_avg: float, z_min: float, shape_error: float, s_max: float,
             res: np.ndarray, use: np.ndarray, work: np.ndarray,
             ebuf: np.ndarray) -> float:  # pragma: no cover
    """The averaged evidence of column ``i`` fitted near ``row`` (rows of ``y_avg``),
    starting at width ``width``: the fitted row, or NaN where the fit is not within a
    pixel of ``row`` or less than ``z_min`` significant (against ``sigma_avg``).
    ``res``, ``use``, ``work``, ``ebuf``: scratch."""
    n = y_avg.shape[1]
    s0 = min(max(width, 0.6), s_max)
    w_half = math.ceil(3.0 * s0 + 3.0)
    c = int(row + 0.5)
    j0 = max(c - w_half, 0)
    j1 = min(c + w_half + 1, n)
    m = j1 - j0
    if m < 6:
        return np.nan
    for jj in range(m):
        use[jj] = mask[i, j0 + jj] and not clipped[i, j0 + jj]
    if fit_gaussian(y_avg[i, j0:j1], use[:m], j0, row, s0, sigma_avg, shape_error,
                    s_max, res, work, ebuf) and abs(res[0] - row) <= 1.0 and \
            res[3] >= z_min:
        return res[0]
    return np.nan


@njit(cache=True, nogil=True)
def fill_gaps(v: np.ndarray, amp: np.ndarray, cand: np.ndarray, y: np.ndarray,
              y_avg: np.ndarray, clipped: np.ndarray, mask: np.ndarray, sigma_y: float,
              sigma_avg: float, row0: int, max_gap: int, max_jump_px: float, z_min: float,
              shape_error: float, s_max: float, own_z: float) -> None:  # pragma: no cover
    """Columns without a stripe between two found ones at most ``max_gap + 1`` apart
    whose rows differ by at most ``max_jump_px`` a column: the stripe passes there, so
    the averaged evidence ``y_avg`` (W, H', rows from ``row0``) of each column between
    is fitted at the row interpolated across the gap (:func:`_fit_gap`, starting at the
    width of the left column's candidate nearest its row). Where that fit holds
    (``z_min`` significant against ``sigma_avg``, within a pixel of the interpolated
    row, and its light the column's own: :func:`~.judge.own_light`, ``own_z``), ``v``
    (W,, rows from the image's top) gets the fitted row and ``amp`` (W,) the left
    column's peak (0 where that is NaN)."""
    n = y_avg.shape[1]
    res = np.empty(6)
    use = np.empty(n, np.bool_)
    work = np.empty((WORK_ROWS, N_PAR))
    ebuf = np.empty(n)
    found = np.flatnonzero(np.isfinite(v))
    for f in range(found.shape[0] - 1):
        a, b = found[f], found[f + 1]
        gap = b - a
        if gap <= 1 or gap > max_gap + 1 or not abs(v[b] - v[a]) <= max_jump_px * gap:
            continue
        # the width of the left column's candidate nearest its row (the first of equals)
        k_best = -1
        best = np.inf
        for q in range(cand.shape[1]):
            d = abs(cand[a, q, 0] - v[a])
            if d < best:
                best = d
                k_best = q
        width = cand[a, max(k_best, 0), 2]
        fill = 0.0 if np.isnan(amp[a]) else min(max(amp[a], -1.7976931348623157e308),
                                                1.7976931348623157e308)
        for i in range(a + 1, b):
            t = (i - a) / (b - a)
            row = v[a] + t * (v[b] - v[a])
            out = _fit_gap(y_avg, clipped, mask, i, row - row0, width, sigma_avg, z_min,
                           shape_error, s_max, res, use, work, ebuf)
            if np.isfinite(out) and own_light(y, y_avg, clipped, mask, i, out, width,
                                              sigma_y, shape_error, own_z):
                v[i] = out + row0
                amp[i] = fill
