"""Colour previews of disparity and distance images, with a colour bar (OpenCV only).

The 16-bit data files (``disparity/``, ``distance/``, docs/stereo.md) look black in an
image viewer: their values fill only the bottom of the 16-bit scale. A preview maps
the values linearly onto the turbo colour map between ``vmin`` and ``vmax`` (values
outside are clipped to the ends), paints invalid pixels black, and appends a vertical
colour bar labelled in the quantity's unit. Previews are for eyes, never for reading
values back: the data files stay the reference.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from slitcli.errors import SlitcliError

INVALID_BGR = (0, 0, 0)


def turbo_bgr(values: np.ndarray, vmin: float, vmax: float) -> np.ndarray:
    """Map values linearly to turbo colours: ``vmin`` -> dark blue, ``vmax`` -> dark red.

    Parameters
    ----------
    values : ndarray (...,) float
        Finite values (non-finite map like ``vmin``; mask them yourself).
    vmin, vmax : float
        The ends of the scale, ``vmin < vmax``.

    Returns
    -------
    ndarray (..., 3) uint8, BGR
    """
    v = np.asarray(values, dtype=np.float32)
    level = (v - np.float32(vmin)) * np.float32(255.0 / (vmax - vmin))
    np.nan_to_num(level, copy=False, nan=0.0, posinf=255.0, neginf=0.0)
    np.clip(level, 0.0, 255.0, out=level)
    index = (level + 0.5).astype(np.uint8)  # round half up: 0..255
    # OpenCV's table lookup in C: a tenth of numpy's fancy indexing on a 320 x 240 image
    bgr = cv2.applyColorMap(index.reshape(-1, 1), cv2.COLORMAP_TURBO)
    return bgr.reshape(*v.shape, 3)


def colour_preview(values: np.ndarray, *, vmin: float, vmax: float, unit: str,
                   label: str = "", valid: np.ndarray | None = None,
                   bar_width_px: int = 72) -> np.ndarray:
    """A colour image of ``values`` with a labelled colour bar on its right.

    Parameters
    ----------
    values : ndarray (H, W) float
        E.g. disparity in px or depth along the optical axis in m.
    vmin, vmax : float
        Value range of the colour scale (clipped outside), in ``unit``.
    unit : str
        Unit written on the bar (``px``, ``m``).
    label : str
        Quantity written above the bar's ticks (``disparity``, ``distance``).
    valid : ndarray (H, W) bool, optional
        Pixels to colour; default: finite and positive values. Others are black.
    bar_width_px : int
        Width of the bar and its tick labels, px.

    Returns
    -------
    ndarray (H, W + bar_width_px, 3) uint8, BGR
        Column ``W + 2 .. W + 11`` of row ``y`` holds the colour of
        ``vmax - (y - top) / (bottom - top) * (vmax - vmin)`` (the bar's scale).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or min(v.shape) < 1:
        raise SlitcliError(f"values: need a 2-D image, got shape {v.shape}")
    if not (math.isfinite(vmin) and math.isfinite(vmax) and vmin < vmax):
        raise SlitcliError(f"vmin {vmin} / vmax {vmax}: need finite numbers with vmin < vmax")
    ok = np.isfinite(v) & (v > 0) if valid is None else np.asarray(valid, dtype=bool)
    img = turbo_bgr(v, vmin, vmax)
    img[~ok] = INVALID_BGR
    return np.concatenate([img, colour_bar(v.shape[0], vmin=vmin, vmax=vmax, unit=unit,
                                           label=label, width_px=bar_width_px)], axis=1)


def bar_rows(height_px: int) -> tuple[int, int]:
    """First and last row of the colour strip in a bar of ``height_px`` rows."""
    top = min(max(height_px // 12, 8), height_px // 3)
    return top, max(height_px - top - 1, top + 1)


def colour_bar(height_px: int, *, vmin: float, vmax: float, unit: str, label: str = "",
               width_px: int = 64) -> np.ndarray:
    """A vertical turbo colour bar, ``vmax`` at the top, with 3-5 labelled ticks.

    Returns
    -------
    ndarray (height_px, width_px, 3) uint8, BGR; white background.
    """
    bar = np.full((height_px, width_px, 3), 255, dtype=np.uint8)
    top, bottom = bar_rows(height_px)
    rows = np.arange(top, bottom + 1)
    vals = vmax - (rows - top) / (bottom - top) * (vmax - vmin)
    bar[top:bottom + 1, 2:12] = turbo_bgr(vals, vmin, vmax)[:, None, :]
    scale = max(0.25, min(0.4, height_px / 600))
    font = cv2.FONT_HERSHEY_SIMPLEX
    for t in nice_ticks(vmin, vmax):
        y = round(top + (vmax - t) / (vmax - vmin) * (bottom - top))
        cv2.line(bar, (12, y), (15, y), (0, 0, 0), 1)
        cv2.putText(bar, f"{t:g}", (17, y + 4), font, scale, (0, 0, 0), 1, cv2.LINE_AA)
    text = f"{label} ({unit})" if label else unit
    cv2.putText(bar, text, (1, max(top - 3, 7)), font, scale * 0.9, (0, 0, 0), 1, cv2.LINE_AA)
    return bar


def nice_ticks(vmin: float, vmax: float) -> np.ndarray:
    """Round tick values inside ``[vmin, vmax]``: 3-6 multiples of 1, 2 or 5 x 10^k."""
    span = vmax - vmin
    raw = span / 4
    mag = 10.0 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    first = math.ceil(vmin / step - 1e-9) * step
    ticks = np.arange(first, vmax + step * 1e-6, step)
    return np.round(ticks, 10)


def disparity_preview(disparity_px: np.ndarray, *, max_disparity_px: float) -> np.ndarray:
    """Colour preview of a disparity image (px, 0 or NaN = invalid), 0..max px."""
    return colour_preview(disparity_px, vmin=0.0, vmax=max_disparity_px, unit="px",
                          label="disparity")


def distance_preview(depth_m: np.ndarray, *, max_range_m: float) -> np.ndarray:
    """Colour preview of a distance image (m, 0 or NaN = invalid), 0..max m."""
    return colour_preview(depth_m, vmin=0.0, vmax=max_range_m, unit="m", label="distance")


__all__ = ["colour_bar", "colour_preview", "disparity_preview", "distance_preview",
           "nice_ticks", "turbo_bgr"]
