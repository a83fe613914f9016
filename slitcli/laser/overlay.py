"""Fig. 4-style overlay: the detected stripe drawn on the left image, ranges annotated.

Drawn with OpenCV only (no matplotlib in the core).
"""

from __future__ import annotations

import cv2
import numpy as np

from slitcli.laser.frame import LaserFrame

IN_BAND_BGR = (0, 255, 0)  # green: inside the rig's laser band
OUT_BAND_BGR = (0, 215, 255)  # amber: found, outside the band
_SCALE = 2  # drawn at twice the image size so that the labels are legible
_MIN_LABEL_COLS = 8  # segments shorter than this are drawn but not labelled


def _segments(frame: LaserFrame, max_jump_px: float) -> list[tuple[int, int]]:
    """(first, last) column of each run of found columns joined by small row steps."""
    found = frame.found
    step = np.abs(np.diff(frame.v_px))
    joined = found[1:] & found[:-1] & (step <= max_jump_px)
    starts = np.flatnonzero(found & np.r_[True, ~joined])
    ends = np.flatnonzero(found & np.r_[~joined, True])
    return list(zip(starts.tolist(), ends.tolist(), strict=True))


def draw_overlay(left_bgr: np.ndarray, frame: LaserFrame, *, max_jump_px: float = 3.0,
                 title: str | None = None) -> np.ndarray:
    """Return a BGR image (2x the input size) with the stripe and its ranges drawn.

    Each stripe segment is drawn as a polyline through its sub-pixel rows (green
    inside the rig's laser band, amber outside) and labelled with its median
    forward distance (sensor x) in metres, as in the paper's Fig. 4.

    Parameters
    ----------
    left_bgr : ndarray, shape (H, W, 3), uint8
    frame : LaserFrame
        The detection for this image.
    max_jump_px : float
        Row step that splits segments, pixels.
    title : str, optional
        Text drawn in the top-left corner (e.g. the frame name).
    """
    s = _SCALE
    img = cv2.resize(np.asarray(left_bgr), None, fx=s, fy=s, interpolation=cv2.INTER_NEAREST)
    font = cv2.FONT_HERSHEY_SIMPLEX
    for first, last in _segments(frame, max_jump_px):
        cols = np.arange(first, last + 1)
        # pixel centre (u, v) maps to ((u + 0.5) s - 0.5, ...) in the enlarged image
        pts = np.stack([(cols + 0.5) * s - 0.5, (frame.v_px[cols] + 0.5) * s - 0.5], axis=1)
        band = np.mean(frame.in_band[cols]) >= 0.5
        colour = IN_BAND_BGR if band else OUT_BAND_BGR
        poly = np.rint(pts * 4).astype(np.int32).reshape(-1, 1, 2)  # 2 fractional bits
        cv2.polylines(img, [poly], False, colour, 2, cv2.LINE_AA, shift=2)
        if last - first + 1 < _MIN_LABEL_COLS:
            continue
        dist = float(np.nanmedian(frame.x_m[cols]))
        label = f"{dist:.2f} m"
        (tw, th), _ = cv2.getTextSize(label, font, 0.5, 1)
        cx = int(np.clip(np.mean(pts[:, 0]) - tw / 2, 2, img.shape[1] - tw - 2))
        cy = int(np.clip(np.min(pts[:, 1]) - 8, th + 2, img.shape[0] - 2))
        cv2.putText(img, label, (cx, cy), font, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(img, label, (cx, cy), font, 0.5, colour, 1, cv2.LINE_AA)
    if title:
        cv2.putText(img, title, (6, 18), font, 0.5, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(img, title, (6, 18), font, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    return img
