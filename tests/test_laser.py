"""Laser extraction (Eqs. 1-4) and triangulation on synthetic frames with exact truth.

The frames come from tests/laser_synth.py: a textured grey wall a known distance
ahead, the stripe drawn as a pixel-integrated Gaussian at the rig's true row per
column, seeded noise, clipping, red and white distractors.
"""

import math

import cv2
import numpy as np
import pandas as pd
import pytest
from laser_synth import make_frame, wall_stripe_rows

from slitcli.errors import SlitcliError
from slitcli.laser import (
    LaserGeometry,
    LaserParams,
    bearing_bin_centres_deg,
    candidate_mask,
    candidates,
    chromaticity,
    detect_laser,
    extract_stripe,
    finish,
    nearest_range_per_bin,
    select,
    triangulate_stripe,
)
from slitcli.rig import paper_rig

RIG = paper_rig()
PARAMS = LaserParams()
GEOM = LaserGeometry.from_rig(RIG, PARAMS)


def _errors(seeds, **kw):
    """Row errors (px) where both truth and detection exist, found share, false columns."""
    errs, vis, found, false = [], 0, 0, 0
    for seed in seeds:
        s = make_frame(RIG, seed=seed, **kw)
        v = extract_stripe(s.bgr, PARAMS).v_px
        t = s.stripe_v_px
        m = np.isfinite(t)
        vis += int(m.sum())
        f = m & np.isfinite(v)
        found += int(f.sum())
        e = v[f] - t[f]
        false += int((np.isfinite(v) & ~m).sum() + (np.abs(e) > 1.5).sum())
        errs.append(e)
    return np.concatenate(errs), found / max(vis, 1), false


def _rms(e):
    return float(np.sqrt(np.mean(e**2)))


def test_chromaticity_eq1_and_black_guard():
    bgr = np.array([[[30, 20, 10], [0, 0, 0], [0, 0, 255]]], dtype=np.uint8)
    c = chromaticity(bgr)
    np.testing.assert_allclose(c[0, 0], [10 / 60, 20 / 60, 30 / 60])
    np.testing.assert_array_equal(c[0, 1], [0.0, 0.0, 0.0])  # r + g + b = 0
    np.testing.assert_allclose(c[0, 2], [1.0, 0.0, 0.0])


def test_candidate_mask_eq2_eq3():
    # BGR pixels over a grey background (90, 90, 90): laser red (contrast (110, 13, 13),
    # the laser's colour), a grey texture bump, a white highlight, no contrast, a
    # saturated core, and a red bump whose green rose as much as its red (white light)
    bgr = np.array([[[103, 103, 200], [130, 130, 130], [250, 250, 250], [90, 90, 90],
                     [200, 205, 255], [90, 150, 150]]], dtype=np.uint8)
    bg = np.full_like(bgr, 90)
    red, sat = candidate_mask(bgr, bg, PARAMS)
    np.testing.assert_array_equal(red[0], [True, False, False, False, False, False])
    np.testing.assert_array_equal(sat[0], [False, False, True, False, True, False])
    # the same tests as the compiled evidence, pixel for pixel, on a random image
    rng = np.random.default_rng(7)
    img = rng.integers(0, 256, (60, 40, 3)).astype(np.uint8)
    back = cv2.morphologyEx(img, cv2.MORPH_OPEN, np.ones((7, 1), np.uint8))
    red, sat = candidate_mask(img, back, PARAMS)
    assert 0.05 < red.mean() < 0.6
    score = np.empty(60)
    sat_col = np.empty(60, bool)
    # the background per channel, one row per column and channel (the extractor's layout)
    back_p = cv2.transpose(back.reshape(60, 120))
    for i in range(40):
        candidates.evidence(img.transpose(1, 0, 2), back_p, np.ones((40, 60), bool), i,
                            PARAMS.min_th, PARAMS.min_delta_th, PARAMS.alpha,
                            PARAMS.saturation_dn, score, sat_col)
        np.testing.assert_array_equal((score > -1.0) & ~sat_col, red[:, i])
        np.testing.assert_array_equal(sat_col, sat[:, i])
    # contiguous columns (the extractor's layout) give the same values; masked pixels
    # none
    img_t = cv2.transpose(img)
    mask_t = rng.random((40, 60)) < 0.7
    score_c = np.empty(60)
    sat_c = np.empty(60, bool)
    for i in range(40):
        candidates.evidence(img.transpose(1, 0, 2), back_p, mask_t, i,
                            PARAMS.min_th, PARAMS.min_delta_th, PARAMS.alpha,
                            PARAMS.saturation_dn, score, sat_col)
        candidates.evidence(img_t, back_p, mask_t, i, PARAMS.min_th, PARAMS.min_delta_th,
                            PARAMS.alpha, PARAMS.saturation_dn, score_c, sat_c)
        np.testing.assert_array_equal(score_c, score)
        np.testing.assert_array_equal(sat_c, sat_col)
        assert np.all(score_c[~mask_t[i]] == -1.0) and not sat_c[~mask_t[i]].any()
        np.testing.assert_array_equal((score_c > -1.0) & ~sat_c, red[:, i] & mask_t[i])


def test_vertical_opening_matches_opencv():
    # the extractor's background (an opening along the rows, rows beyond the border
    # left out) equals OpenCV's morphologyEx with a (k, 1) kernel, value for value: odd
    # and even windows, images shorter than the window, bright bands narrower and
    # wider than it
    rng = np.random.default_rng(3)
    for trial in range(60):
        rows, cols = int(rng.integers(1, 70)), int(rng.integers(1, 40))
        img = rng.integers(0, 256, (rows, cols)).astype(np.uint8)
        if trial % 2:
            img = np.where(rng.random((rows, 1)) < 0.3, 220, 40).astype(np.uint8) + \
                rng.integers(0, 3, (rows, cols)).astype(np.uint8)
        k = int(rng.integers(3, 32))
        out = np.empty_like(img)
        candidates.vertical_opening(img, k, out)
        np.testing.assert_array_equal(
            out, cv2.morphologyEx(img, cv2.MORPH_OPEN, np.ones((k, 1), np.uint8)))
    # a bright band narrower than the window is removed, a wider one kept
    col = np.full((40, 1), 10, np.uint8)
    col[5:9] = 200
    col[20:35] = 150
    out = np.empty_like(col)
    candidates.vertical_opening(col, 7, out)
    assert (out[5:9] == 10).all() and (out[20:35] == 150).all()


def test_noise_sigma_estimate_ignores_texture():
    # a strongly textured wall without the laser: the estimate is the noise alone
    for noise_dn in (2.0, 6.0):
        s = make_frame(RIG, stripe_cols=(0, 0), noise_dn=noise_dn, texture_contrast=0.3)
        bg = cv2.morphologyEx(s.bgr, cv2.MORPH_OPEN, np.ones((21, 1), np.uint8))
        est = candidates.noise_sigma(s.bgr.transpose(1, 0, 2), bg.transpose(1, 0, 2), 4)
        assert est == pytest.approx(noise_dn, rel=0.15)


def test_sheet_scale_paper_rig():
    # rows per metre of height on an upright surface at the laser point, DESIGN §2 rig:
    # v = cy + f tan(phi - theta), phi = atan((H) / X) for a point X ahead on the sheet,
    # |dv/dz| = f sec^2(phi - theta) X / (X^2 + H^2); X = 1 m, H = 0.6 m: 190.7 px/m
    phi = math.atan(0.6 / 1.0)
    expect = 250.0 / math.cos(phi - math.radians(20.0)) ** 2 * 1.0 / (1.0 + 0.36)
    assert GEOM.px_per_m[168, 160] == pytest.approx(expect, rel=0.01)
    assert np.isnan(GEOM.px_per_m[~GEOM.search_mask]).all()


def test_sheet_thickness_rejects_a_thick_red_band():
    # the stripe at its true width (4 mm sheet) in columns 0-159, and a red band of
    # the laser's colour 2.5 times thicker at another row in columns 180-299
    h = RIG.height_px
    sigma_px = np.nan_to_num(GEOM.px_per_m[np.clip(np.rint(wall_stripe_rows(RIG, 0.8)).astype(int),
                                                   0, h - 1), np.arange(RIG.width_px)]) * 0.004
    s = make_frame(RIG, forward_m=0.8, sigma_px=np.hypot(sigma_px, 0.27), stripe_cols=(0, 160))
    band = make_frame(RIG, forward_m=0.9, sigma_px=2.5 * sigma_px, stripe_cols=(180, 300))
    img = np.maximum(s.bgr, band.bgr)
    f = detect_laser(img, RIG, PARAMS, geometry=GEOM)
    assert f.found[:150].mean() >= 0.99
    assert not f.found[185:].any()
    loose = detect_laser(img, RIG, LaserParams(sheet_sigma_mm=0.0), geometry=GEOM)
    assert loose.found[185:295].mean() >= 0.9  # without the test the band is taken


def test_rows_are_smoothed_along_a_segment():
    # independent noise on the rows of a straight segment: the weighted quadratic
    # halves it; a corner (slope change) is not rounded
    rng = np.random.default_rng(3)
    u = np.arange(120, dtype=float)
    line = np.where(u < 60, 150.0 + 0.2 * u, 162.0 - 0.5 * (u - 60))
    noisy = line + rng.normal(0.0, 0.1, u.size)
    out = np.empty_like(noisy)
    select.smooth_rows(noisy, np.full(u.size, 0.1), np.full(u.size, 1.0),
                       np.ones(u.size, bool), 3.0, out)
    inner = (np.abs(u - 60) > 5) & (u > 4) & (u < 115)
    assert _rms(out[inner] - line[inner]) <= 0.6 * _rms(noisy[inner] - line[inner])
    assert abs(out[60] - line[60]) <= 0.35


@pytest.mark.parametrize("forward_m", [0.6, 0.8, 1.0])
def test_clean_stripe_rms_on_walls(forward_m):
    e, found, false = _errors(range(3), forward_m=forward_m, sigma_px=1.2, noise_dn=2.5)
    assert _rms(e) <= 0.10
    assert found >= 0.99
    assert false == 0


@pytest.mark.parametrize(("sigma_px", "noise_dn"), [(1.0, 2.0), (1.5, 3.0)])
def test_clean_stripe_rms_sigma_range(sigma_px, noise_dn):
    e, found, false = _errors(range(3), sigma_px=sigma_px, noise_dn=noise_dn)
    assert _rms(e) <= 0.10
    assert found >= 0.99
    assert false == 0


@pytest.mark.parametrize(("laser_dn", "sigma_px"), [(400.0, 1.2), (600.0, 1.5)])
def test_saturated_stripe_rms(laser_dn, sigma_px):
    s = make_frame(RIG, laser_dn=laser_dn, sigma_px=sigma_px)
    assert np.mean(s.bgr[np.rint(s.stripe_v_px).astype(int), np.arange(320), 2] == 255) > 0.9
    e, found, false = _errors(range(3), laser_dn=laser_dn, sigma_px=sigma_px)
    assert _rms(e) <= 0.20
    assert found >= 0.99
    assert false == 0


@pytest.mark.parametrize("noise_dn", [6.0, 8.0])
def test_noisy_stripe_rms(noise_dn):
    e, found, false = _errors(range(3), noise_dn=noise_dn, sigma_px=1.2)
    assert _rms(e) <= 0.20
    assert found >= 0.99
    assert false == 0


def test_wide_red_object_crossed_by_laser():
    # a red surface (albedo 1.6, 0.25, 0.25 on a textured wall) as tall as the image
    # band the opening sees, the laser saturating on it, and a white highlight
    for seed in range(3):
        s = make_frame(RIG, seed=seed, red_rect=(100, 130, 220, 230),
                       white_blob=(40, 150, 6))
        v = extract_stripe(s.bgr, PARAMS).v_px
        cols = s.red_object_cols
        assert cols.sum() == 120
        on_laser = np.abs(v[cols] - s.stripe_v_px[cols]) < 1.0
        assert on_laser.mean() >= 0.95
        assert _rms(v[cols] - s.stripe_v_px[cols]) <= 0.20


def test_no_stripe_no_columns_highlight_and_texture():
    for seed in range(3):
        s = make_frame(RIG, seed=seed, stripe_cols=(0, 0), white_blob=(160, 190, 8),
                       texture_contrast=0.25)
        assert np.isnan(s.stripe_v_px).all()
        res = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
        assert not res.found.any()


def test_partial_stripe_reports_only_its_columns():
    s = make_frame(RIG, stripe_cols=(60, 200), white_blob=(260, 200, 7))
    v = extract_stripe(s.bgr, PARAMS).v_px
    assert np.isnan(v[:58]).all() and np.isnan(v[202:]).all()
    inner = np.arange(62, 198)
    assert np.isfinite(v[inner]).all()
    assert _rms(v[inner] - s.stripe_v_px[inner]) <= 0.10


def test_previous_frame_continuity_prefers_the_tracked_row():
    # two equally strong stripes; the previous frame's row picks which one is the laser
    s1 = make_frame(RIG, forward_m=0.8, seed=5)
    s2 = make_frame(RIG, forward_m=0.95, seed=5)
    both = np.maximum(s1.bgr, s2.bgr)
    for truth in (s1.stripe_v_px, s2.stripe_v_px):
        v = extract_stripe(both, PARAMS, previous_v_px=truth + 0.3).v_px
        # beta = 0.25 bounds what continuity can overturn: where noise and texture make
        # the other stripe brighter, Eq. 4 still takes it
        assert np.mean(np.abs(v - truth) < 1.0) >= 0.80


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


@pytest.mark.parametrize("forward_m", [0.6, 0.7, 0.8, 0.9, 1.0])
def test_forward_distance_error_walls(forward_m):
    s = make_frame(RIG, forward_m=forward_m, seed=2)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    assert f.found.mean() >= 0.99
    rel = np.abs(f.x_m[f.found] - forward_m) / forward_m
    assert np.median(rel) <= 0.005
    # the wall is a line y = const in x: lateral positions follow the bearing
    np.testing.assert_allclose(np.degrees(np.arctan2(f.y_m, f.x_m))[f.found],
                               f.bearing_deg[f.found])
    np.testing.assert_allclose(f.range_m[f.found], np.hypot(f.x_m, f.y_m)[f.found])


def test_band_flag_and_out_of_band_points_kept():
    s = make_frame(RIG, forward_m=1.15, seed=1, laser_dn=80.0)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    assert f.found.mean() >= 0.99
    assert not f.in_band[f.found].any()  # beyond max_range_m = 1.0, still reported
    s = make_frame(RIG, forward_m=0.75, seed=1)
    f = detect_laser(s.bgr, RIG, PARAMS, geometry=GEOM)
    centre = np.abs(f.bearing_deg) < 20
    assert f.in_band[f.found & centre].all()


def test_bearing_bins_nearest_range():
    centres = bearing_bin_centres_deg(RIG)
    np.testing.assert_array_equal(centres, np.arange(-32.0, 33.0))
    s = make_frame(RIG, forward_m=0.8, seed=3)
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


def test_params_validation():
    with pytest.raises(SlitcliError, match="background_window_px"):
        LaserParams(background_window_px=10)
    with pytest.raises(SlitcliError, match="alpha"):
        LaserParams(alpha=1.5)
    with pytest.raises(SlitcliError, match="sheet_sigma_mm"):
        LaserParams(sheet_sigma_mm=-1.0)


def test_inputs_not_modified():
    s = make_frame(RIG)
    img = s.bgr.copy()
    detect_laser(img, RIG, PARAMS)
    np.testing.assert_array_equal(img, s.bgr)


def test_wall_rows_helper_is_the_rig_line():
    rows = wall_stripe_rows(RIG, 0.8)
    assert rows[160] == pytest.approx(RIG.stripe_row_on_wall(0.8, 160.0), abs=1e-9)
    assert rows[17] == pytest.approx(RIG.stripe_row_on_wall(0.8, 17.0), abs=1e-9)


def test_first_search_row_is_the_masks_first_row():
    # the extractor's crop starts from this row: it must be the first row holding a
    # search pixel in any column, for C- and Fortran-order masks alike, -1 for none
    rng = np.random.default_rng(5)
    for _ in range(200):
        h, w = rng.integers(1, 60, size=2)
        m = rng.random((h, w)) < rng.random() * 0.05
        if rng.random() < 0.5:
            m = np.asfortranarray(m)
        rows = np.flatnonzero(m.any(axis=1))
        assert finish.first_search_row(m.T) == (rows[0] if rows.size else -1)
    v3 = 119.5 + 250.0 * math.tan(math.atan(0.6 / 3.0) - math.radians(20.0))
    assert finish.first_search_row(GEOM.search_mask.T) <= math.ceil(v3) + 1


def test_background_opening_on_one_channel_view_is_per_channel():
    # extract_stripe opens the (rows, 3 W) one-channel view of the image: a vertical
    # window mixes no channels, so it must equal the opening of each channel
    rng = np.random.default_rng(6)
    img = cv2.GaussianBlur(rng.integers(0, 256, (90, 40, 3), dtype=np.uint8), (5, 5), 0)
    k = np.ones((PARAMS.background_window_px, 1), np.uint8)
    view = cv2.morphologyEx(img.reshape(90, 120), cv2.MORPH_OPEN, k).reshape(img.shape)
    # the opening by hand: the max over the window of the erosion (the min over the
    # window), rows beyond the image ignored (padded with the neutral value)
    r = PARAMS.background_window_px // 2
    swv = np.lib.stride_tricks.sliding_window_view
    ero = swv(np.pad(img, ((r, r), (0, 0), (0, 0)), constant_values=255), 2 * r + 1,
              axis=0).min(axis=-1)
    ref = swv(np.pad(ero, ((r, r), (0, 0), (0, 0)), constant_values=0), 2 * r + 1,
              axis=0).max(axis=-1)
    np.testing.assert_array_equal(view, ref)
