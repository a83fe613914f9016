"""Commands ``dwa`` and ``simulate-dwa``: the modified DWA (Eqs. 12-13)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from slitcli.cli.main import cli


def _floats(n: int | None, what: str):
    """A click callback parsing comma-separated numbers (exactly ``n`` of them if given)."""

    def parse(ctx: click.Context, param: click.Parameter, value: str | None) -> Any:
        if value is None:
            return None
        try:
            nums = tuple(float(x) for x in value.split(","))
        except ValueError:
            raise click.BadParameter(f"{value!r} is not {what}") from None
        if (n is not None and len(nums) != n) or not all(x == x and abs(x) != float("inf")
                                                          for x in nums):
            raise click.BadParameter(f"{value!r} is not {what}")
        return nums

    return parse


def _dwa_options(f: Any) -> Any:
    """The planner's parameters (slitcli.dwa.DwaParams), shared by dwa and simulate-dwa."""
    from slitcli.dwa import DwaParams

    d = DwaParams()
    opts = [
        ("--v-max-mps", d.v_max_mps, "Speed limit, m/s (paper: 0.2)."),
        ("--w-max-dps", d.w_max_dps, "Turn-rate limit, deg/s (paper: 7.5)."),
        ("--acc-mps2", d.acc_mps2, "Translational acceleration limit, m/s^2 (paper: 0.2)."),
        ("--ang-acc-dps2", d.ang_acc_dps2, "Angular acceleration limit, deg/s^2."),
        ("--dt-s", d.dt_s, "Control period T, s (paper: 0.2)."),
        ("--heading-clamp-deg", d.heading_clamp_deg, "Clamp of the goal bearing, deg."),
        ("--v-res-mps", d.v_res_mps, "Window sampling of v, m/s."),
        ("--w-res-dps", d.w_res_dps, "Window sampling of w, deg/s."),
        ("--heading-horizon-s", d.heading_horizon_s, "Horizon T_h of the heading term, s."),
        ("--goal-close-m", d.goal_close_m, "Eq. 13 switch and arrival radius, m."),
        ("--d-max-m", d.d_max_m, "Cap of D_collision, m."),
        ("--alpha", d.alpha, "Weight of the heading term (Eq. 12)."),
        ("--beta", d.beta, "Weight of the clearance term (Eq. 12)."),
        ("--gamma", d.gamma, "Weight of the velocity term (Eqs. 12-13)."),
        ("--predict-horizon-s", d.predict_horizon_s,
         "Moving obstacles are predicted at constant velocity this far ahead, s."),
        ("--predict-step-s", d.predict_step_s,
         "Time step of the prediction (arc and obstacle compared at the same instants), s."),
        ("--moving-buffer-m", d.moving_buffer_m,
         "Passing a moving obstacle this far (or farther) scores full clearance, m."),
    ]
    for name, default, text in reversed(opts):
        f = click.option(name, type=float, default=default, show_default=True, help=text)(f)
    f = click.option("--discrete-braking/--no-discrete-braking", default=d.discrete_braking,
                     show_default=True,
                     help="Admissibility counts the v*T/2 driven while a command is held "
                          "(off: the paper's v <= sqrt(2 D acc)).")(f)
    f = click.option("--turn-circle-close/--no-turn-circle-close", default=d.turn_circle_close,
                     show_default=True,
                     help="Eq. 13 also brakes while the goal is inside the current turning "
                          "circle (off: only within --goal-close-m).")(f)
    return f


def _dwa_params(kw: dict[str, Any], footprint_radius_m: float | None = None) -> Any:
    from slitcli.dwa import DwaParams

    names = ("v_max_mps", "w_max_dps", "acc_mps2", "ang_acc_dps2", "dt_s", "heading_clamp_deg",
             "v_res_mps", "w_res_dps", "heading_horizon_s", "goal_close_m", "d_max_m", "alpha",
             "beta", "gamma", "turn_circle_close", "discrete_braking", "predict_horizon_s",
             "predict_step_s", "moving_buffer_m")
    extra = {} if footprint_radius_m is None else {"footprint_radius_m": footprint_radius_m}
    return DwaParams(**{k: kw.pop(k) for k in names}, **extra)


@cli.command("dwa", short_help="Offline modified DWA over a recorded range table.")
@click.argument("ranges", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--goal", required=True, metavar="X,Y",
              callback=_floats(2, "two numbers X,Y in metres"),
              help="Goal X,Y in metres, in the robot frame at the first frame "
                   "(x forward, y left).")
@click.option("-o", "--out", "out", required=True,
              type=click.Path(dir_okay=False, path_type=Path), help="CMDS.csv to write.")
@click.option("--rig", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig file (for mount.forward_m). Default: the paper rig.")
@click.option("--range-column", default="fused_range_m", show_default=True,
              type=click.Choice(["fused_range_m", "laser_range_m", "stereo_range_m"]),
              help="Which range of the table the planner uses.")
@click.option("--footprint-radius-m", type=float, default=0.32, show_default=True,
              help="Robot radius plus safety margin, m.")
@click.option("--memory", type=click.Choice(["clearing", "expiry", "off"]), default="clearing",
              show_default=True,
              help="Obstacle memory: 'clearing' = kept until a frame's rays see the place free, "
                   "moving obstacles tracked and predicted; 'expiry' = every point kept "
                   "--memory-s seconds (the former rule); 'off' = current frame only.")
@click.option("--memory-s", type=float, default=10.0, show_default=True,
              help="With --memory expiry: remember obstacle points this long, s.")
@click.option("--memory-cell-m", type=float, default=0.05, show_default=True,
              help="One remembered point per grid cell of this size, m.")
@click.option("--period-s", type=float, default=None,
              help="Time between frames, s, for a table whose time_s is empty (detect on a "
                   "sequence without times.csv): time_s = frame x this [default: none: such a "
                   "table is refused]. Example: --period-s 0.1")
@click.option("--free-range-m", type=float, default=0.0, show_default=True,
              help="Up to this range a bearing bin with no return counts as free space and "
                   "clears the memory, m. 0 (default) = only a farther return clears: a "
                   "missed return of a vision range table never wipes a real obstacle.")
@click.option("--overwrite", is_flag=True, help="Replace CMDS.csv if it exists.")
@_dwa_options
def dwa_cmd(ranges: Path, goal: tuple[float, float], out: Path, rig: Path | None,
            range_column: str, footprint_radius_m: float, memory: str, memory_s: float,
            memory_cell_m: float, free_range_m: float, period_s: float | None,
            overwrite: bool, **kw: Any) -> None:
    """Offline modified DWA (Eqs. 12-13) over a recorded range table.

    RANGES is a range table written by `slitcli detect` (columns frame, time_s,
    bearing_deg, ..., fused_range_m; empty = no return). For every frame the planner
    writes the command (v_mps, w_dps) it would have sent. A range table has no
    odometry, so the robot is ASSUMED TO HAVE MOVED EXACTLY AS COMMANDED between
    frames; poses and the goal are in the robot frame at the first frame. Output
    columns (CMDS.csv): frame, time_s (s), x_m, y_m (m), heading_deg, goal_distance_m,
    v_mps (m/s), w_dps (deg/s), status, d_collision_m, n_points; docs/dwa.md.

    Example: slitcli dwa out/det/ranges.csv --goal 4,0.5 -o out/cmds.csv
    """
    from slitcli.dwa_table import dwa_offline
    from slitcli.rig import load_rig, paper_rig

    params = _dwa_params(kw, footprint_radius_m)
    the_rig = load_rig(rig) if rig is not None else paper_rig()
    cmds = dwa_offline(ranges, goal, out, params, range_column=range_column,
                       forward_m=the_rig.mount.forward_m, memory_s=memory_s,
                       memory_cell_m=memory_cell_m, memory=memory, free_m=free_range_m,
                       period_s=period_s, overwrite=overwrite, inputs=[rig])
    counts = cmds["status"].value_counts().to_dict()
    click.echo(f"wrote {out}: {len(cmds)} frames ("
               + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + ")")


@cli.command("simulate-dwa")
@click.argument("world", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", "out", required=True,
              type=click.Path(file_okay=False, path_type=Path), help="Output folder.")
@click.option("--scenario", type=click.Choice(["paper", "random", "hard", "dynamic"]),
              default=None,
              help="Built-in worlds instead of WORLD: 'paper' (box in the way, sensing ranges "
                   "0.6,1,1.5,2 m), 'random' (--worlds seeded worlds, 3 m), 'hard' (8 hard "
                   "static worlds, 1,2,3 m) or 'dynamic' (a walking person: crossings, a "
                   "doorway, a slow walker, one walking at the robot; each also run without "
                   "the person as <case>_empty; 3 m) [default: none: give WORLD].")
@click.option("--sensing", type=click.Choice(["perfect", "vision"]), default="perfect",
              show_default=True,
              help="Sensing mode: 'perfect' = true ranges per 1-deg bearing bin over the "
                   "camera's field of view, cut at the sensing range (the paper's Matlab "
                   "simulation); 'vision' = render both cameras, detect and fuse at every "
                   "step (the full pipeline; about 0.2 s a step).")
@click.option("--sensing-range", "sensing_range", metavar="R[,R...]",
              callback=_floats(None, "comma-separated ranges in metres"), default=None,
              help="Sensing range(s), m, one run each, e.g. 0.6,1,1.5,2. Default: the "
                   "scenario's, 3 for a WORLD file.")
@click.option("--worlds", type=click.IntRange(1, 10_000), default=100, show_default=True,
              help="Number of random worlds, 1-10000 (--scenario random).")
@click.option("--seed", type=click.IntRange(0, 2**62), default=0, show_default=True,
              help="Seed of the first random world (>= 0).")
@click.option("--start", metavar="X,Y,YAW_DEG", default=None,
              callback=_floats(3, "three numbers X,Y,YAW_DEG"),
              help="Override the world's start: X,Y in m, heading in deg [default: the "
                   "world's robot.start]. Example: --start 0,0,0")
@click.option("--goal", metavar="X,Y", callback=_floats(2, "two numbers X,Y in metres"),
              default=None,
              help="Override the world's goal X,Y, m [default: the world's goal_xy_m]. "
                   "Example: --goal 6,0")
@click.option("--rig", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig file (field of view, mount.forward_m). Default: the paper rig.")
@click.option("--bin-deg", type=click.FloatRange(0.05, 10.0), default=1.0, show_default=True,
              help="Bearing bin width of the sensed range table, deg (0.05-10).")
@click.option("--safety-margin-m", type=float, default=0.07, show_default=True,
              help="Planner footprint = robot radius + this, m.")
@click.option("--memory", type=click.Choice(["clearing", "expiry", "off"]), default="clearing",
              show_default=True,
              help="Obstacle memory: 'clearing' = kept until a frame's rays see the place free, "
                   "moving obstacles tracked and predicted; 'expiry' = every point kept "
                   "--memory-s seconds (the former rule); 'off' = current frame only.")
@click.option("--memory-s", type=float, default=10.0, show_default=True,
              help="With --memory expiry: remember obstacle points this long, s.")
@click.option("--memory-cell-m", type=float, default=0.05, show_default=True,
              help="One remembered point per grid cell of this size, m.")
@click.option("--max-time-s", type=float, default=300.0, show_default=True,
              help="Give up after this simulated time, s.")
@click.option("--stuck-timeout-s", type=float, default=60.0, show_default=True,
              help="Report 'stuck' when for this long the goal distance has not improved by "
                   "5 cm and the robot has reached no new ground (no place farther than "
                   "--stuck-new-ground-m from everywhere it had been), s.")
@click.option("--stuck-new-ground-m", type=float, default=0.5, show_default=True,
              help="See --stuck-timeout-s, m.")
@click.option("--recovery-after-s", type=float, default=20.0, show_default=True,
              help="A robot that has not moved 5 cm for this long backs up "
                   "--recovery-back-m along the way it came, then plans again, s (0 = off).")
@click.option("--recovery-back-m", type=float, default=0.3, show_default=True,
              help="Back-up distance of the recovery, m.")
@click.option("--save-ranges", is_flag=True,
              help="Also write OUT/ranges_<case>.csv, the sensed range table of each run "
                   "(replay it with slitcli dwa).")
@click.option("--plots", is_flag=True,
              help="Also draw OUT/plots/<case>.png: Figs. 8/9 per case, with the path of "
                   "every moving object.")
@click.option("--overwrite", is_flag=True,
              help="Replace what an earlier simulate-dwa wrote in OUT (other files are kept).")
@_dwa_options
def simulate_dwa_cmd(world: Path | None, out: Path, scenario: str | None, sensing: str,
                     sensing_range: tuple[float, ...] | None, worlds: int, seed: int,
                     start: tuple[float, float, float] | None,
                     goal: tuple[float, float] | None, rig: Path | None, bin_deg: float,
                     safety_margin_m: float, memory: str, memory_s: float,
                     memory_cell_m: float, max_time_s: float, stuck_timeout_s: float,
                     stuck_new_ground_m: float, recovery_after_s: float,
                     recovery_back_m: float, save_ranges: bool, plots: bool,
                     overwrite: bool, **kw: Any) -> None:
    """Closed-loop modified DWA: sense -> plan -> move, per world and sensing range.

    WORLD is a scene file (docs/scene.md) whose robot.start and goal_xy_m are the
    start and goal; or use --scenario. Writes OUT/trajectory_<case>.csv,
    OUT/metrics.csv, the world(s) as YAML and OUT/params.yaml (docs/dwa.md).

    \b
    Examples:
      slitcli simulate-dwa --scenario paper -o out/dwa
      slitcli simulate-dwa --scenario random --worlds 100 -o out/random
      slitcli simulate-dwa --scenario dynamic -o out/dynamic
      slitcli simulate-dwa my_world.yaml --sensing-range 1,3 -o out/mine
    """
    from slitcli.rig import load_rig, paper_rig
    from slitcli.sim.loop import SimParams, simulate_dwa

    params = _dwa_params(kw)
    sim = SimParams(safety_margin_m=safety_margin_m, memory=memory, memory_s=memory_s,
                    memory_cell_m=memory_cell_m, max_time_s=max_time_s,
                    stuck_timeout_s=stuck_timeout_s, stuck_new_ground_m=stuck_new_ground_m,
                    recovery_after_s=recovery_after_s, recovery_back_m=recovery_back_m)
    the_rig = load_rig(rig) if rig is not None else paper_rig()
    metrics = simulate_dwa(out, the_rig, params, sim, sensing=sensing, world_path=world,
                           scenario=scenario, sensing_ranges_m=sensing_range, worlds=worlds,
                           seed=seed, start=start, goal_xy_m=goal, bin_deg=bin_deg,
                           overwrite=overwrite, save_ranges=save_ranges, inputs=[rig])
    if plots:
        from slitcli.figures import dwa_run_figures

        dwa_run_figures(out)
    n = len(metrics)
    reached = int(metrics["reached_goal"].sum())
    collided = int(metrics["collided"].sum())
    click.echo(f"wrote {out}: {n} runs, reached {reached}, collided {collided}, "
               f"stuck {int((metrics['outcome'] == 'stuck').sum())}, "
               f"timeout {int((metrics['outcome'] == 'timeout').sum())}")

