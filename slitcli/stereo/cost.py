"""What the Eq. 10 cost is computed on (grey and prefiltered images) and the matchers'
common result type: shared by the local matcher and SGM, so neither imports the other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.stereo.reasons import Reason

if TYPE_CHECKING:
    from slitcli.stereo.matcher import MatcherParams
    from slitcli.stereo.noise import ChannelNoise

# Prefiltered images are stored as integers in units of 1/_QUANT DN: every window
# sum of the matcher is then exact in float32, whatever the band split of the rows.
_QUANT = 4.0


@dataclass(frozen=True)
class DisparityResult:
    """Output of a matcher for one rectified pair.

    Attributes
    ----------
    disparity_px : ndarray, float32, shape (H, W)
        Left-image disparity (left column minus right column) in pixels; NaN = invalid.
    invalid_reason : ndarray, uint8, shape (H, W)
        0 for valid pixels, else the first filter that rejected the pixel
        (:class:`slitcli.stereo.reasons.Reason` codes).
    match_cost : ndarray, float32, shape (H, W) or None
        Eq. 10 cost of the winning disparity (``nssd`` only; +inf where none).
    """

    disparity_px: np.ndarray
    invalid_reason: np.ndarray
    match_cost: np.ndarray | None = None

    @property
    def valid(self) -> np.ndarray:
        """Boolean (H, W) mask of valid pixels."""
        return self.invalid_reason == Reason.VALID


def to_grey(image: np.ndarray) -> np.ndarray:
    """BGR (H, W, 3) or grey (H, W) uint8 image to grey uint8 (H, W)."""
    img = np.asarray(image)
    if img.ndim == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.ndim == 2:
        return img
    raise SlitcliError(f"image of shape {img.shape} is neither grey (H, W) nor BGR (H, W, 3)")


#: luma weights (ITU-R BT.601, OpenCV's BGR -> grey) in BGR order
_LUMA_BGR = np.array([0.114, 0.587, 0.299], np.float32)


def colour_matching_image(bgr: np.ndarray, window_w_px: int, window_h_px: int,
                          noise: ChannelNoise) -> np.ndarray:
    """The grey image the Eq. 10 cost is computed on for a noisy colour camera, float32
    (H, W), DN: per pixel, the colour channels weighted for the texture's
    signal-to-noise ratio.

    Model: a surface's texture is a modulation of its reflectance (albedo, shading), so
    it moves every channel by the same share of the channel's level ``mu_c`` (in linear
    light, and so too after a power-law tone curve: ``d out / out = d in / (gamma in)``);
    each channel carries its own noise variance ``v_c(mu_c)``, which through a camera
    differs by channel and level (estimated from the pair's matches,
    slitcli.stereo.noise.estimate_channel_noise). The channels' noises taken as
    independent, the combination with the largest texture-to-noise ratio weights
    channel c by ``mu_c / v_c`` (a matched filter); ``mu_c`` is the channel's mean over
    the matching window around the pixel, ``v_c`` its noise at that level plus the 8-bit
    rounding's 1/12 DN^2. On a red surface the texture lives in the red channel, which
    luma weights by 0.3 while it takes 0.7 of the green and blue channels' noise.

    The weights are normalised to sum 1 and act on each channel's departure from its
    window mean; the window means enter with the luma weights, so a flat region keeps
    its luma level (the prefilter removes that part anyway).

    Parameters
    ----------
    bgr : ndarray, uint8, shape (H, W, 3)
        Rectified BGR image.
    window_w_px, window_h_px : int
        The matching window (odd), over which the levels are taken.
    noise : ChannelNoise
        The pair's noise per channel and level.

    Returns
    -------
    ndarray, float32, shape (H, W)
    """
    k = (int(window_w_px), int(window_h_px))
    area = k[0] * k[1]
    img = np.asarray(bgr, np.uint8)
    num = np.zeros(img.shape[:2], np.float32)
    total = np.zeros_like(num)
    level = np.zeros_like(num)
    # window sums of 8-bit levels are whole numbers: the weight mu / v is tabled per sum
    sums = np.arange(area * 255 + 1, dtype=np.float64)
    for c in range(3):
        x = np.ascontiguousarray(img[..., c])
        window_sum = cv2.boxFilter(x, cv2.CV_32S, k, normalize=False,
                                   borderType=cv2.BORDER_REFLECT_101)
        mu_table = sums / area
        w_table = (mu_table / (noise.variance_at(c, mu_table) + 1.0 / 12.0)).astype(np.float32)
        w = w_table[window_sum]
        mu = window_sum.astype(np.float32) * np.float32(1.0 / area)
        num += w * (x - mu)
        total += w
        level += _LUMA_BGR[c] * mu
    # a black window (all levels 0) has no texture to weigh, nor any departure from it
    return (np.divide(num, total, out=np.zeros_like(num), where=total > 0) + level
            ).astype(np.float32)


def gaussian_noise_factor(sigma_px: float, rho_x: float, rho_y: float,
                          rho_diag: float) -> float:
    """Noise variance left by :func:`smooth_image` of ``sigma_px``, over the input's.

    For a separable kernel ``g x g`` and noise correlated at lag 1 only (correlations
    ``rho_x``, ``rho_y`` to the next column and row, ``rho_diag`` to the diagonal
    neighbours): ``A^2 + 2 (rho_x + rho_y) A B + 4 rho_diag B^2`` with ``A = sum g_i^2``,
    ``B = sum g_i g_(i+1)``; 1 at ``sigma_px`` 0.
    """
    if sigma_px <= 0:
        return 1.0
    g = _gaussian_kernel(sigma_px)
    a = float(np.sum(g * g))
    b = float(np.sum(g[:-1] * g[1:]))
    return a * a + 2.0 * (rho_x + rho_y) * a * b + 4.0 * rho_diag * b * b


def smoothing_sigma_px(sigma_dn: float, rho_x: float, rho_y: float, rho_diag: float,
                       ref_dn: float, max_sigma_px: float) -> float:
    """The least Gaussian low-pass (sigma, px) that brings noise of ``sigma_dn`` (with
    its lag-1 correlations) down to ``ref_dn``, the noise the matcher's thresholds were
    set at; at most ``max_sigma_px``, 0 when the noise is already at or below it.

    The texture a window matches lies mostly at scales of several pixels, the camera's
    noise at one to two (a pixel's noise is shared only with its next neighbours), so
    a low-pass takes off more noise than texture; blurring further than the noise
    requires would take texture for no gain in the tests' noise margins.
    """
    target = (ref_dn / sigma_dn) ** 2 if sigma_dn > 0 else 1.0
    if target >= 1.0:
        return 0.0
    factor = lambda s: gaussian_noise_factor(s, rho_x, rho_y, rho_diag)  # noqa: E731
    if factor(max_sigma_px) > target:
        return float(max_sigma_px)
    lo, hi = 0.0, float(max_sigma_px)
    for _ in range(30):  # the factor falls monotonically with sigma
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if factor(mid) > target else (lo, mid)
    return hi


def smooth_image(grey: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian low-pass of ``sigma_px`` (float32, mirrored borders; the kernel of
    :func:`gaussian_noise_factor`)."""
    g = _gaussian_kernel(sigma_px)
    return cv2.sepFilter2D(np.asarray(grey, np.float32), cv2.CV_32F, g, g,
                           borderType=cv2.BORDER_REFLECT_101)


def _gaussian_kernel(sigma_px: float) -> np.ndarray:
    """Normalised 1-D Gaussian reaching 3 sigma (float64)."""
    r = max(1, math.ceil(3.0 * sigma_px))
    t = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (t / sigma_px) ** 2)
    return g / g.sum()


def prefilter_image(grey: np.ndarray, params: MatcherParams) -> np.ndarray:
    """The image the Eq. 10 cost is computed on, float32 (H, W), in units of 1/4 DN.

    ``none`` returns the grey levels; ``mean`` subtracts the ``prefilter_size_px``
    box mean; ``xsobel`` is the horizontal 3x3 Sobel derivative in DN/px; ``log``
    is minus the Laplacian of a Gaussian of ``log_sigma_px``. Filtered values are
    clipped to +-``prefilter_cap_dn`` and rounded to 1/4 DN so every window sum of
    the matcher is exact.
    """
    from slitcli.stereo import _kernel

    g = np.asarray(grey, dtype=np.float32)
    kind = params.prefilter
    if kind == "none":
        return g
    if kind == "mean":
        k = params.prefilter_size_px
        response, smooth, sign = g, cv2.blur(g, (k, k), borderType=cv2.BORDER_REFLECT_101), 1.0
    elif kind == "xsobel":
        response = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3, scale=0.125,
                             borderType=cv2.BORDER_REFLECT_101)
        smooth, sign = response, 0.0
    else:
        blurred = cv2.GaussianBlur(g, (0, 0), params.log_sigma_px,
                                   borderType=cv2.BORDER_REFLECT_101)
        response = cv2.Laplacian(blurred, cv2.CV_32F, ksize=1, scale=-1.0,
                                 borderType=cv2.BORDER_REFLECT_101)
        smooth, sign = response, 0.0
    out = np.empty_like(g)
    _kernel.clip_quantise(response, smooth, np.float32(sign),
                          np.float32(params.prefilter_cap_dn), np.float32(_QUANT), out)
    return out


def ground_window_shifts(px_per_row: float, half_height_px: int) -> np.ndarray:
    """Right-column shifts of a window sheared by the ground plane's disparity gradient.

    On the ground (a plane below the camera, paper Eq. 8 with the floor depth) the
    disparity grows linearly down the image, ``d(v) = W cos(tilt) / h (v - v_h)`` below
    the horizon row ``v_h`` (W baseline, h camera height, no roll): ``px_per_row`` px
    more per row whatever the focal length. A window centred on a ground pixel of
    disparity d therefore finds its row ``dv`` in the right image ``px_per_row dv``
    further left than a fronto-parallel window assumes. The shift is rounded to whole
    pixels (half away from zero, so the window stays symmetric about its centre).

    Parameters
    ----------
    px_per_row : float
        Ground disparity gradient, px of disparity per image row (v down).
    half_height_px : int
        ``n``: the window has rows ``-n .. n``.

    Returns
    -------
    ndarray, int64, shape (2 n + 1,)
        Extra disparity (px) of window rows ``-n .. n``; all zeros where the gradient
        stays below half a pixel across the window's half height.
    """
    dv = np.arange(-half_height_px, half_height_px + 1)
    return (np.sign(dv) * np.floor(np.abs(dv) * float(px_per_row) + 0.5)).astype(np.int64)


def sheared_right_energies(pr: np.ndarray, m: int, n: int, shifts: np.ndarray,
                           pad: int) -> tuple[np.ndarray, np.ndarray]:
    """Window energies of the prefiltered right image over sheared windows.

    The sheared window of right column ``xr`` takes its row ``dv`` from columns
    ``xr - shifts[dv + n] - m .. xr - shifts[dv + n] + m`` (zeros outside the image);
    its energy is a function of ``xr`` alone (the left pixel's disparity moves the
    whole window), so it is one image like the fronto-parallel energies.

    Parameters
    ----------
    pr : ndarray, float32, shape (H, W)
        Prefiltered right image (whole numbers of 1/4 DN, so every sum is exact).
    m, n : int
        Window half width and half height, px.
    shifts : ndarray, int64, shape (2 n + 1,)
        :func:`ground_window_shifts`.
    pad : int
        Zero columns each side of the returned rows.

    Returns
    -------
    err_s, irr_s : ndarray, float32, shape (H, W + 2 pad)
        Energies and their inverse square roots (0 where no energy), along x reversed
        (column ``xr`` at ``pad + W - 1 - xr``), as the SGM cost kernels read them.
    """
    from slitcli.stereo._c.sgm import sheared_energies

    h, w = pr.shape
    err = np.zeros((h, w + 2 * pad), np.float32)
    irr = np.zeros((h, w + 2 * pad), np.float32)
    sheared_energies(np.ascontiguousarray(pr, np.float32), int(m), int(n),
                     np.ascontiguousarray(shifts, np.int64), int(pad), err, irr)
    return err, irr


def ground_shear_from_floor(floor_disparity_px: np.ndarray) -> tuple[float, float]:
    """The ground's disparity gradient and horizon row from the rig's floor disparities.

    Parameters
    ----------
    floor_disparity_px : ndarray, float32, shape (H, W)
        Disparity of the floor plane at each pixel, 0 above the horizon
        (``StereoGeometry.floor_disparity_px``).

    Returns
    -------
    px_per_row : float
        Disparity gain per image row down the middle column (linear below the
        horizon); 0 where the camera does not see the floor.
    horizon_row_px : float
        Row (px, v down) where the floor's disparity reaches 0 in that column.
    """
    col = np.asarray(floor_disparity_px, np.float64)[:, floor_disparity_px.shape[1] // 2]
    rows = np.flatnonzero(col > 0)
    if rows.size < 2:
        return 0.0, float(col.shape[0])
    v0, v1 = int(rows[0]), int(rows[-1])
    grad = (col[v1] - col[v0]) / (v1 - v0)
    if grad <= 0:
        return 0.0, float(col.shape[0])
    return float(grad), float(v0 - col[v0] / grad)


__all__ = ["DisparityResult", "colour_matching_image", "gaussian_noise_factor",
           "ground_shear_from_floor", "ground_window_shifts", "prefilter_image",
           "sheared_right_energies", "smooth_image", "smoothing_sigma_px", "to_grey"]
