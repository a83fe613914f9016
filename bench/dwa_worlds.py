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
    "no memory": (DwaParams(), SimParams(memory_s=0.0)),
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
    args = ap.parse_args()
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


if __name__ == "__main__":
    main()
