"""Editing and checking rigs: mount edits that keep the laser sheet, factory rigs, checks.

The rig stores the laser sheet in the left camera frame (:class:`slitcli.rig.Laser`).
Changing the mount (height, tilt, roll) moves the camera relative to the robot, so the
same camera-frame plane would describe a different sheet in the world. The laser is
fixed to the robot: :func:`rig_with_mount` re-expresses the sheet, unchanged in the
sensor frame, in the camera frame of the new mount.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.rig import (
    Intrinsics,
    Laser,
    Mount,
    Rig,
    laser_plane_for_mount,
    load_rig,
    paper_rig,
    save_rig,
)


def laser_in_camera(rig: Rig, normal_sensor: np.ndarray, offset_sensor_m: float) -> Laser:
    """The sensor-frame plane ``n_s . X_s = d_s`` as the rig's camera-frame laser plane.

    ``X_s = R X_c + o`` gives ``(R^T n_s) . X_c = d_s - n_s . o``; the normal is flipped
    where needed so that the offset is positive (the rig file's convention).

    Raises
    ------
    SlitcliError
        If the sheet passes through the camera's optical centre (its stripe is a line
        seen edge-on: no range can be triangulated).
    """
    n_s = np.asarray(normal_sensor, dtype=float)
    n_c = rig.R_sensor_from_cam.T @ n_s
    d_c = float(offset_sensor_m) - float(n_s @ rig.cam_origin_sensor_xyz)
    if abs(d_c) < 1e-3:
        raise SlitcliError(f"laser sheet: it passes {1000 * abs(d_c):.2f} mm from the camera's "
                           "optical centre; the camera cannot triangulate it (move the laser "
                           "or the camera)")
    if d_c < 0:
        n_c, d_c = -n_c, -d_c
    return replace(rig.laser, normal=tuple(float(v) for v in n_c), offset_m=d_c)


def rig_with_mount(rig: Rig, *, height_m: float | None = None, tilt_deg: float | None = None,
                   roll_deg: float | None = None, forward_m: float | None = None,
                   laser_height_m: float | None = None) -> Rig:
    """The rig with mount fields replaced, the laser sheet kept where it is in the world.

    Parameters
    ----------
    height_m, tilt_deg, roll_deg, forward_m : new mount values (None keeps the old).
    laser_height_m : if given, the sheet becomes horizontal at this height above the
        floor, metres (:func:`slitcli.rig.laser_plane_for_mount`); otherwise the sheet
        keeps its pose in the sensor frame (it is fixed to the robot, the camera moved).

    Returns
    -------
    Rig
        A new rig; ``rig`` is not changed.
    """
    old = rig.mount
    mount = Mount(height_m=old.height_m if height_m is None else float(height_m),
                  tilt_deg=old.tilt_deg if tilt_deg is None else float(tilt_deg),
                  roll_deg=old.roll_deg if roll_deg is None else float(roll_deg),
                  forward_m=old.forward_m if forward_m is None else float(forward_m))
    if not 0 < mount.height_m <= 20:
        raise SlitcliError(f"`height_m` = {mount.height_m:g} is out of range; give the camera "
                           "height above the floor in metres (0-20)", param="height_m")
    for name, v in (("tilt_deg", mount.tilt_deg), ("roll_deg", mount.roll_deg)):
        if not -90 < v < 90:
            raise SlitcliError(f"`{name}` = {v:g} is out of range; give degrees in (-90, 90)",
                               param=name)
    n_s, d_s = rig.laser_plane_sensor()
    moved = replace(rig, mount=mount)
    if laser_height_m is not None:
        if not 0 <= laser_height_m < mount.height_m:
            raise SlitcliError(f"`laser_height_m` = {laser_height_m:g} must be at least 0 and "
                               f"below the camera ({mount.height_m:g} m); the sheet is "
                               "seen from above", param="laser_height_m")
        normal, offset = laser_plane_for_mount(mount, laser_height_m)
        return replace(moved, laser=replace(rig.laser, normal=normal, offset_m=offset))
    return replace(moved, laser=laser_in_camera(moved, n_s, d_s))


def laser_height_m(rig: Rig) -> float:
    """Height of the laser sheet above the floor right below the camera, metres.

    NaN if the sheet is vertical (parallel to the sensor z axis).
    """
    n_s, d_s = rig.laser_plane_sensor()
    return float(d_s / n_s[2]) if abs(n_s[2]) > 1e-12 else float("nan")


def factory_rig(image_size_px: tuple[int, int], fx_px: float, baseline_m: float, *,
                fy_px: float | None = None, cx_px: float | None = None,
                cy_px: float | None = None, base: Rig | None = None,
                name: str = "factory") -> Rig:
    """A rectified rig from a camera's factory calibration (no ``raw``).

    The principal point defaults to the image centre ``((W - 1) / 2, (H - 1) / 2)`` and
    ``fy_px`` to ``fx_px``. Mount, laser sheet (kept where it is in the world) and range
    limits come from ``base`` (default: the paper rig).
    """
    w, h = (int(v) for v in image_size_px)
    if w < 8 or h < 8:
        raise SlitcliError(f"`image_size_px` = {w}x{h} is too small; give W,H in pixels",
                           param="image_size_px")
    if not (fx_px > 0 and math.isfinite(fx_px)):
        raise SlitcliError(f"`fx_px` = {fx_px:g} must be a positive focal length in pixels",
                           param="fx_px")
    if not (0 < baseline_m <= 10):
        raise SlitcliError(f"`baseline_m` = {baseline_m:g} must be in (0, 10] metres",
                           param="baseline_m")
    left = Intrinsics(fx_px=float(fx_px), fy_px=float(fx_px if fy_px is None else fy_px),
                      cx_px=(w - 1) / 2.0 if cx_px is None else float(cx_px),
                      cy_px=(h - 1) / 2.0 if cy_px is None else float(cy_px))
    if not (0 <= left.cx_px <= w - 1 and 0 <= left.cy_px <= h - 1):
        raise SlitcliError(f"principal point ({left.cx_px:g}, {left.cy_px:g}) lies outside the "
                           f"{w}x{h} image; give cx, cy in pixels inside it")
    base = base or paper_rig()
    n_s, d_s = base.laser_plane_sensor()
    rig = replace(base, name=name, image_size_px=(w, h), left=left,
                  baseline_m=float(baseline_m), raw=None)
    return replace(rig, laser=laser_in_camera(rig, n_s, d_s))


def rig_warnings(rig: Rig) -> list[str]:
    """What in a rig cannot be seen: stripe rows outside the image, laser ranges not in view.

    Checks the laser stripe's row on the centre column for a wall at the laser band's
    ends (``laser.min_range_m``, ``laser.max_range_m``) and at 0.6, 0.8, 1.0 m, and the
    floor distance seen at the bottom row against ``laser.min_range_m``.
    """
    h = rig.height_px
    out = []
    ranges = sorted({rig.laser.min_range_m, rig.laser.max_range_m, 0.6, 0.8, 1.0})
    for r in ranges:
        row = rig.stripe_row_on_wall(r)
        if not math.isfinite(row):
            out.append(f"laser stripe on a wall {r:g} m ahead: not in front of the camera "
                       "(the sheet does not cross the centre column)")
        elif not -0.5 <= row <= h - 0.5:
            out.append(f"laser stripe on a wall {r:g} m ahead: row {row:.0f} px is outside "
                       f"the image (rows 0-{h - 1}); check mount, laser plane and image size")
    # nearest floor point in view: the bottom row's ray on the floor (z_s = 0)
    ray = rig.R_sensor_from_cam @ rig.pixel_rays_cam(rig.left.cx_px, h - 0.5)
    if ray[2] < 0:
        near = rig.mount.height_m * math.hypot(ray[0], ray[1]) / -ray[2] + rig.mount.forward_m
        if near > rig.laser.max_range_m:
            out.append(f"the floor is in view only from {near:.2f} m ahead, beyond the laser "
                       f"band's end ({rig.laser.max_range_m:g} m); the stripe on the floor "
                       "cannot be seen")
    return out


def run_rig_set(rig_path: str | Path, out: str | Path | None = None, **changes: float | None
                ) -> Rig:
    """``slitcli rig set``: edit the mount / laser height, keeping the sheet in the world.

    ``changes``: ``height_m``, ``tilt_deg``, ``roll_deg``, ``forward_m``,
    ``laser_height_m`` (None = keep). Written atomically to ``out`` (default: in place).
    """
    rig = load_rig(rig_path)
    if all(v is None for v in changes.values()):
        raise SlitcliError(f"{rig_path}: nothing to change; give a mount value or the laser "
                           "height")
    new = rig_with_mount(rig, **changes)
    save_rig(new, out if out is not None else rig_path)
    return new
