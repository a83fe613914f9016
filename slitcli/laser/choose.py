"""Step 5 of the stripe model: the choice along the stripe (paper Eq. 4, segments, rows
smoothed along them; compiled).

:func:`choose_stripe` is Eq. 4 per column among the candidates that pass
:mod:`slitcli.laser.judge`'s tests, followed by the segments.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from slitcli.laser.profile import (
    F_AMP,
    F_GNOISE,
    F_NOISE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_WIDTH,
    F_Z,
)

#: found columns of one segment may be this many columns apart
MAX_GAP = 2
#: the choice along the stripe is made again, without the candidates of segments that
#: did not stay, at most this many times
CHOICE_ROUNDS = 6
#: rows are smoothed along a segment over this many columns either side
SMOOTH_HALF = 4
#: a second difference of the rows beyond this (and four times its noise) is a corner
SMOOTH_CORNER_PX = 0.5
@njit(cache=True, nogil=True)
def _closeness(v: float, ref: float, scale: float) -> float:  # pragma: no cover
    if not np.isfinite(ref):
        return 0.0
    d = (v - ref) / scale
    return math.exp(-0.5 * d * d)


@njit(cache=True, nogil=True)
def links(dv: float, w_a: float, w_b: float, max_jump_px: float) -> bool:  # pragma: no cover
    """Rows of neighbouring columns on one stripe: a step of at most ``max_jump_px``, or
    on a steep stripe (whose profile across a column widens to ``slope / sqrt(12)``) of
    at most ``sqrt(3)`` times the sum of the two widths."""
    dv = abs(dv)
    return dv <= max_jump_px or dv <= math.sqrt(3.0) * (w_a + w_b)


@njit(cache=True, nogil=True)
def _gain(cand: np.ndarray, u: int, q: int, prev_v: np.ndarray, z_weak: float, beta: float,
          continuity_px: float) -> float:  # pragma: no cover
    """Log-likelihood ratio of candidate ``q`` of column ``u`` being the stripe (its
    significance ``z``: ``(z^2 - z_weak^2) / 2``), its ``z^2`` raised by ``beta`` times
    its closeness to the previous frame's row (Eq. 4's f(y) over time)."""
    # the choice weighs candidates by their significance against the image's noise (the
    # local noise, which also holds the stripe's own irregular surroundings, only
    # judges whether a candidate can be the stripe at all)
    z = cand[u, q, F_Z] * cand[u, q, F_NOISE] / cand[u, q, F_GNOISE]
    f = 0.0
    if prev_v.shape[0] == cand.shape[0] and np.isfinite(prev_v[u]):
        f = _closeness(cand[u, q, F_POS], prev_v[u], continuity_px)
    return 0.5 * (z * z * (1.0 + beta * f) - z_weak * z_weak)


@njit(cache=True, nogil=True)
def best_path(cand: np.ndarray, ok: np.ndarray, prev_v: np.ndarray, z_weak: float,
              beta: float, continuity_px: float, max_jump_px: float,
              pick: np.ndarray) -> None:  # pragma: no cover
    """Eq. 4 along the stripe: the choice of one candidate or none per column that
    maximises the summed evidence (:func:`_gain`) less the continuity cost
    ``(dv / continuity_px)^2 / 2`` between chosen neighbours whose rows link
    (:func:`links`; others are separated by a column without a stripe). Dynamic
    programming over the columns (Viterbi); ``pick[u]`` the chosen index or -1."""
    w_cols, k = cand.shape[0], cand.shape[1]
    score = np.full((w_cols, k), -1e300)
    back = np.full((w_cols, k), -1, np.int64)  # -1: from "none"
    none = np.zeros(w_cols)
    none_back = np.full(w_cols, -1, np.int64)  # -1: from "none", else the candidate
    for u in range(w_cols):
        prev_none = none[u - 1] if u > 0 else 0.0
        best_prev = prev_none
        best_q = -1
        if u > 0:
            for r in range(k):
                if score[u - 1, r] > best_prev:
                    best_prev = score[u - 1, r]
                    best_q = r
        none[u] = best_prev
        none_back[u] = best_q
        for q in range(k):
            if not ok[u, q] or cand[u, q, F_Z] < z_weak:
                continue
            g = _gain(cand, u, q, prev_v, z_weak, beta, continuity_px)
            best = prev_none
            arg = -1
            if u > 0:
                for r in range(k):
                    if score[u - 1, r] <= -1e299:
                        continue
                    dv = cand[u, q, F_POS] - cand[u - 1, r, F_POS]
                    if not links(dv, cand[u, q, F_WIDTH], cand[u - 1, r, F_WIDTH],
                                 max_jump_px):
                        continue
                    d = dv / continuity_px
                    sc = score[u - 1, r] - 0.5 * d * d
                    if sc > best:
                        best = sc
                        arg = r
            score[u, q] = best + g
            back[u, q] = arg
    # backtrack from the best final state
    state = -1
    best = none[w_cols - 1]
    for q in range(k):
        if score[w_cols - 1, q] > best:
            best = score[w_cols - 1, q]
            state = q
    for u in range(w_cols - 1, -1, -1):
        pick[u] = state
        state = back[u, state] if state >= 0 else none_back[u]


@njit(cache=True, nogil=True)
def _segments(cand: np.ndarray, pick: np.ndarray, v: np.ndarray, wid: np.ndarray,
              max_jump_px: float, min_segment_cols: int, min_z: float, strong_z: float,
              keep: np.ndarray, dropped: np.ndarray) -> int:  # pragma: no cover
    """The chosen columns (``pick`` >= 0) joined into segments (:func:`choose_stripe`);
    ``keep`` marks the columns of segments that stay, ``dropped`` those of segments
    that do not; returns the longest kept segment's span in columns."""
    w_cols = cand.shape[0]
    idx = np.empty(w_cols, np.int64)
    keep[:] = False
    dropped[:] = False
    longest = 0
    u = 0
    while u < w_cols:
        if pick[u] < 0:
            u += 1
            continue
        cnt = 1
        idx[0] = u
        last = u
        x = u + 1
        while x < w_cols and x - last <= MAX_GAP + 1:
            if pick[x] >= 0:
                dv = v[x] - v[last]
                if (x == last + 1 and links(dv, wid[x], wid[last], max_jump_px)) or \
                        abs(dv) <= max_jump_px * (x - last):
                    idx[cnt] = x
                    cnt += 1
                    last = x
                else:
                    break
            x += 1
        strong = cnt >= max(2, min_segment_cols // 4)
        z2 = 0.0
        for r in range(cnt):
            z = cand[idx[r], pick[idx[r]], F_Z]
            strong = strong and z >= strong_z
            z2 += z * z
        good = (cnt >= min_segment_cols and z2 >= cnt * min_z * min_z) or strong
        for r in range(cnt):
            keep[idx[r]] = good
            dropped[idx[r]] = not good
        if good:
            longest = max(longest, idx[cnt - 1] - idx[0] + 1)
        u = last + 1
    return longest


@njit(cache=True, nogil=True)
def choose_stripe(cand: np.ndarray, ok: np.ndarray, prev_v: np.ndarray, beta: float,
                  z_weak: float, continuity_px: float, max_jump_px: float,
                  min_segment_cols: int, min_z: float, strong_z: float,
                  min_stripe_cols: int, rounds: int, v_out: np.ndarray, amp_out: np.ndarray,
                  sat_out: np.ndarray) -> None:  # pragma: no cover
    """The choice along the stripe (:func:`best_path`), then the segments; writes the
    rows (NaN none), peaks and clipped flags (W,).

    Chosen columns join into a segment when their rows link (:func:`links`), across a
    gap of up to ``MAX_GAP`` columns when they differ by at most ``max_jump_px`` per
    column. A segment stays when it has ``min_segment_cols`` columns whose root mean
    square significance is ``min_z``, or a quarter of that (at least two), each
    ``strong_z`` significant (a thin object). A candidate of a segment that does not
    stay is not the laser: it is struck out and the choice is made again (up to
    ``rounds`` times; ``CHOICE_ROUNDS`` by default), so that short clutter, more
    significant column by column, does not take the columns of a weaker but continuous
    stripe. One laser
    lights one sheet across the view: a frame whose longest kept segment spans fewer
    than ``min_stripe_cols`` columns shows no stripe (clutter makes short segments,
    the sheet long ones). Rows are then smoothed along the segment
    (:func:`smooth_rows`).
    """
    w_cols = cand.shape[0]
    pick = np.empty(w_cols, np.int64)
    allowed = ok.copy()
    v = np.full(w_cols, np.nan)
    wid = np.full(w_cols, np.nan)
    keep = np.zeros(w_cols, np.bool_)
    dropped = np.zeros(w_cols, np.bool_)
    longest = 0
    for _ in range(max(rounds, 1)):
        best_path(cand, allowed, prev_v, z_weak, beta, continuity_px, max_jump_px, pick)
        for u in range(w_cols):
            v[u] = np.nan
            wid[u] = np.nan
            if pick[u] >= 0:
                v[u] = cand[u, pick[u], F_POS]
                wid[u] = cand[u, pick[u], F_WIDTH]
        longest = _segments(cand, pick, v, wid, max_jump_px, min_segment_cols, min_z,
                            strong_z, keep, dropped)
        if not dropped.any():
            break
        for u in range(w_cols):
            if dropped[u]:
                allowed[u, pick[u]] = False
    for u in range(w_cols):
        if not keep[u]:
            pick[u] = -1
    if longest < min_stripe_cols:
        keep[:] = False
    se = np.full(w_cols, np.nan)
    for u in range(w_cols):
        amp_out[u] = np.nan
        sat_out[u] = False
        if keep[u]:
            q = pick[u]
            se[u] = cand[u, q, F_SE_POS]
            amp_out[u] = cand[u, q, F_AMP]
            sat_out[u] = cand[u, q, F_SAT] > 0
    smooth_rows(v, se, wid, keep, max_jump_px, v_out)


@njit(cache=True, nogil=True)
def smooth_rows(v: np.ndarray, se: np.ndarray, width: np.ndarray, keep: np.ndarray,
                max_jump_px: float, out: np.ndarray) -> None:  # pragma: no cover
    """Each kept column's row from a weighted quadratic through its segment's rows.

    A stripe on a surface is a smooth image curve and the columns' fits carry
    independent noise: the least-squares quadratic through the rows of up to
    ``SMOOTH_HALF`` linked kept columns either side (weights ``1 / se^2``) estimates
    the row with less noise. Windows stop at corners (second difference beyond
    ``SMOOTH_CORNER_PX`` and four times its noise); a column with fewer than two linked
    neighbours on either side keeps its own row. ``out`` (W,): NaN where not kept.
    """
    n = v.shape[0]
    corner = np.zeros(n, np.bool_)
    for x in range(1, n - 1):
        if keep[x - 1] and keep[x] and keep[x + 1]:
            d2 = v[x + 1] - 2.0 * v[x] + v[x - 1]
            noise = math.sqrt(se[x - 1] ** 2 + 4.0 * se[x] ** 2 + se[x + 1] ** 2)
            corner[x] = abs(d2) > max(SMOOTH_CORNER_PX, 4.0 * noise)
    mom = np.empty((5, 3))
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
        mom[:] = 0.0
        for x in range(lo, hi + 1):
            e = max(se[x], 0.02)
            wt = 1.0 / (e * e)
            d = float(x - u)
            yv = v[x] - v[u]
            for p in range(5):
                mom[p, 0] += wt * d ** p
            for p in range(3):
                mom[p, 1] += wt * d ** p * yv
        s0, s1, s2, s3, s4 = mom[0, 0], mom[1, 0], mom[2, 0], mom[3, 0], mom[4, 0]
        t0, t1, t2 = mom[0, 1], mom[1, 1], mom[2, 1]
        det = s0 * (s2 * s4 - s3 * s3) - s1 * (s1 * s4 - s2 * s3) + s2 * (s1 * s3 - s2 * s2)
        if abs(det) < 1e-12 * s0 * s2 * s4:
            continue
        num = t0 * (s2 * s4 - s3 * s3) - s1 * (t1 * s4 - s3 * t2) + s2 * (t1 * s3 - s2 * t2)
        out[u] = v[u] + num / det
