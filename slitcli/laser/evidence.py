"""Step 1 of the stripe model: the laser evidence per pixel and the image's noise.

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

A pixel is clipped where any channel reaches its clipping level (its colour, and so its
evidence, is then wrong): ``saturation_dn``, or lower where the image shows a channel
clipping below it (:func:`clip_levels`: white balance and tone curves clip green or blue
at 230-240 on some cameras, and render a clipped laser core white there).

Images come transposed, ``(W, H, 3)`` BGR uint8 (one image column per array row).

The kernels are compiled ahead of time (Cython, :mod:`slitcli.laser._c.evidence`) and
re-exported here; that module also holds the constants the kernels use
(``CHI2_2_MEDIAN``, ``MAD_TO_SIGMA``, ``MEDIAN_BINS``), re-exported as well.
"""

from __future__ import annotations

import cv2
import numpy as np

from slitcli.laser._c.evidence import (
    CHI2_2_MEDIAN,
    MAD_TO_SIGMA,
    MEDIAN_BINS,
    _median,
    channel_sigma,
    laser_evidence,
    robust_sigma,
    spread_sigma,
    texture_share,
    vertical_opening,
)

#: every NOISE_STEP-th column enters the noise estimates
NOISE_STEP = 4
#: a channel's values pile up at its clipping level: at least CLIP_PILE_PX
#: pixels within CLIP_TOP_DN of its largest value, twice as many as in the CLIP_TOP_DN
#: below those (a smooth histogram tail thins out towards its end)
CLIP_TOP_DN = 3
CLIP_PILE_PX = 10
#: clipping levels below this are not looked for (a plain surface piles up too)
CLIP_MIN_DN = 200


def clip_levels(img_bgr: np.ndarray, saturation_dn: int) -> tuple[int, int, int]:
    """The level at which each channel of an image clips, (b, g, r) DN.

    ``saturation_dn``, or the lowest value of a pile-up at the top of the channel's
    histogram where that lies between ``CLIP_MIN_DN`` and ``saturation_dn``.

    Parameters
    ----------
    img_bgr : ndarray, uint8, shape (H, W, 3)
        The image (BGR).
    saturation_dn : int
        The clipping level when the image shows none lower, DN.
    """
    x = np.ascontiguousarray(img_bgr)
    tops = cv2.reduce(cv2.reduce(x, 0, cv2.REDUCE_MAX), 1, cv2.REDUCE_MAX).ravel()
    levels = []
    for c in range(3):
        top = int(tops[c])
        lo = top - CLIP_TOP_DN + 1
        if not CLIP_MIN_DN <= lo < saturation_dn:
            # at saturation_dn or above, or too low to be a clip: no histogram needed
            levels.append(int(saturation_dn))
            continue
        hist = cv2.calcHist([x], [c], None, [256], [0, 256]).ravel()
        n_top = float(hist[max(lo, 0):top + 1].sum())
        n_below = float(hist[max(lo - CLIP_TOP_DN, 0):max(lo, 0)].sum())
        pile = n_top >= CLIP_PILE_PX and n_top >= 2 * n_below
        levels.append(lo if pile else int(saturation_dn))
    return levels[0], levels[1], levels[2]

__all__ = ["CHI2_2_MEDIAN", "MAD_TO_SIGMA", "MEDIAN_BINS", "NOISE_STEP", "_median",
           "channel_sigma", "clip_levels", "laser_evidence", "robust_sigma", "spread_sigma",
           "texture_share", "vertical_opening"]
