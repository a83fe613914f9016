"""From a raw (distorted, unrectified) stereo calibration to the rectified rig, and back.

The rig (DESIGN §12) describes the *rectified* pair: ``rig.left`` is the rectified left
camera (from ``P1``), ``rig.baseline_m = -P2[0,3] / P2[0,0]``, and the rig's camera frame
(laser plane, mount) is the rectified left camera frame, which differs from the raw left
camera frame by the rotation ``R1`` about the same optical centre. The raw calibration
is kept in ``rig.raw`` so that raw input images can be rectified.

Rectification uses :func:`cv2.stereoRectify` with ``CALIB_ZERO_DISPARITY`` and
``alpha = 0`` by default: the rectified image (same size as the raw one) shows only
valid pixels, so no black borders reach stereo matching or the laser extraction.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.rig import Intrinsics, RawCalibration, Rig, paper_rig


def _freeze(a: np.ndarray) -> tuple:
    a = np.asarray(a, dtype=float)
    return tuple(_freeze(x) for x in a) if a.ndim > 1 else tuple(float(x) for x in a)


def rectify_raw(K1: np.ndarray, D1: np.ndarray, K2: np.ndarray, D2: np.ndarray,
                image_size_px: tuple[int, int], R: np.ndarray, T: np.ndarray, *,
                alpha: float = 0.0, source: str = "calibration",
                model: str = "pinhole") -> RawCalibration:
    """Run :func:`cv2.stereoRectify` and bundle everything as a :class:`RawCalibration`.

    Parameters
    ----------
    K1, K2 : (3, 3) camera matrices, pixels.
    D1, D2 : (N,) OpenCV distortion (k1, k2, p1, p2[, k3[, k4, k5, k6]]).
    image_size_px : (width, height) of the raw images.
    R, T : (3, 3), (3,) pose of the right camera, ``X_right = R X_left + T`` (metres).
    alpha : free scaling of :func:`cv2.stereoRectify` (0: only valid pixels); for the
        equidistant model the ``balance`` of :func:`cv2.fisheye.stereoRectify`.
    source : what to name in error messages.
    model : ``pinhole`` or ``equidistant`` (D1, D2 are then k1 k2 k3 k4).

    Raises
    ------
    SlitcliError
        If the right camera is not to the right of the left one (swapped inputs) or
        the pair is stacked vertically.
    """
    K1, K2, R = (np.asarray(a, dtype=float).reshape(3, 3) for a in (K1, K2, R))
    D1, D2 = (np.asarray(a, dtype=float).ravel() for a in (D1, D2))
    T = np.asarray(T, dtype=float).ravel()
    if T.shape != (3,) or not np.all(np.isfinite(T)) or np.linalg.norm(T) <= 0:
        raise SlitcliError(f"{source}: translation T = {T.tolist()} is not a valid baseline; "
                           "give the right camera's position (metres, 3 values, not all zero)")
    if abs(T[1]) > abs(T[0]) or abs(T[2]) > abs(T[0]):
        raise SlitcliError(f"{source}: the cameras are not side by side (T = "
                           f"{np.round(T, 4).tolist()} m); slitcli needs a horizontal pair")
    if T[0] > 0:
        raise SlitcliError(f"{source}: the right camera is to the left of the left camera "
                           f"(T[0] = {T[0]:+.4f} m); swap the left and right inputs")
    size = (int(image_size_px[0]), int(image_size_px[1]))
    if model == "equidistant":
        if D1.size != 4 or D2.size != 4:
            raise SlitcliError(f"{source}: the equidistant model has 4 coefficients (k1 k2 k3 "
                               f"k4), found {D1.size} and {D2.size}; fix the file")
        R1, R2, P1, P2, _q = cv2.fisheye.stereoRectify(
            K1, D1.reshape(4, 1), K2, D2.reshape(4, 1), size, R, T.reshape(3, 1),
            cv2.CALIB_ZERO_DISPARITY, newImageSize=size, balance=alpha, fov_scale=1.0)
    elif model == "pinhole":
        R1, R2, P1, P2, _q, _r1, _r2 = cv2.stereoRectify(
            K1, D1, K2, D2, size, R, T.reshape(3, 1), flags=cv2.CALIB_ZERO_DISPARITY,
            alpha=alpha, newImageSize=size)
    else:
        raise SlitcliError(f"{source}: lens model '{model}' is not supported; slitcli reads "
                           "pinhole and equidistant")
    return RawCalibration(image_size_px=size, K1=_freeze(K1), D1=_freeze(D1), K2=_freeze(K2),
                          D2=_freeze(D2), R=_freeze(R), T=_freeze(T), R1=_freeze(R1),
                          R2=_freeze(R2), P1=_freeze(P1), P2=_freeze(P2), model=model)


def undistort_rectify_map(raw: RawCalibration, camera: str, size_px: tuple[int, int],
                          m1type: int = cv2.CV_32FC1) -> tuple[np.ndarray, np.ndarray]:
    """Raw -> rectified remap tables of one camera (``left`` or ``right``), either model.

    :func:`cv2.initUndistortRectifyMap` for ``pinhole``,
    :func:`cv2.fisheye.initUndistortRectifyMap` for ``equidistant``.
    """
    k, d, r, p = ("K1", "D1", "R1", "P1") if camera == "left" else ("K2", "D2", "R2", "P2")
    size = (int(size_px[0]), int(size_px[1]))
    if raw.model == "equidistant":
        return cv2.fisheye.initUndistortRectifyMap(raw.array(k), raw.array(d).reshape(4, 1),
                                                   raw.array(r), raw.array(p), size, m1type)
    return cv2.initUndistortRectifyMap(raw.array(k), raw.array(d), raw.array(r), raw.array(p),
                                       size, m1type)


def rig_with_raw(raw: RawCalibration, base: Rig | None = None, *, name: str | None = None,
                 source: str = "calibration") -> Rig:
    """The rectified rig of a raw calibration; mount, laser and limits from ``base``.

    ``rig.left`` comes from ``P1``, ``rig.baseline_m`` from ``P2``, ``image_size_px``
    is the raw size (the rectified images have the raw size).
    """
    base = base or paper_rig()
    P1, P2 = raw.array("P1"), raw.array("P2")
    if P1[0, 0] <= 0 or P2[0, 0] <= 0:
        raise SlitcliError(f"{source}: projection matrices P1/P2 have no positive focal "
                           "length; the rectification is invalid")
    baseline = -P2[0, 3] / P2[0, 0]
    if not baseline > 0:
        raise SlitcliError(f"{source}: the rectified right camera is not to the right "
                           f"(P2[0,3] = {P2[0, 3]:.4g}); swap the left and right inputs")
    if abs(P2[1, 3]) > 1e-6 * abs(P2[0, 3]):
        raise SlitcliError(f"{source}: P2[1,3] = {P2[1, 3]:.4g} describes a vertical "
                           "rectification; slitcli needs a horizontal pair")
    w, h = raw.image_size_px
    left = Intrinsics(fx_px=float(P1[0, 0]), fy_px=float(P1[1, 1]), cx_px=float(P1[0, 2]),
                      cy_px=float(P1[1, 2]))
    if not (0 <= left.cx_px <= w - 1 and 0 <= left.cy_px <= h - 1):
        raise SlitcliError(f"{source}: the rectified principal point ({left.cx_px:.1f}, "
                           f"{left.cy_px:.1f}) lies outside the {w}x{h} image; the "
                           "calibration is unusable (recalibrate with more varied views)")
    return replace(base, name=name or base.name, image_size_px=(int(w), int(h)), left=left,
                   baseline_m=float(baseline), raw=raw)


def ideal_raw(rig: Rig) -> RawCalibration:
    """The raw calibration of an already rectified rig (no distortion, no rotation)."""
    K = rig.left.K
    B = rig.baseline_m
    P1 = np.hstack([K, np.zeros((3, 1))])
    P2 = P1.copy()
    P2[0, 3] = -K[0, 0] * B
    eye = np.eye(3)
    return RawCalibration(image_size_px=tuple(int(v) for v in rig.image_size_px),
                          K1=_freeze(K), D1=_freeze(np.zeros(5)), K2=_freeze(K),
                          D2=_freeze(np.zeros(5)), R=_freeze(eye), T=_freeze([-B, 0.0, 0.0]),
                          R1=_freeze(eye), R2=_freeze(eye), P1=_freeze(P1), P2=_freeze(P2))


@dataclass(frozen=True, eq=False)
class RectificationMaps:
    """Remap tables raw -> rectified of one rig's two cameras (read-only).

    ``left_map1, left_map2`` (and the right ones) are :func:`cv2.initUndistortRectifyMap`
    (:func:`cv2.fisheye.initUndistortRectifyMap` for equidistant lenses) fixed-point
    tables (CV_16SC2 + CV_16UC1: positions to 1/32 px, what :func:`cv2.remap`
    interpolates with anyway), shape (H, W) of the rectified image
    ``rect_size_px``; ``raw_size_px`` is the size of the raw images they read.
    Built once per rig (:meth:`for_rig`) and passed along with it.
    """

    raw_size_px: tuple[int, int]
    rect_size_px: tuple[int, int]
    left_map1: np.ndarray
    left_map2: np.ndarray
    right_map1: np.ndarray
    right_map2: np.ndarray

    @classmethod
    def for_rig(cls, rig: Rig) -> RectificationMaps:
        """The tables of ``rig.raw``.

        Raises
        ------
        SlitcliError
            If the rig has no ``raw`` calibration (its images are already rectified).
        """
        if rig.raw is None:
            raise SlitcliError("rig has no 'raw' calibration; its images are already "
                               "rectified")
        raw = rig.raw
        size = (int(rig.image_size_px[0]), int(rig.image_size_px[1]))
        maps = []
        for camera in ("left", "right"):
            # either lens model (pinhole, or equidistant through cv2.fisheye)
            m1, m2 = undistort_rectify_map(raw, camera, size, cv2.CV_16SC2)
            m1.setflags(write=False)
            m2.setflags(write=False)
            maps += [m1, m2]
        raw_size = (int(raw.image_size_px[0]), int(raw.image_size_px[1]))
        return cls(raw_size, size, *maps)


def rectification_maps(rig: Rig) -> RectificationMaps:
    """The remap tables of ``rig.raw`` (:meth:`RectificationMaps.for_rig`)."""
    return RectificationMaps.for_rig(rig)


def rectify_pair(rig: Rig, left_bgr: np.ndarray, right_bgr: np.ndarray | None = None, *,
                 maps: RectificationMaps | None = None
                 ) -> tuple[np.ndarray, np.ndarray | None]:
    """Rectify raw images with ``rig.raw`` (bilinear); returned unchanged without ``raw``.

    Parameters
    ----------
    rig : Rig
    left_bgr, right_bgr : ndarray, uint8, (H, W, 3) or (H, W)
        Raw images of size ``rig.raw.image_size_px`` (without ``raw``: already rectified
        images of size ``rig.image_size_px``). ``right_bgr`` may be None (one camera).
    maps : RectificationMaps, optional
        The rig's tables, built once per rig by the caller; built here when None.

    Returns
    -------
    left_rect, right_rect : ndarray
        Rectified images of size ``rig.image_size_px`` (``right_rect`` None when
        ``right_bgr`` is).

    Raises
    ------
    SlitcliError
        If an image does not have the size the rig expects.
    """
    want = tuple(rig.raw.image_size_px if rig.raw is not None else rig.image_size_px)
    key = "raw.image_size_px" if rig.raw is not None else "image_size_px"
    for name, img in (("left", left_bgr), ("right", right_bgr)):
        if img is None:
            continue
        got = (int(img.shape[1]), int(img.shape[0]))
        if got != want:
            raise SlitcliError(f"{name} image is {got[0]}x{got[1]} but the rig's {key} is "
                               f"{want[0]}x{want[1]}; use the rig these images were taken "
                               "with")
    if rig.raw is None:
        return left_bgr, right_bgr
    m = RectificationMaps.for_rig(rig) if maps is None else maps
    left = cv2.remap(left_bgr, m.left_map1, m.left_map2, cv2.INTER_LINEAR)
    right = (None if right_bgr is None
             else cv2.remap(right_bgr, m.right_map1, m.right_map2, cv2.INTER_LINEAR))
    return left, right


def rectify_points(rig: Rig, uv_raw_px: np.ndarray, *, camera: str = "left") -> np.ndarray:
    """Raw pixel positions (N, 2) of one camera to rectified pixels (N, 2) of the rig."""
    uv = np.asarray(uv_raw_px, dtype=float).reshape(-1, 1, 2)
    if rig.raw is None:
        return uv.reshape(-1, 2).copy()
    raw = rig.raw
    k, d, r, p = (("K1", "D1", "R1", "P1") if camera == "left" else ("K2", "D2", "R2", "P2"))
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-9)
    if raw.model == "equidistant":
        out = cv2.fisheye.undistortPoints(uv, raw.array(k), raw.array(d).reshape(4, 1),
                                          R=raw.array(r), P=raw.array(p), criteria=crit)
    else:
        out = cv2.undistortPoints(uv, raw.array(k), raw.array(d), R=raw.array(r),
                                  P=raw.array(p), criteria=crit)
    return out.reshape(-1, 2)


def R_rect_from_raw_left(rig: Rig) -> np.ndarray:
    """Rotation from the raw left camera frame to the rig's (rectified) camera frame."""
    return np.eye(3) if rig.raw is None else rig.raw.array("R1")
