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
@pytest.mark.parametrize("edge_dn", [0.0, 8.0, 16.0])
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
@pytest.mark.parametrize("eight", [True, False])
@pytest.mark.parametrize("edge_dn", [16.0, 255.0])
@pytest.mark.parametrize("num", [48, 21])
def test_edge_adapted_p2_over_the_whole_grey_range(seed, eight, edge_dn, num):
    """Grey steps of either sign up to 255 DN (black next to white, in every direction
    of the 8 paths) and none: the adapted P2 of each step, in the 16-lane row loops
    (48 disparities) and in the general ones (21), is the recurrence's."""
    rng = np.random.default_rng(seed)
    cost = rng.integers(0, 513, (7, 10, num)).astype(np.uint16)
    grey = rng.choice(np.array([0, 255, 254, 1, 128], np.uint8), (7, 10))
    grey[rng.random((7, 10)) < 0.3] = rng.integers(0, 256, 1, dtype=np.uint8)
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


def reference_winners(s_a, s_b, cost, el, count, dmin, uniq, lr_tol, energy_min, top, scale):
    """The winner step of slitcli.stereo._sgm.winners_rows from its definition, in NumPy
    (float32 arithmetic as the kernel's): smallest s_a + s_b among candidates (cost <
    top), ties to the smallest disparity; parabola through the sums; texture,
    uniqueness (no sum more than 1 px away below (1 + uniq) times the winner's; it
    overrides left-right, which overrides texture); the right view's winners from the
    same sums."""
    from slitcli.stereo.reasons import Reason

    h, w, num = cost.shape
    big = np.int64(1) << 40
    s = np.where(cost < top, s_a.astype(np.int64) + s_b, big)
    bi = np.argmin(s, axis=2)
    bv = np.take_along_axis(s, bi[..., None], 2)[..., 0]
    has = bv < big
    sm, sp = (np.take_along_axis(s, np.clip(bi + k, 0, num - 1)[..., None], 2)[..., 0]
              for k in (-1, 1))
    f = np.float32
    bvf, cm, cp = bv.astype(f), sm.astype(f), sp.astype(f)
    den = cm - f(2.0) * bvf + cp
    with np.errstate(all="ignore"):
        delta = np.where((bi > 0) & (bi < num - 1) & (sm < big) & (sp < big) & (den > 0),
                         f(0.5) * (cm - cp) / den, f(0.0)).astype(f)
    disp = np.where(has, (dmin + bi).astype(f) + delta, f(np.nan)).astype(f)
    c_win = np.take_along_axis(cost, bi[..., None], 2)[..., 0]
    mcost = np.where(has, c_win.astype(f) / f(scale), f(np.inf)).astype(f)
    i = np.arange(num)
    outside = np.abs(i[None, None, :] - bi[..., None]) > 1
    second = np.where(outside, s, big).min(axis=2)
    unique_fail = (uniq > 0) & (second < big) & (second.astype(f) < bvf * (f(1.0) + f(uniq)))
    # the right view: right pixel xr's candidates are left pixels xr + dmin + i
    xr = np.arange(w)[:, None] + dmin + i[None, :]
    inside = (xr >= 0) & (xr < w)
    rs = np.where(inside[None], s[:, np.clip(xr, 0, w - 1), i[None, :]], big)
    ri = np.argmin(rs, axis=2)
    rhas = rs.min(axis=2) < big
    rdisp = np.where(rhas, (dmin + ri).astype(f), f(np.nan)).astype(f)
    x = np.arange(w)[None, :] - dmin - bi
    xin = (x >= 0) & (x < w)
    xc = np.clip(x, 0, w - 1)
    rows = np.arange(h)[:, None]
    lr_ok = xin & rhas[rows, xc] & (np.abs(ri[rows, xc] - bi) <= lr_tol)
    reason = np.full((h, w), int(Reason.VALID), np.uint8)
    reason[(energy_min > 0) & (el < f(energy_min) * count)] = Reason.TEXTURE
    if lr_tol >= 0:
        reason[~lr_ok] = Reason.LEFT_RIGHT
    reason[unique_fail] = Reason.UNIQUENESS
    reason[~has] = Reason.NO_CANDIDATE
    return disp, mcost, reason, rdisp


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("num", [32, 21])
@pytest.mark.parametrize("high", [40, 3000, 65535])
def test_winners_equal_their_definition(seed, num, high):
    """The winner step (16-lane sums where D is a multiple of 16, int32 keys otherwise
    and where two sums add up past 16 bits) against its definition: random sums with
    many ties (high 40), the sweeps' range (3000) and beyond 16 bits (65535), costs with
    pixels and whole curves without a candidate."""
    rng = np.random.default_rng(seed)
    h, w, dmin = 7, 45, -2
    s_a = rng.integers(0, high + 1, (h, w, num)).astype(np.uint16)
    s_b = rng.integers(0, high + 1, (h, w, num)).astype(np.uint16)
    cost = rng.integers(0, 560, (h, w, num)).astype(np.uint16)
    cost[2, 5:9] = 600   # whole curves without a candidate
    el = rng.uniform(0, 2, (h, w)).astype(np.float32)
    count = np.ones((h, w), np.float32)
    args = (dmin, 0.15, 1.0, 0.5, 512, 256.0)
    tests = (dmin, np.float32(0.15), 1.0, True, np.float32(0.5), np.uint16(512),
             np.float32(256.0))
    got = [np.empty((h, w), t) for t in (np.float32, np.float32, np.uint8, np.float32)]
    _sgm.winners_rows(s_a, s_b, cost, el, count, *tests, 0, h, *got)
    want = reference_winners(s_a, s_b, cost, el, count, *args)
    for a, b in zip(want, got, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", SEEDS[:3])
@pytest.mark.parametrize("threads", ["1", "2"])
def test_a_held_workspace_changes_no_result(seed, threads, monkeypatch):
    """Frames matched through one SgmWorkspace that earlier frames (of other sizes and
    disparity counts) and junk left dirty: every output bit for bit as with fresh
    volumes, on one thread (two volumes) and two (three volumes, three phases)."""
    from concurrent.futures import ThreadPoolExecutor

    from slitcli.stereo.matcher import compute_disparity
    from slitcli.stereo.sgm import SgmWorkspace

    monkeypatch.setenv("SLITCLI_THREADS", threads)
    # the frame's helper threads are wanted even on a loaded machine (bands.kernel_threads
    # counts only free cores): the pool is passed and the split does not depend on load
    monkeypatch.setattr("slitcli.stereo.sgm.kernel_threads", lambda: int(threads))
    ws = SgmWorkspace()
    rng = np.random.default_rng(seed)
    junk = ws.volumes((3, 64, 120, 48))
    junk[...] = rng.integers(0, 65536, junk.shape, dtype=np.uint16)
    frames = [(7.6, 80, 51, 32), (12.2, 120, 64, 48), (5.1, 96, 40, 16)]
    with ThreadPoolExecutor(max_workers=1) as pool:
        for shift, w, h, num in frames:
            left, right = plane_pair(shift, width=w, height=h, noise_dn=2.0, seed=seed,
                                     plain_cols=(w // 3, w // 2))
            p = MatcherParams(num_disparities=num, aggregation="sgm")
            fresh = compute_disparity(left, right, p, pool=pool)
            held = compute_disparity(left, right, p, pool=pool, workspace=ws)
            assert np.isfinite(fresh.disparity_px).mean() > 0.3
            np.testing.assert_array_equal(held.disparity_px, fresh.disparity_px)
            np.testing.assert_array_equal(held.invalid_reason, fresh.invalid_reason)
            np.testing.assert_array_equal(held.match_cost, fresh.match_cost)
