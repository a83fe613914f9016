"""Small dense least-squares kernels (numba) of the laser profile fit
(:func:`slitcli.laser.fit.fit_profile`): a 4x4 solver, the per-row best linear
unbiased colour weights and the Gauss-Newton normal equations of the Gaussian profile
``off + amp exp(-(v - v0)^2 / 2 s^2)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def solve4(a: np.ndarray, b: np.ndarray, x: np.ndarray,
            m: np.ndarray) -> bool:  # pragma: no cover
    """Solve the 4x4 system ``a x = b`` (Gaussian elimination, partial pivoting) using
    the (4, 5) scratch ``m``; False if singular."""
    for r in range(4):
        for c in range(4):
            m[r, c] = a[r, c]
        m[r, 4] = b[r]
    for col in range(4):
        piv = col
        for r in range(col + 1, 4):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if abs(m[piv, col]) < 1e-300:
            return False
        if piv != col:
            for c in range(5):
                t = m[col, c]
                m[col, c] = m[piv, c]
                m[piv, c] = t
        for r in range(col + 1, 4):
            f = m[r, col] / m[col, col]
            for c in range(col, 5):
                m[r, c] -= f * m[col, c]
    for r in range(3, -1, -1):
        s = m[r, 4]
        for c in range(r + 1, 4):
            s -= m[r, c] * x[c]
        x[r] = s / m[r, r]
    return True


@njit(cache=True, nogil=True)
def inverse_diag12(a: np.ndarray, m: np.ndarray) -> tuple[float, float]:  # pragma: no cover
    """Diagonal entries 1 and 2 of ``a^-1`` (4x4; a fit's variances of amplitude and
    centre): :func:`solve4` for the unit vectors e1 and e2, one elimination shared by
    both (the same operations per right-hand side, so the same bits), using the (4, 6)
    scratch ``m``; NaN, NaN if singular."""
    for r in range(4):
        for c in range(4):
            m[r, c] = a[r, c]
        m[r, 4] = 1.0 if r == 1 else 0.0
        m[r, 5] = 1.0 if r == 2 else 0.0
    for col in range(4):
        piv = col
        for r in range(col + 1, 4):
            if abs(m[r, col]) > abs(m[piv, col]):
                piv = r
        if abs(m[piv, col]) < 1e-300:
            return np.nan, np.nan
        if piv != col:
            for c in range(6):
                t = m[col, c]
                m[col, c] = m[piv, c]
                m[piv, c] = t
        for r in range(col + 1, 4):
            f = m[r, col] / m[col, col]
            for c in range(col, 6):
                m[r, c] -= f * m[col, c]
    # back substitution as in solve4 (x[0] is not needed)
    a3 = m[3, 4] / m[3, 3]
    a2 = (m[2, 4] - m[2, 3] * a3) / m[2, 2]
    s = m[1, 4]
    s -= m[1, 2] * a2
    s -= m[1, 3] * a3
    var_1 = s / m[1, 1]
    b3 = m[3, 5] / m[3, 3]
    s = m[2, 5]
    s -= m[2, 3] * b3
    var_2 = s / m[2, 2]
    return var_1, var_2


@njit(cache=True, nogil=True)
def gls_weights(cov: np.ndarray, lr: float, lg: float, lb: float,
         w: np.ndarray) -> float:  # pragma: no cover
    """Best linear unbiased weights for a signal of colour ``l = (lr, lg, lb)`` in noise
    of covariance ``cov`` (3x3, RGB): ``w = cov^-1 l / (l' cov^-1 l)`` written to ``w``;
    returns the information ``l' cov^-1 l`` (inverse variance of ``w . x``), 0 if
    ``cov`` is singular."""
    a, b, c = cov[0, 0], cov[0, 1], cov[0, 2]
    d, e, f = cov[1, 1], cov[1, 2], cov[2, 2]
    i00 = d * f - e * e
    i01 = c * e - b * f
    i02 = b * e - c * d
    i11 = a * f - c * c
    i12 = b * c - a * e
    i22 = a * d - b * b
    det = a * i00 + b * i01 + c * i02
    if abs(det) < 1e-300:
        return 0.0
    v0 = (i00 * lr + i01 * lg + i02 * lb) / det
    v1 = (i01 * lr + i11 * lg + i12 * lb) / det
    v2 = (i02 * lr + i12 * lg + i22 * lb) / det
    info = lr * v0 + lg * v1 + lb * v2
    if info <= 0.0:
        return 0.0
    w[0] = v0 / info
    w[1] = v1 / info
    w[2] = v2 / info
    return info


@njit(cache=True, nogil=True)
def normal_eq(y: np.ndarray, wt: np.ndarray, j0: int, m: int, off: float, amp: float,
               v0: float, s: float, h: np.ndarray, g: np.ndarray) -> float:  # pragma: no cover
    """Weighted chi-square of the profile model at (off, amp, v0, s), with the
    Gauss-Newton normal equations ``h = J' W J`` (4x4) and ``g = J' W r`` there."""
    # the sums live in local variables (the arrays share the fit's workspace, which the
    # compiler cannot keep in registers); each is added to in the same order as ever
    chi = 0.0
    g0 = g1 = g2 = g3 = 0.0
    h00 = h01 = h02 = h03 = h11 = h12 = h13 = h22 = h23 = h33 = 0.0
    # the Gaussian at successive rows by recurrence (two exponentials per pass)
    t = (j0 - v0) / s
    e_next = math.exp(-0.5 * t * t)
    ratio = math.exp(-t / s - 0.5 / (s * s))
    step = math.exp(-1.0 / (s * s))
    for jj in range(m):
        e = e_next
        e_next = e * ratio
        ratio *= step
        wj = wt[jj]
        if wj == 0.0:
            continue
        t = (j0 + jj - v0) / s
        res = y[jj] - (off + amp * e)
        chi += wj * res * res
        j2 = amp * e * t / s
        j3 = j2 * t
        g0 += wj * res
        g1 += wj * e * res
        g2 += wj * j2 * res
        g3 += wj * j3 * res
        h00 += wj
        h01 += wj * e
        h02 += wj * j2
        h03 += wj * j3
        h11 += wj * e * e
        h12 += wj * e * j2
        h13 += wj * e * j3
        h22 += wj * j2 * j2
        h23 += wj * j2 * j3
        h33 += wj * j3 * j3
    g[0] = g0
    g[1] = g1
    g[2] = g2
    g[3] = g3
    h[0, 0] = h00
    h[0, 1] = h[1, 0] = h01
    h[0, 2] = h[2, 0] = h02
    h[0, 3] = h[3, 0] = h03
    h[1, 1] = h11
    h[1, 2] = h[2, 1] = h12
    h[1, 3] = h[3, 1] = h13
    h[2, 2] = h22
    h[2, 3] = h[3, 2] = h23
    h[3, 3] = h33
    return chi
