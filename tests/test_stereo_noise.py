"""The pair's noise model (slitcli.stereo.noise) and the support correlations under it
(slitcli.stereo._c.zncc, ``nv``/``nvf``): the estimate against the noise the camera
model really put into the images, the signal correlation against its hand-derived
value, and the local matcher on a textured plane and a depth step seen through the
``robot`` camera."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from slitcli.sim.camera import apply_camera, camera_preset
from slitcli.stereo._c import zncc
from slitcli.stereo.matcher import MatcherParams, compute_disparity
from slitcli.stereo.noise import MIN_SAMPLES, MatchNoise, estimate_match_noise
from slitcli.stereo.reasons import Reason

SEEDS = [0, 1, 2, 3, 4]
DISPARITY_PX = 6
H, W = 120, 200


def _texture(rng: np.random.Generator, width: int) -> np.ndarray:
    """A smooth random grey texture (H, width), linear DN 50-200, like the renderer's
    noise textures seen at 1-2 m (features of 2-4 px)."""
    t = cv2.GaussianBlur(rng.normal(0.0, 1.0, (H, width)), (0, 0), 1.5)
    t = (t - t.mean()) / t.std()
    return np.clip(125.0 + 30.0 * t, 50.0, 200.0)


def _camera_pair(seed: int, preset: str):
    """Left/right grey views of a fronto-parallel plane at DISPARITY_PX through a camera
    preset, and the same views through the same camera without sensor noise."""
    rng = np.random.default_rng(seed)
    tex = _texture(rng, W + DISPARITY_PX)
    colour = np.array([0.7, 0.66, 0.6])
    views = {"left": tex[:, :W], "right": tex[:, DISPARITY_PX:]}   # L(x) = R(x - d)
    model = camera_preset(preset)
    clean_model = camera_preset(preset, gain_dn_per_e=None, read_noise_e=0.0,
                                full_well_e=None, blooming_share=0.0)
    out = {}
    for k, (name, v) in enumerate(views.items()):
        light = v[..., None] * colour[None, None, :] / colour.max()
        noisy = apply_camera(light, model, np.random.default_rng([seed, k]))
        clean = apply_camera(light, clean_model, np.random.default_rng([seed, k]))
        out[name] = (cv2.cvtColor(noisy, cv2.COLOR_BGR2GRAY),
                     cv2.cvtColor(clean, cv2.COLOR_BGR2GRAY))
    return out


def _truth(views) -> tuple[float, float]:
    """Each view's noise (noisy minus noiseless, both through the camera: JPEG's errors
    included): standard deviation and lag-1 correlation along x, pooled."""
    res = [n.astype(float) - c.astype(float) for n, c in views.values()]
    res = [r[8:-8, 8:-8] - r[8:-8, 8:-8].mean() for r in res]
    var = np.mean([(r * r).mean() for r in res])
    rho = np.mean([(r[:, 1:] * r[:, :-1]).mean() for r in res]) / var
    return float(np.sqrt(var)), float(rho)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("preset", ["robot", "webcam"])
def test_estimate_matches_camera_noise(seed, preset):
    views = _camera_pair(seed, preset)
    sigma, rho = _truth(views)
    disp = np.full((H, W), float(DISPARITY_PX), np.float32)
    valid = np.zeros((H, W), bool)
    valid[4:-4, DISPARITY_PX + 4:-4] = True
    est = estimate_match_noise(views["left"][0], views["right"][0], disp, valid)
    # 20 %: the noise depends on the level (shot noise; the tone curve's slope) and the
    # estimate weighs the levels by where the slope is low, the truth by area
    assert est.sigma_dn == pytest.approx(sigma, rel=0.2)
    # the correlation of 1/2 x (n_l - n_r) from ~15000 pairs: +-0.02 of sampling,
    # 0.08 for the level mix and the JPEG blocks (not the same in both views)
    assert est.rho_x == pytest.approx(rho, abs=0.1)
    assert est.samples >= MIN_SAMPLES


def test_too_few_matches_give_no_model():
    img = np.zeros((20, 30), np.uint8)
    est = estimate_match_noise(img, img, np.zeros((20, 30), np.float32),
                               np.zeros((20, 30), bool))
    assert est == MatchNoise()
    assert est.variance_factor(3, 3) == 1.0


def test_variance_factor_of_correlated_sums():
    """A 3 x 3 sum of noise correlated rho at lag 1 along x only: 9 variances plus
    2 x 6 neighbour pairs x rho -> 1 + 12 rho / 9."""
    assert MatchNoise(1.0, 0.3, 0.0, 0.0, 1000).variance_factor(3, 3) == pytest.approx(1.4)
    rng = np.random.default_rng(0)
    white = rng.normal(0.0, 1.0, (400, 401))
    noise = (white[:, 1:] + white[:, :-1]) / np.sqrt(2.0)   # rho_x = 0.5 exactly
    sums = cv2.boxFilter(noise, -1, (3, 3), normalize=False)[5:-5, 5:-5]
    vf = MatchNoise(1.0, 0.5, 0.0, 0.0, 1000).variance_factor(3, 3)
    assert sums.var() / 9.0 == pytest.approx(vf, rel=0.05)


@pytest.mark.parametrize("seed", SEEDS)
def test_signal_correlation_under_noise(seed):
    """Blocks of a shared signal of variance s2 with independent noise nv in each image:
    plain ZNCC expects s2 / (s2 + nv); with the noise model the correlation of the
    signals, 1. Pure-noise blocks stay as they are (mostly below the 95 % bound)."""
    rng = np.random.default_rng(seed)
    h, w, nv = 90, 120, 25.0
    signal = 128.0 + 10.0 * rng.normal(0.0, 1.0, (h, w))         # s2 = 100 = 4 nv
    gl = (signal + rng.normal(0.0, 5.0, (h, w))).astype(np.float32)
    gr = (signal + rng.normal(0.0, 5.0, (h, w))).astype(np.float32)
    n = 800
    yc = rng.integers(10, h - 10, n).astype(np.intp)
    xc = rng.integers(10, w - 10, n).astype(np.intp)
    d = np.zeros(n, np.float32)
    plain = np.zeros(n, np.float32)
    model = np.zeros(n, np.float32)
    zncc.blocks(gl, gr, yc, xc, d, n, 2, 2, plain)
    zncc.blocks(gl, gr, yc, xc, d, n, 2, 2, model, nv, nv)
    # 5 x 5 blocks: 24 degrees of freedom; the mean of 800 blocks within a few 1/sqrt(n)
    assert np.mean(plain) == pytest.approx(100.0 / 125.0, abs=0.03)
    assert np.mean(model) == pytest.approx(1.0, abs=0.06)
    one = np.zeros(n, np.float32)
    zncc.blocks_one_at_a_time(gl, gr, yc, xc, d, n, 2, 2, one, nv, nv)
    np.testing.assert_array_equal(one, model)   # the eight lanes are the scalar code
    # noise alone: energies below the bound keep plain ZNCC, so the mean stays ~0
    gl0 = (128.0 + rng.normal(0.0, 5.0, (h, w))).astype(np.float32)
    gr0 = (128.0 + rng.normal(0.0, 5.0, (h, w))).astype(np.float32)
    zncc.blocks(gl0, gr0, yc, xc, d, n, 2, 2, model, nv, nv)
    assert abs(float(np.mean(model))) < 0.05


@pytest.mark.parametrize("seed", SEEDS)
def test_robot_camera_plane_denser_not_wronger(seed):
    """A textured plane through the ``robot`` camera: the support tests under the
    estimated noise model keep more right pixels, and no more wrong ones."""
    views = _camera_pair(seed, "robot")
    left, right = views["left"][0], views["right"][0]
    got = {}
    for on in (False, True):
        r = compute_disparity(left, right, MatcherParams(support_noise=on))
        err = np.abs(r.disparity_px[:, 48:] - DISPARITY_PX)
        got[on] = (float(np.mean(err <= 1.0)), float(np.mean(err > 1.0)))
    # the model only raises correlations (energies above the noise bound lose their
    # noise; the strong gate keeps the plain one), so no test rejects more: the right
    # share can only grow, and on ~9000 noisy textured pixels it does
    assert got[True][0] > got[False][0]
    # a wrong match needs a second texture patch that fits within the noise: rare on
    # a fronto-parallel plane; the bound is one pixel in a hundred
    assert got[True][1] <= max(got[False][1], 0.01)


@pytest.mark.parametrize("seed", SEEDS)
def test_noiseless_pair_is_matched_as_before(seed):
    """An exactly shifted noiseless pair: the matches differ only by what the subpixel
    parabola's bias (at most 0.05 px, docs/stereo.md) times the texture's slope leaves,
    so the estimate stays below 0.1 DN; a noise energy that small changes a textured
    block's correlation by a relative ne / v below 1e-3, and no test result changes:
    the matcher's result is the same, bit for bit."""
    rng = np.random.default_rng(seed)
    tex = np.clip(np.rint(_texture(rng, W + DISPARITY_PX)), 0, 255).astype(np.uint8)
    left, right = tex[:, :W], np.ascontiguousarray(tex[:, DISPARITY_PX:])
    on = compute_disparity(left, right, MatcherParams(support_noise=True))
    off = compute_disparity(left, right, MatcherParams(support_noise=False))
    est = estimate_match_noise(left, right, on.disparity_px, on.valid)
    assert est.sigma_dn < 0.1
    np.testing.assert_array_equal(on.invalid_reason, off.invalid_reason)
    np.testing.assert_array_equal(on.disparity_px, off.disparity_px)


def _step_pair(seed: int):
    """A textured foreground (columns < 100 of the left view, disparity 12) before a
    textured background (disparity 6) through the ``robot`` camera, and the left view's
    true disparities."""
    rng = np.random.default_rng(seed)
    fg, bg = _texture(rng, W + 20), _texture(rng, W + 20)
    x = np.arange(W)
    edge, d_fg, d_bg = 100, 12, 6
    left = np.where(x < edge, fg[:, x], bg[:, x])
    xr_fg = x + d_fg   # the right view sees the foreground where it reaches
    right = np.where(xr_fg < edge, fg[:, np.minimum(xr_fg, W + 19)],
                     bg[:, np.minimum(x + d_bg, W + 19)])
    model = camera_preset("robot")
    views = []
    for k, v in enumerate((left, right)):
        light = np.repeat(v[..., None], 3, axis=2)
        views.append(cv2.cvtColor(apply_camera(light, model, np.random.default_rng([seed, k])),
                                  cv2.COLOR_BGR2GRAY))
    truth = np.where(x < edge, float(d_fg), float(d_bg))[None, :].repeat(H, axis=0)
    return views[0], views[1], truth


@pytest.mark.parametrize("seed", SEEDS)
def test_depth_edge_under_noise(seed):
    """A depth step through the robot camera: with both residuals less the views' noise
    the depth-edge test can tell the surfaces apart again (it fires more), more of the
    background is right, and its wrong pixels (the window's fattening, 9-75 of them
    without the model) do not grow beyond their counting noise (2 sqrt(n) + 1)."""
    left, right, truth = _step_pair(seed)
    got = {}
    for on in (False, True):
        r = compute_disparity(left, right, MatcherParams(support_noise=on))
        d = r.disparity_px
        bg = truth == 6.0
        wrong = bg & np.isfinite(d) & (np.abs(d - 6.0) > 1.0)
        good = bg & (np.abs(d - 6.0) <= 1.0)
        got[on] = (int(good.sum()), int(wrong.sum()),
                   int((r.invalid_reason == Reason.BOUNDARY).sum()))
    assert got[True][2] > got[False][2]
    assert got[True][0] > got[False][0]
    assert got[True][1] <= got[False][1] + 2.0 * np.sqrt(got[False][1]) + 1.0
