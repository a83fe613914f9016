"""Laser geometry of a rig: where the stripe may lie, and triangulation (paper Eqs. 5-7
via DESIGN §4).

:class:`LaserGeometry` holds what the extractor needs from a rig (computed once per rig
and parameter set); :func:`triangulate_stripe` intersects stripe pixels' rays with the
laser plane; :func:`laser_sight_range_m` is the nearest range at which the laser is in
sight, per bearing. :func:`triangulate_columns`, the same intersection over one frame's
found columns, is compiled ahead of time (Cython, :mod:`slitcli.laser._c.geometry`) and
re-exported here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slitcli.laser._c.geometry import triangulate_columns
from slitcli.laser.params import LaserParams
from slitcli.rig import Rig

__all__ = ["LaserGeometry", "laser_sight_range_m", "triangulate_columns", "triangulate_stripe"]


@dataclass(frozen=True)
class LaserGeometry:
    """What the extractor needs from a rig, computed once per rig and parameter set.

    Attributes
    ----------
    search_mask : ndarray, shape (H, W) bool
        Pixels whose ray meets the laser plane in front of the camera at a
        horizontal range (sensor frame) of at most ``max_search_range_m``; every pixel
        with ``search="full"``.
    px_per_m : ndarray, shape (H, W) float
        Image rows per metre of height on an upright surface at the point where each
        pixel's ray meets the laser plane (the scale of the sheet's thickness in the
        image); NaN where the ray misses the plane or lies beyond
        ``max_search_range_m``.
    ray_x : ndarray, shape (W,)
        ``(u - cx) / fx`` of every column: the x of its rays ``K^-1 (u, v, 1)``.
    ray_y_coeffs : ndarray, shape (2,)
        ``(1 / fy, -cy / fy)``: the ray's y is ``v / fy - cy / fy``.
    plane_cam : ndarray, shape (4,)
        The laser plane in the camera frame: unit normal and offset (m).
    sensor_from_cam : ndarray, shape (3, 4)
        Rotation and translation (m) from the camera to the sensor frame.

    The last four make :func:`triangulate_stripe`'s ray/plane intersection one
    compiled pass over the found columns (:func:`triangulate_columns`), the same arithmetic.
    """

    search_mask: np.ndarray
    px_per_m: np.ndarray
    ray_x: np.ndarray
    ray_y_coeffs: np.ndarray
    plane_cam: np.ndarray
    sensor_from_cam: np.ndarray

    @classmethod
    def from_rig(cls, rig: Rig, params: LaserParams) -> LaserGeometry:
        """Build the geometry of ``rig`` for ``params.max_search_range_m``."""
        h, w = rig.height_px, rig.width_px
        v, u = np.mgrid[0:h, 0:w]
        pts = rig.cam_to_sensor(rig.intersect_laser_plane(rig.pixel_rays_cam(u, v)))
        rng = np.hypot(pts[..., 0], pts[..., 1])
        with np.errstate(invalid="ignore"):
            in_range = np.isfinite(rng) & (rng <= params.max_search_range_m)
        mask = np.ones((h, w), bool) if params.search == "full" else in_range
        # rows of the points 1 mm above and below on the vertical through each point
        step = np.array([0.0, 0.0, 1e-3])
        _, v_up = rig.project_cam(rig.sensor_to_cam(pts + step))
        _, v_dn = rig.project_cam(rig.sensor_to_cam(pts - step))
        with np.errstate(invalid="ignore"):
            px_per_m = np.abs(v_dn - v_up) / 2e-3
        # Fortran order: the extractor walks image columns, and the transposes of
        # these are contiguous
        cam = rig.left
        return cls(search_mask=np.asfortranarray(mask),
                   px_per_m=np.asfortranarray(np.where(in_range, px_per_m, np.nan)),
                   ray_x=(np.arange(w, dtype=np.float64) - cam.cx_px) / cam.fx_px,
                   ray_y_coeffs=np.array([1.0 / cam.fy_px, -cam.cy_px / cam.fy_px]),
                   plane_cam=np.append(rig.laser.unit_normal, rig.laser.unit_offset_m),
                   sensor_from_cam=np.column_stack([rig.R_sensor_from_cam,
                                                    rig.cam_origin_sensor_xyz]))


def triangulate_stripe(rig: Rig, u_px: np.ndarray, v_px: np.ndarray) -> tuple[np.ndarray, ...]:
    """Sensor-frame points of stripe pixels by exact ray/laser-plane intersection.

    Replaces the paper's Eqs. 5-7 (valid only for an untilted camera) with
    DESIGN §4: ``X = d / (n . r) r`` for the ray ``r = K^-1 (u, v, 1)``, then the
    camera-to-sensor transform of the rig.

    Parameters
    ----------
    rig : Rig
    u_px, v_px : array_like, same shape
        Pixel coordinates of stripe points (NaN allowed).

    Returns
    -------
    x_m, y_m, range_m, bearing_deg : ndarray, same shape as the inputs
        Sensor frame forward and left coordinates, horizontal range and bearing
        (positive left); NaN where the ray misses the plane or the input is NaN.
    """
    pts = rig.cam_to_sensor(rig.intersect_laser_plane(rig.pixel_rays_cam(u_px, v_px)))
    x, y = pts[..., 0], pts[..., 1]
    return x, y, np.hypot(x, y), np.degrees(np.arctan2(y, x))


def laser_sight_range_m(rig: Rig, bearing_deg: np.ndarray, *, margin_px: float = 2.0,
                        max_range_m: float = 10.0, step_m: float = 1e-3) -> np.ndarray:
    """Nearest horizontal range at which the laser can be seen, per bearing.

    The lit point at bearing ``b`` and range ``r`` lies on the laser plane; it is in
    sight when it projects inside the left image with ``margin_px`` to spare (the
    stripe's width needs a few rows). Nearer than this the stripe of an obstacle falls
    out of the image (below it, for the paper's rig: about 0.6 m straight ahead, more
    to the sides), so the laser's silence there says nothing (fusion, Eq. 11).

    Parameters
    ----------
    rig : Rig
    bearing_deg : ndarray, shape (B,)
        Bearings, sensor frame, positive left, degrees.

    Returns
    -------
    ndarray, shape (B,)
        Metres, sampled every ``step_m``; inf where the laser is never in sight up
        to ``max_range_m``.
    """
    b = np.radians(np.asarray(bearing_deg, dtype=float))[:, None]
    r = np.arange(step_m, max_range_m + step_m / 2, step_m)[None, :]
    n_s, d_s = rig.laser_plane_sensor()
    x, y = r * np.cos(b), r * np.sin(b)
    if abs(n_s[2]) < 1e-9:
        return np.full(b.shape[0], np.inf)
    z = (d_s - n_s[0] * x - n_s[1] * y) / n_s[2]
    u, v = rig.project_cam(rig.sensor_to_cam(np.stack([x, y, z], axis=-1)))
    w, h = rig.image_size_px
    with np.errstate(invalid="ignore"):
        inside = ((u >= margin_px) & (u <= w - 1 - margin_px)
                  & (v >= margin_px) & (v <= h - 1 - margin_px))
    first = np.argmax(inside, axis=1)
    return np.where(inside.any(axis=1), r[0, first], np.inf)
