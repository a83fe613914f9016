"""One modified-DWA step at the paper's sampling: array code against the plain-loop reference.

The window from v = 0.1 m/s has 9 speeds (0.01 m/s) x 151 turn rates (0.1 deg/s) =
1359 pairs; 240 obstacle points on three box outlines and a wall in front of the
robot (a typical obstacle memory). Both versions must choose the identical pair; the
ratio is the reference's median time over the array version's, measured in this run.
The second pair of rows adds prediction: a walking person as 16 outline points
(a 0.25 m half circle) moving at 0.8 m/s across the robot's path, compared with every
arc at the 51 instants of the 5 s horizon.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from slitcli.dwa import DwaParams, plan_step, window_pairs
from slitcli.prediction import MovingDiscs

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import dwa_reference as ref  # the reference lives with the tests


def _outline(x0: float, y0: float, x1: float, y1: float, n: int) -> np.ndarray:
    t = np.linspace(0.0, 1.0, n)
    return np.column_stack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)])


def scene_points() -> np.ndarray:
    """240 points in the robot frame: three box fronts/sides and a wall, seeded jitter."""
    parts = [
        _outline(1.2, -0.6, 1.2, -0.1, 30), _outline(1.2, -0.6, 1.6, -0.6, 25),
        _outline(2.0, 0.3, 2.0, 0.9, 35), _outline(2.0, 0.9, 2.5, 0.9, 30),
        _outline(2.6, -1.2, 2.6, -0.5, 40), _outline(0.3, 1.6, 3.0, 1.6, 80),
    ]
    pts = np.concatenate(parts)
    return pts + np.random.default_rng(0).normal(scale=0.005, size=pts.shape)


def person() -> MovingDiscs:
    """16 points on the near half of a 0.25 m circle at (2.2, -1.2), walking +y at 0.8 m/s."""
    a = np.linspace(0.5 * np.pi, 1.5 * np.pi, 16)
    pts = np.column_stack([2.2 + 0.25 * np.cos(a), -1.2 + 0.25 * np.sin(a)])
    return MovingDiscs(pts, np.tile([0.0, 0.8], (16, 1)), np.zeros(16))


def bench(timer) -> list[dict]:
    p = DwaParams()
    pts = scene_points()
    v0, w0, goal = 0.1, 0.02, (4.0, -0.5)
    n_pairs = window_pairs(v0, w0, p)[0].size
    arr = plan_step(v0, w0, goal, pts, p)
    loop_v, loop_w, loop_s = ref.choose(v0, w0, goal, [tuple(q) for q in pts], p)
    same = (arr.v_mps, arr.w_rps) == (loop_v, loop_w) and abs(arr.score - loop_s) < 1e-9
    t_arr = timer(lambda: plan_step(v0, w0, goal, pts, p), runs=101)
    pts_list = [tuple(q) for q in pts]
    t_loop = timer(lambda: ref.choose(v0, w0, goal, pts_list, p), runs=21)
    ratio = t_loop["median_s"] / t_arr["median_s"]
    choice = f"v={arr.v_mps:.2f} m/s w={arr.w_dps:.1f} deg/s"
    mv = person()
    discs = [(*mv.centre_xy[i], *mv.velocity_xy[i], mv.radius_m[i]) for i in range(16)]
    arr_p = plan_step(v0, w0, goal, pts, p, mv)
    lv, lw, ls = ref.choose(v0, w0, goal, pts_list, p, discs)
    same_p = (arr_p.v_mps, arr_p.w_rps) == (lv, lw) and abs(arr_p.score - ls) < 1e-9
    t_arr_p = timer(lambda: plan_step(v0, w0, goal, pts, p, mv), runs=51)
    t_loop_p = timer(lambda: ref.choose(v0, w0, goal, pts_list, p, discs), runs=5)
    ratio_p = t_loop_p["median_s"] / t_arr_p["median_s"]
    choice_p = f"v={arr_p.v_mps:.2f} m/s w={arr_p.w_dps:.1f} deg/s"
    return [
        {"name": "dwa step, array (numpy)", **t_arr,
         "note": f"{n_pairs} pairs x {len(pts)} points; {choice}"},
        {"name": "dwa step, python loop ref", **t_loop, "ratio": ratio,
         "note": f"array {ratio:.0f}x faster (goal >= 30x); identical choice: {same}"},
        {"name": "dwa step + prediction, array", **t_arr_p,
         "note": f"+ 16 moving points x 51 instants; {choice_p}"},
        {"name": "dwa step + prediction, loop ref", **t_loop_p, "ratio": ratio_p,
         "note": f"array {ratio_p:.0f}x faster (goal >= 30x); identical choice: {same_p}"},
    ]
