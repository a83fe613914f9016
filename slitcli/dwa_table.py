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
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from slitcli.dwa import DwaParams, plan_step
from slitcli.errors import SlitcliError
from slitcli.io.atomic import check_output_file, write_csv_atomic
from slitcli.local_map import to_robot, unicycle
from slitcli.ranges import DWA_COMMANDS, RANGE_VALUE_COLUMNS, times_as_text
from slitcli.world_model import MEMORY_MODES, WorldModel, WorldModelParams, moving_to_robot

CMDS_COLUMNS = DWA_COMMANDS.columns


def read_range_table(path: str | Path, range_column: str = "fused_range_m", *,
                     period_s: float | None = None) -> pd.DataFrame:
    """Read and check a range table CSV; returns frame, time_s, bearing_deg, range_m.

    A table whose ``time_s`` column is empty throughout (``detect`` on a sequence without
    times.csv) gets ``time_s = frame * period_s`` when ``period_s`` is given.

    Raises :class:`SlitcliError` naming the file (and line) for a missing file, missing
    columns, non-numeric values, negative or infinite ranges, bearings outside
    [-180, 180] deg, negative or fractional frame numbers, an empty table, an empty
    time_s without ``period_s``, or a time that does not increase with frame.
    """
    p = Path(path)
    if period_s is not None and not (math.isfinite(period_s) and 1e-6 <= period_s <= 3600):
        raise SlitcliError(f"`period_s` {period_s!r} must be a frame period in [1e-06, 3600] s",
                           param="period_s")
    if range_column not in RANGE_VALUE_COLUMNS:
        raise SlitcliError(f"`range_column` {range_column!r} is not a range column; use one of "
                           f"{', '.join(RANGE_VALUE_COLUMNS)}", param="range_column")
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
                           "frame, time_s, bearing_deg and " + ", ".join(RANGE_VALUE_COLUMNS))
    if len(df) == 0:
        raise SlitcliError(f"{p}: the range table has no rows; run detect on a non-empty "
                           "sequence")
    out = pd.DataFrame()
    if df["time_s"].isna().all():
        if period_s is None:
            raise SlitcliError(f"{p}: column time_s is empty (the sequence had no times.csv); "
                               "give `period_s` (seconds between frames) or add "
                               "times.csv to the sequence and run detect again",
                               param="period_s")
        df = df.assign(time_s=pd.to_numeric(df["frame"], errors="coerce") * period_s)
    for c in need:
        col = pd.to_numeric(df[c], errors="coerce")
        bad = col.isna() & df[c].notna()
        if bad.any() or (c != range_column and col.isna().any()):
            row = int(np.flatnonzero(bad | (col.isna() & (c != range_column)))[0]) + 2
            raise SlitcliError(f"{p}: line {row}: column {c} is not a number; fix or drop the "
                               "row")
        out[c if c != range_column else "range_m"] = col.to_numpy(dtype=float)
    _check_values(p, out, range_column)
    out = out.sort_values(["frame", "bearing_deg"], kind="stable").reset_index(drop=True)
    times = out.groupby("frame", sort=True)["time_s"].first().to_numpy()
    if len(times) > 1 and np.any(np.diff(times) <= 0):
        k = int(np.flatnonzero(np.diff(times) <= 0)[0]) + 1
        raise SlitcliError(f"{p}: time_s does not increase at the {k + 1}th frame; the offline "
                           "planner needs increasing frame times")
    return out


def _check_values(p: Path, table: pd.DataFrame, range_column: str) -> None:
    """Refuse values no range table holds, naming the first offending line."""
    rng = table["range_m"].to_numpy()
    frame = table["frame"].to_numpy()
    bearing = table["bearing_deg"].to_numpy()
    time = table["time_s"].to_numpy()
    checks = (
        (np.isfinite(rng) & (rng < 0), range_column, "is negative",
         "a range is a distance >= 0 (empty = no return)"),
        (np.isinf(rng), range_column, "is infinite", "leave the cell empty for no return"),
        (~np.isfinite(frame) | (frame < 0) | (frame != np.round(frame)) | (frame > 2**53),
         "frame", "is not a whole number >= 0", "give frame indices"),
        (~np.isfinite(bearing) | (np.abs(bearing) > 180), "bearing_deg",
         "is outside [-180, 180]", "give bearings in degrees"),
        (~np.isfinite(time) | (np.abs(time) > 1e12), "time_s", "is not a finite time",
         "give seconds"),
    )
    for bad, column, problem, fix in checks:
        if bad.any():
            row = int(np.flatnonzero(bad)[0]) + 2
            raise SlitcliError(f"{p}: line {row}: column {column} {problem}; {fix}")


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
                free_m: float = 0.0, period_s: float | None = None, overwrite: bool = False,
                inputs: Sequence[str | Path | None] = ()) -> pd.DataFrame:
    """``slitcli dwa``: read the range table, plan every frame, write CMDS.csv atomically.

    ``out_csv`` must not be the range table or one of ``inputs`` (the rig file), and
    must not exist unless ``overwrite``. ``period_s`` dates a table without times.
    """
    check_output_file(out_csv, inputs=[ranges_csv, *inputs], overwrite=overwrite)
    if memory not in MEMORY_MODES:
        raise SlitcliError(f"`memory` {memory!r} is unknown; use one of "
                           f"{', '.join(MEMORY_MODES)}", param="memory")
    if not (free_m >= 0 and math.isfinite(free_m)):
        raise SlitcliError(f"`free_m` {free_m!r} must be >= 0 m", param="free_m")
    if not (memory_s >= 0 and math.isfinite(memory_s)):
        raise SlitcliError(f"`memory_s` {memory_s!r} must be >= 0 (0 turns the memory off)",
                           param="memory_s")
    if not (math.isfinite(memory_cell_m) and 1e-4 <= memory_cell_m <= 100):
        raise SlitcliError(f"`memory_cell_m` {memory_cell_m!r} must be in [0.0001, 100] m",
                           param="memory_cell_m")
    if not all(math.isfinite(g) for g in goal_xy_m):
        raise SlitcliError(f"`goal_xy_m` {goal_xy_m!r} must be two finite numbers X,Y in metres",
                           param="goal_xy_m")
    table = read_range_table(ranges_csv, range_column, period_s=period_s)
    cmds = plan_range_table(table, goal_xy_m, params, forward_m=forward_m, memory_s=memory_s,
                            memory_cell_m=memory_cell_m, memory=memory, free_m=free_m)
    # times keep every digit of their stamps (a wall-clock 1.7e9 s with %.6g loses them)
    write_csv_atomic(out_csv, times_as_text(cmds, ("time_s",)))
    return cmds
