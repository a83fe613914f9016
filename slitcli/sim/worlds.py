"""Worlds for the closed-loop DWA simulation: a scene plus the robot's start and goal.

Built-in worlds: the paper's scenario (§4, Fig. 8: the robot heads for a goal with a
box in the way) and seeded random worlds of boxes and cylinders with a guaranteed
free path. A world file is an ordinary scene file (docs/scene.md) whose
``robot.start`` and ``goal_xy_m`` are the start and goal.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from slitcli.errors import SlitcliError
from slitcli.sim.clearance import clearance_m, object_distances, obstacle_geometry
from slitcli.sim.scene import Scene, scene_from_dict


@dataclass(frozen=True)
class World:
    """A validated world: a scene with its start and goal.

    The start is ``scene.robot.start``, the goal ``scene.goal_xy_m``. ``yaml_text`` is
    the scene file it came from (with overrides applied), written next to the results
    so that the obstacle geometry can be redrawn (Fig. 8).
    """

    name: str
    scene: Scene
    yaml_text: str


def world_from_dict(data: dict[str, Any], source: str, *,
                    start: tuple[float, float, float] | None = None,
                    goal_xy_m: tuple[float, float] | None = None) -> World:
    """Validate a scene mapping as a world.

    ``start`` (x_m, y_m, yaw_deg) and ``goal_xy_m`` override the file's. Raises
    :class:`SlitcliError` for a missing goal, a start in collision or a goal inside an
    obstacle.
    """
    d = dict(data) if isinstance(data, dict) else data
    if isinstance(d, dict):
        if start is not None:
            robot = dict(d.get("robot") or {})
            robot["start"] = {"x_m": start[0], "y_m": start[1], "yaw_deg": start[2]}
            d["robot"] = robot
        if goal_xy_m is not None:
            d["goal_xy_m"] = [float(goal_xy_m[0]), float(goal_xy_m[1])]
    scene = scene_from_dict(d, source=source)
    check_world(scene, source)
    return World(scene.name, scene, yaml.safe_dump(d, sort_keys=False))


def load_world(path: str | Path, *, start: tuple[float, float, float] | None = None,
               goal_xy_m: tuple[float, float] | None = None) -> World:
    """Read a world (scene) YAML file; see :func:`world_from_dict`."""
    from slitcli.io.yamlfile import read_yaml

    p = Path(path)
    data = read_yaml(p, kind="world file", missing_hint="check the path or use the paper "
                     "scenario")
    return world_from_dict(data, str(p), start=start, goal_xy_m=goal_xy_m)


def check_world(scene: Scene, source: str) -> None:
    """Refuse an impossible world (:class:`SlitcliError`, naming the object).

    Impossible: no goal, the robot overlapping an obstacle at the start, or the goal
    inside an obstacle.
    """
    if scene.goal_xy_m is None:
        raise SlitcliError(f"{source}: no goal; add 'goal_xy_m: [x, y]' to the world file or "
                           "give `goal_xy_m` X,Y", param="goal_xy_m")
    geom = obstacle_geometry(scene)
    s = scene.robot.start
    pts = np.array([[s.x_m, s.y_m], scene.goal_xy_m], dtype=float)
    d = object_distances(geom, pts)
    if d.shape[1] == 0:
        return
    i = int(np.argmin(d[0]))
    if d[0, i] <= scene.robot.radius_m:
        raise SlitcliError(
            f"{source}: the start ({s.x_m:g}, {s.y_m:g}) puts the robot (radius "
            f"{scene.robot.radius_m:g} m) in collision with objects[{i}]; move robot.start "
            "(or `start`) at least the robot radius away", param="start")
    j = int(np.argmin(d[1]))
    if d[1, j] <= 0:
        g = scene.goal_xy_m
        raise SlitcliError(f"{source}: the goal ({g[0]:g}, {g[1]:g}) lies inside objects[{j}]; "
                           "move goal_xy_m (or `goal_xy_m`) into free space",
                           param="goal_xy_m")


# ------------------------------------------------------------------ paper scenario
PAPER_SENSING_RANGES_M = (0.6, 1.0, 1.5, 2.0)


def paper_world() -> World:
    """The paper's scenario (§4, Figs. 8-9), reconstructed.

    The robot (radius 0.25 m) starts at the origin heading +x towards a goal 6 m ahead.
    A box 0.3 m deep and 0.5 m wide stands in the way, its near face 2.85 m ahead: the
    sensor first sees it at the sensing range of each case (0.6, 1, 1.5, 2 m), never
    at the start. The box is 5 cm left of the line so that the side the robot passes
    on is decided by geometry, not by a floating-point tie between mirror images.
    """
    data = {
        "slitcli_scene": 1,
        "name": "paper_dwa",
        "objects": [{"type": "box", "centre_xy_m": [3.0, 0.05], "size_m": [0.3, 0.5, 0.5],
                     "surface": {"texture": "noise", "colour_rgb": [0.7, 0.55, 0.35]}}],
        "robot": {"start": {"x_m": 0.0, "y_m": 0.0, "yaw_deg": 0.0}, "radius_m": 0.25,
                  "height_m": 0.8},
        "goal_xy_m": [6.0, 0.0],
        "max_range_m": 5.0,
    }
    return world_from_dict(data, "scenario paper")


# ------------------------------------------------------------------ random worlds
@dataclass(frozen=True, kw_only=True)
class RandomWorldParams:
    """Seeded random worlds: boxes and cylinders between a start and a goal.

    The start is at x = 0 and the goal at x = ``length_m``, each at a random
    |y| <= ``end_spread_m``; obstacles are drawn in x in [``margin_m``, length_m -
    margin_m], |y| <= ``half_width_m``, none within ``end_clear_m`` of the start or goal.
    A world is kept only if a path with clearance >= ``path_clearance_m`` (robot
    radius + the planner's safety margin + slack) joins start and goal inside the arena
    (x in [-1, length_m + 1], |y| <= half_width_m + 0.5), checked on a ``grid_m`` grid.
    """

    length_m: float = 8.0
    half_width_m: float = 2.0
    end_spread_m: float = 1.0
    margin_m: float = 1.2
    end_clear_m: float = 0.8
    min_objects: int = 6
    max_objects: int = 10
    box_size_m: tuple[float, float] = (0.2, 0.6)
    cylinder_radius_m: tuple[float, float] = (0.1, 0.3)
    robot_radius_m: float = 0.25
    path_clearance_m: float = 0.35
    grid_m: float = 0.05


def random_world(seed: int, params: RandomWorldParams | None = None) -> World:
    """A random world for ``seed`` (numpy default_rng), redrawn until it has a free path."""
    p = params or RandomWorldParams()
    rng = np.random.default_rng(seed)
    for _ in range(1000):
        data = _draw_world(rng, p, seed)
        w = world_from_dict(data, f"random world {seed}")
        if _has_free_path(w.scene, p):
            return w
    raise SlitcliError(f"random world {seed}: no world with a free path in 1000 draws; "
                       "use fewer or smaller obstacles")


def _draw_world(rng: np.random.Generator, p: RandomWorldParams, seed: int) -> dict[str, Any]:
    sy, gy = rng.uniform(-p.end_spread_m, p.end_spread_m, size=2)
    ends = np.array([[0.0, sy], [p.length_m, gy]])
    n = int(rng.integers(p.min_objects, p.max_objects + 1))
    objects: list[dict[str, Any]] = []
    while len(objects) < n:
        c = np.array([rng.uniform(p.margin_m, p.length_m - p.margin_m),
                      rng.uniform(-p.half_width_m, p.half_width_m)])
        colour = [round(float(x), 3) for x in rng.uniform(0.2, 0.9, size=3)]
        if rng.random() < 0.5:
            sx, sy_ = rng.uniform(*p.box_size_m, size=2)
            reach = 0.5 * math.hypot(sx, sy_)
            ob = {"type": "box", "centre_xy_m": [round(float(c[0]), 3), round(float(c[1]), 3)],
                  "size_m": [round(float(sx), 3), round(float(sy_), 3), 0.5],
                  "yaw_deg": round(float(rng.uniform(0, 180)), 1),
                  "surface": {"colour_rgb": colour}}
        else:
            r = float(rng.uniform(*p.cylinder_radius_m))
            reach = r
            ob = {"type": "cylinder", "centre_xy_m": [round(float(c[0]), 3),
                                                      round(float(c[1]), 3)],
                  "radius_m": round(r, 3), "height_m": 0.5, "surface": {"colour_rgb": colour}}
        if np.min(np.hypot(*(ends - c).T)) - reach < p.end_clear_m:
            continue
        objects.append(ob)
    yaw = math.degrees(math.atan2(gy - sy, p.length_m))
    return {"slitcli_scene": 1, "name": f"random_{seed:03d}", "seed": int(seed),
            "objects": objects,
            "robot": {"start": {"x_m": 0.0, "y_m": round(float(sy), 3),
                                "yaw_deg": round(yaw, 2)},
                      "radius_m": p.robot_radius_m, "height_m": 0.8},
            "goal_xy_m": [round(float(p.length_m), 3), round(float(gy), 3)],
            "max_range_m": 5.0}


def _has_free_path(scene: Scene, p: RandomWorldParams) -> bool:
    """Is there a 4-connected grid path with clearance >= path_clearance_m, start to goal?"""
    xs = np.arange(-1.0, p.length_m + 1.0 + 1e-9, p.grid_m)
    ys = np.arange(-p.half_width_m - 0.5, p.half_width_m + 0.5 + 1e-9, p.grid_m)
    gx, gy = np.meshgrid(xs, ys)
    clear = clearance_m(obstacle_geometry(scene), np.column_stack([gx.ravel(), gy.ravel()]))
    free = (clear.reshape(gx.shape) >= p.path_clearance_m).astype(np.uint8)
    _, labels = cv2.connectedComponents(free, connectivity=4)
    s = scene.robot.start
    goal = scene.goal_xy_m
    assert goal is not None

    def cell(x: float, y: float) -> tuple[int, int]:
        return round((y - ys[0]) / p.grid_m), round((x - xs[0]) / p.grid_m)

    a, b = labels[cell(s.x_m, s.y_m)], labels[cell(*goal)]
    return bool(a != 0 and a == b)


# ------------------------------------------------------------------ hard static worlds
def _wall(a: tuple[float, float], b: tuple[float, float]) -> dict[str, Any]:
    return {"type": "wall", "from_xy_m": [a[0], a[1]], "to_xy_m": [b[0], b[1]], "height_m": 1.0,
            "surface": {"colour_rgb": [0.75, 0.72, 0.68]}}


def _cyl(x: float, y: float, r: float) -> dict[str, Any]:
    return {"type": "cylinder", "centre_xy_m": [round(x, 3), round(y, 3)], "radius_m": r,
            "height_m": 0.6, "surface": {"colour_rgb": [0.5, 0.6, 0.7]}}


def _box(x: float, y: float, sx: float, sy: float, yaw: float = 0.0) -> dict[str, Any]:
    return {"type": "box", "centre_xy_m": [x, y], "size_m": [sx, sy, 0.6], "yaw_deg": yaw,
            "surface": {"colour_rgb": [0.7, 0.55, 0.35]}}


def _world(name: str, objects: list[dict[str, Any]], goal: tuple[float, float],
           start: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> World:
    data = {"slitcli_scene": 1, "name": name, "objects": objects,
            "robot": {"start": {"x_m": start[0], "y_m": start[1], "yaw_deg": start[2]},
                      "radius_m": 0.25, "height_m": 0.8},
            "goal_xy_m": [goal[0], goal[1]], "max_range_m": 5.0}
    return world_from_dict(data, f"scenario hard ({name})")


def _clutter(seed: int) -> list[dict[str, Any]]:
    """Cylinders (0.1-0.2 m) on a jittered 0.9 m lattice over x 1.5-6.5, |y| <= 2."""
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.arange(1.5, 6.6, 0.9), np.arange(-2.0, 2.01, 0.9))
    jit = rng.uniform(-0.2, 0.2, size=(*xs.shape, 2))
    rad = rng.uniform(0.1, 0.2, size=xs.shape)
    return [_cyl(float(x + j[0]), float(y + j[1]), round(float(r), 3))
            for x, y, j, r in zip(xs.ravel(), ys.ravel(), jit.reshape(-1, 2), rad.ravel(),
                                  strict=True)]


def hard_worlds() -> list[World]:
    """Eight static worlds that stress a local planner (``--scenario hard``).

    A 0.7 m doorway (robot 0.5 m + 2 x 0.05 m margin), a U trap open towards the robot,
    dense clutter (cylinders on a jittered 0.9 m lattice, a free path guaranteed), a
    corridor with side openings, a box just behind a corner, a slalom of half-width
    boxes, a channel offset from the start-goal line, and a grid of pillars.
    """
    pillars = [_cyl(1.5 + i, -2.0 + j + (0.5 if i % 2 else 0.0), 0.15)
               for i in range(6) for j in range(5)]
    worlds = [
        _world("doorway_0.7m", [_wall((3.0, -3.0), (3.0, -0.05)), _wall((3.0, 0.65), (3.0, 3.0))],
               (6.0, 0.0)),
        _world("u_trap", [_wall((1.8, 1.0), (3.0, 1.0)), _wall((3.0, 1.0), (3.0, -1.0)),
                          _wall((3.0, -1.0), (1.8, -1.0))], (6.0, 0.0)),
        _world("corridor_openings", [_wall((-0.5, 0.8), (3.0, 0.8)), _wall((4.2, 0.8), (6.5, 0.8)),
                                     _wall((7.5, 0.8), (10.5, 0.8)),
                                     _wall((-0.5, -0.8), (2.0, -0.8)),
                                     _wall((3.0, -0.8), (8.0, -0.8)),
                                     _wall((9.0, -0.8), (10.5, -0.8))], (10.0, 0.0)),
        _world("box_behind_corner", [_wall((-0.5, -0.8), (4.0, -0.8)),
                                     _wall((4.0, -0.8), (4.0, 5.0)),
                                     _wall((-0.5, 0.8), (2.4, 0.8)),
                                     _wall((2.4, 0.8), (2.4, 5.0)),
                                     _box(3.55, 2.0, 0.5, 0.5)], (3.2, 4.2)),
        _world("slalom", [_wall((-0.5, 1.5), (8.5, 1.5)), _wall((-0.5, -1.5), (8.5, -1.5)),
                          _box(2.0, 0.85, 0.3, 1.3), _box(4.0, -0.85, 0.3, 1.3),
                          _box(6.0, 0.85, 0.3, 1.3)], (8.0, 0.0)),
        _world("offset_channel", [_wall((2.5, 0.2), (2.5, -3.0)), _wall((2.5, 1.2), (2.5, 4.0)),
                                  _wall((2.5, 0.2), (5.5, 0.2)), _wall((2.5, 1.2), (5.5, 1.2))],
               (8.0, 0.0)),
        _world("pillar_grid", pillars, (8.0, 0.5)),
    ]
    for seed in range(100):
        w = _world("dense_clutter", _clutter(seed), (8.0, 0.0))
        if _has_free_path(w.scene, RandomWorldParams()):
            worlds.insert(2, w)
            break
    return worlds


# ------------------------------------------------------------------ dynamic cases
PERSON_RADIUS_M = 0.25
PERSON_HEIGHT_M = 1.7


def _person(waypoints: list[tuple[float, float, float]]) -> dict[str, Any]:
    """A person-like cylinder (0.25 m radius, 1.7 m tall) moving through waypoints (t, x, y)."""
    return {"type": "cylinder", "radius_m": PERSON_RADIUS_M, "height_m": PERSON_HEIGHT_M,
            "surface": {"colour_rgb": [0.35, 0.4, 0.6]},
            "motion": {"waypoints": [{"t_s": round(t, 3), "xy_m": [round(x, 3), round(y, 3)]}
                                     for t, x, y in waypoints]}}


@dataclass(frozen=True)
class DynamicCase:
    """A built-in dynamic case: the world with the person and the same world without."""

    name: str
    world: World
    empty: World


def dynamic_cases() -> list[DynamicCase]:
    """The ``--scenario dynamic`` cases (robot from the origin heading +x).

    - ``cross_<u>_d<D>``: a person crosses the robot's lane at x = 4 m at u = 1 or
      0.5 m/s, timed to reach the lane when the robot (driving straight at 0.2 m/s)
      would be D = 2.5, 1.5 or 1.0 m before the crossing line (from the right at
      1 m/s, from the left at 0.5 m/s); goal (8, 0).
    - ``doorway_leave``: a person stands in a 1.2 m doorway at x = 3 m (blocking it)
      and walks out of it, ahead and then sideways, from t = 8 s; goal (6, 0).
    - ``slow_walker``: a person walks ahead of the robot in its lane at 0.1 m/s (half
      the robot's top speed), from x = 2 m; goal (8, 0).
    - ``oncoming``: a person walks at the robot at 0.4 m/s along y = 0.45 m (shoulder
      to shoulder would leave 0.05 m between the two bodies); goal (8, 0).
    """
    def make(name: str, extra: list[dict[str, Any]], person: dict[str, Any],
             goal: tuple[float, float]) -> DynamicCase:
        return DynamicCase(name, _world(name, [*extra, person], goal),
                           _world(f"{name}_empty", extra, goal))

    out = []
    x_c = 4.0
    for u, side in ((1.0, -1.0), (0.5, 1.0)):
        for d in (1.5, 1.0, 0.7):
            t_meet = (x_c - d + 0.1) / 0.2      # 0.1 m lost accelerating from standing
            y0 = 3.0 * side
            out.append(make(f"cross_{u:g}mps_d{d:g}m", [],
                            _person([(t_meet - 3.0 / u, x_c, y0),
                                     (t_meet + 3.0 / u, x_c, -y0)]), (8.0, 0.0)))
    door = [_wall((3.0, -3.0), (3.0, -0.6)), _wall((3.0, 0.6), (3.0, 3.0))]
    out.append(make("doorway_leave", door,
                    _person([(8.0, 3.0, 0.0), (10.0, 4.0, 0.0), (13.0, 4.0, 3.0)]), (6.0, 0.0)))
    out.append(make("slow_walker", [], _person([(0.0, 2.0, 0.0), (60.0, 8.0, 0.0),
                                                (62.0, 8.0, 3.0)]), (8.0, 0.0)))
    out.append(make("oncoming", [], _person([(0.0, 9.0, 0.45), (30.0, -3.0, 0.45)]), (8.0, 0.0)))
    return out
