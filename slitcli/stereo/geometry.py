"""Per-rig stereo geometry, computed once per rig and passed along (no global caches).

Everything the stereo pipeline needs that depends only on the rig (and the bearing-bin
width) lives in one frozen :class:`StereoGeometry`: the pixel rays of the rectified
left image in the camera and sensor frames, each pixel's bearing and bearing bin
(the one bin rule of :mod:`slitcli.ranges`), the disparity the floor plane has at each
pixel, and the raw -> rectified remap tables of a rig with a raw calibration. Build it
with :meth:`StereoGeometry.for_rig` once per rig (``slitcli stereo`` and the
:class:`slitcli.detect.Detector` do) and hand it to
:func:`slitcli.stereo.pipeline.process_stereo_pair`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slitcli.calibrate.rectify import RectificationMaps
from slitcli.errors import SlitcliError
from slitcli.ranges import BearingBins
from slitcli.rig import Rig


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class StereoGeometry:
    """Per-pixel geometry of one rig's rectified left image (read-only arrays).

    Attributes
    ----------
    rig : Rig
        The rig it was built for (rectified intrinsics; ``rig.raw`` may be set).
    rays_cam_xyz : (H, W, 3) float32
        Pixel rays ``K^-1 (u, v, 1)`` in the left camera frame (z = 1).
    rays_sensor_xyz : (H, W, 3) float32
        The same rays in the sensor frame (x forward, y left, z up), unit optical depth.
    bearing_deg : (H, W) float32
        Bearing of each pixel's ray, degrees, positive left. The sensor origin lies
        straight below the left optical centre, so a point's bearing is its ray's.
    bins : BearingBins
        The rig's bearing bins of width ``bins.bin_deg`` (DESIGN §6).
    pixel_bin : (H, W) int64
        Table bin of each pixel (``bins.index(bearing_deg)``, -1 outside the bins).
    floor_disparity_px : (H, W) float32
        Disparity of the floor plane at each pixel, ``d = f W (-r_z) / h`` (Eq. 8 with
        the ray's floor depth ``h / -r_z``); 0 above the horizon.
    rectification : RectificationMaps or None
        Raw -> rectified tables when the rig has a raw calibration.
    """

    rig: Rig
    rays_cam_xyz: np.ndarray
    rays_sensor_xyz: np.ndarray
    bearing_deg: np.ndarray
    bins: BearingBins
    pixel_bin: np.ndarray
    floor_disparity_px: np.ndarray
    rectification: RectificationMaps | None

    def __setstate__(self, state: dict) -> None:
        # a pickled array comes back writable (``--jobs`` workers get the geometry by
        # pickle); read-only again: every frame shares it, none may change it
        for value in state.values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        self.__dict__.update(state)

    @classmethod
    def for_rig(cls, rig: Rig, bin_width_deg: float = 1.0) -> StereoGeometry:
        """Compute the geometry of ``rig`` with bearing bins ``bin_width_deg`` wide.

        Raises
        ------
        SlitcliError
            If the field of view holds no whole bearing bin of that width.
        """
        bins = BearingBins.for_rig(rig, float(bin_width_deg))
        if len(bins) == 0:
            raise SlitcliError(f"bin_width_deg {bin_width_deg} leaves no bearing bin in the "
                               f"{rig.fov_deg()[0]:.1f} deg field of view; use narrower bins")
        w, h = rig.image_size_px
        rays = rig.pixel_rays_cam(np.arange(w)[None, :], np.arange(h)[:, None])
        rays = rays.astype(np.float32)
        rs = (rays @ rig.R_sensor_from_cam.T.astype(np.float32)).astype(np.float32)
        bearing = np.degrees(np.arctan2(rs[..., 1], rs[..., 0])).astype(np.float32)
        rz = rs[..., 2].astype(np.float64)
        floor = np.where(rz < 0, rig.focal_px * rig.baseline_m * -rz / rig.mount.height_m,
                         0.0).astype(np.float32)
        maps = RectificationMaps.for_rig(rig) if rig.raw is not None else None
        return cls(rig, _read_only(rays), _read_only(rs), _read_only(bearing), bins,
                   _read_only(bins.index(bearing)), _read_only(floor), maps)

    @property
    def bin_width_deg(self) -> float:
        """Width of the bearing bins, degrees."""
        return self.bins.bin_deg

    def check_for(self, rig: Rig, bin_width_deg: float) -> None:
        """Raise if this geometry was built for another rig or bin width."""
        if rig != self.rig or float(bin_width_deg) != self.bins.bin_deg:
            raise SlitcliError("the stereo geometry was built for another rig or bin width; "
                               "build it with StereoGeometry.for_rig(rig, bin_width_deg)")


__all__ = ["StereoGeometry"]
