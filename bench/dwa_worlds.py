"""Closed-loop DWA study behind docs/dwa.md: the paper scenario and 100 random worlds,

for the defaults and for each design choice switched off (obstacle memory, discrete
braking, turn-circle braking near the goal). Not part of `make bench` (minutes).

    .venv/bin/python bench/dwa_worlds.py [--worlds 100] [--only default]

Prints markdown tables (paper cases; random-world summary per variant).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from slitcli.dwa import DwaParams
from slitcli.rig import paper_rig
from slitcli.sim.loop import Case, SimParams, run_cases
from slitcli.sim.worlds import paper_world, random_world

VARIANTS = {
    "default": (DwaParams(), SimParams()),
    "former memory (10 s expiry, no tracking)": (DwaParams(), SimParams(memory="expiry")),
    "no memory": (DwaParams(), SimParams(memory="off")),
    "paper braking (v <= sqrt(2 D acc))": (DwaParams(discrete_braking=False), SimParams()),
    "no turn-circle braking": (DwaParams(turn_circle_close=False), SimParams()),
}


def _fmt(x: float, nd: int = 2) -> str:
    return "" if not np.isfinite(x) else f"{x:.{nd}f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", default="", help="run only variants whose name contains this")
    ap.add_argument("--paper-ranges", default="0.6,1,1.5,2,2.5,3")
    ap.add_argument("--missed-returns", action="store_true",
                    help="only the missed-return measurement (vision; about a minute)")
    args = ap.parse_args()
    if args.missed_returns:
        missed_returns()
        return
    rig = paper_rig()
    pw = paper_world()
    ranges = [float(r) for r in args.paper_ranges.split(",")]
    worlds = [random_world(s) for s in range(args.seed, args.seed + args.worlds)]
    for name, (dwa, sim) in VARIANTS.items():
        if args.only and args.only not in name:
            continue
        t0 = time.perf_counter()
        m, _ = run_cases([Case(f"range_{r:g}m", pw, r) for r in ranges], rig, dwa, sim)
        print(f"\n### {name}: paper scenario\n")
        print("| case | sensing_range_m | outcome | min_clearance_m | time_to_goal_s | "
              "path_length_m |\n|---|---|---|---|---|---|")
        for r in m.itertuples():
            print(f"| {r.case} | {r.sensing_range_m:g} | {r.outcome} | "
                  f"{_fmt(r.min_clearance_m, 3)} | {_fmt(r.time_to_goal_s, 1)} | "
                  f"{_fmt(r.path_length_m)} |")
        mr, _ = run_cases([Case(w.name, w, 3.0) for w in worlds], rig, replace(dwa), sim)
        oc = mr["outcome"].value_counts()
        ok = mr[mr["reached_goal"]]
        print(f"\n{name}: {len(mr)} random worlds at 3 m: reached {oc.get('reached', 0)}, "
              f"collided {oc.get('collided', 0)}, stuck {oc.get('stuck', 0)}, "
              f"timeout {oc.get('timeout', 0)}; min clearance {mr['min_clearance_m'].min():.3f} "
              f"m; mean time {ok['time_to_goal_s'].mean():.1f} s, mean path "
              f"{ok['path_length_m'].mean():.2f} m (reached runs); "
              f"not reached: {', '.join(mr.loc[~mr['reached_goal'], 'case']) or '-'} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)



def missed_returns(frames: int = 16) -> None:
    """How a missed vision return would wipe a real obstacle from the memory.

    A plain (textureless, stereo-blind) box and a textured one stand ahead; the robot
    drives towards them and turns. Each frame is rendered, detected and fused
    (vision sensing) and the obstacle memory is updated twice: with the default rule
    for vision (a bin clears only where a farther return was seen, free_m = 0) and
    with "no return = free" up to the sensing range (free_m = 3 m). Printed per rule:
    the remembered points on a true outline (within 5 cm) that were deleted, and the
    memory's true-obstacle points at the end.
    """
    from slitcli.local_map import ObstacleMap, ScanRays, scan_points, to_world
    from slitcli.sim.clearance import clearance_m, obstacle_geometry
    from slitcli.sim.loop import vision_sensor
    from slitcli.sim.scene import Pose2D
    from slitcli.sim.worlds import world_from_dict

    w = world_from_dict({
        "slitcli_scene": 1, "name": "missed", "objects": [
            {"type": "box", "centre_xy_m": [2.6, 0.35], "size_m": [0.3, 0.6, 0.6],
             "surface": {"texture": "plain", "colour_rgb": [0.8, 0.8, 0.78]}},
            {"type": "cylinder", "centre_xy_m": [2.8, -0.6], "radius_m": 0.2, "height_m": 0.6}],
        "robot": {"start": [0, 0, 0]}, "goal_xy_m": [5.0, 0.0]}, "bench")
    rig = paper_rig()
    sensor = vision_sensor(w.scene, rig, 3.0)
    geom = obstacle_geometry(w.scene)
    half = frames // 2
    poses = [Pose2D(0.12 * k, 0.0, 0.0) for k in range(half)] + \
        [Pose2D(0.12 * (half - 1), 0.0, np.radians(4.0 * (k + 1))) for k in range(frames - half)]
    maps = {0.0: ObstacleMap.empty(), 3.0: ObstacleMap.empty()}
    wiped = {0.0: 0, 3.0: 0}
    missed = 0
    for k, pose in enumerate(poses):
        scan = sensor(pose, k, 0.2 * k)
        p = (pose.x_m, pose.y_m, pose.yaw_rad)
        seen = to_world(p, scan_points(scan.bearing_deg, scan.range_m, scan.forward_m))
        origin = np.array([pose.x_m + scan.forward_m * np.cos(pose.yaw_rad),
                           pose.y_m + scan.forward_m * np.sin(pose.yaw_rad)])
        from slitcli.sim.truth import true_ranges

        lo, hi = rig.bearing_bins(1.0)[1:]
        truth = true_ranges(w.scene, pose, lo, hi, forward_m=rig.mount.forward_m,
                            max_range_m=3.0)
        missed += int((np.isfinite(truth) & ~np.isfinite(scan.range_m)).sum())
        for free_m, m in maps.items():
            rays = ScanRays(origin, pose.yaw_rad, scan.bearing_deg, scan.range_m, free_m, 0.05)
            kept = m.clear(rays)
            on = np.abs(clearance_m(geom, m.points_xy)) <= 0.05
            on_kept = np.abs(clearance_m(geom, kept.points_xy)) <= 0.05
            wiped[free_m] += int(on.sum() - on_kept.sum())
            maps[free_m] = kept.add(seen, 0.2 * k, np.full(len(seen), -1), cell_m=0.05)
    print(f"\n{frames} vision frames: {missed} bins with a true obstacle within 3 m and no "
          "return")
    for free_m, m in maps.items():
        on = int((np.abs(clearance_m(geom, m.points_xy)) <= 0.05).sum())
        print(f"free_m = {free_m:g} m: {wiped[free_m]} true-obstacle points wiped; {on} "
              "true-obstacle points in the memory at the end")


if __name__ == "__main__":
    main()
