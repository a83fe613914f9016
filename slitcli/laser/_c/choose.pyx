"""Step 5 of the stripe model, compiled: the choice along the stripe (paper Eq. 4,
segments, rows smoothed along them).

The model is :mod:`slitcli.laser.choose`'s notes. The arithmetic is the numba kernels'
in the same order (Python's ``min`` and ``max``: the first argument kept unless the
second is strictly beyond it), so that results are bit-identical.
"""

import numpy as np

from libc.math cimport NAN, exp, fabs, isfinite, sqrt

from slitcli.laser._c.fields cimport (
    F_AMP,
    F_GNOISE,
    F_NOISE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_WIDTH,
    F_Z,
    N_FIELDS,
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


cdef inline double _gain(const double* c, double prev, double z_weak, double beta,
                         double continuity_px) noexcept nogil:
    """Log-likelihood ratio of the candidate of fields ``c`` being the stripe (its
    significance ``z``: ``(z^2 - z_weak^2) / 2``), its ``z^2`` raised by ``beta`` times
    its closeness to the previous frame's row ``prev`` (NaN none; Eq. 4's f(y) over
    time)."""
    # the choice weighs candidates by their significance against the image's noise (the
    # local noise, which also holds the stripe's own irregular surroundings, only judges
    # whether a candidate can be the stripe at all)
    cdef double z = c[F_Z] * c[F_NOISE] / c[F_GNOISE]
    cdef double f = 0.0
    if isfinite(prev):
        f = _closeness(c[F_POS], prev, continuity_px)
    return 0.5 * (z * z * (1.0 + beta * f) - z_weak * z_weak)


cdef struct Table:
    # a candidate table (w, k, N_FIELDS), C-contiguous, and the previous frame's rows
    const double* cand
    Py_ssize_t w
    Py_ssize_t k
    const double* prev_v  # (w,), or NULL: none


cdef struct Work:
    # the scratch of the choice: score, back (w, k); none, none_back, idx (w,)
    double* score
    Py_ssize_t* back
    double* none
    Py_ssize_t* none_back
    Py_ssize_t* idx


cdef inline const double* _fit(const Table* t, Py_ssize_t u, Py_ssize_t q) noexcept nogil:
    return t.cand + (u * t.k + q) * N_FIELDS


cdef void _best_path(const Table* t, const unsigned char* ok, double z_weak, double beta,
                     double continuity_px, double max_jump_px, Work* ws,
                     Py_ssize_t* pick) noexcept nogil:
    """:func:`best_path` (``ok`` (w, k))."""
    cdef Py_ssize_t w_cols = t.w, k = t.k, u, q, r, best_q, arg, state
    cdef double prev_none, best_prev, g, best, dv, d, sc, prev
    cdef const double* c
    cdef const double* cr
    cdef double* score = ws.score
    cdef Py_ssize_t* back = ws.back
    if w_cols == 0:
        return
    for u in range(w_cols):
        prev_none = ws.none[u - 1] if u > 0 else 0.0
        best_prev = prev_none
        best_q = -1
        if u > 0:
            for r in range(k):
                if score[(u - 1) * k + r] > best_prev:
                    best_prev = score[(u - 1) * k + r]
                    best_q = r
        ws.none[u] = best_prev
        ws.none_back[u] = best_q
        prev = t.prev_v[u] if t.prev_v != NULL else NAN
        for q in range(k):
            score[u * k + q] = -1e300
            back[u * k + q] = -1  # -1: from "none"
            c = _fit(t, u, q)
            if not ok[u * k + q] or c[F_Z] < z_weak:
                continue
            g = _gain(c, prev, z_weak, beta, continuity_px)
            best = prev_none
            arg = -1
            if u > 0:
                for r in range(k):
                    if score[(u - 1) * k + r] <= -1e299:
                        continue
                    cr = _fit(t, u - 1, r)
                    dv = c[F_POS] - cr[F_POS]
                    if not links(dv, c[F_WIDTH], cr[F_WIDTH], max_jump_px):
                        continue
                    d = dv / continuity_px
                    sc = score[(u - 1) * k + r] - 0.5 * d * d
                    if sc > best:
                        best = sc
                        arg = r
            score[u * k + q] = best + g
            back[u * k + q] = arg
    # backtrack from the best final state
    state = -1
    best = ws.none[w_cols - 1]
    for q in range(k):
        if score[(w_cols - 1) * k + q] > best:
            best = score[(w_cols - 1) * k + q]
            state = q
    for u in range(w_cols - 1, -1, -1):
        pick[u] = state
        state = back[u * k + state] if state >= 0 else ws.none_back[u]


cdef inline Table _table(const double[:, :, ::1] cand, const double[::1] prev_v) noexcept:
    """The table of ``cand`` (W, K, N_FIELDS; at least one entry) and ``prev_v`` (W,)
    (another length: none)."""
    cdef Table t
    t.cand = &cand[0, 0, 0]
    t.w = cand.shape[0]
    t.k = cand.shape[1]
    t.prev_v = &prev_v[0] if prev_v.shape[0] == t.w else NULL
    return t


cdef inline Work _work(double* wd, Py_ssize_t* wi, Py_ssize_t w, Py_ssize_t k) noexcept nogil:
    """The scratch in ``wd`` (w k + w doubles) and ``wi`` (w k + 2 w integers)."""
    cdef Work ws
    ws.score = wd
    ws.none = &wd[w * k]
    ws.back = wi
    ws.none_back = &wi[w * k]
    ws.idx = &wi[w * k + w]
    return ws


def best_path(const double[:, :, ::1] cand, const unsigned char[:, ::1] ok,
              prev_v, double z_weak, double beta, double continuity_px,
              double max_jump_px, Py_ssize_t[::1] pick) -> None:
    """Eq. 4 along the stripe: the choice of one candidate or none per column.

    The choice maximises the summed evidence (each candidate's log-likelihood ratio
    ``(z^2 (1 + beta f) - z_weak^2) / 2``, ``f`` its closeness to the previous frame's
    row ``prev_v``) less the continuity cost ``(dv / continuity_px)^2 / 2`` between
    chosen neighbours whose rows link (:func:`links`; others are separated by a column
    without a stripe). Dynamic programming over the columns (Viterbi).

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64, C-contiguous
        The candidate table.
    ok : ndarray, shape (W, K), bool, C-contiguous
        The candidates that may be chosen.
    prev_v : array_like, shape (W,) or (0,), float
        The previous frame's rows, px (NaN none); another length (empty): none.
    z_weak, beta, continuity_px, max_jump_px : float
        Eq. 4's terms (:class:`~slitcli.laser.params.LaserParams`).
    pick : ndarray, shape (W,), int64
        Out: the chosen candidate of each column, -1 none.
    """
    if cand.shape[2] != N_FIELDS:
        raise ValueError(f"cand has {cand.shape[2]} fields, not {N_FIELDS}")
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1]
    if ok.shape[0] != w or ok.shape[1] != k or pick.shape[0] != w:
        raise ValueError("ok, pick and cand differ in shape")
    if w * k == 0:
        pick[:] = -1
        return
    cdef double[::1] wd = np.empty(w * k + w)
    cdef Py_ssize_t[::1] wi = np.empty(w * k + 2 * w, np.intp)
    # (a contiguous copy of a strided prev_v lives as long as pv)
    cdef const double[::1] pv = np.ascontiguousarray(prev_v, dtype=np.float64)
    cdef Table t = _table(cand, pv)
    cdef Work ws = _work(&wd[0], &wi[0], w, k)
    with nogil:
        _best_path(&t, &ok[0, 0], z_weak, beta, continuity_px, max_jump_px, &ws, &pick[0])


cdef inline Py_ssize_t _floor_div(Py_ssize_t a, Py_ssize_t b) noexcept nogil:
    """Python's ``a // b`` (b > 0)."""
    cdef Py_ssize_t d = a / b
    return d - 1 if (a % b != 0 and a < 0) else d


cdef Py_ssize_t _segments(const Table* t, const Py_ssize_t* pick, const double* v,
                          const double* wid, double max_jump_px, Py_ssize_t min_segment_cols,
                          double min_z, double strong_z, unsigned char* keep,
                          unsigned char* dropped, Py_ssize_t* idx) noexcept nogil:
    """The chosen columns (``pick`` >= 0) joined into segments (:func:`choose_stripe`);
    ``keep`` marks the columns of segments that stay, ``dropped`` those of segments that
    do not (``idx`` scratch (W,)); returns the longest kept segment's span in columns."""
    cdef Py_ssize_t w_cols = t.w, longest = 0, u = 0, cnt, last, x, r, quarter
    cdef double dv, z, z2, slope
    cdef const double* fit
    cdef bint strong, good
    for u in range(w_cols):
        keep[u] = 0
        dropped[u] = 0
    u = 0
    quarter = _floor_div(min_segment_cols, 4)
    while u < w_cols:
        if pick[u] < 0:
            u += 1
            continue
        cnt = 1
        idx[0] = u
        last = u
        x = u + 1
        slope = 0.0
        while x < w_cols and x - last <= MAX_GAP + 1:
            if pick[x] >= 0:
                dv = v[x] - v[last]
                # across a gap the stripe runs on along its slope (that of the last
                # link; none before the second column): a row step of one column at most
                if (x == last + 1 and links(dv, wid[x], wid[last], max_jump_px)) or \
                        (x > last + 1 and fabs(dv - slope * (x - last)) <= max_jump_px):
                    slope = dv / (x - last)
                    idx[cnt] = x
                    cnt += 1
                    last = x
                else:
                    break
            x += 1
        strong = cnt >= (quarter if quarter > 2 else 2)
        z2 = 0.0
        for r in range(cnt):
            fit = _fit(t, idx[r], pick[idx[r]])
            z = fit[F_Z]
            # a white core's colour is unknown: its clip says nothing of laser light
            strong = strong and z >= strong_z and fit[F_SAT] != 2
            z2 += z * z
        # the segment's evidence is summed along it: sqrt(z2) is its significance as one
        # fit of a straight stripe of constant peak (the columns' noise independent), and
        # it must reach that of the shortest segment kept, min_segment_cols columns at
        # min_z (a faint but long stripe carries as much evidence as a short strong one;
        # clutter is long only where the colour, shape and sheet tests let it through)
        good = (cnt >= min_segment_cols and z2 >= min_segment_cols * min_z * min_z) or strong
        for r in range(cnt):
            keep[idx[r]] = good
            dropped[idx[r]] = not good
        if good and idx[cnt - 1] - idx[0] + 1 > longest:
            longest = idx[cnt - 1] - idx[0] + 1
        u = last + 1
    return longest


cdef Py_ssize_t _choose_rounds(const Table* t, unsigned char* allowed, double beta,
                               double z_weak, double continuity_px, double max_jump_px,
                               Py_ssize_t min_segment_cols, double min_z, double strong_z,
                               Py_ssize_t rounds, Work* ws, Py_ssize_t* pick, double* v,
                               double* wid, unsigned char* keep,
                               unsigned char* dropped) noexcept nogil:
    """The rounds of :func:`choose_stripe`: the choice, its segments, the candidates of
    dropped segments struck out of ``allowed`` (w, k); returns the longest kept
    segment's span."""
    cdef Py_ssize_t w_cols = t.w, k = t.k, u, i, longest = 0
    cdef bint any_dropped
    cdef const double* c
    for i in range(rounds if rounds > 1 else 1):
        _best_path(t, allowed, z_weak, beta, continuity_px, max_jump_px, ws, pick)
        for u in range(w_cols):
            v[u] = NAN
            wid[u] = NAN
            if pick[u] >= 0:
                c = _fit(t, u, pick[u])
                v[u] = c[F_POS]
                wid[u] = c[F_WIDTH]
        longest = _segments(t, pick, v, wid, max_jump_px, min_segment_cols, min_z,
                            strong_z, keep, dropped, ws.idx)
        any_dropped = False
        for u in range(w_cols):
            if dropped[u]:
                any_dropped = True
                allowed[u * k + pick[u]] = 0
        if not any_dropped:
            break
    return longest


def choose_stripe(const double[:, :, ::1] cand, const unsigned char[:, ::1] ok,
                  prev_v, double beta, double z_weak, double continuity_px,
                  double max_jump_px, Py_ssize_t min_segment_cols, double min_z,
                  double strong_z, Py_ssize_t min_stripe_cols, Py_ssize_t rounds,
                  double[::1] v_out, double[::1] amp_out, unsigned char[::1] sat_out) -> None:
    """The choice along the stripe (:func:`best_path`), then the segments; writes the
    rows, peaks and clipped flags.

    Chosen columns join into a segment when their rows link (:func:`links`), across a
    gap of up to ``MAX_GAP`` columns when they differ by at most ``max_jump_px`` per
    column. A segment stays when it has at least ``min_segment_cols`` columns and its
    significance summed along it, ``sqrt(sum z^2)``, reaches that of
    ``min_segment_cols`` columns at ``min_z`` (a long faint stripe as a short strong
    one), or when it has a quarter of that (at least two) columns, each ``strong_z``
    significant (a thin object). A candidate of a segment that does not
    stay is not the laser: it is struck out and the choice is made again (up to
    ``rounds`` times; ``LaserParams.choice_rounds``), so that short clutter, more
    significant column by column, does not take the columns of a weaker but continuous
    stripe. One laser lights one sheet across the view: a frame whose longest kept
    segment spans fewer than ``min_stripe_cols`` columns shows no stripe (clutter makes
    short segments, the sheet long ones). Rows are then smoothed along the segment
    (:func:`smooth_rows`).

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64, C-contiguous
        The candidate table, rows in px from the image's top.
    ok : ndarray, shape (W, K), bool, C-contiguous
        The candidates that pass :mod:`slitcli.laser.judge`'s tests (not changed).
    prev_v : array_like, shape (W,) or (0,), float
        The previous frame's rows, px (NaN none); another length (empty): none.
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
    if cand.shape[2] != N_FIELDS:
        raise ValueError(f"cand has {cand.shape[2]} fields, not {N_FIELDS}")
    cdef Py_ssize_t w = cand.shape[0], k = cand.shape[1], u, longest
    if ok.shape[0] != w or ok.shape[1] != k or v_out.shape[0] != w or \
            amp_out.shape[0] != w or sat_out.shape[0] != w:
        raise ValueError("ok, v_out, amp_out, sat_out and cand differ in shape")
    if w * k == 0:
        v_out[:] = NAN
        amp_out[:] = NAN
        sat_out[:] = 0
        return
    # (one block of each type: v, wid, se, then the choice's score and none; pick, then
    # back, none_back, idx; allowed, then keep, dropped, corner)
    cdef double[::1] wd = np.empty(3 * w + w * k + w)
    cdef Py_ssize_t[::1] wi = np.empty(w + w * k + 2 * w, np.intp)
    cdef unsigned char[::1] wu = np.empty(w * k + 3 * w, np.uint8)
    cdef double* v = &wd[0]
    cdef double* wid = &wd[w]
    cdef double* se = &wd[2 * w]
    cdef Py_ssize_t* pick = &wi[0]
    cdef unsigned char* allowed = &wu[0]
    cdef unsigned char* keep = &wu[w * k]
    cdef unsigned char* dropped = &wu[w * k + w]
    cdef unsigned char* corner = &wu[w * k + 2 * w]
    # (a contiguous copy of a strided prev_v lives as long as pv)
    cdef const double[::1] pv = np.ascontiguousarray(prev_v, dtype=np.float64)
    cdef Table t = _table(cand, pv)
    cdef Work ws = _work(&wd[3 * w], &wi[w], w, k)
    cdef const double* c
    with nogil:
        for u in range(w * k):
            allowed[u] = ok[u // k, u % k]
        for u in range(w):
            v[u] = NAN
            wid[u] = NAN
        longest = _choose_rounds(&t, allowed, beta, z_weak, continuity_px, max_jump_px,
                                 min_segment_cols, min_z, strong_z, rounds, &ws, pick, v,
                                 wid, keep, dropped)
        if longest < min_stripe_cols:
            for u in range(w):
                keep[u] = 0
        for u in range(w):
            se[u] = NAN
            amp_out[u] = NAN
            sat_out[u] = False
            if keep[u]:
                c = _fit(&t, u, pick[u])
                se[u] = c[F_SE_POS]
                amp_out[u] = c[F_AMP]
                sat_out[u] = c[F_SAT] > 0
        _smooth_rows(v, se, wid, keep, w, max_jump_px, &v_out[0], corner)


cdef void _smooth_rows(const double* v, const double* se, const double* width,
                       const unsigned char* keep, Py_ssize_t n, double max_jump_px,
                       double* out, unsigned char* corner) noexcept nogil:
    """:func:`smooth_rows` of ``n`` columns (``corner`` scratch (n,))."""
    cdef Py_ssize_t x, u, lo, hi, p
    cdef double d2, noise, e, wt, d, yv, pw, det, num
    cdef double m0[5]
    cdef double m1[3]
    for x in range(n):
        corner[x] = 0
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


def smooth_rows(const double[::1] v, const double[::1] se, const double[::1] width,
                const unsigned char[::1] keep, double max_jump_px, double[::1] out) -> None:
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
    keep : ndarray, shape (W,), bool
        The columns to smooth (the others are NaN in ``out``).
    max_jump_px : float
        Largest row step between linked columns, px.
    out : ndarray, shape (W,), float64
        Out: the smoothed rows, px (NaN where not kept).
    """
    cdef Py_ssize_t n = v.shape[0]
    if se.shape[0] != n or width.shape[0] != n or keep.shape[0] != n or out.shape[0] != n:
        raise ValueError("v, se, width, keep and out differ in length")
    if n == 0:
        return
    cdef unsigned char[::1] corner = np.empty(n, np.uint8)
    with nogil:
        _smooth_rows(&v[0], &se[0], &width[0], &keep[0], n, max_jump_px, &out[0],
                     &corner[0])
