"""The stereo + laser-slit rig: the rig file (DESIGN §12) and the geometry every module uses.

The rig describes a *rectified* stereo pair (pinhole, no distortion, right camera at
``+baseline_m`` along the left camera's x axis), how the left camera is mounted on
the robot (height, tilt, roll, forward offset) and the laser sheet as a plane
``n . X = offset_m`` in the left camera frame. Frames are those of the package
docstring (:mod:`slitcli`).

The paper's rig (Hombot, §4 of the paper) is :func:`paper_rig`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from slitcli.errors import SlitcliError
from slitcli.io.keys import KeyReader, image_size
from slitcli.io.yamlfile import brief

SCHEMA_VERSION = 1
MIN_BIN_DEG = 0.05
"""Narrowest bearing bin, degrees (below it bins are finer than a pixel of a 4k image)."""
MAX_BIN_DEG = 10.0
"""Widest bearing bin, degrees."""
MAX_FOCAL_PX = 1e7
"""Largest focal length accepted, pixels (a 0.1-degree field of view on 16k pixels)."""


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of the rectified left camera, in pixels."""

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float

    @property
    def K(self) -> np.ndarray:
        """3x3 camera matrix."""
        return np.array(
            [[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]]
        )


@dataclass(frozen=True)
class Mount:
    """Where the left camera sits on the robot.

    ``height_m`` is the optical centre above the floor, ``tilt_deg`` the pitch of the
    optical axis below horizontal, ``roll_deg`` the roll, ``forward_m`` the
    distance of the camera ahead of the robot's rotation centre. Roll is a right-handed
    rotation about the camera's optical axis (+z).
    """

    height_m: float
    tilt_deg: float
    roll_deg: float = 0.0
    forward_m: float = 0.0


def unit_plane(normal: tuple[float, float, float], offset_m: float) -> tuple[np.ndarray, float]:
    """The plane ``normal . X = offset_m`` with its normal scaled to unit length.

    Returns the unit normal (3,) and the offset in metres.
    """
    n = np.asarray(normal, dtype=float)
    norm = float(np.linalg.norm(n))
    return n / norm, float(offset_m) / norm


@dataclass(frozen=True)
class Laser:
    """The laser sheet: plane ``normal . X = offset_m`` in the left camera frame (metres).

    ``min_range_m`` and ``max_range_m`` bound the band in which the laser return is
    trusted by fusion (the paper's 0.6-1.0 m active range).
    """

    normal: tuple[float, float, float]
    offset_m: float
    min_range_m: float = 0.6
    max_range_m: float = 1.0

    @property
    def unit_normal(self) -> np.ndarray:
        """Normal scaled to unit length (shape (3,))."""
        return unit_plane(self.normal, self.offset_m)[0]

    @property
    def unit_offset_m(self) -> float:
        """Offset of the plane once its normal is scaled to unit length, metres."""
        return unit_plane(self.normal, self.offset_m)[1]


@dataclass(frozen=True)
class StereoLimits:
    """Range up to which stereo is trusted, metres (the paper's 3 m)."""

    max_range_m: float = 3.0


@dataclass(frozen=True)
class RawCalibration:
    """Unrectified calibration from ``slitcli calibrate`` (OpenCV conventions).

    ``K1``, ``K2`` are 3x3 camera matrices, ``D1``, ``D2`` distortion coefficients
    (k1, k2, p1, p2[, k3...]), ``R``, ``T`` the pose of the right camera relative to
    the left (``X_right = R X_left + T``, metres), ``R1``, ``R2``, ``P1``, ``P2`` the
    rectification from :func:`cv2.stereoRectify`. ``image_size_px`` is the raw
    (width, height). Matrices are stored as nested tuples so the rig stays immutable.
    ``model`` is the lens model of both cameras: ``pinhole`` (OpenCV's k1 k2 p1 p2
    [k3 ...]) or ``equidistant`` (``cv2.fisheye``, Kalibr's pinhole-equidistant: D is
    k1 k2 k3 k4).
    """

    image_size_px: tuple[int, int]
    K1: tuple
    D1: tuple
    K2: tuple
    D2: tuple
    R: tuple
    T: tuple
    R1: tuple
    R2: tuple
    P1: tuple
    P2: tuple
    model: str = "pinhole"

    def array(self, name: str) -> np.ndarray:
        """One of the matrices as a float array."""
        return np.asarray(getattr(self, name), dtype=float)


@dataclass(frozen=True)
class Rig:
    """A calibrated stereo camera with a laser slit, mounted on a robot."""

    name: str
    image_size_px: tuple[int, int]
    left: Intrinsics
    baseline_m: float
    mount: Mount
    laser: Laser
    stereo: StereoLimits = field(default_factory=StereoLimits)
    raw: RawCalibration | None = None

    # ------------------------------------------------------------------ derived
    @property
    def width_px(self) -> int:
        return int(self.image_size_px[0])

    @property
    def height_px(self) -> int:
        return int(self.image_size_px[1])

    @property
    def focal_px(self) -> float:
        """Horizontal focal length, the one that scales disparity (Eq. 8)."""
        return float(self.left.fx_px)

    @property
    def R_sensor_from_cam(self) -> np.ndarray:
        """3x3 rotation taking left-camera vectors to the sensor frame."""
        t = math.radians(self.mount.tilt_deg)
        r = math.radians(self.mount.roll_deg)
        # camera axes (x right, y down, z forward) expressed in the sensor frame when level
        base = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
        # pitch down by tilt: rotation about the sensor's +y (left) axis
        pitch = np.array(
            [[math.cos(t), 0.0, math.sin(t)], [0.0, 1.0, 0.0], [-math.sin(t), 0.0, math.cos(t)]]
        )
        # roll about the camera's own optical axis (applied in the camera frame)
        roll = np.array(
            [[math.cos(r), -math.sin(r), 0.0], [math.sin(r), math.cos(r), 0.0], [0.0, 0.0, 1.0]]
        )
        return pitch @ base @ roll

    @property
    def cam_origin_sensor_xyz(self) -> np.ndarray:
        """Left optical centre in the sensor frame, metres (shape (3,))."""
        return np.array([0.0, 0.0, self.mount.height_m])

    @property
    def right_origin_cam_xyz(self) -> np.ndarray:
        """Right optical centre in the left camera frame, metres."""
        return np.array([self.baseline_m, 0.0, 0.0])

    # ------------------------------------------------------------------ geometry
    def pixel_rays_cam(self, u_px: np.ndarray, v_px: np.ndarray) -> np.ndarray:
        """Rays through pixels, ``K^-1 (u, v, 1)``, in the left camera frame.

        Parameters
        ----------
        u_px, v_px : array_like, broadcastable
            Pixel coordinates (pixel centres at integers).

        Returns
        -------
        rays_cam_xyz : ndarray, shape (..., 3)
            Direction vectors with z = 1 (not unit length).
        """
        u = np.asarray(u_px, dtype=float)
        v = np.asarray(v_px, dtype=float)
        u, v = np.broadcast_arrays(u, v)
        x = (u - self.left.cx_px) / self.left.fx_px
        y = (v - self.left.cy_px) / self.left.fy_px
        return np.stack([x, y, np.ones_like(x)], axis=-1)

    def project_cam(self, points_cam_xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project left-camera points to pixels; NaN for points behind the camera."""
        p = np.asarray(points_cam_xyz, dtype=float)
        z = np.where(p[..., 2] > 0, p[..., 2], np.nan)
        u = self.left.fx_px * p[..., 0] / z + self.left.cx_px
        v = self.left.fy_px * p[..., 1] / z + self.left.cy_px
        return u, v

    def cam_to_sensor(self, points_cam_xyz: np.ndarray) -> np.ndarray:
        """Left-camera points (..., 3) to the sensor frame (..., 3), metres."""
        p = np.asarray(points_cam_xyz, dtype=float)
        return p @ self.R_sensor_from_cam.T + self.cam_origin_sensor_xyz

    def sensor_to_cam(self, points_sensor_xyz: np.ndarray) -> np.ndarray:
        """Sensor-frame points (..., 3) to the left camera frame (..., 3), metres."""
        p = np.asarray(points_sensor_xyz, dtype=float)
        return (p - self.cam_origin_sensor_xyz) @ self.R_sensor_from_cam

    def laser_plane_sensor(self) -> tuple[np.ndarray, float]:
        """The laser plane in the sensor frame: unit normal (3,) and offset (m)."""
        n_c = self.laser.unit_normal
        n_s = self.R_sensor_from_cam @ n_c
        d_s = self.laser.unit_offset_m + float(n_s @ self.cam_origin_sensor_xyz)
        return n_s, d_s

    def intersect_laser_plane(self, rays_cam_xyz: np.ndarray) -> np.ndarray:
        """Exact ray/plane intersection (DESIGN §4, replacing paper Eqs. 5-7).

        Parameters
        ----------
        rays_cam_xyz : ndarray, shape (..., 3)
            Ray directions from the left optical centre, camera frame.

        Returns
        -------
        points_cam_xyz : ndarray, shape (..., 3)
            ``X = d / (n . r) r``; NaN where the ray is parallel to the plane or meets
            it behind the camera.
        """
        r = np.asarray(rays_cam_xyz, dtype=float)
        denom = r @ self.laser.unit_normal
        with np.errstate(divide="ignore", invalid="ignore"):
            s = self.laser.unit_offset_m / denom
        s = np.where((np.abs(denom) > 1e-12) & (s > 0), s, np.nan)
        return r * s[..., None]

    def depth_from_disparity(self, disparity_px: np.ndarray) -> np.ndarray:
        """Depth along the optical axis ``D = W f / disparity`` (paper Eq. 8), metres.

        NaN where the disparity is not positive.
        """
        d = np.asarray(disparity_px, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(d > 0, self.baseline_m * self.focal_px / d, np.nan)

    def disparity_from_depth(self, depth_m: np.ndarray) -> np.ndarray:
        """Disparity in pixels of a point at depth ``depth_m`` (inverse of Eq. 8)."""
        z = np.asarray(depth_m, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(z > 0, self.baseline_m * self.focal_px / z, np.nan)

    def stripe_row_on_wall(self, forward_m: float, u_px: float | None = None) -> float:
        """Image row of the laser stripe on a wall ``forward_m`` ahead (sensor x = const).

        The stripe is the line where the laser plane meets the wall; its image is a
        straight line, intersected here with column ``u_px`` (default: cx).
        Returns NaN if the line does not cross that column in front of the camera.
        """
        u = self.left.cx_px if u_px is None else float(u_px)
        n_s, d_s = self.laser_plane_sensor()
        direction = np.cross([1.0, 0.0, 0.0], n_s)
        if np.linalg.norm(direction) < 1e-12:
            return float("nan")
        # one point of the line: x = forward_m on the wall, solve the laser plane in (y, z)
        a = np.array([[1.0, 0.0, 0.0], n_s, direction])
        p0 = np.linalg.solve(a, np.array([forward_m, d_s, 0.0]))
        pts = self.sensor_to_cam(np.stack([p0, p0 + direction]))
        us, vs = self.project_cam(pts)
        if not np.all(np.isfinite(us)) or abs(us[1] - us[0]) < 1e-12:
            return float(vs[0]) if np.isfinite(vs[0]) else float("nan")
        return float(vs[0] + (u - us[0]) * (vs[1] - vs[0]) / (us[1] - us[0]))

    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view of the left image, degrees."""
        w, h = self.image_size_px
        c = self.left
        hfov = math.atan((c.cx_px + 0.5) / c.fx_px) + math.atan((w - 0.5 - c.cx_px) / c.fx_px)
        vfov = math.atan((c.cy_px + 0.5) / c.fy_px) + math.atan((h - 0.5 - c.cy_px) / c.fy_px)
        return math.degrees(hfov), math.degrees(vfov)

    def bearing_limits_deg(self) -> tuple[float, float]:
        """Bearings (sensor frame, positive left) of the left image's outer columns."""
        w = self.image_size_px[0]
        c = self.left
        left = math.degrees(math.atan((c.cx_px + 0.5) / c.fx_px))
        right = -math.degrees(math.atan((w - 0.5 - c.cx_px) / c.fx_px))
        return right, left

    def bearing_bins(self, bin_deg: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bearing bins over the left image's horizontal field of view (DESIGN §6).

        Bin centres are the multiples of ``bin_deg`` whose bins lie (at least half)
        inside the field of view; bin ``c`` holds bearings in ``[c - w/2, c + w/2)``.
        Every range table (ground truth, laser, stereo, fused) uses these bins.

        Returns
        -------
        centres, lower, upper : ndarray, shape (B,)
            Degrees, sensor frame, positive left, ascending (right to left).
        """
        if not MIN_BIN_DEG <= bin_deg <= MAX_BIN_DEG:
            # a width is also a count: 1e-6 deg would make 6e7 bins of a 60-deg view
            raise SlitcliError(f"bearing bin width bin_deg = {bin_deg!r} is out of range; give "
                               f"{MIN_BIN_DEG:g} to {MAX_BIN_DEG:g} degrees")
        right, left = self.bearing_limits_deg()
        k0 = math.ceil(right / bin_deg - 1e-9)
        k1 = math.floor(left / bin_deg + 1e-9)
        centres = np.arange(k0, k1 + 1, dtype=np.float64) * bin_deg
        return centres, centres - bin_deg / 2, centres + bin_deg / 2

    # ------------------------------------------------------------------ file form
    def to_dict(self) -> dict[str, Any]:
        """The rig as the plain mapping written to YAML (DESIGN §12)."""
        d: dict[str, Any] = {"slitcli_rig": SCHEMA_VERSION, "name": self.name}
        d["image_size_px"] = [int(v) for v in self.image_size_px]
        d["left"] = {k: float(v) for k, v in asdict(self.left).items()}
        d["baseline_m"] = float(self.baseline_m)
        d["mount"] = {k: float(v) for k, v in asdict(self.mount).items()}
        d["laser"] = {
            "normal": [float(v) for v in self.laser.normal],
            "offset_m": float(self.laser.offset_m),
            "min_range_m": float(self.laser.min_range_m),
            "max_range_m": float(self.laser.max_range_m),
        }
        d["stereo"] = {"max_range_m": float(self.stereo.max_range_m)}
        if self.raw is None:
            d["raw"] = None
        else:
            raw: dict[str, Any] = {"image_size_px": [int(v) for v in self.raw.image_size_px]}
            for key in _RAW_SHAPES:
                raw[key] = np.asarray(getattr(self.raw, key), dtype=float).tolist()
            if self.raw.model != "pinhole":
                raw["model"] = self.raw.model
            d["raw"] = raw
        return d

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None)


def paper_rig() -> Rig:
    """The paper's Hombot rig with the DESIGN §2 assumptions (f = 250 px, 320x240)."""
    tilt = math.radians(20.0)
    return Rig(
        name="paper",
        image_size_px=(320, 240),
        left=Intrinsics(fx_px=250.0, fy_px=250.0, cx_px=159.5, cy_px=119.5),
        baseline_m=0.088,
        mount=Mount(height_m=0.65, tilt_deg=20.0, roll_deg=0.0, forward_m=0.0),
        laser=Laser(
            normal=(0.0, math.cos(tilt), math.sin(tilt)),
            offset_m=0.60,
            min_range_m=0.6,
            max_range_m=1.0,
        ),
        stereo=StereoLimits(max_range_m=3.0),
        raw=None,
    )


def laser_plane_for_mount(mount: Mount, laser_height_m: float) -> tuple[tuple[float, ...], float]:
    """Camera-frame plane (normal, offset) of a horizontal laser sheet at a floor height."""
    probe = Rig(
        name="probe", image_size_px=(2, 2), left=Intrinsics(1.0, 1.0, 0.5, 0.5),
        baseline_m=1.0, mount=mount, laser=Laser((0.0, 1.0, 0.0), 1.0),
    )
    # horizontal plane z_s = h  ->  n_s = (0, 0, -1)·… expressed in the camera frame
    n_c = probe.R_sensor_from_cam.T @ np.array([0.0, 0.0, -1.0])
    offset = mount.height_m - laser_height_m
    return tuple(float(v) for v in n_c), float(offset)


# ---------------------------------------------------------------------- loading
_RAW_SHAPES: dict[str, tuple[int, ...]] = {
    "K1": (3, 3), "D1": (-1,), "K2": (3, 3), "D2": (-1,), "R": (3, 3), "T": (3,),
    "R1": (3, 3), "R2": (3, 3), "P1": (3, 4), "P2": (3, 4),
}
RAW_MODELS = ("pinhole", "equidistant")
_TOP_KEYS = ("slitcli_rig", "name", "image_size_px", "left", "baseline_m", "mount",
             "laser", "stereo", "raw")
_LEFT_KEYS = ("fx_px", "fy_px", "cx_px", "cy_px")
_MOUNT_KEYS = ("height_m", "tilt_deg", "roll_deg", "forward_m")
_LASER_KEYS = ("normal", "offset_m", "min_range_m", "max_range_m")
_STEREO_KEYS = ("max_range_m",)


def _freeze(a: np.ndarray) -> tuple:
    return tuple(_freeze(x) for x in a) if a.ndim > 1 else tuple(float(x) for x in a)


def rig_from_dict(data: Any, source: str = "rig") -> Rig:
    """Validate a parsed rig mapping and build the :class:`Rig`.

    Raises
    ------
    SlitcliError
        Naming ``source`` and the offending key, for unknown or missing keys, a
        wrong schema version and impossible values.
    """
    r = KeyReader(source)
    top = r.mapping(data, "", _TOP_KEYS, ("slitcli_rig", "image_size_px", "left",
                                          "baseline_m", "mount", "laser"))
    version = top["slitcli_rig"]
    # `true` == 1 in Python: a boolean is not a version number
    if isinstance(version, bool) or version != SCHEMA_VERSION:
        raise r.fail("slitcli_rig", f"= {brief(version)} is not a schema version this slitcli "
                     "reads", f"use {SCHEMA_VERSION} (write a fresh file with `slitcli rig init`)")
    name = top.get("name", Path(source).stem)
    if not isinstance(name, str | int | float) or isinstance(name, bool) or len(str(name)) > 200:
        raise r.fail("name", f"= {brief(name)} is not a short name", "give a string")
    name = str(name)
    w, h = image_size(r, top["image_size_px"], "image_size_px")
    lm = r.mapping(top["left"], "left", _LEFT_KEYS, _LEFT_KEYS)
    left = Intrinsics(
        fx_px=r.number(lm, "fx_px", "left", low=0.0, low_open=True, high=MAX_FOCAL_PX),
        fy_px=r.number(lm, "fy_px", "left", low=0.0, low_open=True, high=MAX_FOCAL_PX),
        cx_px=r.number(lm, "cx_px", "left", low=0.0, high=float(w - 1)),
        cy_px=r.number(lm, "cy_px", "left", low=0.0, high=float(h - 1)),
    )
    baseline = r.number(top, "baseline_m", "", low=0.0, low_open=True, high=10.0)
    mm = r.mapping(top["mount"], "mount", _MOUNT_KEYS, ("height_m", "tilt_deg"))
    mount = Mount(
        height_m=r.number(mm, "height_m", "mount", low=0.0, low_open=True, high=20.0),
        tilt_deg=r.number(mm, "tilt_deg", "mount", low=-90.0, high=90.0, low_open=True,
                          high_open=True),
        roll_deg=r.number(mm, "roll_deg", "mount", default=0.0, low=-90.0, high=90.0,
                          low_open=True, high_open=True),
        forward_m=r.number(mm, "forward_m", "mount", default=0.0, low=-5.0, high=5.0),
    )
    la = r.mapping(top["laser"], "laser", _LASER_KEYS, ("normal", "offset_m"))
    normal = r.vector(la["normal"], "laser.normal", (3,))
    norm = float(np.linalg.norm(normal))
    if abs(norm - 1.0) > 0.01:
        raise r.fail("laser.normal", f"has length {norm:.4f}",
                     "give a unit vector (|n| = 1 within 0.01)")
    laser = Laser(
        normal=_freeze(normal),
        offset_m=r.number(la, "offset_m", "laser", low=0.0, low_open=True, high=20.0),
        min_range_m=r.number(la, "min_range_m", "laser", default=0.6, low=0.0, high=100.0),
        max_range_m=r.number(la, "max_range_m", "laser", default=1.0, low=0.0, low_open=True,
                             high=100.0),
    )
    if laser.min_range_m >= laser.max_range_m:
        raise r.fail("laser.min_range_m", f"= {laser.min_range_m:g} is not below "
                     f"laser.max_range_m = {laser.max_range_m:g}", "swap or correct them")
    _check_sheet_above_floor(r, mount, laser)
    st = top.get("stereo") or {}
    st = r.mapping(st, "stereo", _STEREO_KEYS, ())
    stereo = StereoLimits(max_range_m=r.number(st, "max_range_m", "stereo", default=3.0,
                                               low=0.0, low_open=True, high=1000.0))
    raw = None
    if top.get("raw") is not None:
        rm = r.mapping(top["raw"], "raw", ("image_size_px", *_RAW_SHAPES, "model"),
                       ("image_size_px", *_RAW_SHAPES))
        rw, rh = image_size(r, rm["image_size_px"], "raw.image_size_px")
        arrays = {k: _freeze(r.vector(rm[k], f"raw.{k}", s)) for k, s in _RAW_SHAPES.items()}
        model = rm.get("model", "pinhole")
        if model not in RAW_MODELS:
            raise r.fail("raw.model", f"= {model!r} is not a lens model slitcli reads",
                         f"use one of {', '.join(RAW_MODELS)}")
        if model == "equidistant" and not len(arrays["D1"]) == len(arrays["D2"]) == 4:
            raise r.fail("raw.D1", "must hold 4 coefficients (k1 k2 k3 k4) for the "
                         "equidistant model", "fix D1 and D2")
        raw = RawCalibration(image_size_px=(rw, rh), **arrays, model=model)
    return Rig(name=name, image_size_px=(w, h), left=left, baseline_m=baseline, mount=mount,
               laser=laser, stereo=stereo, raw=raw)


def _check_sheet_above_floor(r: KeyReader, mount: Mount, laser: Laser) -> None:
    """Refuse a laser sheet that lies below the floor over the whole trusted band.

    Where the sheet is not vertical, its height above the floor straight ahead at
    forward distance x solves ``n_s . (x, 0, z) = d_s``; if it is below z = 0 at both
    ends of ``[min_range_m, max_range_m]`` (a plane is linear in x, so everywhere
    between), no obstacle in the band can ever be lit.
    """
    probe = Rig(name="probe", image_size_px=(8, 8), left=Intrinsics(1.0, 1.0, 3.5, 3.5),
                baseline_m=1.0, mount=mount, laser=laser)
    n_s, d_s = probe.laser_plane_sensor()
    if abs(n_s[2]) < 1e-9:
        return
    z = [(d_s - n_s[0] * x) / n_s[2] for x in (laser.min_range_m, laser.max_range_m)]
    if max(z) < 0:
        raise r.fail("laser.offset_m", f"= {laser.offset_m:g} puts the laser sheet "
                     f"{-max(z):.3g} m below the floor between {laser.min_range_m:g} and "
                     f"{laser.max_range_m:g} m ahead",
                     "a horizontal sheet needs laser.offset_m < mount.height_m "
                     f"({mount.height_m:g}); check the sign of laser.normal")


def load_rig(path: str | Path) -> Rig:
    """Read and validate a rig YAML file (DESIGN §12)."""
    from slitcli.io.yamlfile import read_yaml

    p = Path(path)
    data = read_yaml(p, kind="rig file", missing_hint=f"write one with `slitcli rig init {p}`")
    return rig_from_dict(data, source=str(p))


def save_rig(rig: Rig, path: str | Path) -> None:
    """Write the rig as YAML, atomically."""
    from slitcli.io.atomic import write_text_atomic

    write_text_atomic(Path(path), rig.to_yaml())


def describe_rig(rig: Rig) -> dict[str, float]:
    """Derived numbers users check a rig against (printed by ``slitcli rig show``)."""
    hfov, vfov = rig.fov_deg()
    fb = rig.focal_px * rig.baseline_m
    out = {
        "hfov_deg": hfov,
        "vfov_deg": vfov,
        "disparity_at_1m_px": fb / 1.0,
        "disparity_at_3m_px": fb / 3.0,
        "depth_per_px_at_1m_m": 1.0**2 / fb,
        "depth_per_px_at_3m_m": 3.0**2 / fb,
    }
    for d in (0.6, 0.8, 1.0):
        out[f"stripe_row_wall_{d:.1f}m_px"] = rig.stripe_row_on_wall(d)
    return out
