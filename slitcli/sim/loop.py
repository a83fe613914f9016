"""Closed-loop simulation: sense -> modified DWA -> unicycle motion (DESIGN §8, §10).

Each control period T the robot senses a per-bearing range table from its pose,
adds the points to a short-term obstacle memory (world frame), runs one DWA step
(:func:`slitcli.dwa.plan_step`) and holds the command for T, integrated exactly as
a unicycle. Collisions are checked against the true obstacle outlines at
``substeps`` instants per period.

Sensing is any :class:`Sensor`: a callable ``(pose, step) -> RangeScan``.
``perfect`` (:class:`PerfectSensor`) returns the true ranges per bearing bin over the
camera's field of view, cut at the sensing range: the paper's Matlab simulation.
The vision pipeline (render -> detect -> fuse) is another Sensor with the same call.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from types import MappingProxyType
from typing import Protocol

import numpy as np
import pandas as pd
import yaml

from slitcli.dwa import DwaParams, plan_step
from slitcli.errors import SlitcliError
from slitcli.io.atomic import (
    atomic_directory,
    check_output_folder,
    write_csv_atomic,
    write_text_atomic,
)
from slitcli.io.progress import progress_bar
from slitcli.local_map import to_robot, unicycle
from slitcli.prediction import MovingDiscs
from slitcli.ranges import RANGES, SIM_METRICS, SIM_TRAJECTORY, times_as_text
from slitcli.rig import Rig
from slitcli.sim.clearance import clearance_m, obstacle_geometry
from slitcli.sim.scene import Pose2D, Scene
from slitcli.sim.sensing import RangeScan
from slitcli.sim.truth import Footprints, footprints, sensor_origin_xy, wedge_min_range
from slitcli.sim.worlds import (
    PAPER_SENSING_RANGES_M,
    World,
    dynamic_cases,
    hard_worlds,
    load_world,
    paper_world,
    random_world,
)
from slitcli.world_model import MEMORY_MODES, WorldModel, WorldModelParams, moving_to_robot

TRAJECTORY_COLUMNS = SIM_TRAJECTORY.columns
RANGES_COLUMNS = RANGES.columns
METRICS_COLUMNS = SIM_METRICS.columns
MAX_STEPS = 100_000
"""Most control steps of one run (the paper's 300 s at 0.2 s: 1500)."""
MAX_WORLDS = 10_000
"""Most random worlds of one call."""
HARD_SENSING_RANGES_M = (1.0, 2.0, 3.0)


class Sensor(Protocol):
    """What the closed loop senses with: the range table seen from ``pose`` at ``step``,
    time ``t_s`` (moving objects are where they are then)."""

    def __call__(self, pose: Pose2D, step: int, t_s: float = 0.0) -> RangeScan: ...


class SensorFactory(Protocol):
    """Builds the sensor of one run: ``(scene, rig, sensing_range_m, bin_deg=...) -> Sensor``."""

    def __call__(self, scene: Scene, rig: Rig, sensing_range_m: float, *,
                 bin_deg: float = 1.0) -> Sensor: ...


@dataclass(frozen=True)
class PerfectSensor:
    """True nearest range per bearing bin (exact, from the scene), cut at ``sensing_range_m``.

    Bins cover the rig's horizontal field of view (``bin_deg`` wide); obstacles count
    when they reach between the floor margin (2 cm) and the robot's height, as in
    :func:`slitcli.sim.truth.true_ranges`, whose outlines are computed once here.
    """

    outlines: Footprints
    bearing_deg: np.ndarray
    bin_lo_deg: np.ndarray
    bin_hi_deg: np.ndarray
    forward_m: float
    sensing_range_m: float
    scene: Scene

    def __call__(self, pose: Pose2D, step: int, t_s: float = 0.0) -> RangeScan:
        outlines = self.outlines
        if self.scene.is_dynamic:
            outlines = footprints(self.scene.at_time(t_s), z_low_m=0.02,
                                  z_high_m=self.scene.robot.height_m)
        r = wedge_min_range(outlines, sensor_origin_xy(pose, self.forward_m), pose.yaw_rad,
                            self.bin_lo_deg, self.bin_hi_deg)
        # exact sensing: no return means nothing within the sensing range
        return RangeScan(self.bearing_deg, np.where(r <= self.sensing_range_m, r, np.nan),
                         self.forward_m, self.sensing_range_m)


def perfect_sensor(scene: Scene, rig: Rig, sensing_range_m: float, *,
                   bin_deg: float = 1.0) -> PerfectSensor:
    """The ``perfect`` sensing mode for a scene seen through ``rig``'s field of view."""
    if not sensing_range_m > 0:
        raise SlitcliError(f"`sensing_range_m` {sensing_range_m:g} must be > 0 m",
                           param="sensing_range_m")
    centres, lo, hi = rig.bearing_bins(bin_deg)
    outlines = footprints(scene, z_low_m=0.02, z_high_m=scene.robot.height_m)
    return PerfectSensor(outlines, centres, lo, hi, rig.mount.forward_m, float(sensing_range_m),
                         scene)


def vision_sensor(scene: Scene, rig: Rig, sensing_range_m: float, *,
                  bin_deg: float = 1.0) -> Sensor:
    """Render -> detect -> fuse at every step (:mod:`slitcli.sim.vision`)."""
    # imported here: the vision pipeline pulls in the detectors, which perfect sensing
    # and the planner tests do not need
    from slitcli.sim.vision import vision_sensor as make

    return make(scene, rig, sensing_range_m, bin_deg=bin_deg)


# The sensing modes of ``simulate-dwa --sensing``.
SENSING_MODES: Mapping[str, SensorFactory] = MappingProxyType({"perfect": perfect_sensor,
                                                                "vision": vision_sensor})


@dataclass(frozen=True, kw_only=True)
class SimParams:
    """Closed-loop settings.

    Attributes
    ----------
    safety_margin_m : float
        Added to the robot radius to give the planner's footprint radius.
    memory : str
        Obstacle memory (:mod:`slitcli.world_model`): ``clearing`` (cleared by the rays
        of each frame, moving obstacles tracked and predicted), ``expiry`` (points kept
        ``memory_s`` seconds, the former rule) or ``off``.
    memory_s : float
        How long sensed points are remembered with ``memory = expiry``.
    memory_cell_m : float
        One remembered point per grid cell of this size.
    predict : bool
        Track moving obstacles and plan against their predicted positions.
    substeps : int
        Collision checks per control period (0.2 m/s x 0.2 s / 10 = 4 mm apart).
    max_time_s : float
        Give up (outcome ``timeout``) after this simulated time.
    stuck_timeout_s, stuck_progress_m, stuck_new_ground_m : float
        Outcome ``stuck`` when, over the last ``stuck_timeout_s``, the best distance to
        the goal has not improved by ``stuck_progress_m`` AND the robot has not reached
        new ground: no position of that window lies farther than ``stuck_new_ground_m``
        from every position before it. A long detour explores new ground and is not
        stuck; circling in a trap or turning on the spot is.
    recovery_after_s, recovery_back_m, recovery_speed_mps : float
        Recovery: a robot that has not moved ``stuck_progress_m`` for
        ``recovery_after_s`` (outside the goal) backs up ``recovery_back_m`` at
        ``recovery_speed_mps`` along the way it came, if its remembered obstacles leave
        room, and planning resumes (0 s = no recovery).
    """

    safety_margin_m: float = 0.07
    memory: str = "clearing"
    memory_s: float = 10.0
    memory_cell_m: float = 0.05
    predict: bool = True
    substeps: int = 10
    max_time_s: float = 300.0
    stuck_timeout_s: float = 60.0
    stuck_progress_m: float = 0.05
    stuck_new_ground_m: float = 0.5
    recovery_after_s: float = 20.0
    recovery_back_m: float = 0.3
    recovery_speed_mps: float = 0.1

    def __post_init__(self) -> None:
        checks = {"safety_margin_m": self.safety_margin_m >= 0, "memory_s": self.memory_s >= 0,
                  "memory_cell_m": self.memory_cell_m > 0,
                  "substeps": 1 <= self.substeps <= 1000,
                  "max_time_s": 0 < self.max_time_s <= 86400.0,
                  "stuck_timeout_s": self.stuck_timeout_s > 0,
                  "stuck_progress_m": self.stuck_progress_m > 0,
                  "stuck_new_ground_m": self.stuck_new_ground_m > 0,
                  "recovery_after_s": self.recovery_after_s >= 0,
                  "recovery_back_m": self.recovery_back_m >= 0,
                  "recovery_speed_mps": self.recovery_speed_mps > 0}
        for name, ok in checks.items():
            value = getattr(self, name)
            if not ok or isinstance(value, bool) or not math.isfinite(value):
                raise SlitcliError(f"simulation parameter `{name}` = {value!r} is out of "
                                   "range; see the SimParams documentation for its bounds",
                                   param=name)
        if self.memory not in MEMORY_MODES:
            raise SlitcliError(f"simulation parameter `memory` = {self.memory!r} is "
                               f"unknown; use one of {', '.join(MEMORY_MODES)}", param="memory")

    def world_model(self) -> WorldModelParams:
        """The planner's world-model settings."""
        return WorldModelParams(memory=self.memory, memory_s=self.memory_s,
                                cell_m=self.memory_cell_m, predict=self.predict)


@dataclass(frozen=True)
class RunResult:
    """One closed-loop run: trajectory, metrics and what was sensed.

    ``trajectory`` has TRAJECTORY_COLUMNS plus ``status`` (the planner's status per
    step), ``metrics`` the METRICS_COLUMNS without ``case``, and ``ranges`` is what was
    sensed, as a range table (RANGES_COLUMNS, DESIGN §12; fused_source
    ``truth`` for perfect sensing) that ``slitcli dwa`` can replay.
    """

    trajectory: pd.DataFrame
    metrics: dict[str, float | bool | str]
    ranges: pd.DataFrame


class _Truth:
    """True clearance of the robot's disc, with moving objects placed at each instant."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.static = obstacle_geometry(scene)

    def clearance(self, xy: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Signed distance (K,) from centres ``xy`` (K, 2) at times ``t_s`` (K,)."""
        if not self.scene.is_dynamic:
            return clearance_m(self.static, xy)
        return np.array([clearance_m(obstacle_geometry(self.scene.at_time(float(t))),
                                     xy[i:i + 1])[0] for i, t in enumerate(t_s)])


def _stuck(xy: np.ndarray, t: np.ndarray, sim: SimParams) -> bool:
    """No new ground in the last ``stuck_timeout_s`` (see :class:`SimParams`)."""
    before = t < t[-1] - sim.stuck_timeout_s
    if not before.any():
        return False
    old, recent = xy[before], xy[~before]
    d = np.hypot(recent[:, None, 0] - old[None, :, 0], recent[:, None, 1] - old[None, :, 1])
    return not bool((d.min(axis=1) > sim.stuck_new_ground_m).any())


def _backup(pose: tuple[float, float, float], static_world: np.ndarray, sim: SimParams,
            footprint_m: float) -> float:
    """Speed (<= 0) of a back-up move: 0 if a remembered point lies in the way behind."""
    pts = to_robot(pose, static_world)
    behind = (pts[:, 0] < 0) & (pts[:, 0] > -(sim.recovery_back_m + footprint_m)) & \
        (np.abs(pts[:, 1]) < footprint_m)
    return 0.0 if behind.any() else -sim.recovery_speed_mps


def _end(here: float, dist: float, v: float, last: bool, may_be_stuck: bool,
         rows: list[tuple[float, ...]], dwa: DwaParams, sim: SimParams) -> str:
    """Why the run ends at this step ('' = it goes on)."""
    if here <= 0:
        return "collided"
    if dist <= dwa.goal_close_m and abs(v) <= 1e-12:
        return "reached"
    if may_be_stuck and _stuck(np.array([r[1:3] for r in rows]),
                               np.array([r[0] for r in rows]), sim):
        return "stuck"
    return "timeout" if last else ""


def _plan(pose: tuple[float, float, float], v: float, w: float, goal: np.ndarray,
          static_w: np.ndarray, moving_w: MovingDiscs, dwa: DwaParams
          ) -> tuple[float, float, str]:
    """One planning step from the world model (world frame) at ``pose``."""
    cmd = plan_step(max(v, 0.0), w, to_robot(pose, goal[None])[0], to_robot(pose, static_w),
                    dwa, moving_to_robot(pose, moving_w))
    return cmd.v_mps, cmd.w_rps, cmd.status


def run_world(world: World, sensor: Sensor, dwa: DwaParams, sim: SimParams) -> RunResult:
    """Drive the robot from the world's start towards its goal (one closed-loop run).

    The run ends when the robot stands inside the goal radius, collides, gets stuck
    (:class:`SimParams`) or runs out of time.

    The planner's footprint radius is the robot radius plus ``sim.safety_margin_m``
    (``dwa.footprint_radius_m`` is replaced). Each trajectory row holds the pose at
    ``t_s``, the command chosen there and held until the next row, and the true
    clearance between the robot's disc and the nearest obstacle (moving objects where
    they are at that instant; checked at ``substeps`` instants per period).
    """
    scene = world.scene
    radius = scene.robot.radius_m
    dwa = replace(dwa, footprint_radius_m=radius + sim.safety_margin_m)
    truth = _Truth(scene)
    model = WorldModel(sim.world_model())
    goal = np.asarray(scene.goal_xy_m, dtype=float)
    s0 = scene.robot.start
    pose = (s0.x_m, s0.y_m, s0.yaw_rad)
    v = w = 0.0
    steps = math.ceil(sim.max_time_s / dwa.dt_s)
    sub_t = np.arange(1, sim.substeps + 1) * (dwa.dt_s / sim.substeps)
    rows: list[tuple[float, ...]] = []
    statuses: list[str] = []
    scans: list[RangeScan] = []
    here = float(truth.clearance(np.array([pose[:2]]), np.zeros(1))[0] - radius)
    min_clear = initial = here
    path = 0.0
    best_goal = math.inf
    best_t = 0.0
    recovery = _Recovery(pose, sim, dwa)
    t_goal = math.nan
    outcome = "timeout"
    for k in range(steps + 1):
        t = k * dwa.dt_s
        dist = float(math.hypot(*(goal - pose[:2])))
        if dist <= dwa.goal_close_m and math.isnan(t_goal):
            t_goal = t
        if dist < best_goal - sim.stuck_progress_m:
            best_goal, best_t = dist, t
        end = _end(here, dist, v, k == steps, t - best_t > sim.stuck_timeout_s and k % 5 == 0,
                   rows, dwa, sim)
        if end:
            rows.append((t, *pose[:2], math.degrees(pose[2]), 0.0, 0.0, here))
            statuses.append("goal" if end == "reached" else end)
            outcome = end
            break
        scan = sensor(Pose2D(*pose), k, t)
        scans.append(scan)
        static_w, moving_w = model.update(pose, scan.bearing_deg, scan.range_m, scan.forward_m,
                                          scan.free_m, t)
        v_back = recovery.speed(pose, t, dist, static_w)
        cmd_v, cmd_w, status = (v_back, 0.0, "recover") if v_back < 0 else \
            _plan(pose, v, w, goal, static_w, moving_w, dwa)
        rows.append((t, *pose[:2], math.degrees(pose[2]), cmd_v, math.degrees(cmd_w), here))
        statuses.append(status)
        along, clear, lowest = _advance(truth, radius, pose, cmd_v, cmd_w, t, sub_t)
        min_clear = min(min_clear, lowest)
        here = float(clear[-1])
        path += abs(cmd_v) * (len(along) * dwa.dt_s / sim.substeps)
        pose = tuple(float(x) for x in along[-1])
        v, w = cmd_v, cmd_w
    traj = pd.DataFrame(rows, columns=list(TRAJECTORY_COLUMNS))
    traj["status"] = statuses
    ranges = _range_table(scans, dwa.dt_s)
    metrics = {
        "initial_distance_m": initial,
        "reached_goal": outcome == "reached",
        "collided": outcome == "collided",
        "min_clearance_m": min_clear,
        "time_to_goal_s": t_goal if outcome == "reached" else math.nan,
        "path_length_m": path,
        "outcome": outcome,
    }
    return RunResult(traj, metrics, ranges)


def _advance(truth: _Truth, radius_m: float, pose: tuple[float, float, float], v_mps: float,
             w_radps: float, t_s: float, sub_t_s: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, float]:
    """Move the robot under one command for one period: the poses (n, 3) at the
    sub-step instants ``t_s + sub_t_s``, stopped at the first contact, the clearance
    (m) of the robot's disc at each, and the smallest clearance over the whole period
    (the command as if no contact stopped it)."""
    along = unicycle(pose, v_mps, w_radps, sub_t_s)
    clear = truth.clearance(along[:, :2], t_s + sub_t_s) - radius_m
    lowest = float(clear.min())
    hit = np.flatnonzero(clear <= 0)
    if len(hit):  # stop at the first contact
        along, clear = along[: hit[0] + 1], clear[: hit[0] + 1]
    return along, clear, lowest


class _Recovery:
    """Backing up out of a dead end: when the robot has moved less than
    ``stuck_progress_m`` for ``recovery_after_s`` away from the goal, it reverses
    ``recovery_back_m`` at ``recovery_speed_mps`` (as far as the map behind it is free,
    :func:`_backup`), then plans again."""

    def __init__(self, pose: tuple[float, float, float], sim: SimParams, dwa: DwaParams):
        self.sim, self.dwa = sim, dwa
        self.still_xy, self.still_t = np.array(pose[:2]), 0.0
        self.backing = 0

    def speed(self, pose: tuple[float, float, float], t_s: float, goal_dist_m: float,
              static_w: np.ndarray) -> float:
        """The reversing speed (m/s, < 0) for this period, or 0 to plan as usual."""
        sim, dwa = self.sim, self.dwa
        if np.hypot(*(np.array(pose[:2]) - self.still_xy)) > sim.stuck_progress_m:
            self.still_xy, self.still_t = np.array(pose[:2]), t_s
        if (sim.recovery_after_s > 0 and t_s - self.still_t > sim.recovery_after_s
                and goal_dist_m > dwa.goal_close_m and self.backing == 0):
            self.backing = math.ceil(sim.recovery_back_m / (sim.recovery_speed_mps * dwa.dt_s))
            self.still_t = t_s
        v_back = _backup(pose, static_w, sim, dwa.footprint_radius_m) if self.backing else 0.0
        self.backing = self.backing - 1 if v_back < 0 else 0
        return v_back


def _range_table(scans: list[RangeScan], dt_s: float) -> pd.DataFrame:
    """The scans of one run as a DESIGN §12 range table (sensed truth in fused_range_m)."""
    if not scans:
        return pd.DataFrame(columns=list(RANGES_COLUMNS))
    n = np.array([len(s.bearing_deg) for s in scans])
    frame = np.repeat(np.arange(len(scans)), n)
    rng = np.concatenate([s.range_m for s in scans])
    return pd.DataFrame({
        "frame": frame, "time_s": frame * dt_s,
        "bearing_deg": np.concatenate([s.bearing_deg for s in scans]),
        "laser_range_m": np.nan, "stereo_range_m": np.nan, "stereo_has_features": np.nan,
        "fused_range_m": rng, "fused_source": np.where(np.isfinite(rng), "truth", "none"),
    }, columns=list(RANGES_COLUMNS))


# ------------------------------------------------------------------ batches and output
@dataclass(frozen=True)
class Case:
    """One run of a batch: a name (the ``case`` column), a world and a sensing range."""

    name: str
    world: World
    sensing_range_m: float


def run_cases(cases: Sequence[Case], rig: Rig, dwa: DwaParams, sim: SimParams, *,
              sensing: str = "perfect", bin_deg: float = 1.0
              ) -> tuple[pd.DataFrame, dict[str, RunResult]]:
    """Run every case with the ``sensing`` mode; the metrics table and each case's result."""
    factory = _sensor_factory(sensing)
    rows = []
    trajs: dict[str, RunResult] = {}
    with progress_bar(len(cases), "simulate-dwa", unit="run") as bar:
        for c in cases:
            sensor = factory(c.world.scene, rig, c.sensing_range_m, bin_deg=bin_deg)
            res = run_world(c.world, sensor, dwa, sim)
            rows.append({"case": c.name, "sensing_range_m": c.sensing_range_m, **res.metrics})
            trajs[c.name] = res
            bar.update()
    return pd.DataFrame(rows, columns=list(METRICS_COLUMNS)), trajs


def _sensor_factory(sensing: str) -> SensorFactory:
    if sensing not in SENSING_MODES:
        raise SlitcliError(f"`sensing` {sensing!r} is not available; use one of "
                           f"{', '.join(SENSING_MODES)}", param="sensing")
    return SENSING_MODES[sensing]


def build_cases(*, world_path: str | Path | None = None, scenario: str | None = None,
                sensing_ranges_m: Sequence[float] | None = None, worlds: int = 100,
                seed: int = 0, start: tuple[float, float, float] | None = None,
                goal_xy_m: tuple[float, float] | None = None) -> list[Case]:
    """The runs of one ``simulate-dwa`` call.

    Exactly one of ``world_path`` (a world file) and ``scenario`` (``paper``: the paper's
    scenario, default sensing ranges 0.6, 1, 1.5, 2 m; ``random``: ``worlds`` seeded
    random worlds from ``seed`` on, default sensing range 3 m). A world file's default
    sensing range is 3 m. Case names: ``range_<r>m`` per sensing range, ``random_<seed>``
    per random world (with ``_range_<r>m`` appended when several ranges are given).
    """
    if (world_path is None) == (scenario is None):
        raise SlitcliError("simulate-dwa: give either a world file (`world_path`) or "
                           "`scenario` (paper or random), not both and not neither",
                           param=("world_path", "scenario"))
    if scenario is not None and (start is not None or goal_xy_m is not None):
        raise SlitcliError("`start` and `goal_xy_m` apply to a world file, not to `scenario`",
                           param=("start", "goal_xy_m", "scenario"))
    ranges = list(sensing_ranges_m) if sensing_ranges_m else None
    for r in ranges or []:
        if not (r > 0 and math.isfinite(r)):
            raise SlitcliError(f"`sensing_ranges_m` {r:g} must be > 0 m",
                               param="sensing_ranges_m")

    def tag(r: float) -> str:
        return f"range_{r:g}m"

    if scenario == "paper":
        w = paper_world()
        return [Case(tag(r), w, r) for r in (ranges or PAPER_SENSING_RANGES_M)]
    if scenario == "random":
        if not 1 <= worlds <= MAX_WORLDS:
            raise SlitcliError(f"`worlds` {worlds} must be 1 to {MAX_WORLDS}", param="worlds")
        ranges = ranges or [3.0]
        out = []
        for s in range(seed, seed + worlds):
            w = random_world(s)
            out.extend(Case(w.name if len(ranges) == 1 else f"{w.name}_{tag(r)}", w, r)
                       for r in ranges)
        return out
    if scenario == "hard":
        rs = ranges or list(HARD_SENSING_RANGES_M)
        return [Case(f"{w.name}_{tag(r)}", w, r) for w in hard_worlds() for r in rs]
    if scenario == "dynamic":
        rs = ranges or [3.0]
        out = []
        for dc in dynamic_cases():
            for w in (dc.world, dc.empty):
                out.extend(Case(w.name if len(rs) == 1 else f"{w.name}_{tag(r)}", w, r)
                           for r in rs)
        return out
    if scenario is not None:
        raise SlitcliError(f"`scenario` {scenario!r} is unknown; use paper, random, hard or "
                           "dynamic", param="scenario")
    w = load_world(world_path, start=start, goal_xy_m=goal_xy_m)
    return [Case(tag(r), w, r) for r in (ranges or [3.0])]


def simulate_dwa(out_dir: str | Path, rig: Rig, dwa: DwaParams, sim: SimParams, *,
                 sensing: str = "perfect", world_path: str | Path | None = None,
                 scenario: str | None = None,
                 sensing_ranges_m: Sequence[float] | None = None, worlds: int = 100,
                 seed: int = 0, start: tuple[float, float, float] | None = None,
                 goal_xy_m: tuple[float, float] | None = None, bin_deg: float = 1.0,
                 overwrite: bool = False, save_ranges: bool = False,
                 inputs: Sequence[str | Path] = ()) -> pd.DataFrame:
    """``slitcli simulate-dwa``: :func:`build_cases` then :func:`simulate_to_folder`.

    ``inputs`` (the world and rig files) are never replaced by ``overwrite``.
    """
    check_output_folder(out_dir, overwrite=overwrite, inputs=[world_path, *inputs])
    if not (0.05 <= bin_deg <= 10):
        raise SlitcliError(f"`bin_deg` {bin_deg:g} must be in [0.05, 10] degrees",
                           param="bin_deg")
    steps = sim.max_time_s / dwa.dt_s
    if steps > MAX_STEPS:
        raise SlitcliError(f"`max_time_s` {sim.max_time_s:g} / `dt_s` {dwa.dt_s:g} = "
                           f"{steps:.3g} control steps per run, more than {MAX_STEPS}; raise "
                           "`dt_s` or lower `max_time_s`", param=("max_time_s", "dt_s"))
    cases = build_cases(world_path=world_path, scenario=scenario,
                        sensing_ranges_m=sensing_ranges_m, worlds=worlds, seed=seed,
                        start=start, goal_xy_m=goal_xy_m)
    return simulate_to_folder(cases, out_dir, rig, dwa, sim, sensing=sensing,
                              overwrite=overwrite, bin_deg=bin_deg, save_ranges=save_ranges,
                              inputs=[world_path, *inputs])


def simulate_to_folder(cases: Sequence[Case], out_dir: str | Path, rig: Rig, dwa: DwaParams,
                       sim: SimParams, *, sensing: str = "perfect", overwrite: bool = False,
                       bin_deg: float = 1.0, save_ranges: bool = False,
                       inputs: Sequence[str | Path] = ()) -> pd.DataFrame:
    """Run the cases and write OUT/ atomically (docs/dwa.md).

    Files: ``trajectory_<case>.csv``, ``metrics.csv``, the world(s) (``world.yaml``, or
    ``world_<name>.yaml`` for several), ``params.yaml`` (every planner and simulation
    parameter used) and, with ``save_ranges``, ``ranges_<case>.csv`` (what was sensed).
    Returns the metrics table.
    """
    if not cases:
        raise SlitcliError("simulate-dwa: nothing to run; give a world file or `scenario`",
                           param="scenario")
    _sensor_factory(sensing)
    metrics, trajs = run_cases(cases, rig, dwa, sim, sensing=sensing, bin_deg=bin_deg)
    worlds = {c.world.name: c.world for c in cases}
    with atomic_directory(out_dir, overwrite=overwrite, inputs=inputs) as tmp:
        for name, res in trajs.items():
            write_csv_atomic(tmp / f"trajectory_{name}.csv",
                             times_as_text(res.trajectory[list(TRAJECTORY_COLUMNS)]))
            if save_ranges:
                # ten digits: a replay with `slitcli dwa` then makes the same choices
                write_csv_atomic(tmp / f"ranges_{name}.csv", times_as_text(res.ranges),
                                 float_format="%.10g")
        out = times_as_text(metrics)
        out["reached_goal"] = out["reached_goal"].astype(int)
        out["collided"] = out["collided"].astype(int)
        write_csv_atomic(tmp / "metrics.csv", out)
        for name, w in worlds.items():
            fname = "world.yaml" if len(worlds) == 1 else f"world_{name}.yaml"
            write_text_atomic(tmp / fname, w.yaml_text)
        planner = {k: v for k, v in asdict(dwa).items() if k != "footprint_radius_m"}
        params = {"slitcli_dwa_run": 1, "sensing": sensing, "bin_deg": bin_deg,
                  "dwa": planner, "sim": asdict(sim),
                  "cases": [{"case": c.name, "world": c.world.name,
                             "sensing_range_m": c.sensing_range_m,
                             "footprint_radius_m": c.world.scene.robot.radius_m
                             + sim.safety_margin_m} for c in cases]}
        write_text_atomic(tmp / "params.yaml", yaml.safe_dump(params, sort_keys=False))
    return metrics
