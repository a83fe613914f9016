"""The noise of a rectified pair as the matcher sees it, estimated from its own matches.

A camera's noise is not what the paper's matcher was tuned on (i.i.d. Gaussian of 1-2
DN): photo-electron noise grows with the signal and differs per colour; Bayer
demosaicing interpolates each colour from its neighbours, so a pixel's noise is shared
with the next pixel (correlation 0.25-0.3 at lag 1 through the ``robot`` camera preset,
0.45 through ``webcam``, nothing beyond lag 2); the tone curve rescales it by level;
JPEG adds block errors that differ between the two views. For a window test what counts
is the noise variance of each pixel and how much of it neighbouring pixels share (a
window sum of n correlated samples has ``n sigma^2 x VF`` of variance, VF the variance
factor, about 2 for a 3 x 3 block through the ``robot`` preset).

Both are read from the pair itself, where the matcher found the same surface in both
images: at a valid match the left pixel and the right pixel ``d`` columns to its left
see the same light, so their difference is the two views' noise (``2 sigma^2`` of
variance) plus what interpolation misses. :func:`estimate_match_noise` takes that
difference at the whole-pixel shift nearest each valid disparity, removes the
fractional part with the right image's slope, trims outliers (wrong matches, depth
edges; beyond 3.5 robust sigmas) and returns sigma and the lag-1 correlations of the
differences along x, y and the diagonals (the two views' noises are independent, so the
difference carries the same correlation as each view's noise). Anything that differs
between the two views is noise to the matcher, JPEG's block errors included, so this
is the quantity the matcher's tests need, larger than a single view's sensor noise
where compression is strong.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: fewer usable match differences than this: no estimate (the model stays off)
MIN_SAMPLES = 200
#: matches beyond this many are thinned to pairs of rows (the estimate's time; its
#: sampling error at this size is about 1 % of sigma and 0.015 of a correlation)
MAX_SAMPLES = 8000
# a match whose subpixel part is larger leaves too much of the texture in the
# whole-pixel difference for the slope to remove
_MAX_FRACTION_PX = 0.2
# differences beyond this many robust sigmas are wrong matches or depth edges
_TRIM_SIGMAS = 3.5
# a slope (DN/px) within this many noise sigmas: the pixel's difference is mostly noise
_FLAT_SIGMAS = 2.0


@dataclass(frozen=True)
class MatchNoise:
    """Noise of one rectified grey pair, per pixel of one view.

    Attributes
    ----------
    sigma_dn : float
        Standard deviation of one view's noise, DN (the two views' difference at
        matches over sqrt 2); 0 = no estimate.
    rho_x, rho_y, rho_diag : float
        Correlation of the noise of neighbouring pixels: next column, next row, and
        the mean of the two diagonal neighbours.
    samples : int
        Match differences the estimate rests on.
    """

    sigma_dn: float = 0.0
    rho_x: float = 0.0
    rho_y: float = 0.0
    rho_diag: float = 0.0
    samples: int = 0

    def variance_factor(self, width_px: int, height_px: int) -> float:
        """Variance of a ``width_px`` x ``height_px`` block's sum of noise over that of
        as many independent pixels (lag-1 correlations only; the measured correlation
        at lag 2 is below 0.05 through both camera presets).

        ``1 + 2 rho_x (w-1)/w + 2 rho_y (h-1)/h + 4 rho_diag (w-1)(h-1)/(w h)``, at
        least 1/n (a sum's variance is never negative).
        """
        w, h = int(width_px), int(height_px)
        vf = (1.0 + 2.0 * self.rho_x * (w - 1) / w + 2.0 * self.rho_y * (h - 1) / h
              + 4.0 * self.rho_diag * (w - 1) * (h - 1) / (w * h))
        return max(vf, 1.0 / (w * h))


def estimate_match_noise(left_grey: np.ndarray, right_grey: np.ndarray,
                         disparity_px: np.ndarray, valid: np.ndarray) -> MatchNoise:
    """Noise level and lag-1 correlation of a pair from its matches (module notes).

    Parameters
    ----------
    left_grey, right_grey : ndarray, shape (H, W)
        Rectified grey images, DN.
    disparity_px : ndarray, float32, shape (H, W)
        Left disparities (left column minus right column), px; NaN = none.
    valid : ndarray, bool, shape (H, W)
        The matches to use (the winner step's valid pixels).

    Returns
    -------
    MatchNoise
        ``sigma_dn`` 0 when fewer than :data:`MIN_SAMPLES` matches are usable.
    """
    from slitcli.stereo._c import noise as _kernels

    gl = np.ascontiguousarray(left_grey, np.float32)
    gr = np.ascontiguousarray(right_grey, np.float32)
    h, w = gl.shape
    d = np.ascontiguousarray(disparity_px, np.float32)
    ok = np.ascontiguousarray(valid, bool).view(np.uint8)
    count = _kernels.count_matches(d, ok)
    if count < MIN_SAMPLES:
        return MatchNoise()
    # the matches as 1-D arrays (a frame's matches, not its pixels); more than
    # MAX_SAMPLES: pairs of rows at a regular step (neighbours along y stay together)
    step = -(-count // MAX_SAMPLES)
    ys, xs, di = (np.empty(count, np.int32) for _ in range(3))
    diff, slope = np.empty(count, np.float32), np.empty(count, np.float32)
    n = _kernels.match_differences(gl, gr, d, ok, step, _MAX_FRACTION_PX, ys, xs, di,
                                   diff, slope)
    if n < MIN_SAMPLES:
        return MatchNoise()
    ys, xs, di, diff, slope = ys[:n], xs[:n], di[:n], diff[:n], slope[:n]
    q1, centre, q3 = _quantiles(diff)
    robust = max((q3 - q1) / 1.349, 0.5)
    keep = np.abs(diff - centre) <= _TRIM_SIGMAS * robust
    # where the texture is steep the two views' sampling differs by more than the slope
    # removes (blur, pixel phase): the level is taken where the slope is within the
    # noise (the correlations from all kept matches: that choice would bias them along x)
    flat = keep & (np.abs(slope) <= _FLAT_SIGMAS * robust / np.sqrt(2.0))
    n = int(flat.sum())
    if n < MIN_SAMPLES:
        return MatchNoise()
    res = (diff - centre)
    var2 = float(np.mean(np.square(res[flat], dtype=np.float64)))
    # neighbour pairs among the kept matches (one pair of noises: both on one whole
    # disparity): right, below, below-right, below-left
    sums = np.empty((4, 4))
    _kernels.neighbour_sums(ys[keep], xs[keep], di[keep], res[keep].astype(np.float64),
                            np.full(h * w, -1, np.int32), h, w, sums)
    pairs, saa, sbb, sab = sums.T
    den = np.sqrt(saa * sbb)
    enough = (pairs >= MIN_SAMPLES) & (den > 0)
    rho = np.where(enough, sab / np.where(enough, den, 1.0), 0.0)
    return MatchNoise(sigma_dn=float(np.sqrt(var2 / 2.0)), rho_x=float(rho[0]),
                      rho_y=float(rho[1]), rho_diag=float(0.5 * (rho[2] + rho[3])), samples=n)


@dataclass(frozen=True)
class ChannelNoise:
    """Noise variance of each colour channel of one view as a function of the channel's
    level (:func:`estimate_channel_noise`).

    Attributes
    ----------
    levels_dn, variances_dn2 : tuple of three ndarrays, float64, shape (K_c,)
        For channel c (B, G, R order): the median level of each level bin (DN,
        increasing) and the noise variance of one view there (DN^2).
    """

    levels_dn: tuple[np.ndarray, np.ndarray, np.ndarray]
    variances_dn2: tuple[np.ndarray, np.ndarray, np.ndarray]

    def variance_at(self, channel: int, level_dn: np.ndarray) -> np.ndarray:
        """The noise variance (DN^2) of ``channel`` at ``level_dn`` (any shape; linear
        between the bins' levels, constant beyond the end ones)."""
        return np.interp(level_dn, self.levels_dn[channel], self.variances_dn2[channel])


def estimate_channel_noise(left_bgr: np.ndarray, right_bgr: np.ndarray,
                           disparity_px: np.ndarray, valid: np.ndarray,
                           level_bins: int = 8) -> ChannelNoise | None:
    """Each colour channel's noise as a function of its level, from the pair's matches.

    A camera's noise differs by channel and level: photo-electron noise grows with the
    light, the tone curve's slope is steepest in the dark, and the colour matrix that
    undoes the filters' overlap adds a bright channel's noise to the dim ones (a red
    surface's green and blue through the ``robot`` preset carry 15-16 DN, its red 10,
    a grey floor's channels 8-9). As :func:`estimate_match_noise`, per channel: the
    left-minus-right differences at the matches (subpixel rest removed with the right
    image's slope), trimmed at 3.5 robust sigmas and taken where the slope is within
    two noise sigmas, half their mean square in each of ``level_bins`` bins of equal
    count over the left pixel's level.

    Parameters
    ----------
    left_bgr, right_bgr : ndarray, uint8, shape (H, W, 3)
        The rectified colour pair.
    disparity_px, valid : ndarray, shape (H, W)
        Left disparities (px, NaN = none) and the matches to use.
    level_bins : int

    Returns
    -------
    ChannelNoise, or None when a channel has fewer than :data:`MIN_SAMPLES` usable
    differences.
    """
    from slitcli.stereo._c import noise as _kernels

    d = np.ascontiguousarray(disparity_px, np.float32)
    ok = np.ascontiguousarray(valid, bool).view(np.uint8)
    count = _kernels.count_matches(d, ok)
    if count < MIN_SAMPLES:
        return None
    step = -(-count // MAX_SAMPLES)
    levels, variances = [], []
    for c in range(3):
        gl = np.ascontiguousarray(left_bgr[..., c], np.float32)
        gr = np.ascontiguousarray(right_bgr[..., c], np.float32)
        ys, xs, di = (np.empty(count, np.int32) for _ in range(3))
        diff, slope = np.empty(count, np.float32), np.empty(count, np.float32)
        n = _kernels.match_differences(gl, gr, d, ok, step, _MAX_FRACTION_PX, ys, xs, di,
                                       diff, slope)
        if n < MIN_SAMPLES:
            return None
        diff, slope, level = diff[:n], slope[:n], gl[ys[:n], xs[:n]]
        q1, centre, q3 = _quantiles(diff)
        robust = max((q3 - q1) / 1.349, 0.5)
        use = (np.abs(diff - centre) <= _TRIM_SIGMAS * robust) & \
            (np.abs(slope) <= _FLAT_SIGMAS * robust / np.sqrt(2.0))
        if int(use.sum()) < MIN_SAMPLES:
            return None
        order = np.argsort(level[use], kind="stable")
        level = level[use][order]
        res2 = np.square(diff[use] - centre, dtype=np.float64)[order]
        # bins of equal count (at least 50 differences each), in order of level
        k = max(1, min(level_bins, level.size // (MIN_SAMPLES // 4)))
        starts = (np.arange(k) * level.size) // k
        ends = np.append(starts[1:], level.size)
        levels.append(level[(starts + ends - 1) // 2].astype(np.float64))
        variances.append(np.add.reduceat(res2, starts) / (ends - starts) / 2.0)
    return ChannelNoise(tuple(levels), tuple(variances))  # type: ignore[arg-type]


def _quantiles(x: np.ndarray) -> tuple[float, float, float]:
    """First quartile, median and third quartile of ``x`` (nearest rank; one O(n)
    partition instead of a sort)."""
    n = x.size
    k = [(n - 1) // 4, (n - 1) // 2, (3 * (n - 1)) // 4]
    part = np.partition(x, k)
    return float(part[k[0]]), float(part[k[1]]), float(part[k[2]])


__all__ = ["MAX_SAMPLES", "MIN_SAMPLES", "ChannelNoise", "MatchNoise", "estimate_channel_noise",
           "estimate_match_noise"]
