"""SGM's ground from the pair itself (slitcli.stereo.ground: a line in the v-disparity
histogram of a reduced first pass), used where no rig gives it."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from stereo_synth import draw_seeds, plane_pair, quantise, texture
from test_stereo_sgm_ground import ROAD_RIG, SEEDS, render_floor

from slitcli.errors import SlitcliError
from slitcli.rig import paper_rig
from slitcli.stereo.cost import ground_shear_from_floor, ground_window_shifts
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.ground import (
    GroundFitParams,
    estimate_ground,
    fit_ground_line,
    with_pair_ground,
)
from slitcli.stereo.matcher import MatcherParams, compute_disparity, with_rig_ground

#: ROAD_RIG: the paper rig with a 0.25 m baseline (0.361 px per row, horizon row 28.5,
#: KITTI's road about 0.33); HIGH_RIG a higher, less tilted one (0.246 px per row,
#: horizon 75.4)
HIGH_RIG = replace(paper_rig(), baseline_m=0.2,
                   mount=replace(paper_rig().mount, height_m=0.8, tilt_deg=10.0))
NUM = 96


def _render_floor(rig, seed: int, contrast: float) -> dict:
    z = render_floor(seed, contrast, rig)
    return {**z, "left": cv2.cvtColor(z["left"], cv2.COLOR_BGR2GRAY),
            "right": cv2.cvtColor(z["right"], cv2.COLOR_BGR2GRAY)}


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("rig", [ROAD_RIG, HIGH_RIG], ids=["road", "high"])
def test_recovers_the_rendered_ground(seed, rig):
    """A rendered floor (weak texture, contrast 0.08, 2 DN noise) without its rig: the
    estimate finds the rig's ground. Tolerances from what the shear needs: the window
    shifts ``round(g dv)`` are the rig's, and the estimated line lies within its own
    band of the rig's floor disparity over every row of floor within 3 m (there the
    sheared window is offered at the true ground's disparity)."""
    z = _render_floor(rig, seed, 0.08)
    est = estimate_ground(z["left"], z["right"],
                          MatcherParams(num_disparities=NUM, aggregation="sgm"))
    assert est.found, est.why
    grad, horizon = ground_shear_from_floor(StereoGeometry.for_rig(rig).floor_disparity_px)
    np.testing.assert_array_equal(ground_window_shifts(est.px_per_row, 3),
                                  ground_window_shifts(grad, 3))
    v = np.flatnonzero(z["floor"].any(axis=1)).astype(float)
    line = est.px_per_row * (v - est.horizon_row_px)
    assert np.abs(line - grad * (v - horizon)).max() <= est.band_px
    # a floor-only scene: nearly every first-pass pixel lies on the line
    assert est.share >= 0.9


@pytest.mark.parametrize("seed", SEEDS)
def test_no_ground_on_a_wall(seed):
    """A textured fronto-parallel wall is one disparity on every row (a vertical line in
    v-disparity, gradient 0): no ground, and 'auto' matches as 'off' does, bit for bit."""
    left, right = plane_pair(12.0 + seed, seed=seed)
    p = MatcherParams(num_disparities=48, aggregation="sgm")
    est = estimate_ground(left, right, p)
    assert not est.found
    a = compute_disparity(left, right, p)
    b = compute_disparity(left, right, replace(p, sgm_ground="off"))
    np.testing.assert_array_equal(a.disparity_px, b.disparity_px)
    np.testing.assert_array_equal(a.invalid_reason, b.invalid_reason)


@pytest.mark.parametrize("seed", SEEDS)
def test_no_ground_on_a_staircase_of_walls(seed):
    """Four fronto-parallel walls stacked down the image, 60 rows each, each 12 px
    nearer than the one above (a staircase in v-disparity, on average 0.2 px per row,
    a plausible gradient): a line through the steps holds a wall's rows only within
    ``inlier_px`` (1.5 px) of it, about 2 x 1.5 / 12 = 1/4 of the pixels, below the
    0.4 a ground needs."""
    tex_seed, noise_seed = draw_seeds(seed, 2)
    u, v = np.meshgrid(np.arange(320, dtype=float), np.arange(240, dtype=float))
    d = 10.0 + 12.0 * (v // 60)
    rng = np.random.default_rng(noise_seed)
    left = quantise(texture(u, v, seed=tex_seed), 1.0, rng)
    right = quantise(texture(u + d, v, seed=tex_seed), 1.0, rng)
    est = estimate_ground(left, right, MatcherParams(num_disparities=64, aggregation="sgm"))
    assert not est.found
    assert est.share < GroundFitParams().min_share


@pytest.mark.parametrize("seed", SEEDS)
def test_fit_finds_an_exact_line_among_outliers(seed):
    """On an exact ground line (0.3 px per row from row 20 of 80, reduced by 3) with 40 %
    of the pixels replaced by uniform outliers, the refit returns the line itself (the
    outliers within the 0.5 reduced-px inlier window pull it by at most a few 1e-3)."""
    rng = np.random.default_rng(seed)
    hr, wr, s, g, h0 = 80, 107, 3, 0.3, 20.0
    r = np.arange(hr, dtype=float)[:, None] * np.ones((1, wr))
    d = np.where(r >= h0, g * (r - h0), np.nan)          # reduced px: g per reduced row
    out = rng.random(d.shape) < 0.4
    d[out] = rng.uniform(0, 12, out.sum())
    est = fit_ground_line(d.astype(np.float32), s, 0, 3 * 12, GroundFitParams())
    assert est.found
    assert est.px_per_row == pytest.approx(g, abs=3e-3)
    # full rows: reduced row r is centred on s r + (s - 1) / 2
    assert est.horizon_row_px == pytest.approx(s * h0 + (s - 1) / 2, abs=1.5)


@pytest.mark.parametrize("seed", SEEDS)
def test_fit_kernels_equal_plain_loops(seed):
    """The fit's compiled steps (slitcli/stereo/_c/ground.pyx) against plain NumPy on
    random first passes: the valid points in row-major order, each line's v-disparity
    mass counted point by point in its bins, the least-squares refit of the inliers
    (np.polyfit) and their residuals and per-row counts."""
    from slitcli.stereo._c import ground as k

    rng = np.random.default_rng(seed)
    hr, wr = 40, 53
    disp = rng.uniform(0, 12, (hr, wr)).astype(np.float32)
    disp[rng.random((hr, wr)) < 0.3] = np.nan
    disp[0, 0] = np.inf                                   # not finite: not a point
    rows = np.empty(hr * wr, np.int32)
    r, d = np.empty((2, hr * wr))
    n = k.valid_points(disp, rows, r, d)
    yy, xx = np.nonzero(np.isfinite(disp))
    assert n == yy.size
    np.testing.assert_array_equal(rows[:n], yy)
    np.testing.assert_array_equal(d[:n], disp[yy, xx])
    rows, r, d = rows[:n], r[:n], d[:n]
    q, half = 0.25, 2.0
    lo = math.floor(d.min() / q) - 1
    nb = math.floor(d.max() / q) - lo + 2
    g = rng.uniform(0.0, 0.5, 16)
    b = rng.uniform(-5.0, 10.0, 16)
    mass = np.empty(16, np.int64)
    k.line_mass(rows, d, hr, q, lo, nb, half, g, b, mass)
    bins = np.floor(d / q).astype(np.int64) - lo
    for i in range(16):
        c = (g[i] * rows + b[i]) / q - lo
        a = np.clip(np.floor(c - half), 0, nb)
        z = np.clip(np.floor(c + half) + 1, 0, nb)
        assert mass[i] == np.sum((bins >= a) & (bins < z))
    tol = 2.0
    on = np.abs(d - (0.1 * r + 3.0)) <= tol
    g2, b2, count, r_mean, sxx = k.line_refit(r, d, 0.1, 3.0, tol)
    want_g, want_b = np.polyfit(r[on], d[on], 1)
    assert count == on.sum()
    assert (g2, b2) == pytest.approx((want_g, want_b), rel=1e-9, abs=1e-9)
    assert (r_mean, sxx) == pytest.approx((r[on].mean(), ((r[on] - r[on].mean()) ** 2).sum()))
    resid = np.empty(n)
    per_row = np.zeros(hr, np.int64)
    m = k.line_inliers(rows, r, d, 0.1, 3.0, tol, resid, per_row)
    np.testing.assert_array_equal(resid[:m], (d - (0.1 * r + 3.0))[on])
    np.testing.assert_array_equal(per_row, np.bincount(rows[on], minlength=hr))


@pytest.mark.parametrize("seed", SEEDS)
def test_auto_is_the_pair_estimate_and_the_rig_path_stays(seed):
    """Without a rig, 'auto' shears by the pair's estimate (the same map as with those
    values given); with the rig, the pipeline takes the rig's ground (bit for bit the
    rig's explicit values, no estimate), 'pair' the pair's; 'rig' without a rig and
    'off' shear nothing."""
    from slitcli.stereo.pipeline import StereoParams, process_stereo_pair

    z = _render_floor(ROAD_RIG, seed, 0.25)
    p = MatcherParams(num_disparities=NUM, aggregation="sgm")
    given = with_pair_ground(p, z["left"], z["right"])
    assert given.sgm_ground_px_per_row > 0.3
    auto = compute_disparity(z["left"], z["right"], p).disparity_px
    np.testing.assert_array_equal(
        auto, compute_disparity(z["left"], z["right"], given).disparity_px)
    off = compute_disparity(z["left"], z["right"], replace(p, sgm_ground="off")).disparity_px
    np.testing.assert_array_equal(
        off, compute_disparity(z["left"], z["right"], replace(p, sgm_ground="rig")).disparity_px)
    np.testing.assert_array_equal(
        off, compute_disparity(z["left"], z["right"],
                               replace(p, sgm_ground_px_per_row=0.0)).disparity_px)
    bgr = [cv2.cvtColor(z[k], cv2.COLOR_GRAY2BGR) for k in ("left", "right")]
    geo = StereoGeometry.for_rig(ROAD_RIG)
    piped = process_stereo_pair(*bgr, ROAD_RIG, StereoParams(matcher=p)).disparity_px
    np.testing.assert_array_equal(
        piped, compute_disparity(z["left"], z["right"], with_rig_ground(p, geo)).disparity_px)
    pair = process_stereo_pair(*bgr, ROAD_RIG,
                               StereoParams(matcher=replace(p, sgm_ground="pair"))).disparity_px
    np.testing.assert_array_equal(pair, auto)


@pytest.mark.parametrize("seed", SEEDS)
def test_rigless_weak_road_gains_as_with_the_rig(seed):
    """The weakly textured floor (contrast 0.08) matched without a rig: with the ground
    from the pair the median error on the floor within 3 m is below the fronto-parallel
    window's (its slant bias, up to 1.1 px over 7 rows at 0.361 px per row) and no floor
    pixel is lost; fewer than 0.5 % of the valid ones are more than 2 px off."""
    z = _render_floor(ROAD_RIG, seed, 0.08)
    p = MatcherParams(num_disparities=NUM, aggregation="sgm")
    f = z["floor"]
    got = compute_disparity(z["left"], z["right"], p).disparity_px
    flat = compute_disparity(z["left"], z["right"], replace(p, sgm_ground="off")).disparity_px
    ok, ok0 = f & np.isfinite(got), f & np.isfinite(flat)
    err = np.abs(got[ok] - z["gt"][ok])
    assert np.median(err) < np.median(np.abs(flat[ok0] - z["gt"][ok0]))
    assert ok.sum() >= ok0.sum()
    assert (err > 2.0).mean() <= 0.005


@pytest.mark.parametrize("seed", SEEDS)
def test_check_replaces_a_rig_ground_that_is_off(seed):
    """A floor seen with the camera tilted 3 deg more than the rig says: the rig's
    ground is off by ``f W / h x 3 deg`` = 5 px at the horizon, beyond its 1 deg band
    (1.68 px), so 'check' takes the pair's ground; with the true rig it keeps the
    rig's values as given."""
    true_rig = replace(ROAD_RIG, mount=replace(ROAD_RIG.mount, tilt_deg=23.0))
    z = _render_floor(true_rig, seed, 0.08)
    p = MatcherParams(num_disparities=NUM, aggregation="sgm", sgm_ground="check")
    told = with_rig_ground(p, StereoGeometry.for_rig(ROAD_RIG))
    right = with_rig_ground(p, StereoGeometry.for_rig(true_rig))
    assert with_pair_ground(right, z["left"], z["right"]) == right
    fixed = with_pair_ground(told, z["left"], z["right"])
    est = estimate_ground(z["left"], z["right"], p)
    assert est.found
    assert fixed.sgm_ground_px_per_row == est.px_per_row
    assert fixed.sgm_ground_horizon_row_px == est.horizon_row_px
    grad, horizon = ground_shear_from_floor(StereoGeometry.for_rig(true_rig).floor_disparity_px)
    assert abs(est.horizon_row_px - horizon) * grad <= est.band_px


def test_ground_source_and_fit_are_checked():
    with pytest.raises(SlitcliError, match="sgm_ground"):
        MatcherParams(aggregation="sgm", sgm_ground="floor")
    with pytest.raises(SlitcliError, match="sgm_ground_fit"):
        MatcherParams(aggregation="sgm", sgm_ground_fit={"min_share": 0.5})
    with pytest.raises(SlitcliError, match="min_share"):
        GroundFitParams(min_share=1.5)
    with pytest.raises(SlitcliError, match="px_per_row_min"):
        GroundFitParams(px_per_row_min=0.5, px_per_row_max=0.4)
    with pytest.raises(SlitcliError, match="window_h_px"):
        GroundFitParams(window_h_px=4)
    assert not math.isnan(GroundFitParams().band_min_px)
