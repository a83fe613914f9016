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

Images come transposed, ``(W, H, 3)`` BGR uint8 (one image column per array row).

The kernels are compiled ahead of time (Cython, :mod:`slitcli.laser._c.evidence`) and
re-exported here; that module also holds the constants the kernels use
(``CHI2_2_MEDIAN``, ``MAD_TO_SIGMA``, ``MEDIAN_BINS``), re-exported as well.
"""

from __future__ import annotations

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

__all__ = ["CHI2_2_MEDIAN", "MAD_TO_SIGMA", "MEDIAN_BINS", "NOISE_STEP", "_median",
           "channel_sigma", "laser_evidence", "robust_sigma", "spread_sigma",
           "texture_share", "vertical_opening"]
