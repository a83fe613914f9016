"""Scoring against the renderer's truth (slitcli.evaluate)."""

import numpy as np
import pandas as pd
import pytest

from slitcli.evaluate import laser_range_claim, range_errors


@pytest.mark.parametrize("seed", range(5))
def test_laser_claim_counts_bins_within_one_percent(seed):
    """Bins at 0.6-1.0 m with laser errors drawn around the 1 % limit: the claim's rate
    is the share of |error| <= 1 %, counted by hand."""
    rng = np.random.default_rng(seed)
    n = 200
    true_m = rng.uniform(0.6, 0.999, n)
    rel = rng.uniform(-0.02, 0.02, n)
    truth = pd.DataFrame({"frame": np.arange(n), "bearing_deg": 0.0, "laser_true_m": true_m})
    ranges = pd.DataFrame({"frame": np.arange(n), "bearing_deg": 0.0,
                           "laser_range_m": true_m * (1 + rel)})
    claim, table = laser_range_claim(ranges, truth)
    want = 100 * np.mean(np.abs(true_m * rel) <= 0.01 * true_m)
    assert f"{want:.1f} % of {n} bins" in claim.measured
    assert int(table["bins"].sum()) == n


def test_bins_without_a_lit_truth_are_not_scored():
    truth = pd.DataFrame({"frame": [0, 0], "bearing_deg": [0.0, 1.0],
                          "laser_true_m": [0.8, np.nan]})
    ranges = pd.DataFrame({"frame": [0, 0], "bearing_deg": [0.0, 1.0],
                           "laser_range_m": [0.8, 0.5]})
    _, table = laser_range_claim(ranges, truth)
    assert int(table["bins"].sum()) == 1


def test_range_errors_join_on_frame_and_bearing():
    truth = pd.DataFrame({"frame": [0, 0, 1], "bearing_deg": [0.0, 1.0, 0.0],
                          "range_m": [1.0, np.nan, 2.0]})
    ranges = pd.DataFrame({"frame": [0, 0, 1], "bearing_deg": [0.0, 1.0, 0.0],
                           **{f"{k}_range_m": [1.1, 3.0, 1.9] for k in
                              ("fused", "laser", "stereo")}})
    e = range_errors(ranges, truth)
    np.testing.assert_allclose(e["fused_err_m"], [0.1, -0.1])
