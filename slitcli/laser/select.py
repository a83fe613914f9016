"""Compiled (numba) choice of one stripe crossing per column (paper Eq. 4) and segments.

Input: the fitted candidates of every column (:func:`slitcli.laser.candidates.
column_candidates`), an array ``(W, K, N_FIELDS)``; output per column the chosen
row, amplitude, significance and saturation, NaN where the column has no stripe.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.candidates import CLUTTER_SHARE, MAX_COLOUR, MAX_EDGE
from slitcli.laser.fit import (
    AVG_VAR,
    C_AMP,
    C_CHI2,
    C_CLUT,
    C_COLOUR,
    C_EDGE,
    C_HVAR,
    C_POS,
    C_SAT,
    C_WIDTH,
    C_Z,
    PIXEL_VAR,
)
from slitcli.laser.sheet import EQ_WIDTH, MIN_SIGMA_PX, sheet_sigma_m

#: reduced chi-square above which an unsaturated candidate is not a Gaussian stripe
MAX_CHI2 = 8.0
#: a stripe's implied sheet thickness may differ from the expected by this factor;
#: amid clutter (a share of the evidence around above CLUTTER_SHEET_SHARE) by less
SHEET_TOLERANCE = 1.6
CLUTTER_SHEET_SHARE = 0.04
CLUTTER_SHEET_TOLERANCE = 1.3
#: a weak candidate of the averaged columns must be backed by a candidate of the
#: column itself this close (px) and at least this significant
SUPPORT_PX = 1.5
SUPPORT_Z = 2.0
#: rows a mixed end column may differ from its strong neighbour's, px
CONTINUE_PX = 1.5
#: half-window of the running median of the amplitude along a segment, columns
AMP_HALF = 6
#: a segment's end column must be at least this share as bright as the next three
END_SHARE = 0.6
END_DROP = 2
#: a falling end (grazing incidence, :func:`dim_end`): the next three columns' straight
#: line below FALL_RATIO of their median; the end column needs FALL_SHARE of the line's
#: brightness, visibility is judged on FALL_VIS of the median at least, and its row must
#: continue the line of the next two within CURVE_PX
FALL_RATIO = 0.8
FALL_SHARE = 0.4
FALL_VIS = 0.5
CURVE_PX = 0.8
#: a segment shorter than min_segment_cols needs this multiple of z_strong in every
#: column
SHORT_Z_SHARE = 1.6
#: largest reduced chi-square of an unsaturated column of a short segment
SHORT_CHI2 = 3.0
#: found columns of one segment may be this many columns apart (faint stretches)
MAX_GAP = 2
#: a gap column's candidate may lie this far from the row interpolated across it, px
GAP_PX = 1.0
#: rows are smoothed along a segment over this many columns either side
SMOOTH_HALF = 4
#: floor of a row's standard error in the smoothing weights, px
SMOOTH_MIN_SE = 0.02
#: a second difference of the rows beyond this (and four times its noise) is a corner
SMOOTH_CORNER_PX = 0.5


@njit(cache=True, nogil=True)
def merge_sources(cand: np.ndarray, cand_avg: np.ndarray,
                  z_strong: float) -> np.ndarray:  # pragma: no cover
    """Candidates of the columns and of the (1, 2, 1)-averaged columns, as one table.

    An averaged candidate (more signal for a faint stripe, but it smears a stripe's
    end into the next column and widens a steep one) is kept only where the column
    itself has a candidate within ``SUPPORT_PX`` of at least ``SUPPORT_Z``
    significance that is not already strong (``z_strong``). ``C_HVAR`` is set to
    the sampling variance across columns of each source.
    """
    w, k = cand.shape[0], cand.shape[1]
    # every entry is written once: the candidate or NaN (no NaN fill of the whole
    # table first)
    out = np.empty((w, 2 * k, cand.shape[2]))
    for u in range(w):
        for q in range(k):
            if np.isfinite(cand[u, q, C_POS]):
                out[u, q] = cand[u, q]
                out[u, q, C_HVAR] = PIXEL_VAR
            else:
                out[u, q] = np.nan
        for q in range(k):
            out[u, k + q] = np.nan
            v = cand_avg[u, q, C_POS]
            if not np.isfinite(v):
                continue
            back = False
            strong = False
            for r in range(k):
                vr = cand[u, r, C_POS]
                if np.isfinite(vr) and abs(vr - v) <= SUPPORT_PX and \
                        cand[u, r, C_Z] >= SUPPORT_Z:
                    back = True
                    strong = strong or cand[u, r, C_Z] >= z_strong
            if back and not strong:
                out[u, k + q] = cand_avg[u, q]
                out[u, k + q, C_HVAR] = PIXEL_VAR + AVG_VAR
    return out


@njit(cache=True, nogil=True)
def _valid(cand: np.ndarray, u: int, q: int, sigma: float, max_width_px: float,
           z_weak: float) -> bool:  # pragma: no cover
    """Shape and significance tests of one candidate (see :func:`choose`)."""
    if not np.isfinite(cand[u, q, C_POS]):
        return False
    w = cand[u, q, C_WIDTH]
    if w < MIN_SIGMA_PX or w > max_width_px / EQ_WIDTH:
        return False
    if cand[u, q, C_Z] < z_weak or cand[u, q, C_EDGE] > MAX_EDGE:
        return False
    if cand[u, q, C_SAT] > 0:
        return True
    if cand[u, q, C_CHI2] > MAX_CHI2 or cand[u, q, C_COLOUR] > MAX_COLOUR:
        return False
    return cand[u, q, C_CLUT] <= CLUTTER_SHARE


@njit(cache=True, nogil=True)
def _closeness(v: float, ref: float, scale: float) -> float:  # pragma: no cover
    if not np.isfinite(ref):
        return 0.0
    d = (v - ref) / scale
    return math.exp(-0.5 * d * d)


@njit(cache=True, nogil=True)
def links(dv: float, w_a: float, w_b: float, max_jump_px: float) -> bool:  # pragma: no cover
    """Rows of neighbouring columns on one stripe: a step of at most ``max_jump_px``,
    or on a steep stripe (whose profile across a column widens to ``slope / sqrt(12)``)
    of at most ``sqrt(3)`` times the sum of the two widths."""
    dv = abs(dv)
    return dv <= max_jump_px or dv <= math.sqrt(3.0) * (w_a + w_b)


@njit(cache=True, nogil=True)
def choose(cand: np.ndarray, prev_v: np.ndarray, g_map: np.ndarray, sheet_m: float,
           sigma: float, max_width_px: float, beta: float, gamma: float,
           continuity_px: float, max_jump_px: float, z_strong: float, z_weak: float,
           h_img: int, chosen: np.ndarray, extended: np.ndarray) -> None:  # pragma: no cover
    """Eq. 4: per column the valid candidate of best ``red_peak + beta f(y) + gamma g(I)``.

    Valid: fitted sigma in ``[MIN_SIGMA_PX, max_width_px / EQ_WIDTH]``, significance
    at least ``z_weak``, not on an edge between surfaces (``MAX_EDGE``), unsaturated
    ones a Gaussian (``MAX_CHI2``) standing above the clutter (``CLUTTER_SHARE``);
    and, when ``sheet_m > 0``, an implied sheet thickness (:func:`sheet_sigma_m`,
    slope from the first-pass rows it links to, ``g_map`` (H, W) px per metre) within
    ``SHEET_TOLERANCE`` of ``sheet_m`` (amid clutter ``CLUTTER_SHEET_TOLERANCE``;
    saturated: not thicker).

    ``red_peak``: amplitude over the column's largest valid amplitude; ``g(I) = 1 -
    sigma_fit EQ_WIDTH / max_width_px`` (in [0, 1]); ``f(y)``: mean agreement
    ``exp(-dv^2 / (2 continuity_px^2))`` with the rows chosen among the strong
    candidates (``z >= z_strong``) of columns u-2, u-1, u+1, u+2 by a first pass
    (which knows only the previous frame), averaged with the agreement with
    ``prev_v`` (previous frame, (W,) or empty) where finite. A weak candidate is
    eligible only next to an agreeing first-pass row; rows outside the image (``h_img``
    rows) are not. Where a column has no valid candidate, a strong one within
    ``CONTINUE_PX`` of a neighbouring chosen row (carried on along the slope of the
    next two chosen rows where they link) is taken (the end column at an
    object's edge, which mixes two surfaces; ``extended[u]`` True). ``chosen[u]``:
    index or -1.
    """
    w_cols, k = cand.shape[0], cand.shape[1]
    h = g_map.shape[0]
    first = np.full(w_cols, np.nan)
    first_w = np.full(w_cols, np.nan)
    has_prev = prev_v.shape[0] == w_cols
    ok = np.zeros(k, np.bool_)
    for u in range(w_cols):
        amax = 0.0
        for q in range(k):
            ok[q] = _valid(cand, u, q, sigma, max_width_px, z_weak)
            if ok[q]:
                amax = max(amax, cand[u, q, C_AMP])
        best = -1e300
        for q in range(k):
            if not ok[q] or cand[u, q, C_Z] < z_strong:
                continue
            sc = cand[u, q, C_AMP] / amax + gamma * max(
                0.0, 1.0 - cand[u, q, C_WIDTH] * EQ_WIDTH / max_width_px)
            if has_prev:
                sc += beta * _closeness(cand[u, q, C_POS], prev_v[u], continuity_px)
            if sc > best:
                best = sc
                first[u] = cand[u, q, C_POS]
                first_w[u] = cand[u, q, C_WIDTH]
    for u in range(w_cols):
        chosen[u] = -1
        amax = 0.0
        for q in range(k):
            ok[q] = _valid(cand, u, q, sigma, max_width_px, z_weak) and \
                -0.5 <= cand[u, q, C_POS] <= h_img - 1.0
            if ok[q] and sheet_m > 0.0:
                v = cand[u, q, C_POS]
                w = cand[u, q, C_WIDTH]
                slope = 0.0
                n_sl = 0
                if u > 0 and np.isfinite(first[u - 1]) and \
                        links(v - first[u - 1], w, first_w[u - 1], max_jump_px):
                    slope += v - first[u - 1]
                    n_sl += 1
                if u + 1 < w_cols and np.isfinite(first[u + 1]) and \
                        links(first[u + 1] - v, w, first_w[u + 1], max_jump_px):
                    slope += first[u + 1] - v
                    n_sl += 1
                if n_sl > 0:
                    slope /= n_sl
                row = min(max(int(v + 0.5), 0), h - 1)
                t = sheet_sigma_m(w, slope, cand[u, q, C_HVAR], g_map[row, u])
                # a clipped core leaves amplitude and width ill-determined (only the
                # flanks, maybe one, constrain them): only too wide counts there; amid
                # clutter (a red surface's texture, which colour cannot tell from the
                # laser) the width must match more closely
                tol = SHEET_TOLERANCE if cand[u, q, C_CLUT] <= CLUTTER_SHEET_SHARE else \
                    CLUTTER_SHEET_TOLERANCE
                ok[q] = t <= sheet_m * tol and (cand[u, q, C_SAT] > 0 or t >= sheet_m / tol)
            if ok[q]:
                amax = max(amax, cand[u, q, C_AMP])
        best = -1e300
        for q in range(k):
            if not ok[q]:
                continue
            v = cand[u, q, C_POS]
            f = 0.0
            near = False
            for d in (-2, -1, 1, 2):
                if 0 <= u + d < w_cols:
                    c = _closeness(v, first[u + d], continuity_px)
                    f += 0.25 * c
                    near = near or c > 0.6
            if has_prev and np.isfinite(prev_v[u]):
                f = 0.5 * (f + _closeness(v, prev_v[u], continuity_px))
            if cand[u, q, C_Z] < z_strong and not near:
                continue
            sc = cand[u, q, C_AMP] / amax + beta * f + gamma * max(
                0.0, 1.0 - cand[u, q, C_WIDTH] * EQ_WIDTH / max_width_px)
            if sc > best:
                best = sc
                chosen[u] = q
    # an end column at an object's edge mixes two surfaces (the edge test, the profile
    # shape and the width suffer): next to a chosen row, a strong candidate that
    # carries that row on is taken all the same (one column, no chaining)
    strict = chosen.copy()
    for u in range(w_cols):
        extended[u] = False
        if strict[u] >= 0:
            continue
        for d in (-1, 1):
            if not (0 <= u + d < w_cols) or strict[u + d] < 0 or chosen[u] >= 0:
                continue
            ref = cand[u + d, strict[u + d], C_POS]
            # along a steep or curving stripe (a cylinder's grazing end) the row moves
            # by more than CONTINUE_PX a column: it is carried on along the slope of
            # the two neighbouring chosen rows
            if 0 <= u + 2 * d < w_cols and strict[u + 2 * d] >= 0:
                ref2 = cand[u + 2 * d, strict[u + 2 * d], C_POS]
                if links(ref - ref2, cand[u + d, strict[u + d], C_WIDTH],
                         cand[u + 2 * d, strict[u + 2 * d], C_WIDTH], max_jump_px):
                    ref = 2.0 * ref - ref2
            for q in range(k):
                v = cand[u, q, C_POS]
                if np.isfinite(v) and cand[u, q, C_Z] >= z_strong and \
                        cand[u, q, C_WIDTH] <= max_width_px / EQ_WIDTH and \
                        abs(v - ref) <= CONTINUE_PX and -0.5 <= v <= h_img - 1.0:
                    chosen[u] = q
                    extended[u] = True
                    break


@njit(cache=True, nogil=True)
def _median3(x: float, y: float, z: float) -> float:  # pragma: no cover
    return max(min(x, y), min(max(x, y), z))


@njit(cache=True, nogil=True)
def end_level(a1: float, a2: float, a3: float) -> float:  # pragma: no cover
    """Brightness a segment's end column would have if all of it saw the surface,
    from the next three columns' amplitudes ``a1, a2, a3`` (nearest first): their
    median, or less where they fall towards the end (a grazing or curving surface
    dims fast): the straight line through them extrapolated one column."""
    return min(_median3(a1, a2, a3), (4.0 * a1 + a2 - 2.0 * a3) / 3.0)


@njit(cache=True, nogil=True)
def dim_end(a0: float, a1: float, a2: float, a3: float, min_peak_dn: float,
            smooth: bool) -> bool:  # pragma: no cover
    """Whether a segment's end column of amplitude ``a0`` (the next ones ``a1, a2,
    a3``) goes. The truth of a column is its centre ray, which meets the surface when
    more than half of the column sees it: the end column must keep ``END_SHARE`` of
    the brightness the whole column would have (:func:`end_level`, or its own if
    more), and that brightness must be visible (``min_peak_dn``).

    Towards a curved surface's grazing edge (a cylinder's side) the brightness falls
    to nothing within the last column (incidence angle), so a column whose centre
    still sees the surface shows far less than half of the straight-line prediction
    (about 0.37 of it for a brightness falling like the root of the distance to the
    edge), while the stripe's row runs on smoothly. Where the next three columns fall
    monotonically, their straight line is below ``FALL_RATIO`` of their median and
    the end row continues the line of the next two (``smooth``, within
    ``CURVE_PX``), the end column needs ``FALL_SHARE`` of the straight-line
    brightness, and ``min_peak_dn`` is judged on that or ``FALL_VIS`` of the median,
    whichever is more (the fits read such steep, partly covered columns low). A sliver
    beyond the edge breaks the row's line."""
    lin = (4.0 * a1 + a2 - 2.0 * a3) / 3.0
    med = _median3(a1, a2, a3)
    if smooth and a1 <= a2 <= a3 and lin < FALL_RATIO * med:
        full = max(a0, lin)
        return a0 < FALL_SHARE * full or max(full, FALL_VIS * med) < min_peak_dn
    full = max(a0, min(med, lin))
    return a0 < END_SHARE * full or full < min_peak_dn


@njit(cache=True, nogil=True)
def segment(v: np.ndarray, width: np.ndarray, present: np.ndarray, u: int,
            max_jump_px: float, idx: np.ndarray) -> int:  # pragma: no cover
    """The segment starting at column ``u`` (``present[u]``): following columns join
    when ``present`` and their rows link (:func:`links`) with the segment's last one,
    or across a gap of up to ``MAX_GAP`` columns differ by at most ``max_jump_px`` per
    column. Its columns go to ``idx``; returns how many."""
    n = v.shape[0]
    cnt = 1
    idx[0] = u
    last = u
    x = u + 1
    while x < n and x - last <= MAX_GAP + 1:
        if present[x]:
            dv = v[x] - v[last]
            if (x == last + 1 and links(dv, width[x], width[last], max_jump_px)) or \
                    abs(dv) <= max_jump_px * (x - last):
                idx[cnt] = x
                cnt += 1
                last = x
            else:
                break
        x += 1
    return cnt


@njit(cache=True, nogil=True)
def trim_ends(v: np.ndarray, amp: np.ndarray, sat: np.ndarray, idx: np.ndarray, cnt: int,
              min_peak_dn: float) -> tuple[int, int]:  # pragma: no cover
    """The range ``[a, b)`` of a segment's columns (``idx[:cnt]``) without its dim
    ends (:func:`dim_end`, unsaturated ones, up to ``END_DROP`` a side: a partly
    covered column at an object's edge and the one an average smeared into)."""
    a = 0
    b = cnt
    for _ in range(END_DROP):
        if b - a >= 4 and not sat[idx[a]] and dim_end(
                amp[idx[a]], amp[idx[a + 1]], amp[idx[a + 2]], amp[idx[a + 3]],
                min_peak_dn, _on_curve(v, idx[a], idx[a + 1], idx[a + 2])):
            a += 1
        if b - a >= 4 and not sat[idx[b - 1]] and dim_end(
                amp[idx[b - 1]], amp[idx[b - 2]], amp[idx[b - 3]], amp[idx[b - 4]],
                min_peak_dn, _on_curve(v, idx[b - 1], idx[b - 2], idx[b - 3])):
            b -= 1
    return a, b


@njit(cache=True, nogil=True)
def _on_curve(v: np.ndarray, x0: int, x1: int, x2: int) -> bool:  # pragma: no cover
    """Column ``x0``'s row continues the straight line through columns ``x1, x2``
    within ``CURVE_PX``."""
    pred = v[x1] + (v[x1] - v[x2]) * (x0 - x1) / (x1 - x2)
    return abs(v[x0] - pred) <= CURVE_PX


@njit(cache=True, nogil=True)
def prune_ends(v: np.ndarray, width: np.ndarray, amp: np.ndarray, sat: np.ndarray,
               keep: np.ndarray, max_jump_px: float,
               min_peak_dn: float) -> None:  # pragma: no cover
    """:func:`trim_ends` on every segment of the kept columns, and lone spikes
    (:func:`spike`) dropped (``keep`` updated)."""
    n = v.shape[0]
    idx = np.empty(n, np.int64)
    u = 0
    while u < n:
        if not keep[u]:
            u += 1
            continue
        cnt = segment(v, width, keep, u, max_jump_px, idx)
        if cnt == 1 and spike(v, keep, u, max_jump_px):
            keep[u] = False
            u += 1
            continue
        a, b = trim_ends(v, amp, sat, idx, cnt, min_peak_dn)
        for k in range(cnt):
            if k < a or k >= b:
                keep[idx[k]] = False
        u = idx[cnt - 1] + 1


@njit(cache=True, nogil=True)
def spike(v: np.ndarray, keep: np.ndarray, u: int,
          max_jump_px: float) -> bool:  # pragma: no cover
    """Whether the kept column ``u``, which links with no kept neighbour (a segment
    of its own), is a spike off a stripe that passes it by: the nearest kept columns
    on both sides (within ``MAX_GAP + 1`` columns) continue each other across it
    (rows at most ``max_jump_px`` per column apart).

    :func:`keep_segments` takes no segment of one column, but its gap rule can join
    a column several rows off a faint stripe to the stripe's end across a gap;
    tracking then fills that gap along the stripe's course from both sides and
    leaves the column alone between them (a corridor frame: 9 rows off, on a floor
    texture, where no laser light falls)."""
    n = v.shape[0]
    left = -1
    for x in range(u - 1, max(u - MAX_GAP - 2, -1), -1):
        if keep[x]:
            left = x
            break
    right = -1
    for x in range(u + 1, min(u + MAX_GAP + 2, n)):
        if keep[x]:
            right = x
            break
    return left >= 0 and right >= 0 and abs(v[right] - v[left]) <= max_jump_px * (right - left)


@njit(cache=True, nogil=True)
def keep_segments(v: np.ndarray, width: np.ndarray, amp: np.ndarray, z: np.ndarray,
                  chi2: np.ndarray, sat: np.ndarray, extended: np.ndarray, max_jump_px: float,
                  min_segment_cols: int, min_peak_dn: float, z_strong: float,
                  keep: np.ndarray) -> None:  # pragma: no cover
    """Join found columns into segments and keep the stripe's.

    Neighbouring found columns join when their rows link (:func:`links`); across a
    gap of up to ``MAX_GAP`` columns without a stripe (a faint stretch) when their
    rows differ by at most ``max_jump_px`` per column. A segment is kept when it has
    ``min_segment_cols`` found columns, or when it is shorter (a thin object, a steep
    face) but every column is ``SHORT_Z_SHARE`` times strong (``z_strong``) and
    there are at least two;
    ``extended`` columns (:func:`choose`) do not count.
    Within a kept segment a column stays when the running median of the amplitude
    (``AMP_HALF`` found columns either side, within the segment) reaches
    ``min_peak_dn``: the brightness of a stripe changes smoothly along a surface, so
    the median judges a faint column (and the partly covered end column at an
    object's edge) by its neighbours; an unsaturated end column less than
    ``END_SHARE`` as bright as the next three is dropped (less than half of it sees
    the surface, so its centre does not; a clipped core's amplitude is too loosely
    determined to judge). ``keep`` (W,) bool is written.
    """
    n = v.shape[0]
    idx = np.empty(n, np.int64)
    for u in range(n):
        keep[u] = False
    u = 0
    while u < n:
        if not np.isfinite(v[u]):
            u += 1
            continue
        cnt = segment(v, width, np.isfinite(v), u, max_jump_px, idx)
        last = idx[cnt - 1]
        z2 = 0.0
        n_own = 0
        clean = True
        for k in range(cnt):
            if not extended[idx[k]]:
                n_own += 1
                z2 += z[idx[k]] ** 2
                clean = clean and z[idx[k]] >= z_strong and (sat[idx[k]] or
                                                              chi2[idx[k]] <= SHORT_CHI2)
        # a short segment (a thin leg, a steep face) must be strong, Gaussian columns,
        # together as significant as two columns of SHORT_Z_SHARE x z_strong
        good = n_own >= min_segment_cols or \
            (n_own >= 2 and clean and z2 >= 2.0 * (SHORT_Z_SHARE * z_strong) ** 2)
        a, b = trim_ends(v, amp, sat, idx, cnt, min_peak_dn) if good else (0, cnt)
        if good:
            for k in range(a, b):
                # running median: the amplitudes in the window at or above the
                # threshold are a majority
                m = 0
                hi = 0
                for y in range(max(a, k - AMP_HALF), min(b, k + AMP_HALF + 1)):
                    m += 1
                    if amp[idx[y]] >= min_peak_dn:
                        hi += 1
                keep[idx[k]] = 2 * hi >= m + (1 - m % 2)
        u = last + 1


@njit(cache=True, nogil=True)
def gap_rows(v: np.ndarray, keep: np.ndarray, max_jump_px: float, cols: np.ndarray,
             rows: np.ndarray, slopes: np.ndarray) -> int:  # pragma: no cover
    """Columns left empty inside a kept segment (up to ``MAX_GAP`` columns between
    kept ones whose rows differ by at most ``max_jump_px`` per column), the rows
    interpolated across them and the slope there, written to ``cols``, ``rows`` and
    ``slopes``; returns how many."""
    n = v.shape[0]
    m = 0
    last = -1
    for u in range(n):
        if not keep[u]:
            continue
        if last >= 0 and 1 < u - last <= MAX_GAP + 1 and \
                abs(v[u] - v[last]) <= max_jump_px * (u - last):
            for x in range(last + 1, u):
                cols[m] = x
                rows[m] = v[last] + (v[u] - v[last]) * (x - last) / (u - last)
                slopes[m] = (v[u] - v[last]) / (u - last)
                m += 1
        last = u
    return m


@njit(cache=True, nogil=True)
def smooth_rows(v: np.ndarray, se: np.ndarray, width: np.ndarray, keep: np.ndarray,
                max_jump_px: float, out: np.ndarray) -> None:  # pragma: no cover
    """Each kept column's row from a weighted quadratic through its segment's rows.

    A stripe on a surface is a smooth image curve (a straight line on a plane), and
    the per-column fits carry independent noise: a least-squares quadratic through
    the rows of up to ``SMOOTH_HALF`` linked kept columns either side (weights
    ``1 / se^2``, ``se`` the fit's standard error of the row) estimates the row with
    about half the noise. Windows stop short of corners (second difference of the
    rows beyond ``SMOOTH_CORNER_PX`` and four times its noise: two faces meeting);
    columns with fewer than two linked neighbours on either side, and corners, keep
    their own row. ``out`` (W,) gets the rows (NaN where not kept)."""
    n = v.shape[0]
    # corners: where the slope changes by more than noise allows (the second
    # difference), a quadratic would round the corner; windows stop there
    corner = np.zeros(n, np.bool_)
    for x in range(1, n - 1):
        if keep[x - 1] and keep[x] and keep[x + 1]:
            d2 = v[x + 1] - 2.0 * v[x] + v[x - 1]
            noise = math.sqrt(se[x - 1] ** 2 + 4.0 * se[x] ** 2 + se[x + 1] ** 2)
            corner[x] = abs(d2) > max(SMOOTH_CORNER_PX, 4.0 * noise)
    for u in range(n):
        out[u] = v[u] if keep[u] else np.nan
        if not keep[u] or corner[u]:
            continue
        lo = u
        while lo > 0 and u - lo < SMOOTH_HALF and keep[lo - 1] and not corner[lo - 1] and \
                links(v[lo] - v[lo - 1], width[lo], width[lo - 1], max_jump_px):
            lo -= 1
        hi = u
        while hi < n - 1 and hi - u < SMOOTH_HALF and keep[hi + 1] and not corner[hi + 1] \
                and links(v[hi + 1] - v[hi], width[hi + 1], width[hi], max_jump_px):
            hi += 1
        if u - lo < 2 or hi - u < 2:
            continue
        s0 = s1 = s2 = s3 = s4 = t0 = t1 = t2 = 0.0
        for x in range(lo, hi + 1):
            e = max(se[x], SMOOTH_MIN_SE)
            wt = 1.0 / (e * e)
            d = float(x - u)
            y = v[x] - v[u]
            s0 += wt
            s1 += wt * d
            s2 += wt * d * d
            s3 += wt * d * d * d
            s4 += wt * d * d * d * d
            t0 += wt * y
            t1 += wt * d * y
            t2 += wt * d * d * y
        # value at d = 0 of the weighted quadratic (Cramer's rule on the 3x3 normal
        # equations)
        det = s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s2 * s3) + s2 * (s1 * s3 - s2 * s2)
        if abs(det) < 1e-12 * s0 * s2 * s4:
            continue
        num = t0 * (s2 * s4 - s3 * s3) - s1 * (t1 * s4 - s3 * t2) + s2 * (t1 * s3 - s2 * t2)
        out[u] = v[u] + num / det

