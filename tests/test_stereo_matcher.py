"""The Eq. 10 matcher against a brute-force Eq. 10, Middlebury, and exact synthetic pairs."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from stereo_synth import draw_seeds, occlusion_pair, plane_pair, quantise, texture

from slitcli.errors import SlitcliError
from slitcli.stereo.matcher import (
    MatcherParams,
    compute_disparity,
    prefilter_image,
)
from slitcli.stereo.reasons import Reason

PLAIN = dict(prefilter="none", texture_min_dn=0.0, uniqueness_ratio=0.0, lr_max_diff_px=-1,
             support_min_zncc=0.0, boundary_ratio=0.0, speckle_window_px=0, subpixel="none")


def brute_force_eq10(pl: np.ndarray, pr: np.ndarray, dmin: int, num: int, m: int, n: int
                     ) -> np.ndarray:
    """Eq. 10 for every pixel and disparity by explicit window sums (float64).

    The window is clipped to the rows of the image and to the columns both images
    cover (left column c and right column c - d both inside); +inf where the centre's
    partner lies outside the right image.
    """
    h, w = pl.shape
    pl = pl.astype(np.float64)
    pr = pr.astype(np.float64)
    out = np.full((num, h, w), np.inf)
    for i in range(num):
        d = dmin + i
        for y in range(h):
            for x in range(w):
                if not 0 <= x - d < w:
                    continue
                ys = slice(max(0, y - n), min(h, y + n + 1))
                c0, c1 = max(x - m, d, 0), min(x + m, w - 1, w - 1 + d)
                a = pl[ys, c0:c1 + 1]
                b = pr[ys, c0 - d:c1 + 1 - d]
                den = np.sqrt((a * a).sum()) * np.sqrt((b * b).sum())
                out[i, y, x] = ((a - b) ** 2).sum() / den if den > 0 else np.inf
    return out


SEEDS = [0, 1, 2, 3, 4, 5]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("window,dmin", [((5, 5), 0), ((7, 3), 2), ((3, 5), -2)])
def test_cost_and_winner_equal_brute_force_eq10(window, dmin, seed):
    rng = np.random.default_rng(seed)
    left = rng.integers(20, 236, (18, 40)).astype(np.uint8)
    right = np.roll(left, -4, axis=1)  # a shift of 4 px plus fresh noise at the seam
    right[:, -4:] = rng.integers(20, 236, (18, 4))
    num = 9
    p = MatcherParams(num_disparities=num, min_disparity_px=dmin, window_w_px=window[0],
                      window_h_px=window[1], **PLAIN)
    res = compute_disparity(left, right, p)
    ref = brute_force_eq10(left, right, dmin, num, window[0] // 2, window[1] // 2)
    ref_min = ref.min(axis=0)
    ref_d = (ref.argmin(axis=0) + dmin).astype(float)
    ref_d[~np.isfinite(ref_min)] = np.nan
    np.testing.assert_array_equal(res.disparity_px, ref_d)
    finite = np.isfinite(ref_min)
    np.testing.assert_allclose(res.match_cost[finite], ref_min[finite], rtol=2e-5, atol=1e-6)
    # every column u can still be matched with any disparity d <= u: no columns are lost
    assert np.isfinite(res.disparity_px[:, max(dmin, 0):]).all()
    assert np.isnan(res.disparity_px[:, :max(dmin, 0)]).all()


@pytest.mark.parametrize("seed", SEEDS)
def test_prefiltered_cost_is_eq10_of_the_prefiltered_images(seed):
    rng = np.random.default_rng(seed)
    left = cv2.GaussianBlur(rng.integers(0, 256, (16, 36)).astype(np.uint8), (3, 3), 0)
    right = np.roll(left, -3, axis=1)
    p = MatcherParams(num_disparities=8, window_w_px=5, window_h_px=5,
                      **{**PLAIN, "prefilter": "mean"})
    res = compute_disparity(left, right, p)
    ref = brute_force_eq10(prefilter_image(left, p), prefilter_image(right, p), 0, 8, 2, 2)
    finite = np.isfinite(ref.min(axis=0))
    np.testing.assert_allclose(res.match_cost[finite], ref.min(axis=0)[finite], rtol=2e-5,
                               atol=1e-6)


# ------------------------------------------------------------------ Middlebury
@pytest.fixture(scope="module")
def motorcycle():
    """Middlebury 2014 motorcycle from scikit-image, protocol of issue 5."""
    from skimage import data  # a dev dependency: a missing one is a failure, not a skip
    left, right, gt = data.stereo_motorcycle()
    size = (320, 240)
    lg = cv2.resize(cv2.cvtColor(left, cv2.COLOR_RGB2GRAY), size, interpolation=cv2.INTER_AREA)
    rg = cv2.resize(cv2.cvtColor(right, cv2.COLOR_RGB2GRAY), size,
                    interpolation=cv2.INTER_AREA)
    g = cv2.resize(gt, size, interpolation=cv2.INTER_NEAREST) * (320.0 / 741.0)
    return lg, rg, g


def bad2(disp: np.ndarray, gt: np.ndarray) -> tuple[float, float, float]:
    """(bad2 on valid pixels, density, bad2 counting invalid as bad) over finite GT."""
    has_gt = np.isfinite(gt)
    valid = has_gt & np.isfinite(disp)
    bad = valid & (np.abs(disp - gt) > 2.0)
    return (bad.sum() / valid.sum(), valid.sum() / has_gt.sum(),
            (bad.sum() + (has_gt & ~valid).sum()) / has_gt.sum())


def test_middlebury_plain_winner_take_all_reproduces_eq10(motorcycle):
    lg, rg, gt = motorcycle
    res = compute_disparity(lg, rg, MatcherParams(num_disparities=64, **PLAIN))
    b, density, _ = bad2(res.disparity_px, gt)
    assert density == 1.0
    assert 0.185 <= b <= 0.205  # earlier measurement of plain Eq. 10 WTA: 0.193


def test_middlebury_default_filters(motorcycle):
    lg, rg, gt = motorcycle
    res = compute_disparity(lg, rg, MatcherParams(num_disparities=64))
    b_valid, density, b_all = bad2(res.disparity_px, gt)
    assert b_valid <= 0.08
    assert density >= 0.75
    assert b_all <= 0.25
    # StereoBM leaves its 63 leftmost columns empty; here a column u keeps the pixels
    # whose true disparity is at most u (the others are not in the right image at all)
    cols = np.arange(gt.shape[1])[None, :]
    possible = np.isfinite(gt) & (gt <= cols - 1) & (cols < 63)
    assert np.isfinite(res.disparity_px[possible]).mean() >= 0.6
    bm = cv2.StereoBM_create(numDisparities=64, blockSize=9).compute(lg, rg)
    assert (bm[:, :63] < 0).all()


# ------------------------------------------------------------------ synthetic
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("d", [7.4, 12.3, 16.75, 21.6])
def test_subpixel_disparity_of_a_textured_plane(d, seed):
    # 22 px = 1 m, 7.33 px = 3 m for the paper rig; fractions sweep the pixel-locking bias
    left, right = plane_pair(d, noise_dn=1.0, seed=seed)
    res = compute_disparity(left, right, MatcherParams())
    region = res.disparity_px[:, 32:]
    valid = np.isfinite(region)
    assert valid.mean() >= 0.95
    err = region[valid] - d
    assert np.median(np.abs(err)) <= 0.1
    assert np.percentile(np.abs(err), 99) <= 0.5


@pytest.mark.parametrize("seed", SEEDS)
def test_textureless_patch_is_invalid_not_guessed(seed):
    d = 12.3
    left, right = plane_pair(d, noise_dn=2.0, plain_cols=(120, 220), seed=seed)
    res = compute_disparity(left, right, MatcherParams())
    inner = res.valid[:, 124:216]  # at least half a window away from the texture
    assert 1.0 - inner.mean() >= 0.95
    err = np.abs(res.disparity_px[:, 120:220] - d)
    guessed = np.isfinite(err) & (err > 1.0)
    assert guessed.mean() <= 0.01
    assert res.valid[:, 40:110].mean() >= 0.95  # the textured part of the same plane


@pytest.mark.parametrize("seed", SEEDS)
def test_cross_support_rejects_plain_pixels_beside_texture_keeps_a_thin_pole(seed):
    # within half a window of the texture, a plain pixel's 9 x 9 window still holds
    # texture on one side: the centred 3 x 3 support passes it on sensor noise alone
    # about one time in a hundred; the cross support asks for texture on both sides
    # along an axis. The band pixels pass independently (noise), so their count is
    # Poisson: 480 rows give N = 2880 band pixels, enough that the count without the
    # cross test (rate ~1 %, mean ~29) is never near 0 and the share it removes shows.
    d = 12.3
    left, right = plane_pair(d, noise_dn=2.0, plain_cols=(120, 220), seed=seed, height=480)
    res = compute_disparity(left, right, MatcherParams())
    band = np.concatenate([res.valid[:, 122:125], res.valid[:, 215:218]], axis=1)
    off = compute_disparity(left, right, MatcherParams(support_cross_min_zncc=0.0))
    band_off = np.concatenate([off.valid[:, 122:125], off.valid[:, 215:218]], axis=1)
    n = band.size
    # documented rate (docs/notes/stereo-kernels.md) <= 0.3 %, plus 3 sigma of its Poisson count
    assert band.sum() <= 0.003 * n + 3.0 * np.sqrt(0.003 * n)
    # the cross test removes at least half of what passes without it (>= 10 pixels at
    # a 1 % rate: P(Poisson(29) < 10) ~ 3e-4, so the comparison has power)
    assert band_off.sum() >= 10
    assert band.sum() <= 0.5 * band_off.sum()
    assert res.valid[:, 40:110].mean() >= 0.99
    # a textured pole 6 px wide on a plain plane: its pixels have texture above and below
    u, v = np.meshgrid(np.arange(320, dtype=float), np.arange(240, dtype=float))
    tex_seed, noise_seed = draw_seeds(seed, 2)
    pole_l = np.where((u >= 150) & (u < 156), texture(u, v, seed=tex_seed), 140.0)
    pole_r = np.where((u + d >= 150) & (u + d < 156), texture(u + d, v, seed=tex_seed), 140.0)
    rng = np.random.default_rng(noise_seed)
    pole = compute_disparity(quantise(pole_l, 2.0, rng), quantise(pole_r, 2.0, rng),
                             MatcherParams())
    assert pole.valid[20:220, 150:156].mean() >= 0.95
    assert np.nanmedian(np.abs(pole.disparity_px[20:220, 150:156] - d)) <= 0.3


@pytest.mark.parametrize("seed", SEEDS)
def test_left_right_check_marks_the_occluded_band(seed):
    # square at 20 px in front of a background at 8 px: in the left image the 12 px to
    # the left of the square are hidden from the right camera
    left, right, truth = occlusion_pair(8.0, 20.0, (140, 220, 60, 180), seed=seed)
    res = compute_disparity(left, right, MatcherParams(num_disparities=32))
    occluded = np.zeros_like(res.valid)
    occluded[66:174, 128:140] = True  # away from the square's top and bottom edges
    assert (~res.valid[occluded]).mean() >= 0.8
    assert (res.invalid_reason[occluded] == Reason.LEFT_RIGHT).mean() >= 0.3
    seen = res.valid & ~occluded
    assert np.median(np.abs(res.disparity_px[seen] - truth[seen])) <= 0.1
    assert (res.invalid_reason[~occluded] == Reason.VALID).mean() >= 0.85


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("matcher", ["bm", "sgbm"])
def test_opencv_matchers_behind_the_same_interface(matcher, seed):
    """The result is OpenCV's own output under the documented parameter mapping
    (slitcli.stereo.matcher.match_opencv): 1/16 px fixed point to float px, NaN and
    Reason.OPENCV where OpenCV marks no match. How dense StereoBM is on a texture is
    OpenCV's matter (0.81-0.97 of the columns it covers over ten texture seeds), so
    only the accuracy of what it keeps is asserted."""
    d = 12.3
    left, right = plane_pair(d, seed=seed)
    p = MatcherParams(matcher=matcher, num_disparities=48)
    res = compute_disparity(cv2.cvtColor(left, cv2.COLOR_GRAY2BGR),
                            cv2.cvtColor(right, cv2.COLOR_GRAY2BGR), p)
    w = p.window_w_px
    if matcher == "bm":
        st = cv2.StereoBM_create(numDisparities=48, blockSize=w)
        st.setTextureThreshold(round(0.8 * p.texture_min_dn * w * w))
    else:
        st = cv2.StereoSGBM_create(minDisparity=0, numDisparities=48, blockSize=w,
                                   P1=8 * w * w, P2=32 * w * w)
    st.setPreFilterCap(round(p.prefilter_cap_dn))
    st.setUniquenessRatio(round(100 * p.uniqueness_ratio))
    st.setDisp12MaxDiff(p.lr_max_diff_px)
    st.setSpeckleWindowSize(p.speckle_window_px)
    st.setSpeckleRange(int(np.ceil(p.speckle_range_px)))
    raw = st.compute(left, right)
    assert res.disparity_px.dtype == np.float32
    valid = np.isfinite(res.disparity_px)
    np.testing.assert_array_equal(valid, raw >= 0)
    np.testing.assert_array_equal(res.disparity_px[valid], raw[valid] / np.float32(16.0))
    assert (res.invalid_reason[valid] == Reason.VALID).all()
    assert (res.invalid_reason[~valid] == Reason.OPENCV).all()
    assert valid[:, 64:-8].mean() >= 0.5   # enough kept pixels for the median to mean much
    assert np.median(np.abs(res.disparity_px[valid] - d)) <= 0.3


@pytest.mark.parametrize("kwargs,fragment", [
    (dict(num_disparities=0), "`num_disparities` 0"),
    (dict(num_disparities=-5), "`num_disparities` -5"),
    (dict(window_w_px=8), "`window_w_px` 8"),
    (dict(window_h_px=4), "`window_h_px` 4"),
    (dict(matcher="bm", num_disparities=40), "multiple of 16"),
    (dict(prefilter="median"), "`prefilter`"),
    (dict(boundary_ratio=1.5), "`boundary_ratio`"),
    (dict(support_side_min_zncc=2.0), "`support_side_min_zncc`"),
    (dict(boundary_radius_px=0), "boundary_radius_px"),
])
def test_impossible_parameters_are_one_line_errors(kwargs, fragment):
    with pytest.raises(SlitcliError, match=fragment) as e:
        MatcherParams(**kwargs)
    assert "\n" not in str(e.value)


def test_sizes_checked_against_the_images():
    # size errors, raised before any pixel is read: one seed suffices
    left, right = plane_pair(5.0, width=64, height=48)
    with pytest.raises(SlitcliError, match="wider than the image"):
        compute_disparity(left, right, MatcherParams(window_w_px=65, num_disparities=8))
    with pytest.raises(SlitcliError, match="exceeds the image width"):
        compute_disparity(left, right, MatcherParams(num_disparities=80))
    with pytest.raises(SlitcliError, match="differ in size"):
        compute_disparity(left, right[:, :60], MatcherParams(num_disparities=8))


# ------------------------------------------------------------------ compiled helpers
@pytest.mark.parametrize("seed", SEEDS)
def test_speckle_regions_are_those_of_opencv_filter_speckles(seed):
    # the compiled one-pass union-find must find exactly cv2.filterSpeckles' regions
    # (4-connected valid pixels whose 1/16 px disparities differ by <= max_diff)
    from slitcli.stereo._kernel import speckle_finish

    rng = np.random.default_rng(seed)
    for trial in range(6):
        h, w = 37 + trial, 53 + 3 * trial
        # piecewise-constant patches of random size, a ramp, noise, random holes
        disp = cv2.resize(rng.uniform(0, 40, (h // 4 + 1, w // 5 + 1)), (w, h),
                          interpolation=cv2.INTER_NEAREST).astype(np.float32)
        disp += np.linspace(0, 3, w, dtype=np.float32)[None, :] * (trial % 2)
        disp += rng.normal(0, 0.05 * trial, (h, w)).astype(np.float32)
        reason = np.where(rng.random((h, w)) < 0.15, 1, 0).astype(np.uint8)
        max_size, max_diff = [5, 20, 60, 100, 200, 8][trial], [1, 4, 16, 32, 8, 2][trial]
        valid = reason == 0
        fixed = np.where(valid, disp * np.float32(16.0), -32768.0).astype(np.int16)
        cv2.filterSpeckles(fixed, -32768, max_size, max_diff)
        expected = valid & (fixed == -32768)
        got_disp, got_reason = disp.copy(), reason.copy()
        speckle_finish(got_disp, got_reason, max_size, max_diff, 5)
        assert expected.sum() > 0
        np.testing.assert_array_equal(got_reason == 5, expected)
        assert np.isnan(got_disp[got_reason != 0]).all()
        np.testing.assert_array_equal(got_disp[got_reason == 0], disp[got_reason == 0])


@pytest.mark.parametrize("seed", SEEDS)
def test_speckle_small_marks_what_speckle_finish_removes(seed):
    # the SGM bracket test asks which valid pixels the speckle filter would remove,
    # without removing them: the same regions (cv2.filterSpeckles'), maps unchanged
    from slitcli.stereo._kernel import speckle_finish, speckle_small

    rng = np.random.default_rng(seed)
    marked = kept = 0
    for trial in range(6):
        h, w = 41 + trial, 47 + 5 * trial
        disp = cv2.resize(rng.uniform(0, 40, (h // 3 + 1, w // 4 + 1)), (w, h),
                          interpolation=cv2.INTER_NEAREST).astype(np.float32)
        disp += rng.normal(0, 0.04 * trial, (h, w)).astype(np.float32)
        reason = np.where(rng.random((h, w)) < 0.2, 3, 0).astype(np.uint8)
        max_size, max_diff = [4, 12, 50, 100, 200, 9][trial], [1, 3, 16, 32, 8, 2][trial]
        valid = reason == 0
        fixed = np.where(valid, disp * np.float32(16.0), -32768.0).astype(np.int16)
        cv2.filterSpeckles(fixed, -32768, max_size, max_diff)
        expected = valid & (fixed == -32768)
        before = disp.copy(), reason.copy()
        small = np.ones((h, w), np.bool_)
        speckle_small(disp, reason, max_size, max_diff, small.view(np.uint8))
        marked += expected.sum()
        kept += (valid & ~expected).sum()
        np.testing.assert_array_equal(small, expected)
        np.testing.assert_array_equal(disp, before[0])
        np.testing.assert_array_equal(reason, before[1])
        d2, r2 = disp.copy(), reason.copy()
        speckle_finish(d2, r2, max_size, max_diff, 5)
        np.testing.assert_array_equal(small, r2 == 5)
    assert marked > 0 and kept > 0


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("aggregation", ["none", "sgm"])
def test_a_caller_pool_gives_the_same_maps_and_stays_open(seed, aggregation, monkeypatch):
    # a caller that matches a sequence holds one pool of helper threads: with two
    # threads the maps are those of a frame that makes its own pool and of one thread
    # (every array bit for bit), and the caller's pool is not shut down by the frame
    from concurrent.futures import ThreadPoolExecutor

    import slitcli.stereo.matcher as matcher_mod
    import slitcli.stereo.sgm as sgm_mod

    left, right = plane_pair(6.3, width=96, height=64, noise_dn=2.0, seed=seed,
                             plain_cols=(40, 60))
    p = MatcherParams(num_disparities=16, aggregation=aggregation)
    maps = {}
    for threads, caller in ((1, False), (2, False), (2, True)):
        monkeypatch.setattr(matcher_mod, "kernel_threads", lambda t=threads: t)
        monkeypatch.setattr(sgm_mod, "kernel_threads", lambda t=threads: t)
        if caller:
            with ThreadPoolExecutor(max_workers=1) as pool:
                res = [compute_disparity(left, right, p, pool=pool) for _ in range(2)]
                assert pool.submit(lambda: 7).result() == 7
        else:
            res = [compute_disparity(left, right, p)]
        for r in res:
            maps.setdefault((threads, caller), []).append(r)
    want = maps[(1, False)][0]
    assert want.valid.sum() > 0.5 * want.valid.size and (~want.valid).sum() > 50
    for got in (r for rs in maps.values() for r in rs):
        np.testing.assert_array_equal(got.disparity_px, want.disparity_px)
        np.testing.assert_array_equal(got.invalid_reason, want.invalid_reason)
        np.testing.assert_array_equal(got.match_cost, want.match_cost)


@pytest.mark.parametrize("seed", SEEDS)
def test_row_window_minimum_is_an_erosion(seed):
    from slitcli.stereo._boundary import window_min

    rng = np.random.default_rng(seed)
    for radius in (1, 2, 5, 7):
        v = rng.uniform(0, 100, 41).astype(np.float32)
        v[rng.random(41) < 0.3] = np.float32(3e38)
        out = window_min(v, radius)
        ref = cv2.erode(v[None, :], np.ones((1, 2 * radius + 1), np.uint8),
                        borderType=cv2.BORDER_CONSTANT, borderValue=3e38)[0]
        np.testing.assert_array_equal(out, ref)


def test_second_thread_only_when_another_core_is_free(monkeypatch):
    # the matcher's thread count: SLITCLI_THREADS (default every core), less the cores
    # other runnable tasks hold right now (/proc/loadavg's running count includes the
    # calling thread); a setting that is no positive number is an error naming it
    import io

    import slitcli.stereo.bands as matcher

    real_open = open

    def fake_loadavg(running: int):
        def fake_open(path, *args, **kwargs):
            if path == "/proc/loadavg":
                return io.StringIO(f"0.50 0.40 0.30 {running}/123 4567\n")
            return real_open(path, *args, **kwargs)
        return fake_open

    monkeypatch.setattr(matcher.os, "cpu_count", lambda: 2)
    monkeypatch.delenv(matcher.THREADS_ENV, raising=False)
    for running, expected in ((1, 2), (2, 1), (5, 1)):
        monkeypatch.setattr("builtins.open", fake_loadavg(running))
        assert matcher.kernel_threads() == expected
    monkeypatch.setattr("builtins.open", fake_loadavg(1))
    monkeypatch.setenv(matcher.THREADS_ENV, "1")
    assert matcher.kernel_threads() == 1
    for bad in ("0", "-2", "two"):
        monkeypatch.setenv(matcher.THREADS_ENV, bad)
        with pytest.raises(SlitcliError, match="SLITCLI_THREADS"):
            matcher.kernel_threads()
