"""Step 2 of the stripe model: the profile across one column, fitted (numba).

A stripe crossing a column is a Gaussian of the laser evidence (:mod:`.evidence`) on a
straight background, ``y(v) = c + b (v - v_s) + A exp(-(v - v0)^2 / (2 s^2))`` (the line:
what the opening leaves of the surface's texture and shading), with noise ``sigma`` per
row and a model error proportional to the profile (speckle, demosaicing and compression
make real profiles only roughly Gaussian): the shape test allows a row variance
``sigma^2 + (shape_error A p(v))^2``. A hump that fails it (a flat or skewed top) is
centred by its upper half (:func:`flat_top`). Clipped rows carry no shape and are left
out; a clipped core is fitted on its flanks. Rows are pixel centres at integers.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MAX_ITER = 6
CONVERGED_PX = 0.005
MIN_SIGMA_PX = 0.3  # a pixel's own extent gives any profile sqrt(1/12) = 0.29 px
MIN_ROWS = 6
N_PAR = 5  # offset, peak, centre, width, background slope

#: fields of one fit (last axis of the candidate table)
(F_POS, F_AMP, F_WIDTH, F_Z, F_SE_POS, F_CHI2, F_SAT, F_NOISE, F_TR, F_TG, F_TB, F_KR, F_KG,
 F_KB, F_NCORE, F_FLAT, F_GNOISE) = range(17)
N_FIELDS = 17
#: rows of :func:`fit_gaussian`'s scratch (h, g, dx, p)
WORK_ROWS = N_PAR + 3


@njit(cache=True, nogil=True)
def _solve(a: np.ndarray, b: np.ndarray, x: np.ndarray, factor: bool) -> bool:  # pragma: no cover
    """Solve ``a x = b`` for a small symmetric positive definite ``a`` by its Cholesky
    factor ``L`` (``a = L L'``), which ``factor`` first writes over the lower triangle of
    ``a`` (the factor of the normal equations serves the step and the covariance
    alike); False if ``a`` is not positive definite. ``b`` is kept. ``N_PAR`` unknowns
    (a constant: the loops unroll)."""
    n = N_PAR
    if factor:
        for j in range(n):
            d = a[j, j]
            for k in range(j):
                d -= a[j, k] * a[j, k]
            if not d > 1e-300:
                return False
            d = math.sqrt(d)
            a[j, j] = d
            for i in range(j + 1, n):
                t = a[i, j]
                for k in range(j):
                    t -= a[i, k] * a[j, k]
                a[i, j] = t / d
    for i in range(n):  # L z = b
        t = b[i]
        for k in range(i):
            t -= a[i, k] * x[k]
        x[i] = t / a[i, i]
    for i in range(n - 1, -1, -1):  # L' x = z
        t = x[i]
        for k in range(i + 1, n):
            t -= a[k, i] * x[k]
        x[i] = t / a[i, i]
    return True


@njit(cache=True, nogil=True)
def gaussian_rows(j0: int, v0: float, s: float, e: np.ndarray) -> None:  # pragma: no cover
    """``e[k] = exp(-(j0 + k - v0)^2 / (2 s^2))`` for every entry of ``e``, by the ratio
    recurrence from the row nearest the centre (``exp(-(t + u)^2 / 2) = exp(-t^2 / 2)
    exp(-t u - u^2 / 2)``, ``u = 1 / s``): three exponentials instead of one a row (an
    exponential costs what a row's sums in the fit do)."""
    m = e.shape[0]
    u = 1.0 / s
    jc = min(max(math.floor(v0 - j0 + 0.5), 0), m - 1)
    tc = (j0 + jc - v0) * u
    e[jc] = math.exp(-0.5 * tc * tc)
    dd = math.exp(-u * u)
    q = math.exp(-tc * u - 0.5 * u * u)
    for jj in range(jc + 1, m):
        e[jj] = e[jj - 1] * q
        q *= dd
    q = math.exp(tc * u - 0.5 * u * u)
    for jj in range(jc - 1, -1, -1):
        e[jj] = e[jj + 1] * q
        q *= dd


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _normal(y: np.ndarray, use: np.ndarray, j0: int, ref: float, p: np.ndarray,
            sigma: float, shape_error: float, h: np.ndarray, g: np.ndarray,
            e: np.ndarray, with_chi: bool) -> tuple[float, int]:  # pragma: no cover
    """Chi-square of the model at ``p = (c, A, v0, s, b)`` under the row variance with
    the model error, and the Gauss-Newton normal equations ``h = J' J / sigma^2``,
    ``g = J' r / sigma^2`` there (the noise alone weighs the rows: the model error is
    no evidence against the stripe's presence); also the rows used. The background is
    the line ``c + b (v - ref)``. ``e`` (rows,) is scratch for the Gaussian's samples;
    the chi-square (a division a row) only ``with_chi``, else 0."""
    m = y.shape[0]
    c, a, v0, s, sl = p[0], p[1], p[2], p[3], p[4]
    u = 1.0 / s
    gaussian_rows(j0, v0, s, e[:m])
    chi = 0.0
    n = 0.0
    wt = 1.0 / (sigma * sigma)
    var0 = sigma * sigma
    h01 = h02 = h03 = h04 = h11 = h12 = h13 = h14 = 0.0
    h22 = h23 = h24 = h33 = h34 = h44 = 0.0
    g0 = g1 = g2 = g3 = g4 = 0.0
    # branch-free (unused rows weigh 0), so that the sums over the rows vectorise
    for jj in range(m):
        w = 1.0 if use[jj] else 0.0
        t = (j0 + jj - v0) * u
        ej = e[jj]
        model = a * ej
        d = j0 + jj - ref
        r = y[jj] - (c + sl * d + model)
        rw = r * w
        if with_chi:
            chi += rw * r / (var0 + (shape_error * model) ** 2)
        n += w
        j2 = model * t * u
        j3 = j2 * t
        ew = ej * w
        j2w = j2 * w
        j3w = j3 * w
        dw = d * w
        g0 += rw
        g1 += ej * rw
        g2 += j2 * rw
        g3 += j3 * rw
        g4 += d * rw
        h01 += ew
        h02 += j2w
        h03 += j3w
        h04 += dw
        h11 += ew * ej
        h12 += ew * j2
        h13 += ew * j3
        h14 += ew * d
        h22 += j2w * j2
        h23 += j2w * j3
        h24 += j2w * d
        h33 += j3w * j3
        h34 += j3w * d
        h44 += dw * d
    h[0, 0], h[0, 1], h[0, 2], h[0, 3], h[0, 4] = wt * n, wt * h01, wt * h02, wt * h03, wt * h04
    h[1, 1], h[1, 2], h[1, 3], h[1, 4] = wt * h11, wt * h12, wt * h13, wt * h14
    h[2, 2], h[2, 3], h[2, 4] = wt * h22, wt * h23, wt * h24
    h[3, 3], h[3, 4] = wt * h33, wt * h34
    h[4, 4] = wt * h44
    for i in range(N_PAR):
        for k in range(i):
            h[i, k] = h[k, i]
    g[0], g[1], g[2], g[3], g[4] = wt * g0, wt * g1, wt * g2, wt * g3, wt * g4
    return chi, int(n)


@njit(cache=True, nogil=True)
def fit_gaussian(y: np.ndarray, use: np.ndarray, j0: int, v_start: float, s_start: float,
                 sigma: float, shape_error: float, s_max: float, out: np.ndarray,
                 work: np.ndarray, ebuf: np.ndarray) -> bool:  # pragma: no cover
    """Fit ``c + b (v - v_start) + A exp(-(v - v0)^2 / 2 s^2)`` to ``y`` (rows ``j0 ..``)
    where ``use``.

    Gauss-Newton from ``v_start``, ``s_start`` with a bounded step; ``out`` gets
    ``(v0, A, s, z, se_v0, chi2)``: ``z`` is ``A`` over its standard error, ``chi2``
    the reduced chi-square (module notes). False when fewer than ``MIN_ROWS`` rows, no
    convergence to a positive peak inside the window, or a width beyond ``2 s_max``.
    ``work`` (WORK_ROWS, N_PAR) and ``ebuf`` (at least the rows) are scratch (no
    allocation per fit).
    """
    m = y.shape[0]
    h = work[0:N_PAR]
    g = work[N_PAR]
    dx = work[N_PAR + 1]
    p = work[N_PAR + 2]
    p[:] = 0.0
    lo = 1e300
    pk = -1e300
    for jj in range(m):
        if use[jj]:
            lo = min(lo, y[jj])
            if abs(j0 + jj - v_start) <= max(1.5, s_start):
                pk = max(pk, y[jj])
    if lo == 1e300:
        return False
    p[0] = lo
    p[1] = max(pk - lo, 1e-3)
    p[2] = v_start
    p[3] = s_start
    n_use = 0
    chi = 0.0
    for _ in range(MAX_ITER):
        chi, n_use = _normal(y, use, j0, v_start, p, sigma, shape_error, h, g, ebuf, False)
        if n_use < MIN_ROWS:
            return False
        for q in range(N_PAR):
            h[q, q] *= 1.0 + 1e-6
        if not _solve(h, g, dx, True):
            return False
        # keep the step sane: the centre moves at most a width, the width changes by at
        # most half of itself
        lim_v = max(p[3], 0.5)
        dx[2] = min(max(dx[2], -lim_v), lim_v)
        dx[3] = min(max(dx[3], -0.5 * p[3]), 0.5 * p[3])
        for q in range(N_PAR):
            p[q] += dx[q]
        p[3] = max(p[3], 0.5 * MIN_SIGMA_PX)
        if p[3] > 2.0 * s_max or not (j0 - 0.5 <= p[2] <= j0 + m - 0.5):
            return False
        if abs(dx[2]) < CONVERGED_PX and abs(dx[3]) < 0.01 * p[3]:
            break
    chi, n_use = _normal(y, use, j0, v_start, p, sigma, shape_error, h, g, ebuf, True)
    if p[1] <= 0.0 or n_use < MIN_ROWS:
        return False
    # covariance: inverse of h, diagonal entries 1 (A) and 2 (v0), from one factor
    var_a = 0.0
    var_v = 0.0
    for idx in (1, 2):
        g[:] = 0.0
        g[idx] = 1.0
        if not _solve(h, g, dx, idx == 1):
            return False
        if idx == 1:
            var_a = dx[idx]
        else:
            var_v = dx[idx]
    if not (var_a > 0.0 and var_v > 0.0):
        return False
    out[0] = p[2]
    out[1] = p[1]
    out[2] = p[3]
    out[3] = p[1] / math.sqrt(var_a)
    out[4] = math.sqrt(var_v)
    out[5] = chi / max(n_use - N_PAR, 1)
    return True


@njit(cache=True, nogil=True)
def plateau_centre(red: np.ndarray, a: int, b: int, level: float) -> float:  # pragma: no cover
    """Centre of a clipped run ``a .. b - 1`` of the red profile ``red``: the midpoint of
    where the profile crosses ``level`` on either side (linear interpolation; a side cut
    off by the border takes the run's own end)."""
    n = red.shape[0]
    j = a
    while j > 0 and red[j - 1] >= level:
        j -= 1
    up = j - 0.5
    if j > 0:
        lo_v, hi_v = red[j - 1], red[j]
        up = j - 1 + (level - lo_v) / max(hi_v - lo_v, 1e-9)
    j = b - 1
    while j < n - 1 and red[j + 1] >= level:
        j += 1
    dn = j + 0.5
    if j < n - 1:
        hi_v, lo_v = red[j], red[j + 1]
        dn = j + (hi_v - level) / max(hi_v - lo_v, 1e-9)
    return 0.5 * (up + dn)


@njit(cache=True, nogil=True)
def flat_top(y: np.ndarray, use: np.ndarray, j0: int, v_start: float, base: float,
             sigma: float, out: np.ndarray) -> bool:  # pragma: no cover
    """A hump that is no Gaussian (a flat or skewed top: a strong stripe through a
    camera's compressive tone curve, a wide beam, a cut-off flank), centred without a
    shape model: the centre of gravity of its upper half.

    The peak is the largest used ``y`` within 2 rows of ``v_start``; the hump is the
    run of rows above half its height over ``base``, which must end inside the window
    on both sides. ``out`` gets ``(v0, height, s, z, se_v0, chi2)`` with ``s`` the
    half-height width over 2.355, ``z`` the height over ``sigma`` and ``se_v0`` the
    centre of gravity's noise.
    """
    m = y.shape[0]
    kp = -1
    for jj in range(m):
        if use[jj] and abs(j0 + jj - v_start) <= 2.0 and (kp < 0 or y[jj] > y[kp]):
            kp = jj
    if kp < 0:
        return False
    height = y[kp] - base
    if height <= 0.0:
        return False
    level = base + 0.5 * height
    a = kp
    while a > 0 and use[a - 1] and y[a - 1] >= level:
        a -= 1
    b = kp
    while b < m - 1 and use[b + 1] and y[b + 1] >= level:
        b += 1
    if a == 0 or b == m - 1 or not (use[a - 1] and use[b + 1]):
        return False  # a flank cut off: no crossing on that side
    sw = 0.0
    sv = 0.0
    for jj in range(a, b + 1):
        wgt = y[jj] - level
        sw += wgt
        sv += wgt * jj
    v0 = sv / sw
    var = 0.0
    for jj in range(a, b + 1):
        var += (jj - v0) ** 2
    out[0] = j0 + v0
    out[1] = height
    out[2] = (b - a + 1) / 2.355
    out[3] = height / sigma
    out[4] = sigma * math.sqrt(var) / sw
    out[5] = 0.0
    return True
