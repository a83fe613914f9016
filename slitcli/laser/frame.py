"""Per-frame laser API: extraction plus triangulation (paper Eqs. 5-7 via DESIGN §4).

:func:`detect_laser` is what fusion (``detect``) and the closed-loop simulator
call for every frame. The rig's geometry and triangulation are in :mod:`.geometry`,
the segments' sub-pixel ends in :mod:`.edges`, the per-bearing range table
(:func:`nearest_range_per_bin`, DESIGN §6) in :mod:`.bins`; their names are also
importable from here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from slitcli.laser.bins import (
    LaserBins,
    bearing_bin_centres_deg,
    bin_boundary_points,
    nearest_range_per_bin,
)
from slitcli.laser.diagnose import is_grey
from slitcli.laser.edges import (
    EdgeParams,
    LaserEdges,
    covered_shift_px,
    edge_reach_px,
    segment_edges,
)
from slitcli.laser.extract import checked_image, extract_stripe
from slitcli.laser.geometry import (
    LaserGeometry,
    laser_sight_range_m,
    triangulate_columns,
    triangulate_stripe,
)
from slitcli.laser.params import LaserParams
from slitcli.rig import Rig

__all__ = ["EdgeParams", "LaserBins", "LaserEdges", "LaserFrame", "LaserGeometry",
           "bearing_bin_centres_deg", "bin_boundary_points", "covered_shift_px",
           "detect_laser", "edge_reach_px", "laser_sight_range_m", "nearest_range_per_bin",
           "segment_edges", "triangulate_stripe"]


@dataclass(frozen=True)
class LaserFrame:
    """The laser stripe of one frame, per image column, with its triangulated points.

    All arrays have shape (W,) (one entry per image column ``u_px = 0..W-1``);
    columns without a stripe hold NaN (``in_band`` and ``saturated`` False).
    Points are in the sensor frame (x forward, y left, metres; bearing positive
    to the left, degrees).

    Attributes
    ----------
    u_px, v_px : column and sub-pixel stripe row, pixels.
    strength_dn : the stripe's peak brightness in the red channel (light it adds above the
        surface, texture cancelled, pixel blur undone where the rig geometry is known), DN.
    saturated : the stripe core is clipped.
    x_m, y_m : sensor-frame position of the lit point, metres.
    range_m : horizontal distance ``hypot(x, y)`` from the point below the left camera.
    bearing_deg : ``atan2(y, x)`` in degrees.
    in_band : the range lies in the rig's trusted laser band
        ``[laser.min_range_m, laser.max_range_m]``.
    noise_sigma_dn, threshold_dn : noise of the laser evidence measured on the image and
        the seed level used, DN.
    grey_image : the image is grey (red, green and blue equal): it cannot carry a red
        stripe (:func:`slitcli.laser.diagnose.stripe_absence`).
    """

    u_px: np.ndarray
    v_px: np.ndarray
    strength_dn: np.ndarray
    saturated: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    range_m: np.ndarray
    bearing_deg: np.ndarray
    in_band: np.ndarray
    noise_sigma_dn: float
    threshold_dn: float
    grey_image: bool = False

    @property
    def found(self) -> np.ndarray:
        """Columns with a stripe (bool, shape (W,))."""
        return np.isfinite(self.v_px)

    def without(self, drop: np.ndarray) -> LaserFrame:
        """This frame with the columns ``drop`` (W,) bool cleared (no stripe there)."""
        drop = np.asarray(drop, dtype=bool)
        if not drop.any():
            return self
        cleared = {name: np.where(drop, np.nan, getattr(self, name))
                   for name in ("v_px", "strength_dn", "x_m", "y_m", "range_m",
                                "bearing_deg")}
        return replace(self, **cleared, saturated=self.saturated & ~drop,
                       in_band=self.in_band & ~drop)


def detect_laser(left_bgr: np.ndarray, rig: Rig, params: LaserParams | None = None, *,
                 previous: LaserFrame | np.ndarray | None = None,
                 geometry: LaserGeometry | None = None,
                 edges: EdgeParams | None = None) -> LaserFrame:
    """Find the laser stripe in one left image and triangulate it (Eqs. 1-7).

    A column at the near end of a lit segment (its outward neighbour unlit or farther)
    sees the surface over part of its width only; it is triangulated along the ray
    through the centre of that part (:func:`covered_shift_px`), so that its bearing
    lies on the surface, not beyond its edge.

    Parameters
    ----------
    left_bgr : ndarray, shape (H, W, 3), uint8, BGR
        Rectified left image of the rig's size.
    rig : Rig
    params : LaserParams, optional
        Default: the paper's defaults.
    previous : LaserFrame or ndarray (W,), optional
        The previous frame's result (or its ``v_px``), for the continuity term of Eq. 4.
    geometry : LaserGeometry, optional
        ``LaserGeometry.from_rig(rig, params)``; pass it when processing many
        frames so it is computed once.
    edges : EdgeParams, optional
        Surface jump and coverage confidence of the end columns.

    Returns
    -------
    LaserFrame
    """
    params = LaserParams() if params is None else params
    edges = EdgeParams() if edges is None else edges
    img = checked_image(left_bgr)
    if img.shape[:2] != (rig.height_px, rig.width_px):
        raise ValueError(f"image is {img.shape[1]}x{img.shape[0]}, the rig's is "
                         f"{rig.width_px}x{rig.height_px}")
    geometry = LaserGeometry.from_rig(rig, params) if geometry is None else geometry
    prev = previous.v_px if isinstance(previous, LaserFrame) else previous
    stripe = extract_stripe(img, params, search_mask=geometry.search_mask, previous_v_px=prev,
                            px_per_m=geometry.px_per_m)
    u = np.arange(rig.width_px, dtype=np.float64)
    pts = np.empty((4, rig.width_px))
    in_band = np.empty(rig.width_px, bool)
    triangulate_columns(stripe.v_px, geometry.ray_x, geometry.ray_y_coeffs, geometry.plane_cam,
                 geometry.sensor_from_cam, rig.laser.min_range_m, rig.laser.max_range_m,
                 pts, in_band)
    shift = covered_shift_px(pts[2], stripe.strength_dn, stripe.noise_sigma_dn, edges)
    if np.any(shift != 0.0):
        px = geometry.ray_x[1] - geometry.ray_x[0] if rig.width_px > 1 else 0.0
        triangulate_columns(stripe.v_px, geometry.ray_x + shift * px, geometry.ray_y_coeffs,
                     geometry.plane_cam, geometry.sensor_from_cam, rig.laser.min_range_m,
                     rig.laser.max_range_m, pts, in_band)
    x, y, rng, bearing = pts
    return LaserFrame(u_px=u, v_px=stripe.v_px, strength_dn=stripe.strength_dn,
                      saturated=stripe.saturated, x_m=x, y_m=y, range_m=rng,
                      bearing_deg=bearing, in_band=in_band,
                      noise_sigma_dn=stripe.noise_sigma_dn, threshold_dn=stripe.threshold_dn,
                      grey_image=is_grey(img))
