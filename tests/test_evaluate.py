"""Scoring against the renderer's truth (slitcli.evaluate)."""

import numpy as np
import pandas as pd

from slitcli.evaluate import laser_truth_bins


def test_laser_truth_is_the_nearest_lit_point_in_the_wedge():
    # a wall 0.8 m ahead lit at bearings 0.2, 0.6, ..., 2.2 deg (one point per column):
    # bin 1 (0.5-1.5 deg) holds columns at 0.6-1.4 deg, but its nearest lit point is on
    # its 0.5 deg boundary, 0.8 / cos(0.5 deg), interpolated between 0.2 and 0.6 deg (a
    # chord, 4 um behind the arc; the nearest column, at 0.6 deg, is 14 um farther)
    b = np.arange(0.2, 2.3, 0.4)
    wall = pd.DataFrame({"frame": 0, "u_px": np.arange(b.size), "bearing_deg": b,
                         "range_m": 0.8 / np.cos(np.radians(b))})
    t = laser_truth_bins(wall).set_index("bearing_deg")["laser_true_m"]
    np.testing.assert_allclose(t.loc[1.0], 0.8 / np.cos(np.radians(0.5)), atol=5e-6)
    np.testing.assert_allclose(t.loc[2.0], 0.8 / np.cos(np.radians(1.5)), atol=5e-6)
    np.testing.assert_allclose(t.loc[0.0], 0.8 / np.cos(np.radians(0.2)), atol=1e-12)
    # no interpolation across a range jump (another surface) or between frames
    step = wall.assign(range_m=np.where(b > 1.5, wall.range_m + 0.5, wall.range_m))
    t = laser_truth_bins(step).set_index("bearing_deg")["laser_true_m"]
    np.testing.assert_allclose(t.loc[2.0], 0.5 + 0.8 / np.cos(np.radians(1.8)), atol=1e-12)
    two = pd.concat([wall[b < 0.5], wall[b > 0.5].assign(frame=1)])
    t = laser_truth_bins(two).set_index(["frame", "bearing_deg"])["laser_true_m"]
    np.testing.assert_allclose(t.loc[(1, 1.0)], 0.8 / np.cos(np.radians(0.6)), atol=1e-12)
