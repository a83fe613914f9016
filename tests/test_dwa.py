"""The modified DWA planner (Eqs. 12-13) against hand-derived geometry and a loop reference."""

import math
from dataclasses import replace

import dwa_reference as ref  # tests/dwa_reference.py: the plain-loop reference
import numpy as np
import pytest

from slitcli.dwa import (
    DwaParams,
    admissible,
    collision_distance,
    dynamic_window,
    evaluate_pairs,
    goal_is_close,
    plan_step,
    velocity_term,
    window_pairs,
)
from slitcli.errors import SlitcliError
from slitcli.local_map import PointMemory, scan_points, to_robot, to_world, unicycle

P = DwaParams()
R = P.footprint_radius_m  # 0.3 m


def _cd(v, w, pts, d_max=3.0, radius=R):
    return collision_distance(np.atleast_1d(float(v)), np.atleast_1d(float(w)),
                              np.asarray(pts, dtype=float), radius_m=radius, d_max_m=d_max)[0]


# ---------------------------------------------------------------- window
def test_window_paper_sampling_about_1400_pairs():
    v, w = dynamic_window(0.1, 0.0, P)
    np.testing.assert_allclose(v, np.arange(6, 15) * 0.01, atol=1e-12)   # 0.1 +- 0.2 * 0.2
    assert len(w) == 151 and math.degrees(w[0]) == pytest.approx(-7.5)
    assert math.degrees(w[-1]) == pytest.approx(7.5) and 0.0 in w
    assert window_pairs(0.1, 0.0, P)[0].size == 1359
    v0, _ = dynamic_window(0.0, 0.0, P)
    np.testing.assert_allclose(v0, [0, 0.01, 0.02, 0.03, 0.04], atol=1e-12)
    vmax, _ = dynamic_window(0.2, 0.0, P)
    assert vmax.max() == pytest.approx(0.2) and vmax.min() == pytest.approx(0.16)
    # a slow turner: +-10 deg/s^2 * 0.2 s = +-2 deg/s around the current 3 deg/s
    _, ws = dynamic_window(0.1, math.radians(3.0), replace(P, ang_acc_dps2=10.0))
    np.testing.assert_allclose(np.degrees(ws), np.round(np.arange(1.0, 5.0001, 0.1), 1),
                               atol=1e-9)


# ---------------------------------------------------------------- D_collision
def test_d_collision_straight_line_to_a_wall():
    wall = np.column_stack([np.full(201, 1.0), np.linspace(-1, 1, 201)])
    assert _cd(0.1, 0.0, wall) == pytest.approx(1.0 - R, abs=1e-12)        # touches (1, 0)
    # only the points at y = +-0.2 remain: contact where the disc edge reaches them
    two = np.array([[1.0, 0.2], [1.0, -0.2]])
    assert _cd(0.2, 0.0, two) == pytest.approx(1.0 - math.sqrt(R**2 - 0.2**2), abs=1e-12)
    # a point 0.31 m beside the line is never touched; one behind is never touched
    assert _cd(0.2, 0.0, [[1.0, 0.31], [-1.0, 0.0]]) == 3.0
    # beyond D_max: capped
    assert _cd(0.2, 0.0, [[5.0, 0.0]]) == 3.0
    assert _cd(0.2, 0.0, [[2.0, 0.0]], d_max=1.0) == 1.0
    # rotation in place never moves the disc
    assert _cd(0.0, 0.1, wall) == 3.0


def test_d_collision_arc_passing_a_point():
    # v = 0.1 m/s, w = 0.1 rad/s: radius 1 m about (0, 1). The point (1, 1) lies on the
    # centre's path a quarter turn on; the disc first touches it when the centre is a
    # chord R short of it, i.e. 2 asin(R / 2) radians earlier.
    s_hand = math.pi / 2 - 2 * math.asin(R / 2)
    assert _cd(0.1, 0.1, [[1.0, 1.0]]) == pytest.approx(s_hand, abs=1e-12)
    assert _cd(0.1, -0.1, [[1.0, -1.0]]) == pytest.approx(s_hand, abs=1e-12)  # mirrored
    assert _cd(0.1, 0.1, [[1.0, -1.0]]) == 3.0                               # other side
    # (0.71, 1): 0.71 m from the turn centre, inside the swept ring [0.7, 1.3]; law of
    # cosines for the contact angle phi before the quarter turn.
    phi = math.acos((1 + 0.71**2 - R**2) / (2 * 0.71))
    assert _cd(0.1, 0.1, [[0.71, 1.0]]) == pytest.approx(math.pi / 2 - phi, abs=1e-12)
    assert _cd(0.1, 0.1, [[0.69, 1.0]]) == 3.0                                # outside ring
    # a point behind, reached after three quarters of the loop: 3 pi / 2 - 2 asin(R/2)
    s_loop = 3 * math.pi / 2 - 2 * math.asin(R / 2)
    assert _cd(0.1, 0.1, [[-1.0, 1.0]], d_max=6.0) == pytest.approx(s_loop, abs=1e-12)
    assert _cd(0.1, 0.1, [[-1.0, 1.0]]) == 3.0                                # capped
    # the distance is a property of the curvature: same arc at twice the speed
    assert _cd(0.2, 0.2, [[1.0, 1.0]]) == pytest.approx(s_hand, abs=1e-12)


def test_d_collision_points_inside_the_footprint():
    # ahead: every forward motion shrinks the distance -> 0; beside/behind: ignored
    assert _cd(0.1, 0.05, [[0.2, 0.1], [3.0, 0.0]]) == 0.0
    assert _cd(0.1, 0.0, [[-0.1, 0.2], [2.0, 0.0]]) == pytest.approx(2.0 - R)


@pytest.mark.parametrize("seed", range(5))
def test_d_collision_matches_brute_force_marching(seed):
    rng = np.random.default_rng(3 + 10 * seed)
    pts = rng.uniform([-1.5, -2.0], [2.5, 2.0], size=(25, 2))
    pts = pts[np.hypot(*pts.T) > R]
    v, w = window_pairs(0.1, 0.0, P)
    pick = rng.choice(v.size, 12, replace=False)
    d = collision_distance(v[pick], w[pick], pts, radius_m=R, d_max_m=3.0)
    for k, i in enumerate(pick):
        brute = min([ref.contact_marching(v[i], w[i], x, y, R, 3.0) for x, y in pts] + [3.0])
        assert d[k] == pytest.approx(brute, abs=2e-3)


@pytest.mark.parametrize("seed", range(5))
def test_d_collision_blocks_bound_memory_same_result(seed):
    rng = np.random.default_rng(4 + 10 * seed)
    pts = rng.uniform([-1, -2], [3, 2], size=(3000, 2))
    v, w = window_pairs(0.12, 0.0, P)
    d = collision_distance(v, w, pts, radius_m=0.05, d_max_m=3.0)
    d_parts = np.minimum.reduce([collision_distance(v, w, pts[i::3], radius_m=0.05, d_max_m=3.0)
                                 for i in range(3)])
    np.testing.assert_array_equal(d, d_parts)


# ---------------------------------------------------------------- admissibility
def test_admissibility_hand_values():
    # v = 0.2: stopping distance 0.2^2 / (2 * 0.2) = 0.1 m, plus v T / 2 = 0.02 m held
    ok = admissible(np.array([0.2, 0.2, 0.2]), np.zeros(3), np.array([0.119, 0.121, 3.0]), P)
    assert ok.tolist() == [False, True, True]
    lit = replace(P, discrete_braking=False)
    ok = admissible(np.array([0.2, 0.2]), np.zeros(2), np.array([0.099, 0.101]), lit)
    assert ok.tolist() == [False, True]
    # the turn: ang_acc 5 deg/s^2, v 0.1, w 7.5 deg/s -> needs D >= v |w| / (2 ang_acc)
    slow = replace(lit, ang_acc_dps2=5.0)
    w = math.radians(7.5)
    need = 0.1 * w / (2 * math.radians(5.0))                     # 0.075 m
    assert need > 0.1**2 / (2 * 0.2)                             # the v test alone passes
    ok = admissible(np.array([0.1, 0.1]), np.array([w, w]), np.array([need - 1e-3, need + 1e-3]),
                    slow)
    assert ok.tolist() == [False, True]
    assert admissible(np.array([0.0]), np.array([w]), np.array([0.0]), P).tolist() == [True]


@pytest.mark.parametrize("seed", range(5))
def test_a_pair_that_cannot_stop_in_time_is_never_chosen(seed):
    # Driving at 0.2 m/s towards a wall 0.115 m beyond the footprint: straight on at full
    # speed scores best on Eq. 12 but needs 0.12 m to stop, so it must not be chosen.
    wall = np.column_stack([np.full(81, R + 0.115), np.linspace(-2, 2, 81)])
    sc = evaluate_pairs(0.2, 0.0, (5.0, 0.0), wall, P)
    raw = P.alpha * sc.heading + P.beta * sc.clearance + P.gamma * sc.velocity
    best_raw = int(np.argmax(raw))
    assert sc.v_mps[best_raw] == pytest.approx(0.2) and not sc.admissible[best_raw]
    cmd = plan_step(0.2, 0.0, (5.0, 0.0), wall, P)
    assert cmd.status == "move" and cmd.v_mps < 0.2
    assert cmd.v_mps**2 / (2 * P.acc_mps2) + cmd.v_mps * P.dt_s / 2 <= cmd.d_collision_m + 1e-12
    # Seeded clutter: the chosen pair always stops in time by an independent D_collision.
    # (Scenes where nothing is admissible any more give "brake", checked separately.)
    rng = np.random.default_rng(7 + 10 * seed)
    checked = 0
    for _ in range(25):
        pts = rng.uniform([0.0, -1.5], [2.0, 1.5], size=(40, 2))
        pts = pts[np.hypot(*pts.T) > R + 0.02]
        v0 = float(rng.uniform(0, 0.2))
        cmd = plan_step(v0, 0.0, (4.0, float(rng.uniform(-2, 2))), pts, P)
        if cmd.status == "brake" or cmd.v_mps == 0:
            continue
        checked += 1
        d = ref.d_collision(cmd.v_mps, cmd.w_rps, [tuple(p) for p in pts], P)
        assert cmd.v_mps**2 / (2 * P.acc_mps2) + cmd.v_mps * P.dt_s / 2 <= d + 1e-9
    assert checked >= 15


def test_no_admissible_pair_brakes_on_the_arc():
    # an obstacle suddenly 5 cm beyond the footprint at full speed: nothing is admissible
    cmd = plan_step(0.2, math.radians(2.0), (5.0, 0.0), [[R + 0.05, 0.0]], P)
    assert cmd.status == "brake" and cmd.n_admissible == 0
    assert cmd.v_mps == pytest.approx(0.16) and cmd.w_rps == 0.0


# ---------------------------------------------------------------- Eq. 13
def test_eq13_switches_at_the_goal_radius():
    assert not goal_is_close(0.3001, 0.0, 0.2, P)
    assert goal_is_close(0.2999, 0.0, 0.2, P)
    np.testing.assert_allclose(velocity_term(np.array([0.0, 0.1, 0.2]), False, P), [0, 0.5, 1])
    np.testing.assert_allclose(velocity_term(np.array([0.0, 0.1, 0.2]), True, P), [1, 0.5, 0])
    # no obstacles, goal straight ahead: outside the radius the fastest reachable speed,
    # inside it the slowest (braking)
    far = plan_step(0.1, 0.0, (0.3 + 1e-6, 0.0), np.zeros((0, 2)), P)
    near = plan_step(0.1, 0.0, (0.3 - 1e-6, 0.0), np.zeros((0, 2)), P)
    assert far.v_mps == pytest.approx(0.14) and far.status == "move"
    assert near.v_mps == pytest.approx(0.06) and near.status == "goal"
    # standing inside the radius: (0, 0), no rotation towards the goal bearing
    stop = plan_step(0.0, 0.0, (0.05, 0.25), np.zeros((0, 2)), P)
    assert (stop.v_mps, stop.w_rps, stop.status) == (0.0, 0.0, "goal")


def test_eq13_turn_circle_reading():
    # at 0.2 m/s and 7.5 deg/s the turning circle has diameter 2 * 1.528 = 3.056 m: a goal
    # 90 deg to the left and nearer than that cannot be reached without slowing down
    diameter = 2 * 0.2 / math.radians(7.5)
    assert goal_is_close(diameter - 0.01, math.pi / 2, 0.2, P)
    assert not goal_is_close(diameter + 0.01, math.pi / 2, 0.2, P)
    assert not goal_is_close(diameter - 0.01, math.pi / 2, 0.2,
                             replace(P, turn_circle_close=False))
    assert not goal_is_close(1.0, 0.0, 0.2, P)                       # straight ahead: far
    cmd = plan_step(0.2, 0.0, (0.0, 2.0), np.zeros((0, 2)), P)
    assert cmd.v_mps == pytest.approx(0.16) and cmd.w_dps == pytest.approx(7.5)


# ---------------------------------------------------------------- stuck handling
def test_local_minimum_rotates_away_from_the_nearest_point():
    ys = np.linspace(-1.5, 1.5, 61) + 0.01          # nearest point slightly to the left
    wall = np.column_stack([np.full(61, R + 0.05), ys])
    cmd = plan_step(0.0, 0.0, (3.0, 0.0), wall, P)
    assert cmd.status == "rotate" and cmd.v_mps == 0.0
    assert cmd.w_dps == pytest.approx(-7.5)          # turn right, away from it
    wall[:, 1] -= 0.02                               # nearest now to the right
    assert plan_step(0.0, 0.0, (3.0, 0.0), wall, P).w_dps == pytest.approx(7.5)


# ---------------------------------------------------------------- array vs loop
@pytest.mark.parametrize("seed", range(5))
def test_array_step_matches_python_loop_reference(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-0.5, -2.0], [3.0, 2.0], size=(60, 2))
    pts = pts[np.hypot(*pts.T) > R + 0.01]
    v0, w0 = float(rng.uniform(0.05, 0.2)), float(rng.uniform(-0.1, 0.1))
    goal = (float(rng.uniform(1, 5)), float(rng.uniform(-3, 3)))
    cmd = plan_step(v0, w0, goal, pts, P)
    v, w, s = ref.choose(v0, w0, goal, [tuple(p) for p in pts], P)
    assert (cmd.v_mps, cmd.w_rps) == (v, w)
    assert cmd.score == pytest.approx(s, abs=1e-9)


# ---------------------------------------------------------------- parameters
@pytest.mark.parametrize("kw, option", [
    ({"v_max_mps": 0.0}, "--v-max-mps"), ({"v_max_mps": -0.2}, "--v-max-mps"),
    ({"dt_s": 0.0}, "--dt-s"), ({"dt_s": -1.0}, "--dt-s"), ({"acc_mps2": float("nan")}, "--acc"),
    ({"beta": -1.0}, "--beta"), ({"heading_clamp_deg": 200.0}, "--heading-clamp-deg"),
    ({"w_res_dps": 10.0}, "--w-res-dps"), ({"turn_circle_close": 1}, "turn-circle"),
])
def test_impossible_parameters_are_refused(kw, option):
    from slitcli.cli.main import user_message

    with pytest.raises(SlitcliError) as e:
        DwaParams(**kw)
    # the library names the parameter; the command line shows the user its option
    assert e.value.params == tuple(kw) and option in user_message(e.value)
    assert "\n" not in str(e.value)


# ---------------------------------------------------------------- frames and memory
def test_unicycle_quarter_circle_and_line():
    pose = unicycle((1.0, 2.0, 0.0), 0.1, 0.1, [math.pi / 2 / 0.1])[0]
    np.testing.assert_allclose(pose, [2.0, 3.0, math.pi / 2], atol=1e-12)
    pose = unicycle((0.0, 0.0, math.pi / 2), 0.2, 0.0, [2.0])[0]
    np.testing.assert_allclose(pose, [0.0, 0.4, math.pi / 2], atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_frames_and_scan_points(seed):
    pose = (1.0, -2.0, math.radians(30))
    pts = np.random.default_rng(seed).normal(size=(10, 2))
    np.testing.assert_allclose(to_robot(pose, to_world(pose, pts)), pts, atol=1e-12)
    np.testing.assert_allclose(to_world(pose, [[1.0, 0.0]]),
                               [[1 + math.cos(math.radians(30)), -2 + 0.5]], atol=1e-12)
    p = scan_points(np.array([0.0, 90.0, 10.0]), np.array([2.0, 1.0, np.nan]), 0.1)
    np.testing.assert_allclose(p, [[2.1, 0.0], [0.1, 1.0]], atol=1e-12)


def test_point_memory_keeps_recent_points_one_per_cell():
    m = PointMemory.empty().update([[1.0, 1.0], [1.01, 1.01], [2.0, 0.0]], 0.0, keep_s=1.0,
                                   cell_m=0.05)
    assert len(m.points_xy) == 2                      # first two share a 5 cm cell
    m2 = m.update([[1.02, 1.02]], 0.6, keep_s=1.0, cell_m=0.05)
    assert len(m2.points_xy) == 2 and [1.02, 1.02] in m2.points_xy.tolist()   # newest kept
    m3 = m2.update(np.zeros((0, 2)), 1.3, keep_s=1.0, cell_m=0.05)
    assert m3.points_xy.tolist() == [[1.02, 1.02]]    # the t = 0 point has expired
    off = m.update([[5.0, 5.0]], 0.2, keep_s=0.0, cell_m=0.05)
    assert off.points_xy.tolist() == [[5.0, 5.0]]     # no memory: only what is seen now


# ---------------------------------------------------------------- ray clearing
def _rays(ranges, free_m=0.0):
    from slitcli.local_map import ScanRays

    b = np.arange(-30.0, 30.01, 1.0)
    r = np.full(b.shape, np.nan)
    for bearing, rng in ranges.items():
        r[int(bearing + 30)] = rng
    return ScanRays(np.zeros(2), 0.0, b, r, free_m, 0.05)


def test_scan_rays_state_hand_values():
    from slitcli.local_map import FREE, OCCLUDED, SURFACE, UNSEEN

    rays = _rays({0.0: 2.0})
    # tolerance at range r: 0.05 + r * 1 deg = 0.085 m at 2 m
    pts = [[1.0, 0.0], [1.9, 0.0], [2.05, 0.0], [1.95, 0.0], [2.2, 0.0], [3.0, 0.0],
           [1.0, math.tan(math.radians(0.4))]]                # 0.4 deg: still the 0 deg bin
    np.testing.assert_array_equal(rays.state(pts), [FREE, FREE, SURFACE, SURFACE, OCCLUDED,
                                                     OCCLUDED, FREE])
    # outside the field of view, or no return in the bin: unseen unless free_m says free
    side = [[0.0, 1.0], [1.0, math.tan(math.radians(10.0))]]
    np.testing.assert_array_equal(rays.state(side), [UNSEEN, UNSEEN])
    np.testing.assert_array_equal(_rays({0.0: 2.0}, free_m=3.0).state(side), [UNSEEN, FREE])


def test_obstacle_map_keeps_out_of_view_clears_seen_free():
    from slitcli.local_map import ObstacleMap, ScanRays

    wall = np.column_stack([np.full(11, 2.0), np.linspace(-0.5, 0.5, 11)])
    m = ObstacleMap.empty().add(wall, 0.0, np.zeros(11, dtype=np.int64), cell_m=0.05)
    assert len(m.points_xy) == 11
    # robot turned 90 deg left: the wall is out of view; nothing is forgotten
    b = np.arange(-30.0, 30.01, 1.0)
    away = ScanRays(np.zeros(2), math.pi / 2, b, np.full(b.shape, np.nan), 3.0, 0.05)
    assert len(m.clear(away).points_xy) == 11
    # looking at it again with a missed return (vision, free_m = 0): kept
    look = ScanRays(np.zeros(2), 0.0, b, np.full(b.shape, np.nan), 0.0, 0.05)
    assert len(m.clear(look).points_xy) == 11
    # a farther return through it (the wall has gone): cleared where the rays pass
    far = ScanRays(np.zeros(2), 0.0, b, np.full(b.shape, 4.0), 0.0, 0.05)
    assert len(m.clear(far).points_xy) == 0
    # exact sensing says "nothing within 3 m": cleared too
    assert len(m.clear(ScanRays(np.zeros(2), 0.0, b, np.full(b.shape, np.nan), 3.0,
                                0.05)).points_xy) == 0
    assert len(m.drop_tracks(np.array([0])).points_xy) == 0


# ---------------------------------------------------------------- tracking
def _disc_scan(centre, radius, origin, bearings_deg):
    """Exact ranges from ``origin`` to a disc per bearing (NaN on a miss): (B,)."""
    a = np.radians(bearings_deg)
    d = np.column_stack([np.cos(a), np.sin(a)])
    oc = np.asarray(centre) - origin
    b = d @ oc
    disc = b * b - (oc @ oc - radius * radius)
    return np.where(disc >= 0, b - np.sqrt(np.maximum(disc, 0)), np.nan)


@pytest.mark.parametrize("seed", range(6))
def test_tracker_velocity_of_a_walking_disc_and_static_box(seed):
    from slitcli.local_map import ScanRays
    from slitcli.tracking import Tracker

    rng = np.random.default_rng(seed)
    speed = rng.uniform(0.3, 1.0)
    ang = rng.uniform(0, 2 * np.pi)
    vel = speed * np.array([math.cos(ang), math.sin(ang)])
    c0 = np.array([2.5, rng.uniform(-0.5, 0.5)]) - 0.6 * vel    # passes near (2.5, y)
    b = np.arange(-32.0, 32.01, 0.5)
    tr = Tracker()
    for k in range(8):                                            # 1.4 s at 5 Hz
        t = 0.2 * k
        r = _disc_scan(c0 + vel * t, 0.25, np.zeros(2), b)
        ok = np.isfinite(r)
        pts = np.column_stack([r[ok] * np.cos(np.radians(b[ok])),
                               r[ok] * np.sin(np.radians(b[ok]))])
        rays = ScanRays(np.zeros(2), 0.0, b, r, 5.0, 0.05)
        snap = tr.update(pts, t, rays.state, origin_xy=np.zeros(2))
    assert len(snap.track_id) == 1 and snap.moving[0]
    # error budget: 0.5 deg bins at 2.5 m (2 cm per point) over a 1.4 s baseline
    assert np.hypot(*(snap.velocity_xy[0] - vel)) < 0.06
    # a static box seen from a robot driving past it at 0.2 m/s is never moving
    tr = Tracker()
    box = np.column_stack([np.full(30, 2.0), np.linspace(-0.3, 0.6, 30)])
    for k in range(10):
        o = np.array([0.04 * k, rng.uniform(-0.01, 0.01)])
        rel = box - o
        brg = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
        idx = np.floor((brg - b[0]) / 0.5 + 0.5).astype(int)
        keep = (idx >= 0) & (idx < len(b))
        near = np.full(b.shape, np.inf)
        np.minimum.at(near, idx[keep], np.hypot(*rel[keep].T))
        r = np.where(np.isfinite(near), near, np.nan)
        ok = np.isfinite(r)
        pts = o + np.column_stack([r[ok] * np.cos(np.radians(b[ok])),
                                   r[ok] * np.sin(np.radians(b[ok]))])
        snap = tr.update(pts, 0.2 * k, ScanRays(o, 0.0, b, r, 5.0, 0.05).state, origin_xy=o)
    assert not snap.ever_moving.any()


# ---------------------------------------------------------------- prediction
def test_moving_contact_time_hand_values():
    from slitcli.prediction import MovingDiscs, moving_contact_time

    v, w = np.array([0.2, 0.0, 0.2]), np.array([0.0, 0.0, 0.3])
    # a person walking at the robot along its line at 0.5 m/s from 3 m: the two discs
    # (0.3 + 0.25) meet when the gap closes, (3 - 0.55 - slack) / 0.7 s for the moving
    # robot, (3 - 0.55 - slack) / 0.5 s for the standing one; slack = half a step's
    # relative travel
    m = MovingDiscs(np.array([[3.0, 0.0]]), np.array([[-0.5, 0.0]]), np.array([0.25]))
    t_c, gap = moving_contact_time(v, w, m, radius_m=0.3, horizon_s=10.0, step_s=0.1)
    for i, closing in ((0, 0.7), (1, 0.5)):
        slack = 0.05 * (v[i] + 0.5)
        exact = (3.0 - 0.55 - slack) / closing
        assert exact <= t_c[i] < exact + 0.1 + 1e-9
    assert gap[0] < 0
    # the same person walking away never meets the robot: inf, and the gap stays open
    m2 = MovingDiscs(np.array([[3.0, 0.0]]), np.array([[0.5, 0.0]]), np.array([0.25]))
    t2, gap2 = moving_contact_time(v, w, m2, radius_m=0.3, horizon_s=10.0, step_s=0.1)
    assert np.all(np.isinf(t2)) and gap2.min() > 0
    # a disc overlapping the margin but moving off sideways does not block the robot
    m3 = MovingDiscs(np.array([[0.0, 0.5]]), np.array([[0.0, 1.0]]), np.array([0.25]))
    assert np.all(np.isinf(moving_contact_time(v, w, m3, radius_m=0.3, horizon_s=5.0,
                                               step_s=0.1)[0]))


@pytest.mark.parametrize("seed", range(5))
def test_array_step_with_prediction_matches_loop_reference(seed):
    from slitcli.prediction import MovingDiscs

    rng = np.random.default_rng(100 + seed)
    pts = rng.uniform([-0.5, -2.0], [3.0, 2.0], size=(30, 2))
    pts = pts[np.hypot(*pts.T) > R + 0.01]
    c = rng.uniform([0.8, -2.0], [3.0, 2.0], size=(3, 2))
    u = rng.uniform(-1.0, 1.0, size=(3, 2))
    r = rng.uniform(0.0, 0.2, size=3)
    v0, w0 = float(rng.uniform(0.05, 0.2)), float(rng.uniform(-0.1, 0.1))
    goal = (float(rng.uniform(1, 5)), float(rng.uniform(-3, 3)))
    cmd = plan_step(v0, w0, goal, pts, P, MovingDiscs(c, u, r))
    v, w, s = ref.choose(v0, w0, goal, [tuple(q) for q in pts], P,
                         [(*c[i], *u[i], r[i]) for i in range(3)])
    assert (cmd.v_mps, cmd.w_rps) == (v, w)
    assert cmd.score == pytest.approx(s, abs=1e-9)


def test_a_person_crossing_ahead_makes_the_robot_wait_not_rotate():
    from slitcli.prediction import MovingDiscs

    # standing robot, goal straight ahead, a person just in front (0.56 m: 1 cm outside
    # the 0.3 + 0.25 m contact distance, within the half-step slack) walking left at
    # 0.3 m/s: every forward arc closes the gap at once, standing lets it open
    m = MovingDiscs(np.array([[0.56, 0.0]]), np.array([[0.0, 0.3]]), np.array([0.25]))
    cmd = plan_step(0.0, 0.0, (4.0, 0.0), np.zeros((0, 2)), P, m)
    assert cmd.status == "wait" and cmd.v_mps == 0.0 and cmd.w_rps == 0.0
    # once it has passed, the robot goes
    gone = MovingDiscs(np.array([[1.0, 1.5]]), np.array([[0.0, 1.0]]), np.array([0.25]))
    assert plan_step(0.0, 0.0, (4.0, 0.0), np.zeros((0, 2)), P, gone).status == "move"
