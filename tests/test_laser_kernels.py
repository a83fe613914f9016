"""slitcli.laser's compiled kernels (slitcli/laser/_c): their constants are the Python
modules', the profile fit recovers a noiseless stripe, and the candidates are the same
whatever bands of columns or threads compute them."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from slitcli.laser import candidates, judge, profile
from slitcli.laser._c import candidates as compiled


def test_compiled_constants_are_the_python_ones():
    got = compiled.constants()
    fields = [n for n in dir(profile) if n.startswith("F_")]
    assert len(fields) == profile.N_FIELDS
    for name in [*fields, "N_FIELDS", "N_PAR", "MAX_ITER", "MIN_ROWS", "CONVERGED_PX",
                 "MIN_SIGMA_PX"]:
        assert got[name] == getattr(profile, name), name
    for name in ("NMS_HALF", "FLANK_ROWS", "NOISE_HALF", "N_SEEDS", "SEED_MIN_SIGMA_PX",
                 "SEED_EFFICIENCY", "MEAN_TO_SIGMA", "CLIP_SIGMAS"):
        assert got[name] == getattr(candidates, name), name
    assert got["OWN_REACH_PX"] == judge.OWN_REACH_PX


@pytest.mark.parametrize("seed", range(6))
def test_fit_recovers_a_noiseless_stripe(seed):
    # every column: a Gaussian of row v0, width s, peak a on the line c + b (v - v0),
    # exactly the profile model; the fit stops once its step is below CONVERGED_PX and
    # converges quadratically there, so the centre is within CONVERGED_PX, and the
    # width and peak within the float32 rounding of the evidence (relative 1e-6) times
    # the condition of the fit
    rng = np.random.default_rng(seed)
    w, h = 6, 64
    v0 = rng.uniform(20.0, 44.0, w)
    s = rng.uniform(0.8, 2.5, w)
    a = rng.uniform(20.0, 80.0, w)
    c = rng.uniform(-3.0, 3.0, w)
    b = rng.uniform(-0.05, 0.05, w)
    rows = np.arange(h)
    y = (c[:, None] + b[:, None] * (rows - v0[:, None])
         + a[:, None] * np.exp(-0.5 * ((rows - v0[:, None]) / s[:, None]) ** 2))
    y = np.ascontiguousarray(y, np.float32)
    img = np.zeros((w, h, 3), np.uint8)
    bg = np.zeros((3 * w, h), np.uint8)
    clipped = np.zeros((w, h), bool)
    mask = np.ones((w, h), bool)
    out = np.empty((w, 3, profile.N_FIELDS))
    candidates.column_candidates(img, bg, y, y, clipped, mask, 0.5, 0.5, 5.0, 10.0, 255,
                                 4.0, 0.1, 100.0, 3.0, out)
    best = out[:, 0]
    assert np.all(np.abs(best[:, profile.F_POS] - v0) < profile.CONVERGED_PX)
    assert np.allclose(best[:, profile.F_WIDTH], s, rtol=1e-3)
    assert np.allclose(best[:, profile.F_AMP], a, rtol=1e-3)
    assert np.all(best[:, profile.F_SAT] == 0.0)
    # the residuals are float32 rounding only: chi-square far below 1
    assert np.all(best[:, profile.F_CHI2] < 1e-3)
    # one fit per crossing: any other candidate is a pixel or more away
    other = out[:, 1:, profile.F_POS]
    assert np.all(np.isnan(other) | (np.abs(other - v0[:, None]) >= 1.0))


def _noisy_stripes(seed: int, w: int = 48, h: int = 96):
    """column_candidates' inputs for ``w`` columns: two Gaussian stripes with noise, a
    clipped run with red flanks in some columns, the lower rows searched."""
    rng = np.random.default_rng(seed)
    rows = np.arange(h)
    y = rng.normal(0.0, 1.0, (w, h))
    for _ in range(2):
        v0 = rng.uniform(15.0, h - 15.0) + np.cumsum(rng.normal(0.0, 0.3, w))
        s = rng.uniform(0.8, 2.5)
        a = rng.uniform(8.0, 60.0)
        y += a * np.exp(-0.5 * ((rows[None, :] - v0[:, None]) / s) ** 2)
    y = np.ascontiguousarray(y, np.float32)
    y_avg = np.ascontiguousarray(
        (y + np.roll(y, 1, 0) + np.roll(y, -1, 0)) / 3.0, np.float32)
    img = rng.integers(0, 200, (w, h, 3), dtype=np.uint8)
    bg = np.minimum(img.transpose(0, 2, 1).reshape(3 * w, h), 150).astype(np.uint8)
    bg = np.ascontiguousarray(bg)
    clipped = np.zeros((w, h), bool)
    core = rng.integers(20, h - 20)
    clipped[::5, core:core + 3] = True
    img[clipped, 2] = 255
    mask = np.ones((w, h), bool)
    mask[:, : int(rng.integers(0, 10))] = False
    return img, bg, y, y_avg, clipped, mask


@pytest.mark.parametrize("seed", range(6))
def test_candidates_are_the_same_over_bands_and_threads(seed):
    # columns are independent: any split into bands, run in any order or on two
    # threads, gives the whole image's table bit for bit
    args = _noisy_stripes(seed)
    scalars = (1.0, 0.6, 3.0, 10.0, 255, 4.0, 0.1, 4.0, 3.0)
    w = args[2].shape[0]
    whole = np.empty((w, 3, profile.N_FIELDS))
    compiled.column_candidates(*args, *scalars, whole)
    assert np.isfinite(whole[:, 0, profile.F_POS]).sum() >= w // 2  # stripes were found
    rng = np.random.default_rng(100 + seed)
    edges = np.unique(np.r_[0, rng.integers(0, w + 1, 5), w])
    bands = np.full_like(whole, 7.0)
    for c0, c1 in reversed(list(itertools.pairwise(edges))):
        compiled.column_candidates(*args, *scalars, bands, int(c0), int(c1))
    assert np.array_equal(bands, whole, equal_nan=True)
    threaded = np.full_like(whole, 7.0)
    candidates.run_column_bands(
        lambda c0, c1: compiled.column_candidates(*args, *scalars, threaded, c0, c1), w, 2)
    assert np.array_equal(threaded, whole, equal_nan=True)


@pytest.mark.parametrize(("n_cols", "threads"), [(0, 2), (15, 2), (320, 1), (320, 2),
                                                 (97, 3), (1280, 2)])
def test_column_bands_cover_every_column_once(n_cols, threads):
    seen = np.zeros(n_cols, int)

    def band(c0, c1):
        assert 0 <= c0 <= c1 <= n_cols
        seen[c0:c1] += 1

    candidates.run_column_bands(band, n_cols, threads)
    assert np.all(seen == 1)


def test_column_bands_raise_the_bands_error():
    def band(c0, c1):
        if c0 > 0:
            raise ValueError(f"band {c0}")

    with pytest.raises(ValueError, match="band"):
        candidates.run_column_bands(band, 320, 2)


def test_candidates_refuse_columns_outside_the_image():
    args = _noisy_stripes(0, w=8)
    out = np.empty((8, 3, profile.N_FIELDS))
    with pytest.raises(ValueError, match="columns"):
        compiled.column_candidates(*args, 1.0, 0.6, 3.0, 10.0, 255, 4.0, 0.1, 4.0, 3.0,
                                   out, 4, 9)


@pytest.mark.parametrize("seed", range(6))
def test_one_crossing_keeps_the_core_of_overlapping_fits(seed):
    # the rule by hand on random tables (overlapping, nested and NaN candidates): a
    # candidate is out when a valid one of its column overlaps it (centres closer than
    # the two widths) while brighter and narrower
    rng = np.random.default_rng(seed)
    w, k = 64, 3
    cand = np.full((w, k, profile.N_FIELDS), np.nan)
    cand[..., profile.F_POS] = rng.uniform(10.0, 16.0, (w, k))
    cand[..., profile.F_WIDTH] = rng.uniform(0.5, 3.0, (w, k))
    cand[..., profile.F_AMP] = rng.uniform(5.0, 50.0, (w, k))
    cand[rng.random((w, k)) < 0.2] = np.nan
    ok = rng.random((w, k)) < 0.8
    want = ok.copy()
    for i, a, b in itertools.product(range(w), range(k), range(k)):
        ca, cb = cand[i, a], cand[i, b]
        if ok[i, a] and abs(ca[profile.F_POS] - cb[profile.F_POS]) \
                < ca[profile.F_WIDTH] + cb[profile.F_WIDTH] \
                and ca[profile.F_AMP] > cb[profile.F_AMP] \
                and ca[profile.F_WIDTH] < cb[profile.F_WIDTH]:
            want[i, b] = False
    got = judge.one_crossing(cand, ok)
    assert got.dtype == np.bool_ and got.shape == (w, k)
    np.testing.assert_array_equal(got, want)
    assert want.sum() < ok.sum()  # the tables do hold nested fits


@pytest.mark.parametrize("seed", range(6))
def test_covered_shift_moves_segment_ends_onto_the_surface(seed):
    # a lit segment on one surface (ranges within jump_m) between unlit columns: each
    # end column sees the share f = s_end / s_full - coverage_z sigma / s_full of its
    # pixel, whose centre lies (1 - f) / 2 px inwards; inner columns stay
    from slitcli.laser.edges import EdgeParams, covered_shift_px

    rng = np.random.default_rng(seed)
    edges = EdgeParams()
    w, a, b = 40, int(rng.integers(3, 12)), int(rng.integers(24, 36))
    rng_m = np.full(w, np.nan)
    rng_m[a:b + 1] = 1.0 + rng.uniform(-0.2, 0.2) * edges.jump_m
    full = rng.uniform(50.0, 200.0)
    strength = np.full(w, np.nan)
    strength[a:b + 1] = full
    s_a, s_b = rng.uniform(0.2, 0.9, 2) * full
    strength[a], strength[b] = s_a, s_b
    sigma = rng.uniform(0.5, 3.0)
    shift = covered_shift_px(rng_m, strength, sigma, edges)
    f_a = np.clip(s_a / full - edges.coverage_z * sigma / full, 0.0, 1.0)
    f_b = np.clip(s_b / full - edges.coverage_z * sigma / full, 0.0, 1.0)
    assert shift[a] == pytest.approx(0.5 * (1.0 - f_a), abs=1e-12)
    assert shift[b] == pytest.approx(-0.5 * (1.0 - f_b), abs=1e-12)
    inner = np.r_[a + 1:b]
    np.testing.assert_array_equal(shift[inner], 0.0)
    np.testing.assert_array_equal(shift[:a], 0.0)
    # a farther surface beyond the left end does not hide it; a nearer one does
    rng_m[a - 1] = rng_m[a] + 10 * edges.jump_m
    strength[a - 1] = full
    assert covered_shift_px(rng_m, strength, sigma, edges)[a] == pytest.approx(shift[a])
    rng_m[a - 1] = rng_m[a] - 10 * edges.jump_m
    assert covered_shift_px(rng_m, strength, sigma, edges)[a] == 0.0


@pytest.mark.parametrize("seed", range(6))
def test_grey_image_test_counts_the_sampled_share(seed):
    # every 4th row and column sampled (GREY_STEP); grey when at most 0.1 % of them
    # differ by more than GREY_DN: k coloured sampled pixels of n flip it at k > n / 1000
    from slitcli.laser.diagnose import GREY_DN, GREY_SHARE, GREY_STEP, is_grey

    rng = np.random.default_rng(seed)
    h, w = 4 * int(rng.integers(40, 70)), 4 * int(rng.integers(40, 70))
    img = np.repeat(rng.integers(10, 240, (h, w, 1)), 3, axis=2).astype(np.uint8)
    img[..., 2] += rng.integers(0, GREY_DN + 1, (h, w)).astype(np.uint8)
    n = (h // GREY_STEP) * (w // GREY_STEP)
    k_max = max(k for k in range(n) if (n - k) / n >= GREY_SHARE)
    rows = rng.choice(h // GREY_STEP, k_max + 1) * GREY_STEP
    cols = rng.choice(w // GREY_STEP, k_max + 1, replace=False) * GREY_STEP
    img[rows[:-1], cols[:-1], 2] = img[rows[:-1], cols[:-1], 1] + GREY_DN + 1
    img[1::GREY_STEP, 1::GREY_STEP, 0] = 0  # unsampled pixels do not count
    # (also as a view with strides of a larger array)
    wider = np.zeros((h, w + 3, 3), np.uint8)
    wider[:, 3:] = img
    assert is_grey(img) and is_grey(wider[:, 3:])
    img[rows[-1], cols[-1], 2] = img[rows[-1], cols[-1], 1] + GREY_DN + 1
    wider[:, 3:] = img
    assert not is_grey(img) and not is_grey(wider[:, 3:])


@pytest.mark.parametrize("seed", range(4))
def test_white_core_is_judged_against_each_channels_clipping_level(seed):
    # a clipped run with red flanks whose green and blue sit at 234 in its middle: a
    # white core (F_SAT 2) where 234 is their clipping level, a red one (F_SAT 1) where
    # they clip at the red's level (the default)
    rng = np.random.default_rng(seed)
    w, h = 4, 60
    v0 = int(rng.integers(20, 40))
    img = np.full((w, h, 3), 40, np.uint8)
    img[:, v0 - 3] = img[:, v0 + 3] = (60, 60, 150)      # red flanks (BGR)
    img[:, v0 - 2] = img[:, v0 + 2] = (120, 120, 230)
    img[:, v0 - 1:v0 + 2] = (234, 234, 255)               # the clipped core
    bg = np.full((3 * w, h), 40, np.uint8)
    y = np.ascontiguousarray(img[..., 2].astype(np.float32) - 40.0)
    clipped = np.ascontiguousarray(img[..., 2] >= 250)
    mask = np.ones((w, h), bool)
    sat = {}
    for levels in ((-1.0, -1.0), (234.0, 234.0)):
        out = np.empty((w, 3, profile.N_FIELDS))
        compiled.column_candidates(img, bg, y, y, clipped, mask, 1.0, 0.6, 3.0, 10.0, 250,
                                   4.0, 0.1, 4.0, 3.0, out, 0, -1, *levels)
        core = np.abs(out[..., profile.F_POS] - v0) < 1.0
        assert core.any(axis=1).all()
        sat[levels] = out[..., profile.F_SAT][core]
    assert np.all(sat[(-1.0, -1.0)] == 1.0)
    assert np.all(sat[(234.0, 234.0)] == 2.0)
