"""Offline modified DWA over a recorded range table (``slitcli dwa``; docs/dwa.md).

The range table (DESIGN §12: frame, time_s, bearing_deg, ..., fused_range_m) gives
what the robot saw per frame. The planner runs once per frame and writes the
velocity command it would have sent. There is no odometry in a range table, so the
robot is *assumed to have moved exactly as commanded*: the pose of frame k+1 is the
pose of frame k moved along the arc of frame k's command for the time between the
two frames. Poses, the goal and the obstacle memory live in the frame of the robot
at the first frame (origin at its rotation centre, x forward, y left).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from slitcli.dwa import DwaParams, plan_step
from slitcli.errors import SlitcliError
from slitcli.io.atomic import write_csv_atomic
from slitcli.local_map import to_robot, unicycle
from slitcli.world_model import MEMORY_MODES, WorldModel, WorldModelParams, moving_to_robot

CMDS_COLUMNS = ("frame", "time_s", "x_m", "y_m", "heading_deg", "goal_distance_m", "v_mps",
                "w_dps", "status", "d_collision_m", "n_points")
RANGE_COLUMNS = ("laser_range_m", "stereo_range_m", "fused_range_m")


def read_range_table(path: str | Path, range_column: str = "fused_range_m") -> pd.DataFrame:
    """Read and check a range table CSV; returns frame, time_s, bearing_deg, range_m.

    Raises :class:`SlitcliError` naming the file for a missing file, missing columns,
    non-numeric values, an empty table or a time that does not increase with frame.
    """
    p = Path(path)
    if range_column not in RANGE_COLUMNS:
        raise SlitcliError(f"--range-column {range_column!r} is not a range column; use one of "
                           f"{', '.join(RANGE_COLUMNS)}")
    try:
        df = pd.read_csv(p)
    except FileNotFoundError:
        raise SlitcliError(f"{p}: range table not found; write one with `slitcli detect`") \
            from None
    except (OSError, UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError) as e:
        raise SlitcliError(f"{p}: cannot read the range table as CSV "
                           f"({e.__class__.__name__}); give the ranges.csv written by detect") \
            from None
    need = ("frame", "time_s", "bearing_deg", range_column)
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise SlitcliError(f"{p}: missing column(s) {', '.join(missing)}; a range table has "
                           "frame, time_s, bearing_deg and " + ", ".join(RANGE_COLUMNS))
    if len(df) == 0:
        raise SlitcliError(f"{p}: the range table has no rows; run detect on a non-empty "
                           "sequence")
    out = pd.DataFrame()
    for c in need:
        col = pd.to_numeric(df[c], errors="coerce")
        bad = col.isna() & df[c].notna()
        if bad.any() or (c != range_column and col.isna().any()):
            row = int(np.flatnonzero(bad | (col.isna() & (c != range_column)))[0]) + 2
            raise SlitcliError(f"{p}: line {row}: column {c} is not a number; fix or drop the "
                               "row")
        out[c if c != range_column else "range_m"] = col.to_numpy(dtype=float)
    out = out.sort_values(["frame", "bearing_deg"], kind="stable").reset_index(drop=True)
    times = out.groupby("frame", sort=True)["time_s"].first().to_numpy()
    if len(times) > 1 and np.any(np.diff(times) <= 0):
        k = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise SlitcliError(f"{p}: time_s does not increase at the {k + 1}th frame; the offline "
                           "planner needs increasing frame times")
    return out


def plan_range_table(table: pd.DataFrame, goal_xy_m: tuple[float, float], params: DwaParams, *,
                     forward_m: float = 0.0, memory_s: float = 10.0,
                     memory_cell_m: float = 0.05, memory: str = "clearing",
                     free_m: float = 0.0) -> pd.DataFrame:
    """One DWA command per frame of a range table (columns of :func:`read_range_table`).

    Parameters
    ----------
    table : DataFrame
        frame, time_s, bearing_deg, range_m (NaN = no return), sorted by frame.
    goal_xy_m : (2,)
        Goal in the first frame's robot frame, metres.
    params : DwaParams
    forward_m : float
        Sensor origin ahead of the rotation centre (the rig's ``mount.forward_m``).
    memory_s, memory_cell_m, memory : float, float, str
        Obstacle memory, as in the closed loop (:mod:`slitcli.world_model`).
    free_m : float
        Range up to which a bin with no return counts as free space (0: never, the
        safe choice for vision range tables).

    Returns
    -------
    DataFrame with CMDS_COLUMNS: the assumed pose at each frame, the command for it.
    """
    frames = table["frame"].to_numpy()
    starts = np.flatnonzero(np.r_[True, frames[1:] != frames[:-1]])
    ends = np.r_[starts[1:], len(frames)]
    times = table["time_s"].to_numpy()[starts]
    bearing = table["bearing_deg"].to_numpy()
    rng = table["range_m"].to_numpy()
    goal = np.asarray(goal_xy_m, dtype=float)
    pose = (0.0, 0.0, 0.0)
    v = w = 0.0
    model = WorldModel(WorldModelParams(memory=memory, memory_s=memory_s, cell_m=memory_cell_m))
    rows = []
    for i, (a, b) in enumerate(zip(starts, ends, strict=True)):
        if i:
            pose = tuple(float(x) for x in unicycle(pose, v, w, [times[i] - times[i - 1]])[0])
        static, moving = model.update(pose, bearing[a:b], rng[a:b], forward_m, free_m, times[i])
        g = to_robot(pose, goal[None])[0]
        cmd = plan_step(v, w, g, to_robot(pose, static), params, moving_to_robot(pose, moving))
        rows.append((frames[a], times[i], pose[0], pose[1], math.degrees(pose[2]),
                     math.hypot(*g), cmd.v_mps, cmd.w_dps, cmd.status, cmd.d_collision_m,
                     len(static) + len(moving.radius_m)))
        v, w = cmd.v_mps, cmd.w_rps
    out = pd.DataFrame(rows, columns=list(CMDS_COLUMNS))
    out["frame"] = out["frame"].astype(np.int64)
    return out


def dwa_offline(ranges_csv: str | Path, goal_xy_m: tuple[float, float], out_csv: str | Path,
                params: DwaParams, *, range_column: str = "fused_range_m", forward_m: float = 0.0,
                memory_s: float = 10.0, memory_cell_m: float = 0.05, memory: str = "clearing",
                free_m: float = 0.0) -> pd.DataFrame:
    """``slitcli dwa``: read the range table, plan every frame, write CMDS.csv atomically."""
    if memory not in MEMORY_MODES:
        raise SlitcliError(f"--memory {memory!r} is unknown; use one of {', '.join(MEMORY_MODES)}")
    if not (free_m >= 0 and math.isfinite(free_m)):
        raise SlitcliError(f"--free-range-m {free_m!r} must be >= 0 m")
    if not (memory_s >= 0 and math.isfinite(memory_s)):
        raise SlitcliError(f"--memory-s {memory_s!r} must be >= 0 (0 turns the memory off)")
    if not memory_cell_m > 0:
        raise SlitcliError(f"--memory-cell-m {memory_cell_m!r} must be > 0")
    if not all(math.isfinite(g) for g in goal_xy_m):
        raise SlitcliError(f"--goal {goal_xy_m!r} must be two finite numbers X,Y in metres")
    table = read_range_table(ranges_csv, range_column)
    cmds = plan_range_table(table, goal_xy_m, params, forward_m=forward_m, memory_s=memory_s,
                            memory_cell_m=memory_cell_m, memory=memory, free_m=free_m)
    write_csv_atomic(out_csv, cmds)
    return cmds
