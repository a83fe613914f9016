"""The image files the tool writes: disparity, distance and obstacle-mask PNGs.

- disparity: uint16, ``round(disparity_px * 256)``, 0 = invalid (the KITTI convention);
- distance: uint16, depth along the optical axis in millimetres, 0 = invalid or beyond
  65.535 m (the ROS ``16UC1`` depth convention);
- mask: uint8, 255 = obstacle pixel, 0 = floor, free or invalid.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slitcli.errors import SlitcliError


def encode_disparity_png(disparity_px: np.ndarray) -> np.ndarray:
    """KITTI convention: uint16 = round(disparity * 256), 0 = invalid.

    Parameters
    ----------
    disparity_px : ndarray, shape (H, W), float
        Pixels, NaN or <= 0 = invalid.
    """
    d = np.where(np.isfinite(disparity_px) & (disparity_px > 0), disparity_px, 0.0)
    return np.clip(np.rint(d * 256.0), 0, 65535).astype(np.uint16)


def encode_depth_png(depth_m: np.ndarray) -> np.ndarray:
    """ROS 16UC1 convention: uint16 millimetres, 0 = invalid (beyond 65.535 m too).

    Parameters
    ----------
    depth_m : ndarray, shape (H, W), float
        Metres along the optical axis, NaN or <= 0 = invalid.
    """
    mm = np.where(np.isfinite(depth_m) & (depth_m > 0), np.rint(depth_m * 1000.0), 0.0)
    return np.where(mm <= 65535, mm, 0).astype(np.uint16)


def encode_mask_png(obstacle_mask: np.ndarray) -> np.ndarray:
    """uint8, 255 = obstacle pixel (``obstacle_mask`` (H, W) bool)."""
    return np.where(obstacle_mask, np.uint8(255), np.uint8(0))


def png_bytes(path: Path, image: np.ndarray) -> bytes:
    """``image`` encoded as PNG (``path`` only names the target in the error)."""
    import cv2

    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise SlitcliError(f"{path}: OpenCV could not encode the image as PNG")
    return buf.tobytes()


__all__ = ["encode_depth_png", "encode_disparity_png", "encode_mask_png", "png_bytes"]
