"""SGM's Eq. 10 window sheared by the ground's disparity gradient (issue 23's slanted
road: slitcli.stereo.cost.ground_window_shifts, MatcherParams.sgm_ground_*)."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import cv2
import numpy as np
import pytest
from stereo_synth import draw_seeds, quantise, texture

from slitcli.errors import SlitcliError
from slitcli.rig import paper_rig
from slitcli.stereo.cost import ground_shear_from_floor, ground_window_shifts
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.matcher import (
    MatcherParams,
    compute_disparity,
    prefilter_image,
    with_rig_ground,
)
from slitcli.stereo.sgm import COST_MAX, COST_SCALE, _match_fused, cost_volume

SEEDS = [0, 1, 2, 3, 4]
#: the paper rig with a 0.25 m baseline: its floor gains W cos(tilt) / h = 0.361 px of
#: disparity per row, KITTI's road about 0.33 (0.54 m / 1.65 m)
ROAD_RIG = replace(paper_rig(), baseline_m=0.25)


def brute_force_sheared(pl: np.ndarray, pr: np.ndarray, num: int, m: int, n: int,
                        shifts: np.ndarray) -> np.ndarray:
    """Eq. 10 over windows whose row dv reads the right image ``shifts[dv + n]`` px
    further left (zeros outside), (H, W, D) float64; +inf where the centre's partner
    leaves the right image or a window has no energy."""
    h, w = pl.shape
    smax = int(np.abs(shifts).max())
    pad = num + m + smax
    a = np.pad(pl.astype(np.float64), ((n, n), (m, m)))
    b = np.pad(pr.astype(np.float64), ((n, n), (pad, pad)))
    out = np.full((h, w, num), np.inf)
    for y in range(h):
        for x in range(w):
            wl = a[y:y + 2 * n + 1, x:x + 2 * m + 1]
            for d in range(min(num, x + 1)):
                wr = np.stack([b[y + k, pad + x - d - s - m:pad + x - d - s + m + 1]
                               for k, s in enumerate(shifts)])
                den = np.sqrt((wl * wl).sum() * (wr * wr).sum())
                if den > 0:
                    out[y, x, d] = ((wl - wr) ** 2).sum() / den
    return out


def test_shifts_follow_the_gradient():
    # round(g dv), half away from zero, symmetric about the centre row
    assert ground_window_shifts(0.361, 3).tolist() == [-1, -1, 0, 0, 0, 1, 1]
    assert ground_window_shifts(0.127, 3).tolist() == [0] * 7   # paper rig: no shear
    assert ground_window_shifts(0.5, 2).tolist() == [-1, -1, 0, 1, 1]
    assert ground_window_shifts(0.0, 4).tolist() == [0] * 9


def test_rig_gradient_and_horizon_from_the_floor():
    """Below the horizon the floor's disparity is ``W / h (cos(t) (v - cy) + f sin(t))``
    (Eq. 8 with the floor depth; t the tilt, no roll): linear in the row, with slope
    ``W cos(t) / h`` and zero at ``v = cy - f tan(t)``."""
    for rig in (paper_rig(), ROAD_RIG):
        t = math.radians(rig.mount.tilt_deg)
        grad, horizon = ground_shear_from_floor(StereoGeometry.for_rig(rig).floor_disparity_px)
        assert grad == pytest.approx(rig.baseline_m * math.cos(t) / rig.mount.height_m,
                                     rel=1e-5)
        assert horizon == pytest.approx(rig.left.cy_px - rig.focal_px * math.tan(t),
                                        abs=1e-3)
    geo = StereoGeometry.for_rig(ROAD_RIG)
    sgm = with_rig_ground(MatcherParams(aggregation="sgm"), geo)
    assert sgm.sgm_ground_px_per_row == pytest.approx(0.3614, abs=1e-4)
    # a 1 degree tilt error moves the floor's disparity by f W / h x 1 deg (at the
    # horizon; the tilt's cosine term vanishes there): 250 x 0.25 / 0.65 x 0.01745
    assert sgm.sgm_ground_band_px == pytest.approx(250 * 0.25 / 0.65 * math.radians(1.0))
    # explicit values stay; the local matcher has no window to shear
    assert with_rig_ground(MatcherParams(aggregation="sgm", sgm_ground_px_per_row=0.0),
                           geo).sgm_ground_px_per_row == 0.0
    assert with_rig_ground(MatcherParams(), geo).sgm_ground_px_per_row is None


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(("num", "band"), [(8, None), (32, 1.0), (20, 2.5)])
def test_sheared_cost_is_eq10_over_sheared_windows(seed, num, band):
    """From the horizon row down, the cost is the smaller of the fronto-parallel and
    the sheared window's Eq. 10 for the disparities within ``band`` of the ground's
    (0.5 px per row from the horizon at row 4.5; every disparity without a band), the
    fronto-parallel one elsewhere. 32 disparities: the 16-lane rows on a block of 16
    (moved down the image with the ground), 20: the scalar loops."""
    rng = np.random.default_rng(seed)
    h = 40
    left = rng.integers(20, 236, (h, 36)).astype(np.uint8)
    right = np.roll(left, -3, axis=1)
    right[:, -3:] = rng.integers(20, 236, (h, 3))
    horizon = 5
    p = MatcherParams(num_disparities=num, window_w_px=5, window_h_px=5, aggregation="sgm",
                      sgm_ground_px_per_row=0.5, sgm_ground_horizon_row_px=horizon - 0.5,
                      sgm_ground_band_px=band)
    pl, pr = prefilter_image(left, p), prefilter_image(right, p)
    cost, _, _ = cost_volume(pl, pr, p)
    top = round(COST_MAX * COST_SCALE)
    flat = brute_force_sheared(pl, pr, num, 2, 2, np.zeros(5, np.int64))
    sheared = brute_force_sheared(pl, pr, num, 2, 2, ground_window_shifts(0.5, 2))
    near = np.ones((h, num), bool)
    if band is not None:
        ground = 0.5 * (np.arange(h) - (horizon - 0.5))
        near = np.abs(np.arange(num)[None, :] - ground[:, None]) <= band
    near[:horizon] = False
    ref = np.where(near[:, None, :], np.minimum(flat, sheared), flat)
    assert (cost[~np.isfinite(ref)] == top).all()
    fin = np.isfinite(ref)
    want = np.minimum(ref[fin], COST_MAX) * COST_SCALE
    # half a quantisation step, plus the float32 reciprocal square roots
    np.testing.assert_array_less(np.abs(cost[fin] - want), 0.5 + 1e-3 * want + 1e-6)


@pytest.mark.parametrize("seed", SEEDS)
def test_sheared_hypothesis_only_near_the_ground(seed):
    """With a band, only disparities within it of the ground's at each row (0.5 px per
    row from the horizon at row 4.5) may cost less than the fronto-parallel window;
    every other cost is the fronto-parallel one, bit for bit."""
    rng = np.random.default_rng(seed)
    left = rng.integers(20, 236, (40, 48)).astype(np.uint8)
    right = np.roll(left, -5, axis=1)
    flat = MatcherParams(num_disparities=16, window_w_px=5, window_h_px=5,
                         aggregation="sgm", sgm_ground_px_per_row=0.0)
    band = replace(flat, sgm_ground_px_per_row=0.5, sgm_ground_horizon_row_px=4.5,
                   sgm_ground_band_px=1.5)
    pl, pr = prefilter_image(left, flat), prefilter_image(right, flat)
    c0, _, _ = cost_volume(pl, pr, flat)
    c1, _, _ = cost_volume(pl, pr, band)
    ground = 0.5 * (np.arange(40) - 4.5)
    near = np.abs(np.arange(16)[None, :] - ground[:, None]) <= 1.5   # (rows, D)
    near[:5] = False                                                # above the horizon
    near = np.broadcast_to(near[:, None, :], c0.shape)
    np.testing.assert_array_equal(c1[~near], c0[~near])
    assert (c1[near] <= c0[near]).all() and (c1[near] < c0[near]).any()


def slanted_pair(seed: int, slope: float, d0: float = 8.0
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured plane whose disparity grows ``slope`` px per row (exact, no
    resampling: stereo_synth's analytic texture), grey pair and true disparity."""
    u, v = np.meshgrid(np.arange(320, dtype=float), np.arange(240, dtype=float))
    d = d0 + slope * v
    tex_seed, noise_seed = draw_seeds(seed, 2)
    rng = np.random.default_rng(noise_seed)
    left = quantise(texture(u, v, seed=tex_seed), 1.0, rng)
    right = quantise(texture(u + d, v, seed=tex_seed), 1.0, rng)
    return left, right, d


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("num", [96, 40])
def test_fused_passes_equal_the_stages_with_the_shear(threads, num):
    """The fused passes (one or two threads; 96: the 16-lane rows, 40: the scalar
    loops) give the separate stages' winners bit for bit with a sheared window, and
    its horizon row inside the image."""
    from slitcli.stereo import _sgm
    from slitcli.stereo.sgm import aggregate

    left, right, _ = slanted_pair(7, 0.36, d0=2.0)
    left, right = left[:, :200], right[:, :200]
    p = MatcherParams(num_disparities=num, window_w_px=7, window_h_px=7, aggregation="sgm",
                      sgm_ground_px_per_row=0.36, sgm_ground_horizon_row_px=37.2,
                      sgm_ground_band_px=2.0)
    pl, pr = prefilter_image(left, p), prefilter_image(right, p)
    h, w = left.shape
    tests = (0, np.float32(0.15), 1.0, True, np.float32(16.0), np.uint16(512), np.float32(256))

    def outputs():
        return (np.empty((h, w), np.float32), np.empty((h, w), np.float32),
                np.empty((h, w), np.uint8), np.empty((h, w), np.float32))

    grey = np.ascontiguousarray(left)
    cost, el, count = cost_volume(pl, pr, p)
    s_a, s_b = aggregate(cost, p, grey=grey)
    want = outputs()
    _sgm.winners_rows(s_a, s_b, cost, el, count, *tests, 0, h, *want)
    got = outputs()
    with ThreadPoolExecutor(1) as pool:
        fused_cost = _match_fused(pl, pr, p, grey, tests, got, pool, threads)
    np.testing.assert_array_equal(fused_cost, cost)
    for a, b in zip(got, want, strict=True):
        np.testing.assert_array_equal(a, b)


def _energy_centroid_error(left: np.ndarray, p: MatcherParams, slope: float,
                           shifts: np.ndarray) -> np.ndarray:
    """Predicted error (px) of a window on a plane of ``slope`` px per row whose row dv
    is shifted by ``shifts``: the residual slope ``slope dv - shift`` at the centroid of
    the window's horizontal-gradient energy (the SSD of a shifted texture weighs each
    row by its (dI/dx)^2)."""
    grad2 = np.gradient(prefilter_image(left, p).astype(np.float64), axis=1) ** 2
    row_energy = cv2.boxFilter(grad2, -1, (p.sgm_window_px, 1), normalize=False,
                               borderType=cv2.BORDER_REFLECT_101)
    half = p.sgm_window_px // 2
    dv = np.arange(-half, half + 1, dtype=float)
    stack = np.stack([np.roll(row_energy, -k, axis=0) for k in range(-half, half + 1)])
    resid = slope * dv - shifts
    return np.tensordot(resid, stack, axes=1) / np.maximum(stack.sum(axis=0), 1e-9)


@pytest.mark.parametrize("seed", SEEDS)
def test_sheared_window_removes_the_slant_bias(seed):
    """A plane 0.36 px per row (the road rig's floor). Fronto-parallel 7 x 7 windows
    read the disparity at their energy centroid, 0.36 px x its row offset (up to 1.1
    px); with the rows shifted by round(0.36 dv) = 0, 1, 1 px for |dv| = 1, 2, 3 the
    residual slope is 0.36, -0.28, 0.08 px per row offset, so the predicted error
    (``pred``) shrinks. Bounds: median |err| <= median |pred| + 0.1 px (the matcher's
    subpixel noise on a fronto-parallel plane, tests/test_stereo_sgm_quality.py), and
    at most the fronto-parallel window's median error."""
    slope = 0.36
    left, right, d = slanted_pair(seed, slope)
    reg = (slice(10, 230), slice(100, 310))
    flat = MatcherParams(num_disparities=112, aggregation="sgm", sgm_ground_px_per_row=0.0)
    # the plane is the "ground": its disparity 8 + 0.36 v is 0 at row -8 / 0.36
    shear = replace(flat, sgm_ground_px_per_row=slope, sgm_ground_horizon_row_px=-8.0 / slope,
                    sgm_ground_band_px=1.5)
    shifts = ground_window_shifts(slope, shear.sgm_window_px // 2)
    pred = _energy_centroid_error(left, shear, slope, shifts)[reg]
    got = compute_disparity(left, right, shear).disparity_px[reg]
    ok = np.isfinite(got)
    err = got[ok] - d[reg][ok]
    base = compute_disparity(left, right, flat).disparity_px[reg]
    ok0 = np.isfinite(base)
    assert ok.mean() >= 0.97
    assert np.median(np.abs(err)) <= np.median(np.abs(pred[ok])) + 0.1
    assert np.median(np.abs(err)) <= np.median(np.abs(base[ok0] - d[reg][ok0]))
    assert (np.abs(err) > 1.0).mean() <= 0.001


def render_floor(seed: int, contrast: float, rig=ROAD_RIG) -> dict:
    """A textured floor alone (noise texture of ``contrast``, 2 DN noise) seen by ``rig``:
    BGR views, true disparity and the floor within 3 m."""
    from slitcli.sim.render import render_frame
    from slitcli.sim.scene import scene_from_dict

    d = {"slitcli_scene": 1, "name": f"floor-{seed}", "seed": seed,
         "floor": {"colour_rgb": [0.55, 0.5, 0.45], "texture": "noise", "scale_m": 0.03,
                   "contrast": contrast},
         "objects": [], "image": {"noise_sigma_dn": 2.0},
         "robot": {"start": [0.0, 0.0, 0.0], "motion": "static", "frames": 1}}
    scene = scene_from_dict(d, d["name"])
    fr = render_frame(scene, rig, scene.poses(1)[0], frame_index=0)
    return {"left": fr.left_bgr, "right": fr.right_bgr, "gt": fr.truth.disparity_px,
            "floor": (fr.truth.object_id == 0) & (fr.truth.depth_m <= 3.0)
            & np.isfinite(fr.truth.disparity_px)}


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("contrast", [0.25, 0.08])
def test_rendered_floor_with_the_rig_shear(seed, contrast):
    """The rendered floor within 3 m seen by the 0.25 m rig, through the stereo
    pipeline, which shears SGM's window by the rig's 0.361 px per row.

    The fronto-parallel 7-row window reads the disparity at its rows' texture-energy
    centroid, 0.361 px x its offset (``pred0``, up to 1.1 px); the sheared one the
    residual slope 0.36, -0.28, 0.08 px at |dv| = 1, 2, 3 (``pred``, at most 0.36
    px). Textured floor (contrast 0.25): median |err| <= median |pred| + 0.1 px (the
    matcher's subpixel noise on a fronto-parallel plane) and below the fronto-parallel
    window's predicted median bias. Weak texture (contrast 0.08, a plain road): the
    noise dominates, but on the same frame the sheared window has the smaller median
    error and loses no pixels (its cost curve is sharper: uniqueness and left-right
    keep more). Both: fewer than 0.5 % of the valid pixels more than 2 px off (the
    residual never reaches 1 px)."""
    from slitcli.stereo.pipeline import StereoParams, process_stereo_pair

    z = render_floor(seed, contrast)
    num = 96
    p = StereoParams(matcher=MatcherParams(num_disparities=num, aggregation="sgm"))
    got = process_stereo_pair(z["left"], z["right"], ROAD_RIG, p).disparity_px
    f = z["floor"]
    ok = f & np.isfinite(got)
    err = np.abs(got[ok] - z["gt"][ok])
    assert (err > 2.0).mean() <= 0.005
    if contrast == 0.25:
        grey = cv2.cvtColor(z["left"], cv2.COLOR_BGR2GRAY)
        sgm = MatcherParams(aggregation="sgm")
        g = 0.3614
        pred = _energy_centroid_error(grey, sgm, g, ground_window_shifts(g, 3))[ok]
        pred0 = _energy_centroid_error(grey, sgm, g, np.zeros(7))[ok]
        assert np.median(err) <= np.median(np.abs(pred)) + 0.1
        assert np.median(err) < np.median(np.abs(pred0))
        return
    flat = compute_disparity(z["left"], z["right"],
                             MatcherParams(num_disparities=num, aggregation="sgm",
                                           sgm_ground_px_per_row=0.0)).disparity_px
    ok0 = f & np.isfinite(flat)
    assert np.median(err) < np.median(np.abs(flat[ok0] - z["gt"][ok0]))
    assert ok.sum() >= ok0.sum()


def test_ground_parameters_are_checked():
    with pytest.raises(SlitcliError, match="sgm_ground_px_per_row"):
        MatcherParams(aggregation="sgm", sgm_ground_px_per_row=-0.1)
    with pytest.raises(SlitcliError, match="sgm_ground_px_per_row"):
        MatcherParams(aggregation="sgm", sgm_ground_px_per_row=float("nan"))
    with pytest.raises(SlitcliError, match="sgm_ground_horizon_row_px"):
        MatcherParams(aggregation="sgm", sgm_ground_horizon_row_px=float("inf"))


@pytest.mark.parametrize("seed", SEEDS)
def test_no_shift_no_change(seed):
    """A gradient whose shifts all round to 0 (the paper rig's 0.127 px per row over a
    7-row window) leaves the matcher as it was, bit for bit."""
    left, right, _ = slanted_pair(seed, 0.127)
    a = compute_disparity(left, right, MatcherParams(num_disparities=64, aggregation="sgm"))
    b = compute_disparity(left, right, MatcherParams(
        num_disparities=64, aggregation="sgm", sgm_ground_px_per_row=0.127,
        sgm_ground_horizon_row_px=28.5))
    np.testing.assert_array_equal(a.disparity_px, b.disparity_px)
    np.testing.assert_array_equal(a.invalid_reason, b.invalid_reason)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(("dmin", "num", "split"), [(0, 32, 7), (-3, 32, 19), (4, 13, 11)])
def test_sheared_costs_do_not_depend_on_the_bands(seed, dmin, num, split):
    """Two bands of rows (as with two threads) give the sheared costs of one: each
    band sums its sheared window afresh at its first row below the horizon, and the
    block of disparities it computes moves with the ground wherever the band starts."""
    from slitcli.stereo import _sgm
    from slitcli.stereo.sgm import _cost_inputs

    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (40, 48)).astype(np.uint8)
    right = np.roll(left, -5, axis=1)
    p = MatcherParams(num_disparities=num, window_w_px=7, window_h_px=7, aggregation="sgm",
                      min_disparity_px=dmin, sgm_ground_px_per_row=0.6,
                      sgm_ground_horizon_row_px=5.3, sgm_ground_band_px=1.0)
    c = _cost_inputs(prefilter_image(left, p), prefilter_image(right, p), p)
    assert c["shear"] is not None
    args = (c["pl"], c["prr"], c["el"], c["err"], c["irr"], c["pad"], c["dmin"], c["num"],
            c["m"], c["n"], COST_MAX, COST_SCALE)
    a = np.empty((40, 48, num), np.uint16)
    b = np.empty_like(a)
    _sgm.cost_rows(*args, 0, 40, a, c["shear"])
    _sgm.cost_rows(*args, 0, split, b, c["shear"])
    _sgm.cost_rows(*args, split, 40, b, c["shear"])
    np.testing.assert_array_equal(a, b)
