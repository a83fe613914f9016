"""Step 4 of the stripe model: which candidates can be the laser.

:func:`valid_candidates` applies the tests that follow from the model (width, shape,
significance, colour, the sheet's thickness); :func:`laser_share` and
:func:`surface_continues` tell the laser's light from the surface's own colour;
:func:`own_light_candidates` asks a fit on the evidence averaged along the stripe to show
in its own column's evidence. The choice along the stripe among the candidates that pass is
:mod:`slitcli.laser.choose`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser._c.light import own_light_table
from slitcli.laser.profile import (
    F_CHI2,
    F_FLAT,
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


def valid_candidates(cand: np.ndarray, *, height_px: int, s_max: float, min_z: float,
                     max_chi2: float, min_th: float, min_delta_th: float,
                     colour_error: float, channel_sigma_dn: float,
                     sheet_px: np.ndarray | None, sheet_tolerance: float,
                     sheet_support: int = 0) -> tuple[np.ndarray, np.ndarray | None]:
    """Which candidates (W, K) can be the laser, and the laser colour used.

    Valid: a fitted sigma in ``[MIN_SIGMA_PX, s_max]``; an
    unclipped one a Gaussian within the model error (reduced chi-square ``max_chi2``);
    the light its core adds passes Eq. 2 (red chromaticity ``min_th``, ``min_delta_th``)
    and, where the frame shows the laser's colour (:func:`_laser_colour`), lies in the
    plane of that colour and the surface's within ``COLOUR_SIGMAS`` noise sigmas plus
    ``colour_error`` of its size (:func:`_colour_residual`) and shows the laser's share
    (:func:`laser_share`); with ``sheet_px`` (W, K: the sheet's sigma at the
    candidate's row, px, NaN unknown) a width that implies a sheet at most
    ``sheet_tolerance`` times thicker or thinner (unclipped ones) than the frame's
    strong columns do (when at least ``sheet_support`` of them show it, else the
    parameter); and at most
    ``WIDTH_SPREAD`` times the median width of the frame's strong unclipped columns.

    Returns
    -------
    ok : ndarray, shape (W, K) bool
    laser_rgb : ndarray, shape (3,), or None
        The laser's colour (red 1), None where too few strong columns show it.
    """
    ok = np.empty(cand.shape[:2], np.bool_)
    has_sheet = sheet_px is not None
    sheet = np.asarray(sheet_px, np.float64) if has_sheet else np.empty((0, 0))
    laser = np.empty(3)
    found = _shape_tests(cand, has_sheet, sheet, height_px, s_max, min_z, max_chi2, min_th,
                         min_delta_th, sheet_tolerance, sheet_support, WIDTH_SPREAD, ok,
                         laser)
    if not found:
        return ok, None
    # (the unit vector of the laser colour as numpy's norm gives it: the tests below
    # compare against it to the last bit, as they always did)
    lu = laser / np.linalg.norm(laser)
    _colour_tests(cand, laser, lu, channel_sigma_dn, colour_error, LASER_SHARE_Z, ok)
    return ok, laser


@njit(cache=True, nogil=True, error_model="numpy")
def _model_tests(cand: np.ndarray, height_px: int, s_max: float, max_chi2: float,
                 min_th: float, min_delta_th: float, ok: np.ndarray) -> None:  # pragma: no cover
    """The tests of one fit on its own (:func:`valid_candidates`: place, width, shape,
    Eq. 2 on the light its core adds) into ``ok`` (W, K)."""
    for u in range(ok.shape[0]):
        for q in range(ok.shape[1]):
            c = cand[u, q]
            pos, s, sat = c[F_POS], c[F_WIDTH], c[F_SAT] > 0
            good = np.isfinite(pos) and pos >= -0.5 and pos <= height_px - 0.5 and \
                s >= MIN_SIGMA_PX and s <= s_max and \
                (sat or c[F_FLAT] > 0 or c[F_CHI2] <= max_chi2)
            tr, tg, tb = c[F_TR], c[F_TG], c[F_TB]
            tot = tr + tg + tb
            eq2 = tot > 0 and tr / tot > min_th and \
                tr / tot - max(tg, tb) / tot > min_delta_th
            ok[u, q] = good and (eq2 or (sat and not c[F_NCORE] > 0))


@njit(cache=True, nogil=True, error_model="numpy")
def _shape_tests(cand: np.ndarray, has_sheet: bool, sheet_px: np.ndarray, height_px: int,
                 s_max: float, min_z: float, max_chi2: float, min_th: float,
                 min_delta_th: float, sheet_tolerance: float, sheet_support: int,
                 width_spread: float, ok: np.ndarray,
                 laser: np.ndarray) -> bool:  # pragma: no cover
    """:func:`valid_candidates` up to the colour tests: ``ok`` (W, K) and the laser
    colour into ``laser`` (3,); returns whether the frame shows that colour."""
    _model_tests(cand, height_px, s_max, max_chi2, min_th, min_delta_th, ok)
    w, k = ok.shape
    vals = np.empty(w * k)
    strong_z = COLOUR_Z * min_z
    if has_sheet:
        # the sheet's thickness relative to the parameter's; where the frame shows its
        # own clearly (a stripe's worth of strong unclipped columns: a few strong
        # columns beside a clipped core are widened by it), that is a second reference
        ratio = np.empty((w, k))
        m = 0
        for u in range(w):
            for q in range(k):
                s = cand[u, q, F_WIDTH]
                ratio[u, q] = math.sqrt(max(s * s - PIXEL_VAR, 0.01)) / sheet_px[u, q]
                if ok[u, q] and not cand[u, q, F_SAT] > 0 and cand[u, q, F_Z] >= strong_z \
                        and np.isfinite(ratio[u, q]):
                    vals[m] = ratio[u, q]
                    m += 1
        ref = np.median(vals[:m]) if m >= max(COLOUR_SUPPORT, sheet_support) else 1.0
        for u in range(w):
            for q in range(k):
                if ok[u, q] and not cand[u, q, F_SAT] > 0:
                    ok[u, q] = _fits_sheet(cand[u, q, F_WIDTH], cand[u, q, F_SE_POS],
                                           sheet_px[u, q], ref, sheet_tolerance)
    # the sheet's width as the frame shows it: its strong unclipped columns
    m = 0
    for u in range(w):
        for q in range(k):
            if ok[u, q] and not cand[u, q, F_SAT] > 0 and cand[u, q, F_Z] >= strong_z:
                vals[m] = cand[u, q, F_WIDTH]
                m += 1
    if m >= COLOUR_SUPPORT:
        widest = width_spread * np.median(vals[:m])
        for u in range(w):
            for q in range(k):
                if not cand[u, q, F_SAT] > 0:
                    ok[u, q] = ok[u, q] and cand[u, q, F_WIDTH] <= widest
    return _laser_colour(cand, ok, min_z, laser)


@njit(cache=True, nogil=True, error_model="numpy")
def _fits_sheet(s: float, se_pos: float, sheet_px: float, ref: float,
                tolerance: float) -> bool:  # pragma: no cover
    """A fitted width ``s`` that a sheet of sigma ``r x sheet_px`` (``r`` 1 or ``ref``)
    gives, up to ``tolerance`` times either way, the pixel's extent added (subtracting
    it from a noisy narrow fit would inflate the fit's error), widened by two standard
    errors of the width (about the centre's ``se_pos`` for a Gaussian fit); True where
    the sheet's width is unknown. (A clipped core's width rests on its flanks alone:
    not judged. A width that fits the sheet of the parameter passes as well: the
    frame's strong columns can be clutter when the stripe itself is clipped.)"""
    if not np.isfinite(sheet_px):
        return True
    se = 0.0 if np.isnan(se_pos) else min(se_pos, 1.7976931348623157e308)
    se = 2.0 * se
    for r in (1.0, ref):
        a = r * sheet_px / tolerance
        b = r * sheet_px * tolerance
        if math.sqrt(a * a + PIXEL_VAR) - se <= s <= math.sqrt(b * b + PIXEL_VAR) + se:
            return True
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def _laser_colour(cand: np.ndarray, ok: np.ndarray, min_z: float,
                  laser: np.ndarray) -> bool:  # pragma: no cover
    """The laser's colour (RGB, red 1) into ``laser`` from the frame's strong unclipped
    candidates (median of their core contrast over its red); False with fewer than
    ``COLOUR_SUPPORT`` of them."""
    w, k = ok.shape
    g = np.empty(w * k)
    b = np.empty(w * k)
    m = 0
    for u in range(w):
        for q in range(k):
            c = cand[u, q]
            if ok[u, q] and c[F_Z] >= COLOUR_Z * min_z and c[F_SAT] == 0 and \
                    c[F_NCORE] > 0 and c[F_TR] > 0:
                g[m] = c[F_TG] / c[F_TR]
                b[m] = c[F_TB] / c[F_TR]
                m += 1
    if m < COLOUR_SUPPORT:
        return False
    laser[0] = 1.0
    laser[1] = min(max(np.median(g[:m]), 0.0), MAX_LASER_GB)
    laser[2] = min(max(np.median(b[:m]), 0.0), MAX_LASER_GB)
    return True


@njit(cache=True, nogil=True, fastmath={"contract"})
def _dot3(a0: float, a1: float, a2: float, b: np.ndarray) -> float:  # pragma: no cover
    """``a . b`` of 3-vectors, rounded as numpy's ``matmul`` rounds it (its kernel fuses
    the multiply-adds)."""
    return a0 * b[0] + a1 * b[1] + a2 * b[2]


@njit(cache=True, nogil=True, error_model="numpy")
def _norm3(a0: float, a1: float, a2: float) -> float:  # pragma: no cover
    return math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)


@njit(cache=True, nogil=True, error_model="numpy")
def _colour_residual(t: np.ndarray, k: np.ndarray, lu: np.ndarray) -> float:  # pragma: no cover
    """Size of a core contrast ``t`` (RGB, DN) across the plane of the laser colour (unit
    ``lu``) and the surface colour ``k`` (texture and shading move the surface along
    its colour, the laser adds along its own)."""
    kd = _dot3(k[0], k[1], k[2], lu)
    e0, e1, e2 = k[0] - kd * lu[0], k[1] - kd * lu[1], k[2] - kd * lu[2]
    n2 = _norm3(e0, e1, e2)
    if n2 > 1e-6 * _norm3(k[0], k[1], k[2]):
        e0, e1, e2 = e0 / n2, e1 / n2, e2 / n2
    else:
        e0 = e1 = e2 = 0.0
    td = _dot3(t[0], t[1], t[2], lu)
    te = t[0] * e0 + t[1] * e1 + t[2] * e2
    return _norm3(t[0] - td * lu[0] - te * e0, t[1] - td * lu[1] - te * e1,
                  t[2] - td * lu[2] - te * e2)


@njit(cache=True, nogil=True, error_model="numpy")
def laser_share(t: np.ndarray, k: np.ndarray, laser: np.ndarray, lu: np.ndarray,
                 n_core: float, channel_sigma_dn: float,
                 share_z: float) -> bool:  # pragma: no cover
    """Whether the light a candidate adds (core contrast ``t``, surface colour ``k``,
    ``n_core`` core rows) shows the laser's colour (``laser``, unit ``lu``) where the colours can
    tell it from the surface's (True: it does, or they cannot).

    The core contrast ``t`` is the laser's light ``a L`` plus a change of the surface's
    own colour ``b K`` (texture, shading). Only the part of ``L`` across ``K``, the unit
    vector ``e``, tells them apart: ``t . e`` is ``a`` times ``L . e`` plus noise of
    ``channel_sigma_dn / sqrt(n)``. Where all of ``t`` being laser light would show
    across ``K`` by at least twice ``share_z`` noise sigmas but ``t . e`` stays below
    ``share_z`` sigmas, the light is the surface's own (a brighter patch of its texture
    next to a faint stripe's end). On a surface of the laser's colour ``L . e`` is near
    zero and the test does not judge."""
    kk = _norm3(k[0], k[1], k[2])
    kn0, kn1, kn2 = k[0] / kk, k[1] / kk, k[2] / kk
    kd = _dot3(kn0, kn1, kn2, laser)
    e0, e1, e2 = laser[0] - kd * kn0, laser[1] - kd * kn1, laser[2] - kd * kn2
    en = _norm3(e0, e1, e2)
    e0, e1, e2 = e0 / en, e1 / en, e2 / en
    power = _norm3(t[0], t[1], t[2]) * _dot3(e0, e1, e2, lu)
    se = channel_sigma_dn / math.sqrt(max(n_core, 1.0))
    across = t[0] * e0 + t[1] * e1 + t[2] * e2
    return not (power >= 2.0 * share_z * se and across < share_z * se)


@njit(cache=True, nogil=True, error_model="numpy")
def _colour_tests(cand: np.ndarray, laser: np.ndarray, lu: np.ndarray,
                  channel_sigma_dn: float, colour_error: float, share_z: float,
                  ok: np.ndarray) -> None:  # pragma: no cover
    """The colour tests of :func:`valid_candidates` (laser colour ``laser``, its unit
    vector ``lu``) on the
    candidates that show a core, into ``ok`` (W, K)."""
    t = np.empty(3)
    k = np.empty(3)
    for u in range(ok.shape[0]):
        for q in range(ok.shape[1]):
            c = cand[u, q]
            if not ok[u, q] or not c[F_NCORE] > 0:
                continue
            t[0], t[1], t[2] = c[F_TR], c[F_TG], c[F_TB]
            k[0], k[1], k[2] = c[F_KR], c[F_KG], c[F_KB]
            lim = COLOUR_SIGMAS * channel_sigma_dn / math.sqrt(max(c[F_NCORE], 1.0)) + \
                colour_error * _norm3(t[0], t[1], t[2])
            ok[u, q] = _colour_residual(t, k, lu) <= lim
            if ok[u, q] and share_z > 0 and not c[F_SAT] > 0:
                ok[u, q] = laser_share(t, k, laser, lu, c[F_NCORE], channel_sigma_dn,
                                         share_z)


#: significance of the laser's share of a candidate's light (see :func:`laser_share`)
LASER_SHARE_Z = 3.0


def surface_continues(cand: np.ndarray, img_t: np.ndarray, row0: int,
                      channel_sigma_dn: float, need: np.ndarray | None = None) -> np.ndarray:
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
    surface continues or where it cannot be told, and where ``need`` (W, K), when
    given, is False (candidates that are out already are not judged).
    """
    out = np.empty(cand.shape[:2], np.bool_)
    need = np.ones(cand.shape[:2], np.bool_) if need is None else need
    _surface_table(cand, img_t, row0, channel_sigma_dn, need, out)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _side_colour(img_t: np.ndarray, col: int, pos: float, edge: float,
                 tot: np.ndarray) -> bool:  # pragma: no cover
    """Sum (B, G, R) into ``tot`` of column ``col`` of ``img_t`` at the two rows
    ``rint(pos + edge)`` and ``rint(pos + edge +- 1)`` (away from ``pos``); False where
    one of them lies outside the image."""
    n_rows = img_t.shape[1]
    tot[:] = 0.0
    inside = True
    step = 1.0 if edge > 0 else -1.0
    for extra in (0.0, 1.0):
        r = np.rint(pos + step * (abs(edge) + extra))
        inside = inside and 0 <= r < n_rows
        ri = int(min(max(r, 0), n_rows - 1))
        for c in range(3):
            tot[c] += float(img_t[col, ri, c])
    return inside


@njit(cache=True, nogil=True, error_model="numpy")
def _surface_table(cand: np.ndarray, img_t: np.ndarray, row0: int, channel_sigma_dn: float,
                   need: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """:func:`surface_continues` of the candidates where ``need`` (True elsewhere)."""
    n_cols = img_t.shape[0]
    up = np.empty(3)
    dn = np.empty(3)
    for u in range(cand.shape[0]):
        for q in range(cand.shape[1]):
            pos = cand[u, q, F_POS] - row0
            out[u, q] = True
            if not need[u, q] or not np.isfinite(pos):
                continue
            wid = cand[u, q, F_WIDTH]
            off = math.ceil(EQ_WIDTH * (1.0 if np.isnan(wid) else wid) + 2.0)
            breaks = True
            # an edge along the stripe runs on: the break must show in the neighbouring
            # columns too (at the same rows); where an object's side crosses the stripe
            # (its end column) the surfaces differ in one column only
            for shift in (-1, 0, 1):
                col = min(max(u + shift, 0), n_cols - 1)
                inside = _side_colour(img_t, col, pos, -off, up)
                inside = _side_colour(img_t, col, pos, off, dn) and inside
                s_up = up[0] + up[1] + up[2]
                s_dn = dn[0] + dn[1] + dn[2]
                if not (inside and s_up >= 6.0 * SURFACE_MIN_DN and
                        s_dn >= 6.0 * SURFACE_MIN_DN):
                    breaks = False
                    break
                d = 0.0
                for c in range(3):
                    d = max(d, abs(up[c] / s_up - dn[c] / s_dn))
                # a chromaticity of a two-row sum of three channels: noise about
                # sigma sqrt(2) / sum per channel, on each side
                noise = channel_sigma_dn * math.sqrt(2.0) * (1.0 / s_up + 1.0 / s_dn)
                if not d > SURFACE_STEP + 4.0 * noise:
                    breaks = False
                    break
            out[u, q] = not breaks


# The own-light test (compiled: slitcli/laser/_c/light.pxd's own_light, inlined where gaps
# are filled and in light.pyx's table). The evidence averaged along the stripe (weights
# 1, 4, 6, 4, 1 over five columns) stands for a column only where the stripe runs on
# across them: one column past a stripe's end the average still holds 5/16 of the
# neighbours' light, though the column has none. So the peak of a Gaussian at a crossing
# (its row and width) in the averaged evidence must show in the column's own evidence:
# the own peak (weighted least squares of a Gaussian on a straight background, row
# variance sigma^2 + (shape_error A g)^2 as the profile fit's) may fall short of it by at
# most OWN_Z standard errors. Inside a stripe the two agree within the noise; at a partly
# covered end column, whose own light is its coverage's share, the average's missing
# outward columns lower it by about as much. On a steep stripe the average's centre at
# an end column leans towards the inner columns' rows (by up to a pixel): the own light
# is looked for within OWN_REACH_PX of it, the best place kept.

#: the light an averaged fit gives a column must show in the column's own evidence: it
#: may fall short of it by at most this many standard errors of the own estimate
#: (one-sided; a column inside a stripe falls short by more 0.13 % of the time)
OWN_Z = 3.0
#: rows either side of the averaged fit's centre where the column's own light is sought
OWN_REACH_PX = 1.0


def own_light_candidates(cand: np.ndarray, y: np.ndarray, y_avg: np.ndarray,
                         clipped: np.ndarray, mask: np.ndarray, row0: int, sigma_y: float,
                         shape_error: float, need: np.ndarray | None = None) -> np.ndarray:
    """The own-light test (notes above) of every candidate (W, K) fitted on the averaged
    evidence (rows
    of ``cand`` from the image's top, of ``y`` from ``row0``); True where it holds, for
    the others (a fit of the column's own evidence, whose noise ``sigma_y`` its
    ``F_GNOISE`` holds, measured the column's own light; a clipped core is its own),
    and where ``need`` (W, K), when given, is False."""
    ok = np.empty(cand.shape[:2], np.bool_)
    need = np.ones(cand.shape[:2], np.bool_) if need is None else need
    own_light_table(cand, y, y_avg, clipped, mask, row0, sigma_y, shape_error, OWN_Z, need, ok)
    return ok
