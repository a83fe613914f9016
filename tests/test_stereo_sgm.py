"""Semi-global aggregation over the Eq. 10 cost (slitcli.stereo.sgm, issue 23)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from stereo_synth import draw_seeds, plane_pair, quantise, texture

from slitcli.errors import SlitcliError
from slitcli.stereo.matcher import MatcherParams, compute_disparity, prefilter_image
from slitcli.stereo.sgm import COST_MAX, COST_SCALE, cost_volume

SEEDS = [0, 1, 2, 3, 4]


def brute_force_eq10_zero_padded(pl: np.ndarray, pr: np.ndarray, num: int, m: int, n: int
                                 ) -> np.ndarray:
    """Eq. 10 over full windows of the images padded with zeros, (H, W, D) float64;
    +inf where the centre's partner leaves the right image or a window has no energy."""
    h, w = pl.shape
    a = np.pad(pl.astype(np.float64), ((n, n), (m, m)))
    b = np.pad(pr.astype(np.float64), ((n, n), (m + num, m)))
    out = np.full((h, w, num), np.inf)
    for y in range(h):
        for x in range(w):
            wl = a[y:y + 2 * n + 1, x:x + 2 * m + 1]
            for d in range(min(num, x + 1)):
                xr = x - d + num   # column of the right window's left edge in b
                wr = b[y:y + 2 * n + 1, xr:xr + 2 * m + 1]
                den = np.sqrt((wl * wl).sum() * (wr * wr).sum())
                if den > 0:
                    out[y, x, d] = ((wl - wr) ** 2).sum() / den
    return out


@pytest.mark.parametrize("seed", SEEDS)
def test_cost_volume_is_quantised_eq10(seed):
    rng = np.random.default_rng(seed)
    left = rng.integers(20, 236, (14, 30)).astype(np.uint8)
    right = np.roll(left, -3, axis=1)
    right[:, -3:] = rng.integers(20, 236, (14, 3))
    p = MatcherParams(num_disparities=8, window_w_px=5, window_h_px=3, aggregation="sgm")
    pl, pr = prefilter_image(left, p), prefilter_image(right, p)
    cost, _, _ = cost_volume(pl, pr, p)
    ref = brute_force_eq10_zero_padded(pl, pr, 8, 2, 1)
    top = round(COST_MAX * COST_SCALE)
    assert (cost[~np.isfinite(ref)] == top).all()
    fin = np.isfinite(ref)
    want = np.minimum(ref[fin], COST_MAX) * COST_SCALE
    # half a quantisation step, plus the fast reciprocal square root (relative 1e-3)
    np.testing.assert_array_less(np.abs(cost[fin] - want), 0.5 + 1e-3 * want + 1e-6)


def reference_paths(cost: np.ndarray, p1: float, p2: float, eight: bool,
                    grey: np.ndarray | None = None, edge_dn: float = 0.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Hirschmueller's recurrence path by path (float64, plain loops): the sums of the
    top-down sweep's paths and of the bottom-up sweep's paths. With ``grey`` and
    ``edge_dn`` > 0, a step from q to p costs ``int(P2 e / (e + |grey p - grey q|))``
    (at least P1 + 1) for a larger jump."""
    h, w, num = cost.shape
    c = cost.astype(np.float64)
    down = [(0, -1), (-1, 0)] + ([(-1, -1), (-1, 1)] if eight else [])
    sums = []
    for dirs in (down, [(-dy, -dx) for dy, dx in down]):
        total = np.zeros_like(c)
        for dy, dx in dirs:
            lr = np.zeros_like(c)
            ys = range(h) if dy <= 0 else range(h - 1, -1, -1)
            xs = list(range(w)) if dx <= 0 else list(range(w - 1, -1, -1))
            if dy == 0:
                ys = range(h)
            for y in ys:
                for x in xs:
                    py, px = y + dy, x + dx
                    if not (0 <= py < h and 0 <= px < w):
                        lr[y, x] = c[y, x]
                        continue
                    prev = lr[py, px]
                    pm = prev.min()
                    q2 = p2
                    if grey is not None and edge_dn > 0:
                        step = abs(float(grey[y, x]) - float(grey[py, px]))
                        q2 = max(int(np.float32(p2 * edge_dn / (edge_dn + step))), p1 + 1)
                    for d in range(num):
                        v = min(prev[d], pm + q2)
                        if d > 0:
                            v = min(v, prev[d - 1] + p1)
                        if d < num - 1:
                            v = min(v, prev[d + 1] + p1)
                        lr[y, x, d] = c[y, x, d] + v - pm
            total += lr
        sums.append(total)
    return sums[0], sums[1]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("eight", [True, False])
def test_path_costs_equal_the_recurrence(seed, eight):
    from slitcli.stereo import _sgm

    rng = np.random.default_rng(seed)
    cost = rng.integers(0, 512, (6, 9, 7)).astype(np.uint16)
    ref_a, ref_b = reference_paths(cost, 13.0, 102.0, eight)
    for reverse, ref in ((False, ref_a), (True, ref_b)):
        out = np.empty_like(cost)
        _sgm.aggregate_pass(cost, 13, 102, eight, reverse, out,
                            np.zeros(cost.shape[:2], np.uint8), 0.0)
        np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("eight", [True, False])
def test_path_costs_with_edge_adapted_p2(seed, eight):
    from slitcli.stereo import _sgm

    rng = np.random.default_rng(seed)
    cost = rng.integers(0, 512, (6, 9, 7)).astype(np.uint16)
    grey = rng.integers(0, 256, (6, 9)).astype(np.uint8)
    ref_a, ref_b = reference_paths(cost, 13, 102, eight, grey, 8.0)
    for reverse, ref in ((False, ref_a), (True, ref_b)):
        out = np.empty_like(cost)
        _sgm.aggregate_pass(cost, 13, 102, eight, reverse, out, grey, 8.0)
        np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("d", [7.4, 16.75])
def test_textured_plane_subpixel(d, seed):
    left, right = plane_pair(d, noise_dn=1.0, seed=seed)
    res = compute_disparity(left, right, MatcherParams(aggregation="sgm"))
    region = res.disparity_px[:, 32:]
    valid = np.isfinite(region)
    assert valid.mean() >= 0.95
    err = np.abs(region[valid] - d)
    assert np.median(err) <= 0.1
    assert np.percentile(err, 99) <= 0.5


@pytest.mark.parametrize("seed", SEEDS)
def test_slanted_plane_is_followed_row_by_row(seed):
    """A plane whose disparity grows 0.35 px per row (a floor seen by a wide-baseline
    rig; the paper rig's floor: 0.135): a 9-row window spans 3 px of disparity.

    Bounds, derived: (1) the window's estimate is the disparity at the centroid of its
    horizontal-gradient energy (the SSD of a shifted texture weighs each row by its
    (d I / d x)^2), so the error is 0.35 px x that centroid's row offset, predicted here
    from the prefiltered left image (``pred``), plus the matcher's subpixel noise, whose
    median on a fronto-parallel plane is <= 0.1 px
    (test_matcher's textured-plane test): median |err| <= median |pred| + 0.1. (2) The
    window is centred, so the offsets cancel on average: |median err| <= 0.05 px. (3) An
    offset never exceeds half the window, so no error exceeds 0.35 x 4 = 1.4 px plus
    noise; errors over 1 px need the centroid past 2.9 rows: <= 0.1 %. (4) SGM's 1-px
    steps (P1) follow the ramp where the local matcher's uniqueness and left-right
    tests drop it (5-50 % over ten texture seeds): SGM keeps at least as many pixels.
    """
    u, v = np.meshgrid(np.arange(320, dtype=float), np.arange(240, dtype=float))
    slope = 0.35
    d = 8.0 + slope * v
    tex_seed, noise_seed = draw_seeds(seed, 2)
    rng = np.random.default_rng(noise_seed)
    left = quantise(texture(u, v, seed=tex_seed), 1.0, rng)
    right = quantise(texture(u + d, v, seed=tex_seed), 1.0, rng)
    reg = (slice(10, 230), slice(100, 310))
    p = MatcherParams(num_disparities=96, aggregation="sgm")
    # the energy centroid's row offset in each 9 x 9 window (rows -4 .. 4)
    grad2 = np.gradient(prefilter_image(left, p).astype(np.float64), axis=1) ** 2
    row_energy = cv2.boxFilter(grad2, -1, (p.window_w_px, 1), normalize=False,
                               borderType=cv2.BORDER_REFLECT_101)
    half = p.window_h_px // 2
    offsets = np.arange(-half, half + 1, dtype=float)
    stack = np.stack([np.roll(row_energy, -k, axis=0) for k in range(-half, half + 1)])
    pred = slope * np.tensordot(offsets, stack, axes=1) / np.maximum(stack.sum(axis=0), 1e-9)
    got = compute_disparity(left, right, p).disparity_px[reg]
    ok = np.isfinite(got)
    err = got[ok] - d[reg][ok]
    assert np.median(np.abs(err)) <= np.median(np.abs(pred[reg][ok])) + 0.1
    assert abs(np.median(err)) <= 0.05
    assert (np.abs(err) > 1.0).mean() <= 0.001
    local = compute_disparity(left, right, MatcherParams(num_disparities=96)).disparity_px
    assert ok.mean() >= np.isfinite(local[reg]).mean()


@pytest.mark.parametrize("seed", SEEDS)
def test_textureless_patch_stays_invalid(seed):
    d = 12.3
    left, right = plane_pair(d, noise_dn=2.0, plain_cols=(120, 220), seed=seed)
    res = compute_disparity(left, right, MatcherParams(aggregation="sgm"))
    inner = res.valid[:, 124:216]
    assert 1.0 - inner.mean() >= 0.95
    err = np.abs(res.disparity_px[:, 120:220] - d)
    assert (np.isfinite(err) & (err > 1.0)).mean() <= 0.01


def test_sgm_parameters_are_checked():
    with pytest.raises(SlitcliError, match="sgm_paths"):
        MatcherParams(aggregation="sgm", sgm_paths=6)
    with pytest.raises(SlitcliError, match="sgm_p1"):
        MatcherParams(aggregation="sgm", sgm_p1=0.5, sgm_p2=0.1)
    with pytest.raises(SlitcliError, match="`aggregation` 'sgm'"):
        MatcherParams(matcher="bm", aggregation="sgm")
    with pytest.raises(SlitcliError, match="aggregation"):
        MatcherParams(aggregation="global")
    with pytest.raises(SlitcliError, match="at least 2 disparities"):
        MatcherParams(aggregation="sgm", num_disparities=1)
    with pytest.raises(SlitcliError, match="at most 512"):
        MatcherParams(aggregation="sgm", num_disparities=528)
    with pytest.raises(SlitcliError, match="sgm_bracket_px"):
        MatcherParams(aggregation="sgm", sgm_bracket_px=-1)
    with pytest.raises(SlitcliError, match="sgm_p2_edge_dn"):
        MatcherParams(aggregation="sgm", sgm_p2_edge_dn=-2.0)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("dmin", [-4, 0, 2])
def test_disparity_range_offsets(dmin, seed):
    # the same plane found whatever the range's start (negative ranges included)
    left, right = plane_pair(5.3, noise_dn=1.0, seed=seed)
    res = compute_disparity(left, right, MatcherParams(num_disparities=16, min_disparity_px=dmin,
                                                       aggregation="sgm"))
    valid = np.isfinite(res.disparity_px)
    assert valid[:, 20:].mean() >= 0.95
    assert np.median(np.abs(res.disparity_px[valid] - 5.3)) <= 0.1
