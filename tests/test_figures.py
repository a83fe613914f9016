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
    assert ax.lines[0].get_ydata() == pytest.approx([2.0, 2.0, 2.0])
    assert ax.get_ylabel() == "median |range error| (cm)"
    plt.close(fig)
