"""The colour-order check: is an image given as BGR really RGB (paper Eq. 2 needs red)?

A red laser stripe read with red and blue swapped is blue, and Eq. 2's red chromaticity
rejects every column of it: the frame silently has no laser. :func:`check_colour_order`
(called by :class:`slitcli.detect.Detector`) measures the colour of the light a found
line adds (:func:`blue_line_z`) and refuses an image whose line is blue as given.
"""

from __future__ import annotations

import math

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.laser.frame import LaserFrame, LaserGeometry, detect_laser
from slitcli.laser.params import LaserParams
from slitcli.rig import Rig

#: rows of a JPEG 4:2:0 chroma block (8 chroma rows at half resolution): chroma
#: subsampling and the block's quantised AC terms move colour within it, keeping its sum
JPEG_CHROMA_BLOCK_ROWS = 16
#: a median's standard error over m samples of spread sigma is sqrt(pi / 2) sigma / sqrt(m)
MEDIAN_SE = 1.2533


def _band_and_sides(img: np.ndarray, stripe: LaserFrame, half_band_px: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per found column (M of them): the band's rows (M, 2 half_band_px + 1, 3) and the
    per-channel medians (M, 3) of the ``half_band_px + 1`` rows just above and just below
    it, float64, channel slots as given; rows beyond the image repeat its border rows."""
    h = img.shape[0]
    u = np.flatnonzero(stripe.found)
    v = np.rint(stripe.v_px[u]).astype(np.int64)
    band = np.arange(-half_band_px, half_band_px + 1)
    ring = np.arange(half_band_px + 1, 2 * half_band_px + 2)
    rows_band = np.clip(v[:, None] + band[None, :], 0, h - 1)
    band_mb3 = img[rows_band, u[:, None], :].astype(np.float64)
    sides = []
    for offsets in (-ring, ring):
        rows = np.clip(v[:, None] + offsets[None, :], 0, h - 1)
        sides.append(img[rows, u[:, None], :].astype(np.float64))
    return band_mb3, sides[0], sides[1]


def stripe_added_light(img_bgr: np.ndarray, stripe: LaserFrame, half_band_px: int
                       ) -> np.ndarray:
    """Light a found stripe adds to each of its columns, per channel, in the order given.

    The band of ``2 half_band_px + 1`` rows centred on the stripe row is summed after
    subtracting each column's background: the per-channel median of the
    ``half_band_px + 1`` rows just above and just below the band. Summing across the band
    (the stripe's flux, not its peak pixel) keeps the stripe's colour through what JPEG
    does to chroma (4:2:0 averaging and block ringing move colour a few rows, but keep its
    sum within the block), so a red line's blue fringe does not read as a blue line.
    Rows beyond the image repeat its border rows.

    Parameters
    ----------
    img_bgr : np.ndarray, shape (H, W, 3), uint8
        The image the stripe was searched in, channels in the order given.
    stripe : LaserFrame
        A stripe found in it (or in it with channels swapped): ``v_px`` per column.
    half_band_px : int
        Rows either side of the stripe row in the band, pixels.

    Returns
    -------
    np.ndarray, shape (M, 3), float
        Added light per found column (M = ``stripe.found.sum()``), channel slots as
        given, DN summed over the band's rows.
    """
    band_mb3, above_mr3, below_mr3 = _band_and_sides(np.asarray(img_bgr), stripe,
                                                      half_band_px)
    background_m3 = np.median(np.concatenate([above_mr3, below_mr3], axis=1), axis=1)
    return (band_mb3 - background_m3[:, None, :]).sum(axis=1)


def blue_line_z(img_bgr: np.ndarray, stripe: LaserFrame, params: LaserParams | None = None
                ) -> tuple[float, np.ndarray]:
    """How blue, in the order given, the light a found line adds is: a z score.

    The added light of each found column over a band of the widest stripe's width and at
    least half a JPEG chroma block either side (as :func:`stripe_added_light` sums it),
    first slot minus last slot, read twice: against the surface just above the band and
    against the surface just below it. A column counts what both readings agree on (the
    smaller of the two where they have one sign, else nothing): where the band spans the
    border of two surfaces (a blue object's foot on a brown floor), against either
    surface alone the other one reads as added light of its own colour, with opposite
    signs on the two sides; a line's own light reads the same against both. The median
    over the columns divided by the median's standard error (from the columns' own
    robust spread, floored by the image's noise). A red laser read in the right order
    scores far below zero, read from an RGB image far above.

    Returns
    -------
    z : float
        The median first-minus-last added light over its standard error.
    added_m3 : np.ndarray, shape (M, 3), float
        The added light per found column (DN summed over the band, against both sides'
        rows), slots as given.
    """
    img = np.asarray(img_bgr)
    laser = params if params is not None else LaserParams()
    half_band = max(math.ceil(laser.max_width_px(img.shape[0])), JPEG_CHROMA_BLOCK_ROWS // 2)
    band_mb3, above_mr3, below_mr3 = _band_and_sides(img, stripe, half_band)
    band_m3 = band_mb3.sum(axis=1)
    rows = band_mb3.shape[1]
    readings = [band_m3 - rows * np.median(side, axis=1) for side in (above_mr3, below_mr3)]
    a, b = (r[:, 0] - r[:, 2] for r in readings)
    blue_excess = np.where(a * b > 0, np.sign(a) * np.minimum(np.abs(a), np.abs(b)), 0.0)
    centre = float(np.median(blue_excess))
    # the columns' spread holds texture, speckle and compression; the floor is the
    # noise of a difference of two channels summed over the band's rows
    spread = max(1.4826 * float(np.median(np.abs(blue_excess - centre))),
                 stripe.noise_sigma_dn * math.sqrt(2.0 * rows))
    # (stripe_added_light's reading, from the rows gathered above)
    added_m3 = band_m3 - rows * np.median(np.concatenate([above_mr3, below_mr3], axis=1),
                                          axis=1)
    return centre / (MEDIAN_SE * spread / math.sqrt(len(blue_excess))), added_m3


def check_colour_order(left_bgr: np.ndarray, found: LaserFrame, rig: Rig,
                       params: LaserParams | None = None, *,
                       geometry: LaserGeometry | None = None, min_cols: int = 16,
                       margin_z: float = 4.0) -> bool:
    """Raise when an image given as BGR is really RGB (its stripe is in the blue slot).

    A red laser stripe read with red and blue swapped is blue, and Eq. 2's red
    chromaticity rejects every column of it: the frame silently has no laser. The
    evidence is the colour of the light a found line adds, measured in the image as given
    (:func:`blue_line_z`): a red laser adds light whose last slot (red, BGR) is far above
    its first; read from an RGB image it is the reverse. The order is called swapped when
    that line's first-minus-last added light exceeds ``margin_z`` standard errors.

    - When the stripe found in ``left_bgr`` (``found``) has at least ``min_cols`` columns
      (two of the extractor's shortest segments, 8 columns each), its own added light
      is measured: a stray line found in an RGB image (a red object's edge, seen blue)
      is refused too.
    - When it has fewer than ``min_cols / 2`` columns, the stripe is searched again with
      the first and last channels swapped; finding at least ``min_cols`` columns there,
      four times as many as given, is the precondition for measuring that line. A line
      the swapped search finds next to a red stripe (its JPEG chroma fringe, a red
      object's edge) adds red light as given and passes. A scene without any lit
      obstacle or floor in view costs one more extraction and passes.

    Returns
    -------
    bool
        True when the frame settles the question: the stripe was found as given in at
        least ``min_cols`` columns and adds red light (the order is right).

    Raises
    ------
    SlitcliError
        ``param="colour_order"``, naming both counts and the added light.
    """
    img = np.asarray(left_bgr)
    n = int(found.found.sum())
    if n >= min_cols:
        line, m = found, n
    elif 2 * n >= min_cols:
        return False
    else:
        line = detect_laser(np.ascontiguousarray(img[..., ::-1]), rig, params,
                            geometry=geometry)
        m = int(line.found.sum())
        if m < min_cols or m < 4 * max(n, 1):
            return False
    z, added_m3 = blue_line_z(img, line, params)
    if z <= margin_z:
        return line is found
    blue, red = np.median(added_m3[:, 0]), np.median(added_m3[:, 2])
    where = ("as given" if line is found
             else f"with red and blue swapped, {n} as given")
    raise SlitcliError(
        f"the image looks like RGB, not BGR: the line found adds {blue:.0f} DN to the "
        f"first channel and {red:.0f} DN to the last ({m} stripe columns {where}); set "
        "`colour_order` to 'rgb' or convert it with cv2.cvtColor(image, cv2.COLOR_RGB2BGR)",
        param="colour_order")


# --save-images: 16-bit data images, the obstacle mask, and colour previews with a bar


__all__ = ["blue_line_z", "check_colour_order", "stripe_added_light"]
