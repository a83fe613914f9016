"""The compiled SGM kernels (slitcli/stereo/_c/sgm.pyx) against Hirschmueller's
recurrence, over disparity counts that fill whole 16-lane vectors and counts that leave
a scalar tail, and the fused passes against the separate stages: same results bit for
bit, since fusion and vectors only speed up (issue 23)."""

from __future__ import annotations

import numpy as np
import pytest
from stereo_synth import plane_pair
from test_stereo_sgm import reference_paths

from slitcli.stereo import _sgm
from slitcli.stereo.matcher import MatcherParams, prefilter_image
from slitcli.stereo.sgm import COST_MAX, COST_SCALE, _cost_inputs, _match_fused

SEEDS = [0, 1, 2, 3, 4]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("eight", [True, False])
@pytest.mark.parametrize("edge_dn", [0.0, 8.0])
@pytest.mark.parametrize("num", [32, 21])
def test_paths_equal_the_recurrence(seed, eight, edge_dn, num):
    rng = np.random.default_rng(seed)
    cost = rng.integers(0, 513, (6, 9, num)).astype(np.uint16)
    grey = rng.integers(0, 256, (6, 9)).astype(np.uint8)
    ref_a, ref_b = reference_paths(cost, 13, 102, eight, grey, edge_dn)
    for reverse, ref in ((False, ref_a), (True, ref_b)):
        out = np.empty_like(cost)
        _sgm.aggregate_pass(cost, 13, 102, eight, reverse, out, grey, edge_dn)
        np.testing.assert_array_equal(out, ref)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("dmin", [0, -3, 4])
@pytest.mark.parametrize("num", [16, 13])
def test_costs_do_not_depend_on_the_bands(seed, dmin, num):
    """Costs of two bands of rows (as with two threads) equal those of one; each band
    starts its column sums afresh."""
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (20, 40)).astype(np.uint8)
    right = np.roll(left, -5, axis=1)
    left[5:9, 10:20] = 128   # a plain patch: windows without energy
    right[5:9, 5:15] = 128
    p = MatcherParams(num_disparities=num, window_w_px=7, window_h_px=5, aggregation="sgm",
                      min_disparity_px=dmin)
    c = _cost_inputs(prefilter_image(left, p), prefilter_image(right, p), p)
    args = (c["pl"], c["prr"], c["el"], c["err"], c["irr"], c["pad"], c["dmin"], c["num"],
            c["m"], c["n"], COST_MAX, COST_SCALE)
    a = np.empty((20, 40, num), np.uint16)
    b = np.empty_like(a)
    _sgm.cost_rows(*args, 0, 20, a)
    _sgm.cost_rows(*args, 0, 7, b)
    _sgm.cost_rows(*args, 7, 20, b)
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("kw", [{}, {"sgm_paths": 8, "min_disparity_px": 2},
                                {"uniqueness_ratio": 0.0, "lr_max_diff_px": -1.0,
                                 "subpixel": "none"}])
def test_fused_passes_equal_the_scalar_stages(seed, kw):
    """Costs, both sweeps and the winner step: the fused passes against the
    separate stages, on a noisy textured plane with a plain patch (ties, and
    uniqueness and left-right failures where those tests are on, occur)."""
    left, right = plane_pair(9.3, width=96, height=40, noise_dn=2.0, seed=seed,
                             plain_cols=(40, 60))
    p = MatcherParams(num_disparities=32, aggregation="sgm", **kw)
    pl, pr = prefilter_image(left, p), prefilter_image(right, p)
    c = _cost_inputs(pl, pr, p)
    cost = np.empty((40, 96, 32), np.uint16)
    _sgm.cost_rows(c["pl"], c["prr"], c["el"], c["err"], c["irr"], c["pad"], c["dmin"],
                   c["num"], c["m"], c["n"], COST_MAX, COST_SCALE, 0, 40, cost)
    p1, p2 = round(p.sgm_p1 * COST_SCALE), round(p.sgm_p2 * COST_SCALE)
    s_a, s_b = np.empty_like(cost), np.empty_like(cost)
    _sgm.aggregate_pass(cost, p1, p2, p.sgm_paths == 8, False, s_a, left,
                        float(p.sgm_p2_edge_dn))
    _sgm.aggregate_pass(cost, p1, p2, p.sgm_paths == 8, True, s_b, left,
                        float(p.sgm_p2_edge_dn))
    tests = (int(p.min_disparity_px), np.float32(p.uniqueness_ratio), float(p.lr_max_diff_px),
             p.subpixel == "parabola", np.float32((p.texture_min_dn * 4.0) ** 2),
             np.uint16(round(COST_MAX * COST_SCALE)), np.float32(COST_SCALE))
    want = [np.empty((40, 96), t) for t in (np.float32, np.float32, np.uint8, np.float32)]
    _sgm.winners_rows(s_a, s_b, cost, c["el"], c["count"], *tests, 0, 40, *want)
    got = [np.empty_like(a) for a in want]
    _match_fused(pl, pr, p, left, tests, tuple(got))
    # both kinds of pixel are compared: the plain patch and the left border give
    # invalid ones (with uniqueness and left-right off only those: 7-197 px over eight
    # seeds), uniqueness and left-right failures add > 200 when on
    assert (want[2] == 0).sum() > 500 and (want[2] != 0).any()
    if kw.get("lr_max_diff_px", 0) >= 0:
        assert (want[2] != 0).sum() > 50
    for a, b in zip(want, got, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("kw", [{}, {"sgm_paths": 8, "min_disparity_px": -2}])
def test_two_thread_phases_equal_one_thread(seed, kw):
    """The three phases over two threads (split at 2/5 of the height) against the fused
    passes on one thread, on an odd height."""
    from concurrent.futures import ThreadPoolExecutor

    left, right = plane_pair(7.6, width=80, height=51, noise_dn=2.0, seed=seed,
                             plain_cols=(30, 50))
    p = MatcherParams(num_disparities=32, aggregation="sgm", **kw)
    pl, pr = prefilter_image(left, p), prefilter_image(right, p)
    tests = (int(p.min_disparity_px), np.float32(p.uniqueness_ratio), float(p.lr_max_diff_px),
             True, np.float32((p.texture_min_dn * 4.0) ** 2),
             np.uint16(round(COST_MAX * COST_SCALE)), np.float32(COST_SCALE))
    kinds = (np.float32, np.float32, np.uint8, np.float32)
    one = [np.empty((51, 80), t) for t in kinds]
    two = [np.empty((51, 80), t) for t in kinds]
    _match_fused(pl, pr, p, left, tests, tuple(one))
    with ThreadPoolExecutor(max_workers=1) as pool:
        _match_fused(pl, pr, p, left, tests, tuple(two), pool, 2)
    for a, b in zip(one, two, strict=True):
        np.testing.assert_array_equal(a, b)
