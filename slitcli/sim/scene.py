"""Generated scenes (DESIGN §10): the scene file and robot poses.

A scene is a floor (z = 0) plus vertical obstacles standing on it or hanging above it
(boxes, cylinders, walls), optional white highlights (lamp reflections) and the laser
sheet's appearance, seen from a robot that is static, moves straight, or follows a
list of poses. World frame: x, y on the floor, z up, metres. A pose locates the
robot's rotation centre; the sensor origin is ``rig.mount.forward_m`` ahead of it.

The schema (``slitcli_scene: 1``) is documented in docs/scene.md; the exact range
truth of a scene is :mod:`slitcli.sim.truth`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.io.yamlfile import brief, finite_float
from slitcli.sim.camera import CameraModel, camera_from_scene

SCHEMA_VERSION = 1
MAX_ABS = 1e6
"""Largest magnitude of any number in a scene file (metres, degrees...): beyond it the
geometry loses the precision rendering needs, and squares overflow nothing below 1e150."""
MAX_FRAMES = 100_000
"""Most frames a scene may ask for (about 3 hours at 10 Hz)."""
MAX_ITEMS = 5_000
"""Most objects, highlights or listed poses in a scene (longer runs: motion straight)."""
MAX_SEED = 2**63 - 1


@dataclass(frozen=True)
class Surface:
    """How a surface looks: albedo per channel (0-1), and a seeded procedural texture.

    ``texture`` is ``noise`` (multi-octave value noise with feature size ``scale_m`` and
    relative amplitude ``contrast``) or ``plain`` (uniform: no stereo features).
    """

    colour_rgb: tuple[float, float, float] = (0.6, 0.6, 0.6)
    texture: str = "noise"
    scale_m: float = 0.02
    contrast: float = 0.6
    seed: int | None = None


Waypoint = tuple[float, float, float]  # (t_s, x_m, y_m) of a moving object's centre


@dataclass(frozen=True)
class Box:
    """An upright box: centre of its footprint, size (along x, along y, height), yaw.

    ``motion`` lists waypoints (t_s, x_m, y_m) of a moving box's centre (empty: static);
    see :func:`centre_at`.
    """

    centre_xy_m: tuple[float, float]
    size_m: tuple[float, float, float]
    yaw_deg: float = 0.0
    z_min_m: float = 0.0
    surface: Surface = field(default_factory=Surface)
    motion: tuple[Waypoint, ...] = ()

    @property
    def z_max_m(self) -> float:
        return self.z_min_m + self.size_m[2]


@dataclass(frozen=True)
class Cylinder:
    """An upright cylinder; ``motion`` as for :class:`Box`."""

    centre_xy_m: tuple[float, float]
    radius_m: float
    height_m: float
    z_min_m: float = 0.0
    surface: Surface = field(default_factory=Surface)
    motion: tuple[Waypoint, ...] = ()

    @property
    def z_max_m(self) -> float:
        return self.z_min_m + self.height_m


@dataclass(frozen=True)
class Wall:
    """A vertical rectangle of zero thickness (seen from both sides) between two floor points."""

    from_xy_m: tuple[float, float]
    to_xy_m: tuple[float, float]
    height_m: float
    z_min_m: float = 0.0
    surface: Surface = field(default_factory=Surface)

    @property
    def z_max_m(self) -> float:
        return self.z_min_m + self.height_m


Obstacle = Box | Cylinder | Wall


def centre_at(motion: tuple[Waypoint, ...], t_s: float) -> tuple[float, float]:
    """Centre (x_m, y_m) of a moving object at time ``t_s`` (s since the run/sequence start).

    Linear in time between waypoints, held before the first and after the last.
    """
    t = np.array([w[0] for w in motion])
    return (float(np.interp(t_s, t, [w[1] for w in motion])),
            float(np.interp(t_s, t, [w[2] for w in motion])))


def object_at(ob: Obstacle, t_s: float) -> Obstacle:
    """The object placed where it is at ``t_s`` (itself when it does not move)."""
    if isinstance(ob, Wall) or not ob.motion:
        return ob
    return replace(ob, centre_xy_m=centre_at(ob.motion, t_s))


@dataclass(frozen=True)
class Highlight:
    """A white lamp reflection: a saturated Gaussian spot on whatever surface is there."""

    position_xyz_m: tuple[float, float, float]
    radius_m: float = 0.03
    brightness: float = 1.5


@dataclass(frozen=True)
class LaserLook:
    """Appearance of the laser sheet in the images.

    The sheet itself (its plane) comes from the rig. Across the sheet the light is a
    Gaussian of standard deviation ``width_m``; its peak on a white surface is
    ``power_dn * (ref_range_m / r) ** falloff_exponent`` digital numbers at range ``r``
    from the emitter, so by default it saturates at 0.6 m, is about 80 DN on a grey wall
    at 1 m, fades past 1.3 m and is lost in the noise by 2 m. The red light leaks
    ``crosstalk`` of itself into green and blue, so a very bright core saturates towards
    white. Points farther than ``fan_deg`` off
    the forward direction are not lit. ``visible_min_dn`` is the peak below which the
    truth reports no stripe.
    """

    enabled: bool = True
    width_m: float = 0.004
    power_dn: float = 900.0
    ref_range_m: float = 0.6
    falloff_exponent: float = 4.0
    crosstalk: float = 0.12
    fan_deg: float = 60.0
    visible_min_dn: float = 20.0


@dataclass(frozen=True)
class ImageLook:
    """Camera and lighting: sensor noise, anti-aliasing, exposure and light direction.

    ``camera`` (None: the plain Gaussian ``noise_sigma_dn``) is a physical camera model
    (:mod:`slitcli.sim.camera`) that replaces that noise.
    """

    noise_sigma_dn: float = 2.0
    supersample: int = 3
    exposure: float = 0.85
    ambient: float = 0.55
    light_dir_xyz: tuple[float, float, float] = (0.3, 0.2, 1.0)
    camera: CameraModel | None = None


@dataclass(frozen=True)
class Pose2D:
    """Robot pose in the world: rotation centre (x, y) in metres and heading in radians."""

    x_m: float
    y_m: float
    yaw_rad: float


@dataclass(frozen=True)
class Robot:
    """Robot motion for rendering and its body for the planner.

    ``motion`` is ``static`` (every frame at ``start``), ``straight`` (constant
    ``speed_mps`` and ``yaw_rate_dps`` from ``start``) or ``poses`` (the list given).
    """

    start: Pose2D = Pose2D(0.0, 0.0, 0.0)
    motion: str = "static"
    speed_mps: float = 0.0
    yaw_rate_dps: float = 0.0
    poses: tuple[Pose2D, ...] = ()
    frames: int = 1
    frame_rate_hz: float = 5.0
    radius_m: float = 0.25
    height_m: float = 0.8


@dataclass(frozen=True)
class Scene:
    """A complete generated scene."""

    name: str
    seed: int = 0
    floor: Surface = field(default_factory=lambda: Surface(colour_rgb=(0.55, 0.5, 0.45),
                                                           scale_m=0.03, contrast=0.5))
    objects: tuple[Obstacle, ...] = ()
    highlights: tuple[Highlight, ...] = ()
    laser: LaserLook = field(default_factory=LaserLook)
    image: ImageLook = field(default_factory=ImageLook)
    robot: Robot = field(default_factory=Robot)
    goal_xy_m: tuple[float, float] | None = None
    max_range_m: float = 5.0

    @property
    def is_dynamic(self) -> bool:
        """Does any object move (a ``motion:`` key)?"""
        return any(not isinstance(o, Wall) and o.motion for o in self.objects)

    def at_time(self, t_s: float) -> Scene:
        """The scene with every moving object placed where it is at ``t_s`` seconds."""
        if not self.is_dynamic:
            return self
        return replace(self, objects=tuple(object_at(o, t_s) for o in self.objects))

    def poses(self, frames: int | None = None) -> list[Pose2D]:
        """Robot pose per frame (``frames`` overrides the scene's own count)."""
        r = self.robot
        n = r.frames if frames is None else frames
        if not 1 <= n <= MAX_FRAMES:
            raise SlitcliError(f"scene '{self.name}': frames = {n} is out of range; give 1 to "
                               f"{MAX_FRAMES} frames")
        if r.motion == "poses":
            if frames is not None and frames > len(r.poses):
                raise SlitcliError(f"scene '{self.name}': `frames` {frames} exceeds the "
                                   f"{len(r.poses)} poses listed; give at most that many",
                                   param="frames")
            return list(r.poses[:n])
        if r.motion == "static":
            return [r.start] * n
        dt = 1.0 / r.frame_rate_hz
        w = math.radians(r.yaw_rate_dps)
        out = []
        for i in range(n):
            t = i * dt
            yaw = r.start.yaw_rad + w * t
            if abs(w) < 1e-12:
                dx = r.speed_mps * t * math.cos(r.start.yaw_rad)
                dy = r.speed_mps * t * math.sin(r.start.yaw_rad)
            else:  # exact unicycle arc
                rad = r.speed_mps / w
                dx = rad * (math.sin(yaw) - math.sin(r.start.yaw_rad))
                dy = -rad * (math.cos(yaw) - math.cos(r.start.yaw_rad))
            out.append(Pose2D(r.start.x_m + dx, r.start.y_m + dy, yaw))
        return out

    def times_s(self, frames: int | None = None) -> np.ndarray:
        """Capture time of each frame, seconds."""
        n = len(self.poses(frames))
        return np.arange(n) / self.robot.frame_rate_hz


# ------------------------------------------------------------------- geometry
def box_corners_xy(box: Box) -> np.ndarray:
    """The 4 footprint corners of a box, counter-clockwise, shape (4, 2)."""
    hx, hy = box.size_m[0] / 2, box.size_m[1] / 2
    c, s = math.cos(math.radians(box.yaw_deg)), math.sin(math.radians(box.yaw_deg))
    local = np.array([[hx, -hy], [hx, hy], [-hx, hy], [-hx, -hy]])
    rot = np.array([[c, -s], [s, c]])
    return local @ rot.T + np.asarray(box.centre_xy_m, dtype=float)


# ---------------------------------------------------------------------- loading
class _Keys:
    """Validation helpers that name the file and key in one-line errors."""

    def __init__(self, source: str) -> None:
        self.source = source

    def err(self, key: str, problem: str, fix: str) -> SlitcliError:
        return SlitcliError(f"{self.source}: key '{key}' {problem}; {fix}")

    def mapping(self, v: Any, key: str, allowed: tuple[str, ...]) -> Mapping[str, Any]:
        if v is None:
            return {}
        if not isinstance(v, Mapping):
            raise self.err(key, "must be a mapping", f"allowed keys: {', '.join(allowed)}")
        for k in v:
            if k not in allowed:
                import difflib

                close = difflib.get_close_matches(str(k), allowed, n=1)
                hint = f"did you mean '{close[0]}'?" if close else \
                    f"allowed keys: {', '.join(allowed)}"
                raise SlitcliError(f"{self.source}: unknown key {brief(f'{key}.{k}')}; {hint}")
        return v

    def num(self, m: Mapping[str, Any], k: str, key: str, default: float | None = None, *,
            low: float | None = None, high: float | None = None, strict: bool = False) -> float:
        name = f"{key}.{k}"
        if k not in m:
            if default is None:
                raise SlitcliError(f"{self.source}: missing key '{name}'; add it (see "
                                   "docs/scene.md)")
            return default
        v = finite_float(m[k])
        if v is None:
            raise self.err(name, f"= {brief(m[k])} is not a finite number", "give a number")
        low = -MAX_ABS if low is None else low
        high = MAX_ABS if high is None else high
        if v < low or (strict and v == low):
            raise self.err(name, f"= {v:g} is out of range",
                           f"it must be {'>' if strict else '>='} {low:g}")
        if v > high:
            raise self.err(name, f"= {v:g} is out of range", f"it must be <= {high:g}")
        return v

    def vec(self, m: Mapping[str, Any], k: str, key: str, n: int,
            default: tuple[float, ...] | None = None) -> tuple[float, ...]:
        name = f"{key}.{k}"
        if k not in m:
            if default is None:
                raise SlitcliError(f"{self.source}: missing key '{name}'; add it as a list of "
                                   f"{n} numbers")
            return default
        v = m[k]
        nums = [finite_float(x) for x in v] if isinstance(v, list | tuple) and len(v) == n \
            else None
        if nums is None or any(x is None for x in nums):
            raise self.err(name, f"= {brief(v)} is not a list of {n} finite numbers",
                           f"give [{', '.join(['number'] * n)}]")
        if max(abs(x) for x in nums) > MAX_ABS:
            raise self.err(name, f"= {brief(v)} is out of range",
                           f"give numbers within +-{MAX_ABS:g}")
        return tuple(nums)

    def seed(self, v: Any, key: str) -> int:
        if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= MAX_SEED:
            raise self.err(key, f"= {brief(v)} is not a valid seed",
                           f"give a whole number from 0 to {MAX_SEED}")
        return v

    def items(self, v: Any, key: str, what: str, limit: int = MAX_ITEMS) -> list:
        if v is None:
            return []
        if not isinstance(v, list):
            raise self.err(key, "must be a list", f"give a list of {what}")
        if len(v) > limit:
            raise self.err(key, f"has {len(v)} entries", f"give at most {limit}")
        return v


def _surface(r: _Keys, v: Any, key: str) -> Surface:
    m = r.mapping(v, key, ("colour_rgb", "texture", "scale_m", "contrast", "seed"))
    texture = m.get("texture", "noise")
    if not isinstance(texture, str) or texture not in ("noise", "plain"):
        raise r.err(f"{key}.texture", f"= {brief(texture)} is unknown", "use noise or plain")
    colour = r.vec(m, "colour_rgb", key, 3, (0.6, 0.6, 0.6))
    if min(colour) < 0 or max(colour) > 1:
        raise r.err(f"{key}.colour_rgb", f"= {list(colour)} is out of range",
                    "give albedos between 0 and 1")
    seed = m.get("seed")
    if seed is not None:
        seed = r.seed(seed, f"{key}.seed")
    return Surface(colour_rgb=colour, texture=texture,
                   scale_m=r.num(m, "scale_m", key, 0.02, low=0.0, strict=True, high=100.0),
                   contrast=r.num(m, "contrast", key, 0.6, low=0.0, high=1.0), seed=seed)


def _pose(r: _Keys, v: Any, key: str) -> Pose2D:
    if isinstance(v, list | tuple):
        if len(v) != 3:
            raise r.err(key, f"= {brief(v)} has {len(v)} numbers",
                        "give [x_m, y_m, yaw_deg] (3 numbers) or a mapping of those keys")
        v = dict(zip(("x_m", "y_m", "yaw_deg"), v, strict=True))
    m = r.mapping(v, key, ("x_m", "y_m", "yaw_deg"))
    return Pose2D(r.num(m, "x_m", key, 0.0), r.num(m, "y_m", key, 0.0),
                  math.radians(r.num(m, "yaw_deg", key, 0.0)))


def _motion(r: _Keys, v: Any, key: str) -> tuple[Waypoint, ...]:
    """``motion: {waypoints: [{t_s, xy_m}, ...]}``: times strictly increasing."""
    if v is None:
        return ()
    m = r.mapping(v, key, ("waypoints",))
    wps = m.get("waypoints")
    if not isinstance(wps, list) or not wps:
        raise r.err(f"{key}.waypoints", "must be a non-empty list",
                    "give [{t_s: 0.0, xy_m: [x, y]}, ...]")
    out = []
    for i, w in enumerate(wps):
        wk = f"{key}.waypoints[{i}]"
        wm = r.mapping(w, wk, ("t_s", "xy_m"))
        t = r.num(wm, "t_s", wk)
        xy = r.vec(wm, "xy_m", wk, 2)
        if out and t <= out[-1][0]:
            raise r.err(f"{wk}.t_s", f"= {t:g} is not after the previous waypoint's",
                        "list waypoints in increasing time")
        out.append((t, xy[0], xy[1]))
    return tuple(out)


def _centre(r: _Keys, m: Mapping[str, Any], key: str,
            motion: tuple[Waypoint, ...]) -> tuple[float, float]:
    # a moving object's centre_xy_m may be omitted; it is its position at t = 0
    if not motion:
        return r.vec(m, "centre_xy_m", key, 2)  # type: ignore[return-value]
    at0 = centre_at(motion, 0.0)
    if "centre_xy_m" in m:
        c = r.vec(m, "centre_xy_m", key, 2)
        if math.hypot(c[0] - at0[0], c[1] - at0[1]) > 1e-3:
            raise r.err(f"{key}.centre_xy_m", f"= {list(c)} is not where the motion puts the "
                        f"object at t = 0 ({at0[0]:g}, {at0[1]:g})",
                        "omit centre_xy_m for a moving object")
    return at0


def _obstacle(r: _Keys, v: Any, key: str) -> Obstacle:
    if not isinstance(v, Mapping) or "type" not in v:
        raise r.err(key, "needs a 'type'", "use type: box, cylinder or wall")
    kind = v["type"]
    if not isinstance(kind, str):
        raise r.err(f"{key}.type", f"= {brief(kind)} is unknown", "use box, cylinder or wall")
    rest = {k: x for k, x in v.items() if k != "type"}
    common = ("z_min_m", "surface")
    if kind == "box":
        m = r.mapping(rest, key, ("centre_xy_m", "size_m", "yaw_deg", "motion", *common))
        size = r.vec(m, "size_m", key, 3)
        if min(size) <= 0:
            raise r.err(f"{key}.size_m", f"= {brief(list(size))} has a non-positive size",
                        "give positive lengths in metres")
        motion = _motion(r, m.get("motion"), f"{key}.motion")
        return Box(_centre(r, m, key, motion), size, r.num(m, "yaw_deg", key, 0.0),
                   r.num(m, "z_min_m", key, 0.0, low=0.0), _surface(r, m.get("surface"),
                                                                   f"{key}.surface"), motion)
    if kind == "cylinder":
        m = r.mapping(rest, key, ("centre_xy_m", "radius_m", "height_m", "motion", *common))
        motion = _motion(r, m.get("motion"), f"{key}.motion")
        return Cylinder(_centre(r, m, key, motion),
                        r.num(m, "radius_m", key, low=0.0, strict=True),
                        r.num(m, "height_m", key, low=0.0, strict=True),
                        r.num(m, "z_min_m", key, 0.0, low=0.0),
                        _surface(r, m.get("surface"), f"{key}.surface"), motion)
    if kind == "wall":
        m = r.mapping(rest, key, ("from_xy_m", "to_xy_m", "height_m", *common))
        a, b = r.vec(m, "from_xy_m", key, 2), r.vec(m, "to_xy_m", key, 2)
        if a == b:
            raise r.err(f"{key}.to_xy_m", "equals from_xy_m", "give two different points")
        return Wall(a, b, r.num(m, "height_m", key, low=0.0, strict=True),
                    r.num(m, "z_min_m", key, 0.0, low=0.0),
                    _surface(r, m.get("surface"), f"{key}.surface"))
    raise r.err(f"{key}.type", f"= {brief(kind)} is unknown", "use box, cylinder or wall")


_TOP = ("slitcli_scene", "name", "seed", "floor", "objects", "highlights", "laser", "image",
        "robot", "goal_xy_m", "max_range_m")


def scene_from_dict(data: Any, source: str = "scene") -> Scene:
    """Validate a parsed scene mapping (docs/scene.md) and build the :class:`Scene`."""
    r = _Keys(source)
    if not isinstance(data, Mapping):
        raise SlitcliError(f"{source}: a scene file must be a mapping with 'slitcli_scene: 1'; "
                           "see docs/scene.md")
    for k in data:
        if k not in _TOP:
            import difflib

            close = difflib.get_close_matches(str(k), _TOP, n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"allowed keys: {', '.join(_TOP)}"
            raise SlitcliError(f"{source}: unknown key {brief(str(k))}; {hint}")
    version = data.get("slitcli_scene")
    if isinstance(version, bool) or version != SCHEMA_VERSION:
        raise r.err("slitcli_scene", f"= {brief(version)} is not a schema version "
                    "this slitcli reads", f"set slitcli_scene: {SCHEMA_VERSION}")
    seed = r.seed(data.get("seed", 0), "seed")
    name = data.get("name", Path(source).stem)
    if not isinstance(name, str | int | float) or isinstance(name, bool) or len(str(name)) > 200:
        raise r.err("name", f"= {brief(name)} is not a short name", "give a string")
    objs = r.items(data.get("objects"), "objects", "box/cylinder/wall entries")
    objects = tuple(_obstacle(r, o, f"objects[{i}]") for i, o in enumerate(objs))
    hls = r.items(data.get("highlights"), "highlights", "highlight entries")
    highlights = []
    for i, h in enumerate(hls):
        key = f"highlights[{i}]"
        m = r.mapping(h, key, ("position_xyz_m", "radius_m", "brightness"))
        highlights.append(Highlight(r.vec(m, "position_xyz_m", key, 3),
                                    r.num(m, "radius_m", key, 0.03, low=0.0, strict=True,
                                          high=10.0),
                                    r.num(m, "brightness", key, 1.5, low=0.0, high=100.0)))
    lm = r.mapping(data.get("laser"), "laser", tuple(LaserLook.__dataclass_fields__))
    d = LaserLook()
    enabled = lm.get("enabled", True)
    if not isinstance(enabled, bool):
        raise r.err("laser.enabled", f"= {brief(enabled)} is not true/false",
                    "give true or false")
    laser = LaserLook(
        enabled=enabled,
        width_m=r.num(lm, "width_m", "laser", d.width_m, low=0.0, strict=True, high=1.0),
        power_dn=r.num(lm, "power_dn", "laser", d.power_dn, low=0.0),
        ref_range_m=r.num(lm, "ref_range_m", "laser", d.ref_range_m, low=0.0, strict=True,
                          high=100.0),
        falloff_exponent=r.num(lm, "falloff_exponent", "laser", d.falloff_exponent, low=0.0,
                               high=20.0),
        crosstalk=r.num(lm, "crosstalk", "laser", d.crosstalk, low=0.0, high=1.0),
        fan_deg=r.num(lm, "fan_deg", "laser", d.fan_deg, low=0.0, high=90.0, strict=True),
        visible_min_dn=r.num(lm, "visible_min_dn", "laser", d.visible_min_dn, low=0.0),
    )
    im = r.mapping(data.get("image"), "image", tuple(ImageLook.__dataclass_fields__))
    di = ImageLook()
    ss = im.get("supersample", di.supersample)
    if not isinstance(ss, int) or isinstance(ss, bool) or not 1 <= ss <= 8:
        raise r.err("image.supersample", f"= {brief(ss)} is out of range",
                    "give a whole number 1-8")
    light = r.vec(im, "light_dir_xyz", "image", 3, di.light_dir_xyz)
    if math.hypot(*light) < 1e-6:
        raise r.err("image.light_dir_xyz", f"= {list(light)} has no direction",
                    "give a non-zero vector pointing towards the light, e.g. [0.3, 0.2, 1]")
    image = ImageLook(
        noise_sigma_dn=r.num(im, "noise_sigma_dn", "image", di.noise_sigma_dn, low=0.0,
                             high=1000.0),
        supersample=ss,
        exposure=r.num(im, "exposure", "image", di.exposure, low=0.0, strict=True, high=100.0),
        ambient=r.num(im, "ambient", "image", di.ambient, low=0.0, high=1.0),
        light_dir_xyz=light,
        camera=camera_from_scene(im.get("camera"), "image.camera", r),
    )
    robot = _robot(r, data.get("robot"))
    goal = None
    if data.get("goal_xy_m") is not None:
        goal = r.vec(data, "goal_xy_m", "scene", 2)
    floor = _surface(r, data.get("floor"), "floor") if data.get("floor") is not None else \
        Scene.__dataclass_fields__["floor"].default_factory()
    return Scene(
        name=str(name), seed=seed, floor=floor, objects=objects,
        highlights=tuple(highlights), laser=laser, image=image, robot=robot, goal_xy_m=goal,
        max_range_m=r.num(data, "max_range_m", "scene", 5.0, low=0.0, strict=True, high=1000.0),
    )


def _robot(r: _Keys, v: Any) -> Robot:
    m = r.mapping(v, "robot", ("start", "motion", "speed_mps", "yaw_rate_dps", "poses",
                               "frames", "frame_rate_hz", "radius_m", "height_m"))
    motion = m.get("motion", "static")
    if not isinstance(motion, str) or motion not in ("static", "straight", "poses"):
        raise r.err("robot.motion", f"= {brief(motion)} is unknown",
                    "use static, straight or poses")
    listed = r.items(m.get("poses"), "robot.poses", "[x_m, y_m, yaw_deg] poses")
    poses = tuple(_pose(r, p, f"robot.poses[{i}]") for i, p in enumerate(listed))
    if motion == "poses" and not poses:
        raise r.err("robot.poses", "is empty", "list at least one [x_m, y_m, yaw_deg] pose")
    frames = m.get("frames", len(poses) if motion == "poses" else 1)
    if not isinstance(frames, int) or isinstance(frames, bool) or not 1 <= frames <= MAX_FRAMES:
        raise r.err("robot.frames", f"= {brief(frames)} is not a whole number from 1 to "
                    f"{MAX_FRAMES}", "give the number of frames to render")
    if motion == "poses" and frames > len(poses):
        raise r.err("robot.frames", f"= {frames} exceeds the {len(poses)} poses listed",
                    "list more poses or render fewer frames")
    return Robot(
        start=_pose(r, m.get("start"), "robot.start") if m.get("start") is not None else
        Pose2D(0.0, 0.0, 0.0),
        motion=motion, speed_mps=r.num(m, "speed_mps", "robot", 0.0, low=-100.0, high=100.0),
        yaw_rate_dps=r.num(m, "yaw_rate_dps", "robot", 0.0, low=-3600.0, high=3600.0),
        poses=poses, frames=frames,
        frame_rate_hz=r.num(m, "frame_rate_hz", "robot", 5.0, low=1e-3, high=1000.0),
        radius_m=r.num(m, "radius_m", "robot", 0.25, low=0.0, strict=True, high=100.0),
        height_m=r.num(m, "height_m", "robot", 0.8, low=0.0, strict=True, high=100.0),
    )


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene YAML file."""
    from slitcli.io.yamlfile import read_yaml

    p = Path(path)
    data = read_yaml(p, kind="scene file", missing_hint="check the path (examples in "
                     "sample_data/)")
    return scene_from_dict(data, source=str(p))
