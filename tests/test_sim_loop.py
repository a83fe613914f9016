"""Closed-loop DWA simulation, worlds, clearance geometry and the two commands."""

import math

import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.dwa import DwaParams
from slitcli.errors import SlitcliError
from slitcli.rig import paper_rig
from slitcli.sim.clearance import clearance_m, object_distances, obstacle_geometry
from slitcli.sim.loop import (
    METRICS_COLUMNS,
    TRAJECTORY_COLUMNS,
    Case,
    SimParams,
    perfect_sensor,
    run_cases,
    run_world,
)
from slitcli.sim.scene import Pose2D, load_scene, scene_from_dict
from slitcli.sim.worlds import (
    RandomWorldParams,
    _has_free_path,
    paper_world,
    random_world,
    world_from_dict,
)

RIG = paper_rig()
BOX_FACE_X = 2.85          # paper world: near face of the box, 3.0 - 0.3 / 2


def _scene(objects, **extra):
    return scene_from_dict({"slitcli_scene": 1, "name": "t", "objects": objects, **extra})


# ---------------------------------------------------------------- clearance geometry
def test_signed_distances_hand_values():
    s = _scene([
        {"type": "box", "centre_xy_m": [2.0, 0.0], "size_m": [1.0, 0.5, 0.5]},
        {"type": "cylinder", "centre_xy_m": [0.0, 3.0], "radius_m": 0.5, "height_m": 0.5},
        {"type": "wall", "from_xy_m": [-1.0, -2.0], "to_xy_m": [1.0, -2.0], "height_m": 1.0},
        {"type": "box", "centre_xy_m": [0.0, 0.0], "size_m": [0.4, 0.4, 0.3], "z_min_m": 1.0},
        {"type": "box", "centre_xy_m": [-3.0, 0.0], "size_m": [1.0, 1.0, 0.5], "yaw_deg": 45},
    ])
    g = obstacle_geometry(s)
    pts = np.array([[2.0, 0.0], [3.5, 0.0], [3.5, 1.25], [0.0, 4.0], [0.0, 3.0], [0.0, -1.0],
                    [2.0, -2.5], [-3.0 + 1.0, 0.0]])
    d = object_distances(g, pts)
    assert d[0, 0] == pytest.approx(-0.25)                 # inside the box, 0.25 from y edges
    assert d[1, 0] == pytest.approx(1.0)
    assert d[2, 0] == pytest.approx(math.hypot(1.0, 1.0))  # nearest is the corner (2.5, 0.25)
    assert d[3, 1] == pytest.approx(0.5) and d[4, 1] == pytest.approx(-0.5)
    assert d[5, 2] == pytest.approx(1.0)
    assert d[6, 2] == pytest.approx(math.hypot(1.0, 0.5))  # beyond the wall's end (1, -2)
    assert np.all(np.isinf(d[:, 3]))                       # hangs above the robot (0.8 m)
    assert d[7, 4] == pytest.approx(1.0 - math.sqrt(0.5))  # 45 deg box: corner at x = -2.29
    assert clearance_m(g, pts[:1])[0] == pytest.approx(-0.25)


# ---------------------------------------------------------------- sensing
def test_perfect_sensor_is_cut_at_the_sensing_range():
    w = paper_world()
    for r in (0.6, 1.0, 1.5, 2.0):
        sen = perfect_sensor(w.scene, RIG, r)
        assert np.all(np.isnan(sen(w.scene.robot.start, 0).range_m))      # never at the start
        just_out = sen(Pose2D(BOX_FACE_X - r - 0.01, 0.0, 0.0), 0).range_m
        just_in = sen(Pose2D(BOX_FACE_X - r + 0.01, 0.0, 0.0), 0).range_m
        assert np.all(np.isnan(just_out))
        assert np.nanmin(just_in) == pytest.approx(r - 0.01, abs=1e-9)    # straight ahead
    sen = perfect_sensor(w.scene, RIG, 3.0)
    assert sen.bearing_deg[0] == -32 and sen.bearing_deg[-1] == 32       # +-32.6 deg FOV


# ---------------------------------------------------------------- the paper scenario
@pytest.fixture(scope="module")
def paper_runs():
    w = paper_world()
    return run_cases([Case(f"range_{r:g}m", w, r) for r in (0.6, 1.0, 1.5, 2.0)], RIG,
                     DwaParams(), SimParams())


def test_paper_scenario_four_cases_no_collision(paper_runs):
    metrics, runs = paper_runs
    assert list(metrics.columns) == list(METRICS_COLUMNS)
    assert metrics["reached_goal"].all() and not metrics["collided"].any()
    assert (metrics["min_clearance_m"] > 0).all()
    assert metrics["initial_distance_m"].to_numpy() == pytest.approx(BOX_FACE_X - 0.25)
    # no run can beat the straight 5.7 m to the goal circle at 0.2 m/s
    assert (metrics["time_to_goal_s"] >= 5.7 / 0.2).all()
    assert (metrics["path_length_m"] >= 5.7 - 1e-9).all()
    for r, res in zip((0.6, 1.0, 1.5, 2.0), runs.values(), strict=True):
        t = res.trajectory
        # the cases differ only once the box is in sensing range: before that the robot
        # drives straight along y = 0
        before = t[t["x_m"] + r < BOX_FACE_X]
        assert (before["w_dps"] == 0).all() and (before["y_m"].abs() < 1e-12).all()
        assert len(before) > 5
        final = t.iloc[-1]
        assert final["v_mps"] == 0 and final["w_dps"] == 0
        assert math.hypot(final["x_m"] - 6.0, final["y_m"]) <= DwaParams().goal_close_m


def test_discrete_braking_keeps_the_safety_margin(paper_runs):
    # At 0.6 m and 1 m sensing the robot cannot swerve at 0.2 m/s (turn radius 1.53 m)
    # and stops in front of the box: it must stop before its inflated footprint touches.
    metrics, _ = paper_runs
    margin = SimParams().safety_margin_m
    stops = metrics.set_index("case").loc[["range_0.6m", "range_1m"], "min_clearance_m"]
    assert stops.min() >= margin - 1e-9
    # swerving past it, the box is seen as one point per 1 deg bin at the bin centre: a
    # point can sit up to range x half a bin (1.7 cm at 2 m) off the true outline
    assert metrics["min_clearance_m"].min() >= margin - 2.0 * math.radians(0.5)
    # the paper's continuous condition v <= sqrt(2 D acc) ignores the v T / 2 driven while
    # the command is held, and the robot ends up about 1 cm inside its margin
    lit, _ = run_cases([Case("range_1m", paper_world(), 1.0)], RIG,
                       DwaParams(discrete_braking=False), SimParams())
    assert 0 < lit["min_clearance_m"].iloc[0] < margin - 0.005


def test_obstacle_memory_keeps_the_box_out_of_view():
    # The camera sees +-32 deg only: passing the box, the robot loses sight of it while
    # its side is still beside it. The memory must keep the box until the robot is past:
    # the planner's footprint (radius + 0.05 m margin) never overlaps it, with the only
    # slack the bin-centre placement of a remembered point (range x half a bin, 1.7 cm
    # at 2 m).
    w = paper_world()
    cases = [Case("range_1m", w, 1.0), Case("range_2m", w, 2.0)]
    m, runs = run_cases(cases, RIG, DwaParams(), SimParams())
    assert not m["collided"].any() and m["reached_goal"].all()
    assert m["min_clearance_m"].min() >= SimParams().safety_margin_m - 2.0 * math.radians(0.5)
    for res in runs.values():
        t = res.trajectory
        # the robot was beside the box (its x range) with the box out of view
        beside = t[(t["x_m"] > 2.85) & (t["x_m"] < 3.15)]
        assert len(beside) > 3


# ---------------------------------------------------------------- random worlds
@pytest.mark.parametrize("first_seed", [0, 100, 200, 300, 400])
def test_random_worlds_subset_no_collision(first_seed):
    # docs/dwa.md reports 100 worlds (bench/dwa_worlds.py, simulate-dwa --scenario
    # random); here 3 worlds from each of 5 seed ranges
    worlds = [random_world(s) for s in range(first_seed, first_seed + 3)]
    metrics, _ = run_cases([Case(w.name, w, 3.0) for w in worlds], RIG, DwaParams(),
                           SimParams())
    assert not metrics["collided"].any()
    assert metrics["reached_goal"].sum() >= 2
    assert set(metrics.loc[~metrics["reached_goal"], "outcome"]) <= {"stuck", "timeout"}
    assert (metrics["min_clearance_m"] > 0).all()


@pytest.mark.parametrize("first_seed", [0, 100, 200, 300, 400])
def test_random_world_generator_is_seeded_and_has_a_free_path(first_seed):
    a, b = random_world(first_seed + 5), random_world(first_seed + 5)
    assert a.yaml_text == b.yaml_text and a.yaml_text != random_world(first_seed + 6).yaml_text
    p = RandomWorldParams()
    for s in range(first_seed, first_seed + 3):
        w = random_world(s)
        assert _has_free_path(w.scene, p)
        kinds = {type(o).__name__ for o in w.scene.objects}
        assert kinds <= {"Box", "Cylinder"}
        assert p.min_objects <= len(w.scene.objects) <= p.max_objects
    blocked = world_from_dict({"slitcli_scene": 1, "name": "blocked", "objects": [
        {"type": "box", "centre_xy_m": [4.0, 0.0], "size_m": [0.5, 6.0, 0.5]}],
        "robot": {"start": [0, 0, 0]}, "goal_xy_m": [8.0, 0.0]}, "t")
    assert not _has_free_path(blocked.scene, p)


# ---------------------------------------------------------------- stuck, arrival
def test_unreachable_goal_is_reported_stuck_not_collided():
    walls = [[3, -1, 3, 1], [3, 1, 5, 1], [5, 1, 5, -1], [5, -1, 3, -1]]      # a closed room
    w = world_from_dict({"slitcli_scene": 1, "name": "room", "objects": [
        {"type": "wall", "from_xy_m": q[:2], "to_xy_m": q[2:], "height_m": 0.5} for q in walls],
        "robot": {"start": [0, 0, 0]}, "goal_xy_m": [4.0, 0.0]}, "t")
    res = run_world(w, perfect_sensor(w.scene, RIG, 3.0), DwaParams(),
                    SimParams(stuck_timeout_s=20.0, max_time_s=200.0))
    assert res.metrics["outcome"] == "stuck"
    assert not res.metrics["collided"] and res.metrics["min_clearance_m"] > 0
    assert res.trajectory["status"].iloc[-1] == "stuck"


def test_arrival_brakes_once_and_stops_without_dithering():
    w = world_from_dict({"slitcli_scene": 1, "name": "open", "objects": [],
                         "robot": {"start": [0, 0, 30]}, "goal_xy_m": [3.0, 0.5]}, "t")
    res = run_world(w, perfect_sensor(w.scene, RIG, 3.0), DwaParams(), SimParams())
    t = res.trajectory
    assert res.metrics["outcome"] == "reached"
    dist = np.hypot(t["x_m"] - 3.0, t["y_m"] - 0.5)
    inside = np.flatnonzero(dist <= 0.3)
    assert inside[0] > 0 and np.all(np.diff(inside) == 1)        # enters once, stays
    v_in = t["v_mps"].to_numpy()[inside]
    assert np.all(np.diff(v_in) <= 1e-12) and v_in[-1] == 0     # only braking inside
    assert t["w_dps"].iloc[-1] == 0 and t["status"].iloc[-1] == "goal"
    assert res.metrics["time_to_goal_s"] == pytest.approx(t["t_s"].iloc[inside[0]])


# ---------------------------------------------------------------- bad worlds
def test_start_in_collision_and_goal_inside_are_refused():
    box = [{"type": "box", "centre_xy_m": [2.0, 0.0], "size_m": [1.0, 1.0, 0.5]}]
    with pytest.raises(SlitcliError, match="collision with objects\\[0\\]"):
        world_from_dict({"slitcli_scene": 1, "objects": box,
                         "robot": {"start": [1.3, 0, 0]}, "goal_xy_m": [5, 0]}, "w.yaml")
    with pytest.raises(SlitcliError, match="inside objects\\[0\\]"):
        world_from_dict({"slitcli_scene": 1, "objects": box, "goal_xy_m": [2.2, 0.1]},
                        "w.yaml")
    with pytest.raises(SlitcliError, match="no goal"):
        world_from_dict({"slitcli_scene": 1, "objects": box}, "w.yaml")


# ---------------------------------------------------------------- the commands
def _one_line_exit_2(result):
    assert result.exit_code == 2, result.output
    lines = [x for x in result.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in result.stderr
    return lines[0]


def test_simulate_dwa_and_offline_replay_end_to_end(tmp_path):
    out = tmp_path / "dwa"
    r = CliRunner().invoke(cli, ["simulate-dwa", "--scenario", "paper", "--sensing-range",
                                 "1.5", "--save-ranges", "-o", str(out)])
    assert r.exit_code == 0, r.output
    names = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert names == ["metrics.csv", "params.yaml", "ranges_range_1.5m.csv",
                     "trajectory_range_1.5m.csv", "world.yaml"]
    m = pd.read_csv(out / "metrics.csv")
    assert list(m.columns) == list(METRICS_COLUMNS)
    assert m["reached_goal"].tolist() == [1] and m["collided"].tolist() == [0]
    t = pd.read_csv(out / "trajectory_range_1.5m.csv")
    assert list(t.columns) == list(TRAJECTORY_COLUMNS)
    # the obstacle geometry is recoverable for the figures
    scene = load_scene(out / "world.yaml")
    assert scene.objects == paper_world().scene.objects and scene.goal_xy_m == (6.0, 0.0)
    assert yaml.safe_load((out / "params.yaml").read_text())["dwa"]["v_max_mps"] == 0.2
    # Offline DWA over the sensed range table: the simulated robot moved exactly as
    # commanded, so the offline planner must reproduce every command and pose, given
    # the same footprint (0.25 m robot + 0.07 m margin) and the same trust in "no
    # return" (perfect sensing: nothing within its 1.5 m range)
    cmds = tmp_path / "cmds.csv"
    r = CliRunner().invoke(cli, ["dwa", str(out / "ranges_range_1.5m.csv"), "--goal", "6,0",
                                 "--footprint-radius-m", "0.32", "--free-range-m", "1.5",
                                 "-o", str(cmds)])
    assert r.exit_code == 0, r.output
    c = pd.read_csv(cmds)
    assert len(c) == len(t) - 1                        # the last row is the arrival
    np.testing.assert_allclose(c["v_mps"], t["v_mps"].iloc[:-1], atol=1e-9)
    np.testing.assert_allclose(c["w_dps"], t["w_dps"].iloc[:-1], atol=1e-6)
    np.testing.assert_allclose(c[["x_m", "y_m"]], t[["x_m", "y_m"]].iloc[:-1], atol=1e-5)
    # writing again into an existing folder needs --overwrite, and leaves it intact
    r = CliRunner().invoke(cli, ["simulate-dwa", "--scenario", "paper", "-o", str(out)])
    assert "--overwrite" in _one_line_exit_2(r)
    assert (out / "ranges_range_1.5m.csv").exists()


@pytest.mark.parametrize("world, extra, needle", [
    ({"objects": [{"type": "box", "centre_xy_m": [2, 0], "size_m": [1, 1, 0.5]}],
      "goal_xy_m": [2, 0]}, [], "inside objects[0]"),
    ({"objects": [{"type": "cylinder", "centre_xy_m": [0.3, 0], "radius_m": 0.2,
                   "height_m": 0.5}], "goal_xy_m": [4, 0]}, [], "in collision"),
    ({"objects": [], "goal_xy_m": [4, 0]}, ["--v-max-mps", "0"], "--v-max-mps"),
    ({"objects": [], "goal_xy_m": [4, 0]}, ["--v-max-mps", "-0.1"], "--v-max-mps"),
    ({"objects": [], "goal_xy_m": [4, 0]}, ["--dt-s", "0"], "--dt-s"),
    ({"objects": [], "goal_xy_m": [4, 0]}, ["--sensing-range", "1,x"], "--sensing-range"),
    ({"objects": []}, [], "no goal"),
])
def test_simulate_dwa_bad_input_exit_2_one_line(tmp_path, world, extra, needle):
    f = tmp_path / "w.yaml"
    f.write_text(yaml.safe_dump({"slitcli_scene": 1, **world}))
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["simulate-dwa", str(f), "-o", str(out), *extra])
    assert needle in _one_line_exit_2(r)
    assert not out.exists()


def test_dwa_offline_bad_input_exit_2_one_line(tmp_path):
    table = tmp_path / "ranges.csv"
    table.write_text("frame,time_s,bearing_deg,laser_range_m\n0,0,0,1.0\n")
    out = tmp_path / "cmds.csv"
    r = CliRunner().invoke(cli, ["dwa", str(table), "--goal", "3,0", "-o", str(out)])
    assert "fused_range_m" in _one_line_exit_2(r)
    r = CliRunner().invoke(cli, ["dwa", str(tmp_path / "none.csv"), "--goal", "3,0", "-o",
                                 str(out)])
    assert "not found" in _one_line_exit_2(r)
    table.write_text("frame,time_s,bearing_deg,fused_range_m\n0,0,0,1.0\n1,0,0,1.0\n")
    r = CliRunner().invoke(cli, ["dwa", str(table), "--goal", "3,0", "-o", str(out)])
    assert "time_s" in _one_line_exit_2(r)
    r = CliRunner().invoke(cli, ["dwa", str(table), "--goal", "3", "-o", str(out)])
    assert "--goal" in _one_line_exit_2(r)
    r = CliRunner().invoke(cli, ["dwa", str(table), "--goal", "3,0", "--dt-s", "-1", "-o",
                                 str(out)])
    assert "--dt-s" in _one_line_exit_2(r)
    assert not out.exists()


# ---------------------------------------------------------------- moving objects
PERSON = {"type": "cylinder", "radius_m": 0.25, "height_m": 1.7,
          "motion": {"waypoints": [{"t_s": 2.0, "xy_m": [3.5, -4.0]},
                                   {"t_s": 10.0, "xy_m": [3.5, 4.0]}]}}


def test_motion_waypoints_linear_and_held():
    from slitcli.sim.scene import centre_at

    s = _scene([PERSON])
    ob = s.objects[0]
    assert ob.centre_xy_m == (3.5, -4.0) and s.is_dynamic       # t = 0: held at the first
    for t, y in ((0.0, -4.0), (2.0, -4.0), (4.0, -2.0), (6.5, 0.5), (10.0, 4.0), (99.0, 4.0)):
        assert centre_at(ob.motion, t) == pytest.approx((3.5, y))
        assert s.at_time(t).objects[0].centre_xy_m == pytest.approx((3.5, y))
    with pytest.raises(SlitcliError, match="increasing time"):
        _scene([{**PERSON, "motion": {"waypoints": [{"t_s": 1.0, "xy_m": [0, 0]},
                                                    {"t_s": 1.0, "xy_m": [1, 0]}]}}])
    with pytest.raises(SlitcliError, match="centre_xy_m"):
        _scene([{**PERSON, "centre_xy_m": [0.0, 0.0]}])
    with pytest.raises(SlitcliError, match="unknown key"):
        _scene([{**PERSON, "motion": {"path": []}}])


def test_perfect_sensing_and_collisions_see_the_object_where_it_is():
    w = world_from_dict({"slitcli_scene": 1, "name": "p", "objects": [PERSON],
                         "robot": {"start": [0, 0, 0]}, "goal_xy_m": [8.0, 0.0]}, "t")
    sen = perfect_sensor(w.scene, RIG, 5.0)
    start = w.scene.robot.start
    # at t = 6 s the person stands on the robot's line 3.5 m ahead: the near surface is
    # 3.25 m from the rotation centre, minus the sensor's forward offset
    r = sen(start, 30, 6.0).range_m
    assert np.nanmin(r) == pytest.approx(3.25 - RIG.mount.forward_m, abs=1e-9)
    assert np.all(np.isnan(sen(start, 0, 0.0).range_m))        # far to the right at t = 0
    from slitcli.sim.loop import _Truth

    tr = _Truth(w.scene)
    d = tr.clearance(np.array([[3.5, 0.0], [3.5, 0.0]]), np.array([6.0, 0.0]))
    assert d[0] == pytest.approx(-0.25) and d[1] == pytest.approx(4.0 - 0.25)


def test_render_truth_follows_the_moving_object(tmp_path):
    from slitcli.sim.scene import Pose2D as P2
    from slitcli.sim.sequence import render_sequence
    from slitcli.sim.truth import true_ranges

    s = scene_from_dict({"slitcli_scene": 1, "name": "m", "objects": [
        {"type": "cylinder", "radius_m": 0.25, "height_m": 1.7,
         "motion": {"waypoints": [{"t_s": 0.0, "xy_m": [2.5, -0.6]},
                                  {"t_s": 0.4, "xy_m": [2.5, 0.6]}]}}],
        "robot": {"frames": 3, "frame_rate_hz": 5.0}, "image": {"supersample": 1}})
    render_sequence(s, RIG, tmp_path / "seq")
    gt = pd.read_csv(tmp_path / "seq" / "gt" / "ranges.csv")
    lo, hi = RIG.bearing_bins(1.0)[1:]
    for f, t in enumerate((0.0, 0.2, 0.4)):
        want = true_ranges(s.at_time(t), P2(0, 0, 0), lo, hi, forward_m=RIG.mount.forward_m)
        got = gt[gt["frame"] == f]["range_m"].to_numpy()
        np.testing.assert_allclose(got, want, atol=1e-6)
    # the person moved 1.2 m to the left: the nearest bearing moved left
    b = [gt[gt["frame"] == f].set_index("bearing_deg")["range_m"].idxmin() for f in (0, 2)]
    assert b[0] < -5 and b[1] > 5
    back = load_scene(tmp_path / "seq" / "scene.yaml")
    assert back.objects[0].motion == s.objects[0].motion


@pytest.mark.parametrize("name", ["cross_1mps_d0.7m", "oncoming"])
def test_dynamic_case_no_collision_and_on_time(name):
    from slitcli.sim.worlds import dynamic_cases

    dc = {d.name: d for d in dynamic_cases()}[name]
    m, _ = run_cases([Case(name, dc.world, 3.0), Case("empty", dc.empty, 3.0)], RIG,
                     DwaParams(), SimParams())
    assert not m["collided"].any() and m["reached_goal"].all()
    assert m["min_clearance_m"].iloc[0] >= 0.03
    assert m["time_to_goal_s"].iloc[0] <= 1.2 * m["time_to_goal_s"].iloc[1]


def test_stuck_rule_new_ground_not_distance():
    from slitcli.sim.loop import _stuck

    sim = SimParams(stuck_timeout_s=30.0, stuck_new_ground_m=0.5)
    t = np.arange(0, 90, 0.2)
    # a long detour away from the goal explores new ground all the time: not stuck
    detour = np.column_stack([-0.2 * t, np.zeros_like(t)])
    assert not _stuck(detour, t, sim)
    # circling a 0.8 m circle for 90 s: nothing new after the first lap
    a = t * 0.2 / 0.8
    circle = np.column_stack([0.8 * np.cos(a), 0.8 * np.sin(a)])
    assert _stuck(circle, t, sim)
    # turning on the spot
    assert _stuck(np.zeros((len(t), 2)), t, sim)
    # too early to judge
    assert not _stuck(np.zeros((10, 2)), t[:10], sim)


def test_recovery_backs_up_the_way_it_came_then_goes_on():
    # Paper box at 0.6 m sensing: the robot stops at its margin and turns in place for
    # 12 s. With recovery after 5 s standing it backs up 0.3 m (straight, v < 0) into
    # the free space it came from, then plans again and still arrives.
    w = paper_world()
    sim = SimParams(recovery_after_s=5.0, recovery_back_m=0.3)
    res = run_world(w, perfect_sensor(w.scene, RIG, 0.6), DwaParams(), sim)
    t = res.trajectory
    back = t[t["status"] == "recover"]
    assert len(back) > 0 and (back["v_mps"] < 0).all() and (back["w_dps"] == 0).all()
    moved = -back["v_mps"].sum() * DwaParams().dt_s
    assert moved == pytest.approx(0.3, abs=sim.recovery_speed_mps * DwaParams().dt_s + 1e-9)
    first = back.index[0]
    before = t.loc[:first][["x_m", "y_m"]].to_numpy()[-int(5.0 / 0.2) - 1:]
    # it had moved less than 5 cm over the 5 s before backing up
    assert np.hypot(*(before - before[-1]).T).max() <= sim.stuck_progress_m + 1e-9
    assert res.metrics["outcome"] == "reached" and not res.metrics["collided"]
    # without recovery (the default 20 s is longer than this 12 s turn) it never backs up
    plain = run_world(w, perfect_sensor(w.scene, RIG, 0.6), DwaParams(), SimParams())
    assert (plain.trajectory["status"] != "recover").all()
