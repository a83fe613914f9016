"""Laser triangulation (Eqs. 5-7) and the per-bearing ranges on synthetic frames with
exact truth (tests/laser_synth.py); the extraction's tests are in test_laser.py."""

import math

import numpy as np
import pandas as pd
import pytest
from laser_synth import make_frame

from slitcli.laser import (
    LaserGeometry,
    LaserParams,
    bearing_bin_centres_deg,
    detect_laser,
    geometry,
    nearest_range_per_bin,
    triangulate_stripe,
)
from slitcli.rig import paper_rig

RIG = paper_rig()
PARAMS = LaserParams()
GEOM = LaserGeometry.from_rig(RIG, PARAMS)


def test_triangulation_design_worked_check():
    x, y, rng, _bearing = triangulate_stripe(RIG, np.array([159.5]), np.array([167.93]))
    assert x[0] == pytest.approx(1.0, abs=2e-4)
    assert y[0] == pytest.approx(0.0, abs=1e-12)
    assert rng[0] == pytest.approx(1.0, abs=2e-4)
    # DESIGN §4 closed form for the paper rig: Z = H / tan(theta + atan((v - cy) / f))
    v = np.linspace(130.0, 239.0, 12)
    x, _, _, _ = triangulate_stripe(RIG, np.full(12, 80.0), v)
    expect = 0.6 / np.tan(math.radians(20.0) + np.arctan((v - 119.5) / 250.0))
    np.testing.assert_allclose(x, expect, rtol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_triangulate_columns_is_triangulate_stripe(seed):
    # the compiled per-frame pass (LaserGeometry's rays and plane) gives the points of
    # the reference ray/plane intersection: rows from above the horizon (rays that miss
    # the plane: NaN) to below the image, and NaN rows; in_band is the range band
    rng = np.random.default_rng(seed)
    w = RIG.width_px
    v = rng.uniform(-40.0, RIG.height_px + 40.0, w)
    v[rng.random(w) < 0.2] = np.nan
    out = np.empty((4, w))
    in_band = np.empty(w, bool)
    geometry.triangulate_columns(v, GEOM.ray_x, GEOM.ray_y_coeffs, GEOM.plane_cam,
                                 GEOM.sensor_from_cam, RIG.laser.min_range_m,
                                 RIG.laser.max_range_m, out, in_band)
    ref = np.array(triangulate_stripe(RIG, np.arange(w, dtype=float), v))
    # a ray meeting the plane behind the camera or nearly parallel to it is NaN in both
    missed = np.isnan(ref[0])
    assert missed.any() and (~missed).any()
    np.testing.assert_array_equal(np.isnan(out[0]), missed)
    # metres and degrees; both are a few float64 operations from the same terms
    np.testing.assert_allclose(out[:3, ~missed], ref[:3, ~missed], rtol=0, atol=1e-9)
    np.testing.assert_allclose(out[3, ~missed], ref[3, ~missed], rtol=0, atol=1e-9)
    with np.errstate(invalid="ignore"):
        band = (ref[2] >= RIG.laser.min_range_m) & (ref[2] <= RIG.laser.max_range_m)
    np.testing.assert_array_equal(in_band, band)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("forward_m", [0.6, 0.7, 0.8, 0.9, 1.0])
def test_forward_distance_error_walls(forward_m, seed):
    s = make_frame(RIG, forward_m=forward_m, seed=seed)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    assert f.found.mean() >= 0.99
    rel = np.abs(f.x_m[f.found] - forward_m) / forward_m
    assert np.median(rel) <= 0.005
    # the wall is a line y = const in x: lateral positions follow the bearing
    np.testing.assert_allclose(np.degrees(np.arctan2(f.y_m, f.x_m))[f.found],
                               f.bearing_deg[f.found])
    np.testing.assert_allclose(f.range_m[f.found], np.hypot(f.x_m, f.y_m)[f.found])


@pytest.mark.parametrize("seed", range(5))
def test_band_flag_and_out_of_band_points_kept(seed):
    s = make_frame(RIG, forward_m=1.15, seed=seed, laser_dn=80.0)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    assert f.found.mean() >= 0.99
    assert not f.in_band[f.found].any()  # beyond max_range_m = 1.0, still reported
    s = make_frame(RIG, forward_m=0.75, seed=seed)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    centre = np.abs(f.bearing_deg) < 20
    assert f.in_band[f.found & centre].all()


@pytest.mark.parametrize("seed", range(5))
def test_bearing_bins_nearest_range(seed):
    centres = bearing_bin_centres_deg(RIG)
    np.testing.assert_array_equal(centres, np.arange(-32.0, 33.0))
    s = make_frame(RIG, forward_m=0.8, seed=seed)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    bins = nearest_range_per_bin(f, RIG, boundary_jump_m=None)  # column centres only
    # independent reduction with pandas
    df = pd.DataFrame({"b": np.round(f.bearing_deg), "r": f.range_m}).dropna()
    expect = df.groupby("b")["r"].min()
    got = pd.Series(bins.range_m, index=bins.bearing_deg).dropna()
    pd.testing.assert_series_equal(got, expect.loc[got.index], check_names=False)
    # points beyond the camera's horizontal field of view at the optical-axis row
    # (bearings past +-32.6 deg below the axis) fall outside the bins
    inside = expect.index[(expect.index >= -32) & (expect.index <= 32)]
    assert set(inside) <= set(got.index)
    # a wall 0.8 m ahead: nearest range in the bin is 0.8 / cos(bearing), within a bin's slack
    b = bins.bearing_deg[np.isfinite(bins.range_m)]
    r = bins.range_m[np.isfinite(bins.range_m)]
    lo = 0.8 / np.cos(np.radians(np.maximum(np.abs(b) - 0.5, 0.0)))
    hi = 0.8 / np.cos(np.radians(np.abs(b) + 0.5))
    assert np.all((r >= lo - 0.004) & (r <= hi + 0.004))
    inband = nearest_range_per_bin(f, RIG, in_band_only=True)
    assert np.all(np.isnan(inband.range_m) | inband.in_band)
    # with the bin boundaries interpolated, each bin's range is the wall's exact
    # nearest point in the wedge (0.8 m / cos of the boundary bearing nearer the axis)
    edge = nearest_range_per_bin(f, RIG)
    lit = np.isfinite(edge.range_m[1:-1]) & np.isfinite(edge.range_m[:-2]) \
        & np.isfinite(edge.range_m[2:])
    be, re_ = edge.bearing_deg[1:-1][lit], edge.range_m[1:-1][lit]
    exact = 0.8 / np.cos(np.radians(np.maximum(np.abs(be) - 0.5, 0.0)))
    cols = bins.range_m[1:-1][lit]
    assert lit.sum() >= 40
    assert np.abs(re_ - exact).max() <= 0.001
    assert np.median(np.abs(re_ - exact)) < 0.5 * np.median(np.abs(cols - exact))


def test_search_mask_matches_range_limit():
    m = GEOM.search_mask
    # the paper rig's horizontal laser sheet: rows below the 3 m row of each column
    v3 = 119.5 + 250.0 * math.tan(math.atan(0.6 / 3.0) - math.radians(20.0))
    assert not m[math.floor(v3) - 1, 160]
    assert m[math.ceil(v3) + 1:, 160].all()
