"""What the Eq. 10 cost is computed on (grey and prefiltered images) and the matchers'
common result type: shared by the local matcher and SGM, so neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.stereo.reasons import Reason

if TYPE_CHECKING:
    from slitcli.stereo.matcher import MatcherParams

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


__all__ = ["DisparityResult", "prefilter_image", "to_grey"]
