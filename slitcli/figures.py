"""The paper's figures (Figs. 4, 7, 8, 9) and a range-accuracy figure, from written tables.

Each ``draw_*`` function takes tables (pandas) and images (numpy) and draws onto
matplotlib axes it is given; :func:`make_figures` reads the files the other commands
wrote and saves the figures. Nothing here computes detection or planning results.
Figures are plain :class:`matplotlib.figure.Figure` objects rendered by the Agg canvas:
no pyplot, no window, no global state.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import cv2
import matplotlib
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from slitcli.errors import SlitcliError
from slitcli.evaluate import range_errors

FORMATS = ("png", "svg", "pdf")
CASE_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


# ----------------------------------------------------------------------------- Fig. 4
def stripe_segments(laser: pd.DataFrame, *, max_gap_px: int = 2, max_step_m: float = 0.05,
                    min_cols: int = 8) -> list[pd.DataFrame]:
    """Split one frame's stripe points into obstacle segments (continuous columns and
    ranges), longest first."""
    if laser.empty:
        return []
    t = laser.sort_values("u_px")
    brk = (t["u_px"].diff() > max_gap_px) | (t["x_m"].diff().abs() > max_step_m)
    seg = brk.cumsum()
    parts = [g for _, g in t.groupby(seg) if len(g) >= min_cols]
    return sorted(parts, key=len, reverse=True)


def draw_fig4(ax: Axes, left_rgb: np.ndarray, laser: pd.DataFrame,
              truth: pd.DataFrame | None = None, *, n_obstacles: int = 2) -> list[dict]:
    """Fig. 4: the left image, the detected stripe and the range of each obstacle.

    Parameters
    ----------
    ax : Axes
    left_rgb : ndarray (H, W, 3) uint8, RGB
    laser : DataFrame
        One frame of a laser table (``u_px``, ``v_px``, ``x_m``...).
    truth : DataFrame, optional
        The true stripe points of that frame (gt/laser.csv), for the true ranges.
    n_obstacles : int
        Annotate the nearest this many stripe segments.

    Returns
    -------
    list of dict
        Per annotated obstacle: ``measured_m``, ``true_m`` (forward distance, median
        over the segment's columns) and its columns.
    """
    ax.imshow(left_rgb)
    ax.plot(laser["u_px"], laser["v_px"], ".", color="cyan", ms=2.5, label="detected stripe")
    segs = stripe_segments(laser)[: max(n_obstacles, 0) + 3]
    segs = sorted(segs, key=lambda g: float(g["x_m"].median()))[:n_obstacles]
    notes = []
    for g in sorted(segs, key=lambda g: float(g["u_px"].median())):
        measured = float(g["x_m"].median())
        true = float("nan")
        if truth is not None and not truth.empty:
            tr = truth[truth["u_px"].isin(g["u_px"])]
            true = float(tr["x_m"].median()) if len(tr) else float("nan")
        text = f"measured {measured:.3f} m"
        if math.isfinite(true):
            text += f"\ntrue {true:.3f} m"
        u, v = float(g["u_px"].median()), float(g["v_px"].min())
        ax.annotate(text, xy=(u, v), xytext=(u, max(v - 45, 12)), ha="center", fontsize=8,
                    color="white", arrowprops={"arrowstyle": "->", "color": "white"},
                    bbox={"boxstyle": "round", "fc": "black", "alpha": 0.6})
        notes.append({"measured_m": measured, "true_m": true,
                      "u_min": int(g["u_px"].min()), "u_max": int(g["u_px"].max())})
    ax.set_xlabel("u (px)")
    ax.set_ylabel("v (px)")
    ax.set_title("Laser stripe and forward distance of each obstacle")
    ax.legend(loc="upper right", markerscale=4, framealpha=0.85)
    return notes


# ----------------------------------------------------------------------------- Fig. 7
def draw_fig7(axes: Sequence[Axes], left_rgb: np.ndarray, right_rgb: np.ndarray,
              mask: np.ndarray, distance_m: np.ndarray, *, max_range_m: float = 3.0) -> None:
    """Fig. 7: (a) left, (b) right, (c) binary obstacle image, (d) distance image.

    ``mask`` is (H, W) bool; ``distance_m`` (H, W) metres with NaN where invalid.
    """
    a, b, c, d = axes
    a.imshow(left_rgb)
    a.set_title("(a) left image")
    b.imshow(right_rgb)
    b.set_title("(b) right image")
    c.imshow(mask, cmap="gray", vmin=0, vmax=1)
    c.set_title("(c) obstacle (binary disparity) image")
    dist = np.ma.masked_invalid(distance_m)
    cmap = matplotlib.colormaps["turbo"].with_extremes(bad="black")
    im = d.imshow(dist, cmap=cmap, vmin=0.0, vmax=max_range_m)
    d.set_title("(d) distance image")
    cb = d.figure.colorbar(im, ax=d, fraction=0.046, pad=0.04)
    cb.set_label("distance along the optical axis (m)")
    for ax in axes:
        ax.set_xlabel("u (px)")
        ax.set_ylabel("v (px)")


# ----------------------------------------------------------------------------- Fig. 8/9
def _draw_obstacles(ax: Axes, segments_xy: np.ndarray, circles_xyr: np.ndarray) -> None:
    # a box's outline comes as 4 consecutive segments: draw them as filled polygons
    for s in segments_xy:
        ax.plot(s[:, 0], s[:, 1], color="0.3", lw=2)
    for k in range(0, len(segments_xy) - 3, 4):
        quad = segments_xy[k:k + 4, 0, :]
        if np.allclose(segments_xy[k + 3, 1], segments_xy[k, 0]):
            ax.add_patch(Polygon(quad, closed=True, fc="0.75", ec="0.3"))
    for cx, cy, r in circles_xyr:
        ax.add_patch(Circle((cx, cy), r, fc="0.75", ec="0.3"))


def shared_limits(trajectories: dict[str, pd.DataFrame], segments_xy: np.ndarray,
                  circles_xyr: np.ndarray, goal_xy: tuple[float, float] | None = None,
                  margin_m: float = 0.3) -> tuple[tuple[float, float], tuple[float, float]]:
    """One x and one y range (m) holding every path, obstacle and the goal, so panels
    side by side compare at a glance."""
    xs = [t["x_m"].to_numpy(dtype=float) for t in trajectories.values()]
    ys = [t["y_m"].to_numpy(dtype=float) for t in trajectories.values()]
    if len(segments_xy):
        xs.append(np.asarray(segments_xy)[..., 0].ravel())
        ys.append(np.asarray(segments_xy)[..., 1].ravel())
    if len(circles_xyr):
        c = np.asarray(circles_xyr)
        xs += [c[:, 0] - c[:, 2], c[:, 0] + c[:, 2]]
        ys += [c[:, 1] - c[:, 2], c[:, 1] + c[:, 2]]
    if goal_xy is not None:
        xs.append(np.array([goal_xy[0]]))
        ys.append(np.array([goal_xy[1]]))
    x, y = np.concatenate(xs), np.concatenate(ys)
    return ((float(np.nanmin(x)) - margin_m, float(np.nanmax(x)) + margin_m),
            (float(np.nanmin(y)) - margin_m, float(np.nanmax(y)) + margin_m))


def draw_fig8(axes: Sequence[Axes], trajectories: dict[str, pd.DataFrame],
              segments_xy: np.ndarray, circles_xyr: np.ndarray,
              goal_xy: tuple[float, float] | None = None,
              robot_radius_m: float | None = None) -> None:
    """Fig. 8: one x-y panel per case with its trajectory and the obstacles.

    Every panel shows the same x and y range (:func:`shared_limits`) at one scale.
    """
    xlim, ylim = shared_limits(trajectories, segments_xy, circles_xyr, goal_xy,
                               margin_m=0.3 + (robot_radius_m or 0.0))
    for (case, traj), ax, colour in zip(trajectories.items(), axes, CASE_COLOURS,
                                        strict=False):
        _draw_obstacles(ax, segments_xy, circles_xyr)
        ax.plot(traj["x_m"], traj["y_m"], color=colour, lw=1.8, label=f"robot path ({case})")
        ax.plot(traj["x_m"].iloc[0], traj["y_m"].iloc[0], "ko", ms=5)
        if robot_radius_m:
            ax.add_patch(Circle((traj["x_m"].iloc[-1], traj["y_m"].iloc[-1]), robot_radius_m,
                                fill=False, ec=colour, ls="--"))
        if goal_xy is not None:
            ax.plot(*goal_xy, "k*", ms=10)
        ax.set_xlim(*xlim)
        ax.set_ylim(*ylim)
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(case)
        ax.grid(alpha=0.3)


# Line style, marker and width per case: wider lines first, so a case whose curve
# coincides with an earlier one still shows as a narrower, differently dashed line on
# top of it, with its own markers.
CASE_STYLES = (("-", "o", 4.2), ("--", "s", 2.8), ("-.", "^", 2.2), (":", "D", 1.6),
               ((0, (5, 1, 1, 1)), "v", 1.2), ((0, (1, 1)), "P", 1.0))


def coinciding_cases(trajectories: dict[str, pd.DataFrame], column: str,
                     tol: float = 0.005) -> dict[str, list[str]]:
    """For each case, the other cases whose ``column`` over time is the same curve
    (same times, values within ``tol``)."""
    same: dict[str, list[str]] = {c: [] for c in trajectories}
    items = list(trajectories.items())
    for i, (a, ta) in enumerate(items):
        for b, tb in items[i + 1:]:
            if len(ta) == len(tb) and np.allclose(ta["t_s"], tb["t_s"]) and \
                    np.nanmax(np.abs(ta[column].to_numpy() - tb[column].to_numpy())) <= tol:
                same[a].append(b)
                same[b].append(a)
    return same


def draw_fig9(ax: Axes, trajectories: dict[str, pd.DataFrame]) -> dict[str, list[str]]:
    """Fig. 9: robot-obstacle distance against time, one line per case.

    Each case has its own colour, line style, width and marker (``CASE_STYLES``); a
    case whose curve coincides with another's says so in the legend.

    Returns
    -------
    dict
        Per case, the cases drawn on the same curve (:func:`coinciding_cases`).
    """
    same = coinciding_cases(trajectories, "nearest_obstacle_m")
    n_cases = max(len(trajectories), 1)
    for k, ((case, traj), colour, (ls, marker, lw)) in enumerate(
            zip(trajectories.items(), CASE_COLOURS, CASE_STYLES, strict=False)):
        every = max(len(traj) // 12, n_cases)
        # markers start at a different sample per case, so coinciding curves show all
        label = case if not same[case] else \
            f"{case} (same curve as {', '.join(same[case])})"
        ax.plot(traj["t_s"], traj["nearest_obstacle_m"], color=colour, ls=ls, lw=lw,
                marker=marker, ms=6, mfc="white", mew=1.4,
                markevery=(k * every // n_cases, every), label=label, zorder=2 + k)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("robot-obstacle distance (m)")
    ax.set_title("Distance to the nearest obstacle")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2)
    return same


def draw_dynamic_case(axes: Sequence[Axes], traj: pd.DataFrame, world, *, title: str = "",
                      mark_every_s: float = 5.0) -> None:
    """Figs. 8/9 for a world with moving objects: the x-y paths with each moving object's
    track (markers at the same instants on both), and the clearance against time.

    ``world`` is the :class:`slitcli.sim.scene.Scene` run (static outlines at t = 0 are
    drawn grey; moving objects as their centre tracks and their outline at each marker).
    """
    from slitcli.sim.scene import Cylinder, Wall, centre_at
    from slitcli.sim.truth import footprints

    xy, dist = axes[0], axes[1]
    still = [o for o in world.objects if isinstance(o, Wall) or not o.motion]
    moving = [o for o in world.objects if not isinstance(o, Wall) and o.motion]
    fp = footprints(type(world)(name=world.name, objects=tuple(still)), z_low_m=0.0,
                    z_high_m=np.inf)
    _draw_obstacles(xy, fp.segments_xy, fp.circles_xyr)
    t = traj["t_s"].to_numpy()
    xy.plot(traj["x_m"], traj["y_m"], color="tab:blue", lw=1.8, label="robot")
    marks = np.arange(0.0, t[-1] + 1e-9, mark_every_s)
    idx = np.searchsorted(t, marks).clip(0, len(t) - 1)
    xy.plot(traj["x_m"].to_numpy()[idx], traj["y_m"].to_numpy()[idx], "o", color="tab:blue",
            ms=4)
    for i, ob in enumerate(moving):
        track = np.array([centre_at(ob.motion, float(x)) for x in t])
        xy.plot(track[:, 0], track[:, 1], "--", color="tab:red", lw=1.2,
                label="person" if i == 0 else None)
        for m in marks:
            c = centre_at(ob.motion, float(m))
            r = ob.radius_m if isinstance(ob, Cylinder) else 0.5 * math.hypot(*ob.size_m[:2])
            xy.add_patch(Circle(c, r, fill=False, ec="tab:red", lw=0.6, alpha=0.6))
            xy.annotate(f"{m:g}", c, fontsize=6, color="tab:red", ha="center", va="center")
    for m, j in zip(marks, idx, strict=True):
        xy.annotate(f"{m:g}", (traj["x_m"].iloc[j], traj["y_m"].iloc[j]), fontsize=6,
                    xytext=(2, 2), textcoords="offset points")
    if world.goal_xy_m is not None:
        xy.plot(*world.goal_xy_m, "k*", ms=10)
    xy.set_aspect("equal", adjustable="datalim")
    xy.set_xlabel("x (m)")
    xy.set_ylabel("y (m)")
    xy.set_title(title or world.name)
    xy.grid(alpha=0.3)
    xy.legend(fontsize=7)
    dist.plot(t, traj["nearest_obstacle_m"], color="tab:blue")
    dist.set_xlabel("time (s)")
    dist.set_ylabel("robot-obstacle distance (m)")
    dist.set_title("Distance to the nearest obstacle (moving ones where they are)")
    dist.grid(alpha=0.3)


def dwa_run_figures(run_dir: str | Path, *, fmt: str = "png", dpi: int = 120) -> list[Path]:
    """One Figs. 8/9-style figure per case of a ``simulate-dwa`` output folder.

    Writes ``RUN/plots/<case>.<fmt>`` (x-y paths with the moving objects' tracks, and
    the clearance over time) and returns the paths.
    """
    import yaml

    from slitcli.sim.scene import load_scene

    check_format(fmt, dpi)
    run = Path(run_dir)
    params = yaml.safe_load(_need(run / "params.yaml", "slitcli simulate-dwa").read_text())
    cases = params["cases"]
    single = len({c["world"] for c in cases}) == 1
    written = []
    for c in cases:
        world = load_scene(run / ("world.yaml" if single else f"world_{c['world']}.yaml"))
        traj = pd.read_csv(_need(run / f"trajectory_{c['case']}.csv", "slitcli simulate-dwa"))
        fig = Figure(figsize=(11, 4.5), layout="constrained")
        draw_dynamic_case(fig.subplots(1, 2, width_ratios=[1.6, 1]), traj, world,
                          title=f"{c['case']} (sensing {c['sensing_range_m']:g} m)")
        written.append(save(fig, run / "plots" / f"{c['case']}.{fmt}", dpi=dpi))
    return written


# ----------------------------------------------------------------------------- accuracy
def draw_accuracy(ax: Axes, errors: pd.DataFrame, *, bin_m: float = 0.25) -> dict[str, int]:
    """Median absolute range error against the true distance, per sensor.

    Returns the number of bins (x positions) drawn per sensor.
    """
    edges = np.arange(0.0, float(errors["true_m"].max()) + bin_m, bin_m)
    centres = 0.5 * (edges[:-1] + edges[1:])
    k = np.digitize(errors["true_m"], edges) - 1
    drawn = {}
    # fused is drawn last, dashed with open squares, so it stays visible where it is
    # the same curve as stereo (beyond the laser's band fused takes stereo's ranges)
    styles = {"laser": {"color": "tab:red", "marker": "o", "ls": "-", "lw": 1.5, "ms": 5},
              "stereo": {"color": "tab:blue", "marker": "o", "ls": "-", "lw": 1.5, "ms": 5},
              "fused": {"color": "k", "marker": "s", "ls": "--", "lw": 1.8, "ms": 10,
                        "mfc": "none", "mew": 1.6}}
    for z, name in enumerate(("laser", "stereo", "fused")):
        e = errors[f"{name}_err_m"].abs()
        med = np.array([np.nanmedian(e[(k == i) & e.notna()]) if ((k == i) & e.notna()).sum()
                        >= 5 else np.nan for i in range(len(centres))])
        ok = np.isfinite(med)
        ax.plot(centres[ok], 100 * med[ok], label=name, zorder=3 + z, **styles[name])
        drawn[name] = int(ok.sum())
    ax.set_yscale("log")
    ax.axvspan(0.0, 0.6, color="0.9", zorder=0, label="below both sensors' range")
    ax.set_xlim(left=0.0)
    ax.set_xlabel("true distance (m)")
    ax.set_ylabel("median |range error| (cm)")
    ax.set_title("Range accuracy against the truth (rendered scenes)")
    ax.grid(alpha=0.3)
    ax.legend()
    return drawn


# ----------------------------------------------------------------------------- files
def save(fig: Figure, path: Path, *, dpi: int) -> Path:
    """Render a figure with the Agg canvas and write it atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from slitcli.io.atomic import atomic_path

    FigureCanvasAgg(fig)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=path.suffix[1:], bbox_inches="tight")
    return path


def check_format(fmt: str, dpi: int) -> None:
    if fmt not in FORMATS:
        raise SlitcliError(f"`fmt` {fmt!r} is unknown; use one of {', '.join(FORMATS)}",
                           param="fmt")
    if not 20 <= dpi <= 1200:
        raise SlitcliError(f"`dpi` {dpi} is out of range; give 20-1200", param="dpi")


# ----------------------------------------------------------------------------- make
PAPER_CASES = ("range_0.6m", "range_1m", "range_1.5m", "range_2m")


def _read_rgb(path: Path) -> np.ndarray:
    from slitcli.io.sequence import read_image

    return read_image(path)[..., ::-1]


def _need(path: Path, made_by: str) -> Path:
    if not path.exists():
        raise SlitcliError(f"{path}: not found; it is written by `{made_by}` (see "
                           "docs/reproduction.md for the folder layout)")
    return path


def make_figures(work: str | Path, out: str | Path, *, fmt: str = "png", dpi: int = 150
                 ) -> list[Path]:
    """Draw Figs. 4, 7, 8, 9 and the range-accuracy figure from a work folder.

    ``work`` holds what ``make reproduce-figures`` writes: ``sequences/<scene>/`` (render),
    ``detect/<scene>/`` (detect --save-images) and ``dwa/`` (simulate-dwa --scenario
    paper). Returns the paths written (``fig4``, ``fig7``, ``fig8``, ``fig9``,
    ``accuracy``, with the chosen extension).
    """
    check_format(fmt, dpi)
    w, o = Path(work), Path(out)
    written = []

    seq, det = w / "sequences" / "fig4", w / "detect" / "fig4"
    laser = pd.read_csv(_need(det / "laser.csv", "slitcli detect --save-images"))
    truth = pd.read_csv(_need(seq / "gt" / "laser.csv", "slitcli render"))
    fig = Figure(figsize=(6.4, 5.0), layout="constrained")
    draw_fig4(fig.subplots(), _read_rgb(seq / "left" / "000000.png"),
              laser[laser["frame"] == 0], truth[truth["frame"] == 0])
    written.append(save(fig, o / f"fig4.{fmt}", dpi=dpi))

    seq, det = w / "sequences" / "corridor", w / "detect" / "corridor"
    mask = cv2.imread(str(_need(det / "mask" / "000000.png", "slitcli detect --save-images")),
                      cv2.IMREAD_UNCHANGED) > 0
    dist_mm = cv2.imread(str(det / "distance" / "000000.png"), cv2.IMREAD_UNCHANGED)
    dist = np.where(dist_mm > 0, dist_mm / 1000.0, np.nan)
    fig = Figure(figsize=(10, 7.5), layout="constrained")
    draw_fig7(fig.subplots(2, 2).ravel(), _read_rgb(seq / "left" / "000000.png"),
              _read_rgb(seq / "right" / "000000.png"), mask, dist)
    written.append(save(fig, o / f"fig7.{fmt}", dpi=dpi))

    dwa = w / "dwa"
    from slitcli.sim.scene import load_scene
    from slitcli.sim.truth import footprints

    world = load_scene(_need(dwa / "world.yaml", "slitcli simulate-dwa --scenario paper"))
    fp = footprints(world, z_low_m=0.0, z_high_m=np.inf)
    metrics = pd.read_csv(dwa / "metrics.csv").set_index("case")
    trajs = {}
    for case in PAPER_CASES:
        label = f"sensing {metrics.loc[case, 'sensing_range_m']:g} m"
        trajs[label] = pd.read_csv(_need(dwa / f"trajectory_{case}.csv", "simulate-dwa"))
    fig = Figure(figsize=(12, 7.5), layout="constrained")
    draw_fig8(fig.subplots(2, 2).ravel(), trajs, fp.segments_xy, fp.circles_xyr,
              world.goal_xy_m, world.robot.radius_m)
    written.append(save(fig, o / f"fig8.{fmt}", dpi=dpi))
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    draw_fig9(fig.subplots(), trajs)
    written.append(save(fig, o / f"fig9.{fmt}", dpi=dpi))

    errors = []
    for d in sorted((w / "detect").iterdir()):
        gt = w / "sequences" / d.name / "gt" / "ranges.csv"
        if (d / "ranges.csv").exists() and gt.exists():
            errors.append(range_errors(pd.read_csv(d / "ranges.csv"), pd.read_csv(gt)))
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    draw_accuracy(fig.subplots(), pd.concat(errors, ignore_index=True))
    written.append(save(fig, o / f"accuracy.{fmt}", dpi=dpi))
    return written
