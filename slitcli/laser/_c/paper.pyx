"""Compiled kernel of :mod:`slitcli.laser.paper`: the paper's Eqs. 1-4 taken literally.
Releases the GIL; the arithmetic is that of the expressions as written (libm's ``exp``),
the same bits as the numba kernel it replaces.
"""

from libc.math cimport exp, isfinite, NAN
from libc.stdint cimport uint8_t


cdef inline bint _red(const uint8_t* px, double min_th, double min_delta_th,
                      double alpha) noexcept nogil:
    """Eqs. 1-3 on one BGR pixel: relative red above ``min_th``, red less the larger of
    green and blue (relative) above ``min_delta_th``, red above ``alpha`` times it."""
    cdef double r = px[2], g = px[1], b = px[0]
    cdef double s = r + g + b
    cdef double gb = b if b > g else g   # Python's max(g, b)
    return s > 0 and r / s > min_th and (r - gb) / s > min_delta_th and r > alpha * gb


def paper_columns(const uint8_t[:, :, ::1] img, const uint8_t[:, ::1] mask, double min_th,
                  double min_delta_th, double alpha, double beta, double gamma,
                  double continuity_px, double max_width_px, double[::1] v_out,
                  double[::1] amp_out) -> None:
    """Eqs. 1-4 per column: the runs of pixels passing the red tests (Eqs. 1-3), each
    scored (Eq. 4) ``r_max / 255 + beta f + gamma (1 - run length / max_width_px)``
    with ``f = exp(-dv^2 / 2 continuity_px^2)`` the closeness to the previous column's
    row; the best run's centre of gravity of red is the column's row.

    Parameters
    ----------
    img : ndarray, shape (W, H, 3), uint8, BGR (transposed image)
    mask : ndarray, shape (W, H), bool
        The searched pixels.
    min_th, min_delta_th, alpha : float
        Eqs. 2-3 thresholds (relative intensities; alpha a ratio).
    beta, gamma : float
        Eq. 4 weights of continuity and narrowness.
    continuity_px, max_width_px : float
        Eq. 4 scales, px.
    v_out, amp_out : ndarray, shape (W,), float64
        Written: the row, px (NaN none), and the run's red peak, DN (NaN none).
    """
    cdef Py_ssize_t n_cols = img.shape[0], n = img.shape[1], i, j, a
    cdef double prev = NAN, best, rmax, sw, sv, r, centre, f, d, score
    cdef const uint8_t* col
    if mask.shape[0] != n_cols or mask.shape[1] != n or v_out.shape[0] != n_cols \
            or amp_out.shape[0] != n_cols:
        raise ValueError("paper_columns: mask (W, H), v_out and amp_out (W,) for img (W, H, 3)")
    with nogil:
        for i in range(n_cols):
            v_out[i] = NAN
            amp_out[i] = NAN
            best = -1e300
            col = &img[i, 0, 0] if n > 0 else NULL
            j = 0
            while j < n:
                if not (mask[i, j] and _red(col + 3 * j, min_th, min_delta_th, alpha)):
                    j += 1
                    continue
                a = j
                rmax = 0.0
                sw = 0.0
                sv = 0.0
                while j < n and mask[i, j]:
                    if not _red(col + 3 * j, min_th, min_delta_th, alpha):
                        break
                    r = col[3 * j + 2]
                    rmax = r if r > rmax else rmax
                    sw += r
                    sv += r * <double> j
                    j += 1
                centre = sv / sw if sw > 0 else 0.5 * <double> (a + j - 1)
                f = 0.0
                if isfinite(prev):
                    d = (centre - prev) / continuity_px
                    f = exp(-0.5 * d * d)
                score = rmax / 255.0 + beta * f + gamma * (1.0 - <double> (j - a) / max_width_px)
                if score > best:
                    best = score
                    v_out[i] = centre
                    amp_out[i] = rmax
            if isfinite(v_out[i]):
                prev = v_out[i]
