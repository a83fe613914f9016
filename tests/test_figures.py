"""Each figure is drawn from a small table; check what was plotted, not just a file."""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from slitcli.evaluate import range_errors
from slitcli.figures import (
    draw_accuracy,
    draw_fig4,
    draw_fig7,
    draw_fig8,
    draw_fig9,
    stripe_segments,
)


def _laser(u, v, x):
    return pd.DataFrame({"frame": 0, "u_px": u, "v_px": v, "x_m": x, "y_m": 0.0})


def test_fig4_annotates_each_obstacle_with_measured_and_true():
    u1, u2 = np.arange(30, 120), np.arange(180, 280)
    det = pd.concat([_laser(u1, 236.0, 0.603), _laser(u2, 195.3, 0.798)])
    truth = pd.concat([_laser(u1, 236.1, 0.600), _laser(u2, 195.3, 0.800)])
    fig, ax = plt.subplots()
    notes = draw_fig4(ax, np.zeros((240, 320, 3), np.uint8), det, truth)
    assert [round(n["measured_m"], 3) for n in notes] == [0.603, 0.798]
    assert [round(n["true_m"], 3) for n in notes] == [0.6, 0.8]
    texts = [t.get_text() for t in ax.texts]
    assert texts == ["measured 0.603 m\ntrue 0.600 m", "measured 0.798 m\ntrue 0.800 m"]
    assert len(ax.lines[0].get_xdata()) == len(u1) + len(u2)
    assert ax.get_xlabel() == "u (px)" and ax.get_ylabel() == "v (px)"
    plt.close(fig)


def test_stripe_segments_split_on_gaps_and_range_jumps():
    det = pd.concat([_laser(np.arange(0, 20), 200.0, 0.8), _laser(np.arange(20, 40), 190, 1.0),
                     _laser(np.arange(50, 55), 190, 1.0)])
    segs = stripe_segments(det)
    assert [len(s) for s in segs] == [20, 20]  # the 5-column piece is too short


def test_fig7_four_panels_and_a_colour_bar_in_metres():
    fig, axes = plt.subplots(2, 2)
    img = np.zeros((24, 32, 3), np.uint8)
    dist = np.full((24, 32), np.nan)
    dist[5:10, 5:10] = 1.5
    draw_fig7(axes.ravel(), img, img, dist > 0, dist)
    assert len(fig.axes) == 5  # four panels and the colour bar
    assert fig.axes[4].get_ylabel() == "distance along the optical axis (m)"
    assert [a.get_title()[:3] for a in axes.ravel()] == ["(a)", "(b)", "(c)", "(d)"]
    plt.close(fig)


def _traj(n, y_peak):
    t = np.arange(n) * 0.2
    return pd.DataFrame({"t_s": t, "x_m": np.linspace(0, 4, n),
                         "y_m": y_peak * np.sin(np.linspace(0, np.pi, n)),
                         "nearest_obstacle_m": np.linspace(2.0, 0.5, n)})


def test_fig8_and_fig9_one_line_per_case():
    trajs = {f"sensing {s} m": _traj(20 + i, 0.3 * i) for i, s in enumerate([0.6, 1, 1.5, 2])}
    seg = np.array([[[1.9, -0.2], [2.1, -0.2]], [[2.1, -0.2], [2.1, 0.2]],
                    [[2.1, 0.2], [1.9, 0.2]], [[1.9, 0.2], [1.9, -0.2]]])
    fig, axes = plt.subplots(1, 4)
    draw_fig8(axes, trajs, seg, np.array([[3.0, 1.0, 0.2]]), goal_xy=(4.0, 0.0))
    for ax, (case, tr) in zip(axes, trajs.items(), strict=True):
        paths = [ln for ln in ax.lines if ln.get_label().startswith("robot path")]
        assert len(paths) == 1 and len(paths[0].get_xdata()) == len(tr)
        assert ax.get_title() == case and ax.get_xlabel() == "x (m)"
        assert len(ax.patches) == 2  # the box and the cylinder
    plt.close(fig)
    fig, ax = plt.subplots()
    draw_fig9(ax, trajs)
    assert len(ax.lines) == 4
    assert ax.get_xlabel() == "time (s)" and ax.get_ylabel() == "robot-obstacle distance (m)"
    plt.close(fig)


def test_accuracy_joins_truth_and_bins_errors():
    true = np.repeat([0.7, 1.2, 2.4], 10)
    ranges = pd.DataFrame({"frame": 0, "bearing_deg": np.arange(30), "laser_range_m": np.nan,
                           "stereo_range_m": true + 0.05, "fused_range_m": true + 0.02})
    ranges.loc[:9, "laser_range_m"] = 0.701
    truth = pd.DataFrame({"frame": 0, "bearing_deg": np.arange(30), "range_m": true})
    err = range_errors(ranges, truth)
    assert err["fused_err_m"].to_numpy() == pytest.approx(0.02)
    assert err["laser_err_m"].notna().sum() == 10
    fig, ax = plt.subplots()
    drawn = draw_accuracy(ax, err)
    assert drawn == {"fused": 3, "laser": 1, "stereo": 3}
    lines = {ln.get_label(): ln for ln in ax.lines}
    assert lines["fused"].get_ydata() == pytest.approx([2.0, 2.0, 2.0])
    assert ax.get_ylabel() == "median |range error| (cm)"
    plt.close(fig)


def test_accuracy_fused_stays_visible_on_top_of_the_same_stereo_curve():
    true = np.repeat([1.2, 1.6, 2.4], 10)
    ranges = pd.DataFrame({"frame": 0, "bearing_deg": np.arange(30), "laser_range_m": np.nan,
                           "stereo_range_m": true + 0.05, "fused_range_m": true + 0.05})
    truth = pd.DataFrame({"frame": 0, "bearing_deg": np.arange(30), "range_m": true})
    fig, ax = plt.subplots()
    draw_accuracy(ax, range_errors(ranges, truth))
    lines = {ln.get_label(): ln for ln in ax.lines}
    fused, stereo = lines["fused"], lines["stereo"]
    np.testing.assert_allclose(fused.get_ydata(), stereo.get_ydata())  # the same curve
    assert fused.get_zorder() > stereo.get_zorder()
    assert fused.get_linestyle() != stereo.get_linestyle()
    assert fused.get_marker() != stereo.get_marker() and fused.get_markerfacecolor() == "none"
    # the open square is wider than stereo's dot: stereo shows inside, fused around it
    assert fused.get_markersize() > 1.5 * stereo.get_markersize()
    plt.close(fig)


def test_fig9_every_case_visible_where_curves_coincide():
    base = _traj(30, 0.0)
    other = _traj(30, 0.0)
    other["nearest_obstacle_m"] = np.linspace(2.0, 1.0, 30)
    trajs = {"sensing 0.6 m": base, "sensing 1 m": base.copy(),
             "sensing 1.5 m": other, "sensing 2 m": other.copy()}
    fig, ax = plt.subplots()
    same = draw_fig9(ax, trajs)
    assert same["sensing 0.6 m"] == ["sensing 1 m"] and same["sensing 2 m"] == ["sensing 1.5 m"]
    lines = ax.lines
    assert len(lines) == 4
    styles = {(str(ln.get_linestyle()), ln.get_marker()) for ln in lines}
    assert len(styles) == 4  # no two cases share style and marker
    for a, b in ((0, 1), (2, 3)):
        # the data are not shifted: the coinciding lines hold the same values
        np.testing.assert_array_equal(lines[a].get_ydata(), lines[b].get_ydata())
        # the later case is narrower and on top, so both show
        assert lines[b].get_linewidth() < lines[a].get_linewidth()
        assert lines[b].get_zorder() > lines[a].get_zorder()
        # their markers sit on different samples
        assert lines[a].get_markevery()[0] != lines[b].get_markevery()[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0] == "sensing 0.6 m (same curve as sensing 1 m)"
    assert labels[3] == "sensing 2 m (same curve as sensing 1.5 m)"
    plt.close(fig)


def test_fig8_panels_share_their_ranges():
    trajs = {f"sensing {s} m": _traj(20, peak) for s, peak in ((0.6, 1.8), (2, -0.8))}
    seg = np.array([[[2.9, -0.2], [3.1, -0.2]], [[3.1, -0.2], [3.1, 0.2]],
                    [[3.1, 0.2], [2.9, 0.2]], [[2.9, 0.2], [2.9, -0.2]]])
    fig, axes = plt.subplots(1, 2)
    draw_fig8(axes, trajs, seg, np.zeros((0, 3)), goal_xy=(4.0, 0.0), robot_radius_m=0.2)
    assert axes[0].get_ylim() == axes[1].get_ylim()
    assert axes[0].get_xlim() == axes[1].get_xlim()
    lo, hi = axes[0].get_ylim()
    y = np.concatenate([t["y_m"] for t in trajs.values()])
    # both paths, with the margin of 0.3 m plus the robot's radius
    assert lo == pytest.approx(y.min() - 0.5) and hi == pytest.approx(y.max() + 0.5)
    plt.close(fig)


def test_fig4_legend_names_the_stripe():
    fig, ax = plt.subplots()
    draw_fig4(ax, np.zeros((240, 320, 3), np.uint8), _laser(np.arange(30, 120), 236.0, 0.6))
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["detected stripe"]
    plt.close(fig)
