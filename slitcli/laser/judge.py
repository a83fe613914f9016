"""Step 4 of the stripe model: which candidates can be the laser.

:func:`valid_candidates` applies the tests that follow from the model (width, shape,
significance, colour, the sheet's thickness); :func:`laser_share` and
:func:`surface_continues` tell the laser's light from the surface's own colour;
:func:`own_light` asks a fit on the evidence averaged along the stripe to show in its
own column's evidence. The choice along the stripe among the candidates that pass is
:mod:`slitcli.laser.choose`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.profile import (
    F_CHI2,
    F_FLAT,
    F_GNOISE,
    F_KB,
    F_KG,
    F_KR,
    F_NCORE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_TB,
    F_TG,
    F_TR,
    F_WIDTH,
    F_Z,
    MIN_SIGMA_PX,
)

#: a Gaussian's equivalent width (sum over peak) in sigmas, rounded
EQ_WIDTH = 2.5
#: a pixel integrates the profile over its extent: variance 1/12 px^2
PIXEL_VAR = 1.0 / 12.0
#: candidates this many times min_z significant (unclipped) estimate the laser colour;
#: at least COLOUR_SUPPORT of them are needed
COLOUR_Z = 2.0
COLOUR_SUPPORT = 8
#: the laser is red: its green and blue response at most this share of its red
MAX_LASER_GB = 0.6
#: colour residual allowed for noise alone, in noise sigmas of the core's mean
COLOUR_SIGMAS = 3.0
#: an unclipped candidate may be this many times wider than the median width of the
#: frame's strong columns (the sheet's width changes with range and incidence)
WIDTH_SPREAD = 2.5
#: chromaticity step (any channel) between the surface above and below a candidate
#: beyond which they are two surfaces; sides darker than SURFACE_MIN_DN are not judged
SURFACE_STEP = 0.1
SURFACE_MIN_DN = 10.0


def laser_colour(cand: np.ndarray, ok: np.ndarray, min_z: float) -> np.ndarray | None:
    """The laser's colour (RGB, red 1) from the frame's strong unclipped candidates
    (median of their core contrast over its red), or None with fewer than
    ``COLOUR_SUPPORT`` of them."""
    strong = ok & (cand[..., F_Z] >= COLOUR_Z * min_z) & (cand[..., F_SAT] == 0) & \
        (cand[..., F_NCORE] > 0) & (cand[..., F_TR] > 0)
    if strong.sum() < COLOUR_SUPPORT:
        return None
    t = cand[strong][:, [F_TR, F_TG, F_TB]]
    gb = np.clip(np.median(t[:, 1:] / t[:, :1], axis=0), 0.0, MAX_LASER_GB)
    return np.array([1.0, gb[0], gb[1]])


def colour_residual(cand: np.ndarray, laser_rgb: np.ndarray) -> np.ndarray:
    """Size of each candidate's core contrast across the plane of the laser colour and
    the surface colour (DN; texture and shading move the surface along its colour, the
    laser adds along its own); shape (W, K)."""
    t = cand[..., [F_TR, F_TG, F_TB]]
    k = cand[..., [F_KR, F_KG, F_KB]]
    e1 = laser_rgb / np.linalg.norm(laser_rgb)
    e2 = k - (k @ e1)[..., None] * e1
    n2 = np.linalg.norm(e2, axis=-1, keepdims=True)
    e2 = np.divide(e2, n2, out=np.zeros_like(e2), where=n2 > 1e-6 * np.linalg.norm(k, axis=-1,
                                                                                   keepdims=True))
    q = t - (t @ e1)[..., None] * e1 - np.sum(t * e2, axis=-1, keepdims=True) * e2
    return np.linalg.norm(q, axis=-1)


def valid_candidates(cand: np.ndarray, *, height_px: int, s_max: float, min_z: float,
                     max_chi2: float, min_th: float, min_delta_th: float,
                     colour_error: float, channel_sigma_dn: float,
                     sheet_px: np.ndarray | None, sheet_tolerance: float,
                     sheet_support: int = 0) -> tuple[np.ndarray, np.ndarray | None]:
    """Which candidates (W, K) can be the laser, and the laser colour used.

    Valid: a fitted sigma in ``[MIN_SIGMA_PX, s_max]``; an
    unclipped one a Gaussian within the model error (reduced chi-square ``max_chi2``);
    the light its core adds passes Eq. 2 (red chromaticity ``min_th``, ``min_delta_th``)
    and, where the frame shows the laser's colour (:func:`laser_colour`), lies in the
    plane of that colour and the surface's within ``COLOUR_SIGMAS`` noise sigmas plus
    ``colour_error`` of its size; with ``sheet_px`` (W, K: the sheet's sigma at the
    candidate's row, px, NaN unknown) a width that implies a sheet at most
    ``sheet_tolerance`` times thicker or thinner (unclipped ones) than the frame's
    strong columns do (when at least ``sheet_support`` of them show it, else the
    parameter); and at most
    ``WIDTH_SPREAD`` times the median width of the frame's strong unclipped columns.
    """
    pos = cand[..., F_POS]
    s = cand[..., F_WIDTH]
    sat = cand[..., F_SAT] > 0
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(pos) & (pos >= -0.5) & (pos <= height_px - 0.5)
        ok &= (s >= MIN_SIGMA_PX) & (s <= s_max)
        ok &= sat | (cand[..., F_FLAT] > 0) | (cand[..., F_CHI2] <= max_chi2)
        t = cand[..., [F_TR, F_TG, F_TB]]
        tot = t.sum(axis=-1)
        rc = t[..., 0] / tot
        eq2 = (tot > 0) & (rc > min_th) & (rc - np.maximum(t[..., 1], t[..., 2]) / tot
                                           > min_delta_th)
        has_core = cand[..., F_NCORE] > 0
        ok &= eq2 | (sat & ~has_core)
        if sheet_px is not None:
            # the sheet's thickness relative to the parameter's; where the frame shows
            # its own clearly (its strong unclipped columns), that is a second reference
            ratio = np.sqrt(np.maximum(s * s - PIXEL_VAR, 0.01)) / sheet_px
            strong = ok & ~sat & (cand[..., F_Z] >= COLOUR_Z * min_z) & np.isfinite(ratio)
            # (a stripe's worth of them: a few strong columns beside a clipped core are
            # widened by it, and would move the reference for the whole frame)
            ref = float(np.median(ratio[strong])) if strong.sum() >= max(
                COLOUR_SUPPORT, sheet_support) else 1.0
            # judged on the fitted width itself, within its error: the sheet's
            # sigma ``ref x sheet_px`` up to ``sheet_tolerance`` times either way, the
            # pixel's extent added (subtracting it from a noisy narrow fit would
            # inflate the fit's error), widened by two standard errors of the width
            # (about the centre's for a Gaussian fit); a clipped core's width rests on
            # its flanks alone: not judged
            # A width that fits the sheet of the parameter passes as well: the frame's
            # strong columns can be clutter when the stripe itself is clipped
            se = 2.0 * np.nan_to_num(cand[..., F_SE_POS], nan=0.0)
            fits = ~np.isfinite(sheet_px)  # the sheet's width unknown there: not judged
            for r in {1.0, ref}:
                lo = np.sqrt((r * sheet_px / sheet_tolerance) ** 2 + PIXEL_VAR) - se
                hi = np.sqrt((r * sheet_px * sheet_tolerance) ** 2 + PIXEL_VAR) + se
                fits |= (s >= lo) & (s <= hi)
            ok &= sat | fits
        # the sheet's width as the frame shows it: its strong unclipped columns
        strong = ok & ~sat & (cand[..., F_Z] >= COLOUR_Z * min_z)
        if strong.sum() >= COLOUR_SUPPORT:
            ok &= sat | (s <= WIDTH_SPREAD * np.median(s[strong]))
        laser = laser_colour(cand, ok, min_z)
        if laser is not None:
            q = colour_residual(cand, laser)
            n = np.maximum(cand[..., F_NCORE], 1.0)
            lim = COLOUR_SIGMAS * channel_sigma_dn / np.sqrt(n) + \
                colour_error * np.linalg.norm(t, axis=-1)
            ok &= ~has_core | (q <= lim)
            if LASER_SHARE_Z > 0:
                ok &= ~has_core | sat | laser_share(cand, laser, channel_sigma_dn)
    return ok, laser


#: significance of the laser's share of a candidate's light (see :func:`laser_share`)
LASER_SHARE_Z = 3.0


def laser_share(cand: np.ndarray, laser_rgb: np.ndarray, channel_sigma_dn: float) -> np.ndarray:
    """Whether the light each candidate (W, K) adds shows the laser's colour where the
    colours can tell it from the surface's (True: it does, or they cannot).

    The core contrast ``t`` is the laser's light ``a L`` plus a change of the surface's
    own colour ``b K`` (texture, shading). Only the part of ``L`` across ``K``, the unit
    vector ``e``, tells them apart: ``t . e`` is ``a`` times ``L . e`` plus noise of
    ``channel_sigma_dn / sqrt(n)`` (``n`` core rows). Where all of ``t`` being laser
    light would show across ``K`` by at least twice ``LASER_SHARE_Z`` noise sigmas but
    ``t . e`` stays below ``LASER_SHARE_Z`` sigmas, the light is the surface's own (a
    brighter patch of its texture next to a faint stripe's end). On a surface of the
    laser's colour ``L . e`` is near zero and the test does not judge."""
    t = cand[..., [F_TR, F_TG, F_TB]]
    k = cand[..., [F_KR, F_KG, F_KB]]
    with np.errstate(invalid="ignore", divide="ignore"):
        kn = k / np.linalg.norm(k, axis=-1, keepdims=True)
        e = laser_rgb - (kn @ laser_rgb)[..., None] * kn
        e_norm = np.linalg.norm(e, axis=-1)
        e = e / e_norm[..., None]
        lu = laser_rgb / np.linalg.norm(laser_rgb)
        power = np.linalg.norm(t, axis=-1) * (e @ lu)  # t . e if t were all laser light
        se = channel_sigma_dn / np.sqrt(np.maximum(cand[..., F_NCORE], 1.0))
        across = np.sum(t * e, axis=-1)
        return ~((power >= 2.0 * LASER_SHARE_Z * se) & (across < LASER_SHARE_Z * se))


def surface_continues(cand: np.ndarray, img_t: np.ndarray, row0: int,
                      channel_sigma_dn: float) -> np.ndarray:
    """Whether the surface beneath each candidate (W, K) is one surface: the laser adds
    light to the surface it falls on, so the surface's colour (chromaticity) just above
    the stripe and just below it is the same; an edge between two surfaces of different
    colour (a red object's border on a grey floor) is not the laser, whatever light it
    seems to add.

    The colour is taken on the image ``img_t`` (W, H', 3, BGR, rows from ``row0``) in
    two rows each side, ``2.5 sigma + 2`` rows from the candidate's centre (beyond its
    light); the two sides differ when their chromaticities differ by more than
    ``SURFACE_STEP`` plus four noise sigmas (``channel_sigma_dn``) in any channel.
    Sides too dark to show a colour (below ``SURFACE_MIN_DN`` per channel on average)
    are not judged. An edge along the stripe runs on, so the break must show in both
    neighbouring columns too (at the same rows): where an object's side crosses the
    stripe, its end column sees two surfaces alone. Returns (W, K) bool, True where the
    surface continues or where it cannot be told.
    """
    n_cols, n_rows = img_t.shape[0], img_t.shape[1]
    pos = cand[..., F_POS] - row0
    off = np.ceil(EQ_WIDTH * np.nan_to_num(cand[..., F_WIDTH], nan=1.0) + 2.0)
    breaks = np.isfinite(pos)
    # an edge along the stripe runs on: the break must show in the neighbouring columns
    # too (at the same rows); where an object's side crosses the stripe (its end
    # column) the surfaces differ in one column only
    for shift in (-1, 0, 1):
        cols = np.clip(np.arange(n_cols) + shift, 0, n_cols - 1)[:, None]
        sides = []
        for sign in (-1.0, 1.0):
            tot = np.zeros((*cand.shape[:2], 3))
            inside = np.isfinite(pos)
            for extra in (0.0, 1.0):
                r = np.rint(np.nan_to_num(pos, nan=-1e6) + sign * (off + extra))
                inside &= (r >= 0) & (r < n_rows)
                ri = np.clip(r, 0, n_rows - 1).astype(np.int64)
                tot += img_t[cols, ri].astype(np.float64)
            sides.append((tot, inside))
        (up, in_up), (dn, in_dn) = sides
        s_up, s_dn = up.sum(axis=-1), dn.sum(axis=-1)
        lit = (s_up >= 6.0 * SURFACE_MIN_DN) & (s_dn >= 6.0 * SURFACE_MIN_DN)
        with np.errstate(invalid="ignore", divide="ignore"):
            d = np.abs(up / s_up[..., None] - dn / s_dn[..., None]).max(axis=-1)
            # a chromaticity of a two-row sum of three channels: noise about
            # sigma sqrt(2) / sum per channel, on each side
            noise = channel_sigma_dn * math.sqrt(2.0) * (1.0 / s_up + 1.0 / s_dn)
        breaks &= in_up & in_dn & lit & (d > SURFACE_STEP + 4.0 * noise)
    return ~breaks



#: the light an averaged fit gives a column must show in the column's own evidence: it
#: may fall short of it by at most this many standard errors of the own estimate
#: (one-sided; a column inside a stripe falls short by more 0.13 % of the time)
OWN_Z = 3.0
#: rows either side of the averaged fit's centre where the column's own light is sought
OWN_REACH_PX = 1.0


@njit(cache=True, nogil=True)
def _own_amplitude(yi: np.ndarray, ui: np.ndarray, pos: float, s: float, amp: float,
                   sigma: float, shape_error: float) -> tuple[float, float]:  # pragma: no cover
    """Peak of a Gaussian at row ``pos`` of width ``s`` in one column's own evidence
    ``yi`` (rows where ``ui``), on a straight background, by weighted least squares
    (row variance ``sigma^2 + (shape_error amp g)^2`` as the profile fit's); returns the
    peak and its standard error (NaN, NaN with too few rows)."""
    n = yi.shape[0]
    w_half = math.ceil(3.0 * s + 3.0)
    c = math.floor(pos + 0.5)
    h = np.zeros((3, 3))
    b = np.zeros(3)
    m = 0
    for j in range(max(c - w_half, 0), min(c + w_half + 1, n)):
        if not ui[j]:
            continue
        d = j - pos
        g = math.exp(-0.5 * d * d / (s * s))
        var = sigma * sigma + (shape_error * amp * g) ** 2
        x = (1.0, d, g)
        for p in range(3):
            b[p] += x[p] * yi[j] / var
            for q in range(3):
                h[p, q] += x[p] * x[q] / var
        m += 1
    if m < 6:
        return np.nan, np.nan
    # 3x3 inverse by cofactors (the peak's row of it)
    c00 = h[1, 1] * h[2, 2] - h[1, 2] * h[2, 1]
    c01 = h[1, 2] * h[2, 0] - h[1, 0] * h[2, 2]
    c02 = h[1, 0] * h[2, 1] - h[1, 1] * h[2, 0]
    det = h[0, 0] * c00 + h[0, 1] * c01 + h[0, 2] * c02
    if not abs(det) > 1e-300:
        return np.nan, np.nan
    i20 = (h[0, 1] * h[1, 2] - h[0, 2] * h[1, 1]) / det
    i21 = (h[0, 2] * h[1, 0] - h[0, 0] * h[1, 2]) / det
    i22 = (h[0, 0] * h[1, 1] - h[0, 1] * h[1, 0]) / det
    a = i20 * b[0] + i21 * b[1] + i22 * b[2]
    return a, math.sqrt(max(i22, 0.0))


@njit(cache=True, nogil=True)
def own_light(y: np.ndarray, y_avg: np.ndarray, clipped: np.ndarray, mask: np.ndarray,
              cols: np.ndarray, rows: np.ndarray, widths: np.ndarray, sigma_y: float,
              shape_error: float, z: float, ok: np.ndarray) -> None:  # pragma: no cover
    """Whether the light the averaged evidence shows at each crossing is its column's own
    (``ok`` (N,): False where not).

    The evidence averaged along the stripe (weights 1, 4, 6, 4, 1 over five columns)
    stands for a column only where the stripe runs on across them: one column past a
    stripe's end the average still holds 5/16 of the neighbours' light, though the
    column has none. So the peak of a Gaussian at the crossing (column ``cols[k]``, row
    ``rows[k]`` of ``y`` (W, H'), width ``widths[k]``) in the averaged evidence
    ``y_avg`` must show in the column's own evidence ``y``: the own peak
    (:func:`_own_amplitude`, noise ``sigma_y``) may fall short of it by at most ``z``
    standard errors (``OWN_Z``). Inside a stripe the two agree within the noise; at a
    partly covered end column, whose own light is its coverage's share, the average's
    missing outward columns lower it by about as much.
    """
    for k in range(cols.shape[0]):
        ok[k] = True
        i = cols[k]
        pos = rows[k]
        if not np.isfinite(pos):
            continue
        ui = mask[i] & ~clipped[i]
        s = max(widths[k], MIN_SIGMA_PX)
        a_avg, _ = _own_amplitude(y_avg[i], ui, pos, s, 0.0, 1.0, 0.0)
        if not a_avg > 0.0:
            continue
        # on a steep stripe the average's centre at an end column leans towards the
        # inner columns' rows (by up to a pixel): the own light is looked for within
        # OWN_REACH_PX of it, the best place kept
        short = -np.inf
        for step in range(-2, 3):
            a, se = _own_amplitude(y[i], ui, pos + 0.5 * OWN_REACH_PX * step, s, a_avg,
                                   sigma_y, shape_error)
            if np.isfinite(a):
                short = max(short, (a - a_avg) / se)
        if short > -np.inf and short < -z:
            ok[k] = False


def own_light_candidates(cand: np.ndarray, y: np.ndarray, y_avg: np.ndarray,
                         clipped: np.ndarray, mask: np.ndarray, row0: int, sigma_y: float,
                         shape_error: float) -> np.ndarray:
    """:func:`own_light` of every candidate (W, K) fitted on the averaged evidence (rows
    of ``cand`` from the image's top, of ``y`` from ``row0``); True where it holds and
    for the others (a fit of the column's own evidence, whose noise ``sigma_y`` its
    ``F_GNOISE`` holds, measured the column's own light; a clipped core is its own)."""
    w, k = cand.shape[:2]
    cols = np.repeat(np.arange(w, dtype=np.int64), k)
    averaged = (cand[..., F_SAT] == 0) & (cand[..., F_GNOISE] != sigma_y)
    rows = np.where(averaged, cand[..., F_POS] - row0, np.nan).ravel()
    ok = np.empty(w * k, np.bool_)
    own_light(y, y_avg, clipped, mask, cols, rows, np.nan_to_num(cand[..., F_WIDTH].ravel(),
                                                                   nan=1.0),
              sigma_y, shape_error, OWN_Z, ok)
    return ok.reshape(w, k)
