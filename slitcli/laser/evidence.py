"""Step 1 of the stripe model: the laser evidence per pixel and the image's noise (numba).

Signal model of one image column, per channel c in (r, g, b) and row v::

    x_c(v) = s(v) k_c + A p(v) l_c + n_c(v)

``s(v) k_c``: the surface (colour ``k``; texture and shading scale all channels alike);
``A p(v) l_c``: the laser, a profile ``p`` of peak ``A`` and colour ``l`` (the camera's
response to the diode's wavelength, the same on every surface: monochromatic light
reflected by any surface keeps its colour); ``n``: noise. The background under the
stripe is a vertical morphological opening (:func:`vertical_opening`): every feature
narrower than its window is "contrast" ``t = x - opening``. The laser evidence of a
pixel is the red of ``t`` less what its green and blue explain along the surface's
colour (generalised least squares, texture of variance ``tau^2`` along ``k`` over noise of
variance ``sigma^2`` per channel): the share of the surface colour removed is
``lam = tau^2 / (tau^2 + sigma^2)``, measured on each image (:func:`texture_share`). With
texture far above the noise (``lam`` near 1), on a grey surface ``y = t_r - (t_g + t_b)
/ 2``, where white light and texture cancel; on a red surface (``k`` parallel to the red
axis) ``y = t_r``, texture stays. Where the noise is as large as the texture that
survives the opening (real cameras: dim rooms, demosaicing, JPEG), removing the surface
colour would cost more noise than texture it removes, and ``lam`` is smaller.

The noise of every quantity is measured on the image itself, robustly: the median
absolute lag-2 residual ``x(v) - (x(v - 2) + x(v + 2)) / 2`` down the columns (the
stripe, edges and highlights are a small share of the pixels; a lag of two rows skips
most of the correlation that demosaicing leaves between neighbours, not all of what
JPEG's subsampled chroma leaves: there it reads low, so candidates are judged against
the larger of it and the evidence's spread over the image), floored by
``noise_floor_dn`` (quantisation and compression).

Images come transposed, ``(W, H, 3)`` BGR uint8 (one image column per array row).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: 2 ln 2: the median of |n|^2 for isotropic Gaussian noise n of variance sigma^2 per
#: dimension in a plane is 2 ln 2 sigma^2 (chi-square with two degrees of freedom)
CHI2_2_MEDIAN = 2.0 * math.log(2.0)
#: a MAD of a Gaussian is 0.6745 sigma; the lag-2 residual has variance 1.5 sigma^2
MAD_TO_SIGMA = 1.0 / (0.6745 * math.sqrt(1.5))
#: every NOISE_STEP-th column enters the noise estimates
NOISE_STEP = 4


@njit(cache=True, nogil=True)
def _min3(src: np.ndarray, dst: np.ndarray, m: int, sh1: int, sh2: int,
          is_max: bool) -> None:  # pragma: no cover
    """``dst[t] = min(src[t], src[t + sh1], src[t + sh2])`` (max with ``is_max``) for
    ``t < m``; the explicit slices let the compiler vectorise the loop."""
    a = src[:m]
    b = src[sh1:sh1 + m]
    c = src[sh2:sh2 + m]
    d = dst[:m]
    if is_max:
        for t in range(m):
            u, v, w = a[t], b[t], c[t]
            u = u if u > v else v
            d[t] = u if u > w else w
    else:
        for t in range(m):
            u, v, w = a[t], b[t], c[t]
            u = u if u < v else v
            d[t] = u if u < w else w


@njit(cache=True, nogil=True)
def _vertical_filter(x: np.ndarray, k: int, out: np.ndarray, buf_a: np.ndarray,
                     buf_b: np.ndarray, is_max: bool) -> None:  # pragma: no cover
    """Minimum (maximum) over ``k`` rows, anchor ``k // 2``, of ``x`` (rows, C) uint8
    into ``out``; rows beyond the border are left out (OpenCV's erosion and dilation
    with a (k, 1) kernel). Windows doubled in width pass by pass (1, 2, 4, ... rows),
    the last pass joins three: a handful of passes instead of ``k`` comparisons a
    pixel; the scratch buffers hold ``(rows + k - 1) C`` values."""
    n = x.shape[0]
    c = x.shape[1]
    hc = (k // 2) * c
    xf = x.reshape(n * c)
    fill = 0 if is_max else 255  # the padding never wins
    pad_a = buf_a[:hc]
    for t in range(hc):
        pad_a[t] = fill
    mid = buf_a[hc:hc + n * c]
    for t in range(n * c):
        mid[t] = xf[t]
    pad_b = buf_a[hc + n * c:(n + k - 1) * c]
    for t in range(pad_b.size):
        pad_b[t] = fill
    w = 1
    src, dst = buf_a, buf_b
    while 3 * w < k:
        # rows j .. j + 2 w - 1 from two windows of w rows
        _min3(src, dst, (n + k - 2 * w) * c, w * c, w * c, is_max)
        w *= 2
        src, dst = dst, src
    # rows j .. j + k - 1 from three windows of w rows (3 w >= k)
    _min3(src, out.reshape(n * c), n * c, min(w, k - w) * c, (k - w) * c, is_max)


@njit(cache=True, nogil=True)
def vertical_opening(x: np.ndarray, k: int, out: np.ndarray) -> None:  # pragma: no cover
    """Morphological opening of ``x`` (rows, C) uint8 along its rows with a window of
    ``k`` rows, into ``out`` (same shape): the same values as OpenCV's
    ``morphologyEx(x, MORPH_OPEN, ones((k, 1)))`` (min and max are exact), single
    threaded, a fifth faster at 320 x 240 x 3."""
    n, c = x.shape
    buf_a = np.empty((n + k - 1) * c, np.uint8)
    buf_b = np.empty((n + k - 1) * c, np.uint8)
    _vertical_filter(x, k, out, buf_a, buf_b, False)
    _vertical_filter(out, k, out, buf_a, buf_b, True)


@njit(cache=True, nogil=True)
def texture_share(img: np.ndarray, bg: np.ndarray, mask: np.ndarray, sat_dn: int,
                  step: int, max_share: float) -> float:  # pragma: no cover
    """Share ``lam = tau^2 / (tau^2 + sigma^2)`` of the surface colour that the evidence
    removes (module notes), measured on the image: the contrast ``t = x - bg`` of every
    ``step``-th column and every second row (a few thousand pixels fix the spreads to a
    few per cent), split along the surface colour ``k`` and across it. Across ``k``
    there is noise alone (and the few laser pixels): the median of its squared length is
    ``2 ln 2 sigma^2``; along ``k`` texture and noise, of robust spread ``s``
    (1.4826 MAD); so ``lam = 1 - sigma^2 / s^2``, clamped to ``[0, max_share]``.

    ``img`` (W, H, 3) BGR, ``bg`` (3 W, H) as for :func:`laser_evidence`, ``mask`` (W, H)
    the pixels to use (unclipped pixels of the searched rows).
    """
    n_cols, n = img.shape[0], img.shape[1]
    cap = ((n_cols + step - 1) // step) * ((n + 1) // 2)
    along = np.empty(cap)
    across = np.empty(cap)
    m = 0
    for i in range(0, n_cols, step):
        b_b, b_g, b_r = bg[3 * i], bg[3 * i + 1], bg[3 * i + 2]
        xi = img[i]
        for j in range(0, n, 2):
            if not mask[i, j] or xi[j, 2] >= sat_dn or xi[j, 1] >= sat_dn or \
                    xi[j, 0] >= sat_dn:
                continue
            kr = b_r[j] + 0.5
            kg = b_g[j] + 0.5
            kb = b_b[j] + 0.5
            tr = float(xi[j, 2]) - b_r[j]
            tg = float(xi[j, 1]) - b_g[j]
            tb = float(xi[j, 0]) - b_b[j]
            tk = (tr * kr + tg * kg + tb * kb) / math.sqrt(kr * kr + kg * kg + kb * kb)
            along[m] = tk
            across[m] = max(tr * tr + tg * tg + tb * tb - tk * tk, 0.0)
            m += 1
    if m < 16:
        return max_share
    a = along[:m]
    s = 1.4826 * _median(np.abs(a - _median(a)))
    var_n = _median(across[:m]) / CHI2_2_MEDIAN
    if not s > 0.0:
        return max_share
    return min(max(1.0 - var_n / (s * s), 0.0), max_share)


@njit(cache=True, nogil=True)
def laser_evidence(img: np.ndarray, bg: np.ndarray, sat_dn: int, lam: float, y: np.ndarray,
                   clipped: np.ndarray) -> None:  # pragma: no cover
    """Laser evidence ``y`` (W, H) float32 of every pixel (module notes) and its clipped
    flag (red at or above ``sat_dn``).

    ``img`` (W, H, 3) BGR, ``bg`` the opening per channel as (3 W, H): row ``3 i + c``
    holds channel ``c`` (b, g, r) of column ``i``; ``lam`` the share of the surface
    colour removed (:func:`texture_share`). With ``k = bg + 1/2`` and the red axis
    ``e_r``, ``w = (e_r - lam k k_r / |k|^2) / (1 - lam k_r^2 / |k|^2)`` (``w . e_r = 1``)
    and ``y = w . (x - bg)``.
    """
    n_cols, n = img.shape[0], img.shape[1]
    for i in range(n_cols):
        b_b, b_g, b_r = bg[3 * i], bg[3 * i + 1], bg[3 * i + 2]
        xi = img[i]
        yi = y[i]
        ci = clipped[i]
        for j in range(n):
            kr = b_r[j] + 0.5
            kg = b_g[j] + 0.5
            kb = b_b[j] + 0.5
            k2 = kr * kr + kg * kg + kb * kb
            inv = 1.0 / (k2 - lam * kr * kr)
            tr = float(xi[j, 2]) - b_r[j]
            tg = float(xi[j, 1]) - b_g[j]
            tb = float(xi[j, 0]) - b_b[j]
            yi[j] = ((k2 - lam * kr * kr) * tr - lam * kr * (kg * tg + kb * tb)) * inv
            ci[j] = xi[j, 2] >= sat_dn


#: bins of :func:`_median`'s histogram
MEDIAN_BINS = 1024


@njit(cache=True, nogil=True)
def _median(v: np.ndarray) -> float:  # pragma: no cover
    """Median of ``v`` (n,) float, the same value as ``np.median``, without sorting all
    of it: a histogram of ``MEDIAN_BINS`` bins over its range finds the bins of the
    middle order statistics, and only their values are sorted."""
    n = v.shape[0]
    lo = v[0]
    hi = v[0]
    for t in range(n):
        lo = min(lo, v[t])
        hi = max(hi, v[t])
    if not hi > lo:
        return float(lo)
    scale = MEDIAN_BINS / (hi - lo)
    counts = np.zeros(MEDIAN_BINS, np.int64)
    for t in range(n):
        counts[min(int((v[t] - lo) * scale), MEDIAN_BINS - 1)] += 1
    k1 = (n - 1) // 2  # the middle order statistics (one for odd n)
    k2 = n // 2
    below = 0  # values in bins before b1
    b1 = 0
    while below + counts[b1] <= k1:
        below += counts[b1]
        b1 += 1
    b2 = b1
    through = below + counts[b1]
    while through <= k2:
        b2 += 1
        through += counts[b2]
    sel = np.empty(through - below, v.dtype)
    m = 0
    for t in range(n):
        b = min(int((v[t] - lo) * scale), MEDIAN_BINS - 1)
        if b1 <= b <= b2:
            sel[m] = v[t]
            m += 1
    # many equal values (a quantised or clipped quantity) need no sort
    s_lo = sel[0]
    s_hi = sel[0]
    for t in range(m):
        s_lo = min(s_lo, sel[t])
        s_hi = max(s_hi, sel[t])
    if s_lo == s_hi:
        return float(s_lo)
    sel.sort()
    return 0.5 * (float(sel[k1 - below]) + float(sel[k2 - below]))


@njit(cache=True, nogil=True)
def robust_sigma(x: np.ndarray, mask: np.ndarray, step: int) -> float:  # pragma: no cover
    """Noise sigma of ``x`` (W, H) from the median absolute lag-2 residual down every
    ``step``-th column, over rows where ``mask`` (W, H) holds at all five rows used."""
    n_cols, n = x.shape
    vals = np.empty(((n_cols + step - 1) // step) * max(n - 4, 0))
    m = 0
    for i in range(0, n_cols, step):
        for j in range(2, n - 2):
            if mask[i, j - 2] and mask[i, j + 2]:
                vals[m] = abs(x[i, j] - 0.5 * (x[i, j - 2] + x[i, j + 2]))
                m += 1
    if m == 0:
        return 0.0
    return MAD_TO_SIGMA * _median(vals[:m])


@njit(cache=True, nogil=True)
def channel_sigma(img: np.ndarray, step: int) -> np.ndarray:  # pragma: no cover
    """Per-channel noise sigma (R, G, B), DN, of ``img`` (W, H, 3) BGR: the median
    absolute lag-2 residual down every ``step``-th column, unclipped pixels only.

    The residuals of integers come in halves (``k / 2``, ``k = |2 b - a - d|`` in
    0 .. 510): they are counted per half (a histogram, no sort), and the median is
    interpolated within its half-DN bin as for grouped data (the plain median of such
    values moves in whole steps: a 2 DN noise reads 2.4); the bin at 0 is half wide.
    """
    n_cols, n = img.shape[0], img.shape[1]
    out = np.zeros(3)
    hist = np.zeros((3, 511), np.int64)
    for i in range(0, n_cols, step):
        col = img[i]
        for j in range(2, n - 2):
            for c in range(3):
                a, b, d = np.int64(col[j - 2, c]), np.int64(col[j, c]), np.int64(col[j + 2, c])
                if a < 255 and b < 255 and d < 255:
                    hist[c, abs(2 * b - a - d)] += 1
    for c in range(3):
        m = 0
        for k in range(511):
            m += hist[c, k]
        if m == 0:
            continue
        half = m // 2
        lo = 0  # values below the median's bin
        k = 0
        while lo + hist[c, k] <= half:
            lo += hist[c, k]
            k += 1
        hi = lo + hist[c, k]
        step_dn = 0.5
        med = 0.5 * k
        width = step_dn if k > 0 else 0.5 * step_dn
        edge = med - 0.5 * step_dn if k > 0 else 0.0
        out[2 - c] = MAD_TO_SIGMA * (edge + (0.5 * m - lo) / max(hi - lo, 1) * width)
    return out


@njit(cache=True, nogil=True)
def spread_sigma(x: np.ndarray, mask: np.ndarray, step: int) -> float:  # pragma: no cover
    """Robust spread of ``x`` (W, H) about its median over the ``mask``ed pixels of every
    ``step``-th column (1.4826 times the median absolute deviation): noise and all the
    scene structure that the evidence does not cancel (clutter)."""
    n_cols, n = x.shape
    vals = np.empty(((n_cols + step - 1) // step) * n)
    m = 0
    for i in range(0, n_cols, step):
        for j in range(n):
            if mask[i, j]:
                vals[m] = x[i, j]
                m += 1
    if m == 0:
        return 0.0
    v = vals[:m]
    med = _median(v)
    return 1.4826 * _median(np.abs(v - med))
