"""Step 5 of the stripe model, compiled: the choice along the stripe (paper Eq. 4,
segments, rows smoothed along them).

The model is :mod:`slitcli.laser.choose`'s notes. The arithmetic is the numba kernels'
in the same order (Python's ``min`` and ``max``: the first argument kept unless the
second is strictly beyond it), so that results are bit-identical.
"""

import numpy as np

from libc.math cimport INFINITY, NAN, exp, fabs, isfinite, sqrt

from slitcli.laser._c.fields cimport (
    F_AMP,
    F_GNOISE,
    F_NOISE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_WIDTH,
    F_Z,
)

# (the constants of slitcli.laser.choose; constants() returns them and
# tests/test_laser_kernels.py checks that the two sides agree)
cdef enum:
    MAX_GAP = 2
    SMOOTH_HALF = 4

cdef extern from *:
    """
    #define SLITCLI_SMOOTH_CORNER_PX 0.5
    """
    const double SMOOTH_CORNER_PX "SLITCLI_SMOOTH_CORNER_PX"


def constants() -> dict:
    """The compiled constants, by their Python names (for the test that they agree)."""
    return {"MAX_GAP": MAX_GAP, "SMOOTH_HALF": SMOOTH_HALF,
            "SMOOTH_CORNER_PX": SMOOTH_CORNER_PX, "F_AMP": F_AMP, "F_GNOISE": F_GNOISE,
            "F_NOISE": F_NOISE, "F_POS": F_POS, "F_SAT": F_SAT, "F_SE_POS": F_SE_POS,
            "F_WIDTH": F_WIDTH, "F_Z": F_Z}


cpdef bint links(double dv, double w_a, double w_b, double max_jump_px) noexcept nogil:
    """Rows of neighbouring columns on one stripe: a step ``dv`` (px) of at most
    ``max_jump_px``, or on a steep stripe (whose profile across a column widens to
    ``slope / sqrt(12)``) of at most ``sqrt(3)`` times the sum of the two widths
    ``w_a``, ``w_b`` (px)."""
    dv = fabs(dv)
    return dv <= max_jump_px or dv <= sqrt(3.0) * (w_a + w_b)


cdef inline double _closeness(double v, double ref, double scale) noexcept nogil:
    cdef double d
    if not isfinite(ref):
        return 0.0
    d = (v - ref) / scale
    return exp(-0.5 * d * d)


cdef inline double _gain(const double[:, :, ::1] cand, Py_ssize_t u, Py_ssize_t q,
                         const double[::1] prev_v, double z_weak, double beta,
                         double continuity_px) noexcept nogil:
    """Log-likelihood ratio of candidate ``q`` of column ``u`` being the stripe (its
    significance ``z``: ``(z^2 - z_weak^2) / 2``), its ``z^2`` raised by ``beta`` times
    its closeness to the previous frame's row (Eq. 4's f(y) over time)."""
    # the choice weighs candidates by their significance against the image's noise (the
    # local noise, which also holds the stripe's own irregular surroundings, only judges
    # whether a candidate can be the stripe at all)
    cdef double z = cand[u, q, F_Z] * cand[u, q, F_NOISE] / cand[u, q, F_GNOISE]
    cdef double f = 0.0
    if prev_v.shape[0] == cand.shape[0] and isfinite(prev_v[u]):
        f = _closeness(cand[u, q, F_POS], prev_v[u], continuity_px)
    return 0.5 * (z * z * (1.0 + beta * f) - z_weak * z_weak)


cdef void _best_path(const double[:, :, ::1] cand, const unsigned char[:, ::1] ok,
                     const double[::1] prev_v, double z_weak, double beta,
                     double continuity_px, double max_jump_px, double[:, ::1] score,
                     Py_ssize_t[:, ::1] back, double[::1] none, Py_ssize_t[::1] none_back,
                     Py_ssize_t[::1] pick) noexcept nogil:
    """:func:`best_path` with its scratch (``score``, ``back`` (W, K), ``none``,
    ``none_back`` (W,))."""
    cdef Py_ssize_t w_cols = cand.shape[0], k = cand.shape[1], u, q, r, best_q, arg, state
    cdef double prev_none, best_prev, g, best, dv, d, sc
    if w_cols == 0:
        return
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
            score[u, q] = -1e300
            back[u, q] = -1  # -1: from "none"
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


def best_path(const double[:, :, ::1] cand, ok_arr, const double[::1] prev_v, double z_weak,
              double beta, double continuity_px, double max_jump_px,
              Py_ssize_t[::1] pick) -> None:
    """Eq. 4 along the stripe: the choice of one candidate or none per column.

    The choice maximises the summed evidence (each candidate's log-likelihood ratio
    ``(z^2 (1 + beta f) - z_weak^2) / 2``, ``f`` its closeness to the previous frame's
    row ``prev_v``) less the continuity cost ``(dv / continuity_px)^2 / 2`` between
    chosen neighbours whose rows link (:func:`links`; others are separated by a column
    without a stripe). Dynamic programming over the columns (Viterbi).

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64
        The candidate table.
    ok_arr : ndarray, shape (W, K), bool
        The candidates that may be chosen.
    prev_v : ndarray, shape (W,) or (0,), float64
        The previous frame's rows, px (NaN none); empty: none.
    z_weak, beta, continuity_px, max_jump_px : float
        Eq. 4's terms (:class:`~slitcli.laser.params.LaserParams`).
    pick : ndarray, shape (W,), int64
        Out: the chosen candidate of each column, -1 none.
    """
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1]
    cdef const unsigned char[:, ::1] ok = \
        np.ascontiguousarray(ok_arr, dtype=np.bool_).view(np.uint8)
    if ok.shape[0] != w or ok.shape[1] != k or pick.shape[0] != w:
        raise ValueError("ok_arr, pick and cand differ in shape")
    cdef double[:, ::1] score = np.empty((w, k))
    cdef Py_ssize_t[:, ::1] back = np.empty((w, k), np.intp)
    cdef double[::1] none = np.empty(w)
    cdef Py_ssize_t[::1] none_back = np.empty(w, np.intp)
    with nogil:
        _best_path(cand, ok, prev_v, z_weak, beta, continuity_px, max_jump_px, score, back,
                   none, none_back, pick)


cdef inline Py_ssize_t _floor_div(Py_ssize_t a, Py_ssize_t b) noexcept nogil:
    """Python's ``a // b`` (b > 0)."""
    cdef Py_ssize_t d = a / b
    return d - 1 if (a % b != 0 and a < 0) else d


cdef Py_ssize_t _segments(const double[:, :, ::1] cand, const Py_ssize_t[::1] pick,
                          const double[::1] v, const double[::1] wid, double max_jump_px,
                          Py_ssize_t min_segment_cols, double min_z, double strong_z,
                          unsigned char[::1] keep, unsigned char[::1] dropped,
                          Py_ssize_t[::1] idx) noexcept nogil:
    """The chosen columns (``pick`` >= 0) joined into segments (:func:`choose_stripe`);
    ``keep`` marks the columns of segments that stay, ``dropped`` those of segments that
    do not (``idx`` scratch (W,)); returns the longest kept segment's span in columns."""
    cdef Py_ssize_t w_cols = cand.shape[0], longest = 0, u = 0, cnt, last, x, r, quarter
    cdef double dv, z, z2
    cdef bint strong, good
    keep[:] = 0
    dropped[:] = 0
    quarter = _floor_div(min_segment_cols, 4)
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
                        fabs(dv) <= max_jump_px * (x - last):
                    idx[cnt] = x
                    cnt += 1
                    last = x
                else:
                    break
            x += 1
        strong = cnt >= (quarter if quarter > 2 else 2)
        z2 = 0.0
        for r in range(cnt):
            z = cand[idx[r], pick[idx[r]], F_Z]
            strong = strong and z >= strong_z
            z2 += z * z
        good = (cnt >= min_segment_cols and z2 >= cnt * min_z * min_z) or strong
        for r in range(cnt):
            keep[idx[r]] = good
            dropped[idx[r]] = not good
        if good and idx[cnt - 1] - idx[0] + 1 > longest:
            longest = idx[cnt - 1] - idx[0] + 1
        u = last + 1
    return longest


cdef Py_ssize_t _choose_rounds(const double[:, :, ::1] cand, unsigned char[:, ::1] allowed,
                               const double[::1] prev_v, double beta, double z_weak,
                               double continuity_px, double max_jump_px,
                               Py_ssize_t min_segment_cols, double min_z, double strong_z,
                               Py_ssize_t rounds, double[:, ::1] score,
                               Py_ssize_t[:, ::1] back, double[::1] none,
                               Py_ssize_t[::1] none_back, Py_ssize_t[::1] pick,
                               double[::1] v, double[::1] wid, unsigned char[::1] keep,
                               unsigned char[::1] dropped,
                               Py_ssize_t[::1] idx) noexcept nogil:
    """The rounds of :func:`choose_stripe`: the choice, its segments, the candidates of
    dropped segments struck out of ``allowed``; returns the longest kept segment's span."""
    cdef Py_ssize_t w_cols = cand.shape[0], u, i, longest = 0
    cdef bint any_dropped
    for i in range(rounds if rounds > 1 else 1):
        _best_path(cand, allowed, prev_v, z_weak, beta, continuity_px, max_jump_px, score,
                   back, none, none_back, pick)
        for u in range(w_cols):
            v[u] = NAN
            wid[u] = NAN
            if pick[u] >= 0:
                v[u] = cand[u, pick[u], F_POS]
                wid[u] = cand[u, pick[u], F_WIDTH]
        longest = _segments(cand, pick, v, wid, max_jump_px, min_segment_cols, min_z,
                            strong_z, keep, dropped, idx)
        any_dropped = False
        for u in range(w_cols):
            if dropped[u]:
                any_dropped = True
                allowed[u, pick[u]] = 0
        if not any_dropped:
            break
    return longest


def choose_stripe(const double[:, :, ::1] cand, ok_arr, const double[::1] prev_v,
                  double beta, double z_weak, double continuity_px, double max_jump_px,
                  Py_ssize_t min_segment_cols, double min_z, double strong_z,
                  Py_ssize_t min_stripe_cols, Py_ssize_t rounds, double[::1] v_out,
                  double[::1] amp_out, sat_out) -> None:
    """The choice along the stripe (:func:`best_path`), then the segments; writes the
    rows, peaks and clipped flags.

    Chosen columns join into a segment when their rows link (:func:`links`), across a
    gap of up to ``MAX_GAP`` columns when they differ by at most ``max_jump_px`` per
    column. A segment stays when it has ``min_segment_cols`` columns whose root mean
    square significance is ``min_z``, or a quarter of that (at least two), each
    ``strong_z`` significant (a thin object). A candidate of a segment that does not
    stay is not the laser: it is struck out and the choice is made again (up to
    ``rounds`` times; ``CHOICE_ROUNDS`` by default), so that short clutter, more
    significant column by column, does not take the columns of a weaker but continuous
    stripe. One laser lights one sheet across the view: a frame whose longest kept
    segment spans fewer than ``min_stripe_cols`` columns shows no stripe (clutter makes
    short segments, the sheet long ones). Rows are then smoothed along the segment
    (:func:`smooth_rows`).

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64
        The candidate table, rows in px from the image's top.
    ok_arr : ndarray, shape (W, K), bool
        The candidates that pass :mod:`slitcli.laser.judge`'s tests (not changed).
    prev_v : ndarray, shape (W,) or (0,), float64
        The previous frame's rows, px (NaN none); empty: none.
    beta, z_weak, continuity_px, max_jump_px, min_segment_cols, min_z, strong_z, \
min_stripe_cols, rounds
        As above and :class:`~slitcli.laser.params.LaserParams`.
    v_out : ndarray, shape (W,), float64
        Out: the stripe's row per column, px (NaN none).
    amp_out : ndarray, shape (W,), float64
        Out: its peak, DN of evidence (NaN none).
    sat_out : ndarray, shape (W,), bool
        Out: whether its core is clipped.
    """
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1], u, q, longest
    allowed_arr = np.array(ok_arr, dtype=np.bool_, order="C")
    cdef unsigned char[:, ::1] allowed = allowed_arr.view(np.uint8)
    sat_view = np.asarray(sat_out)
    if sat_view.dtype != np.bool_:
        raise ValueError("sat_out must be a bool array")
    cdef unsigned char[::1] sat = sat_view.view(np.uint8)
    if allowed.shape[0] != w or allowed.shape[1] != k or v_out.shape[0] != w or \
            amp_out.shape[0] != w or sat.shape[0] != w:
        raise ValueError("ok_arr, v_out, amp_out, sat_out and cand differ in shape")
    cdef double[:, ::1] score = np.empty((w, k))
    cdef Py_ssize_t[:, ::1] back = np.empty((w, k), np.intp)
    cdef double[::1] none = np.empty(w)
    cdef Py_ssize_t[::1] none_back = np.empty(w, np.intp)
    cdef Py_ssize_t[::1] pick = np.empty(w, np.intp)
    cdef Py_ssize_t[::1] idx = np.empty(w, np.intp)
    cdef double[::1] v = np.empty(w)
    cdef double[::1] wid = np.empty(w)
    cdef double[::1] se = np.empty(w)
    cdef unsigned char[::1] keep = np.zeros(w, np.uint8)
    cdef unsigned char[::1] dropped = np.zeros(w, np.uint8)
    cdef unsigned char[::1] corner = np.empty(w, np.uint8)
    with nogil:
        v[:] = NAN
        wid[:] = NAN
        longest = _choose_rounds(cand, allowed, prev_v, beta, z_weak, continuity_px,
                                 max_jump_px, min_segment_cols, min_z, strong_z, rounds,
                                 score, back, none, none_back, pick, v, wid, keep, dropped,
                                 idx)
        if longest < min_stripe_cols:
            keep[:] = 0
        for u in range(w):
            se[u] = NAN
            amp_out[u] = NAN
            sat[u] = False
            if keep[u]:
                q = pick[u]
                se[u] = cand[u, q, F_SE_POS]
                amp_out[u] = cand[u, q, F_AMP]
                sat[u] = cand[u, q, F_SAT] > 0
        _smooth_rows(v, se, wid, keep, max_jump_px, v_out, corner)


cdef void _smooth_rows(const double[::1] v, const double[::1] se, const double[::1] width,
                       const unsigned char[::1] keep, double max_jump_px, double[::1] out,
                       unsigned char[::1] corner) noexcept nogil:
    """:func:`smooth_rows` (``corner`` scratch (n,))."""
    cdef Py_ssize_t n = v.shape[0], x, u, lo, hi, p
    cdef double d2, noise, e, wt, d, yv, pw, det, num
    cdef double m0[5]
    cdef double m1[3]
    corner[:] = 0
    for x in range(1, n - 1):
        if keep[x - 1] and keep[x] and keep[x + 1]:
            d2 = v[x + 1] - 2.0 * v[x] + v[x - 1]
            noise = sqrt(se[x - 1] * se[x - 1] + 4.0 * (se[x] * se[x]) +
                         se[x + 1] * se[x + 1])
            noise = 4.0 * noise
            corner[x] = fabs(d2) > (noise if noise > SMOOTH_CORNER_PX else SMOOTH_CORNER_PX)
    for u in range(n):
        out[u] = v[u] if keep[u] else NAN
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
        for p in range(5):
            m0[p] = 0.0
        for p in range(3):
            m1[p] = 0.0
        for x in range(lo, hi + 1):
            e = se[x] if not 0.02 > se[x] else 0.02
            wt = 1.0 / (e * e)
            d = <double>(x - u)
            yv = v[x] - v[u]
            # (d ** p exactly: |d| <= SMOOTH_HALF, p <= 4, integers in a double)
            pw = 1.0
            for p in range(5):
                m0[p] += wt * pw
                if p < 3:
                    m1[p] += wt * pw * yv
                pw = pw * d
        det = m0[0] * (m0[2] * m0[4] - m0[3] * m0[3]) - \
            m0[1] * (m0[1] * m0[4] - m0[2] * m0[3]) + m0[2] * (m0[1] * m0[3] - m0[2] * m0[2])
        if fabs(det) < 1e-12 * m0[0] * m0[2] * m0[4]:
            continue
        num = m1[0] * (m0[2] * m0[4] - m0[3] * m0[3]) - m0[1] * (m1[1] * m0[4] - m0[3] * m1[2]) + \
            m0[2] * (m1[1] * m0[3] - m0[2] * m1[2])
        out[u] = v[u] + num / det


def smooth_rows(const double[::1] v, const double[::1] se, const double[::1] width, keep_arr,
                double max_jump_px, double[::1] out) -> None:
    """Each kept column's row from a weighted quadratic through its segment's rows.

    A stripe on a surface is a smooth image curve and the columns' fits carry
    independent noise: the least-squares quadratic through the rows of up to
    ``SMOOTH_HALF`` linked kept columns either side (weights ``1 / se^2``) estimates the
    row with less noise. Windows stop at corners (second difference beyond
    ``SMOOTH_CORNER_PX`` and four times its noise); a column with fewer than two linked
    neighbours on either side keeps its own row.

    Parameters
    ----------
    v : ndarray, shape (W,), float64
        Rows per column, px.
    se : ndarray, shape (W,), float64
        Their standard errors, px.
    width : ndarray, shape (W,), float64
        The stripe's fitted sigma per column, px (:func:`links`).
    keep_arr : ndarray, shape (W,), bool
        The columns to smooth (the others are NaN in ``out``).
    max_jump_px : float
        Largest row step between linked columns, px.
    out : ndarray, shape (W,), float64
        Out: the smoothed rows, px (NaN where not kept).
    """
    cdef Py_ssize_t n = v.shape[0]
    cdef const unsigned char[::1] keep = \
        np.ascontiguousarray(keep_arr, dtype=np.bool_).view(np.uint8)
    if se.shape[0] != n or width.shape[0] != n or keep.shape[0] != n or out.shape[0] != n:
        raise ValueError("v, se, width, keep and out differ in length")
    cdef unsigned char[::1] corner = np.empty(n, np.uint8)
    with nogil:
        _smooth_rows(v, se, width, keep, max_jump_px, out, corner)
