"""The one bin rule, the range table and the table schemas (slitcli.ranges)."""

import math

import numpy as np
import pandas as pd
import pytest

from slitcli.laser.frame import LaserFrame, bin_boundary_points, nearest_range_per_bin
from slitcli.ranges import (
    RANGES,
    TABLES,
    BearingBins,
    RangeTable,
    absolute_bin,
    bin_count,
    bin_median,
    bin_min,
    boundary_deg,
    format_time_s,
    median_of_finite,
    times_as_text,
)
from slitcli.rig import paper_rig

RIG = paper_rig()
BIN_WIDTHS = (1.0, 0.5, 0.25, 0.1, 2.0)


def _laser_frame(bearing_deg: np.ndarray, range_m: np.ndarray) -> LaserFrame:
    """A laser frame whose first columns hold the given points (others: no stripe)."""
    w = RIG.width_px
    b = np.full(w, np.nan)
    r = np.full(w, np.nan)
    b[:bearing_deg.size] = bearing_deg
    r[:range_m.size] = range_m
    v = np.where(np.isfinite(r), 300.0, np.nan)
    return LaserFrame(u_px=np.arange(w, dtype=float), v_px=v, strength_dn=v * 0 + 50,
                      saturated=np.zeros(w, bool), x_m=r * np.cos(np.radians(b)),
                      y_m=r * np.sin(np.radians(b)), range_m=r, bearing_deg=b,
                      in_band=np.isfinite(r), noise_sigma_dn=1.0, threshold_dn=5.0)


@pytest.mark.parametrize("bin_deg", BIN_WIDTHS)
def test_boundary_bearing_lands_in_one_bin_for_laser_and_stereo(bin_deg):
    """A bearing exactly on a bin boundary: the laser's reduction and the index stereo
    uses (BearingBins.index) put it in the same bin, the one on its left."""
    bins = BearingBins.for_rig(RIG, bin_deg)
    lower = np.arange(bins.first, bins.first + len(bins) - 1)  # every inner boundary
    bearing = boundary_deg(lower, bin_deg)
    stereo_bin = bins.index(bearing)
    # the boundary belongs to the bin on its left (larger bearing), up to the rounding
    # of the boundary's own float: never two bins away, and the same for both sensors
    assert np.all((stereo_bin == lower + 1 - bins.first) | (stereo_bin == lower - bins.first))
    for j in range(0, bearing.size, max(1, bearing.size // 7)):
        rng = np.array([1.0 + 0.01 * j])
        las = nearest_range_per_bin(_laser_frame(bearing[j:j + 1], rng), RIG, bin_deg=bin_deg,
                                    boundary_jump_m=None)
        hit = np.flatnonzero(np.isfinite(las.range_m))
        assert hit.tolist() == [stereo_bin[j]]
        assert las.range_m[hit[0]] == rng[0]


def test_exact_boundary_goes_left_not_to_even_bin():
    """floor(b/w + 1/2), not round-half-to-even (np.rint put 2.5 deg in bin 2 and 3.5 in 4)."""
    b = np.array([-3.5, -2.5, -0.5, 0.5, 2.5, 3.5])
    assert absolute_bin(b, 1.0).tolist() == [-3, -2, 0, 1, 3, 4]
    assert np.rint(b).astype(int).tolist() != absolute_bin(b, 1.0).tolist()


@pytest.mark.parametrize("seed", range(5))
def test_index_matches_wedge_limits(seed):
    """Every bearing inside [lower, upper) of a bin gets that bin's index."""
    rng = np.random.default_rng(seed)
    bin_deg = float(rng.choice(BIN_WIDTHS))
    bins = BearingBins.for_rig(RIG, bin_deg)
    k = rng.integers(0, len(bins), 500)
    frac = rng.uniform(0.001, 0.999, 500)
    b = bins.lower_deg[k] + frac * bin_deg
    assert np.array_equal(bins.index(b), k)
    far = np.array([bins.upper_deg[-1] + bin_deg, bins.lower_deg[0] - bin_deg, np.nan, np.inf])
    assert bins.index(far).tolist() == [-1, -1, -1, -1]


@pytest.mark.parametrize("seed", range(5))
def test_bin_reductions_match_a_per_bin_loop(seed):
    rng = np.random.default_rng(seed)
    n_bins = 17
    idx = rng.integers(-2, n_bins + 2, 300)
    v = rng.uniform(0.1, 5.0, 300)
    v[rng.random(300) < 0.1] = np.nan
    got_min, got_n = bin_min(idx, v, n_bins), bin_count(idx, n_bins)
    for k in range(n_bins):
        sel = (idx == k) & np.isfinite(v)
        want = v[sel].min() if sel.any() else np.nan
        assert got_min[k] == want or (math.isnan(want) and math.isnan(got_min[k]))
        assert got_n[k] == (idx == k).sum()
    med, n_finite = bin_median(idx, v, n_bins)
    for k in range(n_bins):
        sel = (idx == k) & np.isfinite(v)
        assert n_finite[k] == sel.sum()
        if sel.any():
            assert med[k] == pytest.approx(float(np.median(v[sel])), abs=0, rel=1e-15)
        else:
            assert math.isnan(med[k])


@pytest.mark.parametrize("seed", range(5))
def test_median_of_finite_along_either_axis(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(7, 30))
    a[rng.random(a.shape) < 0.3] = np.nan
    a[:, 3] = np.nan  # a column without finite entries
    for axis, slices in ((0, a.T), (1, a)):
        got = median_of_finite(a, axis=axis)
        for g, s in zip(got, slices, strict=True):
            f = s[np.isfinite(s)]
            assert (math.isnan(g) and f.size == 0) or g == pytest.approx(np.median(f))


@pytest.mark.parametrize("seed", range(5))
def test_boundary_points_lie_on_the_boundaries(seed):
    """Laser boundary interpolation: each point sits on a bin boundary between its two
    columns, linearly interpolated in bearing."""
    rng = np.random.default_rng(seed)
    b = np.sort(rng.uniform(-20, 20, 40))
    r = 1.0 + 0.001 * np.cumsum(rng.normal(size=40))
    rr, k, first = bin_boundary_points(r, b, np.ones(40, bool), 1.0, 0.05)
    at = boundary_deg(k, 1.0)
    assert np.all((at >= b[first]) & (at <= b[first + 1]))
    t = (at - b[first]) / (b[first + 1] - b[first])
    assert np.allclose(rr, r[first] + t * (r[first + 1] - r[first]))
    # every boundary crossed by a pair of neighbours is listed once
    assert k.size == int(np.abs(np.diff(absolute_bin(b, 1.0))).sum())


def test_range_table_rows_and_schema():
    bins = BearingBins.for_rig(RIG, 1.0)
    n = len(bins)
    nan = np.full(n, np.nan)
    src = np.full(n, "none", dtype=object)
    t = RangeTable(bins.centres_deg, nan, nan, np.zeros(n, bool), nan, src)
    rows = t.rows(3, 1764000000.2)
    assert tuple(rows.columns) == RANGES.columns
    assert (rows["frame"] == 3).all() and len(rows) == n
    assert set(rows["time_s"]) == {"1764000000.2"}
    with pytest.raises(ValueError, match="fused_range_m"):
        RangeTable(bins.centres_deg, nan, nan, np.zeros(n, bool), nan[:-1], src)
    assert TABLES["ranges.csv"] is RANGES
    # one schema per file name; column names unique within a table
    for schema in TABLES.values():
        assert len(set(schema.columns)) == len(schema.columns)


@pytest.mark.parametrize("stamp_ns", [1_764_000_000_000_000_000, 1_764_000_000_200_000_000,
                                      1_700_000_000_123_456_789, 0, 200_000_000])
def test_time_keeps_its_steps(stamp_ns):
    """A wall-clock stamp written and read back keeps 0.2 s steps to 1e-6 s."""
    t0 = stamp_ns * 1e-9
    t1 = (stamp_ns + 200_000_000) * 1e-9
    back = pd.read_csv(pd.io.common.StringIO(f"t\n{format_time_s(t0)}\n{format_time_s(t1)}\n"))
    assert abs(float(np.diff(back["t"].to_numpy())[0]) - 0.2) < 1e-6
    assert format_time_s(float("nan")) == ""


def test_written_times_keep_full_precision():
    """Trajectory, metrics, DWA command and range-table times are written like every table's
    (format_time_s: every digit to the nanosecond), not cut to six significant digits:
    at 12345.675 s, %.6g would write 12345.7 and merge neighbouring 10 ms steps."""
    t_s = np.array([12345.67, 12345.68, 1.76e9 + 0.123456789, np.nan])
    table = pd.DataFrame({"t_s": t_s, "x_m": [1.0, 2.0, 3.0, 4.0]})
    out = times_as_text(table)
    back = pd.to_numeric(out["t_s"].replace("", np.nan))
    np.testing.assert_allclose(back[:3], t_s[:3], rtol=0, atol=1e-9)
    assert back.iloc[0] != back.iloc[1] and math.isnan(back.iloc[3])
    assert table["t_s"].dtype == float  # the input is left alone
