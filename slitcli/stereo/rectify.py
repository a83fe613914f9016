"""Rectification of raw (unrectified) stereo pairs with the rig's ``raw`` calibration.

A rig whose ``raw`` block is set (written by ``slitcli calibrate``) describes cameras
with lens distortion and a relative rotation; ``R1``, ``R2``, ``P1``, ``P2`` from
:func:`cv2.stereoRectify` map them onto the rectified pair that the rest of the rig
(``left``, ``baseline_m``, ``image_size_px``) describes. The remap tables depend only
on the calibration, so they are computed once per calibration and reused (a small
memo keyed by the frozen calibration; the returned tables are read-only).
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.rig import RawCalibration, Rig


@functools.lru_cache(maxsize=8)
def rectification_maps(raw: RawCalibration, size_px: tuple[int, int]
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Fixed-point remap tables for the left and right raw images.

    Parameters
    ----------
    raw : RawCalibration
        Unrectified calibration (OpenCV conventions).
    size_px : (width, height)
        Size of the rectified images (the rig's ``image_size_px``).

    Returns
    -------
    left_map1, left_map2, right_map1, right_map2 : ndarray
        :func:`cv2.initUndistortRectifyMap` tables (CV_16SC2 + CV_16UC1), read-only.
    """
    from slitcli.calibrate.rectify import undistort_rectify_map

    out = []
    for camera in ("left", "right"):
        # either lens model (pinhole or equidistant: cv2.fisheye)
        m1, m2 = undistort_rectify_map(raw, camera, size_px, cv2.CV_16SC2)
        m1.setflags(write=False)
        m2.setflags(write=False)
        out += [m1, m2]
    return out[0], out[1], out[2], out[3]


def rectify_pair(left: np.ndarray, right: np.ndarray, rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Rectify a raw pair with ``rig.raw``; a rig without ``raw`` returns the inputs.

    Parameters
    ----------
    left, right : ndarray, uint8, (H, W, 3) or (H, W)
        Raw images of size ``rig.raw.image_size_px`` (or, without ``raw``, already
        rectified images of size ``rig.image_size_px``).

    Returns
    -------
    left_rect, right_rect : ndarray
        Rectified images of size ``rig.image_size_px`` (bilinear interpolation).

    Raises
    ------
    SlitcliError
        If an image does not have the size the rig expects.
    """
    want = tuple(rig.raw.image_size_px if rig.raw is not None else rig.image_size_px)
    key = "raw.image_size_px" if rig.raw is not None else "image_size_px"
    for name, img in (("left", left), ("right", right)):
        got = (int(img.shape[1]), int(img.shape[0]))
        if got != want:
            raise SlitcliError(f"{name} image is {got[0]}x{got[1]} but the rig's {key} is "
                               f"{want[0]}x{want[1]}; use the rig these images were taken "
                               "with (--rig)")
    if rig.raw is None:
        return left, right
    lm1, lm2, rm1, rm2 = rectification_maps(rig.raw, tuple(rig.image_size_px))
    return (cv2.remap(left, lm1, lm2, cv2.INTER_LINEAR),
            cv2.remap(right, rm1, rm2, cv2.INTER_LINEAR))
